"""Concentric Landolt-C targets: find them in a frame, and read each ring's gap direction from pixels.

Finding (:class:`LandoltFinder`, detector ``landolt``): dark shapes whose outline is an
ellipse are proposed (:func:`propose_rings`) and each is verified by reading it; a
detector that gives boxes only (the oracle) has them read by :func:`attach_landolt_text`.
Reading (:func:`read_landolt`):

The reader knows the target's design (poi/core/landolt.py: every ring a Landolt C of
stroke and gap D/5 [ISO8596]_, each ring ``ring_ratio`` times the one outside it), not
the orientations, which it reads from the image with OpenCV:

1. **Outer ring.** The crop (a detector's box grown by ``margin_frac``) is turned grey,
   upscaled (cubic) so its shorter side is at least ``min_crop_px``, and thresholded
   (Otsu). Of the dark connected components, the largest whose convex hull is an
   ellipse (hull area within ``hull_fit_tol`` of the area of the ellipse fitted to the
   hull's vertices, ``cv2.fitEllipse``) is the outer ring; the ellipse (semi-axes grown
   by half a pixel: hull vertices are pixel centres) is its outline. An ellipse, not a
   circle, so a target seen a little obliquely still reads.
2. **Polar unwrap.** The grey crop is sampled (``cv2.remap``, bilinear) on a polar grid
   about the ellipse's centre: angle psi counter-clockwise as seen (0 = right), radius
   rho in units of the ellipse's radius in that direction (rho = 1 on the outer edge).
   Darkness q = (white - grey) / (white - black), white the 95th percentile of the
   samples, black the 5th percentile of the outer ring's band.
3. **Rings.** The radial profile m(rho), the median of q over angle (the gap, 8% of a
   ring's circumference, does not move a median), peaks at each ring: ring k is looked
   for within a quarter of a stroke of its design centre radius 0.8 ratio**(k-1). Its
   contrast c_k is its peak minus the brighter of the white bands just outside and
   inside it; a ring under ``min_contrast`` (of the full black-white range) is not
   resolved and reads None (at the resolution limit the ring and its white bands blur
   into one grey long before its gap's direction is lost, so this threshold is low).
4. **Gap.** The angular profile p(psi) is the mean of q over the middle half of the
   ring's stroke. For each of the 8 directions, the mean of p over a window of
   ``window_frac`` of the gap's angular width (29 degrees at mid-stroke) gives a score
   s_j = (median(p) - mean_j) / c_k: about 1 where the gap is, 0 elsewhere. The answer
   is the best direction; its confidence is s_best - s_second. It is None when the
   confidence is under ``min_confidence``, or the margin in darkness (confidence x c_k)
   is under ``min_dip`` or under ``noise_k`` robust standard deviations of p outside
   the best window, or the continuous gap angle (the minimum of p smoothed over the
   gap's width) is more than 22.5 degrees from the best direction.

>>> read_landolt(np.full((64, 64, 3), 255, np.uint8)) is None  # a blank card: no ring
True

References
----------
Full entries in docs/SOURCES.md.

.. [ISO8596] ISO 8596, "Ophthalmic optics - Visual acuity testing - Standard and
   clinical optotypes and their presentation".
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from poi.core.landolt import (
    DEFAULT_N_RINGS,
    DEFAULT_RING_RATIO,
    DIRECTIONS_DEG,
    GAP_FRAC,
    STROKE_FRAC,
    orientation_text,
)
from poi.core.types import Detection, Frame
from poi.detectors.base import DetectorConfigError, make_detection, one_class_probs, register
from poi.detectors.qr import box_iou


@dataclass(kw_only=True, frozen=True)
class LandoltReaderConfig:
    """Settings of :func:`read_landolt` (see the module docstring for each step)."""

    n_rings: int = DEFAULT_N_RINGS
    ring_ratio: float = DEFAULT_RING_RATIO
    margin_frac: float = 0.1  # box grown by this fraction of its longer side on each side
    min_crop_px: int = 240  # the crop is upscaled (cubic) to at least this shorter side
    max_upscale: float = 8.0
    min_component_px: int = 20  # dark components smaller than this are not the outer ring
    hull_fit_tol: float = 0.12  # |hull area / ellipse area - 1| at most this
    n_radii: int = 400  # polar samples from rho = 0 to RHO_MAX
    n_angles: int = 720  # polar samples round the circle (0.5 degree)
    # thresholds set on the rendered bench's seed 5 (bench/bench_landolt.py; its table is seed 0):
    # no wrong reading there had a contrast over 0.018 or a dip over 0.06
    min_contrast: float = 0.06  # a ring's darkness over its white bands, of black - white
    window_frac: float = 0.6  # direction window: this fraction of the gap's angular width
    min_confidence: float = 0.4  # best direction's score minus the second best
    min_dip: float = 0.1  # the same difference in darkness (of black - white): confidence x contrast
    noise_k: float = 4.0  # the margin must exceed this many robust sigmas of the profile

    def __post_init__(self) -> None:
        if int(self.n_rings) != self.n_rings or self.n_rings < 1:
            raise ValueError(f"n_rings: expected a positive integer, got {self.n_rings}")
        if not (0.0 < self.ring_ratio < 1.0 - 2.0 * STROKE_FRAC):
            raise ValueError(f"ring_ratio: expected 0 < ratio < 0.6, got {self.ring_ratio}")
        for name in ("margin_frac", "min_contrast", "min_confidence", "min_dip", "noise_k"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name}: expected a number >= 0, got {getattr(self, name)}")
        if not 0 < self.window_frac <= 1:
            raise ValueError(f"window_frac: expected 0 < w <= 1, got {self.window_frac}")
        if self.n_radii < 50 or self.n_angles < 72:
            raise ValueError("n_radii must be at least 50 and n_angles at least 72")


@dataclass(kw_only=True, frozen=True)
class RingReading:
    """One ring's reading. ``orientation_deg`` is one of DIRECTIONS_DEG or None (unreadable)."""

    ring: int  # 1 = outermost
    orientation_deg: int | None
    best_deg: int | None  # the best direction even when it is not confident; None if unresolved
    confidence: float  # best direction's score minus the second best (0 when unresolved)
    contrast: float  # the ring's darkness over its white bands, of black - white
    gap_angle_deg: float | None  # continuous estimate of the gap's direction
    diameter_px: float  # the ring's design outer diameter in frame pixels (geometric mean)


