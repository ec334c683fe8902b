"""Depth aligned to the colour camera, as librealsense's ``rs2::align`` does it [IntelProjection]_.

Each valid depth pixel is deprojected with the depth intrinsics, moved into the colour camera by
the extrinsics, and projected with the colour intrinsics. As in ``rs2::align``, the pixel's two
corners (u - 0.5, v - 0.5) and (u + 0.5, v + 0.5) are projected and every colour pixel of the
rectangle between them takes the depth, so a depth image of lower resolution leaves no holes;
where two surfaces land on one colour pixel the nearer one is kept. Lens distortion is not
modelled (the D435's streams report zero coefficients); a stream with coefficients is aligned as
if it had none.

References
----------
Full entries in docs/SOURCES.md.

.. [IntelProjection] Intel RealSense, "Projection in RealSense SDK 2.0", librealsense wiki.
"""

from __future__ import annotations

import numpy as np

from poi.core.types import Intrinsics


def align_depth_to_color(
    depth_m: np.ndarray, depth_k: Intrinsics, color_k: Intrinsics, T_color_depth: np.ndarray
) -> np.ndarray:
    """Depth (metres, float32, 0 invalid) of the colour camera's pixels, (color_k.height, color_k.width).

    ``T_color_depth`` maps depth-camera points into the colour camera: p_c = R p_d + t.

    A wall 2 m in front of a depth camera of the same optics seen from 10 cm to its left (the colour
    camera's origin at x = -0.1 m in the depth frame, so p_c = p_d + (0.1, 0, 0)) appears shifted by
    f * 0.1 / 2 = 5 pixels to the right:

    >>> k = Intrinsics(width=40, height=30, fx=100.0, fy=100.0, ppx=19.5, ppy=14.5)
    >>> z = np.zeros((30, 40), np.float32); z[:, 10:20] = 2.0
    >>> T = np.eye(4); T[0, 3] = 0.1
    >>> a = align_depth_to_color(z, k, k, T)
    >>> np.flatnonzero(a[15]).tolist() == list(range(15, 25))
    True
    """
    z = np.asarray(depth_m, dtype=np.float32)
    if z.shape != (depth_k.height, depth_k.width):
        raise ValueError(
            f"depth image {z.shape[1]}x{z.shape[0]} does not fit its {depth_k.width}x{depth_k.height} intrinsics"
        )
    Hc, Wc = color_k.height, color_k.width
    out = np.full((Hc, Wc), np.inf, dtype=np.float32)
    v, u = np.nonzero(z > 0)  # (N,) rows and columns of the valid pixels
    d = z[v, u].astype(np.float64)
    R, t = T_color_depth[:3, :3], T_color_depth[:3, 3]

    def project(du: float, dv: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = (u + du - depth_k.ppx) / depth_k.fx * d  # deproject, (N,)
        y = (v + dv - depth_k.ppy) / depth_k.fy * d
        p = np.stack([x, y, d], axis=1) @ R.T + t  # (N, 3) in the colour camera
        zc = p[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uc = p[:, 0] / zc * color_k.fx + color_k.ppx
            vc = p[:, 1] / zc * color_k.fy + color_k.ppy
        return uc, vc, zc

    u0, v0, z0 = project(-0.5, -0.5)
    u1, v1, _ = project(0.5, 0.5)
    ok = (z0 > 0) & np.isfinite(u0) & np.isfinite(u1) & np.isfinite(v0) & np.isfinite(v1)
    # the colour pixels whose centres c fall in the projected rectangle, a <= c < b
    lo_u, hi_u = np.minimum(u0, u1)[ok], np.maximum(u0, u1)[ok]
    lo_v, hi_v = np.minimum(v0, v1)[ok], np.maximum(v0, v1)[ok]
    c0, c1 = np.ceil(lo_u).astype(np.int64), np.ceil(hi_u).astype(np.int64) - 1
    r0, r1 = np.ceil(lo_v).astype(np.int64), np.ceil(hi_v).astype(np.int64) - 1
    # a pixel projected smaller than a colour pixel, holding no centre, marks the one nearest it
    small_c, small_r = c1 < c0, r1 < r0
    c0[small_c] = c1[small_c] = np.rint(0.5 * (lo_u + hi_u)[small_c]).astype(np.int64)
    r0[small_r] = r1[small_r] = np.rint(0.5 * (lo_v + hi_v)[small_r]).astype(np.int64)
    zc = z0[ok].astype(np.float32)
    span_c = int((c1 - c0).max(initial=0)) + 1
    span_r = int((r1 - r0).max(initial=0)) + 1
    for dr in range(span_r):
        for dc in range(span_c):
            cc, rr = c0 + dc, r0 + dr
            m = (cc <= c1) & (rr <= r1) & (cc >= 0) & (cc < Wc) & (rr >= 0) & (rr < Hc)
            np.minimum.at(out, (rr[m], cc[m]), zc[m])
    out[~np.isfinite(out)] = 0.0
    return out
