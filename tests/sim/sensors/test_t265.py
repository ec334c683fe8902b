"""The T265 model (sim/sensors/t265.py): 6-DoF drift, 200 Hz sampling, latency, conditions, relocalisation."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from poi.core.geometry import make_transform, rot_z
from sim.scenario import Scenario, ScenarioError, apply_settings
from sim.sensors.t265 import RelocaliseSpec, T265Spec, TrackingConditions, pose_interpolator, simulate_t265
from sim.sensors.tracking_conditions import T265ConditionsSpec, drift_multiplier

# every effect off: the reported pose is the truth sampled at rate_hz and interpolated
CLEAN = T265Spec(
    drift_fraction=0.0,
    z_drift_fraction=0.0,
    yaw_drift_deg_per_m=0.0,
    tilt_sigma_deg=0.0,
    latency_s=0.0,
    jitter_m=0.0,
    jitter_deg=0.0,
    relocalise=RelocaliseSpec(enabled=False),
)


def _line(speed=0.5, z=0.5):
    """At rest until t = 0, then x = speed t, heading +x: exact at any time."""

    def truth(t):
        t = np.maximum(np.asarray(t, float), 0.0)
        T = np.tile(np.eye(4), (len(t), 1, 1))
        T[:, 0, 3], T[:, 2, 3] = speed * t, z
        return T

    return truth


def _circle(radius=1.0, rate=1.0):
    """Driving round a circle of ``radius`` at ``rate`` rad/s, heading along it."""

    def truth(t):
        a = rate * np.asarray(t, float)
        T = np.tile(np.eye(4), (len(a), 1, 1))
        T[:, :3, :3] = Rotation.from_euler("z", (a + np.pi / 2)[:, None]).as_matrix()
        T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = radius * np.cos(a), radius * np.sin(a), 0.5
        return T

    return truth


def _yaw(R):
    return float(np.arctan2(R[1, 0], R[0, 0]))


def test_interpolation_is_exact_on_a_straight_turning_path_and_the_chord_on_a_circle():
    # constant velocity and turn rate: lerp + slerp between samples give the truth exactly
    def truth(t):
        t = np.asarray(t, float)
        T = np.tile(np.eye(4), (len(t), 1, 1))
        T[:, :3, :3] = Rotation.from_euler("z", 0.3 * t[:, None]).as_matrix()
        T[:, :3, 3] = np.stack([0.4 * t, -0.1 * t, 0.5 + 0.0 * t], axis=1)
        return T

    t_s = 0.0123 + 0.1037 * np.arange(40)
    track = simulate_t265(truth, t_s, CLEAN, np.random.default_rng(0), noise=True)
    assert np.allclose(np.array(track.poses), truth(t_s), atol=1e-12)
    # on a circle a frame halfway between two samples lies on the chord: R (1 - cos(w dt / 2))
    # inside the circle; at 10 Hz and 1 rad/s that is 1 - cos(0.05) = 1.2497 mm, at 200 Hz 3.1 um
    for rate_hz, sagitta in ((10.0, 1.0 - np.cos(0.05)), (200.0, 1.0 - np.cos(0.0025))):
        dt = 1.0 / rate_hz
        t_mid = 1.0 + dt * (np.arange(10) + 0.5)
        spec = replace(CLEAN, rate_hz=rate_hz)
        tr = simulate_t265(_circle(), t_mid, spec, np.random.default_rng(0), noise=True)
        assert tr.error_m == pytest.approx(np.full(10, sagitta), rel=1e-6)


def test_latency_gives_the_pose_of_t_minus_latency_or_extrapolates_it():
    t_s = np.arange(1.0, 3.0, 0.1)
    spec = replace(CLEAN, latency_s=0.05)
    tr = simulate_t265(_line(0.5), t_s, spec, np.random.default_rng(0), noise=True)
    x = np.array([T[0, 3] for T in tr.poses])
    assert x == pytest.approx(0.5 * (t_s - 0.05), abs=1e-12)  # 25 mm behind at 0.5 m/s
    assert tr.error_m == pytest.approx(np.full(len(t_s), 0.025), abs=1e-12)
    ahead = simulate_t265(
        _line(0.5), t_s, replace(spec, latency_extrapolate=True), np.random.default_rng(0), noise=True
    )
    assert [T[0, 3] for T in ahead.poses] == pytest.approx(0.5 * t_s, abs=1e-12)


def test_z_roll_and_pitch_drift_with_their_set_sizes():
    # 10 m at 2 m/s; z drifts at a rate N(0, 0.01^2) m/m: z error at 10 m has sigma 0.1 m;
    # roll and pitch are Gauss-Markov over 1 m: after 10 m their sigma is 1 degree
    spec = replace(CLEAN, z_drift_fraction=0.01, tilt_sigma_deg=1.0, tilt_correlation_m=1.0)
    t_s = np.array([0.0, 5.0])
    dz, roll, pitch = [], [], []
    for seed in range(200):
        tr = simulate_t265(_line(2.0), t_s, spec, np.random.default_rng(seed), noise=True)
        T = tr.poses[-1]
        dz.append(T[2, 3] - 0.5)
        _, r, p = Rotation.from_matrix(T[:3, :3]).as_euler("ZXY", degrees=True)
        roll.append(r)
        pitch.append(p)
        assert T[0, 3] == pytest.approx(10.0, abs=1e-9)  # no x, y or yaw drift was asked for
    # 200 draws: a standard deviation is good to about 5% (1 sigma); 15% is 3 sigma
    assert np.std(dz) == pytest.approx(0.1, rel=0.15)
    assert np.std(roll) == pytest.approx(1.0, rel=0.15)
    assert np.std(pitch) == pytest.approx(1.0, rel=0.15)
    assert abs(np.corrcoef(roll, pitch)[0, 1]) < 0.2


def test_xy_drift_is_a_fraction_of_distance_and_yaw_drift_turns_heading():
    t_s = np.linspace(0.0, 50.0, 101)  # 25 m at 0.5 m/s
    spec = replace(CLEAN, drift_fraction=0.007)
    errs = [
        simulate_t265(_line(0.5), t_s, spec, np.random.default_rng(s), noise=True).error_m[-1] for s in range(40)
    ]
    # the direction wanders slowly (0.2 rad / sqrt(m)): |e| <= 0.7% of 25 m and near it
    assert max(errs) <= 0.007 * 25 + 1e-9
    assert 0.8 * 0.175 < np.mean(errs) <= 0.175
    yaw = simulate_t265(_line(0.5), t_s, replace(CLEAN, yaw_drift_deg_per_m=0.5), np.random.default_rng(0), True)
    assert abs(np.degrees(_yaw(yaw.poses[-1]))) == pytest.approx(12.5, abs=0.01)  # 0.5 deg/m x 25 m


def test_drift_grows_in_the_dark_and_false_jumps_come_more_often():
    t_s = np.linspace(0.0, 50.0, 101)
    spec = replace(T265Spec(), relocalise=RelocaliseSpec(enabled=False), jitter_m=0.0)
    light = TrackingConditions(t_s=np.array([0.0, 50.0]), multiplier=np.array([1.0, 1.0]))
    dark = TrackingConditions(t_s=np.array([0.0, 50.0]), multiplier=np.array([3.0, 3.0]))
    e_light, e_dark = [], []
    for seed in range(20):
        e_light.append(simulate_t265(_line(0.5), t_s, spec, np.random.default_rng(seed), True, light).error_m[-1])
        e_dark.append(simulate_t265(_line(0.5), t_s, spec, np.random.default_rng(seed), True, dark).error_m[-1])
    # the same draws over three times the effective distance: every error grows about 3x
    # (all but the 10 ms latency's 5 mm and the tilt, which do not scale)
    assert np.mean(e_dark) == pytest.approx(3.0 * np.mean(e_light), rel=0.1)
    jumpy = replace(spec, jumps=replace(spec.jumps, rate_per_min=20.0))
    n_light = sum(
        c == "medium"
        for c in simulate_t265(_line(0.5), t_s, jumpy, np.random.default_rng(1), True, light).confidence
    )
    n_dark = sum(
        c == "medium"
        for c in simulate_t265(_line(0.5), t_s, jumpy, np.random.default_rng(1), True, dark).confidence
    )
    assert n_dark > n_light


def test_drift_multiplier_from_light_and_texture():
    spec = T265ConditionsSpec()  # good above 500 lux and contrast 0.12; gains 2 and 2
    m = drift_multiplier(np.array([1000.0, 80.0, 1000.0, 250.0]), np.array([0.15, 0.15, 0.06, 0.03]), spec)
    assert m.tolist() == pytest.approx([1.0, 1.0 + 2.0 * 0.84, 2.0, 1.0 + 2.0 * 0.5 + 2.0 * 0.75])


def test_relocalisation_pulls_the_error_back_on_a_second_lap():
    # two laps of a 4 x 4 m square; back at the start the tracker recognises it
    t, T, yaw, p = [0.0], [make_transform(np.eye(3), [0, 0, 0.5])], 0.0, np.zeros(3)
    for _ in range(2):
        for _side in range(4):
            p = p + 4.0 * np.array([np.cos(yaw), np.sin(yaw), 0.0])
            t.append(t[-1] + 8.0)
            T.append(make_transform(rot_z(yaw), p + [0, 0, 0.5]))
            yaw += np.pi / 2
            t.append(t[-1] + 1.0)
            T.append(make_transform(rot_z(yaw), p + [0, 0, 0.5]))
    truth = pose_interpolator(np.array(t), T)
    t_s = np.arange(0.0, t[-1], 0.1)
    spec = replace(T265Spec(), drift_fraction=0.03, yaw_drift_deg_per_m=0.5)
    on = replace(spec, relocalise=RelocaliseSpec(probability=1.0))
    off = replace(spec, relocalise=RelocaliseSpec(enabled=False))
    tr_on = simulate_t265(truth, t_s, on, np.random.default_rng(4), noise=True)
    tr_off = simulate_t265(truth, t_s, off, np.random.default_rng(4), noise=True)
    assert len(tr_on.relocalisations_s) > 0 and tr_on.relocalisations_s[0] >= 36.0  # on the second lap
    lap2 = t_s > 40.0
    # every keyframe of lap 2 closes the loop on lap 1: the error is lap 1's, not twice it
    assert np.mean(tr_on.error_m[lap2]) < 0.6 * np.mean(tr_off.error_m[lap2])
    assert np.allclose(tr_on.error_m[t_s < 36.0], tr_off.error_m[t_s < 36.0])
    # each loop closure is announced once, on the first frame whose pose holds its jump: that
    # of t_k - latency, interpolated between the samples around it, so within a frame and a
    # sample after the closure
    flagged = t_s[np.array(tr_on.relocalised)]
    assert len(flagged) == len(tr_on.relocalisations_s)
    lag = flagged - np.asarray(tr_on.relocalisations_s) - on.latency_s
    assert np.all(lag > -1.0 / on.rate_hz) and np.all(lag <= 0.1 + 1e-9)
    assert not any(tr_off.relocalised)


def test_scale_error_dropouts_clean_mode_and_determinism():
    t_s = np.linspace(0.0, 20.0, 101)
    tr = simulate_t265(_line(0.5), t_s, replace(CLEAN, scale_error=-0.2), np.random.default_rng(0), True)
    assert tr.poses[-1][0, 3] == pytest.approx(8.0)  # 10 m reported 20% short
    clean = simulate_t265(_line(0.5), t_s, T265Spec(), np.random.default_rng(0), noise=False)
    assert np.allclose(np.array(clean.poses), _line(0.5)(t_s))
    spec = T265Spec()
    spec.dropouts.rate_per_min = 30.0
    t_long = np.linspace(0.0, 60.0, 601)
    a = simulate_t265(_line(0.5), t_long, spec, np.random.default_rng(3), noise=True)
    missing = [k for k, p in enumerate(a.poses) if p is None]
    assert missing and all(a.confidence[k] == "low" for k in missing)
    b = simulate_t265(_line(0.5), t_long, spec, np.random.default_rng(3), noise=True)
    assert [p.tobytes() if p is not None else None for p in a.poses] == [
        p.tobytes() if p is not None else None for p in b.poses
    ]


@pytest.mark.parametrize(
    "setting, message",
    [
        ("sensors.t265.latency_s=-1", "sensors.t265.latency_s: expected a value >= 0 and <= 1, got -1"),
        ("sensors.t265.relocalise.probability=2", "sensors.t265.relocalise.probability: expected a value >= 0"),
        ("sensors.t265.conditions.good_lux=0", "sensors.t265.conditions.good_lux: expected a value > 0, got 0"),
        ("sensors.t265.dropouts.duration_s=[5, 1]", "duration_s: expected (shortest, longest), got [5.0, 1.0]"),
        ("sensors.thermal.metal_emissivity=1.5", "sensors.thermal.metal_emissivity: expected a value >= 0"),
        ("sensors.thermal.ffc_interval_s=0", "sensors.thermal.ffc_interval_s: expected a value > 0, got 0"),
    ],
)
def test_bad_settings_are_refused_at_load_naming_the_field(setting, message):
    with pytest.raises(ScenarioError) as err:
        apply_settings(Scenario(), [setting])
    assert message in str(err.value) and "\n" not in str(err.value)