@dataclass(kw_only=True, frozen=True)
class LandoltReading:
    """A target's outline (frame pixels) and its rings' readings, outermost first."""

    centre_xy: tuple[float, float]
    axes_px: tuple[float, float]  # outer ellipse's full axes
    angle_deg: float  # outer ellipse's rotation (OpenCV's convention)
    rings: tuple[RingReading, ...]


# cv2.fitEllipse's ((cx, cy), (A, B), angle_deg): centre, full axes, rotation of axis A
Ellipse = tuple[tuple[float, float], tuple[float, float], float]

RHO_MAX = 1.15  # polar grid reaches past the outer edge, to the white card round it
PROPOSAL_BLOCKS_PX = (31, 101)  # adaptive-threshold windows of the finder's proposals


def _to_gray(rgb: np.ndarray) -> np.ndarray:
    if rgb.ndim == 2:
        return rgb.astype(np.float32)
    if rgb.ndim == 3 and rgb.shape[2] == 3:
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32)
    raise ValueError(f"expected an RGB (H, W, 3) or grey (H, W) image, got shape {rgb.shape}")


def _outer_ellipse(gray: np.ndarray, cfg: LandoltReaderConfig) -> Ellipse | None:
    """((cx, cy), (A, B), angle) of the outer ring in ``gray``'s pixels, or None."""
    g8 = np.clip(gray, 0, 255).astype(np.uint8)
    _t, dark = cv2.threshold(g8, 0, 255, cv2.THRESH_BINARY_INV | cv2.THRESH_OTSU)
    n, labels, stats, _c = cv2.connectedComponentsWithStats(dark, connectivity=8)
    order = np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1  # largest first, background 0 left out
    for lab in order[:5]:
        if stats[lab, cv2.CC_STAT_AREA] < cfg.min_component_px:
            break
        ys, xs = np.nonzero(labels == lab)
        pts = np.stack([xs, ys], axis=1).astype(np.float32)  # (N, 2) pixel centres
        hull = cv2.convexHull(pts)  # (M, 1, 2)
        if len(hull) < 5:
            continue
        (cx, cy), (A, B), ang = cv2.fitEllipse(hull)
        A, B = A + 1.0, B + 1.0  # hull vertices are pixel centres: the edge is half a pixel out
        if min(A, B) < 4 or min(A, B) / max(A, B) < 0.5:
            continue
        ell_area = math.pi * A * B / 4.0
        hull_area = cv2.contourArea(hull) + 0.5 * cv2.arcLength(hull, True)  # grown by half a pixel
        if abs(hull_area / ell_area - 1.0) > cfg.hull_fit_tol:
            continue
        return (cx, cy), (A, B), ang
    return None


