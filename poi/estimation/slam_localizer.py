"""Drift correction for the pipeline: odometry poses and landmark observations in, corrected
poses and observations out (``localize.mode: slam``).

Per frame, with the odometry pose ``T_map_tracker`` = (Q, t) the frame carries (T265 or
wheel odometry, drift included):

1. the planar pose (x, y, theta) of the tracker is read from (Q, t) (theta = the heading
   of Q's x axis) and extrapolated over the odometry's latency (``slam.odometry_latency_s``)
   at the velocity of the last two reports, so that the filter estimates the pose at the
   frame's time (a T265 reports the pose of 10 ms earlier: turning at 1.6 rad/s, as the
   robot's look-around does, that is 0.9 degrees); the increment from the previous
   frame's extrapolated pose ([Bouda2025]_ eq. 11) drives
   :meth:`poi.estimation.slam.UkfSlam.predict`. With a latency the first report cannot be
   extrapolated (no velocity yet): that frame keeps the odometry's pose, its observations
   are marked stale (:attr:`SlamStep.stale`: placed with a pose up to a degree off, which
   their R does not hold, so the pipeline drops them; a placard 1.7 m away came out 28 mm
   off across the ray against a sigma of 5 mm and started its track there,
   docs/CONSISTENCY.md "The first frame's stale pose"), and the filter starts at the next
   one, on its extrapolated pose with the start covariance (it started on the stale report,
   up to a degree off during a turn against a start sigma of 0.17 degrees, and frame 0's
   pose NEES reached 36). A relocalisation the
   odometry announces (``Frame.pose_relocalised``) is a loop closure: the pose jumped back
   toward the error it had at a place passed before, often too little to stand out by speed
   (rrl's: 3-5 cm and a degree). The jump is no motion, and the filter, whose drift states
   already take the odometry's drift out, must not follow it: the increments of that frame
   and the next (the pose interpolation may split the jump between them) are replaced by
   the last clean one (:func:`lost_increment`), and both frames are extrapolated over the
   latency at the velocity before the jump. An increment faster than ``slam.max_speed_m_s``
   is an unannounced jump (a false relocalisation) and is replaced the same way, for its
   frame alone; it had held the filter still with the jump's size as noise, which lost the
   turn the robot made in that frame. Taken as motion, a 1-degree loop closure put a
   whole rrl run's heading NEES at 13, and taking it with the noise of the drift it removes
   made `rrl-hard`'s 1.1 m closure (hard-02) a heading error of degrees (README
   "Covariance consistency");
2. observations of static types (``slam.landmark_types``) within ``slam.max_range_m``
   are expressed in the levelled robot frame: ``p_l = Rz(theta)^T (p_map - t)``, which
   undoes exactly the pose the observation was placed with, and ``R_l = Rz(theta)^T R
   Rz(theta)`` (its shared part likewise, for the landmark's view bias); their (x, y) parts
   update the filter (:meth:`UkfSlam.observe`);
3. the corrected pose keeps the odometry's height, roll and pitch and replaces its
   planar part with the filter's: ``Q' = Rz(theta' - theta) Q``, ``t' = (x', y', t_z)``;
   every observation is moved to ``p' = Rz(theta' - theta) (p_map - t) + t'`` and its
   covariance gets the pose uncertainty: ``R' = Rz R Rz^T + J P_pose J^T + H`` with
   ``J = d p' / d (x', y', theta')`` (first-order propagation, [Avevor2022]_ 2.2.2's method)
   and ``H`` what the planar filter does not estimate: the height error the odometry has
   gathered, ``(slam.height_drift_sigma_per_m * d)^2`` on z after d metres travelled, and
   its roll and pitch error ``slam.tilt_sigma_deg`` at the point's distance
   (:func:`poi.estimation.covariance.tilt_covariance`). All repeat from frame to frame, so
   they are in the observation's shared part.

Each measurement is used once. The observations are moved with the filter's pose
*before* this frame's landmark update (after the prediction, ``(x', y', theta')`` and
``P_pose`` of the predicted state), and the returned frame pose (:attr:`SlamStep.pose`,
for the in-view test and the fiducials) is the one after it. Mapping an observation with
the pose its own landmark update produced would use it twice: the update pulls the pose
so that the observation agrees with its landmark, and the tracker then fuses the
observation again as if its error were independent of that pose, so the tracks'
covariance came out optimistic. What remains (the tracker treats the pose errors of
successive frames as independent, where drift correlates them) is measured with
``poibench consistency`` (README, "Covariance consistency").

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from poi.config import SlamConfig
from poi.core.geometry import planar_pose, rot_z, wrap_angle
from poi.core.types import Observation
from poi.estimation.covariance import tilt_covariance
from poi.estimation.slam import LandmarkObservation, UkfSlam, odometry_increment


@dataclass(kw_only=True)
class SlamStep:
    """One frame's correction: the corrected pose (after this frame's update) and the
    observations mapped with the pose before it (same order; module docstring)."""

    pose: np.ndarray
    observations: list[Observation]
    stale: bool = False  # the observations were placed with a pose older than the frame


def corrected_pose(T_odom: np.ndarray, odom: np.ndarray, planar: np.ndarray) -> np.ndarray:
    """The odometry pose with its planar part (x, y, theta) replaced by ``planar``: height,
    roll and pitch kept, ``Q' = Rz(theta' - theta) Q``, ``t' = (x', y', t_z)``."""
    T = np.array(T_odom, dtype=float)
    T[:3, :3] = rot_z(float(wrap_angle(planar[2] - odom[2]))) @ T_odom[:3, :3]
    T[:2, 3] = planar[:2]
    return T


