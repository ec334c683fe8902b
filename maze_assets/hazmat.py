"""Hazmat placards drawn to 49 CFR 172 Subpart F: the 16 labels of docs/RULES.md.

Follows docs/FACTS.md "Hazmat placards" ([CFR49-172]_): a square-on-point diamond with
a solid inner border line inset from its edge, the colour fields of each placard, its
symbol in the top corner, its words in large bold capitals across the middle and its
class number in the bottom corner. The colour of symbol, words, number and inner border
is the one each section fixes (table ``INK`` below, checked pixel by pixel in
tests/maze_assets/test_placards_cfr.py). Outside the diamond is the paper it is printed on.

Sizes are fractions of the texture's side, which is the diamond's diagonal: a placard
of side 273 mm ([CFR49-172]_ 172.519(c)) is 386 mm across, so the 41 mm minimum height
of words and class number is 0.106 of the texture and the 64 mm division numeral of
explosives 1.4-1.6 is 0.166. Words are set in a bold sans (DejaVu Sans Bold, shipped
with matplotlib), condensed sideways where a long word must fit the diamond, as
printed placards are.

A :class:`PlacardStyle` picks the variant seen in arenas (with or without words,
explosive divisions 1.1-1.6 with their compatibility letter, alternate words, the
organic-peroxide flame black or white) and a :class:`PrintLook` the print (paper white,
ink density, fading, wear and creases). :func:`placard_style` draws both from a seed;
without a style the canonical design is drawn with a clean print.

Everything is drawn at ``SUPERSAMPLE`` times the requested size and reduced with area
averaging, so edges are smooth and the result is a pure function of its arguments.

>>> img = draw_hazmat("oxidizer", 64)
>>> img.shape, img.dtype.name
((64, 64, 3), 'uint8')
>>> tuple(int(v) for v in img[0, 0])  # paper corner
(246, 246, 244)

References
----------
Full entries in docs/SOURCES.md.

.. [CFR49-172] U.S. Code of Federal Regulations, Title 49, Part 172, Subpart F "Placarding",
   sections 172.500-172.560.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import cv2
import matplotlib
import numpy as np
from PIL import Image, ImageDraw, ImageFont

from poi.core.names import HAZMAT_LABELS

SUPERSAMPLE = 4
MIN_SIZE_PX = 32

PAPER = (246, 246, 244)
BLACK = (20, 20, 20)
WHITE = (255, 255, 255)
ORANGE = (247, 120, 30)
RED = (218, 30, 40)
GREEN = (0, 150, 80)
YELLOW = (255, 206, 0)
BLUE = (0, 95, 175)

Color = tuple[int, int, int]

FONT_PATH = os.path.join(matplotlib.get_data_path(), "fonts", "ttf", "DejaVuSans-Bold.ttf")
PARTS = ("symbol", "text", "number", "border")


class UnknownHazmatLabelError(ValueError):
    """A label that is not one of poi.core.names.HAZMAT_LABELS."""


# --- the regulation's colours: symbol, words, class number, inner border --------------
@dataclass(frozen=True)
class Ink:
    """Colours a placard's section fixes for its symbol, words, class number and border."""

    symbol: Color
    text: Color
    number: Color
    border: Color


_B, _W = BLACK, WHITE
INK: dict[str, Ink] = {
    "explosive": Ink(_B, _B, _B, _B),  # 172.522-172.525
    "blasting-agent": Ink(_B, _B, _B, _B),  # 172.524
    "flammable-gas": Ink(_W, _W, _W, _W),  # 172.532
    "non-flammable-gas": Ink(_W, _W, _W, _W),  # 172.528
    "oxygen": Ink(_B, _B, _B, _B),  # 172.530
    "fuel-oil": Ink(_W, _W, _W, _W),  # 172.544
    "dangerous-when-wet": Ink(_W, _W, _W, _W),  # 172.548
    "flammable-solid": Ink(_B, _B, _B, _B),  # 172.546
    "spontaneously-combustible": Ink(_B, _B, _B, _B),  # 172.547
    "oxidizer": Ink(_B, _B, _B, _B),  # 172.550
    "organic-peroxide": Ink(_B, _B, _B, _B),  # 172.552: the flame may be white instead
    "inhalation-hazard": Ink(_W, _B, _B, _B),  # 172.555: white symbol on the black upper diamond
    "poison": Ink(_B, _B, _B, _B),  # 172.554
    "radioactive": Ink(_B, _B, _B, _B),  # 172.556
    "corrosive": Ink(_B, _W, _W, _B),  # 172.558: words and number white on the black part
    "infectious-substance": Ink(_B, _B, _B, _B),  # 172.432 (a label: black on white)
}


# --- variants and print ------------------------------------------------------------------
@dataclass(frozen=True)
class PrintLook:
    """How a placard came out of the printer and what the arena did to it since.

    ``paper`` is the white of the sheet, ``ink_black`` the darkest ink, ``fade`` the
    fraction of colour saturation kept, ``wear`` the fraction of the face with scuffed
    ink, ``creases`` how many fold lines cross it, ``laminated`` whether a glossy film
    covers it (the scene gives it a specular material), ``cut`` whether it was cut out
    along the diamond (else the square sheet shows); ``seed`` places wear and creases.
    """

    paper: Color = PAPER
    ink_black: int = BLACK[0]
    fade: float = 1.0
    wear: float = 0.0
    creases: int = 0
    laminated: bool = False
    cut: bool = False
    seed: int = 0


