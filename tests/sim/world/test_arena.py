"""The TurtleBot goal arena ([Bouda2025]_ section 1, tasks 2 and 3): its constraints hold for every
seed, the same seed lays out the same arena, and the scenario schema refuses bad figures.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
import pytest

from maze_assets.models import BALL_DIAMETER_M, PILLAR_DIAMETER_M, PILLAR_HEIGHT_M
from sim.motion.arena_route import arena_route
from sim.motion.route import RobotSpec
from sim.scenario import ScenarioError, load_scenario, parse_scenario
from sim.world.arena import (
    ROBOT_RADIUS_M,
    START_HEADING_JITTER_DEG,
    ArenaError,
    ArenaGenerate,
    generate_arena,
)

SEEDS = range(120)  # about 2 ms each; covers 0, 1 and 2 obstacles and 2-4 pillars many times
TASK2 = ArenaGenerate(ball_axis_offset_m=0.15, ball_goal_distance_m=(0.5, 1.5), obstacles=(0, 0))
GRID_M = 0.02  # the corridor check's grid: 2 cm, well under the 0.6 m path it looks for


def _layouts(spec: ArenaGenerate):
    return [(seed, generate_arena(spec, np.random.default_rng(seed))) for seed in SEEDS]


@pytest.fixture(scope="module")
def task3():
    return _layouts(ArenaGenerate())


def _corridor_exists(layout, half_width_m: float) -> bool:
    """Whether a disc of radius ``half_width_m`` can move from the ball to the goal's centre
    without touching an obstacle or a goal pillar: breadth-first search over a grid of the
    field (an independent check of the generator's straight-corridor rule)."""
    W, H = layout.spec.size_m
    xs = np.arange(0.0, W, GRID_M) + GRID_M / 2
    ys = np.arange(0.0, H, GRID_M) + GRID_M / 2
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(X.shape, bool)
    for ob in layout.obstacles:
        dx = np.maximum(np.abs(X - ob.center_xy[0]) - ob.size_m / 2, 0.0)
        dy = np.maximum(np.abs(Y - ob.center_xy[1]) - ob.size_m / 2, 0.0)
        free &= np.hypot(dx, dy) >= half_width_m
    for px, py in layout.goal_posts_xy:
        free &= np.hypot(X - px, Y - py) >= half_width_m + PILLAR_DIAMETER_M / 2

    def cell(p):
        return int(p[0] // GRID_M), int(p[1] // GRID_M)

    start, goal = cell(layout.ball_xy), cell(layout.goal_center_xy)
    if not (free[start] and free[goal]):
        return False
    seen = {start}
    queue = deque([start])
    while queue:
        c = queue.popleft()
        if c == goal:
            return True
        for d in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            n = (c[0] + d[0], c[1] + d[1])
            if 0 <= n[0] < free.shape[0] and 0 <= n[1] < free.shape[1] and free[n] and n not in seen:
                seen.add(n)
                queue.append(n)
    return False


def _check(layout, spec: ArenaGenerate) -> None:
    W, H = spec.size_m
    x_g = W - spec.behind_goal_m
    posts = layout.goal_posts_xy
    # the goal: two blue pillars on the goal line, 0.7-1.0 m apart ("at least 700 mm")
    width = float(np.linalg.norm(posts[1] - posts[0]))
    assert spec.goal_width_m[0] - 1e-9 <= width <= spec.goal_width_m[1] + 1e-9 and width >= 0.7
    assert np.allclose(posts[:, 0], x_g)
    blue = [o for o in layout.objects if o.type == "pillar-blue"]
    assert sorted(map(tuple, (o.position[:2] for o in blue))) == sorted(map(tuple, posts))
    # the ball: at most c off the axis, a..b before the goal line, on the floor
    (ball,) = [o for o in layout.objects if o.type == "ball"]
    axis_y = posts[:, 1].mean()
    assert abs(ball.position[1] - axis_y) <= spec.ball_axis_offset_m + 1e-9
    a = x_g - ball.position[0]
    assert spec.ball_goal_distance_m[0] - 1e-9 <= a <= spec.ball_goal_distance_m[1] + 1e-9
    assert ball.position[2] == pytest.approx(BALL_DIAMETER_M / 2)
    # obstacles: 0..2, between the ball and the goal line, a 0.6 m path free from ball to goal
    lo, hi = spec.obstacles
    assert lo <= len(layout.obstacles) <= hi
    for ob in layout.obstacles:
        assert ball.position[0] - 1e-9 <= ob.center_xy[0] <= x_g
    assert _corridor_exists(layout, spec.min_path_width_m / 2)
    # other pillars: 2..4, red or green, behind the goal line; all pillars 0.3 m apart
    others = [o for o in layout.objects if o.type in ("pillar-red", "pillar-green")]
    assert spec.other_pillars[0] <= len(others) <= spec.other_pillars[1]
    assert all(o.position[0] > x_g for o in others)
    pillars = [o.position[:2] for o in layout.objects if o.type.startswith("pillar-")]
    for i, p in enumerate(pillars):
        for q in pillars[i + 1 :]:
            assert np.linalg.norm(p - q) >= spec.min_pillar_spacing_m - 1e-9
    assert all(o.position[2] == pytest.approx(PILLAR_HEIGHT_M / 2) for o in layout.objects if o.type != "ball")
    # everything inside the walls
    for o in layout.objects:
        assert 0.0 < o.position[0] < W and 0.0 < o.position[1] < H
    # the robot: d..e from the ball's centre, facing it within the jitter, clear of everything
    d = float(np.linalg.norm(layout.start_xy - layout.ball_xy))
    assert spec.robot_ball_distance_m[0] - 1e-9 <= d <= spec.robot_ball_distance_m[1] + 1e-9
    to_ball = math.atan2(*(layout.ball_xy - layout.start_xy)[::-1])
    off = (layout.start_yaw_rad - to_ball + math.pi) % (2 * math.pi) - math.pi
    assert abs(off) <= math.radians(START_HEADING_JITTER_DEG) + 1e-9
    for ob in layout.obstacles:
        gap = np.maximum(np.abs(layout.start_xy - ob.center_xy) - ob.size_m / 2, 0.0)
        assert np.hypot(*gap) >= ROBOT_RADIUS_M
    assert (
        ROBOT_RADIUS_M <= layout.start_xy[0] <= x_g and ROBOT_RADIUS_M <= layout.start_xy[1] <= H - ROBOT_RADIUS_M
    )


def test_task3_constraints_hold_for_every_seed(task3):
    for seed, layout in task3:
        try:
            _check(layout, ArenaGenerate())
        except AssertionError as e:
            raise AssertionError(f"seed {seed}: {e}") from e
    # the draws cover the ranges: every obstacle count and pillar count, both colours
    assert {len(lay.obstacles) for _, lay in task3} == {0, 1, 2}
    assert {sum(o.type != "ball" for o in lay.objects) - 2 for _, lay in task3} == {2, 3, 4}
    assert {o.type for _, lay in task3 for o in lay.objects} == {
        "pillar-blue",
        "pillar-red",
        "pillar-green",
        "ball",
    }


def test_task2_figures():
    for seed, layout in _layouts(TASK2):
        assert layout.obstacles == [], seed
        _check(layout, TASK2)


def test_same_seed_same_arena_other_seed_other():
    def key(layout):
        return (
            [(o.type, o.position.tobytes()) for o in layout.objects],
            [o.center_xy.tobytes() for o in layout.obstacles],
            layout.start_xy.tobytes(),
            layout.start_yaw_rad,
        )

    a = generate_arena(ArenaGenerate(), np.random.default_rng(11))
    b = generate_arena(ArenaGenerate(), np.random.default_rng(11))
    c = generate_arena(ArenaGenerate(), np.random.default_rng(12))
    assert key(a) == key(b) and key(a) != key(c)


def test_route_turns_drives_to_the_ball_and_turns_again(task3):
    spec = RobotSpec(kind="turtlebot", route="arena", speed_mps=0.2, yaw_rate_dps=20.0)
    for seed, layout in task3[:30]:
        r = arena_route(layout, spec)
        assert 40.0 <= r.duration_s <= 90.0, seed  # 400-900 frames at 10 fps
        # a full turn on the spot first, another at the end
        assert r.yaw_rad[1] - r.yaw_rad[0] == pytest.approx(2 * math.pi)
        assert r.yaw_rad[-1] - r.yaw_rad[-3] == pytest.approx(2 * math.pi)
        x, y, yaw = r.base_pose(r.duration_s)
        assert np.allclose([x, y], layout.kick_xy)  # ends behind the ball ...
        assert np.isclose(
            (yaw - layout.goal_heading_rad + math.pi) % (2 * math.pi) - math.pi, 0.0
        )  # facing the goal
        assert r.pan_amplitude_rad == 0.0 and r.pan_rad is None


def test_impossible_figures_are_clear_errors():
    with pytest.raises(ArenaError, match="size_m: .* no room for the ball"):
        generate_arena(ArenaGenerate(size_m=(3.0, 5.0)), np.random.default_rng(0))
    with pytest.raises(ArenaError, match="other_pillars: could not place"):
        generate_arena(ArenaGenerate(other_pillars=(60, 60)), np.random.default_rng(0))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "arena:\n  generate:\n    size_m: [6.2, 5]\n",
            "x.yaml:2: arena.generate: size_m[0]: expected a positive multiple",
        ),
        (
            "arena:\n  generate:\n    goal_width_m: [1.0, 0.7]\n",
            "arena.generate: goal_width_m: expected [low, high]",
        ),
        ("arena:\n  generate:\n    goal_width_m: [0.5, 0.6]\n", "goal_width_m: the goal (0.5 m) must be wider"),
        (
            "arena:\n  generate:\n    obstacles: [0, 2.5]\n",
            "x.yaml:3: arena.generate.obstacles[1]: expected an integer",
        ),
        ("arena:\n  generate:\n    colour: blue\n", "x.yaml:3: arena.generate.colour: unknown key"),
        ("arena: {}\nmaze: {file: default}\nrobot: {route: arena}\n", "give no 'maze' or 'objects' with it"),
        ("arena: {}\n", "robot.route: 'tour' visits maze cells"),
        ("robot: {route: arena}\n", "robot.route: 'arena' drives the goal arena"),
        ("sensors: {pose_source: wheels}\n", "sensors.pose_source: 'wheels' needs robot.kind 'turtlebot'"),
        ("sensors: {pose_source: gps}\n", "x.yaml:1: sensors.pose_source: expected one of 't265', 'wheels'"),
        ("sensors: {wheel_odometry: {wheel_base_m: 0}}\n", "wheel_odometry: wheel_base_m: expected a positive"),
        ("objects: {generate: {counts: {ball: 1}}}\n", "counts: unknown type 'ball' (the arena's types"),
    ],
)
def test_bad_arena_scenarios_are_one_line_errors(text, message):
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "x.yaml")
    assert message in str(e.value) and "\n" not in str(e.value)


