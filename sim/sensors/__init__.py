"""Sensor models: D435 colour and depth noise, T265 pose drift, thermal camera."""