@dataclass(frozen=True)
class PlacardStyle:
    """One variant of a placard as printed for an arena.

    ``words``: the lines of text (empty: the placard without words, which the regulation
    allows for most classes). ``number``: the class number in the bottom corner.
    ``division``/``compat``: explosives' division ("1.4") and compatibility letter
    ("S"). ``flame``: the organic-peroxide flame's colour. ``omit``: parts left out
    (any of ``PARTS``), used to draw the placard without words. ``notice``: small lines
    under the words (the infectious-substance label's leakage notice).
    """

    words: tuple[str, ...]
    number: str
    division: str = ""
    compat: str = ""
    flame: Color = WHITE
    omit: frozenset[str] = frozenset()
    notice: tuple[str, ...] = ()
    look: PrintLook = field(default_factory=PrintLook)


_CANONICAL: dict[str, PlacardStyle] = {
    "explosive": PlacardStyle(("EXPLOSIVES",), "1", division="1.1", compat="D"),
    "blasting-agent": PlacardStyle(("BLASTING", "AGENTS"), "1", division="1.5", compat="D"),
    "flammable-gas": PlacardStyle(("FLAMMABLE", "GAS"), "2"),
    "non-flammable-gas": PlacardStyle(("NON-FLAMMABLE", "GAS"), "2"),
    "oxygen": PlacardStyle(("OXYGEN",), "2"),
    "fuel-oil": PlacardStyle(("FUEL OIL",), "3"),
    "dangerous-when-wet": PlacardStyle(("DANGEROUS", "WHEN WET"), "4"),
    "flammable-solid": PlacardStyle(("FLAMMABLE", "SOLID"), "4"),
    "spontaneously-combustible": PlacardStyle(("SPONTANEOUSLY", "COMBUSTIBLE"), "4"),
    "oxidizer": PlacardStyle(("OXIDIZER",), "5.1"),
    "organic-peroxide": PlacardStyle(("ORGANIC", "PEROXIDE"), "5.2", flame=BLACK),
    "inhalation-hazard": PlacardStyle(("INHALATION", "HAZARD"), "6"),
    "poison": PlacardStyle(("POISON",), "6"),
    "radioactive": PlacardStyle(("RADIOACTIVE",), "7"),
    "corrosive": PlacardStyle(("CORROSIVE",), "8"),
    "infectious-substance": PlacardStyle(("INFECTIOUS SUBSTANCE",), "6"),
}

# Alternates seen on arena placards, beside the canonical words: (words, number) pairs.
_ALTERNATE_WORDS: dict[str, list[tuple[tuple[str, ...], str]]] = {
    "poison": [(("TOXIC",), "6")],
    "inhalation-hazard": [(("POISON", "GAS"), "2"), (("TOXIC", "GAS"), "2")],
    "flammable-gas": [(("FLAMMABLE",), "2")],
    "fuel-oil": [(("COMBUSTIBLE",), "3")],
    "dangerous-when-wet": [(("DANGEROUS", "WHEN", "WET"), "4")],
    "spontaneously-combustible": [(("SPONTANEOUSLY", "COMBUSTIBLE"), "4")],
}

# Explosives 1.1-1.6 as printed for arenas: division and a compatibility letter each.
EXPLOSIVE_DIVISIONS = (
    ("1.1", "D"),
    ("1.1", "A"),
    ("1.2", "E"),
    ("1.3", "C"),
    ("1.3", "G"),
    ("1.4", "S"),
    ("1.4", "G"),
    ("1.4", "C"),
    ("1.6", "N"),
)
# The infectious-substance label as shipped on packages carries a notice under its words
# (172.432 allows it: "IN CASE OF DAMAGE OR LEAKAGE IMMEDIATELY NOTIFY PUBLIC HEALTH
# AUTHORITY"); arenas print both that label and the plain one.
INFECTIOUS_NOTICE = ("IN CASE OF DAMAGE", "OR LEAKAGE IMMEDIATELY", "NOTIFY PUBLIC", "HEALTH AUTHORITY")
INFECTIOUS_NOTICE_SHARE = 0.5
NOTICE_CAP, NOTICE_GAP = 0.022, 0.008
TEXT_OPTIONAL = frozenset(HAZMAT_LABELS) - {"radioactive", "fuel-oil", "blasting-agent"}


def canonical_style(label: str) -> PlacardStyle:
    """The placard as its section draws it, cleanly printed."""
    _check_label(label)
    return _CANONICAL[label]


def random_look(rng: np.random.Generator) -> PrintLook:
    """A print drawn from ranges seen on arena placards (office printers, laminated or not)."""
    paper_w = int(rng.integers(232, 256))
    tint = rng.integers(-6, 4, size=3)
    return PrintLook(
        paper=tuple(int(np.clip(paper_w + t, 0, 255)) for t in tint),
        ink_black=int(rng.integers(10, 55)),
        fade=float(rng.uniform(0.72, 1.0)),
        wear=float(rng.choice([0.0, 0.0, rng.uniform(0.005, 0.04)])),
        creases=int(rng.choice([0, 0, 0, 1, 2])),
        laminated=bool(rng.random() < 0.5),
        cut=bool(rng.random() < 0.6),
        seed=int(rng.integers(2**31)),
    )