def test_shipped_turtlebot_goal_scenario():
    sc = load_scenario("turtlebot-goal")
    assert sc.arena is not None and sc.maze is None and sc.objects is None
    assert (sc.robot.kind, sc.robot.route, sc.sensors.pose_source, sc.rules) == (
        "turtlebot",
        "arena",
        "wheels",
        "turtlebot",
    )
    assert sc.arena.generate == ArenaGenerate()  # it spells out the task 3 defaults
    # a round trip through its own YAML keeps it
    assert parse_scenario(sc.to_yaml(), "again") == sc


@pytest.mark.slow
def test_arena_simulation_truth_mount_odometry_and_oracle(capfd):
    from poi.core.geometry import transform_points
    from poi.core.names import ARENA_TYPES, CLASSES
    from sim.oracle import oracle_for
    from sim.scenario import apply_settings
    from sim.simulator import Simulation

    sc = apply_settings(load_scenario("turtlebot-goal"), ["robot.max_duration_s=3"])
    with Simulation(sc) as sim:
        assert all(w.number == 0 for w in sim.world.data.warning)
        assert "WARNING" not in "".join(capfd.readouterr()).upper()
        # truth in the map frame: pillars at half their height on their axis, the ball at its centre
        truth = sim.truth_objects()
        assert {o.type for o in truth} <= set(ARENA_TYPES) and len(truth) == len(sim.arena.objects)
        for o in truth:
            z = BALL_DIAMETER_M / 2 if o.type == "ball" else PILLAR_HEIGHT_M / 2
            assert o.position_map[2] == pytest.approx(z)
            assert np.allclose(transform_points(sim.T_world_map, o.position_map), o.placed.position)
        # the map origin is the robot's start on the floor; the obstacles are drawn on the map
        assert np.allclose(sim.robot_path_map()[0], [0.0, 0.0])
        assert len(sim.walls_in_map()) == len(sim.maze.wall_segments()) + 4 * len(sim.arena.obstacles)
        # the tracker frame is the base: the camera 0.3 m above it, looking along its x axis
        T = sim.T_tracker_optical_nominal
        assert np.allclose(T[:3, 3], [0.0, 0.0, 0.30]) and np.allclose(T[:3, 2], [1.0, 0.0, 0.0])
        frame, ft = sim.frame(0)
        assert np.allclose(frame.pose, np.eye(4))  # odometry starts at the true start pose
        assert np.allclose(ft.T_map_tracker @ sim.T_tracker_optical_true, ft.T_map_camera)
        oracle = oracle_for(sim)
        oracle.set_truth(ft)
        dets = oracle.detect(frame)
        assert dets and {d.class_name for d in dets} <= set(ARENA_TYPES)
        for d in dets:
            assert d.class_probs.shape == (len(CLASSES),) and d.class_probs.sum() == pytest.approx(1.0)
        # the arena's pillars are thin: the arena's oracle keeps boxes narrower than the rescue 12 px
        assert oracle.settings.min_box_px < 12.0
        # later frames: the odometry has drifted from the truth, by centimetres
        frame, ft = sim.frame(sim.n_frames - 1)
        assert 0.0 <= np.linalg.norm(frame.pose[:2, 3] - ft.T_map_tracker[:2, 3]) < 0.05
        assert frame.pose[2, 3] == pytest.approx(0.0)  # the base stays on the floor
