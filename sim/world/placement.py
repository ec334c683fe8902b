"""Place the scenario's objects in the maze: explicitly, or at random with spacing rules.

Sizes are for RoboCupRescue Robot League scale (1.2 m cells) and shrink with the
cell size for smaller arenas (RMRC's 0.3 m lanes). Wall-mounted signs hang on
wall faces at a height drawn from ``wall_height_m``; floor objects stand
against a wall so the robot's route through the cell centres passes them; doors
replace an inner wall piece ("in an opening").

RMRC mapping fiducials ([RMRC2025]_ "Mapping", as issue 22 quotes it: half-cylinders "mounted
in pairs facing each other on walls") stand on the floor in pairs on the two opposite walls of
a corridor cell, at the same place along it, each pair one pipe diameter drawn from
250-350 mm (:func:`place_fiducials`). QR sheets (``objects.generate.qr_sheets``) are A4
pages of codes in several module sizes on random wall faces at random heights
(:func:`place_qr_sheets`). Landolt-C targets (``counts.landolt-c``, ``objects.generate.landolt``;
[RMRC2025]_ Sensor Cabinet and Linear Rail Inspect) hang on random wall faces at a height
drawn from ``landolt.height_m``: on the wall itself, on a wooden board, or at the back of a
sensor cabinet (:func:`place_landolt`); each ring's gap direction is drawn from the seed.

References
----------
Full entries in docs/SOURCES.md.

.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from maze_assets.landolt import card_side_mm
from maze_assets.models import (
    ARENA_SIZE_M,
    BACKING_M,
    BOARD_THICKNESS_M,
    CRATE_WALL_M,
    DOOR_PANELS,
    FIDUCIAL_DIAMETER_M,
    FIDUCIAL_LENGTH_M,
    LANDOLT_BOARD_M,
    LANDOLT_CABINET_M,
    RAMP_RUN_SIDES,
    RAMP_SLOPE_DEG,
    RAMP_WIDTH_SIDES,
    crate_inner_m,
    door_height_m,
    door_panel_face_m,
    holder_standoff_m,
    qr_side_m,
)
from maze_assets.objects import PlacedObject, fiducial_text
from poi.core.landolt import (
    DEFAULT_N_RINGS,
    LandoltSpec,
    orientation_text,
    parse_orientation_text,
    random_orientations,
)
from poi.core.loader import number
from poi.core.names import ARENA_TYPES, HAZMAT_LABELS, MAPPING_TYPES, RESCUE_TYPES, TARGET_TYPES, TYPES


@dataclass(kw_only=True)
class WallSpot:
    """A spot on a wall face: the face of cell (row, col) on ``side`` (n/e/s/w)."""

    cell: tuple[int, int]
    side: Literal["n", "e", "s", "w"]
    height_m: float = 1.0
    offset_m: float = 0.0  # along the wall from the face centre, positive = left when facing the wall


@dataclass(kw_only=True)
class ObjectSpec:
    """An explicitly placed object: either ``at`` a wall spot or at ``position``."""

    type: str
    text: str = ""
    at: WallSpot | None = None
    position: tuple[float, float, float] | None = None  # world frame, metres
    yaw_deg: float = 0.0
    mount: Literal["wall", "floor", "opening"] | None = None
    size_m: float | None = None
    temperature_c: float | None = None

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"unknown type {self.type!r}; expected one of {', '.join(TYPES)}")
        if (self.at is None) == (self.position is None):
            raise ValueError("give exactly one of 'at' (a wall spot) or 'position'")
        if self.type == "landolt-c" and self.text:  # empty: the gap directions are drawn from the seed
            rings = parse_orientation_text(self.text)
            if sorted(rings) != list(range(1, DEFAULT_N_RINGS + 1)):
                raise ValueError(
                    f"text {self.text!r}: a landolt-c target's text gives rings 1 to {DEFAULT_N_RINGS} once each, "
                    'e.g. "1:E 2:N 3:NE 4:S 5:W"'
                )


DEFAULT_COUNTS: dict[str, int] = {
    "hazmat": 5,
    "qr": 4,
    "door": 1,
    "valve": 1,
    "baby-doll": 1,
    "fire-extinguisher": 1,
    "exit-sign": 1,
    "fire-extinguisher-sign": 1,
    "heat-source": 1,
}


@dataclass(kw_only=True)
class QrSheets:
    """A4 pages of QR codes ([RMRC2025]_, as issue 22 quotes it: "A4 pages of codes in several
    sizes, stapled at random locations and heights, matte"), placed by sim/world/placement.py.

    ``count`` pages, each on a random wall face with its centre at a height drawn from
    ``height_m``; every page carries one code per entry of ``module_mm`` (the side of one
    module, millimetres; the finals' code has 2 mm modules), all encoding the page's name and
    their module size ("Chart F 2mm").
    """

    count: int = number(0, lo=0, hi=100)
    module_mm: tuple[float, ...] = (5.0, 3.0, 2.0)
    height_m: tuple[float, float] = (0.25, 1.0)

    def __post_init__(self) -> None:
        if not self.module_mm or any(not 0.5 <= m <= 20 for m in self.module_mm):
            raise ValueError(
                f"module_mm: expected one or more module sizes in 0.5..20 mm, got {list(self.module_mm)}"
            )
        if len(set(self.module_mm)) != len(self.module_mm):
            raise ValueError(f"module_mm: expected each module size once, got {list(self.module_mm)}")
        lo, hi = self.height_m
        if not 0.0 <= lo <= hi:
            raise ValueError(f"height_m: expected [low, high] with 0 <= low <= high, got {lo}, {hi}")


@dataclass(kw_only=True)
class LandoltTargets:
    """Where the ``counts.landolt-c`` targets go (sim/world/placement.py ``place_landolt``): ``cabinets``
    of them at the back of a sensor cabinet, ``boards`` on a wooden board, the rest on the wall
    itself, each with its centre at a height drawn from ``height_m`` and its gap directions
    drawn from the seed ([RMRC2025]_ Sensor Cabinet and Linear Rail Inspect; docs/RULES.md
    "Landolt-C")."""

    cabinets: int = number(0, lo=0, hi=100)
    boards: int = number(0, lo=0, hi=100)
    height_m: tuple[float, float] = (0.3, 1.0)

    def __post_init__(self) -> None:
        lo, hi = self.height_m
        if not 0.0 < lo <= hi:
            raise ValueError(f"height_m: expected [low, high] with 0 < low <= high, got {lo}, {hi}")


GENERATED_TYPES: tuple[str, ...] = RESCUE_TYPES + MAPPING_TYPES + TARGET_TYPES


@dataclass(kw_only=True)
class ObjectsGenerate:
    """Random placement: how many of each type, and the spacing rules.

    ``counts.fiducial`` places RMRC mapping fiducials in pairs facing each other across a
    cell (so it must be even; sim/world/placement.py); ``qr_sheets`` adds pages of QR codes;
    ``counts.landolt-c`` places Landolt-C targets, ``landolt`` says how many sit in a sensor
    cabinet or on a board and at what heights.
    """

    counts: dict[str, int] = field(default_factory=lambda: dict(DEFAULT_COUNTS))
    min_spacing_m: float = 0.6
    wall_height_m: tuple[float, float] = (0.2, 1.5)
    labels: list[str] | None = None  # hazmat labels to draw from (default: all 16)
    qr_texts: list[str] | None = None  # QR contents to use in order (default: "Chart A", ...)
    # share of the placards laid face up on the floor in front of their wall (sim.world.placement.
    # lay_placards_on_floor); the dataset generator lays some there, trials keep them on walls
    hazmat_on_floor: float = number(0.0, lo=0.0, hi=1.0)
    # wall placards moved onto doors, one per door face (sim.world.placement.hang_placards_on_doors)
    hazmat_on_doors: int = number(0, lo=0, hi=100)
    # wall placards moved into open crates on the floor (sim.world.placement.put_placards_in_crates)
    hazmat_in_crates: int = number(0, lo=0, hi=100)
    # wall placards laid on wooden ramps against their walls (sim.world.placement.lay_placards_on_ramps)
    hazmat_on_ramps: int = number(0, lo=0, hi=100)
    # boards of a wall placard with a QR code and a Landolt-C card beside it
    # (sim.world.placement.hang_placard_boards)
    hazmat_on_boards: int = number(0, lo=0, hi=100)
    qr_sheets: QrSheets | None = None
    landolt: LandoltTargets | None = None  # where the landolt-c targets go (default: all on walls)

    def __post_init__(self) -> None:
        for t, n in self.counts.items():
            if t not in GENERATED_TYPES:
                where = " (the arena's types are laid out by 'arena')" if t in TYPES else ""
                raise ValueError(
                    f"counts: unknown type {t!r}{where}; expected one of {', '.join(GENERATED_TYPES)}"
                )
            if n < 0:
                raise ValueError(f"counts.{t}: must be >= 0, got {n}")
        if self.counts.get("fiducial", 0) % 2:
            raise ValueError(
                f"counts.fiducial: fiducials are mounted in pairs facing each other; expected an even number, "
                f"got {self.counts['fiducial']}"
            )
        unknown = sorted(set(self.labels or ()) - set(HAZMAT_LABELS))
        if unknown:  # checked here, where the loader names the file and line, not when the world is built
            named, known = ", ".join(map(repr, unknown)), ", ".join(HAZMAT_LABELS)
            raise ValueError(f"labels: unknown hazmat label {named}; expected one of {known}")
        lo, hi = self.wall_height_m
        if not 0.0 <= lo <= hi:
            raise ValueError(f"wall_height_m: expected [low, high] with 0 <= low <= high, got {lo}, {hi}")
        if self.landolt is not None:
            n = self.counts.get("landolt-c", 0)
            held = self.landolt.cabinets + self.landolt.boards
            if held > n:
                raise ValueError(
                    f"landolt: {self.landolt.cabinets} cabinets + {self.landolt.boards} boards need "
                    f"{held} targets, but counts.landolt-c is {n}"
                )


@dataclass(kw_only=True)
class ObjectsSpec:
    generate: ObjectsGenerate | None = field(default_factory=ObjectsGenerate)
    explicit: list[ObjectSpec] = field(default_factory=list)


RRL_CELL_M = 1.2

# Characteristic sizes at RRL scale, metres (see sim/objects.py for their meaning).
SIZE_AT_RRL_M: dict[str, float] = {
    "hazmat": 0.25,
    "qr": 0.20,
    "exit-sign": 0.30,
    "fire-extinguisher-sign": 0.20,
    "valve": 0.25,
    "fire-extinguisher": 0.50,
    "baby-doll": 0.35,
    "heat-source": 0.30,
    "door": 0.80,
}
FLOOR_TYPES = ("fire-extinguisher", "baby-doll", "heat-source")
VALVE_PIPE_M = 0.12  # wheel centre stands this far off the wall at RRL scale
BODY_TEMPERATURE_C = 37.0
HEAT_SOURCE_C = (60.0, 90.0)
QR_PREFIX = "Chart "


class PlacementError(ValueError):
    """Objects that do not fit the maze."""


def _scale(maze) -> float:
    return maze.settings.cell_size_m / RRL_CELL_M


def default_size(type_: str, maze) -> float:
    """A type's characteristic size in ``maze``: RRL sizes scaled with the cell size; the
    arena's pillars and ball keep their real size (maze_assets.models.ARENA_SIZE_M)."""
    if type_ in ARENA_SIZE_M:
        return ARENA_SIZE_M[type_]
    if type_ == "fiducial":  # a real pipe: the middle of the rulebook's 250-350 mm
        return sum(FIDUCIAL_DIAMETER_M) / 2
    if type_ == "landolt-c":  # a real print: the card of the rulebook's ring sizes (poi/core/landolt.py)
        return card_side_mm(LandoltSpec()) / 1000
    return SIZE_AT_RRL_M[type_] * _scale(maze)


def qr_text(i: int) -> str:
    """Competition-style QR contents: 'Chart A' .. 'Chart Z', then 'Chart AA', ...

    >>> [qr_text(i) for i in (0, 1, 25, 26, 27)]
    ['Chart A', 'Chart B', 'Chart Z', 'Chart AA', 'Chart AB']
    """
    letters = ""
    n = i
    while True:
        letters = chr(ord("A") + n % 26) + letters
        n = n // 26 - 1
        if n < 0:
            break
    return QR_PREFIX + letters


def _yaw(normal_xy: np.ndarray) -> float:
    return float(np.arctan2(normal_xy[1], normal_xy[0]))


def _along(normal_xy: np.ndarray) -> np.ndarray:
    """Unit vector along a wall face, to the left of someone facing the wall."""
    n = np.asarray(normal_xy, dtype=float)
    # facing the wall means looking along -n; left of -n is rot(+90)(-n) = (n_y, -n_x)
    return np.array([n[1], -n[0]])


def object_at_face(
    obj_id: int,
    type_: str,
    text: str,
    face,
    height_m: float,
    offset_m: float,
    size_m: float,
    maze,
    temperature_c: float | None,
    holder: str | None = None,
) -> PlacedObject:
    """Build a PlacedObject on/against a wall face (see module doc for each type's reference point);
    ``holder`` is a Landolt-C target's board or cabinet (None: on the wall)."""
    n = np.asarray(face.normal_xy, dtype=float)
    base = np.asarray(face.center_xy, dtype=float) + _along(n) * offset_m
    s = _scale(maze)
    if type_ in ("hazmat", "qr", "exit-sign", "fire-extinguisher-sign"):
        pos = np.array([base[0], base[1], height_m])
        mount = "wall"
    elif type_ == "valve":
        xy = base + n * VALVE_PIPE_M * s
        pos = np.array([xy[0], xy[1], height_m])
        mount = "wall"
    elif type_ == "fire-extinguisher":
        xy = base + n * (0.09 * s + 0.02 * s)
        pos = np.array([xy[0], xy[1], size_m / 2.0])
        mount = "floor"
    elif type_ == "baby-doll":
        xy = base + n * (0.10 * s)
        pos = np.array([xy[0], xy[1], 0.06 * s])
        mount = "floor"
    elif type_ == "heat-source":
        xy = base + n * (0.10 * s)
        pos = np.array([xy[0], xy[1], 0.5 * size_m])
        mount = "floor"
    elif type_ == "fiducial":  # standing on the floor, its cut face on the wall face
        pos = np.array([base[0], base[1], FIDUCIAL_LENGTH_M / 2])
        mount = "wall"
    elif type_ == "landolt-c":  # the card's centre; a holder puts it out from the wall
        xy = base + n * holder_standoff_m(holder)
        pos = np.array([xy[0], xy[1], height_m])
        mount = "wall"
    else:
        raise PlacementError(f"object {obj_id}: type {type_!r} is not placed on a wall face")
    return PlacedObject(
        id=obj_id,
        type=type_,
        text=text,
        position=pos,
        yaw=_yaw(n),
        mount=mount,
        size_m=size_m,
        temperature_c=temperature_c,
        wall=face.wall,
        holder=holder,
    )


def landolt_extent_m(holder: str | None) -> tuple[float, float]:
    """(width, height) a Landolt-C target takes on its wall: its card, board or cabinet."""
    if holder == "board":
        return LANDOLT_BOARD_M[0], LANDOLT_BOARD_M[1]
    if holder == "cabinet":
        return LANDOLT_CABINET_M[0], LANDOLT_CABINET_M[1]
    side = default_size("landolt-c", None)
    return side, side


def landolt_text(rng: np.random.Generator) -> str:
    """A target's truth text: a gap direction per ring drawn from ``rng`` (poi.core.landolt)."""
    spec = LandoltSpec()
    return orientation_text(random_orientations(spec.n_rings, rng))


def place_landolt(
    n: int,
    opts: LandoltTargets,
    maze,
    rng: np.random.Generator,
    objects: list[PlacedObject],
    min_spacing_m: float,
) -> None:
    """Append ``n`` Landolt-C targets to ``objects``: ``opts.cabinets`` in sensor cabinets, then
    ``opts.boards`` on boards, the rest on the wall (module docstring).

    Each takes a random wall face long enough for its holder, a random place along it, a height
    in ``opts.height_m`` (kept on the wall), and keeps ``min_spacing_m`` from every object
    placed before; its text is its rings' gap directions (:func:`landolt_text`).
    """
    holders = ["cabinet"] * opts.cabinets + ["board"] * opts.boards + [None] * (n - opts.cabinets - opts.boards)
    wall_h = maze.settings.wall_height_m
    size = default_size("landolt-c", maze)
    for k, holder in enumerate(holders):
        w, h = landolt_extent_m(holder)
        faces = [f for f in maze.wall_faces() if f.length_m >= w + 0.1]
        lo, hi = opts.height_m
        hi = min(hi, wall_h - h / 2 - 0.01)
        lo = max(lo, h / 2 + 0.01)
        if not faces or lo > hi:
            raise PlacementError(
                f"landolt: a {holder or 'wall'} target ({w:.2f} x {h:.2f} m) does not fit this maze's walls "
                f"at heights {opts.height_m[0]:g}-{opts.height_m[1]:g} m"
            )
        text = landolt_text(rng)
        for _attempt in range(400):
            face = faces[int(rng.integers(len(faces)))]
            margin = max(0.0, 0.5 * face.length_m - w / 2 - 0.05)
            offset = float(rng.uniform(-margin, margin))
            height = float(rng.uniform(lo, hi))
            cand = object_at_face(len(objects), "landolt-c", text, face, height, offset, size, maze, None, holder)
            if holder == "board":
                cand.holder_m = (-w / 2, w / 2, -h / 2, h / 2)
            if face.wall in {o.wall for o in objects if o.type in ("door", "fiducial")}:
                continue
            if all(np.linalg.norm(cand.position - o.position) >= min_spacing_m for o in objects):
                objects.append(cand)
                break
        else:
            raise PlacementError(
                f"landolt: could not place target {k + 1} of {n} with min_spacing_m={min_spacing_m}: "
                "the maze is too small"
            )


def door_in_wall(obj_id: int, segment, maze, size_m: float) -> PlacedObject:
    """A door replacing wall piece ``segment``; reference point = leaf centre on the wall line."""
    p0 = np.array([segment.x0, segment.y0])
    p1 = np.array([segment.x1, segment.y1])
    mid = 0.5 * (p0 + p1)
    d = (p1 - p0) / np.linalg.norm(p1 - p0)
    normal = np.array([-d[1], d[0]])
    leaf_h = min(2.0, 0.9 * maze.settings.wall_height_m)
    return PlacedObject(
        id=obj_id,
        type="door",
        position=np.array([mid[0], mid[1], leaf_h / 2.0]),
        yaw=_yaw(normal),
        mount="opening",
        size_m=min(size_m, 0.8 * maze.settings.cell_size_m),
        wall=segment.name,
    )


def _temperature(type_: str, rng: np.random.Generator) -> float | None:
    if type_ == "baby-doll":
        return BODY_TEMPERATURE_C
    if type_ == "heat-source":
        return float(rng.uniform(*HEAT_SOURCE_C))
    return None


def _explicit(spec: ObjectSpec, obj_id: int, maze, rng) -> PlacedObject:
    size = spec.size_m if spec.size_m is not None else default_size(spec.type, maze)
    temp = spec.temperature_c if spec.temperature_c is not None else _temperature(spec.type, rng)
    text = spec.text
    if spec.type == "landolt-c" and not text:
        text = landolt_text(rng)
    if spec.position is not None:
        mount = spec.mount or ("floor" if spec.type in FLOOR_TYPES + ARENA_TYPES else "wall")
        return PlacedObject(
            id=obj_id,
            type=spec.type,
            text=text,
            position=np.array(spec.position, dtype=float),
            yaw=np.deg2rad(spec.yaw_deg),
            mount=mount,
            size_m=size,
            temperature_c=temp,
        )
    r, c = spec.at.cell
    if spec.type == "door":
        for seg in maze.wall_segments():
            for face in maze.wall_faces():
                if face.wall == seg.name and tuple(face.cell) == (r, c) and _side(face) == spec.at.side:
                    return door_in_wall(obj_id, seg, maze, size)
        raise PlacementError(f"object {obj_id}: no wall on side {spec.at.side!r} of cell ({r}, {c})")
    for face in maze.wall_faces():
        if tuple(face.cell) == (r, c) and _side(face) == spec.at.side:
            return object_at_face(
                obj_id, spec.type, text, face, spec.at.height_m, spec.at.offset_m, size, maze, temp
            )
    raise PlacementError(f"object {obj_id}: no wall on side {spec.at.side!r} of cell ({r}, {c})")


def _side(face) -> str:
    """Which side of its cell a face is on, from its inward normal."""
    nx, ny = face.normal_xy
    if abs(nx) > abs(ny):
        return "w" if nx > 0 else "e"
    return "s" if ny > 0 else "n"


def _texts(gen: ObjectsGenerate, n_hazmat: int, n_qr: int, rng) -> tuple[list[str], list[str]]:
    labels = list(gen.labels) if gen.labels else list(HAZMAT_LABELS)
    # hazmat labels: a shuffled cycle through the allowed labels, so labels repeat only when needed
    order: list[str] = []
    while len(order) < n_hazmat:
        order.extend(labels[i] for i in rng.permutation(len(labels)))
    qrs = list(gen.qr_texts) if gen.qr_texts else [qr_text(i) for i in range(n_qr)]
    if len(qrs) < n_qr:
        raise PlacementError(f"objects.generate.qr_texts: {len(qrs)} texts for {n_qr} QR codes")
    return order[:n_hazmat], qrs[:n_qr]


# A corridor between a pair of fiducials keeps at least this much clear width (a robot passes).
FIDUCIAL_CLEAR_M = 0.3
A4_M = (0.210, 0.297)  # width, height of a portrait A4 page
PAGE_MARGIN_M = 0.008


def _opposite_pairs(maze) -> list[tuple[object, object]]:
    """(face, face) pairs on opposite sides of the same cell (n/s or e/w): a corridor."""
    by_cell: dict[tuple[int, int], dict[str, object]] = {}
    for f in maze.wall_faces():
        by_cell.setdefault(tuple(f.cell), {})[_side(f)] = f
    pairs = []
    for cell in sorted(by_cell):
        sides = by_cell[cell]
        for a, b in (("n", "s"), ("w", "e")):
            if a in sides and b in sides:
                pairs.append((sides[a], sides[b]))
    return pairs


def place_fiducials(
    n: int, maze, rng: np.random.Generator, objects: list[PlacedObject], min_spacing_m: float
) -> None:
    """Append ``n`` fiducials (n even) to ``objects``: pairs facing each other across a cell.

    Each pair takes a random corridor cell (walls on two opposite sides) no other pair uses,
    a diameter drawn uniformly from ``FIDUCIAL_DIAMETER_M`` and a random place along the
    walls, the same for both; a pair keeps ``min_spacing_m`` from every object placed before.
    """
    pairs = _opposite_pairs(maze)
    clear = maze.settings.cell_size_m - maze.settings.wall_thickness_m
    if n and clear < FIDUCIAL_DIAMETER_M[1] + FIDUCIAL_CLEAR_M:
        raise PlacementError(
            f"counts.fiducial: a pair of fiducials ({FIDUCIAL_DIAMETER_M[1] * 1000:.0f} mm pipes) needs cells at "
            f"least {FIDUCIAL_DIAMETER_M[1] + FIDUCIAL_CLEAR_M + maze.settings.wall_thickness_m:.2f} m wide; "
            f"this maze's are {maze.settings.cell_size_m:g} m"
        )
    used: set[tuple[int, int]] = set()
    placed = 0
    order = rng.permutation(len(pairs)) if pairs else []
    for i in order:
        if placed == n:
            break
        fa, fb = pairs[int(i)]
        if tuple(fa.cell) in used:
            continue
        d = float(rng.uniform(*FIDUCIAL_DIAMETER_M))
        margin = max(0.0, 0.5 * fa.length_m - d / 2 - 0.02)
        u = float(rng.uniform(-margin, margin))  # along fa's "left"; fb faces it, so its left is the other way
        a = object_at_face(len(objects), "fiducial", fiducial_text(d), fa, 0.0, u, d, maze, None)
        b = object_at_face(len(objects) + 1, "fiducial", fiducial_text(d), fb, 0.0, -u, d, maze, None)
        if any(np.linalg.norm(p.position - o.position) < min_spacing_m for p in (a, b) for o in objects):
            continue
        objects += [a, b]
        used.add(tuple(fa.cell))
        placed += 2
    if placed < n:
        raise PlacementError(
            f"counts.fiducial: only {placed} of {n} fiducials fit: the maze has {len(pairs)} cells with walls on "
            "two opposite sides"
        )


def page_layout(texts: list[str], module_m: list[float]) -> list[tuple[float, float, float]]:
    """Where each code sits on a portrait A4 page: (u, v, side) of its centre from the page's
    centre (u to the viewer's right, v up) and its side, metres.

    Codes are laid out in rows from the top left, largest first as given, with
    ``PAGE_MARGIN_M`` round the page; a page that cannot hold them all is an error.

    >>> [tuple(round(x, 3) for x in c) for c in page_layout(["Chart A 5mm", "Chart A 2mm"], [0.005, 0.002])]
    [(-0.017, 0.06, 0.16), (-0.065, -0.052, 0.064)]
    """
    W, H = A4_M
    sides = [qr_side_m(t, m) for t, m in zip(texts, module_m, strict=True)]
    out = []
    x, y, row_h = PAGE_MARGIN_M, PAGE_MARGIN_M, 0.0  # from the top-left corner, y down
    for t, side in zip(texts, sides, strict=True):
        if x + side > W - PAGE_MARGIN_M + 1e-9 and x > PAGE_MARGIN_M:
            x, y, row_h = PAGE_MARGIN_M, y + row_h, 0.0
        if x + side > W - PAGE_MARGIN_M + 1e-9 or y + side > H - PAGE_MARGIN_M + 1e-9:
            raise PlacementError(
                f"qr_sheets.module_mm: the code {t!r} ({side * 1000:.0f} mm) does not fit on an A4 page"
            )
        out.append((x + side / 2 - W / 2, H / 2 - (y + side / 2), side))
        x += side
        row_h = max(row_h, side)
    return out


def place_qr_sheets(
    sheets: QrSheets,
    first_letter: int,
    maze,
    rng: np.random.Generator,
    objects: list[PlacedObject],
    min_spacing_m: float,
) -> None:
    """Append the codes of ``sheets.count`` A4 pages to ``objects`` (module docstring).

    Page ``k`` is named by :func:`qr_text` (first_letter + k) and each of its codes reads
    "<name> <module>mm"; its first code carries the page (``page_m``) so the page is drawn.
    A page goes on a random wall face, centred at a random place along it and a random height
    in ``sheets.height_m`` (kept on the wall), ``min_spacing_m`` from every object before it.
    """
    W, H = A4_M
    faces = [f for f in maze.wall_faces() if f.length_m >= W]
    wall_h = maze.settings.wall_height_m
    modules = [m / 1000 for m in sheets.module_mm]
    for k in range(sheets.count):
        name = qr_text(first_letter + k)
        texts = [f"{name} {m:g}mm" for m in sheets.module_mm]
        layout = page_layout(texts, modules)
        for _attempt in range(400):
            face = faces[int(rng.integers(len(faces)))]
            margin = max(0.0, 0.5 * face.length_m - W / 2 - 0.02)
            offset = float(rng.uniform(-margin, margin))
            lo, hi = sheets.height_m
            hi = min(hi, wall_h - H / 2 - 0.01)
            lo = min(max(lo, H / 2 + 0.01), hi)
            height = float(rng.uniform(lo, hi))
            centre = object_at_face(-1, "qr", texts[0], face, height, offset, 0.2, maze, None)
            if any(np.linalg.norm(centre.position - o.position) < min_spacing_m for o in objects):
                continue
            right = -_along(np.asarray(face.normal_xy, float))  # the viewer's right on this face
            for j, ((u, v, side), text, m) in enumerate(zip(layout, texts, modules, strict=True)):
                pos = centre.position + np.array([right[0] * u, right[1] * u, v])
                page = (-W / 2 - u, W / 2 - u, -H / 2 - v, H / 2 - v) if j == 0 else None
                objects.append(
                    PlacedObject(
                        id=len(objects),
                        type="qr",
                        text=text,
                        position=pos,
                        yaw=centre.yaw,
                        mount="wall",
                        size_m=side,
                        wall=face.wall,
                        page_m=page,
                        module_m=m,
                    )
                )
            break
        else:
            raise PlacementError(
                f"qr_sheets: could not place page {k + 1} of {sheets.count} with min_spacing_m={min_spacing_m}: "
                "the maze is too small"
            )


UPRIGHT_SHARE = 0.5  # placards hung upright (within a few degrees); the rest at any angle
UPRIGHT_SD_DEG = 3.0


def assign_placard_looks(objects: list[PlacedObject], seed: int) -> None:
    """Give every placard a printed variant and an in-plane turn from the scenario seed.

    Half hang upright (sd 3 degrees), half at any angle, as placards are fixed in real
    arenas. Drawn from a seed sequence of the scenario seed and the object's id, so the
    random stream that places objects is untouched (maze_assets.hazmat.placard_style
    turns the look seed into the variant).
    """
    for o in objects:
        if o.type != "hazmat" or o.look_seed is not None:
            continue
        o.look_seed = int(np.random.SeedSequence([int(seed), o.id, 172]).generate_state(1)[0] & 0x7FFFFFFF)
        rng = np.random.default_rng([o.look_seed, 2])
        if rng.random() < UPRIGHT_SHARE:
            o.roll = float(np.deg2rad(rng.normal(0.0, UPRIGHT_SD_DEG)))
        else:
            o.roll = float(rng.uniform(-np.pi, np.pi))


FLOOR_PLACARD_OUT_M = (0.05, 0.2)  # gap between a floor placard and its wall (RRL scale)


def lay_placards_on_floor(objects: list[PlacedObject], share: float, seed: int, maze) -> None:
    """Lay about ``share`` of the wall placards face up on the floor in front of their wall.

    Real arenas have placards on floors and ramps as well as on walls. Each placard is
    chosen, and its distance out from the wall drawn, from a seed sequence of the scenario
    seed and its id, so the stream that placed the objects is untouched; its position along
    the wall and its in-plane turn stay. The reference point is the face's centre, just
    above the floor. One that would lie against another object stays on its wall.
    """
    if not 0.0 <= share <= 1.0:
        raise PlacementError(f"hazmat_on_floor must be in [0, 1], got {share}")
    if share == 0.0:
        return
    s = _scale(maze)
    for o in objects:
        if o.type != "hazmat" or o.mount != "wall":
            continue
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), o.id, 174]))
        if rng.random() >= share:
            continue
        normal = np.array([np.cos(o.yaw), np.sin(o.yaw)])
        out = float(rng.uniform(*FLOOR_PLACARD_OUT_M)) * s + 0.5 * o.size_m
        xy = o.position[:2] + normal * out
        if any(p is not o and np.hypot(*(p.position[:2] - xy)) < o.size_m + 0.1 * s for p in objects):
            continue  # it would lie on or against another object: it stays on the wall
        o.position = np.array([xy[0], xy[1], BACKING_M + 0.001])
        o.mount = "floor"
        o.tilt = float(np.pi / 2)
        o.wall = None


