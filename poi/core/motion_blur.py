"""A camera's motion blur: the image's motion during one exposure, its line kernel, and the
kernel's inverse (Wiener deconvolution).

The image moves by (du, dv) pixels while the shutter is open. The simulator renders that motion
from the rig's true poses (:func:`image_motion_px`, sim/sensors/d435_color.py); a robot knows
it from its own sensors: the colour frame's exposure time (librealsense's per-frame
``ACTUAL_EXPOSURE`` metadata, [LibrealsenseMetadata]_, which the D435's colour sensor fills
only under manual exposure, [D435RGBIssues]_) and the tracking camera's angular velocity (the
T265's 200 Hz gyroscope, [IntelT265]_); :class:`CameraMotion` holds the two for one frame
and :func:`rotation_motion_px` projects the rotation. Over one exposure the blur is
a line: the image convolved with a normalised segment of length hypot(du, dv) along (du, dv)
(:func:`motion_kernel`).

Deblurring with a known kernel K ([Gonzalez2018]_ 5.8, the Wiener filter): with G the image's
spectrum and a noise-to-signal power ratio ``nsr``, the estimate is
``F = conj(K) G / (|K|^2 + nsr)`` (:func:`wiener_deconvolve`).

References
----------
Full entries in docs/SOURCES.md.

.. [LibrealsenseMetadata] Intel RealSense SDK 2.0, ``rs2_frame_metadata_value`` (rs_frame.h):
   ``ACTUAL_EXPOSURE``, the sensor's exposure in microseconds; ``SENSOR_TIMESTAMP``, the middle
   of the exposure.
.. [D435RGBIssues] librealsense issues #2549 and #5035: the colour sensor's ``ACTUAL_EXPOSURE``
   does not follow its auto-exposure.
.. [IntelT265] Intel RealSense T265 datasheet (gyroscope at 200 Hz).
.. [Gonzalez2018] R. C. Gonzalez and R. E. Woods, "Digital Image Processing", 4th ed., 2018,
   section 5.8 (minimum mean square error, Wiener, filtering).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from poi.core.geometry import invert_transform, transform_points
from poi.core.types import Frame, Intrinsics


def image_motion_px(
    T_map_optical_start: np.ndarray,
    T_map_optical_end: np.ndarray,
    fx: float,
    fy: float,
    ppx: float,
    ppy: float,
    depth_m: float,
) -> tuple[float, float]:
    """(du, dv) pixels the image centre moves from the start to the end of the exposure: the
    point ``depth_m`` along the centre ray at the end pose, projected at the start pose."""
    p_map = transform_points(T_map_optical_end, np.array([0.0, 0.0, depth_m]))
    p0 = transform_points(invert_transform(T_map_optical_start), p_map)
    if p0[2] <= 1e-6:
        return 0.0, 0.0
    u0 = fx * p0[0] / p0[2] + ppx
    v0 = fy * p0[1] / p0[2] + ppy
    return float(ppx - u0), float(ppy - v0)


def rotation_motion_px(
    omega_optical: np.ndarray,
    exposure_s: float,
    fx: float,
    fy: float,
    ppx: float,
    ppy: float,
    u: float,
    v: float,
) -> tuple[float, float]:
    """(du, dv) pixels the image point (u, v) moves during an exposure of ``exposure_s``
    centred on the frame time, while the camera turns at ``omega_optical`` (rad/s, in its own
    optical frame: x right, y down, z forward) and does not move.

    A fixed direction seen along the ray d of (u, v) at mid-exposure is seen at exp(-s theta) d
    at time s of the exposure (s in [-1/2, 1/2], theta = omega * exposure, a body rate), so the
    motion is the projection of exp(-theta / 2) d minus that of exp(theta / 2) d. Translation is
    left out: it moves near things more, and a scanning head turns on the spot.
    """
    theta = np.asarray(omega_optical, np.float64) * float(exposure_s)
    d = np.array([(u - ppx) / fx, (v - ppy) / fy, 1.0])

    def project(rvec: np.ndarray) -> np.ndarray:
        R, _ = cv2.Rodrigues(rvec)
        p = R @ d
        if p[2] <= 1e-6:
            return np.array([u, v])
        return np.array([fx * p[0] / p[2] + ppx, fy * p[1] / p[2] + ppy])

    du, dv = project(-theta / 2.0) - project(theta / 2.0)
    return float(du), float(dv)


# Where the frame does not give its exposure (the D435's colour auto-exposure does not report
# it, [D435RGBIssues]_), the exposures tried: fractions of the camera's cap, in steps of sqrt(2),
# so that one of them is within 19% of any exposure from the cap down to a quarter of it
EXPOSURE_LADDER = (1.0, 2.0**-0.5, 0.5, 2.0**-1.5, 0.25)


@dataclass(frozen=True)
class CameraMotion:
    """The colour camera's turn during one frame's exposure: its angular velocity
    ``omega_optical`` (rad/s, optical axes), seen through ``intrinsics``, over the exposure,
    which is one of ``exposures_s`` (one where the frame gives it, a ladder where it does not)."""

    omega_optical: np.ndarray
    exposures_s: tuple[float, ...]
    intrinsics: Intrinsics

    def motion_px(self, u: float, v: float, exposure_s: float) -> tuple[float, float]:
        """(du, dv) pixels the image point (u, v) moves in ``exposure_s`` (:func:`rotation_motion_px`)."""
        k = self.intrinsics
        return rotation_motion_px(self.omega_optical, exposure_s, k.fx, k.fy, k.ppx, k.ppy, u, v)


def camera_motion(frame: Frame, T_tracker_camera: np.ndarray, max_exposure_s: float) -> CameraMotion | None:
    """The colour camera's motion in ``frame``: the tracking camera's angular velocity turned
    into the colour camera's optical axes by the mount's rotation (omega_optical =
    R_tracker_camera^T omega_tracker), over the frame's exposure where it gives one, else over
    each of ``EXPOSURE_LADDER`` times the camera's cap ``max_exposure_s``; None without a gyro."""
    if frame.angular_velocity is None:
        return None
    w = np.asarray(frame.angular_velocity, np.float64)
    if w.shape != (3,) or not np.all(np.isfinite(w)):
        return None
    e = frame.exposure_s
    exposures = (
        (float(e),)
        if e is not None and np.isfinite(e) and e > 0
        else tuple(f * max_exposure_s for f in EXPOSURE_LADDER)
    )
    R = np.asarray(T_tracker_camera, np.float64)[:3, :3]
    return CameraMotion(omega_optical=R.T @ w, exposures_s=exposures, intrinsics=frame.intrinsics)


