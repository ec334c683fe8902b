"""Wall, floor and hall textures: the sheets an arena is built from, and the hall around it.

RoboCupRescue arenas are built from OSB and plywood sheets, some painted. A wall sheet
(:func:`draw_wall`) is OSB (overlapping wood flakes and fine grain), sanded plywood (long
wavy grain) or painted board; each gets the joints between sheets, rows of screw heads and
the marks of use (pencil lines, tape, scuffs low on the wall, now and then soot). The
textures have detail for a stereo depth camera to match (docs/FACTS.md "D435 depth":
low-texture surfaces read 0). Floors (:func:`draw_floor_kind`) are plywood, OSB or painted
grey; :func:`draw_hall_wall` is the hall seen past the arena (blockwork under windows).
All are drawn from an explicit ``rng`` (same generator state, same image) and tile
seamlessly (everything wraps around the edges); sim/world/world.py picks the kinds per scenario.

>>> w = draw_plywood(64, np.random.default_rng(1))
>>> w.shape, w.dtype.name
((64, 64, 3), 'uint8')
>>> bool(np.array_equal(w, draw_plywood(64, np.random.default_rng(1))))
True
"""

from __future__ import annotations

import cv2
import numpy as np

MIN_SIZE_PX = 16
WALL_BASE_RGB = (196, 160, 112)
FLOOR_BASE_RGB = (170, 140, 100)


class SurfaceSizeError(ValueError):
    """A texture size too small to draw."""


def _check(name: str, size_px: int) -> int:
    if int(size_px) < MIN_SIZE_PX:
        raise SurfaceSizeError(f"{name}: size_px must be >= {MIN_SIZE_PX}, got {size_px}")
    return int(size_px)


def _wrap_blur(a: np.ndarray, sigma_x: float, sigma_y: float) -> np.ndarray:
    """Gaussian blur with wrap-around borders (so the texture tiles): blur a 3x3 tiling."""
    h, w = a.shape
    big = cv2.GaussianBlur(np.tile(a, (3, 3)), (0, 0), sigmaX=sigma_x, sigmaY=sigma_y)
    return big[h : 2 * h, w : 2 * w]


def draw_plywood(size_px: int, rng: np.random.Generator) -> np.ndarray:
    """OSB-like wall texture, RGB uint8 (size_px, size_px, 3), tileable."""
    n = _check("draw_plywood", size_px)
    # strands: overlapping thin rotated rectangles, each a slightly different shade,
    # drawn on a 3x3 tiled canvas and cut from its centre so they wrap around the edges
    big = np.zeros((3 * n, 3 * n), np.float32)
    n_strands = int(3.0 * (n / 8) ** 2)
    for _ in range(n_strands):
        cx, cy = rng.uniform(0, n, size=2)
        length = rng.uniform(0.05, 0.14) * n
        width = length * rng.uniform(0.12, 0.3)
        ang = rng.normal(0.0, 25.0)  # strands lie mostly along the sheet's long side
        shade = float(rng.normal(0.0, 0.10))
        # only the copies that reach the centre tile, the one kept: a corner lies within
        # hypot(length, width) / 2 of the strand's centre, and rounding moves it half a pixel
        reach = 0.5 * float(np.hypot(length, width)) + 1.0
        xs = [ox for ox in (0, n, 2 * n) if n - reach <= cx + ox <= 2 * n - 1 + reach]
        ys = [oy for oy in (0, n, 2 * n) if n - reach <= cy + oy <= 2 * n - 1 + reach]
        for ox in xs:
            for oy in ys:
                box = cv2.boxPoints(((cx + ox, cy + oy), (length, width), ang))
                cv2.fillPoly(big, [np.round(box).astype(np.int32)], shade)
    flakes = big[n : 2 * n, n : 2 * n]
    fine = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 0.7, 0.7) * 0.05
    grain = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 3.0, 0.6) * 0.08
    lum = 1.0 + flakes + fine + grain  # (n, n)
    tint = np.array(WALL_BASE_RGB, np.float32) * lum[..., None]
    # darker edges between flakes: a small dark term where the flake shade changes
    edges = np.abs(cv2.Laplacian(np.tile(flakes, (3, 3)), cv2.CV_32F))[n : 2 * n, n : 2 * n]
    tint *= (1.0 - np.clip(0.5 * edges, 0, 0.12))[..., None]
    return np.clip(np.round(tint), 0, 255).astype(np.uint8)


