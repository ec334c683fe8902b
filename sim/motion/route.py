"""The robot's motion: a timed, piecewise-linear path of base poses plus the camera pan.

A tour (``sim.motion.tour.plan_tour``) visits every cell; the robot turns in place at
each cell centre toward the next one at ``yaw_rate_dps`` and drives straight at
``speed_mps``. The mast robot's camera pans as ``robot.pan`` says
(:class:`PanSpec`; docs/FACTS.md "How a rescue robot searches"): by
default in steps, as a pan-tilt unit scans ([HectorCameraControl]_): at each cell
it enters for the first time the base stops, the camera slews through the step
angles, dwelling at each, and back to 0, and the robot drives on looking ahead;
or, with ``mode: sweep``, continuously as ``pan(t) = A sin(2 pi t / T)`` while the
robot drives and turns. A route can instead be replayed from a CSV of timed
poses in the map frame (columns ``t_s,x_m,y_m,yaw_deg`` and optionally ``pan_deg``).

References
----------
Full entries in docs/SOURCES.md.

.. [HectorCameraControl] Team Hector Darmstadt, hector_camera_control (ROS), sensor head
   "look_around" patterns.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from poi.core.geometry import make_transform, rot_y, rot_z
from poi.core.loader import number


@dataclass(kw_only=True)
class PanSpec:
    """How the mast robot's camera pans (docs/FACTS.md "How a rescue robot searches").

    ``mode: steps`` (the default) scans as a pan-tilt unit does: at each cell the tour enters
    for the first time the base stops, the camera slews at ``rate_dps`` through the pan angles
    ``steps_deg`` (degrees from the base's heading, positive left) in the order given, dwells
    ``dwell_s`` at each, slews back to 0 and the robot drives on looking ahead. Team Hector's
    sensor head scans in steps of 40 degrees out to 80 with a 1 s dwell ([HectorCameraControl]_);
    the defaults, -90 to 90 in 45-degree steps, put each side wall face on in the simulated D435's
    55-degree view with 10 degrees of overlap, and 0.5 s holds the camera still for five frames
    at 10 fps. 120 deg/s is within what a Dynamixel MX-28 (330 deg/s unloaded, [RobotisMX28]_)
    or a PTU-D46 ([PTU-D46]_) turns.

    At a step that faces a wall of the cell (0.6 m away in an RRL cell, where the D435's
    43-degree vertical view spans only 0.27-0.73 m of it from a 0.5 m mast) the head also dwells
    at each tilt of ``wall_tilts_deg`` (up positive) before levelling: at -25 and +25 degrees it
    sees the wall from its foot to 1.1 m, as a sensor head looks down and up a wall within reach.

    ``mode: sweep`` pans continuously, ``pan(t) = amplitude_deg sin(2 pi t / period_s)``, while the
    robot drives and turns without stopping.

    References
    ----------
    Full entries in docs/SOURCES.md.

    .. [HectorCameraControl] Team Hector Darmstadt, hector_camera_control (ROS), sensor head
       "look_around" patterns.
    .. [RobotisMX28] ROBOTIS, DYNAMIXEL MX-28 e-Manual, specifications.
    .. [PTU-D46] Directed Perception, PTU-D46 pan-tilt unit user's manual, v2.14.0, 2006.
    """

    mode: Literal["sweep", "steps"] = "steps"
    steps_deg: tuple[float, ...] = number((-90.0, -45.0, 0.0, 45.0, 90.0), lo=-180.0, hi=180.0)
    dwell_s: float = number(0.5, lo=0.0, hi=60.0)
    wall_tilts_deg: tuple[float, ...] = number((-25.0, 25.0), lo=-60.0, hi=60.0)
    rate_dps: float = number(120.0, lo=0.0, hi=1000.0, lo_open=True)
    amplitude_deg: float = number(80.0, lo=-180.0, hi=180.0)
    period_s: float = number(5.0, lo=0.0, lo_open=True)

    def __post_init__(self) -> None:
        if self.mode == "steps" and not self.steps_deg:
            raise ValueError("steps_deg: mode 'steps' needs at least one pan angle, e.g. [-90, -45, 0, 45, 90]")


TURTLEBOT_CAMERA_HEIGHT_M = 0.30  # the D435 on a TurtleBot's top plate


@dataclass(kw_only=True)
class RobotSpec:
    """The robot base and its camera (kinematic: it follows the route exactly).

    ``kind``: ``mast``, the rescue robot whose camera pans on a mast (``pan``); or
    ``turtlebot``, a differential-drive base with the camera fixed on its top plate,
    looking forward (``pan`` does not apply; ``mast_height_m`` is the camera's height,
    default ``TURTLEBOT_CAMERA_HEIGHT_M``). ``route``: ``tour`` (visit every maze
    cell), ``arena`` (the goal arena's look-around and approach, sim/motion/arena_route.py) or
    a CSV file of timed poses ``t,x,y,yaw[,pan]``.
    """

    kind: Literal["mast", "turtlebot"] = "mast"
    route: str = "tour"
    speed_mps: float = 0.3
    yaw_rate_dps: float = 60.0
    mast_height_m: float | None = None  # default: 0.5 m for RRL cells, 0.2 m for RMRC; turtlebot 0.3 m
    tilt_deg: float = 0.0  # positive looks up
    pan: PanSpec = field(default_factory=PanSpec)
    max_duration_s: float | None = None

    def __post_init__(self) -> None:
        if self.speed_mps <= 0 or self.yaw_rate_dps <= 0:
            raise ValueError("speed_mps and yaw_rate_dps must be positive")


class RouteError(ValueError):
    """A route file that cannot be used."""


@dataclass(kw_only=True)
class Route:
    """Keyframes of the base pose in the world frame; yaw is unwrapped (continuous)."""

    t_s: np.ndarray  # (K,)
    x_m: np.ndarray
    y_m: np.ndarray
    yaw_rad: np.ndarray
    pan_rad: np.ndarray | None = None  # per keyframe when replayed from a file
    pan_amplitude_rad: float = 0.0
    pan_period_s: float = 8.0
    tilt_rad: np.ndarray | None = None  # per keyframe: the camera head's tilt over the mount's, up positive

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1])

    def base_pose(self, t: float) -> tuple[float, float, float]:
        """(x, y, yaw) of the robot base at time t (clamped to the route's ends)."""
        x = float(np.interp(t, self.t_s, self.x_m))
        y = float(np.interp(t, self.t_s, self.y_m))
        yaw = float(np.interp(t, self.t_s, self.yaw_rad))
        return x, y, yaw

    def pan(self, t: float) -> float:
        if self.pan_rad is not None:
            return float(np.interp(t, self.t_s, self.pan_rad))
        if self.pan_amplitude_rad == 0.0:
            return 0.0
        return self.pan_amplitude_rad * float(np.sin(2.0 * np.pi * t / self.pan_period_s))

    def pans(self, t: np.ndarray) -> np.ndarray:
        """(n,) :meth:`pan` at each of the times ``t`` (n,), in one array operation."""
        t = np.asarray(t, dtype=float)
        if self.pan_rad is not None:
            return np.interp(t, self.t_s, self.pan_rad)
        if self.pan_amplitude_rad == 0.0:
            return np.zeros(t.shape)
        return self.pan_amplitude_rad * np.sin(2.0 * np.pi * t / self.pan_period_s)

    def tilt(self, t: float) -> float:
        """The camera head's tilt at time t over the mount's own (0 without keyframes)."""
        if self.tilt_rad is None:
            return 0.0
        return float(np.interp(t, self.t_s, self.tilt_rad))


def _wrap_to(target: float, current: float) -> float:
    """The angle equal to ``target`` mod 2 pi that is closest to ``current``."""
    return current + (target - current + np.pi) % (2.0 * np.pi) - np.pi


class _Keyframes:
    """The route's keyframes as they are laid down: the state now, appended when time moves."""

    def __init__(self, x: float, y: float, yaw: float) -> None:
        self.t, self.x, self.y, self.yaw, self.pan, self.tilt = 0.0, x, y, yaw, 0.0, 0.0
        self.rows = [(0.0, x, y, yaw, 0.0, 0.0)]

    def advance(self, dt: float) -> None:
        """Let ``dt`` seconds pass and record the state reached (nothing when dt is 0)."""
        if dt > 0.0:
            self.t += dt
            self.rows.append((self.t, self.x, self.y, self.yaw, self.pan, self.tilt))

    def slew(self, pan: float, tilt: float, rate_rad_s: float) -> None:
        """Pan and tilt together to (pan, tilt), each axis at ``rate_rad_s``: the slower axis decides."""
        dt = max(abs(pan - self.pan), abs(tilt - self.tilt)) / rate_rad_s
        self.pan, self.tilt = pan, tilt
        self.advance(dt)

    def scan(
        self,
        steps_rad: np.ndarray,
        rate_rad_s: float,
        dwell_s: float,
        wall_tilts_rad: np.ndarray | None = None,
        walled: list[bool] | None = None,
    ) -> None:
        """The base still, the camera slews to each step angle at ``rate_rad_s``, dwells
        ``dwell_s`` there, and slews back to 0 (a pan-tilt unit's stepped scan); at a step that
        faces a wall beside the cell (``walled``) it also dwells at each of ``wall_tilts_rad``
        before tilting back level, so the wall is seen from its foot to its top."""
        for i, a in enumerate(steps_rad):
            self.slew(float(a), 0.0, rate_rad_s)
            self.advance(dwell_s)
            if walled is not None and walled[i] and wall_tilts_rad is not None:
                for tilt in wall_tilts_rad:
                    self.slew(float(a), float(tilt), rate_rad_s)
                    self.advance(dwell_s)
        self.slew(0.0, 0.0, rate_rad_s)


def walled_steps(maze, cell: tuple[int, int], yaw: float, steps_rad: np.ndarray) -> list[bool]:
    """For each pan step, whether the camera then faces a wall of ``cell`` (at yaw + pan along
    one of the grid's four directions, within 10 degrees, with no open neighbour there)."""
    cx, cy = maze.cell_center(*cell)
    open_dirs = [
        float(np.arctan2(ny - cy, nx - cx))
        for nx, ny in (maze.cell_center(*nb) for nb in maze.open_neighbours(*cell))
    ]
    out = []
    for a in steps_rad:
        d = yaw + float(a)
        on_grid = abs(_wrap_to(d, 0.0) - np.round(_wrap_to(d, 0.0) / (np.pi / 2)) * np.pi / 2) < np.deg2rad(10.0)
        is_open = any(abs(_wrap_to(d, o) - o) < np.deg2rad(10.0) for o in open_dirs)
        out.append(on_grid and not is_open)
    return out


def route_from_tour(maze, cells: list[tuple[int, int]], spec: RobotSpec, start_yaw: float) -> Route:
    """Turn-then-drive keyframes through the centres of ``cells``, with the camera's pan.

    With ``spec.pan.mode == "steps"`` on the mast robot the base stops at the first visit
    of each cell (the start cell included, revisits not) while the camera scans
    (:meth:`_Keyframes.scan`); the pan is 0 whenever the base moves. Otherwise (``sweep``,
    or a TurtleBot, whose camera does not pan) the pan is the sinusoid and the route ends
    with a full turn in place in the last cell; the stepped route needs none, its last cell
    being new and so scanned.
    """
    w = np.deg2rad(spec.yaw_rate_dps)
    steps = spec.kind == "mast" and spec.pan.mode == "steps"
    steps_rad = np.deg2rad(np.asarray(spec.pan.steps_deg, dtype=float))
    tilts_rad = np.deg2rad(np.asarray(spec.pan.wall_tilts_deg, dtype=float))
    rate = np.deg2rad(spec.pan.rate_dps)
    x, y = maze.cell_center(*cells[0])
    k = _Keyframes(float(x), float(y), float(start_yaw))
    seen = {cells[0]}

    def scan(cell: tuple[int, int]) -> None:
        k.scan(steps_rad, rate, spec.pan.dwell_s, tilts_rad, walled_steps(maze, cell, k.yaw, steps_rad))

    if steps:
        scan(cells[0])
    for cell in cells[1:]:
        nx, ny = maze.cell_center(*cell)
        heading = _wrap_to(float(np.arctan2(ny - k.y, nx - k.x)), k.yaw)
        turn = abs(heading - k.yaw)
        k.yaw = heading
        k.advance(turn / w if turn > 1e-9 else 0.0)
        dist = float(np.hypot(nx - k.x, ny - k.y))
        k.x, k.y = float(nx), float(ny)
        k.advance(dist / spec.speed_mps)
        if steps and cell not in seen:
            scan(cell)
        seen.add(cell)
    if not steps:  # finish with a full look around in the last cell
        k.yaw += 2.0 * np.pi
        k.advance(2.0 * np.pi / w)
    t, xs, ys, yaws, pans, tilts = (np.array(c) for c in zip(*k.rows, strict=True))
    return Route(
        t_s=t,
        x_m=xs,
        y_m=ys,
        yaw_rad=yaws,
        pan_rad=pans if steps else None,
        tilt_rad=tilts if steps and np.any(tilts) else None,
        pan_amplitude_rad=0.0 if steps else float(np.deg2rad(spec.pan.amplitude_deg)),
        pan_period_s=spec.pan.period_s,
    )


def load_route_csv(path: str | Path, T_world_map: np.ndarray) -> Route:
    """Read timed poses in the map frame (t_s,x_m,y_m,yaw_deg[,pan_deg]) into a world-frame Route."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except OSError as e:
        raise RouteError(f"{p}: cannot read route file: {e.strerror or e}") from None
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        raise RouteError(f"{p}:1: empty route file; expected a header t_s,x_m,y_m,yaw_deg[,pan_deg]")
    header = [h.strip() for h in rows[0]]
    need = ["t_s", "x_m", "y_m", "yaw_deg"]
    if header[:4] != need or (len(header) == 5 and header[4] != "pan_deg") or len(header) > 5:
        raise RouteError(f"{p}:1: header {','.join(header)!r}; expected t_s,x_m,y_m,yaw_deg[,pan_deg]")
    vals = []
    for i, row in enumerate(rows[1:], start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(header):
            raise RouteError(f"{p}:{i}: {len(row)} values; expected {len(header)}")
        try:
            v = [float(c) for c in row]
        except ValueError:
            raise RouteError(f"{p}:{i}: not a number in {','.join(row)!r}") from None
        if not np.all(np.isfinite(v)):
            raise RouteError(f"{p}:{i}: non-finite value")
        if vals and v[0] <= vals[-1][0]:
            raise RouteError(f"{p}:{i}: time {v[0]} does not increase")
        vals.append(v)
    if len(vals) < 2:
        raise RouteError(f"{p}: a route needs at least two poses")
    a = np.array(vals)
    R = T_world_map[:3, :3]
    xy = a[:, 1:3] @ R[:2, :2].T + T_world_map[:2, 3]
    yaw0 = float(np.arctan2(R[1, 0], R[0, 0]))
    yaw = np.unwrap(np.deg2rad(a[:, 3])) + yaw0
    pan = np.deg2rad(a[:, 4]) if a.shape[1] == 5 else np.zeros(len(a))
    return Route(t_s=a[:, 0] - a[0, 0], x_m=xy[:, 0], y_m=xy[:, 1], yaw_rad=yaw, pan_rad=pan)


def rig_pose(route: Route, t: float, mast_height_m: float, tilt_rad: float) -> np.ndarray:
    """T_world_rig: the camera rig body frame (x fwd, y left, z up) at time t; ``tilt_rad`` the
    mount's own tilt, to which the head's (:meth:`Route.tilt`) adds."""
    x, y, yaw = route.base_pose(t)
    T_world_base = make_transform(rot_z(yaw), [x, y, 0.0])
    R = rot_z(route.pan(t)) @ rot_y(-(tilt_rad + route.tilt(t)))
    T_base_rig = make_transform(R, [0.0, 0.0, mast_height_m])
    return T_world_base @ T_base_rig