def hang_placards_on_doors(objects: list[PlacedObject], count: int, seed: int, maze) -> None:
    """Move ``count`` wall placards onto doors: on the upper raised panel of a door face.

    Real arenas stick placards on doors as well as on walls. Door faces (two a door) are
    taken in an order drawn from the scenario seed; each takes one placard, the wall
    placards being taken in an order drawn from the same seed, so the stream that placed
    the objects is untouched. The placard keeps its in-plane turn; it is centred on the
    panel, 1 mm proud of it, facing out of the door.
    """
    if count < 0:
        raise PlacementError(f"hazmat_on_doors must be >= 0, got {count}")
    if count == 0:
        return
    doors = [o for o in objects if o.type == "door"]
    wall_placards = [o for o in objects if o.type == "hazmat" and o.mount == "wall"]
    if count > 2 * len(doors):
        raise PlacementError(
            f"hazmat_on_doors: {count} placards need {count} door faces, the maze has {2 * len(doors)} "
            f"({len(doors)} doors)"
        )
    if count > len(wall_placards):
        raise PlacementError(f"hazmat_on_doors: {count} placards asked, only {len(wall_placards)} hang on walls")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 175]))
    faces = [(d, side) for d in doors for side in (1.0, -1.0)]
    face_order = rng.permutation(len(faces))[:count]
    placard_order = rng.permutation(len(wall_placards))[:count]
    H = door_height_m(maze.settings.wall_height_m)
    out = door_panel_face_m(maze.settings.wall_thickness_m) + 0.001
    a, b = DOOR_PANELS[1]
    for fi, pi in zip(face_order, placard_order, strict=True):
        door, side = faces[int(fi)]
        o = wall_placards[int(pi)]
        normal = side * np.array([np.cos(door.yaw), np.sin(door.yaw)])
        xy = door.position[:2] + normal * out
        o.position = np.array([xy[0], xy[1], 0.5 * (a + b) * H])
        o.yaw = float(np.arctan2(normal[1], normal[0]))
        o.size_m = min(o.size_m, (b - a) * H / np.sqrt(2.0))  # the diamond fits the panel
        o.wall = door.wall