def lost_increment(
    previous: tuple[np.ndarray, float] | None, dt: float, n: int, cfg: SlamConfig
) -> tuple[np.ndarray, tuple[float, float]]:
    """The increment of a frame whose odometry jumped, the ``n``-th such frame in a row, and
    the standard deviations (m, rad) of its error: the last clean increment ``previous``
    (increment, its duration) scaled to this
    frame's duration (constant velocity), off by n changes of the robot's speed and turn rate
    from frame to frame (``slam.relocalisation_speed_sigma_m_s``,
    ``slam.relocalisation_turn_sigma_rad_s``, times ``dt`` each: the velocity walks, so the
    n-th frame's error is the sum of n changes); zero motion when there is no clean increment.

    >>> from poi.config import SlamConfig
    >>> cfg = SlamConfig(relocalisation_speed_sigma_m_s=0.05, relocalisation_turn_sigma_rad_s=0.25)
    >>> d, s = lost_increment((np.array([0.01, 0.0, 0.02]), 0.05), 0.1, 2, cfg)
    >>> d.tolist(), [round(x, 6) for x in s]
    ([0.02, 0.0, 0.04], [0.01, 0.05])
    """
    sigma = (n * cfg.relocalisation_speed_sigma_m_s * dt, n * cfg.relocalisation_turn_sigma_rad_s * dt)
    if previous is None or previous[1] <= 0.0:
        return np.zeros(3), sigma
    return previous[0] * (dt / previous[1]), sigma


