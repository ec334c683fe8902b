"""The D435 depth model (sim/sensors/d435_depth.py) against hand-computed stereo figures."""

from __future__ import annotations

import numpy as np
import pytest

from poi.core.depth_units import from_z16, to_z16
from poi.core.sensor_noise import depth_sigma_m
from sim.scenario import Scenario, ScenarioError, apply_settings
from sim.sensors.d435_depth import DepthSpec, DepthTrial, edge_shadow_mask, shift_image, simulate_depth
from sim.sensors.noise_pool import NoisePool

FX_COLOUR = 612.4
# only the effect under test: no random holes, texture, flying pixels or registration error
QUIET = dict(dropout=0.0, texture=False, flying_pixels=0.0, registration_error_px=0.0)


def _box_on_wall(z_box=1.0, z_wall=2.0, cols=(100, 160), shape=(40, 240)) -> np.ndarray:
    z = np.full(shape, z_wall, np.float32)
    z[:, cols[0] : cols[1]] = z_box
    return z


def test_shadow_falls_left_of_a_near_box_at_the_stereo_and_alignment_width():
    # box at 1 m before a wall at 2 m, columns 100..159. Hand-computed: the right imager is
    # B = 50 mm right of the reference, the colour camera 15 mm left of it, so the band
    # left of the box is 612.4 * (0.05 + 0.015) * (1/1 - 1/2) = 19.903 px: columns c with
    # c + 1 > 100 - 19.903, i.e. 80..99; the box's right edge casts none.
    z = _box_on_wall()
    mask = edge_shadow_mask(z, FX_COLOUR, 0.05, 0.015)
    assert np.array_equal(np.nonzero(mask[0])[0], np.arange(80, 100))
    assert (mask == mask[0]).all()
    # stereo alone (no colour offset): 612.4 * 0.05 * 0.5 = 15.31 px: c + 1 > 84.69, columns 84..99
    assert np.array_equal(np.nonzero(edge_shadow_mask(z, FX_COLOUR, 0.05)[0])[0], np.arange(84, 100))
    # the whole model with noise on: the same band reads 0, nothing right of the box does
    spec = DepthSpec(**QUIET)
    out = simulate_depth(z, spec, FX_COLOUR, np.random.default_rng(0), True)
    holes = np.nonzero((out == 0).all(axis=0))[0]
    assert np.array_equal(holes, np.arange(80, 100))
    assert (out[:, 100:] > 0).all()


@pytest.fixture(scope="module")
def plane_frames() -> tuple[np.ndarray, DepthSpec]:
    """30 frames of a plane 1 m away, one trial (fixed pattern), pooled noise as in a trial."""
    spec = DepthSpec(**QUIET)
    shape = (160, 200)
    trial = DepthTrial.draw(spec, shape, np.random.default_rng(11))
    pool = NoisePool.standard_normal([3, 1, 10**9 + 1], 3 * shape[0] * shape[1])
    z = np.full(shape, 1.0, np.float32)
    frames = np.stack(
        [
            simulate_depth(z, spec, FX_COLOUR, np.random.default_rng([3, 1, k]), True, pool, trial=trial)
            for k in range(30)
        ]
    )
    return frames, spec


def test_temporal_sigma_at_1m_matches_intels_formula(plane_frames):
    frames, spec = plane_frames
    expected = depth_sigma_m(
        1.0, sigma_d_px=spec.sigma_d_px, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m
    )
    assert expected == pytest.approx(0.08 / (384.2 * 0.05))  # 4.16 mm
    temporal = np.sqrt(frames.var(axis=0, ddof=1).mean())
    # 32k pixels x 29 degrees of freedom, correlated over 7x7 windows: the estimate is good to
    # about 1%; the 1 mm and 1/32 px rounding add about 1% of variance: 10% is the spec
    assert temporal == pytest.approx(expected, rel=0.10)