def _free_wall_items(objects: list[PlacedObject], type_: str) -> list[PlacedObject]:
    """Items of ``type_`` hanging on a wall by themselves: not on the floor, a door, a holder or
    a QR page (a page's codes stay together)."""
    door_walls = {o.wall for o in objects if o.type == "door"}
    return [
        o
        for o in objects
        if o.type == type_
        and o.mount == "wall"
        and o.holder is None
        and o.module_m is None
        and o.wall is not None
        and o.wall not in door_walls
    ]


def _facing(o: PlacedObject) -> np.ndarray:
    """The unit vector in plan that an item faces along (out of its wall): ``o.yaw``'s."""
    return np.array([np.cos(o.yaw), np.sin(o.yaw)])


def _placards_to_move(objects: list[PlacedObject], count: int, seed: int, stream: int, setting: str) -> list:
    """The wall placards (:func:`_free_wall_items`) in an order drawn from a seed sequence of the
    scenario seed and ``stream``, so that the stream that placed the objects is untouched;
    none for ``count`` 0, a one-line error naming ``setting`` for a negative one."""
    if count < 0:
        raise PlacementError(f"{setting} must be >= 0, got {count}")
    if count == 0:
        return []
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), stream]))
    candidates = _free_wall_items(objects, "hazmat")
    return [candidates[int(i)] for i in rng.permutation(len(candidates))]