class SlamLocalizer:
    """Runs :class:`poi.estimation.slam.UkfSlam` on a stream of odometry poses and observations."""

    def __init__(self, cfg: SlamConfig) -> None:
        self.cfg = cfg
        self.landmark_types = frozenset(cfg.landmark_types)
        self.slam: UkfSlam | None = None
        self._last_odometry: np.ndarray | None = None  # as reported, and its time
        self._last_t_s = 0.0
        self._last_filter_odometry: np.ndarray | None = None  # extrapolated to the frame time
        self.jumps = 0  # increments faster than slam.max_speed_m_s, taken as relocalisations
        self.distance_m = 0.0  # travelled so far, by the odometry's increments (jumps not counted)
        self.relocalisations = 0  # announced relocalisations (Frame.pose_relocalised)
        self._jumped = 0  # frames left whose increment may hold an announced jump
        self._last_increment: tuple[np.ndarray, float] | None = None  # the last clean one, and its dt
        self._lost = 0  # frames in a row whose increment was replaced (lost_increment)
        self._velocity: tuple[np.ndarray, float] | None = None  # last two reports' difference, time

    def _report_difference(self, reported: np.ndarray, t_s: float) -> tuple[np.ndarray, float] | None:
        """The difference of this report from the last (heading wrapped) and the time between
        them; None at the first report or when the time did not advance."""
        if self._last_odometry is None or t_s <= self._last_t_s:
            return None
        d = reported - self._last_odometry
        d[2] = wrap_angle(d[2])
        return d, t_s - self._last_t_s

    def frame_time_odometry(self, odom: np.ndarray, velocity: tuple[np.ndarray, float] | None) -> np.ndarray:
        """The reported planar pose extrapolated over ``slam.odometry_latency_s`` at
        ``velocity`` (a difference of two reports and the time between them): the pose at the
        frame's time (what librealsense's pose prediction does). Without a velocity (frame 0),
        or with latency 0, the pose as reported."""
        lat = self.cfg.odometry_latency_s
        if lat <= 0.0 or velocity is None:
            return odom
        d, dt = velocity
        out = odom + d * (lat / dt)
        out[2] = wrap_angle(out[2])
        return out

    def step(
        self, T_odom: np.ndarray, observations: list[Observation], t_s: float, relocalised: bool = False
    ) -> SlamStep:
        reported = planar_pose(T_odom)
        if self.slam is None and self.cfg.odometry_latency_s > 0.0 and self._last_odometry is None:
            # a stale pose and no velocity yet to bring it to the frame's time: the filter
            # starts at the next frame (module docstring); these observations, placed with the
            # stale pose, are marked so
            self._last_odometry, self._last_t_s = reported, t_s
            return SlamStep(pose=np.array(T_odom, dtype=float), observations=list(observations), stale=True)
        if relocalised:
            # the pose interpolation may split the jump between this frame and the next
            self.relocalisations += 1
            self._jumped = 2
        jumped = self._jumped > 0
        # the velocity to extrapolate with: the last two reports', or, when the odometry jumped
        # and they straddle the jump, the one before it
        current = self._report_difference(reported, t_s)
        before_jump = current if current is None or self._velocity is None else self._velocity
        odom = self.frame_time_odometry(reported, before_jump if jumped else current)
        last = self._last_filter_odometry  # set with the filter, after its first frame
        if self.slam is None or last is None:
            self.slam = UkfSlam(self.cfg, pose0=tuple(odom))
        else:
            delta = odometry_increment(last, odom)
            dt = t_s - self._last_t_s
            if not jumped and dt > 0.0 and float(np.hypot(delta[0], delta[1])) > self.cfg.max_speed_m_s * dt:
                # faster than the robot can move: the odometry jumped unannounced (a false
                # relocalisation); this frame's extrapolation over the latency held it too
                self.jumps += 1
                jumped, self._jumped = True, 1
                odom = self.frame_time_odometry(reported, before_jump)
            if jumped:
                # the increment holds the motion and the jump, which no model here can part:
                # the motion is taken as the last clean increment's, and the filter learns
                # what that may miss (lost_increment)
                self._lost += 1
                delta, sigma = lost_increment(self._last_increment, dt, self._lost, self.cfg)
                self.slam.predict(delta, extra_sigma=sigma)
            else:
                self._lost = 0
                self.slam.predict(delta)
                self._last_increment = (delta, dt)
            self.distance_m += float(np.hypot(delta[0], delta[1]))
        if current is not None:
            self._velocity = before_jump if jumped else current
        self._jumped = max(self._jumped - 1, 0)
        self._last_odometry, self._last_t_s, self._last_filter_odometry = reported, t_s, odom
        odom = reported  # the observations were placed with the reported pose
        prior_pose, prior_P = self.slam.pose, self.slam.pose_covariance  # before this frame's update

        Rz_T = rot_z(odom[2]).T
        t = T_odom[:3, 3]
        lms: list[LandmarkObservation] = []
        for obs in observations:
            if obs.detection.type not in self.landmark_types:
                continue
            if float(np.linalg.norm(obs.position_cam)) > self.cfg.max_range_m:
                continue
            p_l = Rz_T @ (obs.position_map - t)
            R_l = Rz_T @ obs.R @ Rz_T.T
            S_l = None if obs.R_shared is None else (Rz_T @ obs.R_shared @ Rz_T.T)[:2, :2]
            lms.append(
                LandmarkObservation(class_name=obs.detection.class_name, xy=p_l[:2], R=R_l[:2, :2], R_shared=S_l)
            )
        self.slam.observe(lms, t_s)

        T_prior = corrected_pose(T_odom, odom, prior_pose)
        Rd = T_prior[:3, :3] @ T_odom[:3, :3].T  # Rz(theta' - theta)
        # the height and tilt errors of the odometry, which the planar filter does not hold
        height = np.zeros((3, 3))
        height[2, 2] = (self.cfg.height_drift_sigma_per_m * self.distance_m) ** 2
        tilt = np.deg2rad(self.cfg.tilt_sigma_deg)
        corrected = []
        for obs in observations:
            p_rel = Rd @ (obs.position_map - t)  # the point relative to the corrected tracker
            p = p_rel + T_prior[:3, 3]
            J = np.zeros((3, 3))
            J[0, 0] = J[1, 1] = 1.0
            J[0, 2], J[1, 2] = -p_rel[1], p_rel[0]  # d(Rz(theta) v)/d theta = (-v_y, v_x)
            pose_part = J @ prior_P @ J.T + height + tilt_covariance(p_rel, tilt)
            R = Rd @ obs.R @ Rd.T + pose_part
            # the filter's pose error, the height drift and the tilt repeat from frame to frame:
            # shared, not fresh
            shared = pose_part if obs.R_shared is None else Rd @ obs.R_shared @ Rd.T + pose_part
            corrected.append(dataclasses.replace(obs, position_map=p, R=R, R_shared=shared))
        return SlamStep(pose=corrected_pose(T_odom, odom, self.slam.pose), observations=corrected)

    @property
    def n_landmarks(self) -> int:
        return 0 if self.slam is None else len(self.slam.landmarks)
