"""Concentric Landolt-C targets drawn as RGB textures (docs/FACTS.md "Landolt-C").

Each ring is a Landolt C ([ISO8596]_): the annulus between 3/10 and 5/10 of its outer
diameter D, less a parallel-sided cut D/5 wide from the centre outwards in the ring's
gap direction. Rings are black on a white square card whose side is the outer diameter
plus ``margin_frac`` of it on every side. The image is drawn at ``SUPERSAMPLE`` times
its size and averaged down (area), so edges are anti-aliased as a camera would see a
print.

Directions: degrees counter-clockwise as the viewer sees the target, 0 = gap to the
right, 90 = up (poi/core/landolt.py).

>>> spec = LandoltSpec()
>>> img = draw_landolt(spec, (0, 90, 180, 270, 45), 256)
>>> img.shape, img.dtype.name
((256, 256, 3), 'uint8')
>>> int(img[128, 128, 0]), int(img[0, 0, 0])  # centre (inside ring 5's hole) and card: white
(255, 255)

References
----------
Full entries in docs/SOURCES.md.

.. [ISO8596] ISO 8596, "Ophthalmic optics - Visual acuity testing - Standard and
   clinical optotypes and their presentation".
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from poi.core.landolt import DIRECTIONS_DEG, GAP_FRAC, STROKE_FRAC, LandoltSpec

SUPERSAMPLE = 4  # drawn at 4x and area-averaged: anti-aliased edges
DEFAULT_MARGIN_FRAC = 0.15  # white card round the outer ring, as a fraction of its diameter
INK = 0  # printed black
PAPER = 255  # white card


def card_side_mm(spec: LandoltSpec, margin_frac: float = DEFAULT_MARGIN_FRAC) -> float:
    """Side of the square card the target is printed on (mm)."""
    return spec.outer_diameter_mm * (1.0 + 2.0 * margin_frac)


def _check_orientations(spec: LandoltSpec, orientations_deg: Sequence[int]) -> tuple[int, ...]:
    out = tuple(int(o) % 360 for o in orientations_deg)
    if len(out) != spec.n_rings:
        raise ValueError(f"orientations_deg: expected {spec.n_rings} directions (one per ring), got {len(out)}")
    bad = [o for o in out if o not in DIRECTIONS_DEG]
    if bad:
        raise ValueError(f"orientations_deg: each must be one of {DIRECTIONS_DEG}, got {bad}")
    return out


def ring_mask(x: np.ndarray, y: np.ndarray, diameter: float, orientation_deg: float) -> np.ndarray:
    """True where a Landolt C of outer ``diameter`` centred at the origin is ink.

    ``x`` right, ``y`` down (image axes), same unit as ``diameter``. The gap is the strip
    |p . v| < D GAP_FRAC / 2 on the side p . u > 0 of the direction u = (cos a, -sin a)
    (a counter-clockwise as seen, y down), v perpendicular to u.
    """
    r2 = x * x + y * y
    r_out, r_in = diameter / 2.0, diameter / 2.0 - STROKE_FRAC * diameter
    a = np.deg2rad(orientation_deg)
    ux, uy = np.cos(a), -np.sin(a)
    along = x * ux + y * uy
    across = -x * uy + y * ux
    gap = (along > 0) & (np.abs(across) < GAP_FRAC * diameter / 2.0)
    return (r2 <= r_out * r_out) & (r2 >= r_in * r_in) & ~gap


def draw_landolt(
    spec: LandoltSpec,
    orientations_deg: Sequence[int],
    size_px: int = 1024,
    *,
    margin_frac: float = DEFAULT_MARGIN_FRAC,
) -> np.ndarray:
    """RGB uint8 (size_px, size_px, 3) image of the target on its card.

    ``orientations_deg``: one gap direction per ring, outermost first, each one of
    DIRECTIONS_DEG. The card's side is :func:`card_side_mm`; the target is centred.
    """
    size_px = int(size_px)
    if size_px < 8:
        raise ValueError(f"size_px: expected at least 8, got {size_px}")
    if not margin_frac >= 0:
        raise ValueError(f"margin_frac: expected a number >= 0, got {margin_frac}")
    orient = _check_orientations(spec, orientations_deg)
    n = size_px * SUPERSAMPLE
    mm_per_px = card_side_mm(spec, margin_frac) / n
    c = (np.arange(n, dtype=np.float32) + 0.5) * mm_per_px - card_side_mm(spec, margin_frac) / 2.0
    x, y = np.meshgrid(c, c)  # (n, n) each: mm from the centre, x right, y down
    ink = np.zeros((n, n), bool)
    for d, o in zip(spec.diameters_mm(), orient, strict=True):
        ink |= ring_mask(x, y, d, o)
    hi = np.where(ink, np.float32(INK), np.float32(PAPER))  # (n, n)
    grey = cv2.resize(hi, (size_px, size_px), interpolation=cv2.INTER_AREA)  # (size_px, size_px)
    grey = np.clip(np.rint(grey), 0, 255).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)
