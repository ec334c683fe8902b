"""The TurtleBot goal arena ([Bouda2025]_ section 1, tasks 2 and 3), laid out from the seed.

The document's task: a TurtleBot kicks a yellow ball between two blue pillars (the
goal) at least 700 mm apart. The ball lies at most c off the goal's axis and a to b
before the goal line; the robot starts d to e from the ball's centre; any number of
pillars of other colours may stand behind the goal; task 3 adds up to two obstacles
before the line, always leaving a path at least 600 mm wide from the ball to the goal.
:class:`ArenaGenerate` (below) holds the figures (task 3's by default).

Layout, world frame (z up, metres): an open floor ``[0, W] x [0, H]`` inside low
boundary walls (a :class:`sim.world.maze.Maze` of ``ARENA_CELL_M`` cells with no inner
walls, so the scene builder, the map and the lights treat it like any maze). The goal
line is ``x = x_g = W - behind_goal_m``; the goal's axis is ``y = y_c`` and the goal
pillars stand at ``(x_g, y_c -+ w / 2)``.

Draws, in this order, each from the scenario's generator ``rng``: goal width w and
centre y_c; the ball's distance a and offset c; the number of obstacles and, for each,
positions until one fits; the number of other pillars, their colours and positions;
the robot's start (distance, bearing, heading jitter) until the kick point can be
reached from it. The same seed gives the same arena.

Constraints kept (the tests check them over many seeds):

* the ball's centre is ``a`` before the goal line and ``|c|`` off the axis;
* every obstacle (an axis-aligned cube, not a POI) lies between the ball and the goal
  line and at least ``min_path_width_m / 2`` from the segment joining the ball's centre
  to the goal's centre: a straight corridor ``min_path_width_m`` wide stays free from
  the ball through the goal (stronger than the document's "a path exists");
* other pillars stand behind the goal line, every two pillars (goal ones included) at
  least ``min_pillar_spacing_m`` apart (centre to centre);
* the robot starts within ``robot_ball_distance_m`` of the ball's centre, in front of
  the goal line, clear of everything by its radius, facing the ball to within
  ``START_HEADING_JITTER_DEG``, and a clear path leads from there to the kick point
  (``KICK_STANDOFF_M`` behind the ball on its line to the goal's centre).

Reference points (what the ground truth lists): a pillar's is on its axis at half its
height, the ball's is its centre (maze_assets/models.py).

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from maze_assets.models import BALL_DIAMETER_M, PILLAR_DIAMETER_M, PILLAR_HEIGHT_M
from maze_assets.objects import PlacedObject
from sim.world.arena_path import FloorPlan, plan_path, point_box_distance, segment_box_distance
from sim.world.maze import Maze, MazeSettings

ARENA_CELL_M = 0.5  # the arena's floor is a grid of these cells (its walls are pieces this long)


def _range(name: str, lo: float, hi: float, *, positive: bool = False) -> None:
    if not lo <= hi or lo < 0 or (positive and lo <= 0):
        bound = "0 < low" if positive else "0 <= low"
        raise ValueError(f"{name}: expected [low, high] with {bound} <= high, got [{lo}, {hi}]")


@dataclass(kw_only=True)
class ArenaGenerate:
    """The TurtleBot goal arena ([Bouda2025]_ section 1, tasks 2 and 3), laid out from the seed.

    An open floor ``size_m`` (x by y) inside low boundary walls; the goal, two blue
    pillars ``goal_width_m`` apart, ``behind_goal_m`` before the +x wall with its axis
    along x; the ball within ``ball_axis_offset_m`` (c) of the axis and
    ``ball_goal_distance_m`` (a..b) before the goal line; ``obstacles`` cubes of side
    ``obstacle_size_m`` between the ball and the goal line that always leave a corridor
    ``min_path_width_m`` wide from the ball to the goal; ``other_pillars`` red or green
    pillars behind the goal, every two pillars at least ``min_pillar_spacing_m`` apart;
    the robot starting ``robot_ball_distance_m`` (d..e) from the ball, facing roughly
    towards it. Defaults are task 3's figures; task 2's are ``ball_axis_offset_m: 0.15``,
    ``ball_goal_distance_m: [0.5, 1.5]``, ``obstacles: [0, 0]``. Counts and ranges are
    drawn uniformly.
    """

    size_m: tuple[float, float] = (6.0, 5.0)
    boundary_wall_height_m: float = 0.15  # below the camera (0.3 m) and the pillars: never hides one
    goal_width_m: tuple[float, float] = (0.7, 1.0)  # between the blue pillars' centres; "at least 700 mm"
    ball_axis_offset_m: float = 0.3  # c
    ball_goal_distance_m: tuple[float, float] = (0.5, 2.0)  # a..b
    obstacles: tuple[int, int] = (0, 2)  # "up to two obstacles before the line"
    obstacle_size_m: float = 0.3
    min_path_width_m: float = 0.6  # "a path at least 600 mm wide from the ball to the goal"
    other_pillars: tuple[int, int] = (2, 4)  # "any number of pillars behind the goal"
    min_pillar_spacing_m: float = 0.3
    robot_ball_distance_m: tuple[float, float] = (0.7, 2.5)  # d..e
    behind_goal_m: float = 1.5  # floor between the goal line and the +x wall

    def __post_init__(self) -> None:
        for i, v in enumerate(self.size_m):
            if v <= 0 or abs(v / ARENA_CELL_M - round(v / ARENA_CELL_M)) > 1e-9:
                raise ValueError(f"size_m[{i}]: expected a positive multiple of {ARENA_CELL_M} m, got {v}")
        for name in ("boundary_wall_height_m", "obstacle_size_m", "min_path_width_m", "behind_goal_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: expected a positive number, got {getattr(self, name)}")
        if self.ball_axis_offset_m < 0 or self.min_pillar_spacing_m < 0:
            raise ValueError("ball_axis_offset_m and min_pillar_spacing_m: expected numbers >= 0")
        _range("goal_width_m", *self.goal_width_m, positive=True)
        _range("ball_goal_distance_m", *self.ball_goal_distance_m, positive=True)
        _range("robot_ball_distance_m", *self.robot_ball_distance_m, positive=True)
        _range("obstacles", *self.obstacles)
        _range("other_pillars", *self.other_pillars)
        if self.goal_width_m[0] <= self.min_path_width_m:
            raise ValueError(
                f"goal_width_m: the goal ({self.goal_width_m[0]} m) must be wider than min_path_width_m "
                f"({self.min_path_width_m} m)"
            )
        if self.behind_goal_m >= self.size_m[0]:
            raise ValueError(
                f"behind_goal_m: {self.behind_goal_m} m leaves no field in a {self.size_m[0]} m floor"
            )


WALL_THICKNESS_M = 0.05
GOAL_SIDE_MARGIN_M = 1.5  # the goal's centre stays this far from the side walls (less on a narrow floor)
WALL_MARGIN_M = 0.3  # pillars and obstacles keep this far from the walls (centre to wall face, at least)
BEHIND_GOAL_MIN_M = 0.3  # other pillars stand at least this far behind the goal line
OBSTACLE_GAP_M = 0.1  # free gap between an obstacle and a goal pillar or another obstacle
OBSTACLE_SIDE_M = 1.5  # obstacles are drawn within this distance of the goal's axis
ROBOT_RADIUS_M = 0.18  # a TurtleBot 2 (Kobuki) is 354 mm across
ROBOT_GAP_M = 0.05  # extra clearance the robot keeps from everything when planning
KICK_STANDOFF_M = 0.45  # the kick point: this far behind the ball's centre, on its line to the goal
START_HEADING_JITTER_DEG = 30.0  # "facing roughly towards" the ball
MAX_TRIES = 500


class ArenaError(ValueError):
    """An arena that cannot be laid out with the figures asked for (one line)."""


@dataclass(kw_only=True)
class Obstacle:
    """An axis-aligned cube standing on the floor (not a POI): centre (x, y), side ``size_m``."""

    name: str
    center_xy: np.ndarray
    size_m: float

    @property
    def lo(self) -> np.ndarray:
        return self.center_xy - self.size_m / 2

    @property
    def hi(self) -> np.ndarray:
        return self.center_xy + self.size_m / 2

    def corners(self) -> np.ndarray:
        """(4, 2) corners, counter-clockwise from (lo, lo)."""
        lo, hi = self.lo, self.hi
        return np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])


@dataclass(kw_only=True)
class ArenaLayout:
    """A laid-out arena: floor, POIs (goal pillars, ball, other pillars), obstacles, start."""

    floor: Maze
    objects: list[PlacedObject]
    obstacles: list[Obstacle]
    goal_posts_xy: np.ndarray  # (2, 2): the blue pillars, -y one first
    ball_xy: np.ndarray
    start_xy: np.ndarray
    start_yaw_rad: float
    kick_xy: np.ndarray
    path_xy: list[np.ndarray]  # planned legs from the start to the kick point
    spec: ArenaGenerate

    @property
    def goal_center_xy(self) -> np.ndarray:
        return self.goal_posts_xy.mean(axis=0)

    @property
    def goal_line_x(self) -> float:
        return float(self.goal_posts_xy[0, 0])

    @property
    def goal_heading_rad(self) -> float:
        """Heading from the kick point toward the goal's centre."""
        d = self.goal_center_xy - self.kick_xy
        return float(math.atan2(d[1], d[0]))


