"""sim/motion/route.py: the tour's base path and the camera's pan, stepped (the default) or swept.

Everything here is computed from the route alone (no rendering): the camera's angle is the
rig's yaw, ``sim.motion.route.rig_pose``, sampled finely or at the frame times.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.motion.route import RobotSpec, Route, rig_pose, route_from_tour
from sim.motion.tour import plan_tour
from sim.scenario import ScenarioError, apply_settings, load_scenario, parse_scenario
from sim.world.maze import find_maze, load_maze

MAST_HEIGHT_M = 0.5
DEFAULT_SWEEP_DURATION_S = 119.0  # the default trial's route before issue 57 (sweep mode)


def _route(settings: list[str] = ()) -> tuple[Route, RobotSpec, list[tuple[int, int]]]:
    sc = apply_settings(load_scenario("default"), list(settings))
    maze = load_maze(find_maze(sc.resolve(sc.maze.file)))
    cells = plan_tour(maze, maze.start_cell)
    return route_from_tour(maze, cells, sc.robot, maze.start_heading_rad), sc.robot, cells


def _camera_yaw_deg(route: Route, t: np.ndarray) -> np.ndarray:
    """The camera rig's heading in the world (tilt 0: base yaw plus pan), unwrapped."""
    R = [rig_pose(route, float(ti), MAST_HEIGHT_M, 0.0)[:3, :3] for ti in t]
    return np.rad2deg(np.unwrap([np.arctan2(r[1, 0], r[0, 0]) for r in R]))


