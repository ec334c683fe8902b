"""The concentric Landolt-C target's geometry: what the drawing and the reader share.

A Landolt C ([ISO8596]_) is a ring whose stroke width and gap width are both 1/5 of
its outer diameter D (inner diameter 3/5 D); the gap is a parallel-sided cut as wide as
the stroke. The concentric target nests ``n_rings`` such Cs, each ``ring_ratio`` times
the diameter of the one outside it, each with its own gap direction (docs/FACTS.md
"Landolt-C").

poibench's default ratio is 3/7: the white band between a ring and the next one inside
it is then exactly the inner ring's stroke (and gap) wide, so every ring's critical
detail (its gap, its stroke and the white band round it) is one size. Diameters are
fixed by the 3rd ring's gap, about 1.8 mm in the RMRC Sensor Cabinet [RMRC2025]_:
D3 = 5 x 1.8 = 9 mm, D1 = D3 / ratio**2 = 49 mm.

Directions are the 8 of a Landolt chart, 45 degrees apart, as the viewer sees the
target: 0 = gap to the right, 90 = up, 180 = left, 270 = down (counter-clockwise).

A target's text (its ground-truth text, and what a report says it read; docs/RULES.md
"Landolt-C") lists ring number and gap direction as a compass point on the card seen from
the front (N up, E right), outermost ring first, rings that were not read left out:
"1:E 2:N 3:NE 4:S 5:W" (:func:`orientation_text`, :func:`parse_orientation_text`).

>>> orientation_text([0, 90, 45, None, 180])
'1:E 2:N 3:NE 5:W'
>>> parse_orientation_text("3:NE 4:s")
{3: 45, 4: 270}
>>> merge_orientation_votes({"1:E 2:N": 2, "1:E 2:S 3:W": 1, "1:N 3:W": 1})
'1:E 2:N 3:W'

>>> spec = LandoltSpec()
>>> [round(d, 3) for d in spec.diameters_mm()]
[49.0, 21.0, 9.0, 3.857, 1.653]
>>> [round(g, 3) for g in spec.gaps_mm()][:3]
[9.8, 4.2, 1.8]

References
----------
Full entries in docs/SOURCES.md.

.. [ISO8596] ISO 8596, "Ophthalmic optics - Visual acuity testing - Standard and
   clinical optotypes and their presentation".
.. [RMRC2025] RoboCup Rapidly Manufactured Robot Challenge rules, 2025.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

STROKE_FRAC = 0.2  # stroke width / outer diameter [ISO8596]
GAP_FRAC = 0.2  # gap width / outer diameter [ISO8596]
DEFAULT_RING_RATIO = 3.0 / 7.0  # poibench's choice: white band = next ring's stroke
RING3_GAP_MM = 1.8  # the scored 3rd ring's gap, RMRC Sensor Cabinet [RMRC2025]
DEFAULT_N_RINGS = 5
DIRECTIONS_DEG: tuple[int, ...] = (0, 45, 90, 135, 180, 225, 270, 315)
DIRECTION_NAMES: dict[int, str] = dict(
    zip(DIRECTIONS_DEG, ("E", "NE", "N", "NW", "W", "SW", "S", "SE"), strict=True)
)
_DIRECTION_OF: dict[str, int] = {n: d for d, n in DIRECTION_NAMES.items()}


def default_outer_diameter_mm(ring_ratio: float = DEFAULT_RING_RATIO, ring3_gap_mm: float = RING3_GAP_MM) -> float:
    """The outer ring's diameter that gives the 3rd ring a gap of ``ring3_gap_mm``."""
    return ring3_gap_mm / GAP_FRAC / ring_ratio**2


