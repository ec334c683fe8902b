"""Sensor models, one a file, each with its settings (a ``*Spec`` dataclass) beside it: D435
colour and depth, T265 pose drift and the conditions that scale it, wheel odometry, the thermal
camera; what they share is base.py."""
