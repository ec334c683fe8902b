"""poi.estimation.slam_localizer: each landmark measurement is used once (the SLAM update, and
the tracker with the pose before that update)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from poi.config import SlamConfig
from poi.core.geometry import make_transform, planar_pose, rot_z
from poi.core.types import Observation
from poi.detectors.base import make_detection
from poi.estimation.slam_localizer import SlamLocalizer


def _obs(p_map, sigma=0.02) -> Observation:
    det = make_detection("valve", (100.0, 100.0, 120.0, 120.0), 0.9, source="test", class_probs=None)
    p = np.asarray(p_map, dtype=float)
    return Observation(
        detection=det,
        timestamp_s=0.0,
        position_map=p,
        R=sigma**2 * np.eye(3),
        position_cam=np.array([0.0, 0.0, 1.0]),
        Sigma_c=sigma**2 * np.eye(3),
        depth_m=1.0,
    )


def test_observations_are_mapped_with_the_pose_before_their_own_update():
    loc = SlamLocalizer(SlamConfig(n_min=0, start_sigma_m=1e-4, start_sigma_rad=1e-4, odometry_latency_s=0.0))
    T0 = np.eye(4)
    loc.step(T0, [_obs([2.0, 0.0, 0.5])], 0.0)  # the valve becomes a landmark at (2, 0)
    # odometry says the robot moved 0.5 m along x; the valve is seen 0.1 m off where the map has it
    T1 = make_transform(rot_z(0.0), [0.5, 0.0, 0.0])
    step = loc.step(T1, [_obs([2.1, 0.0, 0.5])], 1.0)  # 0.5 m/s: motion, not a jump
    slam = loc.slam
    before = np.array([0.5, 0.0, 0.0])  # the predicted pose: odometry exactly, the start being exact
    after = planar_pose(step.pose)
    assert after[0] < before[0] - 1e-3  # the update moved the robot back towards the valve's map position
    # the observation keeps its place relative to the odometry pose, moved by the predicted pose
    # (here the odometry pose itself), not by the updated one
    assert step.observations[0].position_map == pytest.approx([2.1, 0.0, 0.5], abs=1e-6)
    # (mapped with the updated pose it would have moved by the update: 2.1 - 0.08 m, towards the map)
    # and its covariance holds the predicted pose's: R + J P J^T with P the predicted covariance,
    # larger than the updated one
    assert step.observations[0].R[0, 0] > 0.02**2
    assert np.trace(slam.pose_covariance) < np.trace(step.observations[0].R)


def test_reported_poses_are_extrapolated_over_the_odometry_latency():
    # reported: (0, 0, 0) at 0 s, (0.05, 0, 0.1) at 0.1 s; with 10 ms latency the frame-time
    # pose is the second plus a tenth of the step: (0.055, 0, 0.11)
    cfg = SlamConfig(odometry_latency_s=0.01, start_sigma_m=1e-4, start_sigma_rad=1e-4)
    loc = SlamLocalizer(cfg)
    loc.step(np.eye(4), [], 0.0)
    step = loc.step(make_transform(rot_z(0.1), [0.05, 0.0, 0.0]), [], 0.1)
    assert loc.slam.pose == pytest.approx([0.055, 0.0, 0.11], abs=1e-5)
    # the frame's pose is the filter's; height, roll and pitch stay the reported ones
    assert planar_pose(step.pose) == pytest.approx([0.055, 0.0, 0.11], abs=1e-5)
    # latency 0: the pose as reported
    loc = SlamLocalizer(SlamConfig(odometry_latency_s=0.0, start_sigma_m=1e-4, start_sigma_rad=1e-4))
    loc.step(np.eye(4), [], 0.0)
    loc.step(make_transform(rot_z(0.1), [0.05, 0.0, 0.0]), [], 0.1)
    assert loc.slam.pose == pytest.approx([0.05, 0.0, 0.1], abs=1e-5)


def test_with_latency_the_filter_starts_on_the_first_pose_it_can_bring_to_its_frame_time():
    """Turning at 1 rad/s with 10 ms of latency, the first report is 0.01 rad behind its frame
    and nothing yet says how fast the robot turns: that frame keeps the odometry (observations
    as placed, no filter), and the filter starts at the next frame on the extrapolated pose
    with the start covariance, not 0.57 degrees off it."""
    cfg = SlamConfig(odometry_latency_s=0.01, start_sigma_m=1e-3, start_sigma_rad=5e-4)
    loc = SlamLocalizer(cfg)
    T0 = make_transform(rot_z(0.0), [0.0, 0.0, 0.0])
    first = loc.step(T0, [_obs([2.0, 0.0, 0.5])], 0.0)
    assert loc.slam is None and first.stale  # the pipeline drops its observations
    assert first.pose == pytest.approx(T0)
    r_first = first.observations[0].R
    assert r_first == pytest.approx(0.02**2 * np.eye(3))  # as placed: no pose covariance added
    second = loc.step(make_transform(rot_z(0.1), [0.0, 0.0, 0.0]), [], 0.1)  # 0.1 rad in 0.1 s
    assert not second.stale
    assert loc.slam.pose == pytest.approx([0.0, 0.0, 0.11], abs=1e-9)  # the frame's time
    assert np.sqrt(loc.slam.pose_covariance[2, 2]) == pytest.approx(5e-4, rel=1e-6)
    # without latency the first report is the frame's pose: the filter starts at once
    loc = SlamLocalizer(SlamConfig(odometry_latency_s=0.0))
    assert not loc.step(T0, [], 0.0).stale
    assert loc.slam is not None


def test_a_relocalisation_jump_is_not_taken_as_motion():
    # the robot stands still; the odometry jumps 1 m and 5 degrees in 0.1 s (10 m/s): the filter
    # keeps its pose (the last clean increment's motion: none yet), its covariance takes what a
    # change of speed and turn rate over the frame may miss (0.05 m/s and 0.25 rad/s sigma, 0.1 s),
    # not the jump's size, and the jump is counted
    cfg = SlamConfig(
        start_sigma_m=1e-3,
        start_sigma_rad=1e-3,
        odometry_latency_s=0.0,
        max_speed_m_s=1.5,
        sigma_xy_m=0.0,
        sigma_theta_rad=0.0,
        relocalisation_speed_sigma_m_s=0.05,
        relocalisation_turn_sigma_rad_s=0.25,
    )
    loc = SlamLocalizer(cfg)
    loc.step(np.eye(4), [], 0.0)
    loc.step(make_transform(rot_z(np.deg2rad(5.0)), [1.0, 0.0, 0.0]), [], 0.1)
    assert loc.jumps == 1
    assert loc.slam.pose == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
    assert np.sqrt(loc.slam.pose_covariance[0, 0]) == pytest.approx(np.hypot(1e-3, 0.005), rel=0.01)
    assert np.sqrt(loc.slam.pose_covariance[2, 2]) == pytest.approx(np.hypot(1e-3, 0.025), rel=0.01)
    # 0.1 m in 0.1 s is motion
    loc.step(make_transform(rot_z(np.deg2rad(5.0)), [1.1, 0.0, 0.0]), [], 0.2)
    assert loc.jumps == 1 and loc.slam.pose[0] == pytest.approx(0.1 * np.cos(np.deg2rad(0.0)), abs=0.01)


def test_the_height_drift_grows_r_on_z_with_the_distance_travelled():
    # 0.5 m steps at 0.5 m/s along x; after 10 m a valve's R gains (0.003 * 10)^2 on z, shared
    cfg = SlamConfig(odometry_latency_s=0.0, height_drift_sigma_per_m=0.003, tilt_sigma_deg=0.0, landmark_types=[])
    loc = SlamLocalizer(cfg)
    for k in range(21):
        step = loc.step(
            make_transform(rot_z(0.0), [0.5 * k, 0.0, 0.0]), [_obs([0.5 * k + 1.0, 0.0, 0.5])], float(k)
        )
    assert loc.distance_m == pytest.approx(10.0)
    o = step.observations[0]
    none = SlamLocalizer(
        SlamConfig(odometry_latency_s=0.0, height_drift_sigma_per_m=0.0, tilt_sigma_deg=0.0, landmark_types=[])
    )
    for k in range(21):
        ref = none.step(
            make_transform(rot_z(0.0), [0.5 * k, 0.0, 0.0]), [_obs([0.5 * k + 1.0, 0.0, 0.5])], float(k)
        )
    d = o.R - ref.observations[0].R
    assert d[2, 2] == pytest.approx(0.03**2) and np.count_nonzero(np.abs(d) > 1e-15) == 1
    assert (o.R_shared - ref.observations[0].R_shared)[2, 2] == pytest.approx(0.03**2)


def test_the_tilt_error_moves_a_point_ahead_up_and_down_by_its_distance():
    # a valve 2 m ahead of the tracker (map x), at its height: a 0.5 degree tilt gives
    # (2 * 0.5 deg)^2 on z only, beside the run with no tilt
    def run(tilt: float):
        loc = SlamLocalizer(
            SlamConfig(
                odometry_latency_s=0.0, height_drift_sigma_per_m=0.0, tilt_sigma_deg=tilt, landmark_types=[]
            )
        )
        return loc.step(make_transform(rot_z(0.0), [0.0, 0.0, 0.5]), [_obs([2.0, 0.0, 0.5])], 0.0).observations[0]

    d = run(0.5).R - run(0.0).R
    np.testing.assert_allclose(d, np.diag([0.0, 0.0, (2.0 * np.deg2rad(0.5)) ** 2]), atol=1e-15)


def _drive(loc: SlamLocalizer, jump_deg: float, announce: bool) -> tuple[float, float, float]:
    """Drive along x at 0.3 m/s, 10 frames a second, the odometry exact but for a loop closure
    at 15 m that turns its heading by ``jump_deg`` from then on: the filter's heading variance
    before the closure's frame and after the next, and its heading then (rad)."""
    for k in range(502):
        if k == 500:
            var_before = float(loc.slam.pose_covariance[2, 2])
        heading = np.deg2rad(jump_deg) if k >= 500 else 0.0
        T = make_transform(rot_z(heading), [0.03 * k, 0.0, 0.0])
        loc.step(T, [], 0.1 * k, relocalised=announce and k == 500)
    return var_before, float(loc.slam.pose_covariance[2, 2]), float(loc.slam.pose[2])


