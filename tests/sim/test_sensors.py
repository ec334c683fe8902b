"""Sensor models: depth noise statistics, edge shadows, T265 drift magnitude, thermal registration."""

import numpy as np
import pytest

from poi.core.depth_units import to_z16
from poi.core.geometry import make_transform, rot_z
from poi.core.sensor_noise import depth_sigma_m
from sim.scenario import DepthSpec, T265Spec, ThermalSpec
from sim.sensors.d435_depth import (
    disparity_noise,
    edge_shadow_mask,
    simulate_depth,
)
from sim.sensors.noise_pool import NoisePool, two_sided_threshold
from sim.sensors.t265 import simulate_t265
from sim.sensors.thermal import thermal_image


@pytest.mark.parametrize("z", [1.0, 2.0, 4.0])
def test_depth_noise_sigma_grows_with_square_of_distance(z):
    spec = DepthSpec()
    rng = np.random.default_rng(0)
    zs = disparity_noise(np.full((400, 400), z, np.float32), spec, rng)
    expected = depth_sigma_m(
        z, sigma_d_px=spec.sigma_d_px, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m
    )
    # 160k samples: the std estimate is good to well under 1%; quantisation to 1/32 px
    # adds variance q^2/12 in disparity (about 2% of sigma_d^2 at sigma_d = 0.08), so 5%
    assert np.std(zs) == pytest.approx(expected, rel=0.05)
    assert abs(np.mean(zs) - z) < 0.05 * expected + 1e-4


def test_pooled_noise_has_the_same_statistics_and_is_deterministic():
    spec = DepthSpec(edge_holes=False, dropout=0.02)
    pool = NoisePool.standard_normal([7, 1, 99], 3 * 300 * 400)
    z = np.full((300, 400), 2.0, np.float32)
    a = simulate_depth(z, spec, 612.4, np.random.default_rng(5), True, pool)
    b = simulate_depth(z, spec, 612.4, np.random.default_rng(5), True, pool)
    assert np.array_equal(a, b)
    valid = a > 0
    # dropout: |n| beyond the two-sided 2% quantile; 120k pixels give +-0.1% (3 sigma ~ 0.13%)
    assert 1.0 - valid.mean() == pytest.approx(0.02, abs=0.0015)
    expected = depth_sigma_m(
        2.0, sigma_d_px=spec.sigma_d_px, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m
    )
    assert np.std(a[valid]) == pytest.approx(expected, rel=0.05)
    c = simulate_depth(z, spec, 612.4, np.random.default_rng(6), True, pool)
    assert not np.array_equal(a, c)  # another frame's generator: another window


def test_noise_pool_windows_and_threshold():
    pool = NoisePool(np.arange(100, dtype=np.float32))
    w = pool.take(np.random.default_rng(0), (4, 5))
    assert w.shape == (4, 5) and not w.flags.writeable
    assert np.array_equal(np.diff(w.ravel()), np.ones(19))  # a contiguous window
    with pytest.raises(ValueError, match="cannot fill"):
        pool.take(np.random.default_rng(0), (11, 10))
    assert two_sided_threshold(0.3173) == pytest.approx(1.0, abs=1e-3)
    with pytest.raises(ValueError, match="probability"):
        two_sided_threshold(0.0)


def test_disparity_is_quantised_to_subpixel_steps():
    spec = DepthSpec()
    zs = disparity_noise(np.full((50, 50), 3.0, np.float32), spec, np.random.default_rng(1))
    d = spec.fx_depth_px * spec.baseline_m / zs
    steps = d / spec.subpixel
    assert np.allclose(steps, np.round(steps), atol=1e-3)


def test_edge_shadow_width_matches_stereo_geometry():
    # far surface (2 m) on the left half, near (1 m) on the right: the shadow of
    # f B (1/1 - 1/2) = 612.4 * 0.05 * 0.5 = 15.3 px falls left of the edge
    z = np.full((4, 100), 2.0, np.float32)
    z[:, 50:] = 1.0
    mask = edge_shadow_mask(z, 612.4, 0.05)
    cols = np.nonzero(mask[0])[0]
    assert cols.max() == 49
    assert cols.min() == 50 - 16  # reach 50 - 15.31 touches columns 34..49
    # a near-to-far step casts no shadow
    assert not edge_shadow_mask(z[:, ::-1].copy(), 612.4, 0.05)[:, 51:].any()