def _polar(
    gray: np.ndarray, ellipse: Ellipse, cfg: LandoltReaderConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P, rho, psi): P (n_radii, n_angles) grey sampled at rho x ellipse radius in direction
    psi (degrees counter-clockwise as seen, image y down)."""
    (cx, cy), (A, B), ang = ellipse
    a, b = A / 2.0, B / 2.0
    phi = np.deg2rad(ang)
    e1 = np.array([np.cos(phi), np.sin(phi)])  # first axis (width A) in image x, y
    e2 = np.array([-np.sin(phi), np.cos(phi)])
    psi = np.arange(cfg.n_angles) * (360.0 / cfg.n_angles)  # (NA,)
    d = np.stack([np.cos(np.deg2rad(psi)), -np.sin(np.deg2rad(psi))], axis=1)  # (NA, 2), y down
    r_e = 1.0 / np.sqrt((d @ e1 / a) ** 2 + (d @ e2 / b) ** 2)  # (NA,) ellipse radius per direction
    rho = np.linspace(0.0, RHO_MAX, cfg.n_radii)  # (NR,)
    map_x = (cx + rho[:, None] * (r_e * d[:, 0])[None, :]).astype(np.float32)  # (NR, NA)
    map_y = (cy + rho[:, None] * (r_e * d[:, 1])[None, :]).astype(np.float32)
    P = cv2.remap(gray, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)  # (NR, NA)
    return P, rho, psi


def _band(m: np.ndarray, rho: np.ndarray, lo: float, hi: float) -> np.ndarray:
    sel = (rho >= lo) & (rho <= hi)
    if not sel.any():
        sel = np.zeros_like(sel)
        sel[int(np.argmin(np.abs(rho - (lo + hi) / 2)))] = True
    return m[sel]


def _read_ring(
    k: int,
    q: np.ndarray,
    m: np.ndarray,
    rho: np.ndarray,
    psi: np.ndarray,
    scale_px: float,
    cfg: LandoltReaderConfig,
) -> RingReading:
    """Ring k (0 = outermost) from the darkness q (NR, NA) and its radial median m (NR,)."""
    r_out = cfg.ring_ratio**k  # design outer radius, rho units
    s = STROKE_FRAC * 2.0 * r_out  # stroke, rho units
    r_mid = r_out - s / 2.0
    diameter_px = 2.0 * r_out * scale_px

    def unresolved(contrast: float) -> RingReading:
        return RingReading(
            ring=k + 1,
            orientation_deg=None,
            best_deg=None,
            confidence=0.0,
            contrast=contrast,
            gap_angle_deg=None,
            diameter_px=diameter_px,
        )

    near = (rho >= r_mid - 0.25 * s) & (rho <= r_mid + 0.25 * s)
    if not near.any():
        return unresolved(0.0)
    idx = np.flatnonzero(near)
    i_peak = int(idx[np.argmax(m[idx])])
    peak = float(m[i_peak])
    # white bands: outside (card for ring 1), inside (the next ring's band, or the hole)
    r_in = r_out - s
    if k == 0:
        outside = _band(m, rho, r_out + 0.3 * s, r_out + 0.7 * s)
    else:
        prev_in = r_out / cfg.ring_ratio * (1.0 - 2.0 * STROKE_FRAC)
        outside = _band(m, rho, r_out + 0.3 * (prev_in - r_out), r_out + 0.7 * (prev_in - r_out))
    if k + 1 < cfg.n_rings:
        nxt = r_out * cfg.ring_ratio
        inside = _band(m, rho, nxt + 0.3 * (r_in - nxt), nxt + 0.7 * (r_in - nxt))
    else:
        inside = _band(m, rho, 0.2 * r_in, 0.7 * r_in)
    white_local = max(float(np.mean(outside)), float(np.mean(inside)))
    contrast = peak - white_local
    if contrast <= 0.0:
        return unresolved(contrast)
    rho_c = float(rho[i_peak])
    rows = (rho >= rho_c - 0.25 * s) & (rho <= rho_c + 0.25 * s)
    if not rows.any():
        rows[i_peak] = True
    p = q[rows].mean(axis=0)  # (NA,) angular darkness profile
    base = float(np.median(p))
    step = psi[1] - psi[0]
    gap_halfwidth_deg = math.degrees(math.asin(min(1.0, (GAP_FRAC * r_out) / max(rho_c, 1e-9))))
    half_win = max(1, int(round(cfg.window_frac * gap_halfwidth_deg / step)))
    na = len(psi)
    scores = []
    for direction in DIRECTIONS_DEG:
        c = int(round(direction / step)) % na
        win = np.take(p, np.arange(c - half_win, c + half_win + 1), mode="wrap")
        scores.append((base - float(win.mean())) / contrast)
    order = np.argsort(scores)[::-1]
    best, second = int(order[0]), int(order[1])
    confidence = float(scores[best] - scores[second])
    # continuous gap angle: minimum of p smoothed over the gap's full width (circular)
    half_gap = max(1, int(round(gap_halfwidth_deg / step)))
    kernel = np.ones(2 * half_gap + 1) / (2 * half_gap + 1)
    padded = np.concatenate([p[-half_gap:], p, p[:half_gap]])
    smooth = np.convolve(padded, kernel, mode="valid")  # (NA,)
    gap_angle = float(psi[int(np.argmin(smooth))])
    off = abs((gap_angle - DIRECTIONS_DEG[best] + 180.0) % 360.0 - 180.0)
    # noise: robust sigma of p away from the best window
    c_best = int(round(DIRECTIONS_DEG[best] / step))
    keep = np.ones(na, bool)
    keep[np.arange(c_best - 2 * half_gap, c_best + 2 * half_gap + 1) % na] = False
    sigma = 1.4826 * float(np.median(np.abs(p[keep] - np.median(p[keep]))))
    readable = (
        contrast >= cfg.min_contrast
        and confidence >= cfg.min_confidence
        and confidence * contrast >= cfg.min_dip
        and confidence * contrast > cfg.noise_k * sigma
        and off <= 22.5
    )
    return RingReading(
        ring=k + 1,
        orientation_deg=int(DIRECTIONS_DEG[best]) if readable else None,
        best_deg=int(DIRECTIONS_DEG[best]),
        confidence=confidence,
        contrast=contrast,
        gap_angle_deg=gap_angle,
        diameter_px=diameter_px,
    )


def read_landolt(
    rgb: np.ndarray,
    box_xyxy: Sequence[float] | None = None,
    config: LandoltReaderConfig | None = None,
) -> LandoltReading | None:
    """Read a concentric Landolt-C target in ``rgb`` (inside ``box_xyxy``, pixels, if given).

    Returns None when no outer ring is found; otherwise a reading per ring (outermost
    first), each with its gap direction or None. Coordinates in the reading are in
    ``rgb``'s pixels. The method is the module docstring's.
    """
    cfg = config or LandoltReaderConfig()
    gray = _to_gray(np.asarray(rgb))
    h, w = gray.shape
    x0, y0 = 0.0, 0.0
    if box_xyxy is not None:
        x1, y1, x2, y2 = (float(v) for v in box_xyxy)
        if not all(np.isfinite([x1, y1, x2, y2])) or x2 <= x1 or y2 <= y1:
            raise ValueError(f"box_xyxy: expected finite x1 < x2, y1 < y2, got {tuple(box_xyxy)}")
        mg = cfg.margin_frac * max(x2 - x1, y2 - y1)
        c1, r1 = max(int(np.floor(x1 - mg)), 0), max(int(np.floor(y1 - mg)), 0)
        c2, r2 = min(int(np.ceil(x2 + mg)), w), min(int(np.ceil(y2 + mg)), h)
        if c2 - c1 < 4 or r2 - r1 < 4:
            return None
        gray = gray[r1:r2, c1:c2]  # a view, only read
        x0, y0 = float(c1), float(r1)
    s = float(np.clip(cfg.min_crop_px / min(gray.shape), 1.0, cfg.max_upscale))
    big = gray if s == 1.0 else cv2.resize(gray, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
    ellipse = _outer_ellipse(big, cfg)
    if ellipse is None:
        return None
    P, rho, psi = _polar(big, ellipse, cfg)
    white = float(np.percentile(P, 95))
    outer_band = P[(rho >= 1.0 - 2 * STROKE_FRAC * 0.75) & (rho <= 1.0 - 2 * STROKE_FRAC * 0.25)]
    black = float(np.percentile(outer_band, 5))
    if white - black < 1.0:
        return None
    q = (white - P) / (white - black)  # (NR, NA) darkness, 0 white .. 1 black
    m = np.median(q, axis=1)  # (NR,)
    (cx, cy), (A, B), ang = ellipse
    scale_px = math.sqrt(A * B) / 2.0 / s  # outer radius in frame pixels
    rings = tuple(_read_ring(k, q, m, rho, psi, scale_px, cfg) for k in range(cfg.n_rings))
    # the centre of pixel i of the upscaled crop is at (i + 0.5) / s - 0.5 in the crop's pixels
    return LandoltReading(
        centre_xy=(x0 + (cx + 0.5) / s - 0.5, y0 + (cy + 0.5) / s - 0.5),
        axes_px=(A / s, B / s),
        angle_deg=float(ang),
        rings=rings,
    )


def reading_text(reading: LandoltReading | None) -> str:
    """A reading as a target's text (poi.core.landolt.orientation_text): the rings whose gap was
    read, "" when none was (or there was no target)."""
    if reading is None:
        return ""
    return orientation_text([r.orientation_deg for r in reading.rings])


def attach_landolt_text(
    rgb: np.ndarray, detections: Sequence[Detection], config: LandoltReaderConfig | None = None
) -> list[Detection]:
    """Copies of ``detections`` with the rings read from pixels as the text of every
    'landolt-c' one that has none ("" if nothing reads); others unchanged, inputs not modified.
    A detector that gives boxes only (the oracle) gets its readings from here."""
    out = []
    for det in detections:
        if det.type == "landolt-c" and not det.text:
            box = det.box_xyxy
            ok = box[2] > box[0] and box[3] > box[1]
            det = dataclasses.replace(det, text=reading_text(read_landolt(rgb, box, config)) if ok else "")
        out.append(det)
    return out


def _ellipse_box(reading: LandoltReading, w: int, h: int) -> tuple[float, float, float, float]:
    """The axis-aligned box of a reading's outer ellipse, clipped to the image."""
    (cx, cy), (A, B), ang = reading.centre_xy, reading.axes_px, math.radians(reading.angle_deg)
    hx = math.hypot(A / 2 * math.cos(ang), B / 2 * math.sin(ang))
    hy = math.hypot(A / 2 * math.sin(ang), B / 2 * math.cos(ang))
    return (max(cx - hx, 0.0), max(cy - hy, 0.0), min(cx + hx, float(w)), min(cy + hy, float(h)))


