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
from dataclasses import dataclass
from typing import overload

import cv2
import numpy as np

from poi.config import PipelineConfig
from poi.core.depth_units import DEPTH_UNIT_M
from poi.core.sensor_noise import depth_sigma_m, window_correlation
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
# The depth plane of box_depth_plane: at least this many valid pixels (three fix a plane; a
# few more keep one noisy pixel from tilting it), at most about this many (a grid over a large
# box), and one refit without residuals beyond this many robust sigmas (the wall behind a
# valve's spokes, flying pixels at the box's edge).
PLANE_MIN_PIXELS = 9
PLANE_MAX_PIXELS = 4096
PLANE_OUTLIER_SIGMAS = 3.0
# median_variance_fraction averages a block's noise only when at least this share of its valid
# pixels lie within one sigma_z of the median (68% do on a flat block)
MEDIAN_MIN_BAND = 0.5
# flat_item: a ray within this cosine of the depth plane (87 degrees off its normal) sees
# it edge-on, and the plane says nothing of the item's size
EDGE_ON_COS = 0.05
# in-plane turns of a square sampled over its quarter turn (flat_item with turned=True), and
# the Newton steps that fit each one's centre to its box
TURN_SAMPLES = 9
TURN_NEWTON_STEPS = 3
# planar_face_center: an upright face's unit normal has at most this component along the
# camera's vertical (the sine of 30 degrees: the camera's own pitch and a ramp's, with margin)
PLANAR_MAX_NORMAL_UP = 0.5
# where occluded_sides reads beside a box: from 2 px outside its edge (a box's edge jitters by a
# pixel or two) to 10 px (past an occluder's edge pixels, which the depth camera blurs)
OCCLUDER_STRIP_PX = (2, 10)


class LocalizeError(ValueError):
    """Inputs to localisation that do not fit together (e.g. depth and intrinsics sizes)."""


def _inner_span(shape: tuple[int, int], box_xyxy, inner_fraction: float) -> tuple[int, int, int, int]:
    """(r0, r1, c0, c1), inclusive: the pixels whose centres lie in the box (corner convention)
    shrunk about its centre to ``inner_fraction`` of its width and height (at least the pixel
    holding the centre), clipped to the image; r1 < r0 or c1 < c0 when none is left."""
    if not 0.0 < inner_fraction <= 1.0:
        raise LocalizeError(f"inner_fraction: expected a value in (0, 1], got {inner_fraction!r}")
    H, W = shape
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
    return r0, r1, c0, c1