def test_spatial_rms_is_at_least_the_temporal_and_neighbours_correlate(plane_frames):
    frames, _ = plane_frames
    temporal = np.sqrt(frames.var(axis=0, ddof=1).mean())
    H, W = frames.shape[1:]
    v, u = np.mgrid[0:H, 0:W]
    A = np.c_[np.ones(H * W), u.ravel(), v.ravel()]
    spatial = []
    for f in frames:
        coef, *_ = np.linalg.lstsq(A, f.ravel().astype(float), rcond=None)
        spatial.append(np.sqrt(np.mean((f.ravel() - A @ coef) ** 2)))
    spatial_rms = float(np.mean(spatial))
    # fixed pattern 0.3: spatial about sqrt(1 + 0.3^2) = 1.044 x temporal
    assert spatial_rms >= temporal
    assert spatial_rms == pytest.approx(1.044 * temporal, rel=0.03)
    e = frames[0] - 1.0
    r = np.corrcoef(e[:, :-1].ravel(), e[:, 1:].ravel())[0, 1]
    assert r > 0.7  # a 7-px window: 6/7 = 0.86 before the 1 mm rounding


def test_independent_pixels_when_the_window_is_one():
    spec = DepthSpec(**QUIET, window_px=1, fixed_pattern=0.0)
    out = simulate_depth(np.full((200, 200), 2.0, np.float32), spec, FX_COLOUR, np.random.default_rng(1), True)
    e = out - 2.0
    assert abs(np.corrcoef(e[:, :-1].ravel(), e[:, 1:].ravel())[0, 1]) < 0.03


def test_minimum_range_follows_the_disparity_search():
    # MinZ = f B / 126: 384.2 * 0.05 / 126 = 0.1525 m at 640x480, 425 * 0.05 / 126 = 0.1687 m at 848x480
    assert DepthSpec().min_range_m == pytest.approx(0.15246, abs=1e-5)
    assert DepthSpec(fx_depth_px=425.0).min_range_m == pytest.approx(0.16865, abs=1e-5)
    assert DepthSpec(min_m=0.28).min_range_m == 0.28
    z = np.array([[0.10, 0.15, 0.16, 1.0, 12.0]], np.float32)
    spec = DepthSpec(**QUIET)
    out = simulate_depth(z, spec, FX_COLOUR, np.random.default_rng(0), True)
    assert out[0, 0] == 0 and out[0, 1] == 0 and out[0, 2] > 0 and out[0, 4] == 0
    clean = simulate_depth(z, spec, FX_COLOUR, np.random.default_rng(0), False)
    assert clean.tolist()[0] == pytest.approx([0.0, 0.0, 0.16, 1.0, 0.0])
    wrong = simulate_depth(z, DepthSpec(**QUIET, below_min="wrong"), FX_COLOUR, np.random.default_rng(0), True)
    assert 1.5 * 0.10 - 1e-3 <= wrong[0, 0] <= 3.0 * 0.10 + 1e-3


def test_output_is_z16_millimetres():
    z = np.random.default_rng(2).uniform(0.3, 6.0, (50, 60)).astype(np.float32)
    for noise in (False, True):
        out = simulate_depth(z, DepthSpec(), FX_COLOUR, np.random.default_rng(0), noise)
        assert out.dtype == np.float32
        mm = out.astype(np.float64) * 1000.0
        assert np.abs(mm - np.rint(mm)).max() < 1e-3
        assert np.array_equal(from_z16(to_z16(out)), out)  # already on the grid
    assert to_z16(np.array([0.0, 1.2344, 1.2346])).tolist() == [0, 1234, 1235]
    assert to_z16(np.array([1.2344]), 0.0001).tolist() == [12344]


def test_same_seed_same_bytes_and_another_frame_differs():
    spec = DepthSpec()
    z = _box_on_wall(shape=(60, 240))
    rgb = np.random.default_rng(4).integers(0, 256, (60, 240, 3), dtype=np.uint8)
    pool = NoisePool.standard_normal([9, 1, 10**9 + 1], 3 * 60 * 240)

    def frame(k: int, seed: int = 9) -> bytes:
        trial = DepthTrial.draw(spec, z.shape, np.random.default_rng([seed, 1, 10**9 + 2]))
        return simulate_depth(
            z, spec, FX_COLOUR, np.random.default_rng([seed, 1, k]), True, pool, rgb=rgb, trial=trial
        ).tobytes()

    assert frame(3) == frame(3)
    assert frame(3) != frame(4)
    assert frame(3) != frame(3, seed=10)


