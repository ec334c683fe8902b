"""Each colour-camera effect's property, checked by hand (sim/sensors/d435_color.py)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from poi.core.geometry import make_transform, rot_y
from poi.core.motion_blur import image_motion_px, motion_kernel
from sim.sensors.base import Exposure
from sim.sensors.d435_color import (
    ColourCamera,
    ColourSpec,
    lagged_exposure,
    meter,
    steady_state_exposure,
    vignette_map,
)

W, H, FX, FY, PPX, PPY = 640, 480, 612.4, 610.6, 314.3, 237.8
# every effect off: exposure and tone only
PLAIN = ColourSpec(
    shot_noise=False,
    read_noise_e=0.0,
    motion_blur=False,
    defocus_sigma_px=0.0,
    vignetting=0.0,
    wb_gains=(1.0, 1.0, 1.0),
    jpeg_quality=0,
)


def _camera(spec: ColourSpec) -> ColourCamera:
    return ColourCamera(spec, W, H, FX, FY, PPX, PPY)


def _unit_exposure(spec: ColourSpec, lux: float = 1000.0) -> Exposure:
    """The exposure product that maps a decoded 1 to a signal of exactly 1 (full scale)."""
    return Exposure(exposure_ms=spec.full_well_e / (lux * spec.sensitivity_e_per_lux_ms), gain=1.0)


def test_vignetting_at_the_corner_is_the_cos4_formula():
    v = vignette_map(W, H, FX, FY, PPX, PPY, 0.4)
    # corner (0, 0): tan^2 = (314.3/612.4)^2 + (237.8/610.6)^2 = 0.26340 + 0.15167 = 0.41507
    cos4 = 1.0 / (1.0 + 0.41507) ** 2  # 0.49943
    assert v[0, 0] == pytest.approx(1.0 - 0.4 * (1.0 - cos4), abs=1e-4)  # 0.79977
    assert v[238, 314] == pytest.approx(1.0, abs=1e-5)  # on the axis: no falloff


def test_noise_variance_grows_with_signal_as_a_s_plus_b():
    spec = replace(PLAIN, gamma=1.0, shot_noise=True, read_noise_e=20.0, full_well_e=2000.0)
    cam, ex = _camera(spec), Exposure(exposure_ms=spec.full_well_e / (1000.0 * 0.2), gain=2.0)
    # with gain 2 a decoded x gives s = 2 x; a = G / FW = 1e-3, b = (G * 20 / FW)^2 = 4e-4
    a, b = 2.0 / 2000.0, (2.0 * 20.0 / 2000.0) ** 2
    rng = np.random.default_rng(0)
    for v in (20, 60, 100):
        img = np.full((H, W, 3), v, np.uint8)
        out = cam.render(img, ex, 1000.0, rng=rng, pool=None).astype(np.float64) / 255.0
        s = 2.0 * v / 255.0
        # 921600 samples: the variance is within 1% (plus the 8-bit quantisation's 1/12 level^2)
        assert out.mean() == pytest.approx(s, abs=2e-3)
        assert out.var() == pytest.approx(a * s + b + 1.0 / (12 * 255.0**2), rel=0.02)


def test_motion_blur_of_a_pure_rotation_smears_a_dot_along_the_pan():
    # the camera yaws (about optical y) by 0.02 rad during the exposure: the centre moves
    # fx * tan(0.02) = 12.25 px along u, none along v, whatever the depth
    T0 = make_transform(np.eye(3), [0.0, 0.0, 0.0])
    T1 = make_transform(rot_y(0.02), [0.0, 0.0, 0.0])
    du, dv = image_motion_px(T0, T1, FX, FY, PPX, PPY, depth_m=3.0)
    assert du == pytest.approx(-FX * math.tan(0.02), rel=1e-3)
    assert dv == pytest.approx(0.0, abs=1e-9)
    k = motion_kernel(du, dv)
    img = np.zeros((41, 41), np.float32)
    img[20, 20] = 1.0
    import cv2

    out = cv2.filter2D(img, -1, k)
    assert out.sum() == pytest.approx(1.0, abs=1e-5)
    ys, xs = np.nonzero(out > 1e-4)
    assert set(ys) == {20}  # a horizontal smear only
    # spread: a segment of length L has standard deviation L / sqrt(12)
    w = out[20]
    x = np.arange(41)
    mu = (w * x).sum()
    sd = math.sqrt((w * (x - mu) ** 2).sum())
    assert mu == pytest.approx(20.0, abs=0.05)
    assert sd == pytest.approx(abs(du) / math.sqrt(12.0), rel=0.05)


def test_white_balance_gains_scale_channel_means():
    spec = replace(PLAIN, gamma=1.0, wb_gains=(1.2, 1.0, 0.8))
    img = np.full((H, W, 3), 150, np.uint8)
    out = _camera(spec).render(img, _unit_exposure(spec), 1000.0, rng=np.random.default_rng(0), pool=None)
    m = out.reshape(-1, 3).mean(axis=0)
    assert m[0] / m[1] == pytest.approx(1.2, abs=0.01) and m[2] / m[1] == pytest.approx(0.8, abs=0.01)


def test_the_default_white_balance_leaves_a_white_surface_cool():
    """The default white balance leaves whites a little cool, as real placard photos show them and
    in the direction a real D435 takes in a warm room (docs/FACTS.md "D435 colour camera"): blue
    above red on a grey surface, by 1.15 in linear light, 1.15^(1/2.2) = 1.066 encoded."""
    spec = replace(
        ColourSpec(), shot_noise=False, read_noise_e=0.0, motion_blur=False, defocus_sigma_px=0.0, vignetting=0.0
    )
    img = np.full((H, W, 3), 180, np.uint8)
    out = _camera(spec).render(img, _unit_exposure(spec), 1000.0, rng=np.random.default_rng(0), pool=None)
    r, g, b = out.reshape(-1, 3).astype(float).mean(axis=0)
    assert b / r == pytest.approx(1.15 ** (1 / 2.2), abs=0.01) and r == pytest.approx(g, abs=1.0)


def test_jpeg_off_leaves_the_image_byte_identical_and_on_changes_it():
    spec = replace(PLAIN, gamma=1.0)
    img = np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8)
    rng = np.random.default_rng(0)
    out = _camera(spec).render(img, _unit_exposure(spec), 1000.0, rng=rng, pool=None)
    assert np.array_equal(out, img)
    out_q = _camera(replace(spec, jpeg_quality=50)).render(img, _unit_exposure(spec), 1000.0, rng=rng, pool=None)
    assert not np.array_equal(out_q, img)


def test_same_seed_same_image_byte_for_byte():
    spec = ColourSpec()
    img = np.random.default_rng(2).integers(0, 256, (H, W, 3), dtype=np.uint8)
    ex = Exposure(exposure_ms=5.0, gain=3.0)

    def run(seed):
        cam = _camera(spec)
        return cam.render(img, ex, 1000.0, rng=np.random.default_rng(seed), pool=None, motion_px=(7.0, 2.0))

    assert np.array_equal(run(3), run(3))
    assert not np.array_equal(run(3), run(4))


def test_auto_exposure_converges_a_white_patch_into_200_235():
    spec = ColourSpec()  # the defaults
    # a scene of OSB-like grey (render 110) with a white placard (render 160), as the
    # default maze renders them; start far too dark, then hold the scene
    scene = np.full((H, W, 3), 110, np.uint8)
    scene[200:280, 280:360] = 160
    lux = 1000.0
    ss = steady_state_exposure(meter(scene, spec.gamma), spec, lux)
    history = [Exposure(exposure_ms=0.1, gain=1.0)] * 7
    for _ in range(12):
        history = [ss, *history[:7]]
    ex = lagged_exposure(history, spec, 0.1)
    assert ex.product_ms == pytest.approx(ss.product_ms, rel=1e-9)
    # one frame after the jump it is still darker: the lag
    assert lagged_exposure([ss] + [Exposure(exposure_ms=0.1, gain=1.0)] * 7, spec, 0.1).product_ms < ss.product_ms
    out = _camera(replace(spec, jpeg_quality=0)).render(
        scene, ex, lux, rng=np.random.default_rng(0), pool=None, effects=False
    )
    white = out[210:270, 290:350].mean()
    assert 200 <= white <= 235


def test_the_camera_blurs_with_the_same_line_kernel_as_motion_kernel():
    # the render crops the kernel to its non-zero rows; the result is the full kernel's
    import cv2

    spec = replace(PLAIN, gamma=1.0, motion_blur=True)
    img = np.random.default_rng(5).integers(0, 256, (H, W, 3), dtype=np.uint8)
    for motion in ((9.3, 0.4), (3.0, -7.5)):
        out = _camera(spec).render(
            img, _unit_exposure(spec), 1000.0, rng=np.random.default_rng(0), pool=None, motion_px=motion
        )
        ref = cv2.filter2D(img, -1, motion_kernel(*motion), borderType=cv2.BORDER_REFLECT)
        assert np.abs(out.astype(int) - ref.astype(int)).max() <= 1  # float sums in another order