def placard_style(label: str, seed: int) -> PlacardStyle:
    """A variant and print for ``label`` drawn from ``seed`` (same seed, same placard).

    One in five placards of labels whose section allows it has no words; one in three
    has the alternate words where arenas use them; explosives take a division 1.1-1.6
    with its letter; the organic-peroxide flame is black three times in four.
    """
    _check_label(label)
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 172])
    style = _CANONICAL[label]
    alts = _ALTERNATE_WORDS.get(label, [])
    if alts and rng.random() < 1 / 3:
        words, number = alts[int(rng.integers(len(alts)))]
        style = replace(style, words=words, number=number)
    if label == "explosive":
        div, letter = EXPLOSIVE_DIVISIONS[int(rng.integers(len(EXPLOSIVE_DIVISIONS)))]
        style = replace(style, division=div, compat=letter)
    if label == "organic-peroxide":
        style = replace(style, flame=BLACK if rng.random() < 0.75 else WHITE)
    if label in TEXT_OPTIONAL and rng.random() < 0.2:
        style = replace(style, omit=frozenset({"text"}))
    look = random_look(rng)
    # its own stream, so adding the notice left every other draw as it was
    notice_draw = np.random.default_rng([int(seed) & 0xFFFFFFFF, 432]).random()
    if label == "infectious-substance" and not style.omit and notice_draw < INFECTIOUS_NOTICE_SHARE:
        style = replace(style, notice=INFECTIOUS_NOTICE)
    return replace(style, look=look)


# --- drawing primitives -------------------------------------------------------------------
@functools.lru_cache(maxsize=64)
def _font(size: int) -> ImageFont.FreeTypeFont:
    return ImageFont.truetype(FONT_PATH, size)


CAP_RATIO = 0.73  # DejaVu Sans Bold: cap height / font size


class _Canvas:
    """A square drawing surface in unit coordinates (0..1, y down) at N pixels."""

    def __init__(self, n: int, fill: Color) -> None:
        self.n = n
        self.img = np.empty((n, n, 3), np.uint8)
        self.img[:] = fill

    def p(self, x: float, y: float) -> tuple[int, int]:
        return int(round(x * self.n)), int(round(y * self.n))

    def poly(self, pts, color: Color) -> None:
        arr = np.round(np.asarray(pts, dtype=float) * self.n).astype(np.int32)
        cv2.fillPoly(self.img, [arr], color, cv2.LINE_AA)

    def circle(self, x: float, y: float, r: float, color: Color) -> None:
        cv2.circle(self.img, self.p(x, y), max(1, int(round(r * self.n))), color, -1, cv2.LINE_AA)

    def line(self, x0: float, y0: float, x1: float, y1: float, w: float, color: Color) -> None:
        th = max(1, int(round(w * self.n)))
        cv2.line(self.img, self.p(x0, y0), self.p(x1, y1), color, th, cv2.LINE_AA)

    def rect(self, x0: float, y0: float, x1: float, y1: float, color: Color) -> None:
        cv2.rectangle(self.img, self.p(x0, y0), self.p(x1, y1), color, -1)

    def text(self, s: str, cx: float, cy: float, cap: float, max_w: float, color: Color) -> float:
        """Set ``s`` in bold capitals ``cap`` high, centred at (cx, cy); returns its width.

        A line wider than ``max_w`` is first condensed sideways (to 45% at most, as
        condensed placard faces are), then scaled down as a whole.
        """
        size = max(4, int(round(cap * self.n / CAP_RATIO)))
        font = _font(size)
        left, top, right, bottom = font.getbbox(s, anchor="ls")
        mask = Image.new("L", (right - left + 2, bottom - top + 2), 0)
        ImageDraw.Draw(mask).text((1 - left, 1 - top), s, font=font, fill=255, anchor="ls")
        m = np.asarray(mask, np.float32) / 255.0
        baseline = 1 - top  # row of the baseline in ``m``
        w_px, limit = m.shape[1], max_w * self.n
        sx = sy = 1.0
        if w_px > limit:
            sx = max(0.45, limit / w_px)
            if w_px * sx > limit:
                sy = sx = limit / w_px
        if (sx, sy) != (1.0, 1.0):
            new = (max(1, int(round(m.shape[1] * sx))), max(1, int(round(m.shape[0] * sy))))
            m = cv2.resize(m, new, interpolation=cv2.INTER_AREA)
            baseline *= sy
        cap_px = cap * self.n * sy
        x0 = int(round(cx * self.n - m.shape[1] / 2))
        y0 = int(round(cy * self.n + cap_px / 2 - baseline))
        self._blend(m, x0, y0, color)
        return m.shape[1] / self.n

    def _blend(self, m: np.ndarray, x0: int, y0: int, color: Color) -> None:
        h, w = m.shape
        ys, xs = slice(max(0, y0), min(self.n, y0 + h)), slice(max(0, x0), min(self.n, x0 + w))
        a = m[ys.start - y0 : ys.stop - y0, xs.start - x0 : xs.stop - x0, None]
        region = self.img[ys, xs].astype(np.float32)
        self.img[ys, xs] = np.round(region * (1 - a) + np.float32(color) * a).astype(np.uint8)