def _room_for(o: PlacedObject, objects: list[PlacedObject], centre_xy: np.ndarray, reach_m: float) -> bool:
    """A holder of ``o`` reaching ``reach_m`` (in plan) round ``centre_xy`` keeps clear of every
    other object by half its size."""
    return not any(
        p is not o and np.hypot(*(p.position[:2] - centre_xy)) < reach_m + 0.5 * p.size_m for p in objects
    )


def put_placards_in_crates(objects: list[PlacedObject], count: int, seed: int, maze) -> None:
    """Move up to ``count`` wall placards into open crates standing on the floor against their walls.

    Real arenas hide placards in crates and boxes, where the robot must look in. A crate
    (maze_assets.models.build_holder) stands where the placard hung along its wall, on the
    floor, open towards the corridor; the placard sits on the inside of its back panel,
    centred, and keeps its turn. Placards are taken in an order drawn from a seed sequence of
    the scenario seed, so the stream that placed the objects is untouched; one whose crate
    would stand against another object stays on its wall.
    """
    moved = 0
    for o in _placards_to_move(objects, count, seed, 176, "hazmat_in_crates"):
        if moved == count:
            break
        inner, depth = crate_inner_m(o.size_m)
        t = CRATE_WALL_M
        side = inner + 2 * t
        n = _facing(o)
        wall_xy = o.position[:2]
        centre = wall_xy + n * (t + depth) / 2
        if not _room_for(o, objects, centre, 0.5 * np.hypot(side, depth + t)):
            continue
        z = t + inner / 2
        o.position = np.array([*(wall_xy + n * t), z])
        o.holder = "crate"
        o.holder_m = (float(-side / 2), float(side / 2), float(-z), float(side - z))
        moved += 1


