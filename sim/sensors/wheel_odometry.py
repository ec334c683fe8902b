"""Wheel odometry of a differential-drive base, with the errors real odometry has.

A wheeled robot can feed its tracking camera wheel odometry ([IntelT265]_); [Bouda2025]_ (2.2.3) predicts
its SLAM from the TurtleBot's odometry, the pose integrated from the wheels. Given the
true base poses at the frame times, each step k-1 -> k is split the way a base moves
it (the odometry motion model: turn delta_rot1 toward the step, drive delta_trans,
turn delta_rot2), each part into the travel of the right and left wheels (a turn of
delta moves them +-delta b / 2, a drive moves both delta_trans, b the true wheel base),
and what the encoders make of that travel is integrated back:

    s_R' = s_R (1 + e_r) / (1 + m / 2),   s_L' = s_L (1 + e_r) / (1 - m / 2)
    trans' = (s_R' + s_L') / 2 + N(0, k_s^2 |trans|)
    rot'   = (s_R' - s_L') / (b (1 + e_b)) + N(0, k_r^2 |rot| + k_d^2 |trans|)

with e_r = ``wheel_radius_error`` (the radius the odometry assumes is 1 + e_r times the
true one: every distance and turn reads 1 + e_r long), m = ``wheel_radius_mismatch``
(true right minus left radius over their mean: driving straight reads as a slow turn of
-m / b rad per metre), e_b = ``wheel_base_error`` (the wheel base it assumes is 1 + e_b
times the true one: turns read 1 / (1 + e_b) as large, a heading error proportional to
the turning), and the random slip of each step drawn with variance proportional to the
distance driven (k_s = ``slip_m_per_sqrt_m``, k_d = ``slip_rad_per_sqrt_m``) or the
angle turned (k_r = ``slip_rad_per_sqrt_rad``), so the errors are random walks whose
sigma grows with the square root of the distance or angle, whatever the frame rate.

The pose is integrated from the true start pose: theta += rot1'; (x, y) += trans'
(cos theta, sin theta); theta += rot2'. The reported frame keeps the true pose's
height and tilt: ``R_meas = Rz(theta' - theta) R_true`` (as the T265 model does), so a
mount error in the true tracker frame carries through. Draws: one vectorised normal
per error term, in a fixed order, from the trial's generator.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
.. [IntelT265] Intel, "Intel RealSense Tracking Camera T265 Datasheet".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from poi.core.geometry import make_transform, planar_pose, rot_z, wrap_angle
from sim.sensors.base import PoseTrack, TrackerMotion


@dataclass(kw_only=True)
class WheelOdometrySpec:
    """Differential-drive wheel odometry (sim/sensors/wheel_odometry.py). Defaults: a
    TurtleBot 2 (Kobuki base, 0.23 m between the wheels) on a hard floor.

    Systematic errors (fixed for a run): ``wheel_radius_error`` (the radius the odometry
    assumes over the true one, minus 1: +0.05 reports every distance and turn 5% long),
    ``wheel_radius_mismatch`` (true right minus left wheel radius over their mean: a
    straight run curves), ``wheel_base_error`` (the wheel base the odometry assumes over
    the true one, minus 1: +0.02 reports turns 2% short). Random slip, a random walk in
    distance travelled: ``slip_m_per_sqrt_m`` (distance error sigma after 1 m driven),
    ``slip_rad_per_sqrt_rad`` (heading error sigma after 1 rad turned),
    ``slip_rad_per_sqrt_m`` (heading error sigma after 1 m driven).
    """

    wheel_base_m: float = 0.23
    wheel_radius_error: float = 0.01  # worn or soft tyres: about 1%
    wheel_radius_mismatch: float = 0.002  # UMBmark-size diameter ratio error: about 0.5 deg per metre
    wheel_base_error: float = 0.01  # the contact patches' spread: about 1%, 3.6 deg per full turn
    slip_m_per_sqrt_m: float = 0.01
    slip_rad_per_sqrt_rad: float = 0.02  # about 2.9 deg after a full turn in place
    slip_rad_per_sqrt_m: float = 0.005

    def __post_init__(self) -> None:
        if self.wheel_base_m <= 0:
            raise ValueError(f"wheel_base_m: expected a positive number, got {self.wheel_base_m}")
        for name in ("wheel_radius_error", "wheel_base_error"):
            if getattr(self, name) <= -1.0:
                raise ValueError(f"{name}: expected a relative error > -1, got {getattr(self, name)}")
        if not abs(self.wheel_radius_mismatch) < 2.0:
            raise ValueError(
                f"wheel_radius_mismatch: expected a number in (-2, 2), got {self.wheel_radius_mismatch}"
            )
        for name in ("slip_m_per_sqrt_m", "slip_rad_per_sqrt_rad", "slip_rad_per_sqrt_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: expected a number >= 0, got {getattr(self, name)}")


MIN_TRANS_M = 1e-9  # below this a step is a turn in place (its direction is undefined)


def motion_steps(T_true: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rot1, trans, rot2) of each step k-1 -> k (first entries 0), from the true poses.

    >>> T = [make_transform(np.eye(3), [0, 0, 0]), make_transform(rot_z(np.pi / 2), [1, 0, 0])]
    >>> [v.round(6).tolist() for v in motion_steps(T)]
    [[0.0, 0.0], [0.0, 1.0], [0.0, 1.570796]]
    """
    xyt = np.array([planar_pose(T) for T in T_true])  # (n, 3)
    d = np.diff(xyt, axis=0)  # (n-1, 3)
    trans = np.hypot(d[:, 0], d[:, 1])
    heading = np.arctan2(d[:, 1], d[:, 0])
    rot1 = np.where(trans > MIN_TRANS_M, wrap_angle(heading - xyt[:-1, 2]), 0.0)
    rot2 = wrap_angle(d[:, 2] - rot1)
    z = np.zeros(1)
    return np.r_[z, rot1], np.r_[z, trans], np.r_[z, rot2]