def _camera_rate_dps(route: Route, t: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """|d(camera yaw)/dt| at times t by a central difference over 2 h."""
    return np.abs(_camera_yaw_deg(route, t + h) - _camera_yaw_deg(route, t - h)) / (2 * h)


NO_TILTS = ["robot.pan.wall_tilts_deg=[]"]  # the pan alone: no tilted dwells at walls beside the cell


def test_default_pan_steps_through_the_angles_with_a_dwell_at_each():
    route, spec, cells = _route(NO_TILTS)
    p = spec.pan
    assert p.mode == "steps" and route.pan_rad is not None
    pan_deg = np.rad2deg(route.pan_rad)
    dt = np.diff(route.t_s)
    dpan = np.diff(pan_deg)
    # between keyframes the pan either holds (a dwell, or the base moving with the camera
    # ahead) or slews at exactly rate_dps
    moving = np.abs(dpan) > 1e-9
    assert np.allclose(np.abs(dpan[moving]) / dt[moving], p.rate_dps)
    # the dwells: segments of dwell_s where the pan holds at a step angle and the base is still
    held = ~moving & np.isclose(dt, p.dwell_s)
    held_at = pan_deg[:-1][held]
    assert set(np.round(held_at, 9)) == set(p.steps_deg)
    # one dwell at each angle per scan, one scan per distinct cell (revisits are not scanned)
    n_scans = len(set(cells))
    assert len(held_at) == n_scans * len(p.steps_deg)
    for angle in p.steps_deg:
        assert np.sum(np.isclose(held_at, angle)) == n_scans
    # sampled finely, the camera's angular rate is 0 inside each dwell and never above the
    # larger of the slew and the in-place turn rates (5% for the finite difference at corners)
    t_fine = np.arange(0.01, route.duration_s - 0.01, 0.02)
    rate = _camera_rate_dps(route, t_fine)
    assert rate.max() <= max(p.rate_dps, spec.yaw_rate_dps) * 1.05
    starts = route.t_s[:-1][held]
    inside = np.concatenate([np.linspace(s + 0.01, s + p.dwell_s - 0.01, 5) for s in starts])
    assert np.all(_camera_rate_dps(route, inside, h=1e-4) < 1e-6)


def test_the_base_is_still_while_the_camera_scans_and_drives_looking_ahead():
    route, _, _ = _route()
    pan, tilt = route.pan_rad, route.tilt_rad
    base_moves = (np.diff(route.x_m) != 0) | (np.diff(route.y_m) != 0) | (np.diff(route.yaw_rad) != 0)
    head_moves = (np.diff(pan) != 0) | (np.diff(tilt) != 0)
    assert not np.any(base_moves & head_moves)
    # whenever the base moves the camera looks straight ahead, level, at both ends of the segment
    assert np.all(pan[:-1][base_moves] == 0.0) and np.all(pan[1:][base_moves] == 0.0)
    assert np.all(tilt[:-1][base_moves] == 0.0) and np.all(tilt[1:][base_moves] == 0.0)
    # it starts and ends looking ahead; the stepped route needs no closing turn in place
    assert pan[0] == 0.0 and pan[-1] == 0.0


def test_sweep_mode_gives_the_route_before_issue_57():
    route, spec, cells = _route(["robot.pan.mode=sweep"])
    assert route.pan_rad is None
    assert route.duration_s == pytest.approx(DEFAULT_SWEEP_DURATION_S)
    t = np.linspace(0.0, route.duration_s, 97)
    want = spec.pan.amplitude_deg * np.sin(2 * np.pi * t / spec.pan.period_s)
    assert np.allclose([np.rad2deg(route.pan(ti)) for ti in t], want)
    # the same base path as the stepped route with its scans taken out, plus the closing turn
    stepped, s, _ = _route(NO_TILTS)
    p = s.pan
    scan_s = (abs(p.steps_deg[0]) + np.abs(np.diff(p.steps_deg)).sum() + abs(p.steps_deg[-1])) / p.rate_dps
    scan_s += len(p.steps_deg) * p.dwell_s
    spin_s = 360.0 / spec.yaw_rate_dps
    assert stepped.duration_s == pytest.approx(route.duration_s - spin_s + len(set(cells)) * scan_s)


def test_a_turtlebot_on_a_tour_does_not_stop_to_scan():
    """Its camera is fixed to the base: the pan settings do not apply."""
    sweep, _, _ = _route(["robot.pan.mode=sweep"])
    bot, _, _ = _route(["robot.kind=turtlebot"])
    assert bot.pan_rad is None and bot.duration_s == pytest.approx(sweep.duration_s)


def test_steps_with_no_dwell_and_a_single_angle():
    one = ["robot.pan.steps_deg=[90]", "robot.pan.dwell_s=0", "robot.pan.rate_dps=90"]
    route, spec, cells = _route([*one, *NO_TILTS])
    pan_deg = np.rad2deg(route.pan_rad)
    assert pan_deg.max() == pytest.approx(90.0) and pan_deg.min() == 0.0
    assert np.all(np.diff(route.t_s) > 0)  # no two keyframes at one time
    sweep, s, _ = _route(["robot.pan.mode=sweep"])
    assert route.duration_s == pytest.approx(sweep.duration_s - 360.0 / s.yaw_rate_dps + len(set(cells)) * 2.0)


def test_the_head_looks_down_and_up_each_wall_beside_the_cell_and_nowhere_else():
    """At a pan step that faces a wall of the cell the head also dwells at each wall tilt; at a
    step that faces an opening (or between the grid's directions) it does not."""
    from sim.motion.route import walled_steps

    route, spec, cells = _route()
    p = spec.pan
    sc = load_scenario("default")
    maze = load_maze(find_maze(sc.resolve(sc.maze.file)))
    steps = np.deg2rad(p.steps_deg)
    # the grid's four directions: +-90 and 0 can face a wall, +-45 never do
    first = walled_steps(maze, cells[0], maze.start_heading_rad, steps)
    assert not first[1] and not first[3]
    n_walled = 0
    yaw = maze.start_heading_rad
    seen: set = set()
    for cell in cells:  # the walls each first visit faces, by the heading the route has there
        if cell in seen:
            continue
        seen.add(cell)
        cx, cy = maze.cell_center(*cell)
        yaw = float(route.yaw_rad[int(np.argmin(np.abs(route.x_m - cx) + np.abs(route.y_m - cy)))])
        n_walled += sum(walled_steps(maze, cell, yaw, steps))
    tilt_deg = np.rad2deg(route.tilt_rad)
    dt = np.diff(route.t_s)
    held = np.isclose(dt, p.dwell_s) & (np.diff(tilt_deg) == 0) & (np.diff(route.pan_rad) == 0)
    tilted = held & (tilt_deg[:-1] != 0)
    assert n_walled > 0
    for tilt in p.wall_tilts_deg:  # one dwell at each wall tilt per wall faced
        assert np.sum(np.isclose(tilt_deg[:-1][tilted], tilt)) == n_walled
    # tilted dwells only at the steps that face the grid's directions
    pans = np.round(np.rad2deg(route.pan_rad[:-1][tilted]), 6)
    assert set(pans) <= {-90.0, 0.0, 90.0}
    # the camera looks up at a positive tilt: its optical axis (rig x) has a positive z
    k = int(np.flatnonzero(tilted & (tilt_deg[:-1] > 0))[0])
    R = rig_pose(route, float(route.t_s[k]) + 0.01, MAST_HEIGHT_M, 0.0)[:3, :3]
    assert R[2, 0] == pytest.approx(np.sin(np.deg2rad(tilt_deg[k])))
    # each wall costs the tilts' dwells and their slews (down 25, up 50; levelling again rides on
    # the next pan slew, both axes turning at once)
    plain, _, _ = _route(NO_TILTS)
    extra = n_walled * (len(p.wall_tilts_deg) * p.dwell_s + (25 + 50) / p.rate_dps)
    assert route.duration_s == pytest.approx(plain.duration_s + extra)


@pytest.mark.parametrize(
    "text, message",
    [
        ("robot: {pan: {mode: spin}}\n", "x.yaml:1: robot.pan.mode: expected one of 'sweep', 'steps'"),
        ("robot: {pan: {steps_deg: []}}\n", "x.yaml:1: robot.pan: steps_deg: mode 'steps' needs at least one"),
        ("robot: {pan: {steps_deg: [0, 200]}}\n", "robot.pan.steps_deg: expected a value >= -180 and <= 180"),
        ("robot: {pan: {dwell_s: -1}}\n", "robot.pan.dwell_s: expected a value >= 0"),
        ("robot: {pan: {rate_dps: 0}}\n", "robot.pan.rate_dps: expected a value > 0"),
        ("robot: {pan: {period_s: 0}}\n", "robot.pan.period_s: expected a value > 0"),
        ("robot: {pan: {dwel_s: 1}}\n", "robot.pan.dwel_s: unknown key"),
    ],
)
def test_bad_pan_settings_give_one_line_errors_naming_the_key(text, message):
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "x.yaml")
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_an_empty_step_list_is_fine_for_a_sweep():
    sc = parse_scenario("robot: {pan: {mode: sweep, steps_deg: []}}\n", "x.yaml")
    assert sc.robot.pan.mode == "sweep"


@pytest.mark.parametrize("kind", ["keyframes", "sweep", "none"], ids=["pan from keyframes", "swept pan", "no pan"])
def test_pans_at_many_times_equal_pan_at_each_bit_for_bit(kind):
    # Route.pans is Simulation._tracker_poses' one-array form of Route.pan (issue 62): the T265's
    # 200 Hz poses must not move by a rounding step, or a trial's pois.csv would change
    rng = np.random.default_rng(3)
    k = np.arange(12.0)
    extra = {"keyframes": {"pan_rad": rng.normal(size=12)}, "sweep": {"pan_amplitude_rad": 0.7}, "none": {}}[kind]
    route = Route(t_s=k, x_m=k * 0.1, y_m=k * 0.0, yaw_rad=k * 0.0, **extra)
    t = np.sort(rng.uniform(-1.0, 14.0, 20_000))
    assert np.array_equal(route.pans(t), [route.pan(float(ti)) for ti in t])