def lay_placards_on_ramps(objects: list[PlacedObject], count: int, seed: int, maze) -> None:
    """Lay up to ``count`` wall placards on wooden ramps leaning against their walls.

    Real arenas have placards on their ramps as well as on floors and walls. A ramp
    (maze_assets.models, ``RAMP_*``) rises ``RAMP_SLOPE_DEG`` towards the wall where the
    placard hung, ``RAMP_RUN_SIDES`` placard sides out from it (at most half the cell's
    clear width) and ``RAMP_WIDTH_SIDES`` wide (at most the wall face); the placard lies face
    up in the middle of its slope, its top edge towards the wall, and keeps its turn.
    Placards are taken in an order drawn from a seed sequence of the scenario seed, so the
    stream that placed the objects is untouched; one whose ramp would lie against another
    object stays on its wall.
    """
    faces = list(maze.wall_faces())
    clear = maze.settings.cell_size_m - maze.settings.wall_thickness_m
    slope = np.radians(RAMP_SLOPE_DEG)
    moved = 0
    for o in _placards_to_move(objects, count, seed, 178, "hazmat_on_ramps"):
        if moved == count:
            break
        face = _face_of(o, faces)
        if face is None:
            continue
        run = min(RAMP_RUN_SIDES * o.size_m, 0.5 * clear)
        width = min(RAMP_WIDTH_SIDES * o.size_m, face.length_m - 0.02)
        n = _facing(o)
        centre = o.position[:2] + n * run / 2
        if width < o.size_m * np.sqrt(2.0) or not _room_for(o, objects, centre, 0.5 * np.hypot(run, width)):
            continue
        along = run / 2 / np.cos(slope)  # the slope's length either side of the placard
        normal = np.array([*(np.sin(slope) * n), np.cos(slope)])
        q = np.array([*centre, run / 2 * np.tan(slope)])
        o.position = q + normal * holder_standoff_m("ramp")
        o.tilt = float(np.pi / 2 - slope)
        o.mount = "floor"
        o.holder = "ramp"
        o.holder_m = (float(-width / 2), float(width / 2), float(-along), float(along))
        o.wall = None
        moved += 1


