"""Pixels and camera-frame points, as librealsense maps them ([IntelProjection]_), and a round
object's centre behind the surface point its depth hit.

Pixel conventions: detection boxes use the corner convention of YOLO exports (pixel column i
covers [i, i + 1)); intrinsics, (de)projection and image indexing use RealSense's pixel-centre
convention (pixel i is centred on coordinate i). A box centre cx is therefore the pixel
coordinate u = cx - 0.5 (``BOX_CORNER_TO_CENTER_PX``).

>>> k = Intrinsics(width=640, height=480, fx=600.0, fy=600.0, ppx=320.0, ppy=240.0)
>>> deproject_pixel_to_point(k, 380.0, 240.0, 2.0).tolist()
[0.2, 0.0, 2.0]
>>> project_point_to_pixel(k, np.array([0.2, 0.0, 2.0])).tolist()
[380.0, 240.0]

References
----------
Full entries in docs/SOURCES.md.

.. [IntelProjection] Intel RealSense, "Projection in RealSense SDK 2.0", librealsense wiki
   (rsutil.h: ``rs2_deproject_pixel_to_point``, ``rs2_project_point_to_pixel``).
"""

from __future__ import annotations

import numpy as np

from poi.core.types import Intrinsics

BOX_CORNER_TO_CENTER_PX = 0.5  # corner-convention coordinate minus this = pixel-centre coordinate
BROWN_CONRADY_ITERATIONS = 10  # as librealsense's rs2_deproject_pixel_to_point


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
    hit: ``p_c (1 + r / |p_c|)``, on the ray one radius further (a negative r: nearer, for a
    thin object whose depth reads the wall behind it). Its Jacobian,
    ``(1 + r/|p|) I - r p p^T / |p|^3``, is carried into J2 by :func:`localize`.

    >>> surface_to_center(np.array([0.0, 0.0, 2.0]), 0.1).tolist()
    [0.0, 0.0, 2.1]
    >>> surface_to_center(np.array([0.0, 0.0, 2.0]), -0.1).tolist()
    [0.0, 0.0, 1.9]
    """
    if radius_m == 0.0:
        return p_c
    return p_c * (1.0 + radius_m / float(np.linalg.norm(p_c)))
