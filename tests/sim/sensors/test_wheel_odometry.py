"""Wheel odometry of a differential-drive base: each error term does what it should, alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

from poi.core.geometry import make_transform, planar_pose, rot_z
from sim.sensors.wheel_odometry import WheelOdometrySpec, simulate_wheel_odometry

EXACT = dict(
    wheel_radius_error=0.0,
    wheel_radius_mismatch=0.0,
    wheel_base_error=0.0,
    slip_m_per_sqrt_m=0.0,
    slip_rad_per_sqrt_rad=0.0,
    slip_rad_per_sqrt_m=0.0,
)


def _poses(xyt: np.ndarray) -> list[np.ndarray]:
    return [make_transform(rot_z(t), [x, y, 0.0]) for x, y, t in xyt]


def _straight(length_m: float, n: int = 101, yaw: float = 0.3) -> list[np.ndarray]:
    s = np.linspace(0.0, length_m, n)
    return _poses(np.c_[1.0 + s * math.cos(yaw), 2.0 + s * math.sin(yaw), np.full(n, yaw)])


def _turn(angle_rad: float, n: int = 101) -> list[np.ndarray]:
    return _poses(np.c_[np.full(n, 1.0), np.full(n, 2.0), np.linspace(0.0, angle_rad, n)])


def _square(side_m: float = 2.0, steps: int = 40) -> list[np.ndarray]:
    """Drive a side, turn left 90 deg in place, four times (true poses every step)."""
    rows, x, y, th = [(0.0, 0.0, 0.0)], 0.0, 0.0, 0.0
    for _ in range(4):
        for _ in range(steps):
            x, y = x + side_m / steps * math.cos(th), y + side_m / steps * math.sin(th)
            rows.append((x, y, th))
        for _ in range(steps):
            th += (math.pi / 2) / steps
            rows.append((x, y, th))
    return _poses(np.array(rows))


def _run(T, seed=0, noise=True, **kw) -> list[np.ndarray]:
    spec = WheelOdometrySpec(**{**EXACT, **kw})
    track = simulate_wheel_odometry(T, np.arange(len(T)) * 0.1, spec, np.random.default_rng(seed), noise)
    assert track.confidence == ["high"] * len(T) and all(p is not None for p in track.poses)
    return track.poses


def _path_length(poses) -> float:
    p = np.array([P[:2, 3] for P in poses])
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


def test_no_error_when_noise_is_off_or_every_error_is_zero():
    T = _square()
    assert all(np.array_equal(a, b) for a, b in zip(_run(T, noise=False, wheel_radius_error=0.3), T, strict=True))
    # the integration itself is exact: with every error zero the true poses come back
    for a, b in zip(_run(T), T, strict=True):
        assert np.allclose(a, b, atol=1e-9)


def test_wheel_radius_error_scales_the_path():
    T = _straight(4.0)
    odo = _run(T, wheel_radius_error=0.05)
    assert _path_length(odo) == pytest.approx(1.05 * _path_length(T), rel=1e-9)
    # along the straight line, 5% long: 4.2 m from the start instead of 4 m
    assert np.linalg.norm(odo[-1][:2, 3] - odo[0][:2, 3]) == pytest.approx(4.2, rel=1e-9)
    # on a closed square the path is still 5% long (turns read 5% large too)
    Tsq = _square()
    assert _path_length(_run(Tsq, wheel_radius_error=0.05)) == pytest.approx(1.05 * _path_length(Tsq), rel=1e-9)


def test_wheel_base_error_gives_a_heading_error_proportional_to_the_turn():
    for angle in (math.pi / 2, 2 * math.pi):
        odo = _run(_turn(angle), wheel_base_error=0.02)
        turned = np.unwrap([planar_pose(P)[2] for P in odo])
        # the odometry divides by a wheel base 2% too large: it reads the turn 1/1.02 as large
        assert turned[-1] - turned[0] == pytest.approx(angle / 1.02, rel=1e-9)
        assert np.allclose(odo[-1][:2, 3], [1.0, 2.0])  # no translation from a turn in place
    # and driving straight is unaffected
    assert np.allclose(_run(_straight(3.0), wheel_base_error=0.02)[-1], _straight(3.0)[-1], atol=1e-9)


def test_wheel_radius_mismatch_curves_a_straight_run():
    b, m = 0.23, 0.004
    odo = _run(_straight(2.0), wheel_base_m=b, wheel_radius_mismatch=m)
    heading = planar_pose(odo[-1])[2] - 0.3
    # right wheel 0.4% larger: it travels farther than its encoder says, so the odometry
    # sees the left wheel ahead and a right turn of about m / b per metre
    assert heading == pytest.approx(-m / b * 2.0, rel=1e-3)


def test_slip_grows_with_the_square_root_of_distance_and_angle():
    # 400 runs each: the sample std is good to about 3.5% (1 / sqrt(2 * 400)); allow 12%
    d_err = [
        np.linalg.norm(
            _run(_straight(4.0), seed=s, slip_m_per_sqrt_m=0.01)[-1][:2, 3]
            - [1 + 4 * math.cos(0.3), 2 + 4 * math.sin(0.3)]
        )
        for s in range(400)
    ]
    assert np.sqrt(np.mean(np.square(d_err))) == pytest.approx(0.01 * math.sqrt(4.0), rel=0.12)
    th_err = [
        np.unwrap([planar_pose(P)[2] for P in _run(_turn(2 * math.pi), seed=s, slip_rad_per_sqrt_rad=0.02)])[-1]
        - 2 * math.pi
        for s in range(400)
    ]
    assert np.std(th_err) == pytest.approx(0.02 * math.sqrt(2 * math.pi), rel=0.12)
    assert abs(np.mean(th_err)) < 4 * 0.02 * math.sqrt(2 * math.pi) / math.sqrt(400)  # unbiased


def test_same_seed_same_track_other_seed_other():
    T = _square()
    spec = WheelOdometrySpec()  # the TurtleBot defaults: every term on
    a = simulate_wheel_odometry(T, np.arange(len(T)) * 0.1, spec, np.random.default_rng(4), True)
    b = simulate_wheel_odometry(T, np.arange(len(T)) * 0.1, spec, np.random.default_rng(4), True)
    c = simulate_wheel_odometry(T, np.arange(len(T)) * 0.1, spec, np.random.default_rng(5), True)
    assert all(np.array_equal(p, q) for p, q in zip(a.poses, b.poses, strict=True))
    assert not np.array_equal(a.poses[-1], c.poses[-1])
    assert np.array_equal(a.error_m, b.error_m) and a.error_m[0] == 0.0 and a.error_m[-1] > 0.0