BOARD_MARGIN_M = 0.03  # round a board's items and between them, at RRL scale


def hang_placard_boards(objects: list[PlacedObject], count: int, seed: int, maze) -> None:
    """Hang up to ``count`` plywood boards, each holding a placard with a QR code and a Landolt-C
    card beside it, as real arenas group their test sheets.

    Each board takes a wall placard, then, while any are left, a QR code and a Landolt-C card
    that hang on walls by themselves, in orders drawn from a seed sequence of the scenario
    seed (the stream that placed the objects is untouched). The board hangs on the placard's
    wall face at the placard's height, moved along the face and down as far as it must to fit;
    its items stand in a row, left to right as listed, ``BOARD_MARGIN_M`` apart and from its
    edges, each in a square as wide as it can turn in (a placard's sheet at 45 degrees), its
    face ``BOARD_THICKNESS_M`` out from the wall. The placard's ``holder_m`` draws the board. A
    board that would cover another object is not hung, and its items stay where they were.
    """
    if count < 0:
        raise PlacementError(f"hazmat_on_boards must be >= 0, got {count}")
    if count == 0:
        return
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 177]))
    pools = {t: _free_wall_items(objects, t) for t in ("hazmat", "qr", "landolt-c")}
    orders = {t: [items[int(i)] for i in rng.permutation(len(items))] for t, items in pools.items()}
    faces = list(maze.wall_faces())
    margin = BOARD_MARGIN_M * _scale(maze)
    wall_h = maze.settings.wall_height_m
    hung = 0
    while hung < count and orders["hazmat"]:
        placard = orders["hazmat"].pop(0)
        group = [placard] + [orders[t][0] for t in ("qr", "landolt-c") if orders[t]]
        spans = [o.size_m * (np.sqrt(2.0) if o.type == "hazmat" else 1.0) for o in group]
        width = sum(spans) + margin * (len(group) + 1)
        height = max(spans) + 2 * margin
        face = _face_of(placard, faces)
        if face is None or face.length_m < width + 0.02 or wall_h < height + 0.02:
            continue
        n = np.asarray(face.normal_xy, float)
        right = -_along(n)
        # the board's centre: along the face where the placard is, kept on the face and the wall
        u_placard = float((placard.position[:2] - np.asarray(face.center_xy, float)) @ right)
        room = 0.5 * (face.length_m - width) - 0.01
        u_centre = float(np.clip(u_placard, -room, room))
        z_centre = float(np.clip(placard.position[2], height / 2 + 0.01, wall_h - height / 2 - 0.01))
        centre = np.asarray(face.center_xy, float) + right * u_centre
        others = [p for p in objects if all(p is not g for g in group)]
        if any(_covers(centre, z_centre, width, height, n, p) for p in others):
            continue
        u = u_centre - width / 2 + margin
        for o, span in zip(group, spans, strict=True):
            xy = centre + right * (u + span / 2 - u_centre) + n * BOARD_THICKNESS_M
            o.position = np.array([xy[0], xy[1], z_centre])
            o.yaw = _yaw(n)
            o.wall = face.wall
            o.mount = "wall"
            o.holder = "board"
            u += span + margin
        left = -(margin + spans[0] / 2)  # the board's left edge from the placard, first in the row
        placard.holder_m = (float(left), float(left + width), float(-height / 2), float(height / 2))
        for t in ("qr", "landolt-c"):
            if orders[t] and orders[t][0] in group:
                orders[t].pop(0)
        hung += 1


