"""UKF-SLAM ([Bouda2025]_ 2.2.1-2.2.5): sigma points and weights, prediction, association,
candidate map, augmentation, and drift correction on a synthetic run.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from poi.config import SlamConfig
from poi.core.geometry import wrap_angle
from poi.estimation.slam import (
    LandmarkObservation,
    SlamError,
    UkfSlam,
    huber_scale,
    odometry_increment,
    rot2,
    sigma_points,
)

# the document's state: the pose and landmarks only, no odometry error parameters
DOCUMENT_STATE = {"scale_sigma": 0.0, "drift_sigma": 0.0, "heading_drift_sigma": 0.0}


def test_weights_match_eq_2_to_5_by_hand():
    # n = 5, alpha = 0.5, beta = 2, kappa = 3 - n = -2 (the document's choice)
    # lambda = 0.25 * (5 - 2) - 5 = -4.25; n + lambda = 0.75
    pts = sigma_points(5, SlamConfig(alpha=0.5, beta=2.0, kappa=None))
    assert pts.Wm[0] == pytest.approx(-4.25 / 0.75)
    assert pts.Wc[0] == pytest.approx(-4.25 / 0.75 + 1 - 0.25 + 2)
    assert np.allclose(pts.Wm[1:], 1 / (2 * 0.75))
    assert np.allclose(pts.Wc[1:], 1 / (2 * 0.75))
    assert pts.Wm.sum() == pytest.approx(1.0)
    # explicit kappa: n = 3, alpha = 1, kappa = 0 -> lambda = 0: w0m = 0, wi = 1/6, w0c = 2
    pts = sigma_points(3, SlamConfig(alpha=1.0, beta=2.0, kappa=0.0))
    assert pts.Wm.tolist() == pytest.approx([0.0] + [1 / 6] * 6)
    assert pts.Wc[0] == pytest.approx(2.0)


def test_sigma_points_eq_1():
    # n = 2, alpha = 1, kappa = 3 - n = 1 -> lambda = 1, n + lambda = 3
    pts = sigma_points(2, SlamConfig(kappa=None))
    x = np.array([1.0, -2.0])
    P = np.array([[4.0, 0.0], [0.0, 9.0]])
    chi = pts.sigma_points(x, P)
    r3 = math.sqrt(3.0)
    expected = [[1, -2], [1 + 2 * r3, -2], [1, -2 + 3 * r3], [1 - 2 * r3, -2], [1, -2 - 3 * r3]]
    assert chi == pytest.approx(np.array(expected, dtype=float))


def test_odometry_increment_and_prediction_rotate_correctly():
    # odometry says: facing +y, moved 1 m forward and turned left 90 degrees
    d = odometry_increment(np.array([0.0, 0.0, math.pi / 2]), np.array([0.0, 1.0, math.pi]))
    assert d.tolist() == pytest.approx([1.0, 0.0, math.pi / 2])
    # the filter thinks it faces -x: the same increment moves it 1 m along -x
    slam = UkfSlam(SlamConfig(start_sigma_m=1e-4, start_sigma_rad=1e-4), pose0=(2.0, 3.0, math.pi))
    slam.predict(d)
    assert slam.pose.tolist() == pytest.approx([1.0, 3.0, -math.pi / 2], abs=1e-6)


def test_process_noise_is_rotated_by_the_jacobian_eq_14_15():
    cfg = SlamConfig(sigma_xy_m=0.0, sigma_xy_per_m=0.1, sigma_theta_rad=0.01, sigma_theta_per_m=0.0)
    slam = UkfSlam(cfg, pose0=(0.0, 0.0, math.pi / 2))
    Q = slam.process_noise(np.array([1.0, 0.0, 0.0]))
    # Q_c = diag(0.01, 0.01, 1e-4); rotation by 90 degrees keeps an isotropic xy block
    assert Q[:3, :3] == pytest.approx(np.diag([0.01, 0.01, 1e-4]))
    cfg = SlamConfig(sigma_xy_m=0.0, sigma_xy_per_m=0.1, sigma_theta_rad=0.0, sigma_theta_per_m=0.0)
    J = np.eye(3)
    J[:2, :2] = rot2(0.3)
    slam = UkfSlam(cfg, pose0=(0.0, 0.0, 0.3))
    Qc = np.diag([0.01, 0.01, 0.0])
    assert slam.process_noise(np.array([0.6, 0.8, 0.0]))[:3, :3] == pytest.approx(J @ Qc @ J.T)


def _observe(slam: UkfSlam, truth_xy: dict[str, np.ndarray], robot: np.ndarray, rng, sigma: float, t: float):
    obs = []
    for cls, p in truth_xy.items():
        xy = rot2(robot[2]).T @ (p - robot[:2]) + rng.normal(0.0, sigma, 2)
        obs.append(LandmarkObservation(class_name=cls, xy=xy, R=sigma**2 * np.eye(2)))
    return slam.observe(obs, t)


def test_landmark_promoted_only_after_more_than_n_min_sightings():
    # [Bouda2025] 2.2.5: added once "seen more than n_min times": n_min = 3 -> the 4th sighting
    slam = UkfSlam(SlamConfig(n_min=3))
    rng = np.random.default_rng(0)
    truth = {"valve": np.array([2.0, 0.5])}
    for k in range(3):
        res = _observe(slam, truth, np.zeros(3), rng, 0.01, 0.1 * k)
        assert not res.promoted and slam.n == slam.robot_dim
    assert slam.candidates[0].n_seen == 3
    res = _observe(slam, truth, np.zeros(3), rng, 0.01, 0.3)
    assert res.promoted == [0] and slam.n == slam.robot_dim + 2 and not slam.candidates
    assert slam.landmark_xy(0) == pytest.approx([2.0, 0.5], abs=0.02)


def test_candidate_weighted_mean_and_t_max():
    slam = UkfSlam(SlamConfig(n_min=10, t_max_s=1.0))
    for k, x in enumerate([1.0, 1.2, 1.1]):
        slam.observe([LandmarkObservation(class_name="door", xy=np.array([x, 0.0]), R=0.01 * np.eye(2))], 0.1 * k)
    # w_n = 1 / (1 + n): running mean of the sightings
    assert slam.candidates[0].xy == pytest.approx([1.1, 0.0])
    slam.observe([], 1.3)  # last sighting at 0.2 s: 1.1 s ago > t_max
    assert slam.candidates == []


def test_association_is_per_class_and_mutual_nearest():
    slam = UkfSlam(SlamConfig(n_min=0, associate_m=0.5))
    slam.observe(
        [
            LandmarkObservation(class_name="qr", xy=np.array([2.0, 0.0]), R=0.01 * np.eye(2)),
            LandmarkObservation(class_name="valve", xy=np.array([2.1, 0.0]), R=0.01 * np.eye(2)),
        ],
        0.0,
    )
    assert [lm.class_name for lm in slam.landmarks] == ["qr", "valve"]
    # a qr observation next to the valve pairs with the qr landmark, not the closer valve
    res = slam.observe([LandmarkObservation(class_name="qr", xy=np.array([2.12, 0.0]), R=0.01 * np.eye(2))], 0.1)
    assert res.associated == [(0, 0)]
    # two qr observations near one qr landmark: only the nearer pairs (eq. 18 both ways)
    res = slam.observe(
        [
            LandmarkObservation(class_name="qr", xy=np.array([2.3, 0.0]), R=0.01 * np.eye(2)),
            LandmarkObservation(class_name="qr", xy=np.array([2.02, 0.0]), R=0.01 * np.eye(2)),
        ],
        0.2,
    )
    assert res.associated == [(1, 0)] and res.to_candidates == [0]


def test_static_robot_converges_on_fixed_landmarks():
    rng = np.random.default_rng(1)
    # a start known to 0.1 mm: a robot standing still cannot learn the map frame's heading from
    # the landmarks it maps itself, so a start heading sigma bounds theirs (0.02 rad x 3 m)
    slam = UkfSlam(SlamConfig(n_min=3, start_sigma_m=1e-4, start_sigma_rad=1e-4))
    truth = {"valve": np.array([2.0, 1.0]), "door": np.array([3.0, -1.5]), "qr": np.array([-1.0, 2.5])}
    traces = []
    for k in range(200):
        slam.predict(np.zeros(3))
        _observe(slam, truth, np.zeros(3), rng, 0.05, 0.1 * k)
        if len(slam.landmarks) == 3:
            traces.append(np.trace(slam.P) - slam.P[3, 3])  # k is not observable standing still
    assert len(slam.landmarks) == 3
    for lm in slam.landmarks:
        assert slam.landmark_xy(lm.slot) == pytest.approx(truth[lm.class_name], abs=0.03)
        assert np.sqrt(np.linalg.eigvalsh(slam.landmark_covariance(lm.slot)).max()) < 0.03
    assert slam.pose == pytest.approx([0.0, 0.0, 0.0], abs=0.02)
    assert traces[-1] < 0.2 * traces[0]


def test_augmentation_keeps_p_symmetric_positive_definite():
    rng = np.random.default_rng(2)
    slam = UkfSlam(SlamConfig(n_min=2))
    robot = np.zeros(3)
    truth = {f"c{i}": rng.uniform(-3, 3, 2) for i in range(12)}
    seen_ever: set[str] = set()
    for k in range(120):
        step = np.array([0.05, 0.0, 0.05])
        robot = robot + np.r_[rot2(robot[2]) @ step[:2], step[2]]
        slam.predict(step)
        seen = {c: p for c, p in truth.items() if np.linalg.norm(p - robot[:2]) < 3.0}
        _observe(slam, seen, robot, rng, 0.03, 0.1 * k)
        seen_ever |= set(seen)
        assert np.array_equal(slam.P, slam.P.T)
        assert np.linalg.eigvalsh(slam.P).min() > 0.0
    assert len(seen_ever) >= 10
    assert sorted(lm.class_name for lm in slam.landmarks) == sorted(seen_ever)
    assert slam.n == slam.robot_dim + 2 * len(seen_ever)


def test_drift_corrected_by_landmarks():
    """A robot circling landmarks with 10% odometry scale error and a heading bias:
    the filter's pose error stays far below the odometry's."""
    rng = np.random.default_rng(3)
    cfg = SlamConfig(n_min=3, sigma_xy_per_m=0.1, sigma_theta_per_m=0.02)
    slam = UkfSlam(cfg)
    truth = {f"c{i}": np.array([3.0 * math.cos(a), 3.0 * math.sin(a)]) for i, a in enumerate(np.linspace(0, 6, 8))}
    robot = np.array([0.0, 0.0, 0.0])
    odom = robot.copy()
    err_odom, err_slam = [], []
    for k in range(600):
        step = np.array([0.03, 0.0, 0.02])
        robot = robot + np.r_[rot2(robot[2]) @ step[:2], step[2]]
        meas = np.array([1.1 * step[0], 0.0, step[2] + 0.002])  # scale and heading error
        odom = odom + np.r_[rot2(odom[2]) @ meas[:2], meas[2]]
        slam.predict(meas)
        seen = {c: p for c, p in truth.items() if np.linalg.norm(p - robot[:2]) < 4.0}
        _observe(slam, seen, robot, rng, 0.03, 0.1 * k)
        err_odom.append(np.linalg.norm(odom[:2] - robot[:2]))
        err_slam.append(np.linalg.norm(slam.pose[:2] - robot[:2]))
    assert err_odom[-1] > 1.0
    assert max(err_slam[100:]) < 0.15
    assert abs(wrap_angle(slam.pose[2] - robot[2])) < 0.05


def test_bad_inputs_are_refused():
    slam = UkfSlam(SlamConfig())
    with pytest.raises(SlamError, match="odometry increment"):
        slam.predict(np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(SlamError, match="'valve'"):
        slam.observe([LandmarkObservation(class_name="valve", xy=np.array([1.0, np.inf]), R=np.eye(2))], 0.0)


def test_structured_prediction_equals_the_full_unscented_transform():
    """predict's O(n) transform against filterpy's over all 2n + 1 sigma points (eq. 6-7)."""
    from filterpy.kalman import unscented_transform

    rng = np.random.default_rng(4)
    slam = UkfSlam(SlamConfig(n_min=0))
    R = 0.02 * np.eye(2)
    seen = [LandmarkObservation(class_name=f"c{i}", xy=rng.uniform(-3, 3, 2), R=R) for i in range(6)]
    slam.observe(seen, 0.0)
    A = rng.normal(size=(slam.n, slam.n))
    slam.P = slam.P + 0.01 * A @ A.T  # correlated, robot heading uncertain
    slam.x[2] = 3.1  # near the wrap
    delta = np.array([0.4, -0.1, 0.3])
    pts = slam._points
    chi = pts.sigma_points(slam.x, slam.P)
    Y = chi.copy()
    # k, b, c: the odometry scale, drift rate and heading drift
    c, s, k = np.cos(chi[:, 2]), np.sin(chi[:, 2]), chi[:, slam.i_scale]
    d = math.hypot(delta[0], delta[1])
    Y[:, 0] += k * (c * delta[0] - s * delta[1]) + chi[:, slam.i_drift] * d
    Y[:, 1] += k * (s * delta[0] + c * delta[1]) + chi[:, slam.i_drift + 1] * d
    Y[:, 2] += delta[2] + chi[:, slam.i_heading_drift] * d
    Y[:, 2] = Y[0, 2] + wrap_angle(Y[:, 2] - Y[0, 2])
    x_ref, P_ref = unscented_transform(Y, pts.Wm, pts.Wc, slam.process_noise(delta))
    x_ref[2] = wrap_angle(x_ref[2])
    slam.predict(delta)
    np.testing.assert_allclose(slam.x, x_ref, rtol=0, atol=1e-10)
    np.testing.assert_allclose(slam.P, P_ref, rtol=0, atol=1e-10)


def test_augmentation_carries_the_pose_cross_covariance_by_hand():
    """P_new = [[P, P J_x^T], [J_x P, J_x P J_x^T + J_z R J_z^T]] ([Bouda2025]_ eq. 16 as g)."""
    slam = UkfSlam(SlamConfig(n_min=0, **DOCUMENT_STATE), pose0=(1.0, 2.0, math.pi / 2))
    slam.P = np.diag([0.01, 0.04, 0.0025])
    R = np.diag([0.0009, 0.0004])  # robot frame
    # facing +y, 2 m ahead: the landmark is at (1, 4) in the map
    res = slam.observe([LandmarkObservation(class_name="valve", xy=np.array([2.0, 0.0]), R=R)], 0.0)
    assert res.promoted == [0]
    assert slam.landmark_xy(0) == pytest.approx([1.0, 4.0])
    # J_x = [[1, 0, -2], [0, 1, 0]] (d(R(theta) z)/d theta at theta = 90 deg, z = (2, 0)),
    # J_z = R(90 deg): P J_x^T = [[0.01, 0], [0, 0.04], [-0.005, 0]];
    # J_x P J_x^T = diag(0.01 + 4 * 0.0025, 0.04), J_z R J_z^T = diag(0.0004, 0.0009)
    np.testing.assert_allclose(slam.P[:3, 3:], [[0.01, 0.0], [0.0, 0.04], [-0.005, 0.0]], atol=1e-12)
    np.testing.assert_allclose(slam.P[3:, :3], slam.P[:3, 3:].T, atol=0)
    np.testing.assert_allclose(slam.landmark_covariance(0), np.diag([0.0204, 0.0409]), atol=1e-12)
    assert np.linalg.eigvalsh(slam.P).min() > 0.0


def test_default_weights_are_non_negative_with_many_landmarks():
    # kappa = 0, alpha = 1: lambda = 0 -> W_0^m = 0, W_0^c = beta = 2, W_i = 1 / (2n)
    for n in (3, 23, 83):
        pts = sigma_points(n, SlamConfig())
        assert pts.Wm[0] == pytest.approx(0.0) and pts.Wc[0] == pytest.approx(2.0)
        assert np.allclose(pts.Wm[1:], 1 / (2 * n)) and np.all(pts.Wc >= 0)
    # the document's kappa = 3 - n: W_0 = (3 - n) / 3, -26 with 40 landmarks
    assert sigma_points(83, SlamConfig(kappa=None)).Wm[0] == pytest.approx(-80 / 3)


def test_an_indefinite_covariance_is_repaired_counted_and_logged(caplog):
    slam = UkfSlam(SlamConfig(n_min=0))
    slam.observe([LandmarkObservation(class_name="qr", xy=np.array([2.0, 0.0]), R=0.01 * np.eye(2))], 0.0)
    slam.P[3, 3] = -1e-3  # what rounding could leave
    with caplog.at_level("WARNING", logger="poi.estimation.slam"):
        slam.predict(np.array([0.1, 0.0, 0.0]))
        slam.observe([LandmarkObservation(class_name="qr", xy=np.array([1.9, 0.0]), R=0.01 * np.eye(2))], 0.1)
    assert slam.repairs == 1
    assert "not positive definite" in caplog.text
    assert np.linalg.eigvalsh(slam.P).min() > 0.0


def test_scale_prediction_by_hand():
    """x' = x + k R(theta) Delta with k in the state: for Delta = (2, 0, 0) at theta = 0,
    var(x') = var(x) + 4 var(k), cov(x', k) = 2 var(k), var(y') = var(y) + 4 var(theta)."""
    cfg = SlamConfig(
        sigma_xy_m=0.0,
        sigma_xy_per_m=0.0,
        sigma_theta_rad=0.0,
        sigma_theta_per_rad=0.0,
        sigma_theta_per_m=0.0,
        scale_sigma=0.1,
        scale_sigma_per_m=0.0,
        drift_sigma=0.0,
        heading_drift_sigma=0.0,
        start_sigma_m=1e-4,
        start_sigma_rad=1e-4,
    )
    slam = UkfSlam(cfg)
    assert slam.robot_dim == 4 and slam.odometry_scale == 1.0
    slam.predict(np.array([2.0, 0.0, 0.0]))
    assert slam.pose == pytest.approx([2.0, 0.0, 0.0], abs=1e-7)
    assert slam.P[0, 0] == pytest.approx(1e-8 + 4 * 0.01, rel=1e-6)
    assert slam.P[0, 3] == pytest.approx(2 * 0.01, rel=1e-6)
    assert slam.P[1, 1] == pytest.approx(1e-8 + 4 * 1e-8, rel=1e-6)
    assert slam.P[1, 2] == pytest.approx(2 * 1e-8, rel=1e-6)
    assert slam.P[3, 3] == pytest.approx(0.01, rel=1e-12)
    # the random walk of k: (scale_sigma_per_m * d)^2 for d = 2 m
    slam = UkfSlam(SlamConfig(scale_sigma_per_m=0.01))
    assert slam.process_noise(np.array([1.2, 1.6, 0.0]))[3, 3] == pytest.approx(4e-4)
    assert UkfSlam(SlamConfig(**DOCUMENT_STATE)).robot_dim == 3


def _short_odometry_run(cfg: SlamConfig) -> tuple[UkfSlam, np.ndarray]:
    """160 steps of 0.05 m along x, odometry reporting 10% short; four valves in the first
    4 m, seen within 2.5 m; then 4 m with nothing in view."""
    rng = np.random.default_rng(5)
    slam = UkfSlam(cfg)
    truth = {f"v{i}": np.array([1.0 + i, 1.0 if i % 2 else -1.0]) for i in range(4)}
    robot = np.zeros(3)
    step = np.array([0.05, 0.0, 0.0])
    for k in range(160):
        robot = robot + step
        slam.predict(0.9 * step)
        seen = {c: p for c, p in truth.items() if np.linalg.norm(p - robot[:2]) < 2.5}
        _observe(slam, seen, robot, rng, 0.02, 0.1 * k)
    return slam, robot


def test_a_short_odometry_scale_is_learnt_and_the_pose_stays_consistent():
    white = {"n_min": 2, "sigma_xy_per_m": 0.01, "sigma_theta_per_m": 0.005}
    cfg = SlamConfig(**white, drift_sigma=0.0, heading_drift_sigma=0.0)
    slam, robot = _short_odometry_run(cfg)
    assert slam.odometry_scale == pytest.approx(1 / 0.9, abs=0.03)
    e = slam.pose - robot
    nees = float(e @ np.linalg.solve(slam.pose_covariance, e))
    assert nees < 16.27  # chi-square 3 dof, 99.9%
    # without the odometry's error parameters the same run ends far outside its covariance:
    # the scale error is not white noise
    fixed, robot = _short_odometry_run(SlamConfig(**white, **DOCUMENT_STATE))
    e = fixed.pose - robot
    assert float(e @ np.linalg.solve(fixed.pose_covariance, e)) > 100.0


def test_a_heading_drift_is_learnt_on_a_circuit():
    """A robot circling four landmarks while its odometry turns 0.01 rad per metre too far:
    c converges on -0.01 (the correction) and the pose ends inside its covariance."""
    rng = np.random.default_rng(6)
    cfg = SlamConfig(n_min=2, sigma_xy_per_m=0.01, sigma_theta_per_m=0.002, heading_drift_sigma=0.02)
    truth = {f"c{i}": 2.5 * np.array([math.cos(a), math.sin(a)]) for i, a in enumerate(np.linspace(0.3, 5.0, 4))}
    robot = np.array([1.0, 0.0, math.pi / 2])
    slam = UkfSlam(cfg, pose0=tuple(robot))
    step = np.array([0.04, 0.0, 0.04])  # a circle of 1 m radius
    for k in range(300):
        robot = robot + np.r_[rot2(robot[2]) @ step[:2], step[2]]
        slam.predict(step + np.array([0.0, 0.0, 0.01 * 0.04]))
        seen = {c: p for c, p in truth.items() if np.linalg.norm(p - robot[:2]) < 3.0}
        _observe(slam, seen, robot, rng, 0.02, 0.1 * k)
    b, c = slam.odometry_drift
    assert c == pytest.approx(-0.01, abs=0.003)
    e = slam.pose - robot
    e[2] = wrap_angle(e[2])
    assert float(e @ np.linalg.solve(slam.pose_covariance, e)) < 16.27


def test_a_view_bias_starts_with_the_landmark_by_hand():
    """With R_shared S, promotion adds the landmark and its visit bias b: cov(b) = J_z S J_z^T,
    cov(l, b) = -cov(b), and l + b is known to J_x P J_x^T + J_z (R - S) J_z^T."""
    slam = UkfSlam(SlamConfig(n_min=0, **DOCUMENT_STATE), pose0=(1.0, 2.0, math.pi / 2))
    slam.P = np.diag([0.01, 0.04, 0.0025])
    R, S = np.diag([0.0009, 0.0004]), np.diag([0.0005, 0.0001])  # robot frame
    obs = LandmarkObservation(class_name="valve", xy=np.array([2.0, 0.0]), R=R, R_shared=S)
    assert slam.observe([obs], 0.0).promoted == [0]
    assert slam.n == 3 + 2 + 2 and slam.bias_index(0) == 5
    assert slam.view_bias(0) == pytest.approx([0.0, 0.0])
    S_map = np.diag([0.0001, 0.0005])  # J_z = R(90 deg) swaps the axes
    np.testing.assert_allclose(slam.P[5:, 5:], S_map, atol=1e-12)
    np.testing.assert_allclose(slam.P[3:5, 5:], -S_map, atol=1e-12)
    np.testing.assert_allclose(slam.P[:3, 5:], 0.0, atol=0)
    np.testing.assert_allclose(slam.landmark_covariance(0), np.diag([0.0204, 0.0409]), atol=1e-12)
    A = np.hstack([np.eye(2), np.eye(2)])  # l + b
    np.testing.assert_allclose(A @ slam.P[3:, 3:] @ A.T, np.diag([0.0203, 0.0404]), atol=1e-12)
    assert np.linalg.eigvalsh(slam.P).min() > -1e-15


def test_a_landmark_mapped_from_n_sightings_has_their_fresh_noise_averaged():
    """Promoted at its 4th sighting, the landmark's R is R_shared + (R - R_shared) / 4: the
    candidate is the mean of four sightings, whose fresh errors average and shared one does not."""
    slam = UkfSlam(SlamConfig(n_min=3, **DOCUMENT_STATE))
    slam.P = np.diag([0.01, 0.04, 0.0025])
    R, S = np.diag([0.0009, 0.0004]), np.diag([0.0005, 0.0001])
    for k in range(4):
        res = slam.observe(
            [LandmarkObservation(class_name="valve", xy=np.array([2.0, 0.0]), R=R, R_shared=S)], 0.1 * k
        )
    assert res.promoted == [0]
    # facing +x: J_x = [[1, 0, 0], [0, 1, 2]], J_z = I; J_x P J_x^T = diag(0.01, 0.04 + 4 * 0.0025)
    R_mean = S + (R - S) / 4  # diag(0.0006, 0.000175)
    np.testing.assert_allclose(slam.landmark_covariance(0), np.diag([0.01, 0.05]) + R_mean, atol=1e-12)
    np.testing.assert_allclose(slam.P[5:, 5:], S, atol=1e-12)


def test_a_turned_view_decorrelates_the_bias_by_hand():
    """Driving past a landmark turns the view of it by dphi: the bias takes a Gauss-Markov step
    with a = exp(-dphi / view_decorrelation_deg): mean a b, cross-covariances a times,
    variance a^2 P_bb + (1 - a^2) S. Turning in place leaves it as it was."""
    slam = UkfSlam(SlamConfig(n_min=0, view_decorrelation_deg=10.0, **DOCUMENT_STATE))
    R, S = 0.01 * np.eye(2), 0.004 * np.eye(2)
    slam.observe([LandmarkObservation(class_name="door", xy=np.array([2.0, 0.0]), R=R, R_shared=S)], 0.0)
    i = slam.bias_index(0)
    slam.x[i : i + 2] = [0.02, -0.01]  # as if an update had estimated it
    slam.predict(np.array([0.0, 0.0, 0.5]))  # a turn in place: the same view
    P0, x0 = slam.P.copy(), slam.x.copy()
    slam._move_view(0, S)
    np.testing.assert_array_equal(slam.P, P0)
    np.testing.assert_array_equal(slam.x, x0)
    # back to facing it, then 2 tan(10 deg) m sideways: the line of sight turns by 10 degrees
    slam.predict(np.array([0.0, 0.0, -0.5]))
    slam.predict(np.array([0.0, 2.0 * math.tan(math.radians(10.0)), 0.0]))
    P0, x0 = slam.P.copy(), slam.x.copy()
    r0, r = slam.landmarks[0].view_from - slam.landmark_xy(0), slam.x[:2] - slam.landmark_xy(0)
    dphi = math.degrees(math.atan2(abs(r0[0] * r[1] - r0[1] * r[0]), r0 @ r))
    assert dphi == pytest.approx(10.0, abs=0.01)  # the predicted mean, a hair short of 2 tan(10 deg)
    slam._move_view(0, 2.0 * S)
    a = math.exp(-dphi / 10.0)
    np.testing.assert_allclose(slam.x[i : i + 2], a * x0[i : i + 2], atol=1e-12)
    np.testing.assert_allclose(slam.P[:i, i : i + 2], a * P0[:i, i : i + 2], atol=1e-12)
    np.testing.assert_allclose(
        slam.P[i : i + 2, i : i + 2], a * a * P0[i : i + 2, i : i + 2] + (1 - a * a) * 2.0 * S, atol=1e-12
    )
    assert np.linalg.eigvalsh(slam.P).min() > 0.0


def test_shared_errors_off_takes_every_observation_as_fresh():
    slam = UkfSlam(SlamConfig(n_min=0, shared_errors=False, **DOCUMENT_STATE))
    obs = LandmarkObservation(
        class_name="door", xy=np.array([2.0, 0.0]), R=0.01 * np.eye(2), R_shared=0.004 * np.eye(2)
    )
    slam.observe([obs], 0.0)
    assert slam.view_bias(0) is None and slam.n == 5


def test_an_r_shared_larger_than_r_is_refused():
    slam = UkfSlam(SlamConfig())
    bad = LandmarkObservation(
        class_name="door", xy=np.array([2.0, 0.0]), R=0.01 * np.eye(2), R_shared=0.02 * np.eye(2)
    )
    with pytest.raises(SlamError, match="R_shared exceeds R"):
        slam.observe([bad], 0.0)


def _revisit_pose_nees(shared_errors: bool, runs: int, seed: int) -> float:
    """Mean pose NEES after a landmark is mapped from one side and seen again from the other,
    every observation's error a fresh part plus a bias drawn anew for each side."""
    rng = np.random.default_rng(seed)
    cfg = SlamConfig(
        n_min=3,
        shared_errors=shared_errors,
        start_sigma_m=0.005,
        start_sigma_rad=0.001,
        sigma_xy_m=1e-4,
        sigma_xy_per_m=0.0,
        sigma_theta_rad=1e-5,
        sigma_theta_per_rad=0.0,
        sigma_theta_per_m=0.0,
        **DOCUMENT_STATE,
    )
    Rw, S = 0.01**2 * np.eye(2), 0.05**2 * np.eye(2)
    landmark = np.array([2.0, 0.3])
    nees = []
    for _ in range(runs):
        slam = UkfSlam(cfg)
        truth = rng.multivariate_normal(np.zeros(3), slam.pose_covariance)
        t = 0.0
        for side, frames in enumerate((10, 30)):  # mapped from one side, then seen from the other
            if side:
                # past it and turned round, the odometry 10 cm and 0.3 degrees off
                step, lost = np.array([4.0, 0.0, math.pi]), (0.1, 0.005)
                noise = slam.process_noise(step, lost)[:3, :3]
                slam.predict(step, extra_sigma=lost)
                truth = (
                    truth + np.r_[rot2(truth[2]) @ step[:2], step[2]] + rng.multivariate_normal(np.zeros(3), noise)
                )
                t += 2.0
            bias = rng.multivariate_normal(np.zeros(2), S)
            for _ in range(frames):
                xy = rot2(truth[2]).T @ (landmark + bias - truth[:2]) + rng.multivariate_normal(np.zeros(2), Rw)
                slam.observe([LandmarkObservation(class_name="qr", xy=xy, R=Rw + S, R_shared=S)], t)
                t += 0.1
        e = slam.pose - truth
        e[2] = wrap_angle(e[2])
        nees.append(float(e @ np.linalg.solve(slam.pose_covariance, e)))
    return float(np.mean(nees))


def test_a_bias_repeated_over_a_view_leaves_the_pose_covariance_honest():
    """The second side's 30 frames share one bias: with view biases the pose NEES (3 dof, 300
    runs) is inside its chi-square 99% interval [2.71, 3.31]; taken as fresh, the filter
    believes 30 observations' worth and comes out over-confident."""
    assert 2.71 <= _revisit_pose_nees(True, 300, seed=4) <= 3.31
    assert _revisit_pose_nees(False, 300, seed=4) > 3.31 * 2


def _mapped_static_slam(robust_nis: float) -> tuple[UkfSlam, dict[str, np.ndarray]]:
    """A robot standing at the origin that has mapped three landmarks from 1 cm sightings."""
    rng = np.random.default_rng(11)
    slam = UkfSlam(SlamConfig(n_min=2, robust_nis=robust_nis, **DOCUMENT_STATE))
    truth = {"valve": np.array([2.0, 1.0]), "door": np.array([3.0, -1.5]), "qr": np.array([-1.0, 2.5])}
    for k in range(10):
        slam.predict(np.zeros(3))
        _observe(slam, truth, np.zeros(3), rng, 0.01, 0.1 * k)
    assert len(slam.landmarks) == 3
    return slam, truth


def _update_with(slam: UkfSlam, truth: dict[str, np.ndarray], offset_m: float) -> None:
    """One update: the qr code seen ``offset_m`` along x from where it is, the others exactly."""
    slam.predict(np.zeros(3))
    obs = [
        LandmarkObservation(
            class_name=c, xy=p + (offset_m if c == "qr" else 0.0) * np.array([1.0, 0.0]), R=1e-4 * np.eye(2)
        )
        for c, p in truth.items()
    ]
    res = slam.observe(obs, 5.0)
    assert len(res.associated) == 3  # all within associate_m (0.5 m): eq. 18 pairs them


def test_huber_scale_leaves_expected_innovations_and_bounds_the_rest():
    """Below robust_nis nothing changes; above it the block is scaled by sqrt(NIS / c^2), so
    the NIS the update sees is sqrt(NIS c^2) (Huber's weight c / r on a residual of r sigmas);
    the other blocks and the cross terms are kept."""
    S = np.array([[4.0, 1.0, 0.5, 0.0], [1.0, 2.0, 0.0, 0.2], [0.5, 0.0, 1.0, 0.0], [0.0, 0.2, 0.0, 1.0]])
    nu = np.array([1.0, -1.0, 6.0, 0.0])  # NIS 0.86 and 36
    out = huber_scale(nu, S, 9.0)
    assert np.array_equal(out[:2, :], S[:2, :]) and np.array_equal(out[:, :2], S[:, :2])
    assert out[2:, 2:] == pytest.approx(S[2:, 2:] * 2.0)  # sqrt(36 / 9)
    assert float(nu[2:] @ np.linalg.solve(out[2:, 2:], nu[2:])) == pytest.approx(math.sqrt(36.0 * 9.0))
    assert np.array_equal(huber_scale(nu, S, 0.0), S)  # off


def test_an_unexpected_sighting_moves_the_state_by_a_bounded_amount():
    """A qr code seen 0.3 m off where its landmark is mapped to millimetres (NIS in the
    hundreds): the document's update takes all of it and moves the map and pose by
    centimetres; with Huber's weight the move is a small fraction of that. A sighting within
    its noise updates exactly as the document's."""
    moved = {}
    for nis in (0.0, 9.21):
        slam, truth = _mapped_static_slam(nis)
        before = slam.x.copy()
        _update_with(slam, truth, 0.3)
        moved[nis] = float(np.linalg.norm(slam.x - before))
    assert moved[0.0] > 0.025  # 3.1 cm, mostly the qr landmark
    assert moved[9.21] < 0.2 * moved[0.0]  # 0.3 cm
    same = []
    for nis in (0.0, 9.21):
        slam, truth = _mapped_static_slam(nis)
        _update_with(slam, truth, 0.005)
        same.append((slam.x.copy(), slam.P.copy()))
    assert np.array_equal(same[0][0], same[1][0]) and np.array_equal(same[0][1], same[1][1])
