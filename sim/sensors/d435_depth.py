"""D435 depth, aligned to the colour camera, as librealsense gives it (docs/FACTS.md "D435 depth").

Each effect is a ``DepthSpec`` setting (below); in the order they apply:

1. **Registration error.** The depth image sits ``registration_error_px`` (RMS, drawn once per
   trial) off the colour image: an extrinsic calibration error of about 0.1 degree moves
   every pixel about 1 px (**poibench**). Applied as a whole-pixel shift (nearest pixel).
2. **Range.** z = f B / d for disparity d. The D4 matcher searches 126 disparities, so
   closer than MinZ = f B / 126 it finds no match ([IntelTuning]: MinZ = focal length x
   baseline / 126; 0.152 m at 640x480 with f = 384.2 px): those pixels read 0 by default,
   as librealsense's default preset leaves them (``below_min: wrong`` gives a wrong match,
   1.5-3 times too far, instead). Beyond ``max_m``, 0.
3. **Texture, light and the projector.** Stereo matching needs contrast within its window:
   the local standard deviation of the render's linear luminance over the
   ``window_px`` x ``window_px`` window (so a dim scene has less of it), plus the IR
   projector's dot pattern, worth ``texture_ref`` at ``projector_range_m`` and falling with
   the square of the distance (its light spreads over z^2) ([IntelTuning],
   [IntelProjectors]). Where the sum q (in units of ``texture_ref``) is below 1 the disparity
   noise grows as 1 / q (at most ``max_noise_gain``); where it is below ``min_texture``
   (times a per-pixel log-normal spread in blobs of the window's size) the pixel has no
   depth. Saturated pixels (linear luminance above ``saturation``: specular highlights,
   lamps) read 0. The reference levels are **poibench** judgements.
4. **Flying pixels.** Where the 3x3 neighbourhood spans a depth step of more than
   ``FLYING_STEP`` (relative), the matching window straddles the edge: with probability
   ``flying_pixels`` the pixel reads a depth drawn uniformly between the two sides
   (**poibench**'s model of the mixed depths stereo gives at edges).
5. **Disparity noise.** White N(0, 1) noise averaged over the matching window (a box of
   ``window_px``; scaled back to unit variance), so neighbours correlate (0.86 at one pixel
   with a 7-px window), plus a fixed pattern of the same kind drawn once per trial,
   ``fixed_pattern`` times as large: the per-pixel temporal sigma stays Intel's formula
   sigma_z = z^2 sigma_d / (f B) (:func:`poi.core.sensor_noise.depth_sigma_m`), and the
   spatial (plane-fit) RMS is about sqrt(1 + fixed_pattern^2) times it, at least the
   temporal as on the real camera ([IntelTuning], [Keselman2017]). d is rounded to
   ``subpixel`` (1/32 px) steps and converted back, which squares the distance once only.
6. **Holes.** The stereo shadow: the left imager is the reference and the right one sits B
   to its right, so the background just left of a near object is hidden from the right
   imager; aligning depth to the colour camera, ``colour_offset_m`` further left, uncovers
   more of it. Both fall left of the near object in the aligned image, together
   ``fx_color * (B + colour_offset_m) * (1 / z_near - 1 / z_far)`` colour pixels wide
   ([IntelD400], [IntelProjection]; derived in docs/FACTS.md). Then a random ``dropout``.
7. **Z16.** Depth is rounded to counts of ``depth_unit_m`` (1 mm) as librealsense's Z16
   stream is, and handed on in metres (:mod:`poi.core.depth_units`).

Cost: 16 ms CPU per 640x480 frame with every effect on, against 5 ms for the earlier
noise-shadow-dropout model, on the 2-core machine under a load of 42
(``python bench/bench_depth.py --baseline OLD.py``); the sensor thread runs it beside the
GL thread's render.

References
----------
Full entries in docs/SOURCES.md.

.. [IntelD400] Intel Corporation, "Intel RealSense Product Family D400 Series" datasheet.
.. [IntelTuning] A. Grunnet-Jepsen, J. N. Sweetser, J. Woodfill, "Tuning depth cameras for
   best performance", Intel RealSense white paper.
.. [IntelProjectors] A. Grunnet-Jepsen et al., "Projectors for Intel RealSense depth cameras
   D4xx", Intel RealSense white paper.
.. [IntelProjection] Intel RealSense, "Projection in RealSense SDK 2.0".
.. [Keselman2017] L. Keselman, J. I. Woodfill, A. Grunnet-Jepsen, A. Bhowmik, "Intel
   RealSense Stereoscopic Depth Cameras", IEEE CVPR Workshops, 2017.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from poi.core.depth_units import from_z16, to_z16
from poi.core.loader import number
from sim.sensors.base import Shot
from sim.sensors.d435_color import decode_lut
from sim.sensors.noise_pool import NoisePool, two_sided_threshold


@dataclass(kw_only=True)
class DepthSpec:
    """The D435 depth stream's effects (sim/sensors/d435_depth.py; docs/FACTS.md "D435 depth").
    Each is a setting and can be switched off; ``sensors.noise: false`` switches off the random
    ones and the depth-dependent holes, leaving the range limits and the Z16 unit.

    Stereo: ``fx_depth_px`` (the depth imager's focal length in the resolution mode used:
    384.2 px at 640x480), ``baseline_m``; disparity noise ``sigma_d_px`` rounded to
    ``subpixel`` steps, spread over the stereo matcher's ``window_px`` x ``window_px`` window
    (1: independent pixels), plus a per-trial fixed pattern ``fixed_pattern`` times as large.
    Range: ``min_m`` (default: ``fx_depth_px * baseline_m / disparity_search_px``, the
    D4 matcher's 126-pixel search) and ``max_m``; closer than ``min_m`` a pixel reads 0
    (``below_min: zero``) or a wrong depth (``wrong``). Holes: the stereo shadow of near
    objects on their left (``edge_holes``) widened by the colour camera's offset
    ``colour_offset_m`` to the left of the depth reference (alignment disocclusion);
    ``dropout``, a random fraction. Texture (``texture``): the noise grows and the fill falls
    where the surface has less local contrast than ``texture_ref`` (linear luminance std over
    the window) counting the IR projector's dots (``projector_range_m``); below
    ``min_texture`` times that, holes. Pixels brighter than ``saturation`` (linear, 0..1;
    specular highlights, lamps) read 0. ``flying_pixels``: the chance that a pixel at a
    depth edge reads a depth between the two sides. ``registration_error_px``: RMS offset
    of the depth image against the colour image, drawn once per trial. Output: Z16 counts of
    ``depth_unit_m`` (1 mm), handed on in metres.
    """

    noise: bool = True
    sigma_d_px: float = number(0.08, lo=0.0, lo_open=True)  # subpixel disparity noise
    baseline_m: float = number(0.05, lo=0.0, lo_open=True)
    fx_depth_px: float = number(384.2, lo=0.0, lo_open=True)  # depth imager focal length at 640x480
    subpixel: float = number(1.0 / 32.0, lo=0.0, lo_open=True)
    min_m: float | None = number(None, lo=0.0)  # None: fx_depth_px * baseline_m / disparity_search_px
    disparity_search_px: float = number(126.0, lo=1.0)
    below_min: Literal["zero", "wrong"] = "zero"
    max_m: float = number(10.0, lo=0.0, lo_open=True)
    edge_holes: bool = True
    colour_offset_m: float = number(0.015, lo=0.0, hi=1.0)
    dropout: float = number(0.002, lo=0.0, hi=1.0, hi_open=True)  # fraction of pixels randomly invalid
    window_px: int = number(7, lo=1, hi=31)
    fixed_pattern: float = number(0.3, lo=0.0, hi=10.0)
    texture: bool = True
    texture_ref: float = number(0.02, lo=0.0, lo_open=True)
    projector_range_m: float = number(3.0, lo=0.0)
    min_texture: float = number(0.25, lo=0.0, hi=1.0)
    max_noise_gain: float = number(4.0, lo=1.0)
    saturation: float = number(0.98, lo=0.0, hi=1.0, lo_open=True)
    flying_pixels: float = number(0.5, lo=0.0, hi=1.0)
    registration_error_px: float = number(1.0, lo=0.0, hi=20.0)
    depth_unit_m: float = number(0.001, lo=0.0, hi=0.01, lo_open=True)

    def __post_init__(self) -> None:
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        for name in ("sigma_d_px", "baseline_m", "fx_depth_px", "subpixel", "max_m", "depth_unit_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.min_range_m < self.max_m:
            raise ValueError(f"need 0 <= min_m < max_m, got min_m={self.min_range_m}, max_m={self.max_m}")
        if self.max_m / self.depth_unit_m > 65535:
            raise ValueError(f"max_m {self.max_m} m does not fit Z16 counts of depth_unit_m {self.depth_unit_m} m")

    @property
    def min_range_m(self) -> float:
        """The minimum range: ``min_m``, or where the disparity reaches the matcher's search
        range, f B / d_max ([IntelTuning]: MinZ = focal length x baseline / 126)."""
        if self.min_m is not None:
            return self.min_m
        return self.fx_depth_px * self.baseline_m / self.disparity_search_px


FLYING_STEP = 0.05  # a 3x3 neighbourhood whose depths differ by more than 5% straddles an edge (poibench)
HOLE_SPREAD = 0.5  # log-normal spread of the texture threshold, in blobs of the window (poibench)
WRONG_FACTOR = (1.5, 3.0)  # below_min: wrong reads z times U(1.5, 3.0) (poibench)


@dataclass(kw_only=True)
class DepthTrial:
    """What a D435 draws once per trial: its fixed-pattern disparity error and its
    depth-to-colour registration offset."""

    fixed: np.ndarray | None  # (H, W) float32 unit-variance window-correlated field
    offset_px: tuple[float, float]  # drawn (dx, dy) registration error
    shift_px: tuple[int, int]  # the whole-pixel shift applied, (dx, dy) rounded

    @classmethod
    def draw(cls, spec: DepthSpec, shape: tuple[int, int], rng: np.random.Generator) -> DepthTrial:
        """Fixed pattern (when ``spec.fixed_pattern`` > 0), then the offset: each axis
        N(0, e^2 / 2), so the offset's RMS length is ``spec.registration_error_px`` = e."""
        fixed = None
        if spec.fixed_pattern > 0:
            white = rng.standard_normal(white_shape(shape, spec.window_px), dtype=np.float32)
            fixed = window_noise(white, spec.window_px)
        dx, dy = rng.normal(0.0, spec.registration_error_px / np.sqrt(2.0), size=2)
        return cls(fixed=fixed, offset_px=(float(dx), float(dy)), shift_px=(int(np.rint(dx)), int(np.rint(dy))))


def white_shape(shape: tuple[int, int], window_px: int) -> tuple[int, int]:
    """The white noise :func:`window_noise` needs for an image of ``shape``: one window wider."""
    return (shape[0] + window_px - 1, shape[1] + window_px - 1)


def window_noise(white: np.ndarray, window_px: int) -> np.ndarray:
    """Unit-variance noise correlated over a ``window_px`` square: the box mean of ``white``
    (i.i.d. N(0, 1), of :func:`white_shape`) over each full window, times ``window_px``: an
    image ``window_px - 1`` smaller than ``white`` each way. Neighbours ``k`` pixels apart
    along a row correlate at 1 - k / window_px. ``white`` is not changed.

    >>> w = window_noise(np.random.default_rng(0).standard_normal((306, 306), np.float32), 7)
    >>> w.shape, round(float(w.std()), 1)
    ((300, 300), 1.0)
    """
    white = np.asarray(white, np.float32)
    if window_px <= 1:
        return white.copy()
    out = cv2.boxFilter(white, -1, (window_px, window_px), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
    h, w = white.shape[0] - window_px + 1, white.shape[1] - window_px + 1
    out = out[:h, :w]
    out *= np.float32(window_px)
    return out


def shift_image(img: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """``img`` moved ``dx`` pixels right and ``dy`` down; uncovered pixels read 0."""
    if dx == 0 and dy == 0:
        return img
    H, W = img.shape[:2]
    out = np.zeros_like(img)
    if abs(dx) >= W or abs(dy) >= H:
        return out
    out[max(dy, 0) : H + min(dy, 0), max(dx, 0) : W + min(dx, 0)] = img[
        max(-dy, 0) : H + min(-dy, 0), max(-dx, 0) : W + min(-dx, 0)
    ]
    return out


def disparity_noise(
    z_m: np.ndarray,
    spec: DepthSpec,
    rng: np.random.Generator,
    std_normal: np.ndarray | None = None,
    sigma_scale: np.ndarray | None = None,
    fixed: np.ndarray | None = None,
) -> np.ndarray:
    """d = f B / z; d += sigma_d (n + fixed_pattern * fixed); quantise d to ``spec.subpixel``; z = f B / d.

    ``std_normal`` supplies white N(0, 1) samples of :func:`white_shape` (e.g. from a
    ``NoisePool``; without it they are drawn from ``rng``), averaged over ``spec.window_px``
    (:func:`window_noise`);
    ``sigma_scale`` multiplies sigma_d per pixel (texture); ``fixed`` is the trial's fixed
    pattern (:class:`DepthTrial`).
    """
    fB = np.float32(spec.fx_depth_px * spec.baseline_m)
    z = np.asarray(z_m, dtype=np.float32)
    if std_normal is None:
        std_normal = rng.standard_normal(white_shape(z.shape, spec.window_px), dtype=np.float32)
    e = window_noise(std_normal, spec.window_px)
    if fixed is not None and spec.fixed_pattern > 0:
        e += np.float32(spec.fixed_pattern) * fixed
    e *= np.float32(spec.sigma_d_px)
    if sigma_scale is not None:
        e *= sigma_scale
    valid = z > 0
    d = np.divide(fB, z, out=np.zeros(z.shape, np.float32), where=valid)
    d += e
    q = np.float32(spec.subpixel)
    d /= q
    np.rint(d, out=d)
    d *= q
    ok = valid & (d > 0)
    return np.divide(fB, d, out=np.zeros(z.shape, np.float32), where=ok)


def edge_shadow_mask(
    z_m: np.ndarray, fx_color_px: float, baseline_m: float, colour_offset_m: float = 0.0
) -> np.ndarray:
    """Pixels in the shadow left of each near object (True = invalid).

    At a step from a far surface z_f (column e - 1) to a near one z_n (column e) the
    shadow covers w = fx (B + b) (1/z_n - 1/z_f) pixels left of the edge: columns c with
    c + 1 > e - w, that is c from floor(e - w) to e - 1 (B the stereo baseline, b the colour
    camera's offset to the left of the reference imager); steps under half a pixel shadow
    nothing. The steps are few (none on 24 of 40 frames of the default tour, at most 1876), so the
    shadowed runs are written by their flat indices, each run's start plus 0, 1, ... its
    length: the cost follows the shadow's pixels, not the image's.
    """
    z = np.asarray(z_m, dtype=np.float32)
    H, W = z.shape
    inv = np.divide(np.float32(1.0), z, out=np.zeros((H, W), np.float32), where=z > 1e-6)
    width = inv[:, 1:] - inv[:, :-1]  # (H, W - 1): the step between c (far) and c + 1 (near)
    width *= np.float32(fx_color_px * (baseline_m + colour_offset_m))
    mask = np.zeros((H, W), bool)
    ys, cs = np.nonzero(width > 0.5)
    if len(ys) == 0:
        return mask
    edge = cs + 1
    first = np.maximum(np.floor(edge.astype(np.float32) - width[ys, cs]).astype(np.int64), 0)
    length = edge - first
    ends = np.cumsum(length)
    flat = np.arange(ends[-1]) + np.repeat(ys * W + first - (ends - length), length)
    mask.ravel()[flat] = True
    return mask


def texture_quality(lin: np.ndarray, z_m: np.ndarray, spec: DepthSpec) -> np.ndarray:
    """q: the matching window's contrast in units of ``spec.texture_ref``: the local std of the
    linear luminance ``lin`` over the window plus the projector's (projector_range_m / z)^2."""
    k = (spec.window_px, spec.window_px) if spec.window_px > 1 else (3, 3)
    mean = cv2.boxFilter(lin, -1, k, borderType=cv2.BORDER_REFLECT)
    mean2 = cv2.sqrBoxFilter(lin, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT)
    mean *= mean
    mean2 -= mean
    np.maximum(mean2, 0.0, out=mean2)
    q = np.sqrt(mean2)
    q *= np.float32(1.0 / spec.texture_ref)
    if spec.projector_range_m > 0:
        z = np.maximum(np.asarray(z_m, np.float32), np.float32(1e-3))
        proj = np.float32(spec.projector_range_m) / z
        proj *= proj
        q += proj
    return q


def flying_pixels(
    z_m: np.ndarray, valid: np.ndarray, spec: DepthSpec, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) and depths of the pixels at depth edges that read a mix of both sides."""
    z = np.asarray(z_m, np.float32)
    k = np.ones((3, 3), np.uint8)
    zmin = cv2.erode(z, k, borderType=cv2.BORDER_REPLICATE)
    zmax = cv2.dilate(z, k, borderType=cv2.BORDER_REPLICATE)
    zmin *= np.float32(1.0 + FLYING_STEP)
    ys, xs = np.nonzero(zmax > zmin)  # a few percent of the pixels: the rest is done on them
    zmin /= np.float32(1.0 + FLYING_STEP)
    keep = valid[ys, xs] & (zmin[ys, xs] > 0)
    ys, xs = ys[keep], xs[keep]
    pick = rng.random(len(ys)) < spec.flying_pixels
    ys, xs = ys[pick], xs[pick]
    lo = zmin[ys, xs]
    hi = np.minimum(zmax[ys, xs], np.float32(spec.max_m))
    u = rng.random(len(ys)).astype(np.float32)
    return (ys, xs), lo + u * np.maximum(hi - lo, 0)


def simulate_depth(
    z_true_m: np.ndarray,
    spec: DepthSpec,
    fx_color_px: float,
    rng: np.random.Generator,
    noise: bool,
    pool: NoisePool | None = None,
    *,
    rgb: np.ndarray | None = None,
    gamma: float = 2.2,
    trial: DepthTrial | None = None,
) -> np.ndarray:
    """The aligned depth image the pipeline receives (float32 metres on the Z16 grid, 0 = invalid).

    ``z_true_m``: the render's z-depth seen from the colour camera; ``rgb``: the same
    rasterisation's colour, display-encoded with ``gamma`` (without it every surface counts
    as well textured and unsaturated); ``trial``: the trial's fixed pattern and registration
    offset. With a ``pool`` the white noise comes from windows of pre-drawn N(0, 1) samples
    (the dropout where |n| exceeds the two-sided quantile of ``spec.dropout``); the offsets
    come from ``rng``.
    """
    z = np.asarray(z_true_m, dtype=np.float32)
    zmin_m = np.float32(spec.min_range_m)
    if not noise or not spec.noise:
        out = np.where((z >= zmin_m) & (z <= spec.max_m), z, np.float32(0.0)).astype(np.float32)
        return from_z16(to_z16(out, spec.depth_unit_m), spec.depth_unit_m)

    def white() -> np.ndarray:
        shape = white_shape(z.shape, spec.window_px)
        return rng.standard_normal(shape, dtype=np.float32) if pool is None else pool.take(rng, shape)

    if trial is not None:
        z = shift_image(z, *trial.shift_px)
    in_range = (z > 0) & (z <= np.float32(spec.max_m))
    invalid = ~in_range
    near = in_range & (z < zmin_m)
    scale = None
    if spec.texture and rgb is not None:
        gray = cv2.cvtColor(np.asarray(rgb, np.uint8), cv2.COLOR_RGB2GRAY)
        if trial is not None:
            gray = shift_image(gray, *trial.shift_px)
        lin = cv2.LUT(gray, decode_lut(gamma).astype(np.float32))  # (H, W) float32 linear luminance
        q = texture_quality(lin, z, spec)
        # sigma_d grows as 1 / q below the reference, at most max_noise_gain times
        scale = np.clip(q, np.float32(1.0 / spec.max_noise_gain), np.float32(1.0))
        np.reciprocal(scale, out=scale)
        # holes where q < min_texture * exp(spread * m), m window-correlated N(0, 1), the
        # threshold capped at its value for m = 4 (all but 3e-5 of the draws); over the whole
        # image at once: gathering the pixels under the cap first cost twice as much
        thresh = window_noise(white(), spec.window_px)  # (H, W) m
        thresh *= np.float32(HOLE_SPREAD)
        np.exp(thresh, out=thresh)
        thresh *= np.float32(spec.min_texture)
        np.minimum(thresh, np.float32(spec.min_texture * np.exp(4.0 * HOLE_SPREAD)), out=thresh)
        invalid |= q < thresh
        invalid |= lin > np.float32(spec.saturation)
    z_in = z
    if spec.flying_pixels > 0:
        (ys, xs), mixed = flying_pixels(z, in_range & ~near, spec, rng)
        if len(ys):
            z_in = z.copy()
            z_in[ys, xs] = mixed
    out = disparity_noise(z_in, spec, rng, white(), scale, None if trial is None else trial.fixed)
    if spec.edge_holes:
        invalid |= edge_shadow_mask(z, fx_color_px, spec.baseline_m, spec.colour_offset_m)
    if spec.dropout > 0:
        if pool is None:
            invalid |= rng.random(z.shape, dtype=np.float32) < np.float32(spec.dropout)
        else:
            invalid |= np.abs(pool.take(rng, z.shape)) > np.float32(two_sided_threshold(spec.dropout))
    if spec.below_min == "zero":
        invalid |= near
    elif near.any():  # the matcher finds a wrong disparity: a value well off the truth
        out[near] = z[near] * rng.uniform(*WRONG_FACTOR, size=int(near.sum())).astype(np.float32)
    out[invalid] = 0.0
    return from_z16(to_z16(out, spec.depth_unit_m), spec.depth_unit_m)


@dataclass(kw_only=True)
class DepthSensor:
    """The depth stream, aligned to colour, as a frame sensor (:class:`sim.sensors.base.FrameSensor`):
    :func:`simulate_depth` with the trial's draws ``trial`` and noise from ``pool``."""

    frame_field = "depth_m"
    spec: DepthSpec
    fx_color_px: float
    noise: bool
    pool: NoisePool | None
    trial: DepthTrial

    def measure(self, shot: Shot, rng: np.random.Generator) -> np.ndarray:
        return simulate_depth(
            shot.z_m,
            self.spec,
            self.fx_color_px,
            rng,
            self.noise,
            self.pool,
            rgb=shot.rgb,
            gamma=shot.gamma,
            trial=self.trial,
        )