def _face_of(o: PlacedObject, faces: list) -> object | None:
    """The wall face ``o`` hangs on: the face of its wall that it faces out of (None: none)."""
    n = _facing(o)
    return next((f for f in faces if f.wall == o.wall and float(np.asarray(f.normal_xy, float) @ n) > 0.99), None)


def _covers(centre_xy: np.ndarray, z: float, width: float, height: float, n: np.ndarray, p: PlacedObject) -> bool:
    """A board ``width`` x ``height`` centred at (``centre_xy``, ``z``) on a face with normal ``n``
    comes within half of object ``p``'s size of it (in the face's plane, and near the wall)."""
    d = p.position - np.array([*centre_xy, z])
    right = -_along(n)
    out = float(d[:2] @ n)
    if out < -0.01 or out > 0.5 + p.size_m:
        return False
    return abs(float(d[:2] @ right)) < width / 2 + p.size_m / 2 and abs(float(d[2])) < height / 2 + p.size_m / 2


def place_objects(spec: ObjectsSpec, maze, rng: np.random.Generator) -> list[PlacedObject]:
    """All objects of a scenario (its ``objects``): the explicit ones, then the generated ones
    (ids in that order)."""
    objects: list[PlacedObject] = []
    for explicit in spec.explicit:
        objects.append(_explicit(explicit, len(objects), maze, rng))
    gen = spec.generate
    if gen is None:
        return objects
    counts = {t: n for t, n in gen.counts.items() if n > 0}
    labels, qrs = _texts(gen, counts.get("hazmat", 0), counts.get("qr", 0), rng)
    faces = list(maze.wall_faces())
    used_walls = {o.wall for o in objects if o.wall}
    s = _scale(maze)
    wall_h = maze.settings.wall_height_m

    def far_enough(p: np.ndarray) -> bool:
        return all(np.linalg.norm(p - o.position) >= gen.min_spacing_m * s for o in objects)

    # doors first: they need a whole inner wall piece, with a cell on each side
    n_doors = counts.pop("door", 0)
    if n_doors:
        # faces counted once per wall (a count per wall piece over all faces grew with the square of
        # the maze: a 64 x 64 maze had not set up after 200 s)
        faces_per_wall = Counter(f.wall for f in faces)
        inner = [seg for seg in maze.wall_segments() if faces_per_wall[seg.name] == 2]
        inner.sort(key=lambda seg: seg.name)
        picks = rng.permutation(len(inner))
        placed = 0
        for i in picks:
            if placed == n_doors:
                break
            seg = inner[i]
            cand = door_in_wall(len(objects), seg, maze, default_size("door", maze))
            if far_enough(cand.position):
                objects.append(cand)
                used_walls.add(seg.name)
                placed += 1
        if placed < n_doors:
            raise PlacementError(f"only {placed} of {n_doors} doors fit: the maze has too few inner walls")

    n_fid = counts.pop("fiducial", 0)
    if n_fid:
        place_fiducials(n_fid, maze, rng, objects, gen.min_spacing_m * s)
        used_walls |= {o.wall for o in objects if o.type == "fiducial"}

    # then everything else, in a fixed type order, each on a random free wall face
    todo: list[tuple[str, str]] = []
    for t in ("hazmat", "qr", "exit-sign", "fire-extinguisher-sign", "valve", *FLOOR_TYPES):
        n = counts.get(t, 0)
        for k in range(n):
            text = labels[k] if t == "hazmat" else qrs[k] if t == "qr" else ""
            todo.append((t, text))
    lo, hi = gen.wall_height_m
    for t, text in todo:
        size = default_size(t, maze)
        for _attempt in range(400):
            face = faces[int(rng.integers(len(faces)))]
            if face.wall in used_walls and t in FLOOR_TYPES:
                continue  # one floor object per wall face piece keeps corridors passable
            half = 0.5 * size if t != "exit-sign" else 0.5 * size
            margin = max(0.0, 0.5 * face.length_m - half - 0.05 * s)
            offset = float(rng.uniform(-margin, margin))
            if t in FLOOR_TYPES:
                height = 0.0
            else:
                top = min(hi * s if s < 1 else hi, wall_h - 0.5 * size - 0.02 * s)
                bottom = max(lo * s if s < 1 else lo, 0.5 * size + 0.02 * s)
                if t == "valve":
                    top = min(top, 1.2 * s)
                if bottom > top:
                    bottom = top = 0.5 * wall_h
                height = float(rng.uniform(bottom, top))
            cand = object_at_face(len(objects), t, text, face, height, offset, size, maze, _temperature(t, rng))
            if face.wall in {o.wall for o in objects if o.type == "door"}:
                continue
            if far_enough(cand.position):
                objects.append(cand)
                used_walls.add(face.wall)
                break
        else:
            raise PlacementError(
                f"objects.generate: could not place a {t} with min_spacing_m={gen.min_spacing_m}: the maze is "
                "too small for the requested counts (lower counts or min_spacing_m, or give a bigger maze)"
            )
    if gen.qr_sheets is not None and gen.qr_sheets.count:
        place_qr_sheets(gen.qr_sheets, len(qrs), maze, rng, objects, gen.min_spacing_m * s)
    n_landolt = counts.get("landolt-c", 0)
    if n_landolt:  # last: a scenario without them draws exactly what it drew before
        place_landolt(n_landolt, gen.landolt or LandoltTargets(), maze, rng, objects, gen.min_spacing_m * s)
    return objects