def test_an_announced_loop_closure_is_not_taken_as_motion():
    # the T265 jumps 1 degree back toward an earlier error: announced, the filter drives on at
    # its last velocity over that frame and the next, its heading widened by one and then two
    # changes of the turn rate (sigma 0.25 rad/s over 0.1 s frames); unannounced, it turns with
    # the odometry
    cfg = SlamConfig(
        odometry_latency_s=0.01,
        start_sigma_m=1e-3,
        start_sigma_rad=1e-4,
        sigma_theta_rad=0.0,
        sigma_theta_per_rad=0.0,
        sigma_theta_per_m=0.0,
        heading_drift_sigma=np.deg2rad(0.1),
        drift_sigma=0.01,
        relocalisation_turn_sigma_rad_s=0.25,
    )
    told = SlamLocalizer(cfg)
    before, after, heading = _drive(told, 1.0, announce=True)
    assert told.relocalisations == 1 and told.jumps == 0
    assert heading == pytest.approx(0.0, abs=1e-9)  # straight on: the jump is no turn
    blind = SlamLocalizer(cfg)
    before_b, after_b, heading_b = _drive(blind, 1.0, announce=False)
    assert blind.relocalisations == 0 and heading_b == pytest.approx(np.deg2rad(1.0), abs=1e-9)
    # the two frames add (1 + 4) x (0.25 rad/s x 0.1 s)^2 to the heading's variance, besides
    # what the heading drift state adds over 6 cm (the unannounced run's growth)
    assert after_b - before_b < 0.01 * (after - before)
    assert (after - before) - (after_b - before_b) == pytest.approx(5 * 0.025**2, rel=0.01)


def test_an_observations_shared_part_reaches_the_slam_in_the_robot_frame():
    """R_shared (map frame) is rotated into the robot frame like R and starts the landmark's
    visit bias, whose covariance is then R_shared's planar block in the map frame."""
    loc = SlamLocalizer(SlamConfig(n_min=0, odometry_latency_s=0.0))
    T0 = make_transform(rot_z(np.pi / 2), [0.0, 0.0, 0.0])
    obs = _obs([0.0, 2.0, 0.5], sigma=0.05)
    shared = np.diag([0.0016, 0.0004, 0.0009])  # map frame: larger along x
    loc.step(T0, [dataclasses.replace(obs, R_shared=shared)], 0.0)
    slam = loc.slam
    assert slam.biased == [0]
    i = slam.bias_index(0)
    np.testing.assert_allclose(slam.P[i : i + 2, i : i + 2], shared[:2, :2], atol=1e-12)
