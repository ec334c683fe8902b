"""A box's depth: the median of its inner block and the plane through it, with their variances
([Bouda2025]_ 2.1.3, [Avevor2022]_ 2.2.2).

The median (:func:`box_depth`) is the depth a box reports; the plane (:func:`box_depth_plane`)
gives J1's depth gradient and, for a flat item, its depth at the box centre. Their variances
under the depth camera's window-correlated noise: :func:`median_variance_fraction`,
:meth:`DepthPlane.depth_variance_at`.

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
from typing import TYPE_CHECKING, overload

import cv2
import numpy as np

from poi.core.depth_units import DEPTH_UNIT_M
from poi.core.sensor_noise import depth_sigma_m, window_correlation
from poi.core.types import Intrinsics

if TYPE_CHECKING:
    from poi.config import LocalizeConfig

# few more keep one noisy pixel from tilting it), at most about this many (a grid over a large
# box), and one refit without residuals beyond this many robust sigmas (the wall behind a
# valve's spokes, flying pixels at the box's edge).
PLANE_MIN_PIXELS = 9
PLANE_MAX_PIXELS = 4096
PLANE_OUTLIER_SIGMAS = 3.0
# median_variance_fraction averages a block's noise only when at least this share of its valid
# pixels lie within one sigma_z of the median (68% do on a flat block)
MEDIAN_MIN_BAND = 0.5


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
) -> DepthPlane | None:
    """The least-squares plane d = a + g_u (u - c_u) + g_v (v - c_v) through the valid depths of
    the same inner box as :func:`box_depth`, refitted once without the pixels more than
    ``PLANE_OUTLIER_SIGMAS`` robust standard deviations (1.4826 MAD) off the first plane.
    None with fewer than ``PLANE_MIN_PIXELS`` valid pixels or when they do not span both axes.

    Only the depths within ``split_m`` of the block's median count (``localize.depth_split_m``,
    the item's surface as :func:`box_depth` tells two apart): a nearer surface in part of the
    block is another surface, not a slope.

    Its slopes are J1's depth gradient ([Avevor2022]_ 2.2.2: how the box's depth changes when
    the box moves by a pixel), averaged over the block where central differences of single
    pixels (:func:`poi.estimation.covariance.depth_jacobian`) read the per-pixel noise.
    ``d0`` is the plane's depth at the block's centre (u0, v0) (:meth:`DepthPlane.depth_at`).

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
    flat item's depth read on its plane (:func:`plane_depth_variance`). The scaled slope
    variances above stay for J1 and the tilt checks (docs/CONSISTENCY.md).

    >>> v, u = np.mgrid[0:20, 0:20]
    >>> pl = box_depth_plane(2.0 + 0.01 * u + 0.002 * v, (0, 0, 20, 20), 0.5)
    >>> round(pl.g_u, 6), round(pl.g_v, 6), pl.var_g_u < 1e-20
    (0.01, 0.002, True)
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


def plane_slope_sigma(var_g: tuple[float, float], intr: Intrinsics, d: float) -> float:
    """The standard error of a depth plane's tilt, as the larger of its two slopes' tangents:
    sqrt(var(g)) f / d for the gradient g (m / px) at depth d (m); ``localize.
    flat_max_slope_sigma`` bounds it where a measure needs the tilt.

    >>> k = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=320.0, ppy=240.0)
    >>> plane_slope_sigma((1e-6, 4e-6), k, 2.0)
    0.5
    """
    return max(math.sqrt(var_g[0]) * intr.fx, math.sqrt(var_g[1]) * intr.fy) / d


@dataclass(kw_only=True)
class BoxDepth:
    """A box's depth as :func:`read_box_depth` reads it: the ``median`` of its inner block (the
    depth image's units), its depth ``plane`` (None where none fits), J1 ([Avevor2022]_ 2.2.2:
    the identity with the plane's slopes g_u, g_v in m / px as its last row's first two entries,
    0 without a plane) and those slopes' variances ``var_g`` (m^2 / px^2)."""

    median: float
    plane: DepthPlane | None
    J1: np.ndarray
    var_g: tuple[float, float]

    @property
    def grad(self) -> tuple[float, float]:
        """(g_u, g_v): J1's depth gradient."""
        return self.J1[2, 0], self.J1[2, 1]

    @property
    def surface(self) -> float | DepthPlane:
        """What :func:`poi.estimation.box_cuts.occluded_sides` carries past the box: the plane,
        else the median."""
        return self.median if self.plane is None else self.plane