def test_texture_and_projector_set_fill_and_noise():
    spec = DepthSpec(dropout=0.0, flying_pixels=0.0, registration_error_px=0.0, fixed_pattern=0.0)
    flat = np.full((120, 160, 3), 128, np.uint8)  # no texture: only the projector's dots
    textured = np.random.default_rng(5).integers(0, 256, (120, 160, 3), dtype=np.uint8)

    def frames(z_m, rgb, n=12):
        z = np.full((120, 160), z_m, np.float32)
        return np.stack(
            [simulate_depth(z, spec, FX_COLOUR, np.random.default_rng(k), True, rgb=rgb) for k in range(n)]
        )

    # within the projector's 3 m a flat wall fills and has the formula's noise
    near = frames(1.0, flat)
    assert (near > 0).all()
    # at 6 m the dots are worth (3/6)^2 = 0.25 of the reference: holes where 0.25 < 0.25 exp(0.5 m),
    # half the pixels; a textured wall at 6 m fills
    far = frames(6.0, flat)
    assert 0.35 < (far == 0).mean() < 0.65
    assert (frames(6.0, textured, 2) > 0).mean() > 0.99
    # at 4.5 m the dots are worth (3/4.5)^2 = 0.444: sigma_d grows 2.25 times; holes where
    # m > 2 ln(0.444 / 0.25) = 1.15, 12.5% of pixels
    mid = frames(4.5, flat)
    assert 0.08 < (mid == 0).mean() < 0.18
    both = (mid > 0).all(axis=0)
    sigma = np.sqrt(mid[:, both].var(axis=0, ddof=1).mean())
    expected = depth_sigma_m(4.5, sigma_d_px=0.08, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m)
    assert sigma == pytest.approx(2.25 * expected, rel=0.12)


def test_saturated_pixels_read_zero():
    rgb = np.random.default_rng(6).integers(0, 200, (40, 50, 3), dtype=np.uint8)
    rgb[10:20, 10:20] = 255  # a specular highlight
    spec = DepthSpec(**{**QUIET, "texture": True})
    out = simulate_depth(
        np.full((40, 50), 1.0, np.float32), spec, FX_COLOUR, np.random.default_rng(0), True, rgb=rgb
    )
    assert (out[10:20, 10:20] == 0).all()
    assert (out[25:, 25:] > 0).all()


def test_flying_pixels_lie_between_the_two_sides_of_an_edge():
    spec = DepthSpec(**{**QUIET, "flying_pixels": 1.0, "edge_holes": False})
    z = _box_on_wall(shape=(200, 240))
    out = simulate_depth(z, spec, FX_COLOUR, np.random.default_rng(0), True)
    edge = out[:, [99, 100, 159, 160]]
    assert (edge > 0.98).all() and (edge < 2.1).all()
    mixed = (edge > 1.1) & (edge < 1.9)
    assert mixed.mean() > 0.5  # uniform between 1 and 2 m: 80% of them inside (1.1, 1.9)
    assert not ((out[:, 110:150] > 1.1) & (out[:, 110:150] < 1.9)).any()  # none inside the box


def test_registration_offset_is_about_one_pixel_and_shifts_the_image():
    spec = DepthSpec(fixed_pattern=0.0)
    rng = np.random.default_rng(7)
    offsets = np.array([DepthTrial.draw(spec, (4, 4), rng).offset_px for _ in range(4000)])
    assert np.sqrt((offsets**2).sum(axis=1).mean()) == pytest.approx(1.0, rel=0.05)
    img = np.arange(12, dtype=np.float32).reshape(3, 4)
    assert shift_image(img, 1, -1).tolist() == [[0, 4, 5, 6], [0, 8, 9, 10], [0, 0, 0, 0]]


@pytest.mark.parametrize(
    "setting, message",
    [
        ("window_px=0", "window_px"),
        ("below_min=never", "below_min"),
        ("saturation=1.5", "saturation"),
        ("depth_unit_m=0", "depth_unit_m"),
    ],
)
def test_bad_depth_settings_are_refused_at_load(setting, message):
    with pytest.raises(ScenarioError, match=message):
        apply_settings(Scenario(), [f"sensors.d435.depth.{setting}"])