def draw_floor(size_px: int, rng: np.random.Generator) -> np.ndarray:
    """Plywood floor texture, RGB uint8 (size_px, size_px, 3), tileable, grain along x."""
    n = _check("draw_floor", size_px)
    yy = np.arange(n, dtype=np.float32)[:, None]
    xx = np.arange(n, dtype=np.float32)[None, :]
    # growth-ring bands: a sine across y whose phase wanders along x (integer cycles: tiles)
    phase = _wrap_blur(rng.normal(0.0, 1.0, (1, n)).astype(np.float32), n / 8, 0.1) * 12.0
    cycles = int(rng.integers(5, 9))
    bands = np.sin(2 * np.pi * cycles * yy / n + phase + 0.3 * np.sin(2 * np.pi * xx / n)) * 0.06
    streaks = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 4.0, 0.5) * 0.10
    speckle = rng.normal(0.0, 0.035, (n, n)).astype(np.float32)
    lum = 1.0 + bands + streaks + speckle
    img = np.array(FLOOR_BASE_RGB, np.float32) * lum[..., None]
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


# --- arena variety: wall and floor kinds, sheet seams, screws, marks, tape, scuffs ----------

WALL_KINDS = ("osb", "plywood", "painted")
FLOOR_KINDS = ("plywood", "osb", "painted")
SHEET_M = 1.22  # an OSB or plywood sheet is 1.22 m x 2.44 m (4 x 8 ft): one texture tile across
PAINT_RGB = ((232, 232, 226), (196, 198, 196), (52, 54, 58), (120, 140, 160), (170, 60, 50))
PLYWOOD_RGB = (214, 186, 140)
TAPE_RGB = ((160, 164, 170), (40, 90, 190), (25, 25, 25), (230, 200, 40), (230, 230, 225))


def _plywood_sheet(n: int, rng: np.random.Generator, base=PLYWOOD_RGB) -> np.ndarray:
    """Sanded plywood: a light face veneer with long wavy grain along y (the sheet's length)."""
    yy = np.arange(n, dtype=np.float32)[:, None]
    xx = np.arange(n, dtype=np.float32)[None, :]
    phase = _wrap_blur(rng.normal(0.0, 1.0, (n, 1)).astype(np.float32), 0.1, n / 10) * 10.0
    cycles = int(rng.integers(6, 14))
    bands = np.sin(2 * np.pi * cycles * xx / n + phase + 0.4 * np.sin(2 * np.pi * yy / n)) * 0.05
    streaks = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 0.5, 5.0) * 0.08
    lum = 1.0 + bands + streaks + rng.normal(0.0, 0.02, (n, n)).astype(np.float32)
    return np.array(base, np.float32) * lum[..., None]


def _painted(n: int, rng: np.random.Generator, rgb) -> np.ndarray:
    """Roller-painted board: a flat colour with a fine stipple and faint roller streaks."""
    stipple = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 0.8, 0.8) * 0.035
    streaks = _wrap_blur(rng.normal(0.0, 1.0, (n, n)).astype(np.float32), 1.5, 12.0) * 0.03
    return np.array(rgb, np.float32) * (1.0 + stipple + streaks)[..., None]


def _seams_and_screws(img: np.ndarray, rng: np.random.Generator) -> None:
    """A dark gap along the tile's left and top edges (sheets butt there when tiled) and rows
    of screw heads 2 cm in from them and down the middle stud, every 15-25 cm."""
    n = img.shape[0]
    px_m = n / SHEET_M
    gap = max(1, int(round(0.003 * px_m)))
    img[:, :gap] *= 0.45
    img[:gap, :] *= 0.45
    step = rng.uniform(0.15, 0.25) * px_m
    inset = 0.02 * px_m
    r = max(1.0, 0.005 * px_m)
    for x in (inset, n / 2, n - inset):
        for y in np.arange(inset, n, step):
            c = (int(round(x)), int(round(y + rng.normal(0, 0.1 * r))))
            cv2.circle(img, c, int(round(r * 1.4)), tuple(float(v) * 0.95 for v in img[c[1] % n, c[0] % n]), -1)
            cv2.circle(img, c, int(round(r)), (70.0, 70.0, 72.0), -1, cv2.LINE_AA)


