"""What a trial tells the pipeline of its sensors, as a team that has measured them knows them.

A team configures its pipeline from its robot: the camera mount it measured, the odometry's
latency from the driver's timestamps, and how far its T265 and its mount calibration can be
off (found by driving a measured loop in the arena, or from the datasheet). A poibench trial
gives the pipeline the same figures, taken from the scenario's sensor settings:

* the nominal mount (the simulator moves the camera by ``sensors.mount.error_*``, which the
  pipeline is not told) and how well it is known: ``localize.mount_sigma_deg`` and
  ``mount_sigma_m`` are the root mean square of the error's components, so the pipeline
  knows the calibration's size, not its direction;
* the depth image's registration error against the colour image
  (:func:`depth_registration_settings`);
* the odometry's latency (:func:`odometry_latency_settings`);
* the sizes of the T265's systematic errors, the priors of the SLAM's scale, drift and heading
  drift states and the height drift it adds to R, and the white odometry noise it lacks
  (:func:`odometry_prior_settings`), from the
  drift model of :mod:`sim.sensors.t265` and the arena's light and texture (its mean drift
  multiplier);
* whether the robot carries a thermal camera: without one the thermal detector is off
  (:func:`thermal_settings`), and with it the heat-source boxes of the colour network that
  the thermal camera does not vouch for (poi.heat_sources).

Without them the pipeline's defaults assume a worse odometry and mount than the default maze
has (a 10% scale error, 2% drift, a mount measured by hand) and its covariances come out
several times too large there (README "Covariance consistency").
"""

from __future__ import annotations

import numpy as np

from poi.core.geometry import matrix_to_quat_wxyz
from sim.sensors.t265 import DRIFT_DIRECTION_WANDER_RAD_PER_SQRT_M


def mount_settings(T: np.ndarray) -> list[str]:
    """The pipeline settings that give it the camera mount ``T`` (T_tracker_optical)."""
    q = matrix_to_quat_wxyz(T[:3, :3])
    return [
        f"mount.T_tracker_camera.translation_m=[{T[0, 3]:.6f}, {T[1, 3]:.6f}, {T[2, 3]:.6f}]",
        f"mount.T_tracker_camera.quaternion_wxyz=[{q[0]:.9f}, {q[1]:.9f}, {q[2]:.9f}, {q[3]:.9f}]",
    ]


def mount_prior_settings(sc) -> list[str]:
    """How well the pipeline knows its mount: the root mean square of the scenario's mount
    error components (``sensors.mount.error_rpy_deg``, ``error_t_m``) as its per-axis sigmas.

    >>> from sim.scenario import Scenario, apply_settings
    >>> mount_prior_settings(apply_settings(Scenario(), ["sensors.mount.error_rpy_deg=[0, 1, 0]"]))
    ['localize.mount_sigma_deg=0.57735', 'localize.mount_sigma_m=0']
    """
    m = sc.sensors.mount
    rms_deg = float(np.sqrt(np.mean(np.square(m.error_rpy_deg))))
    rms_m = float(np.sqrt(np.mean(np.square(m.error_t_m))))
    return [f"localize.mount_sigma_deg={rms_deg:.6g}", f"localize.mount_sigma_m={rms_m:.6g}"]


def depth_registration_settings(sc) -> list[str]:
    """The pipeline setting that tells it how far its depth image may sit off the colour image:
    the scenario's ``sensors.d435.depth.registration_error_px`` (the RMS of the offset drawn
    once per trial), 0 with the noise off.

    >>> from sim.scenario import Scenario
    >>> depth_registration_settings(Scenario())
    ['localize.registration_sigma_px=1']
    """
    on = 1.0 if sc.sensors.noise else 0.0
    return [f"localize.registration_sigma_px={on * sc.sensors.d435.depth.registration_error_px:.6g}"]


def odometry_latency_settings(sc) -> list[str]:
    """The pipeline setting that tells the SLAM its odometry's latency, as a team reads it off
    its sensor's data: the T265's ``latency_s`` when its noise is on and its driver does not
    already extrapolate; 0 for wheel odometry, a noise-free sensor or a predicting driver."""
    t265 = sc.sensors.t265
    stale = sc.sensors.noise and sc.sensors.pose_source == "t265" and not t265.latency_extrapolate
    return [f"slam.odometry_latency_s={t265.latency_s if stale else 0.0:g}"]


