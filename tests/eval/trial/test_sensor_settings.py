"""eval.trial.sensor_settings: what a trial tells the pipeline of its sensors, and that the
SLAM's odometry priors describe the simulator's T265."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from eval.trial.sensor_settings import mount_prior_settings, odometry_latency_settings, odometry_prior_settings
from poi.config import apply_overrides, load_config
from sim.scenario import Scenario, apply_settings
from sim.sensors.t265 import RelocaliseSpec, T265Spec, simulate_t265

# the simulated T265 with every error off (drift, jitter, latency, tilt, scale, relocalisation):
# each test turns on the one it measures
QUIET_T265 = replace(
    T265Spec(), drift_fraction=0.0, z_drift_fraction=0.0, yaw_drift_deg_per_m=0.0, tilt_sigma_deg=0.0,
    scale_error=0.0, latency_s=0.0, jitter_m=0.0, jitter_deg=0.0, relocalise=RelocaliseSpec(enabled=False),
)  # fmt: skip


def _values(sets: list[str]) -> dict[str, float]:
    return {k: float(v) for k, v in (s.split("=", 1) for s in sets)}


def test_the_slam_is_told_the_odometry_latency_the_sensor_has():
    assert odometry_latency_settings(Scenario()) == ["slam.odometry_latency_s=0.01"]  # the T265's
    for sets in (["sensors.noise=false"], ["sensors.t265.latency_extrapolate=true"]):
        assert odometry_latency_settings(apply_settings(Scenario(), sets)) == ["slam.odometry_latency_s=0"], sets
    wheels = apply_settings(Scenario(), ["robot.kind=turtlebot", "sensors.pose_source=wheels"])
    assert odometry_latency_settings(wheels) == ["slam.odometry_latency_s=0"]
    assert odometry_latency_settings(apply_settings(Scenario(), ["sensors.t265.latency_s=0.03"])) == [
        "slam.odometry_latency_s=0.03"
    ]


def test_the_mount_prior_is_the_rms_of_the_calibration_error():
    assert _values(mount_prior_settings(Scenario())) == {
        "localize.mount_sigma_deg": 0.0,
        "localize.mount_sigma_m": 0.0,
    }
    hard = apply_settings(
        Scenario(), ["sensors.mount.error_rpy_deg=[0.5, 1.0, 0.5]", "sensors.mount.error_t_m=[0.01, 0.0, 0.01]"]
    )
    v = _values(mount_prior_settings(hard))
    assert v["localize.mount_sigma_deg"] == pytest.approx(np.sqrt(1.5 / 3), rel=1e-5)  # 0.707
    assert v["localize.mount_sigma_m"] == pytest.approx(np.sqrt(2e-4 / 3), rel=1e-5)  # 8.2 mm


def test_the_odometry_priors_follow_the_t265_settings_and_the_arena():
    hard = apply_settings(Scenario(), ["sensors.t265.drift_fraction=0.03", "sensors.t265.scale_error=-0.1"])
    v = _values(odometry_prior_settings(hard, 2.0))
    assert v["slam.scale_sigma"] == pytest.approx(0.1)
    assert v["slam.drift_sigma"] == pytest.approx(0.03 * 2.0 / np.sqrt(2), rel=1e-5)
    assert v["slam.drift_sigma_per_sqrt_m"] == pytest.approx(0.2 * v["slam.drift_sigma"], rel=1e-4)
    assert v["slam.heading_drift_sigma"] == pytest.approx(np.deg2rad(0.08) * 2.0, rel=1e-5)
    assert v["slam.height_drift_sigma_per_m"] == pytest.approx(0.002 * 2.0)
    assert v["slam.tilt_sigma_deg"] == pytest.approx(0.3)  # bounded: light does not grow it
    # the simulated T265's heading does not walk as it turns, and its jitter does not add up
    assert v["slam.sigma_theta_rad"] == 0.0 and v["slam.sigma_theta_per_rad"] == 0.0
    # nor does its position jitter (test_the_t265s_position_jitter_does_not_add_up)
    assert v["slam.sigma_xy_m"] == 0.0
    # an exact sensor: no systematic error, so the SLAM leaves those states out
    clean = _values(odometry_prior_settings(apply_settings(Scenario(), ["sensors.noise=false"]), 1.0))
    assert set(clean.values()) == {0.0}
    # wheel odometry keeps the pipeline's defaults
    assert (
        odometry_prior_settings(
            apply_settings(Scenario(), ["robot.kind=turtlebot", "sensors.pose_source=wheels"]), 1.0
        )
        == []
    )
    # every setting is one the pipeline knows
    apply_overrides(load_config(), odometry_prior_settings(hard, 2.0) + mount_prior_settings(hard))


def test_the_t265s_position_jitter_does_not_add_up():
    """With its drift off, the simulated T265 standing still for 400 frames is off by its
    jitter at the end as at the start: a white error per sample, not a random walk, so the
    SLAM's white position noise per frame (``slam.sigma_xy_m``) is 0 in a trial. A walk of the
    pipeline's default 0.5 mm a frame would be 10 mm off after 400 frames."""
    jitter_m = 0.0005
    spec = replace(QUIET_T265, jitter_m=jitter_m)

    def still(t):
        T = np.tile(np.eye(4), (len(np.atleast_1d(t)), 1, 1))
        T[:, 2, 3] = 0.5
        return T

    t_s = np.arange(400) / 30.0
    err = np.array(
        [
            np.array(simulate_t265(still, t_s, spec, np.random.default_rng(s), noise=True).poses)[:, :2, 3]
            for s in range(50)
        ]
    )  # (run, frame, axis)
    first, last = err[:, :50].std(), err[:, -50:].std()
    assert last == pytest.approx(first, rel=0.15)
    assert last < 2 * jitter_m  # a walk: 0.5 mm * sqrt(375) = 9.7 mm


def test_the_drift_priors_are_the_simulated_t265s_spread():
    """Over many seeds, the drift rate of the simulated T265 on its first metre has the per-axis
    standard deviation the prior says (its direction is uniform), and its heading drift rate
    the size the prior says (its sign is drawn once)."""
    spec = replace(QUIET_T265, drift_fraction=0.01)
    sc = Scenario()
    sc.sensors.t265 = replace(spec, yaw_drift_deg_per_m=0.1)
    v = _values(odometry_prior_settings(sc, 1.0))

    def line(t):  # 0.5 m/s along x
        t = np.maximum(np.asarray(t, float), 0.0)
        T = np.tile(np.eye(4), (len(t), 1, 1))
        T[:, 0, 3], T[:, 2, 3] = 0.5 * t, 0.5
        return T

    t_s = np.array([0.0, 2.0])  # 1 m: the direction turns by 0.2 rad at most one sigma
    rates = np.array(
        [
            simulate_t265(line, t_s, spec, np.random.default_rng(s), noise=True).poses[-1][:2, 3] - [1.0, 0.0]
            for s in range(600)
        ]
    )
    # 600 draws: the sample sigma is within 6% of the truth 99% of the time (chi2 with 600 dof)
    assert rates.std(axis=0) == pytest.approx([v["slam.drift_sigma"]] * 2, rel=0.08)
    yaw = simulate_t265(line, t_s, sc.sensors.t265, np.random.default_rng(0), noise=True).poses[-1]
    assert abs(np.arctan2(yaw[1, 0], yaw[0, 0])) == pytest.approx(v["slam.heading_drift_sigma"], rel=1e-6)