def _marks(img: np.ndarray, rng: np.random.Generator) -> None:
    """What an arena's walls collect: pencil lines, tape, scuffs and a sooty patch."""
    n = img.shape[0]
    for _ in range(int(rng.integers(0, 4))):  # pencil lines and ticks
        p0 = rng.uniform(0, n, 2)
        p1 = p0 + rng.normal(0, 0.15 * n, 2)
        cv2.line(img, tuple(int(v) for v in p0), tuple(int(v) for v in p1), (90.0, 88.0, 86.0), 1, cv2.LINE_AA)
    for _ in range(int(rng.choice([0, 0, 1, 1, 2]))):  # tape strips
        colour = TAPE_RGB[int(rng.integers(len(TAPE_RGB)))]
        w = rng.uniform(0.025, 0.05) * n
        c = rng.uniform(0, n, 2)
        length = rng.uniform(0.1, 0.5) * n
        ang = float(rng.choice([0.0, 90.0, rng.uniform(0, 180)]))
        box = cv2.boxPoints(((float(c[0]), float(c[1])), (length, w), ang))
        cv2.fillPoly(img, [np.round(box).astype(np.int32)], tuple(float(v) for v in colour), cv2.LINE_AA)
    scuff = np.zeros((n, n), np.float32)
    for _ in range(int(rng.integers(2, 10))):  # scuffs: short dark smears, low on the wall
        c = (int(rng.uniform(0, n)), int(rng.uniform(0.55, 1.0) * n))
        axes = (int(rng.uniform(0.01, 0.06) * n), int(rng.uniform(0.003, 0.015) * n))
        cv2.ellipse(scuff, c, axes, float(rng.uniform(-20, 20)), 0, 360, float(rng.uniform(0.15, 0.4)), -1)
    scuff = cv2.GaussianBlur(scuff, (0, 0), max(1.0, n / 150))
    if rng.random() < 0.3:  # soot: a large soft dark patch
        soot = np.zeros((n, n), np.float32)
        r = rng.uniform(0.05, 0.15) * n
        c = (int(rng.uniform(0, n)), int(rng.uniform(0, n)))
        cv2.circle(soot, c, int(r), float(rng.uniform(0.3, 0.6)), -1)
        scuff += cv2.GaussianBlur(soot, (0, 0), r / 2)
    img *= (1.0 - np.clip(scuff, 0, 0.8))[..., None]


def draw_wall(kind: str, size_px: int, rng: np.random.Generator) -> np.ndarray:
    """One arena wall sheet, RGB uint8 (size_px, size_px, 3), SHEET_M across.

    ``kind``: ``osb`` (oriented strands, :func:`draw_plywood`), ``plywood`` (sanded veneer)
    or ``painted`` (one of ``PAINT_RGB``); every kind gets seams, screw rows and the marks
    of use. A tile's edges are sheet joints, so the texture tiles as sheets do.
    """
    n = _check("draw_wall", size_px)
    if kind == "osb":
        img = draw_plywood(n, rng).astype(np.float32) * rng.uniform(0.85, 1.1)
    elif kind == "plywood":
        img = _plywood_sheet(n, rng)
    elif kind == "painted":
        img = _painted(n, rng, PAINT_RGB[int(rng.integers(len(PAINT_RGB)))])
    else:
        raise SurfaceSizeError(f"draw_wall: kind must be one of {', '.join(WALL_KINDS)}, got {kind!r}")
    _seams_and_screws(img, rng)
    _marks(img, rng)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def draw_floor_kind(kind: str, size_px: int, rng: np.random.Generator) -> np.ndarray:
    """A floor: ``plywood`` (:func:`draw_floor`), ``osb`` (darker strands) or ``painted`` grey."""
    n = _check("draw_floor_kind", size_px)
    if kind == "plywood":
        return draw_floor(n, rng)
    if kind == "osb":
        img = draw_plywood(n, rng).astype(np.float32) * 0.85
    elif kind == "painted":
        img = _painted(n, rng, (118, 120, 122))
    else:
        raise SurfaceSizeError(f"draw_floor_kind: kind must be one of {', '.join(FLOOR_KINDS)}, got {kind!r}")
    _marks(img, rng)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


