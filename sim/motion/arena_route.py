"""The TurtleBot's route in the goal arena: look around, drive to the ball, look again.

The robot of [Bouda2025]_ must find the ball and the goal before it can kick, and its SLAM maps
the pillars as it moves (section 2.2). The route gives a mapper what it needs: a full
turn in place at the start (every pillar in view once, from one spot), the drive along
the planned legs to the kick point behind the ball (sim/world/arena.py: turning in place at
each corner, then straight at ``speed_mps``), so the pillars are seen from a moving
viewpoint, a turn to face the goal and a pause of ``GOAL_LOOK_S`` there, then a second
full turn from the new spot. Turns run at ``yaw_rate_dps``. The camera is fixed to the
base: no pan. No randomness.

>>> import numpy as np
>>> from sim.world.arena import generate_arena
>>> from sim.motion.route import RobotSpec
>>> from sim.world.arena import ArenaGenerate
>>> layout = generate_arena(ArenaGenerate(), np.random.default_rng(0))
>>> r = arena_route(layout, RobotSpec(kind="turtlebot", route="arena", speed_mps=0.2, yaw_rate_dps=20))
>>> 40 < r.duration_s < 90, r.pan_amplitude_rad
(True, 0.0)

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math

import numpy as np

from sim.motion.route import RobotSpec, Route, _wrap_to
from sim.world.arena import ArenaLayout

GOAL_LOOK_S = 2.0  # standing still facing the goal before the second look around


class _Keyframes:
    def __init__(self, xy: np.ndarray, yaw: float) -> None:
        self.t, self.x, self.y, self.yaw = 0.0, float(xy[0]), float(xy[1]), float(yaw)
        self.rows = [(self.t, self.x, self.y, self.yaw)]

    def _add(self) -> None:
        self.rows.append((self.t, self.x, self.y, self.yaw))

    def turn_to(self, heading: float, rate: float) -> None:
        target = _wrap_to(heading, self.yaw)
        if abs(target - self.yaw) > 1e-9:
            self.t += abs(target - self.yaw) / rate
            self.yaw = target
            self._add()

    def turn_by(self, angle: float, rate: float) -> None:
        self.t += abs(angle) / rate
        self.yaw += angle
        self._add()

    def drive_to(self, xy: np.ndarray, speed: float, rate: float) -> None:
        dx, dy = float(xy[0]) - self.x, float(xy[1]) - self.y
        dist = math.hypot(dx, dy)
        if dist < 1e-9:
            return
        self.turn_to(math.atan2(dy, dx), rate)
        self.t += dist / speed
        self.x, self.y = float(xy[0]), float(xy[1])
        self._add()

    def wait(self, seconds: float) -> None:
        self.t += seconds
        self._add()


def arena_route(layout: ArenaLayout, spec: RobotSpec) -> Route:
    """Timed keyframes of the base in the world frame (see the module docstring)."""
    rate = math.radians(spec.yaw_rate_dps)
    k = _Keyframes(layout.start_xy, layout.start_yaw_rad)
    k.turn_by(2.0 * math.pi, rate)
    for xy in layout.path_xy[1:]:
        k.drive_to(xy, spec.speed_mps, rate)
    k.turn_to(layout.goal_heading_rad, rate)
    k.wait(GOAL_LOOK_S)
    k.turn_by(2.0 * math.pi, rate)
    a = np.array(k.rows)
    return Route(t_s=a[:, 0], x_m=a[:, 1], y_m=a[:, 2], yaw_rad=a[:, 3], pan_amplitude_rad=0.0)