def _inner_block(depth_m: np.ndarray, box_xyxy, inner_fraction: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The inner block of a box (:func:`_inner_span`) as float depths and its valid-pixel mask
    (finite, > 0); None when the block is empty."""
    r0, r1, c0, c1 = _inner_span(depth_m.shape, box_xyxy, inner_fraction)
    if c1 < c0 or r1 < r0:
        return None
    patch = np.asarray(depth_m[r0 : r1 + 1, c0 : c1 + 1], dtype=float)
    return patch, np.isfinite(patch) & (patch > 0.0)


def median_variance_fraction(
    depth_m: np.ndarray, box_xyxy, inner_fraction: float, window_px: float, sigma: float, median: float
) -> float:
    """The variance of :func:`box_depth`'s median (``median``, as it returned it for this box)
    over one pixel's (``sigma``^2, in the depth image's units): 1^T C 1 / n^2 over the n valid
    pixels of the inner block whose depth lies within ``sigma`` of the median, C their noise's
    correlation over the stereo matcher's window (:func:`correlated_fit_covariance` with A = 1,
    exact for any pattern of holes).

    Those pixels are the ones that decide the median. On a flat block they are most of it and
    the median averages its windows' noise (about window^2 / N of one pixel's variance for N
    pixels); on a surface that slopes or curves by more than ``sigma`` across the block they are
    a band across it, and the median averages less. Checked on 1500 draws each of the
    simulator's noise (:func:`sim.sensors.d435_depth.window_noise`, 7 px) over 20 x 20 px
    blocks, flat, sloping by 0.1-2 sigma a pixel and curved as cylinders: within 2% (1.02-1.37
    times too little with the band at 1.25-2 sigma). A box larger than ``PLANE_MAX_PIXELS`` is
    read on a grid, which gives a little more.

    1 (one pixel's variance) with no valid pixel, or when fewer than ``MEDIAN_MIN_BAND`` of the
    valid pixels lie in that band: the block's surfaces spread by more than its noise (a door's
    leaf, frame and the room past it, seen close), and which of them the median reads changes
    from view to view by more than the noise does. Averaged there as well, the default maze's
    door tracks ended 0.3-0.7 m off at NEES 50-100 (docs/CONSISTENCY.md).

    >>> d = np.full((40, 40), 2.0)
    >>> round(median_variance_fraction(d, (0, 0, 40, 40), 0.5, 7.0, 0.01, 2.0), 4)  # 20 x 20 px
    0.0961
    >>> median_variance_fraction(d, (0, 0, 40, 40), 0.5, 1.0, 0.01, 2.0) == 1 / 400
    True
    """
    block = _inner_block(depth_m, box_xyxy, inner_fraction)
    if block is None or not block[1].any():
        return 1.0
    patch, ok = block
    band = ok & (np.abs(patch - median) <= sigma)
    if np.count_nonzero(band) < MEDIAN_MIN_BAND * np.count_nonzero(ok):
        # the block's surfaces spread by more than its noise: which of them the median reads
        # changes from view to view, and one pixel's variance stays
        return 1.0
    ok = band
    step = max(1, math.ceil(math.sqrt(ok.size / PLANE_MAX_PIXELS)))
    cells = np.argwhere(ok[::step, ::step])
    if len(cells) == 0:
        return 1.0
    rho = window_correlation(max(1, round(window_px)), step)
    return min(1.0, float(correlated_fit_covariance(np.ones((len(cells), 1)), cells, rho)[0, 0]))


def box_depth(
    depth_m: np.ndarray,
    box_xyxy,
    inner_fraction: float,
    min_fill: float = 0.0,
    *,
    split_m: float = math.inf,
    max_split: float = 1.0,
) -> float | None:
    """Median of the valid depths (finite, > 0) in the inner fraction of a box ([Bouda2025]_ 2.1.3).

    The box (corner convention) is shrunk about its centre to ``inner_fraction`` of its
    width and height; the pixels whose centres lie inside it count (at least the pixel
    holding the centre). None when none of them is valid, or when fewer than ``min_fill`` of
    them are: an item seen past a near edge lies in that edge's stereo shadow (no depth), so
    the few valid pixels in its box are the occluder's (``localize.min_depth_fill``).

    None also when more than ``max_split`` of the valid depths lie farther than ``split_m``
    from their median (``localize.max_depth_split``, ``localize.depth_split_m``): the box
    holds two surfaces, and the median may be either or neither. An extinguisher behind a
    bucket (the bucket fills the inner box, the extinguisher shows above and beside it) read
    the bucket, 0.65 m short; a valve on a pipe read the wall behind it, 0.4-1.3 m long.

    >>> d = np.zeros((10, 10), np.float32); d[2:8, 2:8] = 3.0; d[4, 4] = np.nan
    >>> box_depth(d, (0, 0, 10, 10), 0.5)
    3.0
    >>> box_depth(np.zeros((10, 10)), (0, 0, 10, 10), 0.5) is None
    True
    >>> d[2:8, 2:6] = 0.0; box_depth(d, (0, 0, 10, 10), 0.5, min_fill=0.4) is None  # 12 of 36 valid
    True
    >>> d = np.full((10, 10), 3.0); d[2:8, 2:4] = 2.0  # 12 of the inner 36 pixels 1 m nearer
    >>> box_depth(d, (0, 0, 10, 10), 0.5, split_m=0.3, max_split=0.25) is None
    True
    """
    block = _inner_block(depth_m, box_xyxy, inner_fraction)
    if block is None:
        return None
    patch, ok = block
    valid = patch[ok]
    if valid.size == 0 or valid.size < min_fill * patch.size:
        return None
    median = float(np.median(valid))
    if max_split < 1.0 and np.count_nonzero(np.abs(valid - median) > split_m) > max_split * valid.size:
        return None
    return median


@dataclass(kw_only=True)
class DepthPlane:
    """The depth plane of a box (:func:`box_depth_plane`): its depth ``d0`` (m) at pixel
    (``u0``, ``v0``), the centre of the block it was fitted to, its slopes in metres per pixel
    and their variances (m^2 / px^2)."""

    d0: float
    u0: float
    v0: float
    g_u: float
    g_v: float
    var_g_u: float
    var_g_v: float
    # the covariance (m^2, m^2/px, m^2/px^2) of (d0, g_u, g_v) under the depth camera's
    # window-correlated noise (box_depth_plane with mean_variance); only depth_variance_at reads it
    cov: np.ndarray | None = None

    @overload
    def depth_at(self, u: float, v: float) -> float: ...
    @overload
    def depth_at(self, u: np.ndarray, v: np.ndarray) -> np.ndarray: ...
    def depth_at(self, u, v):
        """The plane's depth (m) at pixel (u, v): d0 + g_u (u - u0) + g_v (v - v0); elementwise
        for arrays of pixels.

        >>> DepthPlane(d0=2.0, u0=10.0, v0=5.0, g_u=0.01, g_v=0.0, var_g_u=0.0, var_g_v=0.0).depth_at(12.0, 9.0)
        2.02
        """
        return self.d0 + self.g_u * (u - self.u0) + self.g_v * (v - self.v0)

    def depth_variance_at(self, u: float, v: float) -> float:
        """The variance (m^2) of :meth:`depth_at`: x^T cov x with x = (1, u - u0, v - v0).

        >>> pl = DepthPlane(d0=2.0, u0=10.0, v0=5.0, g_u=0.01, g_v=0.0, var_g_u=0.0, var_g_v=0.0,
        ...                 cov=np.diag([1e-5, 1e-6, 0.0]))
        >>> round(pl.depth_variance_at(12.0, 5.0), 12)
        1.4e-05
        """
        if self.cov is None:
            raise LocalizeError("DepthPlane.depth_variance_at: the plane was fitted without mean_variance")
        x = np.array([1.0, u - self.u0, v - self.v0])
        return float(x @ self.cov @ x)


def correlated_fit_covariance(A: np.ndarray, cells: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """(A^T A)^-1 A^T C A (A^T A)^-1: the covariance, in units of the noise's variance, of the
    least-squares coefficients of rows ``A`` (N, p) sampled at grid ``cells`` (N, 2: row,
    column), whose noise correlates between cells (di, dj) apart by rho[di] rho[dj] (``rho``
    symmetric, centred; :func:`poi.core.sensor_noise.window_correlation`). C A is a separable
    convolution of each column laid out on the grid, so no N x N matrix is formed.

    >>> A = np.ones((4, 1)); cells = np.array([[0, 0], [0, 1], [0, 2], [0, 3]])
    >>> correlated_fit_covariance(A, cells, np.array([1.0])).tolist()  # independent: 1 / N
    [[0.25]]
    >>> correlated_fit_covariance(A, cells, np.ones(7)).tolist()  # one error shared by all
    [[1.0]]
    """
    n_rows, n_cols = int(cells[:, 0].max()) + 1, int(cells[:, 1].max()) + 1
    kernel = np.asarray(rho, dtype=np.float64)
    CA = np.empty_like(A, dtype=np.float64)
    grid = np.zeros((n_rows, n_cols), np.float64)
    for j in range(A.shape[1]):
        grid[:] = 0.0
        grid[cells[:, 0], cells[:, 1]] = A[:, j]
        conv = cv2.sepFilter2D(grid, cv2.CV_64F, kernel, kernel, borderType=cv2.BORDER_CONSTANT)
        CA[:, j] = conv[cells[:, 0], cells[:, 1]]
    inv = np.linalg.pinv(A.T @ A)
    return inv @ (A.T @ CA) @ inv


def box_depth_plane(
    depth_m: np.ndarray,
    box_xyxy,
    inner_fraction: float,
    window_px: float = 1.0,
    noise_sigma_m: float | None = None,
    mean_variance: bool = False,
    split_m: float = math.inf,
    inverse: bool = False,
) -> DepthPlane | None:
    """The least-squares plane d = a + g_u (u - c_u) + g_v (v - c_v) through the valid depths of
    the same inner box as :func:`box_depth`, refitted once without the pixels more than
    ``PLANE_OUTLIER_SIGMAS`` robust standard deviations (1.4826 MAD) off the first plane.
    None with fewer than ``PLANE_MIN_PIXELS`` valid pixels or when they do not span both axes.

    Only the depths within ``split_m`` of the block's median count (``localize.depth_split_m``,
    the item's surface as :func:`box_depth` tells two apart): a nearer surface in part of the
    block is another surface, not a slope. A QR code at 4.2 m whose box's left 4 of 30 columns
    lay on a wall edge at 3.0 m got a plane of 34 mm a pixel from a first fit through both (the
    outlier refit then kept the wall), was measured 1.9 m wide on it and called cut in height by
    130 px: R 0.5 m wide against an error of 2 cm.

    J1 needs how the box's depth changes when the box moves by a pixel. Central differences
    of single pixels at the centre (:func:`poi.estimation.covariance.depth_jacobian`) read the
    D435's per-pixel noise instead: at 1 m its sigma_z (4 mm) is larger than the slope of a
    wall seen at 45 degrees (about 1.7 mm per pixel), so the gradient they give points anywhere,
    and Sigma_c, which is thin across the surface, came out thin in the wrong direction. The
    plane averages that noise over the box.

    ``d0`` is the plane's depth at the block's centre (u0, v0), where :func:`localize` reads a
    flat item's depth (:meth:`DepthPlane.depth_at`).

    The slopes' variances are the least-squares ones, s^2 (A^T A)^-1, times ``window_px``^2:
    stereo matching correlates the noise of neighbouring pixels over its window, so N pixels
    hold about N / window^2 independent errors. s is ``noise_sigma_m``, the depth camera's
    per-pixel noise, when given (a 3-D object's curvature leaves residuals that are no noise,
    and would count as slope error), else the residuals' standard deviation.

    With ``mean_variance``, ``cov`` is the covariance of (d0, g_u, g_v) when the depths' noise
    correlates as the stereo matcher's window makes it (C over the samples that count,
    :func:`poi.core.sensor_noise.window_correlation`): the least-squares sandwich
    s^2 (A^T A)^-1 A^T C A (A^T A)^-1, exact for any pattern of holes
    (:func:`correlated_fit_covariance`), with s^2 the larger of the noise given and the
    residuals' own (RSS / (N - tr(H C)), unbiased for that noise: a dark or textureless block
    is noisier than the camera's nominal sigma_z, and shows it). Its d0 variance is about
    s^2 window^2 / N for a block of N pixels, far less than one pixel's s^2: the variance of a
    flat item's depth read on its plane (``localize.flat_depth_variance: plane``). The scaled
    slope variances above stay as they are for J1 and the tilt checks: they are 2-10 times the
    exact ones in blocks of 6-12 px (docs/CONSISTENCY.md).

    With ``inverse``, the fit is of 1 / d instead, a + b_u (u - c_u) + b_v (v - c_v), and the
    plane returned is its tangent at the block's centre: d0 = 1 / a, g = -b d0^2, the
    covariances carried through that map's Jacobian. A surface that is flat in space has an
    inverse depth linear in the pixel (n . (z r) = c with r = K^-1 (u, v, 1) gives
    1 / z = n . r / c), and a depth that is not: across a door's leaf seen 75 degrees off
    face-on its depth runs from 2.0 to 2.8 m over 64 px, where the straight fit's slope is the
    chord's, not the tangent's at the centre. The stereo noise is also even in 1 / z (a
    disparity's), so ``noise_sigma_m`` is taken at the block's median depth, over its square.

    >>> v, u = np.mgrid[0:20, 0:20]
    >>> pl = box_depth_plane(2.0 + 0.01 * u + 0.002 * v, (0, 0, 20, 20), 0.5)
    >>> round(pl.g_u, 6), round(pl.g_v, 6), pl.var_g_u < 1e-20
    (0.01, 0.002, True)
    >>> pl = box_depth_plane(1.0 / (0.5 - 0.002 * (u - 9.5)), (0, 0, 20, 20), 0.5, inverse=True)
    >>> round(pl.d0, 6), round(pl.g_u, 6), round(pl.g_v, 6)  # the tangent at u = 9.5: 0.002 / 0.5^2
    (2.0, 0.008, 0.0)
    """
    r0, r1, c0, c1 = _inner_span(depth_m.shape, box_xyxy, inner_fraction)
    if c1 <= c0 or r1 <= r0:
        return None
    # at most about PLANE_MAX_PIXELS pixels: a box filling the image fits as well from a grid
    step = max(1, math.ceil(math.sqrt((r1 - r0 + 1) * (c1 - c0 + 1) / PLANE_MAX_PIXELS)))
    # whole-pixel slices only: a depth image may be an array-like that takes no step
    patch = np.asarray(depth_m[r0 : r1 + 1, c0 : c1 + 1], dtype=float)[::step, ::step]
    rows, cols = np.mgrid[r0 : r1 + 1 : step, c0 : c1 + 1 : step]
    ok = np.isfinite(patch) & (patch > 0.0)
    if math.isfinite(split_m) and ok.any():
        ok &= np.abs(patch - float(np.median(patch[ok]))) <= split_m
    if int(ok.sum()) < PLANE_MIN_PIXELS:
        return None
    d = patch[ok]
    if inverse:
        if noise_sigma_m is not None:
            noise_sigma_m = noise_sigma_m / float(np.median(d)) ** 2
        d = 1.0 / d
    u0, v0 = 0.5 * (c0 + c1), 0.5 * (r0 + r1)
    du = cols[ok] - u0
    dv = rows[ok] - v0
    cells = np.argwhere(ok)  # each sample's (row, column) on the grid, in the order of d
    if np.ptp(du) == 0 or np.ptp(dv) == 0:
        return None
    A = np.stack([np.ones_like(d), du, dv], axis=1)  # (N, 3)
    coef = np.linalg.lstsq(A, d, rcond=None)[0]
    res = d - A @ coef
    s = 1.4826 * float(np.median(np.abs(res - np.median(res))))
    keep = np.abs(res) <= PLANE_OUTLIER_SIGMAS * s if s > 0.0 else np.ones(d.size, bool)
    if PLANE_MIN_PIXELS <= int(keep.sum()) < d.size and np.ptp(du[keep]) > 0 and np.ptp(dv[keep]) > 0:
        A, d, cells = A[keep], d[keep], cells[keep]
        coef = np.linalg.lstsq(A, d, rcond=None)[0]
    res = d - A @ coef
    s2 = float(res @ res) / max(d.size - 3, 1) if noise_sigma_m is None else noise_sigma_m**2
    # each sample of the grid stands for step^2 pixels; the window correlates window^2 of them
    cov = s2 * max(window_px / step, 1.0) ** 2 * np.linalg.pinv(A.T @ A)  # (3, 3)
    exact = None
    if mean_variance:
        rho = window_correlation(max(1, round(window_px)), step)
        M = correlated_fit_covariance(A, cells, rho)
        # the residuals' noise variance, unbiased for correlated noise: E[RSS] = s^2 (N - tr(H C))
        s2_res = float(res @ res) / max(d.size - float(np.trace(M @ (A.T @ A))), 1.0)
        exact = max(s2, s2_res) * M
    if inverse:
        # (1 / a, -b_u / a^2, -b_v / a^2) and its Jacobian in (a, b_u, b_v)
        a, b_u, b_v = (float(c) for c in coef)
        d0 = 1.0 / a
        J = np.array(
            [[-(d0**2), 0.0, 0.0], [2.0 * b_u * d0**3, -(d0**2), 0.0], [2.0 * b_v * d0**3, 0.0, -(d0**2)]]
        )
        coef = np.array([d0, -b_u * d0**2, -b_v * d0**2])
        cov = J @ cov @ J.T
        exact = None if exact is None else J @ exact @ J.T
    return DepthPlane(
        d0=float(coef[0]),
        u0=u0,
        v0=v0,
        g_u=float(coef[1]),
        g_v=float(coef[2]),
        var_g_u=float(cov[1, 1]),
        var_g_v=float(cov[2, 2]),
        cov=exact,
    )


@dataclass(kw_only=True)
class FlatItem:
    """A flat item framed by a box, measured on its depth plane (:func:`flat_item`): its
    width and height (m), the camera-frame point of its centre, and its plane's unit normal,
    pointing away from the camera."""

    width_m: float
    height_m: float
    center: np.ndarray
    normal: np.ndarray
    # the centre's spread over an unknown in-plane turn (px, along u and v; 0 unless turned)
    turn_sigma_px: tuple[float, float] = (0.0, 0.0)


def flat_item(
    intr: Intrinsics,
    u: float,
    v: float,
    d: float,
    grad: tuple[float, float],
    box_xyxy,
    diamond: bool = False,
    turned: bool = False,
) -> FlatItem | None:
    """The size and centre of the flat item (a sign) a box frames, on the depth plane; None
    when the plane is seen edge-on.

    The plane passes through the box centre's point p(u, v, d) with the depth gradient
    ``grad`` (:func:`box_depth_plane`); the rays of the box's sides meet it in lines. A wall
    sign (the plane turned about the image's vertical) lies between the lines of the box's
    two vertical sides: its width is their distance, its centre line halfway. Perspective makes
    its near edge larger in the image, and off the camera's height also higher or lower, so the
    box centre is not the image of the sign's centre (1-2 cm off at 0.5-1 m and 45 degrees).
    Heights along the sides, X . e (e the sides' direction on the plane), are 0 at the
    camera's height: a rectangle's top edge reaches the box's top row at its near side when it
    lies above the camera (seen nearer, it reaches higher), else at its far side, and its bottom
    edge alike; the centre is halfway between the two on the centre line. A diamond (a hazmat
    placard) touches its box's top and bottom rows at its own centre column. A floor sign: the
    same with rows and columns swapped. Corner convention: column x1 is pixel coordinate
    x1 - 0.5.

    A diamond hung at an unknown in-plane turn (``turned``: a placard hung at any angle) is a
    square whose corners may touch the box's ends anywhere: seen at an angle and off the
    camera's height, the diamond rule's centre was 5-12 px off (a placard 1 m away, 70 degrees
    off face-on, turned 15-45 degrees), against a centre sigma of 6-7 px. For each of
    ``TURN_SAMPLES`` turns over a quarter turn, the square whose across extent is the box
    sides' distance on the plane has its centre height fitted (Newton) so that its corners'
    images span the box's ends about their middle; the centre is the mean over the turns, and
    ``turn_sigma_px`` their spread imaged at the centre (the turn taken as uniform).

    >>> k = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=320.0, ppy=240.0)
    >>> f = flat_item(k, 319.5, 239.5, 2.0, (0.0, 0.0), (270, 215, 370, 265))
    >>> round(f.width_m, 6), round(f.height_m, 6), f.center.round(6).tolist()
    (0.4, 0.2, [-0.002, -0.002, 2.0])
    """
    x1, y1, x2, y2 = (float(c) - BOX_CORNER_TO_CENTER_PX for c in box_xyxy)
    gu, gv = grad
    P0 = deproject_pixel_to_point(intr, u, v, d)
    n = np.cross(
        deproject_pixel_to_point(intr, u + 1.0, v, d + gu) - P0,
        deproject_pixel_to_point(intr, u, v + 1.0, d + gv) - P0,
    )
    if not np.any(n):
        return None
    n = n / np.linalg.norm(n)
    n = -n if float(n @ P0) < 0.0 else n  # away from the camera

    def on_plane(a: float, b: float) -> np.ndarray | None:
        r = deproject_pixel_to_point(intr, a, b, 1.0)
        nr = float(n @ r)
        if abs(nr) < EDGE_ON_COS * float(np.linalg.norm(r)):
            return None
        t = float(n @ P0) / nr
        return t * r if t > 0.0 else None

    wall = abs(n[0]) >= abs(n[1])

    def at(side: float, end: float) -> np.ndarray | None:
        # the plane point on box side ``side`` (a column for a wall, a row for a floor) at ``end``
        return on_plane(side, end) if wall else on_plane(end, side)

    (sa, sb), (e0, e1) = ((x1, x2), (y1, y2)) if wall else ((y1, y2), (x1, x2))
    a0, a1, b0, b1 = at(sa, e0), at(sa, e1), at(sb, e0), at(sb, e1)
    if a0 is None or a1 is None or b0 is None or b1 is None:
        return None
    la, lb = float(np.linalg.norm(a1 - a0)), float(np.linalg.norm(b1 - b0))
    if la <= 0.0 or lb <= 0.0:
        return None
    e = (a1 - a0) / la + (b1 - b0) / lb  # along the sides, from end e0 to end e1
    e = e / float(np.linalg.norm(e))
    gap = b0 - a0
    gap = gap - (gap @ e) * e  # from side a's line to side b's, across
    across = float(np.linalg.norm(gap))
    mid = 0.5 * (a0 + a1) + 0.5 * gap  # on the item's centre line
    if diamond:
        # the corners touching ends e0 and e1 lie on the centre line
        uv = project_point_to_pixel(intr, mid)
        c = float(uv[0] if wall else uv[1])
        T, B = at(c, e0), at(c, e1)
        if T is None or B is None:
            return None
        lo, hi = float(T @ e), float(B @ e)
    else:
        # X @ e is a point's height along the sides, 0 at the camera's: a rectangle's edge at
        # end e0 meets the box there at its near side when it lies before the camera's height
        # (seen from nearer, it reaches further out), else at its far side; end e1 alike
        near_a = float(np.linalg.norm(a0 + a1)) <= float(np.linalg.norm(b0 + b1))
        (n0, n1), (f0, f1) = ((a0, a1), (b0, b1)) if near_a else ((b0, b1), (a0, a1))
        lo = float(n0 @ e) if float(n0 @ e) <= 0.0 else float(f0 @ e)
        hi = float(n1 @ e) if float(n1 @ e) >= 0.0 else float(f1 @ e)
    along = max(hi - lo, 0.0)
    height = 0.5 * (lo + hi)  # the centre's, along e
    turn_sigma_px = (0.0, 0.0)
    if diamond and turned:
        g = gap / across if across > 0.0 else gap
        heights = _turned_square_heights(intr, mid, e, g, 0.5 * across, (e0, e1), height, wall)
        height = float(heights.mean())
        spread = float(heights.std())
        span = [
            project_point_to_pixel(intr, mid + (height + k * spread - float(mid @ e)) * e) for k in (-1.0, 1.0)
        ]
        d_px = 0.5 * np.abs(span[1] - span[0])
        turn_sigma_px = (float(d_px[0]), float(d_px[1]))
    center = mid + (height - float(mid @ e)) * e
    w_m, h_m = (across, along) if wall else (along, across)
    return FlatItem(width_m=w_m, height_m=h_m, center=center, normal=n, turn_sigma_px=turn_sigma_px)


def _turned_square_heights(
    intr: Intrinsics,
    mid: np.ndarray,
    e: np.ndarray,
    g: np.ndarray,
    half_across: float,
    ends: tuple[float, float],
    start: float,
    wall: bool,
) -> np.ndarray:
    """The centre heights (along ``e``) of squares turned by each of ``TURN_SAMPLES`` angles
    over a quarter turn whose images fit a box (:func:`flat_item`).

    The squares lie on the plane with their centre on the centre line (through ``mid``, along
    the unit ``e``), ``g`` the unit direction across it. A square turned by theta has corners
    at angles phi = theta + k pi / 2 about its centre, r (cos phi g + sin phi e) away, and its
    across extent r max(|cos theta|, |sin theta|) is ``half_across`` (the box sides' lines).
    Each centre height h solves F(h) = (min + max) / 2 - (e0 + e1) / 2 = 0 over the corners'
    image coordinates along the box's ends (rows for a wall sign, columns for a floor one),
    by Newton's method from ``start`` with a 1 mm difference quotient.
    """
    theta = (np.arange(TURN_SAMPLES) + 0.5) * (0.5 * np.pi / TURN_SAMPLES)
    r = half_across / np.maximum(np.abs(np.cos(theta)), np.abs(np.sin(theta)))
    phi = theta[:, None] + 0.5 * np.pi * np.arange(4)[None, :]  # (turns, corners)
    across = r[:, None] * np.cos(phi)
    rise = r[:, None] * np.sin(phi)
    base = mid - float(mid @ e) * e  # the centre line's point at height 0
    axis = 1 if wall else 0
    target = 0.5 * (ends[0] + ends[1])

    def middle(h: np.ndarray) -> np.ndarray:
        pts = base + across[..., None] * g + (h[:, None] + rise)[..., None] * e  # (turns, 4, 3)
        coord = project_point_to_pixel(intr, pts.reshape(-1, 3).T)[axis].reshape(pts.shape[:2])
        return 0.5 * (coord.min(axis=1) + coord.max(axis=1)) - target

    h = np.full(TURN_SAMPLES, float(start))
    step = 1e-3
    for _ in range(TURN_NEWTON_STEPS):
        f = middle(h)
        slope = (middle(h + step) - f) / step
        h = h - np.divide(f, slope, out=np.zeros_like(f), where=np.abs(slope) > 0.0)
    return h


@dataclass(kw_only=True)
class FlatMeasure:
    """A flat item measured from its box (:func:`measure_flat_item`): its centre on the depth
    plane (camera frame; None where the plane's tilt is not known well enough), the pixels its
    box leaves out across u and v, the move of the box centre (px) that puts it at the
    centre of the whole item where the image border cut it (0 elsewhere), and the centre's
    spread over an unknown in-plane turn (px along u and v: :func:`flat_item`)."""

    centre: np.ndarray | None
    hidden_w: float
    hidden_h: float
    shift_u: float = 0.0
    shift_v: float = 0.0
    turn_sigma_px: tuple[float, float] = (0.0, 0.0)


def hidden_lengths_px(
    size_wh: tuple[float, float], size_m: tuple[float, float], aspect: float, tolerance: float
) -> tuple[float, float]:
    """How many pixels of a flat item of width / height ``aspect`` a w x h box leaves out,
    (across u, across v); at most one is non-zero.

    ``size_m`` is the box's (width, height) measured on the item's plane
    (:func:`flat_item`). q = (W / H) / aspect is 1 for the whole item (a cut box is
    only ever shorter than the item); q < 1 - ``tolerance`` says its width was cut (by the
    image border or an occluder in front) and about w / q - w pixels are hidden;
    1 / q < 1 - ``tolerance`` says the same of its height. The box then holds the visible part,
    and its centre is off the item's by up to half the hidden length, on a side the box does
    not say (:func:`localize` widens sigma_u or sigma_v by that half).

    >>> hidden_lengths_px((50.0, 100.0), (0.1, 0.2), 1.0, 0.1)
    (50.0, 0.0)
    >>> hidden_lengths_px((95.0, 100.0), (0.19, 0.2), 1.0, 0.1)
    (0.0, 0.0)
    """
    w, h = size_wh
    W, H = size_m
    if w <= 0.0 or h <= 0.0 or W <= 0.0 or H <= 0.0 or aspect <= 0.0:
        return 0.0, 0.0
    q = W / H / aspect
    if q < 1.0 - tolerance:
        return w / q - w, 0.0
    if 1.0 / q < 1.0 - tolerance:
        return 0.0, h * q - h
    return 0.0, 0.0


def hidden_solid_px(
    size_wh: tuple[float, float],
    size_m: tuple[float, float],
    depth_m: float,
    focal_px: tuple[float, float],
    at_border: tuple[bool, bool],
) -> tuple[float, float]:
    """How many pixels of a 3-D item a box cut by the image border leaves out, (across u,
    across v): f S / z - w on an axis where the box touches the border (``at_border``, from
    :func:`box_at_border`), S the width or height the type's uncut box spans (``size_m``,
    ``localize.box_width_m`` / ``box_height_m``; 0: not known), z the depth of its centre and
    f the focal length (a length S at depth z spans f S / z pixels);
    0 on an axis the box does not touch, or where it is no shorter than f S / z.

    A flat item's box says by its own shape how much of it is cut (:func:`hidden_lengths_px`);
    a 3-D item's shape changes with the side seen, so only the border says that it is cut, and
    its known size how much. The box holds the visible part, its centre off the item's by up
    to half the hidden length, toward the image's inside (:func:`localize`).

    >>> hidden_solid_px((90.0, 240.0), (0.16, 0.52), 1.0, (615.0, 615.0), (False, True))
    (0.0, 79.8)
    >>> hidden_solid_px((90.0, 240.0), (0.16, 0.52), 1.0, (615.0, 615.0), (True, False))
    (8.4, 0.0)
    """
    out = []
    for n_px, s_m, f_px, cut in zip(size_wh, size_m, focal_px, at_border, strict=True):
        full = f_px * s_m / depth_m if cut and s_m > 0.0 and depth_m > 0.0 else 0.0
        out.append(round(max(full - n_px, 0.0), 9))
    return out[0], out[1]


def box_at_border(box_xyxy, width: int, height: int, border_px: float | tuple[float, float]) -> tuple[bool, bool]:
    """Whether a box (corner convention) comes within ``border_px`` of the image's left or right
    edge, and of its top or bottom edge; ``border_px`` may be one margin or one per axis (u, v).

    >>> box_at_border((0.0, 100.0, 50.0, 200.0), 640, 480, 2.0), box_at_border((3, 3, 637, 477), 640, 480, 2.0)
    ((True, False), (False, False))
    >>> box_at_border((3, 3, 637, 477), 640, 480, (2.0, 4.0))
    (False, True)
    """
    (left, right), (top, bottom) = _border_contacts(box_xyxy, width, height, border_px)
    return left or right, top or bottom


def _border_contacts(
    box_xyxy, width: int, height: int, border_px: float | tuple[float, float]
) -> tuple[tuple[bool, bool], tuple[bool, bool]]:
    """Whether a box (corner convention) comes within ``border_px`` (one margin, or one per
    axis) of the image's (left, right) and (top, bottom) edges."""
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    bu, bv = border_px if isinstance(border_px, tuple) else (border_px, border_px)
    return (x1 <= bu, x2 >= width - bu), (y1 <= bv, y2 >= height - bv)


def border_sides(box_xyxy, width: int, height: int, border_px: float | tuple[float, float]) -> tuple[int, int]:
    """Which image border a box (corner convention) comes within ``border_px`` of, across u and
    v: -1 the left (top), +1 the right (bottom), 0 neither or both (a box that spans the image
    says no side), as :func:`box_at_border` tests.

    >>> border_sides((0.0, 100.0, 50.0, 478.0), 640, 480, 4.0), border_sides((1, 3, 639, 477), 640, 480, 2.0)
    ((-1, 1), (0, 0))
    """
    (left, right), (top, bottom) = _border_contacts(box_xyxy, width, height, border_px)
    return int(right) - int(left), int(bottom) - int(top)


def occluded_sides(
    depth_m: np.ndarray,
    box_xyxy,
    surface: float | DepthPlane,
    margin_m: float,
    strip_px: tuple[int, int] = OCCLUDER_STRIP_PX,
) -> tuple[bool, bool]:
    """Whether a nearer surface borders a box on its left or right side, and on its top: the
    box then holds the part of the item that the occluder leaves visible. Not on its bottom:
    below an item on the floor lies the floor before it, which is nearer by its slope (0.2 m
    10 px below a heater 2 m from a camera 0.3 m up) and occludes nothing.

    On each side a strip ``strip_px`` = (from, to) pixels outside the box edge, along the
    middle half of the edge, is read; the side is occluded when at least half of the strip's
    valid depths lie more than ``margin_m`` nearer than the item's ``surface`` carried on to
    them: its depth plane (:func:`box_depth_plane`), or one depth for the whole box. A door
    seen past a corridor's corner is; a door seen at 70 degrees is not, though its near edge
    and the wall beside it are 0.3 m nearer than its centre. A strip outside the image or
    without valid depth says nothing. The strip starts a few pixels out so that a box a few
    pixels too small still reads past the item's own edge.

    >>> d = np.full((100, 100), 3.0, np.float32); d[:, :40] = 1.0  # a wall 2 m nearer on the left
    >>> occluded_sides(d, (40, 30, 70, 70), 3.0, 0.15)
    (True, False)
    >>> occluded_sides(d, (60, 30, 90, 70), 3.0, 0.15), occluded_sides(d, (40, 30, 70, 70), 1.1, 0.15)
    ((False, False), (False, False))
    >>> d = 1.0 + 0.02 * np.arange(100.0)[None, :].repeat(100, 0)  # a wall seen at a slant
    >>> slant = DepthPlane(d0=2.1, u0=55.0, v0=50.0, g_u=0.02, g_v=0.0, var_g_u=0.0, var_g_v=0.0)
    >>> occluded_sides(d, (40, 30, 70, 70), slant, 0.15), occluded_sides(d, (40, 30, 70, 70), 2.1, 0.15)
    ((False, False), (True, False))
    """
    h, w = depth_m.shape
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    a, b = strip_px
    r0, r1 = max(int(y1 + 0.25 * (y2 - y1)), 0), min(int(math.ceil(y2 - 0.25 * (y2 - y1))), h)
    c0, c1 = max(int(x1 + 0.25 * (x2 - x1)), 0), min(int(math.ceil(x2 - 0.25 * (x2 - x1))), w)
    u_end = int(math.ceil(x2))
    strips = (  # (rows, columns) of each strip: left, right, top
        ((r0, r1), (max(int(x1) - b, 0), max(int(x1) - a, 0))),
        ((r0, r1), (min(u_end + a, w), min(u_end + b, w))),
        ((max(int(y1) - b, 0), max(int(y1) - a, 0)), (c0, c1)),
    )

    def nearer(rows: tuple[int, int], cols: tuple[int, int]) -> bool:
        if rows[1] <= rows[0] or cols[1] <= cols[0]:
            return False
        z = np.asarray(depth_m[rows[0] : rows[1], cols[0] : cols[1]], dtype=float)
        if isinstance(surface, DepthPlane):
            vv, uu = np.mgrid[rows[0] : rows[1], cols[0] : cols[1]]
            item = surface.depth_at(uu, vv)
        else:
            item = np.full(z.shape, float(surface))
        ok = np.isfinite(z) & (z > 0.0)
        return bool(ok.any() and np.count_nonzero(z[ok] < item[ok] - margin_m) >= 0.5 * np.count_nonzero(ok))

    left, right, top = (nearer(rows, cols) for rows, cols in strips)
    return left or right, top


def plane_slope_sigma(var_g: tuple[float, float], intr: Intrinsics, d: float) -> float:
    """The standard error of a depth plane's tilt, as the larger of its two slopes' tangents:
    sqrt(var(g)) f / d for the gradient g (m / px) at depth d (m); ``localize.
    flat_max_slope_sigma`` bounds it where a measure needs the tilt.

    >>> k = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=320.0, ppy=240.0)
    >>> plane_slope_sigma((1e-6, 4e-6), k, 2.0)
    0.5
    """
    return max(math.sqrt(var_g[0]) * intr.fx, math.sqrt(var_g[1]) * intr.fy) / d


def least_tilted_gradient(
    grad: tuple[float, float], var_g: tuple[float, float], n_sigmas: float
) -> tuple[float, float]:
    """The depth gradient (m / px) of the most face-on plane a measured one allows: each
    axis's slope moved toward 0 by ``n_sigmas`` of its standard errors, not past 0. A plane
    seen face-on makes an item look widest, so a box judged on this plane is called cut only
    when no tilt within ``n_sigmas`` explains its shortfall.

    >>> [round(g, 6) for g in least_tilted_gradient((0.01, -0.001), (1e-6, 1e-6), 2.0)]
    [0.008, -0.0]
    """
    out = []
    for g, var in zip(grad, var_g, strict=True):
        shrink = n_sigmas * math.sqrt(max(var, 0.0))
        out.append(math.copysign(max(abs(g) - shrink, 0.0), g))
    return out[0], out[1]


def measure_flat_item(
    detection: Detection,
    intr: Intrinsics,
    u: float,
    v: float,
    d: float,
    grad: tuple[float, float],
    var_g: tuple[float, float],
    lc,
    depth_m: np.ndarray | None = None,
    *,
    at_border: tuple[bool, bool],
    cause: tuple[bool, bool] = (True, True),
    toward: tuple[int, int] = (0, 0),
) -> FlatMeasure:
    """A flat item of ``lc.aspect`` measured from its box (:class:`FlatMeasure`): its centre
    measured on the depth plane (:func:`flat_item`) when the plane's tilt is known to
    ``lc.flat_max_slope_sigma`` (of its tangent: the slope's standard error times f / d), else
    None, and the pixels its box leaves out across u and v (:func:`hidden_lengths_px`).

    The image border hides the part beyond it: where a box is cut on an axis by the border on
    side ``toward`` (-1 left / top, +1 right / bottom, 0 none: :func:`border_sides`), the
    plane's tilt is known and ``lc.flat_border_shift`` is on, the box is taken to go on past
    that border by the hidden length, and the centre is the extended box's (shift_u / shift_v,
    the move of the box centre in pixels). With the tilt not known the hidden length is a bound
    only, and the centre stays. Left at the visible part's centre and widened by half the
    hidden length both ways, placards cut at the top or bottom of the image came out 2.6 cm
    short of the border side on average (35 views, vertical NEES 2.0, docs/CONSISTENCY.md).

    The shape is judged on the plane when its tilt is known; a plane tilted by its error theta
    lengthens a side by 1 / cos(theta) - 1, about theta^2 / 2, so the tolerance then grows by
    slope_sigma^2 (two sigmas' worth). Else (a far or narrow box's few noisy pixels do not fix
    the tilt) it is judged on the most face-on plane the depth allows
    (:func:`least_tilted_gradient`, ``lc.flat_tilt_sigmas``), fitted to the whole box in
    ``depth_m`` (a wider base than the inner box; the wall around a placard is in its plane),
    or to the inner box when that fit fails: the widest the item can look, so the hidden length
    is an upper bound at that many sigmas. Judging such a box face-on, as this did before,
    took a sign seen at 75 degrees (15 x 65 px) for one cut to a quarter: its sigma_u grew by
    25 px and R's widest axis to 0.2-0.4 m against errors of 2-3 cm (README, "Covariance
    consistency"). A box touching the image border on an axis (``at_border``, u and v:
    :func:`box_at_border`) counts as cut there whenever it is short of the shape at all (no
    tolerance on that axis). An axis without a ``cause`` (``localize.flat_cut_needs_cause``:
    neither the image border nor a nearer surface borders the box there, :func:`localize`)
    is not cut, whatever the shape: a sign on a wall is hidden only by something. Judged by
    shape alone, 40% of the signs' views with more than 90% of the sign in sight were called
    cut (box jitter, a tilt that noise leaves open), and their R's widest axis came out 1.5-3
    times too wide beyond 3 m (docs/CONSISTENCY.md).
    """
    t = detection.type
    diamond = t in lc.diamond_types
    slope_sigma = plane_slope_sigma(var_g, intr, d)
    fitted = slope_sigma <= lc.flat_max_slope_sigma
    # the turn model only where the centre is kept (a tilt not known gives no centre)
    turned = fitted and t in lc.turned_types
    item = flat_item(intr, u, v, d, grad, detection.box_xyxy, diamond, turned)
    if fitted:
        shape = item
    else:
        wide = None
        if depth_m is not None:
            sigma_px = depth_sigma_m(
                d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m
            )
            wide = box_depth_plane(
                depth_m, detection.box_xyxy, 1.0, lc.depth_window_px, sigma_px, split_m=lc.depth_split_m
            )
        if wide is not None:
            grad, var_g = (wide.g_u, wide.g_v), (wide.var_g_u, wide.var_g_v)
        least = least_tilted_gradient(grad, var_g, lc.flat_tilt_sigmas)
        shape = flat_item(intr, u, v, d, least, detection.box_xyxy, diamond)
    w, h = detection.size_wh
    hid_w = hid_h = 0.0
    if shape is not None:
        size_m = (shape.width_m, shape.height_m)
        tol = lc.truncation_tolerance + (slope_sigma**2 if fitted else 0.0)
        hid_w, hid_h = hidden_lengths_px((w, h), size_m, lc.aspect[t], tol)
        at_u, at_v = at_border
        if at_u or at_v:
            bw, bh = hidden_lengths_px((w, h), size_m, lc.aspect[t], 0.0)
            hid_w = max(hid_w, bw) if at_u else hid_w
            hid_h = max(hid_h, bh) if at_v else hid_h
        hid_w, hid_h = (hid_w if cause[0] else 0.0), (hid_h if cause[1] else 0.0)
    # the hidden part's side is known at the border, and its length where the tilt is (else the
    # face-on bound above is an upper bound only)
    shift = lc.flat_border_shift and fitted
    shift_u = 0.5 * hid_w * toward[0] if shift else 0.0
    shift_v = 0.5 * hid_h * toward[1] if shift else 0.0
    if shift_u or shift_v:
        # the whole item's box: the cut one gone on past the border by the hidden length
        x1, y1, x2, y2 = (float(c) for c in detection.box_xyxy)
        whole = (
            x1 + min(2.0 * shift_u, 0.0),
            y1 + min(2.0 * shift_v, 0.0),
            x2 + max(2.0 * shift_u, 0.0),
            y2 + max(2.0 * shift_v, 0.0),
        )
        item = flat_item(intr, u, v, d, grad, whole, diamond, turned)
    centre = item.center if item is not None and fitted else None
    turn = item.turn_sigma_px if item is not None and centre is not None else (0.0, 0.0)
    return FlatMeasure(
        centre=centre, hidden_w=hid_w, hidden_h=hid_h, shift_u=shift_u, shift_v=shift_v, turn_sigma_px=turn
    )


def planar_face_center(
    depth_m: np.ndarray, box_xyxy, intr: Intrinsics, u: float, v: float, lc, sigma_px: float
) -> FlatItem | None:
    """The flat face (a door's leaf) a box frames, measured as a flat item (:func:`flat_item`)
    on the face's plane, fitted in inverse depth (:func:`box_depth_plane`); None where that
    plane cannot be fitted, its tilt is not known to ``lc.flat_max_slope_sigma`` or it is seen
    edge-on. Seen at an angle, the face's near half fills more of the box, and the ray through
    the box's centre meets the face nearer than its middle: doors 1.2 m away and 70-80
    degrees off face-on came out 10-15 cm near. ``surface_to_center_m`` then lies behind the
    face across it (``FlatItem.normal``), not along the ray, which for a face seen edge-on runs
    along the face (docs/CONSISTENCY.md "A door seen at an angle: centred on its leaf").

    A door's face is upright: a plane whose normal leans more than ``PLANAR_MAX_NORMAL_UP``
    (the sine of 30 degrees) toward the camera's vertical is the floor, a ceiling or a box that
    frames no door (a false detection), and gives None. Without that check a box on the floor
    was measured as a sign lying there, and its point moved 2.5 cm along the floor's normal,
    into the floor (docs/CONSISTENCY.md "A door seen at an angle: centred on its leaf").
    """
    plane = box_depth_plane(
        depth_m, box_xyxy, lc.inner_fraction, lc.depth_window_px, sigma_px, split_m=lc.depth_split_m, inverse=True
    )
    if plane is None:
        return None
    s = lc.depth_scale
    d = plane.depth_at(u, v) * s
    if plane_slope_sigma((s**2 * plane.var_g_u, s**2 * plane.var_g_v), intr, d) > lc.flat_max_slope_sigma:
        return None
    face = flat_item(intr, u, v, d, (s * plane.g_u, s * plane.g_v), box_xyxy)
    if face is None or abs(float(face.normal[1])) > PLANAR_MAX_NORMAL_UP:
        return None
    return face


def registration_depth_variance(grad: tuple[float, float], var_g: tuple[float, float], sigma_px: float) -> float:
    """Variance of a box's depth from the depth image's registration error against the colour
    image: the depth is read (du, dv) pixels off the colour box, each N(0, s^2 / 2) with s =
    ``sigma_px`` (``localize.registration_sigma_px``, the offset's RMS length), so it is off by
    g_u du + g_v dv for the box's depth slopes ``grad`` (J1's last row), with variance (g_u^2 +
    var_g_u + g_v^2 + var_g_v) s^2 / 2 (a slope known to var_g, as for the centre's error in
    :func:`localize`).

    A D435 maps depth into the colour image through its factory extrinsics; an error of about
    0.1 degree there moves every pixel about 1 px (docs/FACTS.md "D435 depth"). The offset is
    the same all run long, so a sloping box's depth is off the same way in every view: it is
    a shared error (docs/CONSISTENCY.md "The depth registration").

    >>> registration_depth_variance((0.004, 0.0), (0.0, 0.0), 1.0)
    8e-06
    """
    s2 = 0.5 * sigma_px**2
    return float(s2 * (grad[0] ** 2 + var_g[0] + grad[1] ** 2 + var_g[1]))


def extent_covariance(p_c: np.ndarray, sigma_lat_m: float, sigma_ray_m: float) -> np.ndarray:
    """Sigma_ext = sigma_ray^2 r r^T + sigma_lat^2 (I - r r^T), r = p_c / |p_c|: an object's
    reference point spreads about the observation by ``sigma_ray_m`` along the camera ray (how
    deep behind the surface seen it lies depends on the side seen) and ``sigma_lat_m`` across it.

    >>> np.diag(extent_covariance(np.array([0.0, 0.0, 2.0]), 0.1, 0.3)).round(6).tolist()
    [0.01, 0.01, 0.09]
    """
    r = p_c / float(np.linalg.norm(p_c))
    rr = np.outer(r, r)
    return sigma_ray_m**2 * rr + sigma_lat_m**2 * (np.eye(3) - rr)


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


def localize(
    detection: Detection,
    frame: Frame,
    cfg: PipelineConfig,
    T_tracker_camera: np.ndarray,
    calibration: Calibration | None = None,
) -> Observation | None:
    """Place a detection in the map frame with its covariance R ([Avevor2022]_ 2.2-2.3).

    p_map = Q (Q0 p_c + t0) + t with (Q, t) = ``frame.pose`` (T_map_tracker) and (Q0, t0)
    = ``T_tracker_camera``; R = Q Q0 (Sigma_c + Sigma_ext) Q0^T Q^T + sigma_eps^2 I + R_mount,
    where

    * Sigma_c = J2 J1 Sigma_1 J1^T J2^T is the detection and depth model: J1 holds the depth
      gradient of the box (``localize.depth_gradient``: by default the plane through its
      inner depths, :func:`box_depth_plane`), J2 the Jacobian of the deprojection and, for
      a type with ``surface_to_center_m``, of its centre offset (:func:`surface_to_center`);
      Sigma_1's centre variances grow by (hidden / 2)^2 on an axis along which a flat item of
      known ``localize.aspect`` is cut (:func:`hidden_lengths_px`), or along which the box of
      a 3-D item of known ``localize.box_width_m`` / ``box_height_m`` is cut by the image
      border or a nearer surface (:func:`hidden_solid_px`, :func:`occluded_sides`); for a
      3-D type not in ``localize.hidden_on_plane`` that growth skips J1 (the hidden part's
      depth does not follow the visible part's slope). A flat item cut by the image border on
      one side (``localize.flat_border_shift``) is instead centred on the whole item, its box
      gone on past that border by the hidden length (:func:`measure_flat_item`), and its
      centre variance there grows by the square of half that length's error: the full length
      times the shape's relative error, hypot(2 sigma_u / w, 2 sigma_v / h) (a box side's
      length errs by both its edges' errors, each sqrt(2) times the centre's sigma), and half
      the rest of that length's error, ``localize.hidden_length_sigma`` of it. A diamond hung at
      an unknown in-plane turn (``localize.turned_types``) is centred as the mean over the
      turns of a square, and its centre variances grow by that centre's spread over them
      (:func:`flat_item`). A type in ``localize.planar_center`` (a door) is centred on the
      middle of its face (:func:`planar_face_center`);
    * Sigma_ext (:func:`extent_covariance`, ``Observation.Sigma_extent_c``) is the spread of
      a 3-D object's reference point about the observation, ``extent_ray_sigma_m`` along the
      camera ray and ``extent_sigma_m`` across it;
    * sigma_eps is ``slam.sigma_eps_m`` in slam mode, ``tracker.sigma_eps_m`` in t265 mode,
      and R_mount the mount calibration's error
      (:func:`poi.estimation.covariance.mount_covariance`).

    Sigma_c also holds Sigma_reg, the depth image's registration error against the colour image
    (:func:`registration_depth_variance`). Sigma_reg, Sigma_eps, R_mount and Sigma_ext repeat
    from frame to frame: they are the observation's shared part (``Observation.R_shared``,
    :mod:`poi.estimation.tracker`).

    The depth is the median of the box's inner block (:func:`box_depth`; its variance the share
    of one pixel's that the pixels deciding it leave, ``localize.median_depth_variance``:
    :func:`median_variance_fraction`), or for a flat item
    (``localize.flat_depth``: plane) its depth plane's at the box centre
    (:meth:`DepthPlane.depth_at`): on a sloping sign the median is the depth where the block's
    valid pixels centre, off the box centre's where holes lie to one side.

    None when the frame has no pose or no depth, too little valid depth lies in the box
    (``localize.min_depth_fill``, :func:`box_depth`) or it holds two surfaces
    (``localize.max_depth_split``), the depth is out of range, or
    (``localize.flat_reject_corner``) the box of a flat item touches the image border on both
    axes (within ``localize.border_px`` plus ``localize.flat_border_sigmas`` of its centre
    sigmas: a cut box's edge jitters inward with it).
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
    d_med = box_depth(
        depth,
        detection.box_xyxy,
        lc.inner_fraction,
        lc.min_depth_fill,
        split_m=lc.depth_split_m,
        max_split=lc.max_depth_split,
    )
    if d_med is None:
        return None
    cx, cy = detection.center_uv
    u, v = cx - BOX_CORNER_TO_CENTER_PX, cy - BOX_CORNER_TO_CENTER_PX
    w, h = detection.size_wh
    t = detection.type

    # J1: the depth gradient of the box, from its depth plane or central differences
    var_g = (0.0, 0.0)
    plane = None
    # a flat item read on its plane takes the plane's own depth variance (flat_depth_variance)
    mean_variance = lc.flat_depth == "plane" and lc.flat_depth_variance == "plane" and t in lc.aspect
    sigma_px = depth_sigma_m(d_med, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    if lc.depth_gradient == "plane":
        J1 = np.eye(3)
        plane = box_depth_plane(
            depth,
            detection.box_xyxy,
            lc.inner_fraction,
            lc.depth_window_px,
            sigma_px,
            mean_variance,
            split_m=lc.depth_split_m,
        )
        if plane is not None:
            J1[2, :2] = lc.depth_scale * plane.g_u, lc.depth_scale * plane.g_v
            var_g = (lc.depth_scale**2 * plane.var_g_u, lc.depth_scale**2 * plane.var_g_v)
    else:
        J1 = depth_jacobian(depth, u, v, lc.depth_scale)
    # a flat item's depth at its box centre: its plane's there (the median of a sloping
    # surface is the depth where its valid pixels centre, off the box centre where holes lie)
    flat_plane = plane if lc.flat_depth == "plane" and t in lc.aspect else None  # None: read off the plane
    d = (d_med if flat_plane is None else flat_plane.depth_at(u, v)) * lc.depth_scale
    if not lc.min_depth_m <= d <= lc.max_depth_m:
        return None
    to_center = lc.surface_to_center_m.get(t, 0.0)

    def point(a: float, b: float, c: float) -> np.ndarray:
        # a 3-D object: the depth is its front surface, the report names its centre
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
    hid_w = hid_h = 0.0  # pixels of the item its box leaves out, across u and v
    # a flat item's or a body's box edge may sit a few of its sigmas inside the image and still
    # be cut there (an extinguisher cut at its foot at 0.7-1 m, its box's bottom 11-17 px up);
    # a door's or a doll's may not: its hidden length moves its depth along its plane, and a
    # whole door called cut got a needle-thin R
    sized = t in lc.box_width_m or t in lc.box_height_m  # a 3-D type of known full-view size
    n_sigmas = 0.0
    if t in lc.aspect:
        n_sigmas = lc.flat_border_sigmas
    elif sized and t not in lc.hidden_on_plane:
        n_sigmas = lc.body_border_sigmas
    margin = (lc.border_px + n_sigmas * sigma_u, lc.border_px + n_sigmas * sigma_v)
    at = box_at_border(detection.box_xyxy, intr.width, intr.height, margin)
    if t in lc.aspect and lc.flat_reject_corner and all(at):
        # a flat item cut by two borders: its shape cannot say how much of it is hidden
        return None
    occluded = (False, False)  # a nearer surface borders the box across u, across v
    flat_cause = t in lc.aspect and lc.flat_cut_needs_cause
    if lc.occluder_margin_m > 0.0 and (flat_cause or sized):
        surface = d_med if plane is None else plane
        occluded = occluded_sides(depth, detection.box_xyxy, surface, lc.occluder_margin_m / lc.depth_scale)
    shifted = (False, False)  # the centre moved toward the border that cut it, across u, v
    turn_px = (0.0, 0.0)  # a square's centre spread over its unknown in-plane turn, across u, v
    if t in lc.aspect:
        cause = (at[0] or occluded[0], at[1] or occluded[1]) if flat_cause else (True, True)
        toward = border_sides(detection.box_xyxy, intr.width, intr.height, margin)
        flat = measure_flat_item(
            detection,
            intr,
            u,
            v,
            d,
            (J1[2, 0], J1[2, 1]),
            var_g,
            lc,
            depth,
            at_border=at,
            cause=cause,
            toward=toward,
        )
        hid_w, hid_h = flat.hidden_w, flat.hidden_h
        shifted = (flat.shift_u != 0.0, flat.shift_v != 0.0)
        if any(shifted):
            # the whole item's box centre, and its depth on the plane there
            u, v = u + flat.shift_u, v + flat.shift_v
            if flat_plane is not None:
                d = flat_plane.depth_at(u, v) * lc.depth_scale
            p_c = point(u, v, d)
        if flat.centre is not None and lc.flat_center:
            p_c = flat.centre
            turn_px = flat.turn_sigma_px
    elif sized:
        if t in lc.planar_center and plane is not None:
            face = planar_face_center(depth, detection.box_xyxy, intr, u, v, lc, sigma_px)
            p_c = p_c if face is None else face.center + to_center * face.normal
        # a 3-D item cut by the image border or by a nearer surface: its hidden length from its
        # known size
        size_m = (lc.box_width_m.get(t, 0.0), lc.box_height_m.get(t, 0.0))
        at = (at[0] or occluded[0], at[1] or occluded[1])
        hid_w, hid_h = hidden_solid_px((w, h), size_m, float(p_c[2]), (intr.fx, intr.fy), at)
    # a cut box: its centre is off the item's by up to half the hidden length. Where the hidden
    # part goes on along the box's depth plane (a flat sign, a door's leaf, a lying doll:
    # localize.hidden_on_plane) its depth follows the centre through J1; a body whose visible
    # part's slope says nothing of the hidden part's (an extinguisher cut at its foot) keeps
    # its visible part's depth (hidden_var, through J2 only)
    hidden_var = (0.0, 0.0)
    if any(shifted):
        # moved to the whole item's centre: off by half the hidden length's error, the full
        # length times the shape's relative error. A side's length errs by both its edges'
        # errors, the centre by their mean: with the edges independent, a side's sigma is
        # twice the centre's; and by the rest of the hidden length's own error
        # (localize.hidden_length_sigma of it: the plane's tilt, a slanted sign's perspective)
        shape_sigma = math.hypot(2.0 * sigma_u / w, 2.0 * sigma_v / h)
        k = 0.5 * lc.hidden_length_sigma
        if shifted[0]:
            sigma_u = math.hypot(sigma_u, 0.5 * (w + hid_w) * shape_sigma, k * hid_w)
        if shifted[1]:
            sigma_v = math.hypot(sigma_v, 0.5 * (h + hid_h) * shape_sigma, k * hid_h)
        hid_w, hid_h = (0.0 if shifted[0] else hid_w), (0.0 if shifted[1] else hid_h)
    sigma_u, sigma_v = math.hypot(sigma_u, turn_px[0]), math.hypot(sigma_v, turn_px[1])
    if t in lc.aspect or t in lc.hidden_on_plane:
        sigma_u = math.hypot(sigma_u, 0.5 * hid_w)
        sigma_v = math.hypot(sigma_v, 0.5 * hid_h)
    else:
        hidden_var = ((0.5 * hid_w) ** 2, (0.5 * hid_h) ** 2)
    if flat_plane is not None and mean_variance:
        # the plane's depth at the box centre averages the noise of the block's windows
        # plus the Z16 unit's rounding, which a block facing the camera shares (1 mm^2 / 12)
        var_depth = lc.depth_scale**2 * (flat_plane.depth_variance_at(u, v) + DEPTH_UNIT_M**2 / 12.0)
    else:
        sigma_d = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
        var_depth = sigma_d**2
        if flat_plane is None and lc.median_depth_variance == "window":
            # the median of the inner block averages its windows' noise, but keeps the Z16
            # unit's rounding (1 mm^2 / 12)
            sigma_raw = sigma_d / lc.depth_scale  # in the depth image's units, as its pixels
            fraction = median_variance_fraction(
                depth, detection.box_xyxy, lc.inner_fraction, lc.depth_window_px, sigma_raw, d_med
            )
            var_depth = fraction * var_depth + (lc.depth_scale * DEPTH_UNIT_M) ** 2 / 12.0
    # the slope's own error times the centre's: var(g du) = g^2 var(du) (in J1) + var(g) var(du)
    var_d = var_depth + var_g[0] * sigma_u**2 + var_g[1] * sigma_v**2
    Sigma_1 = np.diag([sigma_u**2, sigma_v**2, var_d])
    J2 = deprojection_jacobian(point, u, v, d)  # with the centre offset, for a 3-D object
    Sigma_c = camera_covariance(J1, J2, Sigma_1)
    if hidden_var != (0.0, 0.0):
        Sigma_c = Sigma_c + camera_covariance(np.eye(3), J2, np.diag([*hidden_var, 0.0]))
    # the depth image's registration error: its depth is read (du, dv) off the colour box,
    # the same offset all run long (a shared error), so the box's depth is off by g . (du, dv)
    var_reg = registration_depth_variance((J1[2, 0], J1[2, 1]), var_g, lc.registration_sigma_px)
    Sigma_reg = camera_covariance(np.eye(3), J2, np.diag([0.0, 0.0, var_reg]))
    Sigma_c = Sigma_c + Sigma_reg
    sigma_lat = lc.extent_sigma_m.get(t, 0.0)
    sigma_ray = lc.extent_ray_sigma_m.get(t, sigma_lat)
    Sigma_ext = extent_covariance(p_c, sigma_lat, sigma_ray)

    pose = np.asarray(frame.pose, dtype=float)
    Q, t_map = pose[:3, :3], pose[:3, 3]
    Q0, t0 = T_tracker_camera[:3, :3], T_tracker_camera[:3, 3]
    # p_map = Q (Q0 p_c + t0) + t
    p_map = Q @ (Q0 @ p_c + t0) + t_map
    # Sigma_eps: the pose error as delivered (t265 mode), or what the planar SLAM, which adds
    # its own pose covariance later, leaves (height, roll, pitch: slam mode)
    sigma_eps = cfg.slam.sigma_eps_m if lc.mode == "slam" else cfg.tracker.sigma_eps_m
    # the mount calibration's error (a range-dependent part of what Sigma_eps lumps together)
    R_mount = mount_covariance(Q @ Q0 @ p_c, np.deg2rad(lc.mount_sigma_deg), lc.mount_sigma_m)
    # Sigma_eps, the mount and the extent recur from frame to frame: the shared part the
    # tracker does not average away; the detection and depth noise does not
    R_shared = map_covariance(Sigma_ext, Q, Q0, sigma_eps) + R_mount
    R = map_covariance(Sigma_c, Q, Q0, 0.0) + R_shared
    R_shared = R_shared + map_covariance(Sigma_reg, Q, Q0, 0.0)  # in Sigma_c, and shared
    return Observation(
        detection=detection,
        timestamp_s=frame.timestamp_s,
        position_map=p_map,
        R=R,
        position_cam=p_c,
        Sigma_c=Sigma_c,
        depth_m=d,
        R_shared=R_shared,
        Sigma_extent_c=Sigma_ext,
        box_cut=(bool(at[0]), bool(at[1])),
    )
