"""The concentric Landolt-C target: its ring sizes and its drawing (maze_assets/landolt.py)."""

from __future__ import annotations

import numpy as np
import pytest

from maze_assets.landolt import DEFAULT_MARGIN_FRAC, card_side_mm, draw_landolt
from poi.core.landolt import DIRECTIONS_DEG, LandoltSpec, default_outer_diameter_mm, random_orientations


def test_default_ring_sizes_are_hand_computed():
    # ring 3's gap 1.8 mm -> D3 = 5 x 1.8 = 9 mm; ratio 3/7 -> D2 = 21 mm, D1 = 49 mm
    spec = LandoltSpec()
    assert default_outer_diameter_mm() == pytest.approx(49.0)
    assert spec.diameters_mm()[:3] == pytest.approx([49.0, 21.0, 9.0])
    assert spec.gaps_mm()[2] == pytest.approx(1.8)
    # the white band inside ring k (inner radius 0.3 D_k to the next ring's 0.5 D_k+1) is ring k+1's stroke
    d = spec.diameters_mm()
    for k in range(len(d) - 1):
        assert 0.3 * d[k] - 0.5 * d[k + 1] == pytest.approx(0.2 * d[k + 1])


def test_bad_specs_and_orientations_are_refused():
    with pytest.raises(ValueError, match="ring_ratio"):
        LandoltSpec(ring_ratio=0.6)
    with pytest.raises(ValueError, match="n_rings"):
        LandoltSpec(n_rings=0)
    with pytest.raises(ValueError, match="orientations_deg: each must be one of"):
        draw_landolt(LandoltSpec(), (0, 30, 90, 180, 270), 64)
    with pytest.raises(ValueError, match="expected 5 directions"):
        draw_landolt(LandoltSpec(), (0, 90), 64)


def test_random_orientations_are_seeded_and_from_the_eight():
    a = random_orientations(200, np.random.default_rng(3))
    assert a == random_orientations(200, np.random.default_rng(3))
    assert set(a) == set(DIRECTIONS_DEG)  # 200 draws cover all 8


@pytest.mark.parametrize("direction", DIRECTIONS_DEG)
def test_the_gap_is_drawn_where_its_direction_points(direction):
    spec = LandoltSpec()
    n = 400
    img = draw_landolt(spec, (direction, 0, 0, 0, 0), n)
    px_per_mm = n / card_side_mm(spec, DEFAULT_MARGIN_FRAC)
    r_mid = 0.4 * spec.outer_diameter_mm * px_per_mm  # ring 1's stroke centre, pixels
    c = n / 2 - 0.5  # pixel-index coordinate of the card's centre
    for other in DIRECTIONS_DEG:
        a = np.deg2rad(other)
        x, y = c + r_mid * np.cos(a), c - r_mid * np.sin(a)  # counter-clockwise as seen, y down
        value = int(img[int(round(y)), int(round(x)), 0])
        assert value == (255 if other == direction else 0), (other, value)