def propose_rings(
    gray: np.ndarray, min_diameter_px: float, max_candidates: int, hull_fit_tol: float = 0.15
) -> list[tuple[float, float, float, float]]:
    """Boxes (x1, y1, x2, y2) of dark shapes in ``gray`` that could be a target's outer ring.

    The image is thresholded against its local mean (``cv2.adaptiveThreshold``, 10 grey
    levels darker than the mean of a 31 px window, and again of a 101 px one: the small window
    keeps a small blurred ring, the large one a ring whose stroke is wider than the small
    window), so a black ring on a white card stands out under any exposure. An outer
    contour is a candidate when its convex hull is an ellipse (hull area within
    ``hull_fit_tol`` of the fitted ellipse's, axes ratio at least 0.5) at least
    ``min_diameter_px`` across, and it fills 35-100% of the hull (a C ring, about 60%, or a
    blurred one whose gap has closed). Largest first, at most ``max_candidates``.
    """
    g8 = np.clip(gray, 0, 255).astype(np.uint8)
    contours: list[np.ndarray] = []
    for block in PROPOSAL_BLOCKS_PX:
        dark = cv2.adaptiveThreshold(g8, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV, block, 10)
        contours += cv2.findContours(dark, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0]
    min_area = math.pi * (min_diameter_px / 2.0) ** 2 * 0.35
    found: list[tuple[float, tuple[float, float, float, float]]] = []
    for c in contours:
        area = cv2.contourArea(c)
        if area < min_area or len(c) < 5:
            continue
        hull = cv2.convexHull(c)
        if len(hull) < 5:
            continue
        (cx, cy), (A, B), _ang = cv2.fitEllipse(hull)
        if min(A, B) < min_diameter_px or min(A, B) / max(A, B) < 0.5:
            continue
        hull_area = cv2.contourArea(hull)
        if abs(hull_area / (math.pi * A * B / 4.0) - 1.0) > hull_fit_tol:
            continue
        if not 0.35 <= area / max(hull_area, 1e-9) <= 1.0:
            continue
        x, y, bw, bh = cv2.boundingRect(hull)
        found.append((hull_area, (float(x), float(y), float(x + bw), float(y + bh))))
    found.sort(key=lambda t: -t[0])
    boxes: list[tuple[float, float, float, float]] = []
    for _a, box in found:  # the two windows often find the same ring
        if not any(box_iou(box, b) > 0.8 for b in boxes):
            boxes.append(box)
    return boxes[:max_candidates]


