"""Procedural textures: hazmat placards, QR codes, safety signs, wall and floor."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

from maze_assets.hazmat import PAPER, TOP_FIELD_RGB, UnknownHazmatLabelError, draw_hazmat
from maze_assets.qr import MAX_QR_TEXTS, QrTextureError, draw_qr, qr_modules, qr_texts
from maze_assets.signs import SAFETY_GREEN, SAFETY_RED, draw_exit_sign, draw_fire_extinguisher_sign
from maze_assets.surfaces import draw_floor, draw_plywood
from poi.core.names import HAZMAT_LABELS


@pytest.mark.parametrize("label", HAZMAT_LABELS)
def test_every_label_draws_a_diamond(label):
    img = draw_hazmat(label, 256)
    assert img.shape == (256, 256, 3) and img.dtype == np.uint8
    # the four corners lie outside the diamond: paper
    for r, c in ((0, 0), (0, 255), (255, 0), (255, 255), (20, 20)):
        assert tuple(img[r, c]) == PAPER
    # just inside the top corner, below the border line (y = 0.07 of the side), is the
    # placard's top colour field (tolerance 12 levels: anti-aliasing is 2+ px away)
    top = img[int(0.11 * 256), 128].astype(int)
    assert np.abs(top - TOP_FIELD_RGB[label]).max() <= 12, (label, top)
    # (the inner border's colour, black or white by placard, is checked in
    # test_placards_cfr.py)


def test_hazmat_is_deterministic():
    assert np.array_equal(draw_hazmat("poison", 128), draw_hazmat("poison", 128))


def test_hazmat_labels_pairwise_distinct():
    # Changed pixels: some channel differs by more than 100 levels (a symbol, field or
    # glyph, not anti-aliasing). The closest pair (oxygen / oxidizer: same field and symbol,
    # different word and class number) differs on about 1.4 % of a 128 px placard; 1 %
    # (164 px, the area of one class-number glyph) is the bar every pair must clear.
    imgs = {lab: draw_hazmat(lab, 128).astype(int) for lab in HAZMAT_LABELS}
    for a, b in itertools.combinations(HAZMAT_LABELS, 2):
        changed = (np.abs(imgs[a] - imgs[b]).max(axis=2) > 100).mean()
        assert changed > 0.01, (a, b, changed)


def test_unknown_label_is_a_value_error_naming_it():
    with pytest.raises(UnknownHazmatLabelError, match="'laser-hazard'"):
        draw_hazmat("laser-hazard")
    assert issubclass(UnknownHazmatLabelError, ValueError)
    with pytest.raises(ValueError, match="size_px"):
        draw_hazmat("poison", 8)


@pytest.mark.parametrize("text", ["Chart M", "Chart AB", "poibench 12345"])
def test_qr_texture_decodes(text):
    img = draw_qr(text, 256)
    assert img.shape == (256, 256, 3)
    decoded, _, _ = cv2.QRCodeDetector().detectAndDecode(img)
    assert decoded == text


def test_qr_is_crisp_with_quiet_zone():
    # "Chart M" is a version 1 code: 21 modules; with 4 quiet modules each side 29 across,
    # so 256 px gives 256 // 29 = 8 px per module and the code starts at (256 - 168) // 2 = 44.
    n = qr_modules("Chart M").shape[0]
    assert n == 21
    img = draw_qr("Chart M", 256)[:, :, 0]
    assert set(np.unique(img)) == {0, 255}  # nearest neighbour: no grey
    dark_rows = np.flatnonzero((img == 0).any(axis=1))
    assert dark_rows[0] == 44 and dark_rows[-1] == 44 + 168 - 1
    assert dark_rows[0] >= 4 * 8  # quiet zone of at least 4 modules
    # the top-left finder pattern's outer ring: 7 modules = 56 dark pixels in a row
    assert (img[44, 44 : 44 + 56] == 0).all() and img[44, 44 + 56] == 255


def test_qr_errors():
    with pytest.raises(QrTextureError):
        draw_qr("", 256)
    with pytest.raises(QrTextureError, match="modules"):
        draw_qr("Chart M", 20)


def test_qr_texts():
    a = qr_texts(30, np.random.default_rng(4))
    assert a == qr_texts(30, np.random.default_rng(4))
    assert len(set(a)) == 30 and all(t.startswith("Chart ") for t in a)
    suffixes = [t[len("Chart ") :] for t in a]
    assert sorted(suffixes[:26]) == [chr(ord("A") + i) for i in range(26)]
    assert all(len(s) == 2 for s in suffixes[26:])
    assert qr_texts(5, np.random.default_rng(1)) != qr_texts(5, np.random.default_rng(2))
    with pytest.raises(QrTextureError):
        qr_texts(MAX_QR_TEXTS + 1, np.random.default_rng(0))


def _near(img: np.ndarray, rgb, tol: int = 30) -> np.ndarray:
    return np.abs(img.astype(int) - np.array(rgb)).max(axis=2) <= tol


def test_exit_sign():
    img = draw_exit_sign(256)
    assert img.shape == (128, 256, 3)
    white = _near(img, (255, 255, 255))
    assert _near(img, SAFETY_GREEN).mean() > 0.5  # a green sign ...
    assert 0.10 < white.mean() < 0.45  # ... with a white figure, door, arrow and border
    # the arrow points right: in the arrow's band (x 0.70..0.93 of the width) white
    # reaches further right at mid-height than at the arrow's shaft ends
    band = white[:, int(0.70 * 256) : int(0.93 * 256)]
    mid_cols = np.flatnonzero(band[64])
    top_cols = np.flatnonzero(band[int(0.40 * 128)])
    assert mid_cols.max() > top_cols.max() + 10


def test_fire_extinguisher_sign():
    img = draw_fire_extinguisher_sign(256)
    assert img.shape == (256, 256, 3)
    assert _near(img, SAFETY_RED).mean() > 0.5
    assert 0.12 < _near(img, (255, 255, 255)).mean() < 0.45


@pytest.mark.parametrize("draw", [draw_plywood, draw_floor])
def test_surfaces(draw):
    a = draw(128, np.random.default_rng(7))
    assert a.shape == (128, 128, 3) and a.dtype == np.uint8
    assert np.array_equal(a, draw(128, np.random.default_rng(7)))
    assert not np.array_equal(a, draw(128, np.random.default_rng(8)))
    mean = a.reshape(-1, 3).mean(axis=0)
    assert 120 < mean.mean() < 220  # mid-light
    assert mean[0] > mean[1] > mean[2]  # wood tan: R > G > B
    # texture for stereo matching: neighbouring pixels differ by a few grey levels on average
    grey = a.astype(float).mean(axis=2)
    interior = np.abs(np.diff(grey, axis=1)).mean()
    assert interior > 2.0
    # tileable: the step across the wrap-around seam is no larger than a typical step
    seam = np.abs(grey[:, 0] - grey[:, -1]).mean()
    assert seam < 2.0 * interior


def _plywood_every_copy(n: int, rng: np.random.Generator) -> np.ndarray:
    """draw_plywood's strands with all nine copies drawn (before issue 62): the reference."""
    import cv2

    big = np.zeros((3 * n, 3 * n), np.float32)
    for _ in range(int(3.0 * (n / 8) ** 2)):
        cx, cy = rng.uniform(0, n, size=2)
        length = rng.uniform(0.05, 0.14) * n
        width = length * rng.uniform(0.12, 0.3)
        ang = rng.normal(0.0, 25.0)
        shade = float(rng.normal(0.0, 0.10))
        for ox in (0, n, 2 * n):
            for oy in (0, n, 2 * n):
                box = cv2.boxPoints(((cx + ox, cy + oy), (length, width), ang))
                cv2.fillPoly(big, [np.round(box).astype(np.int32)], shade)
    return big[n : 2 * n, n : 2 * n]


@pytest.mark.parametrize("n", [16, 37, 128])
def test_plywood_strands_drawn_only_where_they_reach_the_kept_tile_change_nothing(n, monkeypatch):
    # draw_plywood skips the copies of a strand that cannot reach the centre tile (issue 62: a
    # third of a world's build); the flakes must be those of all nine copies, bit for bit
    import maze_assets.surfaces as surfaces

    kept: list[np.ndarray] = []
    real_laplacian = surfaces.cv2.Laplacian

    def laplacian(src, ddepth, *args, **kwargs):
        h = src.shape[0] // 3
        kept.append(src[:h, :h].copy())  # np.tile(flakes, (3, 3)): its first tile is the flakes
        return real_laplacian(src, ddepth, *args, **kwargs)

    monkeypatch.setattr(surfaces.cv2, "Laplacian", laplacian)
    surfaces.draw_plywood(n, np.random.default_rng(n))
    assert np.array_equal(kept[0], _plywood_every_copy(n, np.random.default_rng(n)))