def test_simulate_depth_range_limits_and_clean_mode():
    spec = DepthSpec()
    z = np.array([[0.1, 1.0, 5.0, 12.0]], np.float32)
    clean = simulate_depth(z, spec, 612.4, np.random.default_rng(0), noise=False)
    assert clean.tolist() == [[0.0, 1.0, 5.0, 0.0]]
    noisy = simulate_depth(
        np.tile(z, (1, 1)),
        DepthSpec(dropout=0.0, edge_holes=False, below_min="wrong"),
        612.4,
        np.random.default_rng(0),
        noise=True,
    )
    assert noisy[0, 3] == 0.0  # beyond 10 m: invalid
    assert noisy[0, 0] > 0.15  # below min range: wrong, not zero (below_min: wrong)


def test_millimetres_round_and_keep_zero():
    assert to_z16(np.array([0.0, 1.2344, 1.2346])).tolist() == [0, 1234, 1235]


def _straight_line(n=2001, length_m=25.0):
    t = np.linspace(0, length_m / 0.3, n)
    return [make_transform(np.eye(3), [length_m * i / (n - 1), 0.0, 0.5]) for i in range(n)], t


def test_t265_drift_is_about_one_percent_of_distance():
    T, t = _straight_line()
    errs = []
    for seed in range(40):
        tr = simulate_t265(T, t, T265Spec(yaw_drift_deg_per_m=0.0), np.random.default_rng(seed), noise=True)
        errs.append(tr.error_m[-1])
    # the drift direction wanders, so |e| <= 1% of 25 m = 0.25 m, and on average is a good
    # part of it; 40 runs put the mean well inside [0.12, 0.25]
    assert max(errs) <= 0.25 + 1e-9
    assert 0.12 < np.mean(errs) < 0.25


def test_t265_scale_error_and_clean_mode():
    T, t = _straight_line(101, 10.0)
    spec = T265Spec(drift_fraction=0.0, yaw_drift_deg_per_m=0.0, scale_error=-0.2)
    tr = simulate_t265(T, t, spec, np.random.default_rng(0), noise=True)
    assert tr.poses[-1][0, 3] == pytest.approx(8.0)  # 10 m reported 20% short
    clean = simulate_t265(T, t, spec, np.random.default_rng(0), noise=False)
    assert np.allclose(clean.poses[-1], T[-1])


def test_t265_dropouts_give_no_pose_and_low_confidence():
    T, t = _straight_line(601, 20.0)
    spec = T265Spec()
    spec.dropouts.rate_per_min = 30.0
    tr = simulate_t265(T, t, spec, np.random.default_rng(3), noise=True)
    missing = [k for k, p in enumerate(tr.poses) if p is None]
    assert missing, "30 dropouts a minute over a minute must drop some frames"
    assert all(tr.confidence[k] == "low" for k in missing)


def test_t265_yaw_drift_rotates_heading():
    T, t = _straight_line(101, 10.0)
    spec = T265Spec(drift_fraction=0.0, yaw_drift_deg_per_m=0.5)
    tr = simulate_t265(T, t, spec, np.random.default_rng(0), noise=True)
    R = tr.poses[-1][:3, :3]
    yaw = np.degrees(np.arctan2(R[1, 0], R[0, 0]))
    assert abs(yaw) == pytest.approx(5.0, abs=0.01)
    assert np.allclose(rot_z(np.radians(yaw)), R)


def test_thermal_image_sees_hot_geoms_against_ambient():
    seg = np.full((480, 640), -1, np.int32)
    seg[100:200, 100:200] = 3  # a hot geom
    seg[300:400, 400:500] = 1  # a body-temperature geom
    temps = np.array([20.0, 37.0, 20.0, 80.0])
    img = thermal_image(seg, temps, ThermalSpec(), np.random.default_rng(0), noise=False)
    assert img.shape == (120, 160)
    assert img[37, 37] == pytest.approx(80.0)  # centre of the hot block at 1/4 scale
    assert img[87, 112] == pytest.approx(37.0)
    assert img[5, 5] == pytest.approx(20.0)
