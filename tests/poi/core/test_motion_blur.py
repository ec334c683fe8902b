"""The camera's motion blur: the motion a turn makes in the image, the line kernel and its Wiener
inverse."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from poi.core.geometry import make_transform
from poi.core.motion_blur import (
    EXPOSURE_LADDER,
    camera_motion,
    image_motion_px,
    motion_kernel,
    rotation_motion_px,
    wiener_deconvolve,
)
from poi.core.types import Frame, Intrinsics

K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)


@pytest.mark.parametrize("omega", [(0.0, 2.0, 0.0), (1.5, 0.0, 0.0), (0.4, -1.8, 0.9)])
def test_a_turn_moves_the_centre_as_the_pose_pair_says(omega):
    # the same turn given as a rate over the exposure and as the start and end poses it spans:
    # the camera at exp(theta s) for s in [-1/2, 1/2] (a body rate)
    w, e = np.array(omega), 0.01
    R0, _ = cv2.Rodrigues(-w * e / 2)
    R1, _ = cv2.Rodrigues(w * e / 2)
    want = image_motion_px(
        make_transform(R0, [0, 0, 0]), make_transform(R1, [0, 0, 0]), K.fx, K.fy, K.ppx, K.ppy, 2.0
    )
    got = rotation_motion_px(w, e, K.fx, K.fy, K.ppx, K.ppy, K.ppx, K.ppy)
    # the pose pair follows the point at the centre at the end, the rate the one there mid-exposure:
    # a tenth of a pixel apart at most
    assert got == pytest.approx(want, abs=0.1)


def test_a_pan_at_120_deg_per_s_smears_about_13_px_in_10_ms():
    # yaw about the optical y axis at 120 deg/s for 10 ms: 1.2 deg, fx tan(1.2 deg) = 12.8 px along u
    du, dv = rotation_motion_px(
        np.array([0.0, math.radians(120), 0.0]), 0.010, K.fx, K.fy, K.ppx, K.ppy, K.ppx, K.ppy
    )
    assert abs(du) == pytest.approx(2 * K.fx * math.tan(math.radians(0.6)), rel=1e-6)
    assert dv == pytest.approx(0.0, abs=1e-9)


def test_camera_motion_turns_the_gyro_into_the_optical_axes():
    # the colour camera looks along the tracker's x (its optical z = tracker x, optical x = -tracker y,
    # optical y = -tracker z): a yaw of the tracker about its z is a turn about optical -y
    R = np.column_stack([[0, -1, 0], [0, 0, -1], [1, 0, 0]]).astype(float)  # tracker <- optical
    T = make_transform(R, [0.1, 0.0, 0.05])

    def frame(**kw) -> Frame:
        return Frame(index=0, timestamp_s=0.0, rgb=None, intrinsics=K, **kw)

    m = camera_motion(frame(exposure_s=0.004, angular_velocity=np.array([0, 0, 2.0])), T, 0.010)
    assert m is not None and m.omega_optical == pytest.approx([0.0, -2.0, 0.0])
    assert m.exposures_s == (0.004,)  # the frame's own exposure, where it gives one
    # without it (the D435's colour auto-exposure does not report it): the ladder below the cap
    m = camera_motion(frame(angular_velocity=np.array([0, 0, 2.0])), T, 0.010)
    assert m.exposures_s == pytest.approx([0.010 * f for f in EXPOSURE_LADDER])
    assert m.exposures_s[0] == 0.010 and m.exposures_s[-1] == pytest.approx(0.0025)
    assert camera_motion(frame(exposure_s=0.01), T, 0.010) is None  # no gyro
    assert camera_motion(frame(exposure_s=0.01, angular_velocity=np.array([np.nan, 0, 0])), T, 0.010) is None


def test_motion_kernel_is_a_unit_line_of_the_motion_length():
    k = motion_kernel(9.0, 0.0)
    assert k.sum() == pytest.approx(1.0, abs=1e-6)
    rows = np.nonzero(k.sum(axis=1))[0]
    cols = np.nonzero(k.sum(axis=0))[0]
    assert len(rows) <= 2 and 9 <= cols[-1] - cols[0] + 1 <= 11
    assert motion_kernel(0.5, 0.5) is None


def _edge_width_px(row: np.ndarray, lo: float, hi: float) -> int:
    """Pixels a dark-to-light step from ``lo`` to ``hi`` takes to climb from 10% to 90%."""
    t10, t90 = lo + 0.1 * (hi - lo), lo + 0.9 * (hi - lo)
    return int(np.argmax(row > t90) - np.argmax(row > t10))


def test_wiener_deconvolution_sharpens_a_step_smeared_by_a_known_line():
    # a vertical step at u = 48 smeared 12.8 px along u (a pan): a ramp about 12 px wide;
    # deblurred by the same kernel it climbs in 4 px or less. Rows averaged: the noise (sigma 2)
    # comes back amplified (about 7 at nsr 0.01), the step's shape does not depend on it.
    step = np.full((64, 96), 40, np.uint8)
    step[:, 48:] = 220
    k = motion_kernel(12.8, 0.0)
    rng = np.random.default_rng(3)
    blurred = cv2.filter2D(step.astype(np.float32), -1, k, borderType=cv2.BORDER_REFLECT)
    blurred = np.clip(blurred + rng.normal(0, 2, blurred.shape), 0, 255).astype(np.uint8)
    restored = wiener_deconvolve(blurred, k, 0.01)
    window = slice(30, 66)  # the step and 18 px either side
    before = blurred[:, window].astype(float).mean(axis=0)
    after = restored[:, window].astype(float).mean(axis=0)
    assert _edge_width_px(before, 40, 220) >= 9
    assert _edge_width_px(after, 40, 220) <= 4
    assert abs(after[:12].mean() - 40) < 8 and abs(after[-12:].mean() - 220) < 8
    with pytest.raises(ValueError, match="nsr must be > 0"):
        wiener_deconvolve(blurred, k, 0.0)
    with pytest.raises(ValueError, match="grey"):
        wiener_deconvolve(np.zeros((8, 8, 3), np.uint8), k, 0.01)


def test_rotation_motion_matches_pose_pair_off_centre():
    # off the centre a turn about the optical axis moves a point tangentially: r * theta
    w, e = np.array([0.0, 0.0, 3.0]), 0.01
    u, v = K.ppx + 200.0, K.ppy
    du, dv = rotation_motion_px(w, e, K.fx, K.fy, K.ppx, K.ppy, u, v)
    # the tangential motion r theta, in v's pixels (fy / fx of u's); second order left aside
    assert abs(du) < 0.1 and abs(dv) == pytest.approx(200.0 * 0.03 * K.fy / K.fx, rel=0.03)