# Floors of the halls and buildings real placard photos are taken in (issue 58: on real photos the
# shipped detector missed most placards lying on textured floors seen from above); poibench dataset
# lays them on ``floor_textures`` of its scenarios (sim/world/world.py SceneLooks), trials never.
DATASET_FLOOR_KINDS = ("terrazzo", "concrete", "carpet", "tile")
DATASET_FLOOR_PX = 512  # one tile of SHEET_M: 2.4 mm a texel, for placards seen from close above
TERRAZZO_BASE_RGB = ((205, 200, 190), (180, 178, 172), (150, 140, 128), (215, 205, 185))
TERRAZZO_CHIP_RGB = ((245, 245, 240), (30, 30, 32), (120, 120, 118), (160, 80, 60), (90, 110, 90), (200, 180, 150))
CARPET_RGB = ((40, 50, 90), (90, 90, 92), (110, 80, 60), (120, 40, 45), (50, 80, 60), (150, 140, 120))
TILE_RGB = ((235, 235, 230), (200, 195, 185), (120, 122, 125), (40, 40, 42), (170, 150, 120))


def _terrazzo(n: int, rng: np.random.Generator) -> np.ndarray:
    """Cement with marble chips (5-20 mm, several colours), polished."""
    base = TERRAZZO_BASE_RGB[int(rng.integers(len(TERRAZZO_BASE_RGB)))]
    mottle = _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), 1.0, 1.0) * 0.06
    img = np.array(base, np.float32) * (1.0 + mottle)[..., None]
    palette = [TERRAZZO_CHIP_RGB[int(i)] for i in rng.choice(len(TERRAZZO_CHIP_RGB), size=3, replace=False)]
    px_m = n / SHEET_M
    for _ in range(int(n * n / 60)):
        c = rng.uniform(0, n, 2)
        r = rng.uniform(0.002, 0.01) * px_m
        k = int(rng.integers(6, 9))  # an angular chip: a polygon of k jittered corners
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        rad = r * rng.uniform(0.6, 1.3, k)
        pts = np.stack([np.cos(ang) * rad, np.sin(ang) * rad], 1)
        colour = np.array(palette[int(rng.integers(len(palette)))], np.float32) * rng.uniform(0.85, 1.1)
        for ox in (-n, 0, n):  # drawn at the wrapped positions too: the texture tiles
            for oy in (-n, 0, n):
                poly = np.round((pts + c + (ox, oy)) * 16).astype(np.int32)  # 1/16 px: smooth edges
                cv2.fillPoly(img, [poly], tuple(float(v) for v in colour), cv2.LINE_AA, shift=4)
    return img


def _concrete(n: int, rng: np.random.Generator) -> np.ndarray:
    """Grey concrete: large blotches, fine grain, pores and a saw-cut joint."""
    g = float(rng.uniform(110, 175))
    blotch = _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), n / 12, n / 12) * 4.0
    grain = _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), 0.7, 0.7) * 0.07
    lum = 1.0 + np.clip(blotch, -0.25, 0.25) + grain
    img = np.array((g, g * 0.99, g * 0.96), np.float32) * lum[..., None]
    pores = rng.random((n, n)) < 0.004
    img[pores] *= 0.55
    img[:, :2] *= 0.5  # a joint along one edge: the slab's saw cut where tiles meet
    return img


