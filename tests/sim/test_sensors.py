"""Sensor models: depth noise statistics, edge shadows, thermal registration (the T265: sensors/test_t265.py)."""

import numpy as np
import pytest

from poi.core.depth_units import to_z16
from poi.core.sensor_noise import depth_sigma_m
from sim.sensors.d435_depth import (
    DepthSpec,
    disparity_noise,
    edge_shadow_mask,
    simulate_depth,
)
from sim.sensors.noise_pool import NoisePool, two_sided_threshold
from sim.sensors.thermal import ThermalSpec, thermal_image


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
