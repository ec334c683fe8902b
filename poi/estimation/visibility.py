"""Is a track in view? The test behind the negative update (docs/FACTS.md, "Tracking").

A track that is in view but not detected loses support, so false tracks die. In view
means: the track's centre lies in front of the camera within ``max_range`` m, projects
into the image at least ``margin_px`` from its border, and is not hidden: the depth
read at that pixel, when valid, is not smaller than the track's depth minus
``occlusion_tolerance_m``.

>>> from poi.core.types import Frame, Intrinsics
>>> k = Intrinsics(width=64, height=48, fx=50.0, fy=50.0, ppx=31.5, ppy=23.5)
>>> f = Frame(index=0, timestamp_s=0.0, rgb=np.zeros((48, 64, 3), np.uint8), intrinsics=k,
...           depth_m=np.full((48, 64), 2.0, np.float32), pose=np.eye(4))
>>> in_view(np.array([0.0, 0.0, 2.0]), f, np.eye(4), k, margin_px=4, max_range=5.0)
True
>>> in_view(np.array([0.0, 0.0, 3.0]), f, np.eye(4), k, margin_px=4, max_range=5.0)  # behind a wall
False
"""

from __future__ import annotations

import math

import numpy as np

from poi.core.geometry import invert_transform, transform_points
from poi.core.types import Frame, Intrinsics
from poi.estimation.projection import project_point_to_pixel

MIN_VIEW_DEPTH_M = 0.05  # points closer than this to the camera plane are not projected
DEFAULT_OCCLUSION_TOLERANCE_M = 0.3


def pixel_of_map_point(
    point_map: np.ndarray, frame: Frame, T_tracker_camera: np.ndarray, intr: Intrinsics
) -> tuple[float, float, float] | None:
    """(u, v, z): the pixel the map point projects to in ``frame`` (the pinhole model of
    :func:`poi.estimation.projection.project_point_to_pixel`, the camera at ``frame.pose`` times
    the mount ``T_tracker_camera``) and its depth z in the optical frame; None without a pose or
    closer to the camera plane than ``MIN_VIEW_DEPTH_M`` (behind it included). The pixel may lie
    outside the image."""
    if frame.pose is None:
        return None
    T_map_camera = np.asarray(frame.pose, dtype=float) @ T_tracker_camera
    p_c = transform_points(invert_transform(T_map_camera), np.asarray(point_map, dtype=float))
    z = float(p_c[2])
    if z < MIN_VIEW_DEPTH_M:
        return None
    u, v = project_point_to_pixel(intr, p_c)
    return float(u), float(v), z


def in_view(
    track_mu: np.ndarray,
    frame: Frame,
    T_tracker_camera: np.ndarray,
    intr: Intrinsics,
    margin_px: float,
    max_range: float,
    occlusion_tolerance_m: float = DEFAULT_OCCLUSION_TOLERANCE_M,
) -> bool:
    """True when the map point ``track_mu`` is visible in ``frame`` (see module docstring)."""
    seen = pixel_of_map_point(track_mu, frame, T_tracker_camera, intr)
    if seen is None:
        return False
    u, v, z = seen
    if z > max_range:
        return False
    if not (margin_px <= u <= intr.width - 1 - margin_px and margin_px <= v <= intr.height - 1 - margin_px):
        return False
    if frame.depth_m is not None:
        d = float(frame.depth_m[int(round(v)), int(round(u))])
        if math.isfinite(d) and d > 0.0 and d < z - occlusion_tolerance_m:
            return False
    return True