@register("landolt")
@dataclass(kw_only=True)
class LandoltFinder:
    """Finds concentric Landolt-C targets over the whole image and reads them.

    Candidates come from :func:`propose_rings`; each is verified by the reader
    (:func:`read_landolt` on the candidate's box): it is a target when the outer ring and at
    least ``min_rings_read`` rings in all read a gap direction. A target becomes a Detection of
    class 'landolt-c', its box the outer ellipse's, its text the rings read
    (:func:`reading_text`). Candidates overlapping a target already found by more than
    ``dedupe_iou`` are skipped (the rings inside a target are candidates too).
    """

    confidence: float = 0.9
    min_diameter_px: float = 12.0
    max_candidates: int = 12
    min_rings_read: int = 2
    dedupe_iou: float = 0.3
    name: str = field(default="landolt", init=False)

    def __post_init__(self) -> None:
        if not 0.0 < float(self.confidence) <= 1.0:
            raise DetectorConfigError(f"detector 'landolt': confidence must be in (0, 1], got {self.confidence}")
        if not self.min_diameter_px >= 4:
            raise DetectorConfigError(
                f"detector 'landolt': min_diameter_px must be >= 4, got {self.min_diameter_px}"
            )
        if int(self.max_candidates) < 1 or int(self.min_rings_read) < 1:
            raise DetectorConfigError("detector 'landolt': max_candidates and min_rings_read must be >= 1")
        if not 0.0 <= float(self.dedupe_iou) <= 1.0:
            raise DetectorConfigError(f"detector 'landolt': dedupe_iou must be in [0, 1], got {self.dedupe_iou}")

    def detect(self, frame: Frame) -> list[Detection]:
        gray = _to_gray(np.asarray(frame.rgb))
        h, w = gray.shape
        cfg = LandoltReaderConfig()
        found: list[tuple[str, tuple[float, float, float, float]]] = []
        for box in propose_rings(gray, self.min_diameter_px, int(self.max_candidates)):
            if any(box_iou(box, b) > self.dedupe_iou or _inside(box, b) for _t, b in found):
                continue
            reading = read_landolt(gray, box, cfg)
            if reading is None or reading.rings[0].orientation_deg is None:
                continue
            if sum(r.orientation_deg is not None for r in reading.rings) < self.min_rings_read:
                continue
            found.append((reading_text(reading), _ellipse_box(reading, w, h)))
        probs = one_class_probs("landolt-c", float(self.confidence))
        return [
            make_detection(
                "landolt-c", box, float(self.confidence), source="landolt", class_probs=probs.copy(), text=t
            )
            for t, box in found
        ]


def _inside(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
    """Whether box ``a``'s centre lies inside box ``b``."""
    cx, cy = (a[0] + a[2]) / 2, (a[1] + a[3]) / 2
    return b[0] <= cx <= b[2] and b[1] <= cy <= b[3]
