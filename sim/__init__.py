"""sim: the simulated rescue maze, its objects, the robot's motion, sensors and ground truth.

Importing ``sim`` chooses a headless OpenGL backend for MuJoCo (``sim.gl``) before
any of its modules imports mujoco.
"""

from sim import gl as _gl  # noqa: F401