def odometry_prior_settings(sc, drift_multiplier: float) -> list[str]:
    """The SLAM's priors on its odometry's systematic errors (``slam.scale_sigma``,
    ``drift_sigma``, ``drift_sigma_per_sqrt_m``, ``heading_drift_sigma``,
    ``heading_drift_sigma_per_sqrt_m``, ``height_drift_sigma_per_m``, ``tilt_sigma_deg``) and
    its white heading and position noise (``sigma_theta_rad``, ``sigma_theta_per_rad``,
    ``sigma_xy_m``) for the scenario's T265, whose drift is ``drift_multiplier`` times its
    good-light figures on average in the arena.

    :mod:`sim.sensors.t265` drifts in x and y at ``drift_fraction`` m per metre in a horizontal
    direction drawn uniformly that turns by 0.2 rad per sqrt(m): each axis of the drift rate
    has sigma ``f m / sqrt(2)`` and its random walk sigma 0.2 times that per sqrt(m). Its heading
    drifts at ``yaw_drift_deg_per_m`` times the multiplier with a sign drawn once (no random
    walk), its height at a rate drawn once with sigma ``z_drift_fraction`` times the
    multiplier, its roll and pitch within ``tilt_sigma_deg``; distances are ``1 + scale_error``
    times the truth. Its heading does not walk as the robot turns, and its jitter (0.5 mm and
    a few hundredths of a degree per sample) does not add up from frame to frame, so the white
    heading noise of the SLAM's Q_c is 0 (``slam.sigma_theta_rad``, ``sigma_theta_per_rad``;
    the defaults are for a tracker whose gyro may walk) and so is its floor of white position
    noise per frame (``slam.sigma_xy_m``; the default's 0.5 mm a frame walks 1 cm over 400
    frames standing still, which made the default maze's SLAM position conservative, NEES
    1.02 against [1.19, 3.06]; docs/CONSISTENCY.md). The part that grows with distance
    (``sigma_xy_per_m``) stays: it holds what of the drift multiplier's changes along the
    route the prior, which takes its mean, lacks. With the noise off the T265 is
    exact and every prior is 0 (the SLAM leaves those states out). Wheel odometry keeps the
    pipeline's defaults (a wheel's errors are not this model's).

    >>> from sim.scenario import Scenario
    >>> odometry_prior_settings(Scenario(), 1.0)[1:3]
    ['slam.drift_sigma=0.00494975', 'slam.drift_sigma_per_sqrt_m=0.000989949']
    >>> odometry_prior_settings(Scenario(), 1.0)[-3:]
    ['slam.sigma_theta_rad=0', 'slam.sigma_theta_per_rad=0', 'slam.sigma_xy_m=0']
    """
    if sc.sensors.pose_source != "t265":
        return []
    t = sc.sensors.t265
    on = 1.0 if sc.sensors.noise else 0.0
    drift = on * t.drift_fraction * drift_multiplier / np.sqrt(2.0)
    return [
        f"slam.scale_sigma={on * abs(t.scale_error):.6g}",
        f"slam.drift_sigma={drift:.6g}",
        f"slam.drift_sigma_per_sqrt_m={drift * DRIFT_DIRECTION_WANDER_RAD_PER_SQRT_M:.6g}",
        f"slam.heading_drift_sigma={on * np.deg2rad(t.yaw_drift_deg_per_m) * drift_multiplier:.6g}",
        "slam.heading_drift_sigma_per_sqrt_m=0",
        f"slam.height_drift_sigma_per_m={on * t.z_drift_fraction * drift_multiplier:.6g}",
        f"slam.tilt_sigma_deg={on * t.tilt_sigma_deg:.6g}",
        "slam.sigma_theta_rad=0",
        "slam.sigma_theta_per_rad=0",
        "slam.sigma_xy_m=0",
    ]


def thermal_settings(sc) -> list[str]:
    """``thermal.enabled=false`` for a scenario without a thermal camera, else nothing.

    >>> from sim.scenario import Scenario, apply_settings
    >>> without = apply_settings(Scenario(), ["sensors.thermal.enabled=false"])
    >>> thermal_settings(Scenario()), thermal_settings(without)
    ([], ['thermal.enabled=false'])
    """
    return [] if sc.sensors.thermal.enabled else ["thermal.enabled=false"]


def mean_drift_multiplier(sim) -> float:
    """The arena's mean T265 drift multiplier along the route (1 without a T265 model)."""
    cond = sim.tracking_conditions
    return 1.0 if cond is None else float(np.mean(cond.multiplier))


def sensor_settings(T_tracker_optical_nominal: np.ndarray, sc, drift_multiplier: float) -> list[str]:
    """What a trial tells the pipeline of its sensors, as a team knows them (module docstring):
    the nominal mount, scenario ``sc``'s mount, depth registration and T265 error sizes and
    the arena's mean drift multiplier (:func:`mean_drift_multiplier`; a perception record keeps
    both inputs, so a replay computes the settings with the code of its day)."""
    return (
        mount_settings(T_tracker_optical_nominal)
        + mount_prior_settings(sc)
        + depth_registration_settings(sc)
        + odometry_latency_settings(sc)
        + odometry_prior_settings(sc, drift_multiplier)
        + thermal_settings(sc)
    )


def simulation_sensor_settings(sim) -> list[str]:
    """:func:`sensor_settings` of a :class:`sim.simulator.Simulation`."""
    return sensor_settings(sim.T_tracker_optical_nominal, sim.scenario, mean_drift_multiplier(sim))