# --- geometry of the placard (unit coordinates, y down) ---------------------------------
EDGE = 0.015  # paper margin around the diamond's corners
BORDER_INSET = 0.050  # the inner border line: 12.5 mm in from a 250 mm edge (172.519(c))
BORDER_W = 0.010
SYM_CX, SYM_BASE_Y, SYM_H = 0.5, 0.43, 0.27  # symbol box: bottom centre and height
# the skull fills more of the top corner on printed placards
BIG_SYM_H = 0.33
# The infectious-substance label's biohazard sign fills its upper half, over one line of
# words (172.432's figure; so do the printed labels of the real photo set, where a label
# drawn with a smaller sign over two lines of words was read right 58% of the time).
INFECTIOUS_SYM_BASE, INFECTIOUS_SYM_H = 0.47, 0.37
NUMBER_CY, NUMBER_CAP = 0.81, 0.125
WORD_CAP = 0.106  # 41 mm on a 273 mm placard (172.519(c))
MM = 1.0 / (273.0 * np.sqrt(2.0))  # one millimetre of a 273 mm placard, in texture units


def _diamond(inset: float) -> np.ndarray:
    a = EDGE + inset
    return np.array([(0.5, a), (1 - a, 0.5), (0.5, 1 - a), (a, 0.5)])


def _half_width(y: float, inset: float = BORDER_INSET + 0.02) -> float:
    """Half the width of the usable diamond at height y (unit coordinates)."""
    return max(0.0, 0.5 - EDGE - inset - abs(y - 0.5))


def _chaikin(pts: np.ndarray, rounds: int = 3) -> np.ndarray:
    """Corner-cutting subdivision of a closed polygon (smooth flame outlines)."""
    for _ in range(rounds):
        nxt = np.roll(pts, -1, axis=0)
        q = 0.75 * pts + 0.25 * nxt
        r = 0.25 * pts + 0.75 * nxt
        pts = np.stack([q, r], axis=1).reshape(-1, 2)
    return pts


class _Symbol:
    """Maps symbol-local coordinates (x right, y up, base at 0, height 1) onto the canvas."""

    def __init__(self, c: _Canvas, cx: float = SYM_CX, base: float = SYM_BASE_Y, h: float = SYM_H):
        self.c, self.cx, self.base, self.h = c, cx, base, h

    def u(self, pts) -> np.ndarray:
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        return np.stack([self.cx + pts[:, 0] * self.h, self.base - pts[:, 1] * self.h], axis=1)

    def poly(self, pts, color: Color) -> None:
        self.c.poly(self.u(pts), color)

    def circle(self, x: float, y: float, r: float, color: Color) -> None:
        ((px, py),) = self.u([(x, y)])
        self.c.circle(px, py, r * self.h, color)

    def line(self, x0: float, y0: float, x1: float, y1: float, w: float, color: Color) -> None:
        (a, b), (d, e) = self.u([(x0, y0), (x1, y1)])
        self.c.line(a, b, d, e, w * self.h, color)

    def sector(self, x: float, y: float, r: float, a0: float, a1: float, color: Color) -> None:
        """Filled pie slice, angles in degrees counter-clockwise from +x (y up)."""
        ((px, py),) = self.u([(x, y)])
        ctr = self.c.p(px, py)
        rad = max(1, int(round(r * self.h * self.c.n)))
        cv2.ellipse(self.c.img, ctr, (rad, rad), 0, -a1, -a0, color, -1, cv2.LINE_AA)


_FLAME = np.array(
    [
        (-0.20, 0.00),
        (-0.36, 0.09),
        (-0.42, 0.25),
        (-0.39, 0.42),
        (-0.32, 0.56),
        (-0.36, 0.74),
        (-0.22, 0.62),
        (-0.14, 0.50),
        (-0.15, 0.68),
        (-0.07, 0.86),
        (0.03, 1.00),
        (0.09, 0.82),
        (0.13, 0.64),
        (0.18, 0.54),
        (0.25, 0.66),
        (0.33, 0.80),
        (0.40, 0.56),
        (0.42, 0.36),
        (0.37, 0.17),
        (0.24, 0.03),
        (0.10, -0.01),
        (-0.05, -0.01),
    ]
)


def _flame(s: _Symbol, color: Color, base: float = 0.12, height: float = 0.88, bar=True) -> None:
    """The DOT flame: three tongues on a horizontal base bar."""
    pts = _chaikin(_FLAME.copy())
    pts[:, 0] *= height * 1.05
    pts[:, 1] = base + pts[:, 1] * height
    s.poly(pts, color)
    if bar:
        s.poly([(-0.50, 0.0), (0.50, 0.0), (0.50, 0.07), (-0.50, 0.07)], color)


def _flame_over_circle(s: _Symbol, color: Color, bg: Color) -> None:
    s.poly([(-0.50, 0.0), (0.50, 0.0), (0.50, 0.07), (-0.50, 0.07)], color)
    _flame(s, color, base=0.30, height=0.70, bar=False)
    s.circle(0.0, 0.34, 0.22, color)
    s.circle(0.0, 0.34, 0.13, bg)