def simulate_wheel_odometry(
    T_true: list[np.ndarray], t_s: np.ndarray, spec: WheelOdometrySpec, rng: np.random.Generator, noise: bool
) -> PoseTrack:
    """Odometry poses of the base (module docstring) at each frame, as a :class:`PoseTrack`.

    ``T_true`` are the true tracker (base) poses in the map frame at the times ``t_s``;
    with ``noise`` off the true poses are reported. Odometry never drops out: every
    frame has a pose, with confidence "high".
    """
    n = len(T_true)
    if n == 0:
        return PoseTrack(poses=[], confidence=[], error_m=np.zeros(0), relocalised=[])
    if not noise:
        return PoseTrack(
            poses=[T.copy() for T in T_true], confidence=["high"] * n, error_m=np.zeros(n), relocalised=[False] * n
        )
    rot1, trans, rot2 = motion_steps(T_true)
    b = spec.wheel_base_m
    gain_r = (1.0 + spec.wheel_radius_error) / (1.0 + spec.wheel_radius_mismatch / 2.0)
    gain_l = (1.0 + spec.wheel_radius_error) / (1.0 - spec.wheel_radius_mismatch / 2.0)
    b_odo = b * (1.0 + spec.wheel_base_error)

    def measured(turn: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # wheel travel of a turn and a drive, read through the encoders and the assumed geometry
        s_r = (drive + turn * b / 2.0) * gain_r
        s_l = (drive - turn * b / 2.0) * gain_l
        return (s_r + s_l) / 2.0, (s_r - s_l) / b_odo

    t1, r1 = measured(rot1, np.zeros(n))  # t1, t2: a turn in place on unequal wheels creeps
    t_m, r_drive = measured(np.zeros(n), trans)
    t2, r2 = measured(rot2, np.zeros(n))
    t_m = t_m + t1 + t2
    # slip: random walks in distance driven and angle turned (fixed draw order, one per term)
    e_trans = rng.standard_normal(n) * spec.slip_m_per_sqrt_m * np.sqrt(trans)
    e_turn = rng.standard_normal(n) * spec.slip_rad_per_sqrt_rad * np.sqrt(np.abs(rot1) + np.abs(rot2))
    e_drive = rng.standard_normal(n) * spec.slip_rad_per_sqrt_m * np.sqrt(trans)
    t_m = t_m + e_trans
    # a drive's heading change (wheel mismatch, slip) is split evenly about the step
    r1 = r1 + 0.5 * (r_drive + e_turn + e_drive)
    r2 = r2 + 0.5 * (r_drive + e_turn + e_drive)

    x, y, th = planar_pose(T_true[0])
    poses: list[np.ndarray | None] = []
    err = np.zeros(n)
    for k in range(n):
        if k:
            th += r1[k]
            x += t_m[k] * np.cos(th)
            y += t_m[k] * np.sin(th)
            th += r2[k]
        Tt = T_true[k]
        _, _, th_true = planar_pose(Tt)
        p = np.array([x, y, Tt[2, 3]])
        poses.append(make_transform(rot_z(th - th_true) @ Tt[:3, :3], p))
        err[k] = float(np.linalg.norm(p - Tt[:3, 3]))
    return PoseTrack(poses=poses, confidence=["high"] * n, error_m=err, relocalised=[False] * n)


@dataclass(kw_only=True)
class WheelOdometry:
    """The base's wheel odometry as a trial's pose sensor (:class:`sim.sensors.base.PoseSensor`)."""

    spec: WheelOdometrySpec
    noise: bool

    def track(self, motion: TrackerMotion, rng: np.random.Generator) -> PoseTrack:
        return simulate_wheel_odometry(motion.poses, motion.times_s, self.spec, rng, self.noise)
