"""How the robot moves through the world: its timed route and camera pan (route.py), the
cell-by-cell tour of a maze (tour.py) and the TurtleBot's route in the goal arena (arena_route.py)."""