@dataclass(kw_only=True, frozen=True)
class LandoltSpec:
    """A concentric Landolt-C target's rings: outer diameter, ring count and ratio.

    ``ring_ratio`` must be under 0.6 (= 1 - 2 x STROKE_FRAC), or a ring would not fit
    inside the one outside it.
    """

    outer_diameter_mm: float = default_outer_diameter_mm()
    n_rings: int = DEFAULT_N_RINGS
    ring_ratio: float = DEFAULT_RING_RATIO

    def __post_init__(self) -> None:
        if not (np.isfinite(self.outer_diameter_mm) and self.outer_diameter_mm > 0):
            raise ValueError(f"outer_diameter_mm: expected a positive number, got {self.outer_diameter_mm}")
        if int(self.n_rings) != self.n_rings or self.n_rings < 1:
            raise ValueError(f"n_rings: expected a positive integer, got {self.n_rings}")
        if not (0.0 < self.ring_ratio < 1.0 - 2.0 * STROKE_FRAC):
            raise ValueError(
                f"ring_ratio: expected 0 < ratio < {1.0 - 2.0 * STROKE_FRAC:.1f}, got {self.ring_ratio}"
            )

    def diameters_mm(self) -> list[float]:
        """Outer diameter of each ring, outermost first (ring 1)."""
        return [self.outer_diameter_mm * self.ring_ratio**k for k in range(self.n_rings)]

    def gaps_mm(self) -> list[float]:
        """Gap (= stroke) width of each ring, outermost first."""
        return [GAP_FRAC * d for d in self.diameters_mm()]


def random_orientations(n_rings: int, rng: np.random.Generator) -> tuple[int, ...]:
    """``n_rings`` gap directions (degrees, each one of DIRECTIONS_DEG), drawn uniformly and
    independently from ``rng``."""
    return tuple(int(DIRECTIONS_DEG[i]) for i in rng.integers(0, len(DIRECTIONS_DEG), size=int(n_rings)))


def orientation_text(orientations: Sequence[int | None] | Mapping[int, int]) -> str:
    """A target's text: "ring:direction" for each ring read, outermost (ring 1) first.

    ``orientations``: one direction (degrees, one of DIRECTIONS_DEG) or None per ring,
    outermost first, or a mapping ring number -> direction.
    """
    items = orientations.items() if isinstance(orientations, Mapping) else enumerate(orientations, start=1)
    parts = []
    for ring, deg in sorted((int(k), v) for k, v in items):
        if deg is None:
            continue
        d = int(deg) % 360
        if d not in DIRECTION_NAMES:
            raise ValueError(f"ring {ring}: direction {deg} is not one of {DIRECTIONS_DEG}")
        parts.append(f"{ring}:{DIRECTION_NAMES[d]}")
    return " ".join(parts)


def parse_orientation_text(text: str) -> dict[int, int]:
    """Ring number -> gap direction (degrees) of a target's text (:func:`orientation_text`);
    compass points in any case. A malformed text raises ValueError saying what is wrong."""
    out: dict[int, int] = {}
    for token in text.split():
        ring_s, sep, name = token.partition(":")
        if not sep or not ring_s.isdigit() or int(ring_s) < 1 or name.upper() not in _DIRECTION_OF:
            raise ValueError(
                f"Landolt-C text {text!r}: {token!r} is not RING:DIRECTION (a ring number from 1 and one of "
                f"{', '.join(DIRECTION_NAMES.values())})"
            )
        if int(ring_s) in out:
            raise ValueError(f"Landolt-C text {text!r}: ring {ring_s} is given twice")
        out[int(ring_s)] = _DIRECTION_OF[name.upper()]
    return out


def merge_orientation_votes(votes: Mapping[str, int]) -> str:
    """One text from many readings of a target: per ring, the direction read most often
    (weighted by each text's count; ties: the direction of the first text that has it).
    Texts that do not parse are skipped."""
    per_ring: dict[int, dict[int, int]] = {}
    for text, n in votes.items():
        try:
            rings = parse_orientation_text(text)
        except ValueError:
            continue
        for ring, deg in rings.items():
            tally = per_ring.setdefault(ring, {})
            tally[deg] = tally.get(deg, 0) + int(n)
    best = {ring: max(tally, key=lambda d: tally[d]) for ring, tally in per_ring.items()}
    return orientation_text(best)
