"""The drawn placards against 49 CFR 172 Subpart F (docs/FACTS.md "Hazmat placards").

Each part (symbol, words, class number, inner border) is found by drawing the placard
with and without it: the pixels that change are that part's. Their colour is then
compared with the colour the section fixes, written out here from the regulation's
text, not taken from the drawing code.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from maze_assets.hazmat import (
    EXPLOSIVE_DIVISIONS,
    PlacardStyle,
    canonical_style,
    draw_hazmat,
    placard_style,
)
from poi.core.names import HAZMAT_LABELS

N = 256
BLACKISH, WHITEISH = "black", "white"
# (symbol, words, class number, inner border) as each section writes it.
CFR = {
    "explosive": ("black", "black", "black", "black"),  # 172.522
    "blasting-agent": (None, "black", "black", "black"),  # 172.524 (no symbol)
    "flammable-gas": ("white", "white", "white", "white"),  # 172.532
    "non-flammable-gas": ("white", "white", "white", "white"),  # 172.528
    "oxygen": ("black", "black", "black", "black"),  # 172.530
    "fuel-oil": ("white", "white", "white", "white"),  # 172.544: "FUEL OIL" white
    "dangerous-when-wet": ("white", "white", "white", "white"),  # 172.548
    "flammable-solid": ("black", "black", "black", "black"),  # 172.546
    "spontaneously-combustible": ("black", "black", "black", "black"),  # 172.547
    "oxidizer": ("black", "black", "black", "black"),  # 172.550
    "organic-peroxide": ("either", "black", "black", "black"),  # 172.552: flame black or white
    "inhalation-hazard": ("white", "black", "black", "black"),  # 172.555
    "poison": ("black", "black", "black", "black"),  # 172.554
    "radioactive": ("black", "black", "black", "black"),  # 172.556
    "corrosive": ("black", "white", "white", "black"),  # 172.558
    "infectious-substance": ("black", "black", "black", "black"),  # 172.432
}
PARTS = ("symbol", "text", "number", "border")


def _part_pixels(label: str, part: str, style: PlacardStyle | None = None) -> np.ndarray:
    """RGB values of the pixels that belong to ``part`` (drawn with against without it)."""
    st = style or canonical_style(label)
    full = draw_hazmat(label, N, st).astype(int)
    without = draw_hazmat(label, N, replace(st, omit=st.omit | {part})).astype(int)
    changed = np.abs(full - without).max(axis=2) > 60
    # leave out anti-aliased rims: keep pixels whose 4-neighbours changed too
    core = changed.copy()
    core[1:-1, 1:-1] &= changed[:-2, 1:-1] & changed[2:, 1:-1] & changed[1:-1, :-2] & changed[1:-1, 2:]
    core[[0, -1], :] = False
    core[:, [0, -1]] = False
    return full[core]


def _is(colour: str, px: np.ndarray) -> bool:
    med = np.median(px, axis=0)
    if colour == "black":
        return bool(med.max() <= 60)
    if colour == "white":
        return bool(med.min() >= 200)
    return _is("black", px) or _is("white", px)


@pytest.mark.parametrize("label", HAZMAT_LABELS)
@pytest.mark.parametrize("k", range(4))
def test_part_colour_is_the_regulations(label, k):
    want = CFR[label][k]
    px = _part_pixels(label, PARTS[k])
    if want is None:
        assert len(px) == 0, f"{label}: the section draws no {PARTS[k]}"
        return
    assert len(px) > 20, f"{label}: {PARTS[k]} not drawn"
    assert _is(want, px), (label, PARTS[k], np.median(px, axis=0))


def test_organic_peroxide_flame_black_or_white_both_drawn():
    st = canonical_style("organic-peroxide")
    black = _part_pixels("organic-peroxide", "symbol", replace(st, flame=(20, 20, 20)))
    white = _part_pixels("organic-peroxide", "symbol", replace(st, flame=(255, 255, 255)))
    assert _is("black", black) and _is("white", white)
    flames = [placard_style("organic-peroxide", s).flame for s in range(400)]
    black_share = np.mean([f[0] < 128 for f in flames])
    assert 0.65 < black_share < 0.85  # mostly black, as arena placards are


def _cap_height(label: str, style: PlacardStyle | None = None) -> float:
    """Height of the words' tallest line, as a fraction of the texture's side."""
    st = style or canonical_style(label)
    full = draw_hazmat(label, N, st).astype(int)
    without = draw_hazmat(label, N, replace(st, omit=st.omit | {"text"})).astype(int)
    rows = np.flatnonzero((np.abs(full - without).max(axis=2) > 60).any(axis=1))
    # split into lines at gaps in the rows
    lines = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    return max(len(r) for r in lines) / N


@pytest.mark.parametrize("label", ["poison", "oxidizer", "corrosive", "flammable-gas", "non-flammable-gas"])
def test_words_are_at_least_41_mm_high(label):
    # 172.519(c): 41 mm letters on a 273 mm placard (diagonal 386 mm): 0.106 of the
    # texture; 172.528 allows 38 mm (0.098) on NON-FLAMMABLE GAS. 2 px for anti-aliasing.
    need = (38 if label == "non-flammable-gas" else 41) / (273 * np.sqrt(2)) - 2 / N
    assert _cap_height(label) >= need


@pytest.mark.parametrize("division", ["1.4", "1.6"])
def test_explosive_division_numeral_at_least_64_mm(division):
    st = replace(canonical_style("explosive"), division=division, compat="S")
    full = draw_hazmat("explosive", N, st).astype(int)
    without = draw_hazmat("explosive", N, replace(st, omit=st.omit | {"number"})).astype(int)
    rows = np.flatnonzero((np.abs(full - without).max(axis=2) > 60).any(axis=1))
    lines = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    assert len(lines[0]) / N >= 64 / (273 * np.sqrt(2)) - 2 / N  # the numeral, the first line


def test_every_explosive_division_has_a_compatibility_letter():
    assert {d for d, _ in EXPLOSIVE_DIVISIONS} == {"1.1", "1.2", "1.3", "1.4", "1.6"}
    assert all(len(letter) == 1 and letter.isalpha() for _, letter in EXPLOSIVE_DIVISIONS)
    st = canonical_style("explosive")
    assert st.division == "1.1" and st.compat
    # the letter is drawn: removing it changes the placard
    assert not np.array_equal(draw_hazmat("explosive", N, st), draw_hazmat("explosive", N, replace(st, compat="")))


def _field(label: str, y_mm_above_centre: float) -> np.ndarray:
    """Field colour on the vertical centre line ``y`` mm above the centre, nothing on top."""
    st = replace(canonical_style(label), omit=frozenset(PARTS))
    img = draw_hazmat(label, N, st).astype(int)
    y = 0.5 - y_mm_above_centre / (273 * np.sqrt(2))
    x = N // 2 + 40  # off the centre line, clear of symbol columns
    return img[int(round(y * N)), x]


@pytest.mark.parametrize(
    ("label", "base_mm", "above", "below"),
    [
        ("radioactive", 29, (255, 206, 0), (255, 255, 255)),  # 172.556: 29 +- 5 mm
        ("corrosive", 38, (255, 255, 255), (20, 20, 20)),  # 172.558: 38 +- 5 mm
    ],
)
def test_split_line_height(label, base_mm, above, below):
    assert np.abs(_field(label, base_mm + 7) - above).max() <= 10
    assert np.abs(_field(label, base_mm - 7) - below).max() <= 10


def test_inhalation_hazard_upper_diamond_lower_point_65_mm_above_centre():
    st = replace(canonical_style("inhalation-hazard"), omit=frozenset(PARTS))
    img = draw_hazmat("inhalation-hazard", N, st).astype(int)
    col = img[:, N // 2].max(axis=1)
    black_rows = np.flatnonzero(col < 60)
    lowest = black_rows.max() + 0.5
    mm_above = (0.5 - lowest / N) * 273 * np.sqrt(2)
    assert abs(mm_above - 65) <= 3


def test_flammable_solid_seven_stripes_as_wide_as_the_six_spaces():
    st = replace(canonical_style("flammable-solid"), omit=frozenset(PARTS))
    row = draw_hazmat("flammable-solid", 1024, st)[512].astype(int)
    red = (row[:, 0] > 150) & (row[:, 1] < 100)
    runs = np.diff(np.concatenate([[0], red.astype(int), [0]]))
    starts, ends = np.flatnonzero(runs == 1), np.flatnonzero(runs == -1)
    assert len(starts) == 7
    widths = ends - starts
    gaps = starts[1:] - ends[:-1]
    assert np.ptp(widths[1:-1]) <= 2 and abs(np.median(widths) - np.median(gaps)) <= 2


def test_styles_are_deterministic_and_varied():
    a = [placard_style("explosive", s) for s in range(50)]
    assert a == [placard_style("explosive", s) for s in range(50)]
    assert len({(s.division, s.compat) for s in a}) >= 6
    assert np.array_equal(
        draw_hazmat("poison", 96, a[3] and placard_style("poison", 3)),
        draw_hazmat("poison", 96, placard_style("poison", 3)),
    )
    no_text = np.mean([bool(placard_style("flammable-gas", s).omit) for s in range(500)])
    assert 0.12 < no_text < 0.28
    assert not any(placard_style("radioactive", s).omit for s in range(200))  # words required


def test_print_look_keeps_paper_and_ink_off_the_extremes():
    st = placard_style("corrosive", 11)
    img = draw_hazmat("corrosive", 128, st)
    assert img.min() >= st.look.ink_black - 2
    assert img.max() <= max(st.look.paper) + 2


def test_infectious_label_with_its_leakage_notice():
    """Half the worded infectious-substance labels carry the notice; it is black on white,
    under the words and above the number, and no other label gets one."""
    styles = [placard_style("infectious-substance", s) for s in range(400)]
    share = np.mean([bool(st.notice) for st in styles if not st.omit])
    assert 0.42 < share < 0.58
    assert not any(
        placard_style(lab, s).notice for lab in HAZMAT_LABELS if lab != "infectious-substance" for s in range(30)
    )
    plain = replace(canonical_style("infectious-substance"), notice=())
    noticed = replace(
        plain, notice=("IN CASE OF DAMAGE", "OR LEAKAGE IMMEDIATELY", "NOTIFY PUBLIC", "HEALTH AUTHORITY")
    )
    a, b = draw_hazmat("infectious-substance", N, plain), draw_hazmat("infectious-substance", N, noticed)
    rows = np.nonzero(np.any(np.abs(a.astype(int) - b.astype(int)).sum(axis=2) > 60, axis=1))[0]
    # the words move up and the notice lies between them and the class number (centre 0.81 N)
    notice_rows = [r for r in rows if r > 0.61 * N]
    assert notice_rows and max(notice_rows) < 0.75 * N
    band = b[int(0.62 * N) : int(0.73 * N), int(0.35 * N) : int(0.65 * N)].reshape(-1, 3)
    dark = band[band.max(axis=1) < 100]
    assert len(dark) > 50 and np.all(np.ptp(dark, axis=1) < 20)  # black ink, not coloured


def test_the_biohazard_sign_fills_the_upper_half_over_one_line_of_words():
    """172.432's figure and the printed labels: the sign spans the diamond's upper half,
    the words run in one line under it, clear of the sign."""
    st = canonical_style("infectious-substance")
    full = draw_hazmat("infectious-substance", N, st).astype(int)

    def mask(part: str) -> np.ndarray:  # (N, N) bool: the pixels the part changes
        without = draw_hazmat("infectious-substance", N, replace(st, omit=st.omit | {part})).astype(int)
        return np.abs(full - without).max(axis=2) > 60

    sign = mask("symbol")
    rows = np.flatnonzero(sign.any(axis=1)) / N
    cols = np.flatnonzero(sign.any(axis=0)) / N
    assert rows.max() - rows.min() >= 0.3 and rows.max() <= 0.5
    assert cols.max() - cols.min() >= 0.3
    words = mask("text")
    word_rows = np.flatnonzero(words.any(axis=1)) / N
    assert word_rows.min() > rows.max()  # under the sign
    assert word_rows.max() - word_rows.min() < 0.09  # one line


def test_the_placards_picture_in_the_docs_is_what_the_code_draws():
    """docs/placards.png (the mazes guide's picture of the 16 and five variants each) is the
    current drawing: a redrawn label fails this until the picture is made again."""
    from pathlib import Path

    import cv2

    from maze_assets.hazmat import placard_sheet

    path = Path(__file__).resolve().parents[2] / "docs" / "placards.png"
    shown = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB).astype(int)
    drawn = placard_sheet().astype(int)
    assert shown.shape == drawn.shape == (8 * 96, 2 * 6 * 96 + 8, 3)
    diff = np.abs(shown - drawn).mean(axis=2)
    stale = [
        HAZMAT_LABELS[h * 8 + r]
        for h in range(2)
        for r in range(8)
        if diff[r * 96 : (r + 1) * 96, h * 584 : h * 584 + 576].mean() > 0.5
    ]
    assert not stale, (
        f"docs/placards.png shows an older drawing of {', '.join(stale)}: make it again with "
        'python -c "import cv2; from maze_assets.hazmat import placard_sheet; '
        "cv2.imwrite('docs/placards.png', placard_sheet()[..., ::-1], [cv2.IMWRITE_PNG_COMPRESSION, 9])\""
    )
