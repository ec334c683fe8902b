"""sim: the simulated rescue maze, its objects, the robot's motion, sensors and ground truth."""
