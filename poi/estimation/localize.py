"""From a detection box to a map position with its covariance ([Avevor2022]_ 2.2-2.3, [Bouda2025]_ 2.1.3).

Pixel conventions: detection boxes use the corner convention of YOLO exports (pixel
column i covers [i, i + 1), so a box around columns 10..19 is x1 = 10, x2 = 20);
intrinsics, (de)projection and image indexing use RealSense's pixel-centre convention
(pixel i is centred on coordinate i). A box centre cx is therefore the pixel
coordinate u = cx - 0.5.

>>> k = Intrinsics(width=640, height=480, fx=600.0, fy=600.0, ppx=320.0, ppy=240.0)
>>> deproject_pixel_to_point(k, 380.0, 240.0, 2.0).tolist()
[0.2, 0.0, 2.0]
>>> project_point_to_pixel(k, np.array([0.2, 0.0, 2.0])).tolist()
[380.0, 240.0]

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math

import numpy as np

from poi.config import PipelineConfig
from poi.core.sensor_noise import depth_sigma_m
from poi.core.types import Detection, Frame, Intrinsics, Observation
from poi.estimation.covariance import (
    Calibration,
    camera_covariance,
    center_sigmas_px,
    deprojection_jacobian,
    depth_jacobian,
    map_covariance,
    mount_covariance,
)

BOX_CORNER_TO_CENTER_PX = 0.5  # corner-convention coordinate minus this = pixel-centre coordinate
BROWN_CONRADY_ITERATIONS = 10  # as librealsense's rs2_deproject_pixel_to_point


class LocalizeError(ValueError):
    """Inputs to localisation that do not fit together (e.g. depth and intrinsics sizes)."""


def box_depth(depth_m: np.ndarray, box_xyxy, inner_fraction: float) -> float | None:
    """Median of the valid depths (finite, > 0) in the inner fraction of a box ([Bouda2025]_ 2.1.3).

    The box (corner convention) is shrunk about its centre to ``inner_fraction`` of its
    width and height; the pixels whose centres lie inside it count (at least the pixel
    holding the centre). None when none of them is valid.

    >>> d = np.zeros((10, 10), np.float32); d[2:8, 2:8] = 3.0; d[4, 4] = np.nan
    >>> box_depth(d, (0, 0, 10, 10), 0.5)
    3.0
    >>> box_depth(np.zeros((10, 10)), (0, 0, 10, 10), 0.5) is None
    True
    """
    if not 0.0 < inner_fraction <= 1.0:
        raise LocalizeError(f"inner_fraction: expected a value in (0, 1], got {inner_fraction!r}")
    H, W = depth_m.shape
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    cx, cy = 0.5 * (x1 + x2), 0.5 * (y1 + y2)
    hw, hh = 0.5 * inner_fraction * (x2 - x1), 0.5 * inner_fraction * (y2 - y1)

    def span(c: float, half: float, n: int) -> tuple[int, int]:
        # pixels i with centre i + 0.5 in [c - half, c + half]
        lo = math.ceil(c - half - 0.5)
        hi = math.floor(c + half - 0.5)
        if hi < lo:
            lo = hi = math.floor(c)
        return max(lo, 0), min(hi, n - 1)

    c0, c1 = span(cx, hw, W)
    r0, r1 = span(cy, hh, H)
    if c1 < c0 or r1 < r0:
        return None
    patch = np.asarray(depth_m[r0 : r1 + 1, c0 : c1 + 1], dtype=float)
    valid = patch[np.isfinite(patch) & (patch > 0.0)]
    if valid.size == 0:
        return None
    return float(np.median(valid))


def deproject_pixel_to_point(intr: Intrinsics, u: float, v: float, depth: float) -> np.ndarray:
    """Pixel (u, v) and depth to a point in the camera optical frame, as librealsense does.

    Same maths as ``rs2_deproject_pixel_to_point`` (rsutil.h) for models "none" and
    "brown_conrady" (RS2_DISTORTION_BROWN_CONRADY: ten fixed-point iterations undoing
    the radial and tangential terms), in float64 rather than float32.
    """
    x = (u - intr.ppx) / intr.fx
    y = (v - intr.ppy) / intr.fy
    if intr.model == "brown_conrady":
        k1, k2, p1, p2, k3 = intr.coeffs
        xo, yo = x, y
        for _ in range(BROWN_CONRADY_ITERATIONS):
            r2 = x * x + y * y
            icdist = 1.0 / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2)
            delta_x = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
            delta_y = 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y)
            x = (xo - delta_x) * icdist
            y = (yo - delta_y) * icdist
    return np.array([depth * x, depth * y, depth])


def project_point_to_pixel(intr: Intrinsics, point: np.ndarray) -> np.ndarray:
    """A camera-frame point to pixel (u, v), as librealsense's ``rs2_project_point_to_pixel``."""
    x = point[0] / point[2]
    y = point[1] / point[2]
    if intr.model == "brown_conrady":
        k1, k2, p1, p2, k3 = intr.coeffs
        r2 = x * x + y * y
        f = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2
        xf, yf = x * f, y * f
        dx = xf + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        dy = yf + 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y)
        x, y = dx, dy
    return np.array([x * intr.fx + intr.ppx, y * intr.fy + intr.ppy])