def _bomb(s: _Symbol, color: Color) -> None:
    """Exploding bomb: a ball, rays and flying fragments."""
    s.circle(0.0, 0.42, 0.16, color)
    for k in range(12):
        a = np.deg2rad(k * 30 + 15)
        r0, r1 = (0.22, 0.52) if k % 2 == 0 else (0.22, 0.40)
        s.line(
            r0 * np.cos(a),
            0.42 + r0 * np.sin(a),
            r1 * np.cos(a),
            0.42 + r1 * np.sin(a),
            0.05,
            color,
        )
    for k in range(6):
        a = np.deg2rad(k * 60)
        cx, cy = 0.50 * np.cos(a), 0.42 + 0.48 * np.sin(a)
        t = np.array([(0.0, 0.06), (0.05, -0.04), (-0.05, -0.03)])
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        s.poly(t @ rot.T + (cx, cy), color)


def _cylinder(s: _Symbol, color: Color) -> None:
    """Upright gas cylinder with a valve."""
    s.poly([(-0.16, 0.02), (0.16, 0.02), (0.16, 0.66), (-0.16, 0.66)], color)
    s.circle(0.0, 0.66, 0.16, color)
    s.circle(-0.12, 0.06, 0.04, color)
    s.circle(0.12, 0.06, 0.04, color)
    s.poly([(-0.06, 0.78), (0.06, 0.78), (0.06, 0.90), (-0.06, 0.90)], color)
    s.poly([(-0.12, 0.90), (0.12, 0.90), (0.12, 0.96), (-0.12, 0.96)], color)
    s.line(0.06, 0.86, 0.18, 0.86, 0.04, color)


def _skull(s: _Symbol, color: Color, bg: Color) -> None:
    """Skull and crossbones."""
    for sign in (-1, 1):
        s.line(-0.40 * sign, 0.02, 0.40 * sign, 0.32, 0.09, color)
        for ex, ey in ((-0.40 * sign, 0.02), (0.40 * sign, 0.32)):
            dy = 0.04
            s.circle(ex - 0.02 * sign, ey + dy, 0.05, color)
            s.circle(ex + 0.03 * sign, ey - dy, 0.05, color)
    s.circle(0.0, 0.66, 0.27, color)
    s.poly([(-0.17, 0.62), (0.17, 0.62), (0.15, 0.34), (-0.15, 0.34)], color)
    s.circle(-0.10, 0.62, 0.075, bg)
    s.circle(0.10, 0.62, 0.075, bg)
    s.poly([(0.0, 0.55), (-0.04, 0.47), (0.04, 0.47)], bg)
    for x in (-0.08, 0.0, 0.08):
        s.line(x, 0.34, x, 0.42, 0.025, bg)


def _trefoil(s: _Symbol, color: Color, bg: Color) -> None:
    """Radiation trefoil: a centre disc and three 60-degree blades, one pointing down."""
    cy, r0 = 0.50, 0.085
    for a in (-90.0, 30.0, 150.0):
        s.sector(0.0, cy, 5 * r0, a - 30, a + 30, color)
    s.circle(0.0, cy, 1.5 * r0, bg)
    s.circle(0.0, cy, r0, color)


def _biohazard(s: _Symbol, color: Color, bg: Color) -> None:
    """Three crescents around a ring (the biohazard symbol)."""
    cy = 0.48
    dirs = [np.deg2rad(a) for a in (90.0, 210.0, 330.0)]
    for a in dirs:
        s.circle(0.22 * np.cos(a), cy + 0.22 * np.sin(a), 0.26, color)
    for a in dirs:
        s.circle(0.30 * np.cos(a), cy + 0.30 * np.sin(a), 0.19, bg)
    s.circle(0.0, cy, 0.17, color)
    s.circle(0.0, cy, 0.13, bg)
    for a in dirs:
        s.line(0.0, cy, 0.30 * np.cos(a), cy + 0.30 * np.sin(a), 0.035, bg)
    s.circle(0.0, cy, 0.05, bg)


def _corrosive(s: _Symbol, color: Color, bg: Color) -> None:
    """Two tubes pouring drops onto a hand (left) and a bar (right)."""
    for sx in (-1, 1):
        s.line(0.44 * sx, 0.80, 0.12 * sx, 0.66, 0.13, color)
        s.circle(0.44 * sx, 0.80, 0.065, color)
        s.line(0.41 * sx, 0.80, 0.16 * sx, 0.69, 0.05, bg)  # the glass's hollow
        for k, yy in enumerate((0.58, 0.46, 0.34)):
            s.circle(0.17 * sx, yy, 0.030 + 0.006 * k, color)
    # hand: palm, thumb and four fingers
    s.poly([(-0.50, 0.02), (-0.20, 0.02), (-0.14, 0.10), (-0.20, 0.18), (-0.50, 0.18)], color)
    for k in range(4):
        x = -0.46 + 0.085 * k
        s.line(x, 0.16, x, 0.27 - 0.02 * abs(k - 1.5), 0.055, color)
    # bar with a bitten notch
    s.poly([(0.06, 0.02), (0.50, 0.02), (0.50, 0.18), (0.06, 0.18)], color)
    s.circle(0.20, 0.19, 0.05, bg)
    s.circle(0.34, 0.19, 0.035, bg)


def _stripes(c: _Canvas) -> None:
    """Seven red vertical stripes as wide as the six white spaces between them (172.546)."""
    x0, x1 = EDGE, 1 - EDGE
    w = (x1 - x0) / 13
    for k in range(0, 13, 2):
        c.rect(x0 + k * w, 0.0, x0 + (k + 1) * w, 1.0, RED)