def floor_maze(spec: ArenaGenerate, name: str, start_xy: np.ndarray, start_yaw: float) -> Maze:
    """An open floor: ``ARENA_CELL_M`` cells, walls on the boundary only."""
    W, H = spec.size_m
    cols, rows = round(W / ARENA_CELL_M), round(H / ARENA_CELL_M)
    h = np.zeros((rows + 1, cols), dtype=bool)
    v = np.zeros((rows, cols + 1), dtype=bool)
    h[0, :] = h[rows, :] = True
    v[:, 0] = v[:, cols] = True
    settings = MazeSettings(
        cell_size_m=ARENA_CELL_M, wall_height_m=spec.boundary_wall_height_m, wall_thickness_m=WALL_THICKNESS_M
    )
    col = min(int(start_xy[0] // ARENA_CELL_M), cols - 1)
    row = min(rows - 1 - int(start_xy[1] // ARENA_CELL_M), rows - 1)
    return Maze(
        rows=rows,
        cols=cols,
        h_walls=h,
        v_walls=v,
        settings=settings,
        start_cell=(row, col),
        start_heading_rad=start_yaw,
        name=name,
    )


def _pillar(obj_id: int, type_: str, xy: np.ndarray) -> PlacedObject:
    return PlacedObject(
        id=obj_id,
        type=type_,
        position=np.array([xy[0], xy[1], PILLAR_HEIGHT_M / 2]),
        mount="floor",
        size_m=PILLAR_HEIGHT_M,
    )


def _uniform(rng: np.random.Generator, lo_hi: tuple[float, float]) -> float:
    return float(rng.uniform(lo_hi[0], lo_hi[1]))


def _count(rng: np.random.Generator, lo_hi: tuple[int, int]) -> int:
    return int(rng.integers(lo_hi[0], lo_hi[1] + 1))


def generate_arena(spec: ArenaGenerate, rng: np.random.Generator, name: str = "arena") -> ArenaLayout:
    """Lay out an arena from ``spec`` with draws from ``rng`` (see the module docstring)."""
    W, H = spec.size_m
    x_g = W - spec.behind_goal_m
    r_ball = BALL_DIAMETER_M / 2
    r_pillar = PILLAR_DIAMETER_M / 2
    robot_r = ROBOT_RADIUS_M + ROBOT_GAP_M
    if x_g - spec.ball_goal_distance_m[1] - KICK_STANDOFF_M - robot_r < WALL_THICKNESS_M:
        raise ArenaError(
            f"size_m: a {W} m floor with behind_goal_m {spec.behind_goal_m} leaves no room for the ball "
            f"{spec.ball_goal_distance_m[1]} m before the goal line and the robot behind it"
        )

    # goal and ball
    w = _uniform(rng, spec.goal_width_m)
    margin = min(GOAL_SIDE_MARGIN_M, H / 2)
    y_c = float(rng.uniform(margin, H - margin))
    if y_c - w / 2 - r_pillar < WALL_THICKNESS_M or y_c + w / 2 + r_pillar > H - WALL_THICKNESS_M:
        raise ArenaError(f"size_m: a {H} m wide floor cannot hold a {w:.2f} m goal")
    posts = np.array([[x_g, y_c - w / 2], [x_g, y_c + w / 2]])
    goal_c = posts.mean(axis=0)
    a = _uniform(rng, spec.ball_goal_distance_m)
    c = float(rng.uniform(-spec.ball_axis_offset_m, spec.ball_axis_offset_m))
    ball = np.array([x_g - a, y_c + c])

    # obstacles: between the ball and the goal line, clear of the ball-to-goal corridor
    obstacles: list[Obstacle] = []
    s = spec.obstacle_size_m
    half_path = spec.min_path_width_m / 2
    n_obstacles = _count(rng, spec.obstacles)
    x_lo, x_hi = ball[0], x_g - s / 2 - OBSTACLE_GAP_M
    y_lo = max(WALL_MARGIN_M + s / 2, y_c - OBSTACLE_SIDE_M)
    y_hi = min(H - WALL_MARGIN_M - s / 2, y_c + OBSTACLE_SIDE_M)
    for k in range(n_obstacles):
        for _ in range(MAX_TRIES):
            xy = np.array([rng.uniform(x_lo, max(x_lo, x_hi)), rng.uniform(y_lo, y_hi)])
            cand = Obstacle(name=f"obstacle_{k}", center_xy=xy, size_m=s)
            if x_hi < x_lo or segment_box_distance(ball, goal_c, cand.lo, cand.hi) < half_path:
                continue
            if np.any(point_box_distance(posts, cand.lo, cand.hi) < r_pillar + OBSTACLE_GAP_M):
                continue
            if any(np.max(np.abs(o.center_xy - xy)) < s + OBSTACLE_GAP_M for o in obstacles):
                continue
            obstacles.append(cand)
            break
        else:
            raise ArenaError(
                f"obstacles: could not place obstacle {k + 1} of {n_obstacles} between the ball and the goal "
                f"with a {spec.min_path_width_m} m path free; ask for fewer or smaller (obstacle_size_m)"
            )

    # pillars: the goal's two, then the others behind the goal line
    objects = [_pillar(0, "pillar-blue", posts[0]), _pillar(1, "pillar-blue", posts[1])]
    objects.append(
        PlacedObject(
            id=2, type="ball", position=np.array([ball[0], ball[1], r_ball]), mount="floor", size_m=2 * r_ball
        )
    )
    pillar_xy = [posts[0], posts[1]]
    n_other = _count(rng, spec.other_pillars)
    colours = ["pillar-red" if rng.random() < 0.5 else "pillar-green" for _ in range(n_other)]
    bx_lo, bx_hi = x_g + BEHIND_GOAL_MIN_M, W - WALL_MARGIN_M
    for k, colour in enumerate(colours):
        for _ in range(MAX_TRIES):
            xy = np.array([rng.uniform(bx_lo, max(bx_lo, bx_hi)), rng.uniform(WALL_MARGIN_M, H - WALL_MARGIN_M)])
            if bx_hi < bx_lo:
                continue
            if all(np.linalg.norm(xy - p) >= spec.min_pillar_spacing_m for p in pillar_xy):
                pillar_xy.append(xy)
                objects.append(_pillar(len(objects), colour, xy))
                break
        else:
            raise ArenaError(
                f"other_pillars: could not place pillar {k + 1} of {n_other} behind the goal "
                f"{spec.min_pillar_spacing_m} m from the others; ask for fewer or make behind_goal_m larger"
            )

    # the robot's start, and the path from it to the kick point
    plan = FloorPlan(
        size_m=(W, H),
        discs=[(ball, r_ball)] + [(p, r_pillar) for p in pillar_xy],
        boxes=[(o.lo, o.hi) for o in obstacles],
        wall_m=WALL_THICKNESS_M / 2,
    )
    u = (goal_c - ball) / np.linalg.norm(goal_c - ball)
    kick = ball - KICK_STANDOFF_M * u
    jitter = math.radians(START_HEADING_JITTER_DEG)
    for _ in range(MAX_TRIES):
        d = _uniform(rng, spec.robot_ball_distance_m)
        bearing = float(rng.uniform(-math.pi, math.pi))
        turn = float(rng.uniform(-jitter, jitter))
        start = ball + d * np.array([math.cos(bearing), math.sin(bearing)])
        if start[0] > x_g - robot_r or plan.clearance(start) < robot_r:
            continue
        path = plan_path(plan, start, kick, radius_m=robot_r)
        if path is None:
            continue
        yaw = math.atan2(-math.sin(bearing), -math.cos(bearing)) + turn  # facing the ball, +- jitter
        break
    else:
        raise ArenaError(
            f"robot_ball_distance_m: no start {spec.robot_ball_distance_m[0]}-{spec.robot_ball_distance_m[1]} m "
            "from the ball leaves the robot a free path to it; make the floor larger"
        )
    return ArenaLayout(
        floor=floor_maze(spec, name, start, yaw),
        objects=objects,
        obstacles=obstacles,
        goal_posts_xy=posts,
        ball_xy=ball,
        start_xy=start,
        start_yaw_rad=float(yaw),
        kick_xy=kick,
        path_xy=path,
        spec=spec,
    )