def surface_to_center(p_c: np.ndarray, radius_m: float) -> np.ndarray:
    """The centre of a round object of radius ``radius_m`` whose surface point ``p_c`` the depth
    hit: ``p_c (1 + r / |p_c|)``, on the ray one radius further. Its Jacobian,
    ``(1 + r/|p|) I - r p p^T / |p|^3``, is carried into J2 by :func:`localize`.

    >>> surface_to_center(np.array([0.0, 0.0, 2.0]), 0.1).tolist()
    [0.0, 0.0, 2.1]
    """
    if radius_m <= 0.0:
        return p_c
    return p_c * (1.0 + radius_m / float(np.linalg.norm(p_c)))


def localize(
    detection: Detection,
    frame: Frame,
    cfg: PipelineConfig,
    T_tracker_camera: np.ndarray,
    calibration: Calibration | None = None,
) -> Observation | None:
    """Place a detection in the map frame with its covariance R ([Avevor2022]_ 2.2-2.3).

    p_map = Q (Q0 p_c + t0) + t with (Q, t) = ``frame.pose`` (T_map_tracker) and (Q0, t0)
    = ``T_tracker_camera``; R = Q Q0 Sigma_c Q0^T Q^T + sigma_eps^2 I + R_mount
    (:func:`poi.estimation.covariance.mount_covariance`) + extent^2 I, with J2 the Jacobian of
    the deprojection and, for a round object, of its centre offset (:func:`surface_to_center`).
    None when the frame
    has no pose or no depth, no valid depth lies in the box, or the depth is out of range.
    """
    if frame.pose is None or frame.depth_m is None:
        return None
    intr = frame.intrinsics
    depth = frame.depth_m
    if depth.shape != (intr.height, intr.width):
        raise LocalizeError(
            f"frame {frame.index}: depth image {depth.shape[1]}x{depth.shape[0]} does not match "
            f"the colour intrinsics {intr.width}x{intr.height} (depth must be aligned to colour)"
        )
    lc = cfg.localize
    d_med = box_depth(depth, detection.box_xyxy, lc.inner_fraction)
    if d_med is None:
        return None
    d = d_med * lc.depth_scale
    if not lc.min_depth_m <= d <= lc.max_depth_m:
        return None
    cx, cy = detection.center_uv
    u, v = cx - BOX_CORNER_TO_CENTER_PX, cy - BOX_CORNER_TO_CENTER_PX
    w, h = detection.size_wh
    to_center = cfg.localize.surface_to_center_m.get(detection.type, 0.0)

    def point(a: float, b: float, c: float) -> np.ndarray:
        # a round object: the depth is its front surface, the report names its centre
        return surface_to_center(deproject_pixel_to_point(intr, a, b, c), to_center)

    p_c = point(u, v, d)

    # Sigma_1 = diag(sigma_u^2, sigma_v^2, sigma_d^2)
    sigma_u, sigma_v = center_sigmas_px(
        detection.class_name,
        w,
        h,
        a_px=lc.center_sigma_px.a_px,
        b=lc.center_sigma_px.b,
        calibration=calibration,
    )
    sigma_d = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    Sigma_1 = np.diag([sigma_u**2, sigma_v**2, sigma_d**2])
    J1 = depth_jacobian(depth, u, v, lc.depth_scale)
    J2 = deprojection_jacobian(point, u, v, d)  # with the centre offset, for a round object
    Sigma_c = camera_covariance(J1, J2, Sigma_1)

    pose = np.asarray(frame.pose, dtype=float)
    Q, t = pose[:3, :3], pose[:3, 3]
    Q0, t0 = T_tracker_camera[:3, :3], T_tracker_camera[:3, 3]
    # p_map = Q (Q0 p_c + t0) + t
    p_map = Q @ (Q0 @ p_c + t0) + t
    # Sigma_eps: the pose error as delivered (t265 mode), or what the planar SLAM, which adds
    # its own pose covariance later, leaves (height, roll, pitch: slam mode)
    sigma_eps = cfg.slam.sigma_eps_m if lc.mode == "slam" else cfg.tracker.sigma_eps_m
    R = map_covariance(Sigma_c, Q, Q0, sigma_eps)
    extent = cfg.localize.extent_sigma_m.get(detection.type, 0.0)
    if extent > 0.0:
        R = R + extent**2 * np.eye(3)
    # the mount calibration's error (a range-dependent part of what Sigma_eps lumps together)
    R_mount = mount_covariance(Q @ Q0 @ p_c, np.deg2rad(lc.mount_sigma_deg), lc.mount_sigma_m)
    R = R + R_mount
    # Sigma_eps, the mount and the extent (which part of the object the depth hits) repeat
    # from frame to frame; the detection and depth noise in Sigma_c does not
    R_shared = (sigma_eps**2 + extent**2) * np.eye(3) + R_mount
    return Observation(
        detection=detection,
        timestamp_s=frame.timestamp_s,
        position_map=p_map,
        R=R,
        position_cam=p_c,
        Sigma_c=Sigma_c,
        depth_m=d,
        R_shared=R_shared,
    )