def _upper_triangle(c: _Canvas, top: Color, bottom: Color, base_y: float) -> None:
    """``bottom`` everywhere, ``top`` above the horizontal line ``base_y`` (172.556, 172.558)."""
    c.rect(0.0, 0.0, 1.0, 1.0, bottom)
    c.rect(0.0, 0.0, 1.0, base_y, top)


def _upper_diamond(c: _Canvas, lower_point_y: float, color: Color) -> None:
    """A diamond in the top corner whose lower point is at ``lower_point_y`` (172.540, 172.555)."""
    top = EDGE
    mid = (top + lower_point_y) / 2
    half = (lower_point_y - top) / 2
    c.poly([(0.5, top), (0.5 + half, mid), (0.5, lower_point_y), (0.5 - half, mid)], color)


# Heights of the colour splits above the horizontal centre line, from the sections.
RADIOACTIVE_SPLIT_Y = 0.5 - 29 * MM  # 172.556: yellow triangle's base 29 +- 5 mm above
CORROSIVE_SPLIT_Y = 0.5 - 38 * MM  # 172.558: white triangle's base 38 +- 5 mm above
INHALATION_POINT_Y = 0.5 - 65 * MM  # 172.555: the upper diamond's lower point 65 mm above


_FIELD: dict[str, Callable[[_Canvas, PlacardStyle], None]] = {
    "explosive": lambda c, st: c.rect(0, 0, 1, 1, ORANGE),
    "blasting-agent": lambda c, st: c.rect(0, 0, 1, 1, ORANGE),
    "flammable-gas": lambda c, st: c.rect(0, 0, 1, 1, RED),
    "non-flammable-gas": lambda c, st: c.rect(0, 0, 1, 1, GREEN),
    "oxygen": lambda c, st: c.rect(0, 0, 1, 1, YELLOW),
    "fuel-oil": lambda c, st: c.rect(0, 0, 1, 1, RED),
    "dangerous-when-wet": lambda c, st: c.rect(0, 0, 1, 1, BLUE),
    "flammable-solid": lambda c, st: (c.rect(0, 0, 1, 1, WHITE), _stripes(c)),
    "spontaneously-combustible": lambda c, st: _upper_triangle(c, WHITE, RED, 0.5),
    "oxidizer": lambda c, st: c.rect(0, 0, 1, 1, YELLOW),
    "organic-peroxide": lambda c, st: _upper_triangle(c, RED, YELLOW, 0.5),
    "inhalation-hazard": lambda c, st: (c.rect(0, 0, 1, 1, WHITE), _upper_diamond(c, INHALATION_POINT_Y, BLACK)),
    "poison": lambda c, st: c.rect(0, 0, 1, 1, WHITE),
    "radioactive": lambda c, st: _upper_triangle(c, YELLOW, WHITE, RADIOACTIVE_SPLIT_Y),
    "corrosive": lambda c, st: _upper_triangle(c, WHITE, BLACK, CORROSIVE_SPLIT_Y),
    "infectious-substance": lambda c, st: c.rect(0, 0, 1, 1, WHITE),
}