def read_box_depth(depth_m: np.ndarray, box_xyxy, lc: LocalizeConfig, plane_variance: bool) -> BoxDepth | None:
    """The median depth of a box (:func:`box_depth`) and its depth plane (:func:`box_depth_plane`,
    its noise the depth camera's sigma_z at the median, ``plane_variance`` its ``mean_variance``),
    with J1 = [[1, 0, 0], [0, 1, 0], [s g_u, s g_v, 1]] and var(s g) for depth_scale s; None where
    :func:`box_depth` gives none.

    >>> from poi.config import LocalizeConfig
    >>> v, u = np.mgrid[0:40, 0:40]
    >>> bd = read_box_depth(2.0 + 0.001 * u, (0, 0, 40, 40), LocalizeConfig(), False)
    >>> round(bd.median, 4), round(float(bd.grad[0]), 6), bd.plane is not None
    (2.0195, 0.001, True)
    """
    d_med = box_depth(
        depth_m,
        box_xyxy,
        lc.inner_fraction,
        lc.min_depth_fill,
        split_m=lc.depth_split_m,
        max_split=lc.max_depth_split,
    )
    if d_med is None:
        return None
    sigma_px = depth_sigma_m(d_med, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    plane = box_depth_plane(
        depth_m,
        box_xyxy,
        lc.inner_fraction,
        lc.depth_window_px,
        sigma_px,
        plane_variance,
        split_m=lc.depth_split_m,
    )
    J1 = np.eye(3)
    var_g = (0.0, 0.0)
    if plane is not None:
        J1[2, :2] = lc.depth_scale * plane.g_u, lc.depth_scale * plane.g_v
        var_g = (lc.depth_scale**2 * plane.var_g_u, lc.depth_scale**2 * plane.var_g_v)
    return BoxDepth(median=d_med, plane=plane, J1=J1, var_g=var_g)


def plane_depth_variance(plane: DepthPlane, u: float, v: float, depth_scale: float) -> float:
    """The variance (m^2) of a plane's depth at pixel (u, v), s (plane.depth_at(u, v)) for
    depth_scale s: s^2 (x^T cov x + q^2 / 12), the plane fit's own variance under the
    window-correlated noise (:meth:`DepthPlane.depth_variance_at`) plus the Z16 unit q's
    rounding, which a block facing the camera shares (uniform over one unit: q^2 / 12)."""
    return depth_scale**2 * (plane.depth_variance_at(u, v) + DEPTH_UNIT_M**2 / 12.0)


def median_depth_variance(depth_m: np.ndarray, box_xyxy, lc: LocalizeConfig, d: float, median: float) -> float:
    """The variance (m^2) of a box's median depth ``median`` (the depth image's units), read as
    ``d`` m: f sigma_z(d)^2 + (s q)^2 / 12, with sigma_z(d) = d^2 sigma_d / (f_depth b) one pixel's
    noise ([IntelTuning]_, :func:`poi.core.sensor_noise.depth_sigma_m`), f the share of it the
    pixels deciding the median leave (:func:`median_variance_fraction`) and q the Z16 unit,
    whose rounding the median keeps.

    .. [IntelTuning] Intel RealSense, "Tuning depth cameras for best performance" (docs/SOURCES.md).
    """
    sigma_d = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    var_depth = sigma_d**2
    sigma_raw = sigma_d / lc.depth_scale  # in the depth image's units, as its pixels
    fraction = median_variance_fraction(
        depth_m, box_xyxy, lc.inner_fraction, lc.depth_window_px, sigma_raw, median
    )
    return fraction * var_depth + (lc.depth_scale * DEPTH_UNIT_M) ** 2 / 12.0