def _carpet(n: int, rng: np.random.Generator) -> np.ndarray:
    """Tufted carpet: strong fibre noise over a colour, with a faint woven pattern."""
    base = np.array(CARPET_RGB[int(rng.integers(len(CARPET_RGB)))], np.float32) * rng.uniform(0.8, 1.15)
    fibre = _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), 0.6, 0.6) * 0.35
    tone = _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), n / 20, n / 20) * 2.0
    period = int(rng.choice([16, 32, 64]))
    yy, xx = np.mgrid[0:n, 0:n].astype(np.float32)
    weave = 0.06 * np.sign(np.sin(2 * np.pi * xx / period) * np.sin(2 * np.pi * yy / period))
    return base * (1.0 + fibre + np.clip(tone, -0.15, 0.15) + weave)[..., None]


def _tile(n: int, rng: np.random.Generator) -> np.ndarray:
    """Glazed floor tiles (30 or 40 cm in the sheet's 1.22 m: 4 or 3 across) with grout lines;
    sim/world/world.py gives the floor a glossy material with it."""
    across = int(rng.choice([3, 4]))
    base = np.array(TILE_RGB[int(rng.integers(len(TILE_RGB)))], np.float32)
    img = np.empty((n, n, 3), np.float32)
    step = n / across
    for i in range(across):
        for k in range(across):
            shade = base * rng.uniform(0.93, 1.05)
            img[int(i * step) : int((i + 1) * step), int(k * step) : int((k + 1) * step)] = shade
    img *= (1.0 + _wrap_blur(rng.normal(0, 1, (n, n)).astype(np.float32), 1.5, 1.5) * 0.05)[..., None]
    grout = np.array((150, 148, 142) if base.mean() < 100 else (95, 92, 88), np.float32)
    w = max(1, int(round(0.004 * n / SHEET_M * 1.22)))
    for i in range(across):
        a = int(i * step)
        img[a : a + w, :] = grout
        img[:, a : a + w] = grout
    return img


def draw_dataset_floor(kind: str, size_px: int, rng: np.random.Generator) -> np.ndarray:
    """A floor of ``DATASET_FLOOR_KINDS`` (terrazzo, concrete, carpet, glazed tile), RGB uint8
    (size_px, size_px, 3), SHEET_M across, tileable; with the marks of use.

    >>> im = draw_dataset_floor("tile", 64, np.random.default_rng(0))
    >>> im.shape, bool(np.array_equal(im, draw_dataset_floor("tile", 64, np.random.default_rng(0))))
    ((64, 64, 3), True)
    """
    n = _check("draw_dataset_floor", size_px)
    draw = {"terrazzo": _terrazzo, "concrete": _concrete, "carpet": _carpet, "tile": _tile}.get(kind)
    if draw is None:
        raise SurfaceSizeError(
            f"draw_dataset_floor: kind must be one of {', '.join(DATASET_FLOOR_KINDS)}, got {kind!r}"
        )
    img = draw(n, rng)
    _marks(img, rng)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def draw_hall_wall(size_px: int, rng: np.random.Generator) -> np.ndarray:
    """A sports-hall wall seen past the arena: painted blockwork below a band of windows.

    The top third is windows (bright sky-grey panes in dark frames); below, light painted
    concrete blocks (39 x 19 cm) with mortar lines.
    """
    n = _check("draw_hall_wall", size_px)
    img = _painted(n, rng, (200, 200, 194))
    block_h, block_w = n / 24, n / 12
    for k, y in enumerate(np.arange(0, n, block_h)):
        cv2.line(img, (0, int(y)), (n, int(y)), (150.0, 150.0, 146.0), 1)
        off = (k % 2) * block_w / 2
        for x in np.arange(off, n, block_w):
            cv2.line(img, (int(x), int(y)), (int(x), int(y + block_h)), (150.0, 150.0, 146.0), 1)
    top = int(n / 3)
    img[:top] = (60.0, 62.0, 66.0)
    panes = int(rng.integers(3, 6))
    pw = n / panes
    sky = np.array(rng.choice([(225, 232, 240), (190, 200, 210), (250, 250, 250)]), np.float32)
    for i in range(panes):
        x0, x1 = int(i * pw + 0.06 * pw), int((i + 1) * pw - 0.06 * pw)
        img[int(0.05 * top) : int(0.92 * top), x0:x1] = sky
    return np.clip(np.round(img), 0, 255).astype(np.uint8)