def _draw_symbol(label: str, c: _Canvas, st: PlacardStyle) -> None:
    ink = INK[label].symbol
    bg = tuple(int(v) for v in c.img[int(0.3 * c.n), c.n // 2])
    s = _Symbol(c)
    if label in (
        "flammable-gas",
        "fuel-oil",
        "dangerous-when-wet",
        "flammable-solid",
        "spontaneously-combustible",
    ):
        _flame(s, ink)
    elif label == "organic-peroxide":
        _flame(s, st.flame)
    elif label in ("oxygen", "oxidizer"):
        _flame_over_circle(s, ink, bg)
    elif label == "non-flammable-gas":
        _cylinder(s, ink)
    elif label == "poison":
        _skull(_Symbol(c, base=SYM_BASE_Y, h=BIG_SYM_H), ink, bg)
    elif label == "inhalation-hazard":
        h = (INHALATION_POINT_Y - EDGE) * 0.47
        _skull(_Symbol(c, base=INHALATION_POINT_Y - 0.05, h=h), ink, BLACK)
    elif label == "infectious-substance":
        _biohazard(_Symbol(c, base=INFECTIOUS_SYM_BASE, h=INFECTIOUS_SYM_H), ink, bg)
    elif label == "radioactive":
        _trefoil(_Symbol(c, base=RADIOACTIVE_SPLIT_Y + 0.01, h=0.27), ink, YELLOW)
    elif label == "corrosive":
        _corrosive(_Symbol(c, base=CORROSIVE_SPLIT_Y - 0.015, h=0.29), ink, WHITE)
    elif label == "explosive" and st.division in ("1.1", "1.2", "1.3"):
        _bomb(s, ink)


def _words_layout(label: str, st: PlacardStyle) -> tuple[float, float]:
    """(centre line, cap height) of the words: below the splits and big numerals."""
    lines = len(st.words)
    cap = WORD_CAP if lines <= 2 else 0.08
    cy = {1: 0.555, 2: 0.57, 3: 0.59}.get(lines, 0.6)
    if label == "radioactive":
        cy = 0.545
    if label == "corrosive":
        cy = 0.565
    if label == "inhalation-hazard":
        cy = 0.53 if lines == 2 else 0.50
    if label == "infectious-substance" and lines == 1:  # under the large sign, the width's limit
        cy, cap = 0.55, 0.06
    if label in ("explosive", "blasting-agent") and st.division in ("1.4", "1.5", "1.6"):
        cy, cap = (0.62, 0.075) if lines == 1 else (0.635, 0.07)
    if st.notice:  # words raised and smaller, the notice between them and the number
        cy, cap = 0.52, 0.08
        if label == "infectious-substance" and lines == 1:
            cy, cap = 0.53, 0.055
    return cy, cap


def _draw_words(label: str, c: _Canvas, st: PlacardStyle) -> None:
    ink = INK[label].text
    cy, cap = _words_layout(label, st)
    gap = 0.25 * cap
    y = cy - (len(st.words) - 1) * (cap + gap) / 2
    for line in st.words:
        c.text(line, 0.5, y, cap, 2 * _half_width(y + cap / 2), ink)
        y += cap + gap
    y += -gap - cap / 2 + NOTICE_GAP + NOTICE_CAP / 2  # from the next word line's centre
    for line in st.notice:
        c.text(line, 0.5, y, NOTICE_CAP, 2 * _half_width(y + NOTICE_CAP / 2), ink)
        y += NOTICE_CAP + NOTICE_GAP
    if label == "explosive" and st.division in ("1.1", "1.2", "1.3"):
        c.text(f"{st.division}{st.compat}", 0.5, cy + cap + 0.03, 0.07, 0.4, ink)


def _draw_number(label: str, c: _Canvas, st: PlacardStyle) -> None:
    ink = INK[label].number
    if label in ("explosive", "blasting-agent") and st.division in ("1.4", "1.5", "1.6"):
        # the division numeral large (>= 64 mm, 172.523-172.525), the letter under it
        c.text(st.division, 0.5, 0.33, 64 * MM * 1.15, 0.42, ink)
        c.text(st.compat, 0.5, 0.49, 0.06, 0.2, ink)
    cy = NUMBER_CY
    while True:  # raise a wide number ("5.1") to where the diamond is wide enough
        allowed = 2 * _half_width(cy + NUMBER_CAP / 2, BORDER_INSET + 0.01)
        width = _font_width(st.number, NUMBER_CAP, c.n)
        if width <= allowed or cy <= 0.74:
            break
        cy -= 0.005
    c.text(st.number, 0.5, cy, NUMBER_CAP, allowed, ink)


def _font_width(s: str, cap: float, n: int) -> float:
    size = max(4, int(round(cap * n / CAP_RATIO)))
    left, _, right, _ = _font(size).getbbox(s, anchor="ls")
    return (right - left + 2) / n


def _print(img: np.ndarray, look: PrintLook, inside: np.ndarray) -> np.ndarray:
    """Apply paper white, ink density, fading, wear and creases to a float RGB image."""
    if replace(look, laminated=False, cut=False) == PrintLook():
        return img
    out = img.copy()
    grey = out.mean(axis=2, keepdims=True)
    out = grey + (out - grey) * look.fade  # faded inks lose saturation
    lo, hi = float(look.ink_black), np.asarray(look.paper, np.float32)
    out = lo + out / 255.0 * (hi - lo)  # black ink is never black, paper never 255
    n = img.shape[0]
    rng = np.random.default_rng([look.seed, 7])
    if look.wear > 0:  # scuffs: small blobs where the ink is rubbed towards the paper
        wear = np.zeros((n, n), np.float32)
        k = max(1, int(look.wear * 4000))
        for x, y, r in zip(
            rng.uniform(0, n, k), rng.uniform(0, n, k), rng.uniform(0.002, 0.01, k) * n, strict=True
        ):
            cv2.circle(wear, (int(x), int(y)), max(1, int(r)), 1.0, -1, cv2.LINE_AA)
        wear = cv2.GaussianBlur(wear, (0, 0), max(1.0, n / 400)) * rng.uniform(0.3, 0.7)
        out = out * (1 - wear[..., None]) + hi * wear[..., None]
    for _ in range(look.creases):  # a fold: a thin light ridge beside a thin shadow
        a = rng.uniform(0, np.pi)
        off = rng.uniform(-0.3, 0.3) * n
        yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
        d = (xx - n / 2) * np.cos(a) + (yy - n / 2) * np.sin(a) - off
        w = max(0.8, n / 300)
        shade = 1 + 0.10 * np.exp(-((d - w) ** 2) / (2 * w * w)) - 0.14 * np.exp(-((d + w) ** 2) / (2 * w * w))
        out = out * shade[..., None]
    out = np.where(inside[..., None], out, img)  # the paper outside the diamond is set below
    return np.clip(out, 0, 255)


def reprint(rgb: np.ndarray, saturation: float, black: float, ink_black: float) -> np.ndarray:
    """A placard image as another printer put it out: colour saturation (HSV S) scaled by
    ``saturation``, and its black ink (grey ``ink_black``, ``PrintLook.ink_black``) moved to
    ``black``, the paper (the image's 99th-percentile grey p) kept: each pixel's grey g goes
    to ``g' = p - (p - g) (p - black) / (p - ink_black)`` and its RGB is scaled by g' / g (hue
    and saturation stay).

    For training data (poibench dataset): real placard crops have median HSV saturation 60
    against 88 rendered, and 5th-percentile grey 73 against 83 rendered (issue 58); a
    ``black`` below the print's own deepens its blacks, above washes them out.

    >>> im = np.zeros((8, 8, 3), np.uint8); im[:4] = (200, 30, 30); im[4:] = (250, 250, 250)
    >>> out = reprint(im, 0.5, 60.0, 0.0)
    >>> int(cv2.cvtColor(out, cv2.COLOR_RGB2HSV)[0, 0, 1]) < int(cv2.cvtColor(im, cv2.COLOR_RGB2HSV)[0, 0, 1])
    True
    """
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV).astype(np.float32)
    hsv[..., 1] *= float(saturation)
    out = cv2.cvtColor(np.clip(np.round(hsv), 0, 255).astype(np.uint8), cv2.COLOR_HSV2RGB).astype(np.float32)
    grey = out.mean(axis=2)
    b0, p = float(ink_black), float(np.percentile(grey, 99))
    if p - b0 > 1.0:
        g = p - (p - grey) * (p - float(black)) / (p - b0)
        out = np.where(grey[..., None] >= 1.0, out * (g / np.maximum(grey, 1.0))[..., None], g[..., None])
    return np.clip(np.round(out), 0, 255).astype(np.uint8)


def _check_label(label: str) -> None:
    if label not in _CANONICAL:
        raise UnknownHazmatLabelError(
            f"unknown hazmat label {label!r}; expected one of {', '.join(HAZMAT_LABELS)}"
        )


def draw_hazmat(label: str, size_px: int = 256, style: PlacardStyle | None = None) -> np.ndarray:
    """RGB uint8 (size_px, size_px, 3) image of the placard for ``label``.

    ``label`` is a canonical label of poi.core.names.HAZMAT_LABELS; anything else raises
    :class:`UnknownHazmatLabelError` naming it. ``style`` (default: the canonical design,
    cleanly printed) picks the variant; see :func:`placard_style`.
    """
    _check_label(label)
    if int(size_px) < MIN_SIZE_PX:
        raise ValueError(f"draw_hazmat: size_px must be >= {MIN_SIZE_PX}, got {size_px}")
    st = _CANONICAL[label] if style is None else style
    unknown = set(st.omit) - set(PARTS)
    if unknown:
        raise ValueError(f"draw_hazmat: omit has {sorted(unknown)}; expected parts of {PARTS}")
    n = int(size_px) * SUPERSAMPLE
    c = _Canvas(n, WHITE)
    _FIELD[label](c, st)
    if "symbol" not in st.omit:
        _draw_symbol(label, c, st)
    if "text" not in st.omit and st.words:
        _draw_words(label, c, st)
    if "number" not in st.omit:
        _draw_number(label, c, st)
    if "border" not in st.omit:
        border = np.round(_diamond(BORDER_INSET) * n).astype(np.int32)
        cv2.polylines(c.img, [border], True, INK[label].border, max(1, int(BORDER_W * n)), cv2.LINE_AA)
    mask = np.zeros((n, n), np.uint8)
    cv2.fillPoly(mask, [np.round(_diamond(0.0) * n).astype(np.int32)], 255, cv2.LINE_AA)
    size = (int(size_px), int(size_px))
    face = cv2.resize(c.img.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    alpha = cv2.resize(mask.astype(np.float32) / 255.0, size, interpolation=cv2.INTER_AREA)[..., None]
    face = _print(face, st.look, alpha[..., 0] > 0)
    small = face * alpha + np.asarray(st.look.paper, np.float32) * (1 - alpha)
    return np.clip(np.round(small), 0, 255).astype(np.uint8)


def placard_sheet(size_px: int = 96, variants: int = 5, halves: int = 2, gap_px: int = 8) -> np.ndarray:
    """RGB uint8 picture of every label (rows, :data:`HAZMAT_LABELS` order, in ``halves`` side by
    side with a white ``gap_px`` between) as its section draws it, then its variants of seeds
    0 .. ``variants`` - 1 (:func:`placard_style`): docs/placards.png, which tests keep current."""
    per_half = -(-len(HAZMAT_LABELS) // halves)
    blank = np.full((size_px, size_px, 3), 255, np.uint8)
    cols = []
    for h in range(halves):
        rows = []
        for k in range(h * per_half, (h + 1) * per_half):
            if k >= len(HAZMAT_LABELS):
                rows.append(np.hstack([blank] * (variants + 1)))
                continue
            label = HAZMAT_LABELS[k]
            tiles = [draw_hazmat(label, size_px)]
            tiles += [draw_hazmat(label, size_px, placard_style(label, seed)) for seed in range(variants)]
            rows.append(np.hstack(tiles))
        cols.append(np.vstack(rows))
        if h < halves - 1:
            cols.append(np.full((per_half * size_px, gap_px, 3), 255, np.uint8))
    return np.hstack(cols)


# The colour a viewer sees at the top of the placard, just inside the border (used by tests
# that check a rendered placard is upright).
TOP_FIELD_RGB: dict[str, Color] = {
    "explosive": ORANGE,
    "blasting-agent": ORANGE,
    "flammable-gas": RED,
    "non-flammable-gas": GREEN,
    "oxygen": YELLOW,
    "fuel-oil": RED,
    "dangerous-when-wet": BLUE,
    "flammable-solid": RED,
    "spontaneously-combustible": WHITE,
    "oxidizer": YELLOW,
    "organic-peroxide": RED,
    "inhalation-hazard": BLACK,
    "poison": WHITE,
    "radioactive": YELLOW,
    "corrosive": WHITE,
    "infectious-substance": WHITE,
}