def motion_kernel(du: float, dv: float) -> np.ndarray | None:
    """A normalised line kernel of length hypot(du, dv) along (du, dv), centred (None under 1 px).

    Samples along the segment are splatted bilinearly, so fractional lengths and angles count.
    """
    L = math.hypot(du, dv)
    if L < 1.0:
        return None
    r = math.ceil(max(abs(du), abs(dv)) / 2.0) + 1
    n = 2 * r + 1
    k = np.zeros((n, n), np.float64)
    s = np.linspace(-0.5, 0.5, max(2, int(math.ceil(L * 4)) + 1))
    x, y = r + s * du, r + s * dv
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    np.add.at(k, (y0, x0), (1 - fx) * (1 - fy))
    np.add.at(k, (y0, x0 + 1), fx * (1 - fy))
    np.add.at(k, (y0 + 1, x0), (1 - fx) * fy)
    np.add.at(k, (y0 + 1, x0 + 1), fx * fy)
    return (k / k.sum()).astype(np.float32)


def wiener_deconvolve(gray: np.ndarray, kernel: np.ndarray, nsr: float) -> np.ndarray:
    """The uint8 image ``gray`` (H, W) deblurred by ``kernel`` (odd square, centred, sum 1):
    ``F = conj(K) G / (|K|^2 + nsr)`` ([Gonzalez2018]_ 5.8). The image is padded by reflection
    by the kernel's size on every side first, so the filter's circular wrap stays in the pad."""
    if gray.ndim != 2:
        raise ValueError(f"wiener_deconvolve: expected a grey (H, W) image, got shape {gray.shape}")
    if nsr <= 0:
        raise ValueError(f"wiener_deconvolve: nsr must be > 0, got {nsr}")
    pad = kernel.shape[0]
    g = cv2.copyMakeBorder(gray.astype(np.float32) / 255.0, pad, pad, pad, pad, cv2.BORDER_REFLECT)
    H, W = g.shape
    k = np.zeros((H, W), np.float32)
    k[: kernel.shape[0], : kernel.shape[1]] = kernel
    k = np.roll(k, (-(kernel.shape[0] // 2), -(kernel.shape[1] // 2)), axis=(0, 1))  # centre at (0, 0)
    K = np.fft.rfft2(k)
    F = np.fft.irfft2(np.fft.rfft2(g) * np.conj(K) / (np.abs(K) ** 2 + nsr), s=(H, W))
    return np.clip(F[pad:-pad, pad:-pad] * 255.0 + 0.5, 0, 255).astype(np.uint8)
