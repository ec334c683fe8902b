"""The maze: square cells with thin walls, read from and written to a text drawing.

File format (``*.maze``, UTF-8)::

    # poibench maze v1
    # any line starting with '#' is a comment
    preset: rrl            # optional "key: value" settings before the drawing
    cell_size_m: 1.2       # overrides the preset
    start: 0 0 east        # start cell (row col) and heading
    +---+---+---+
    |       |   |
    +   +---+   +
    |           |
    +---+---+---+

The drawing has corners ``+`` at every fourth column (0, 4, 8, ...) of every
even drawing line, a horizontal wall ``---`` or an opening ``   `` between two
corners, and on odd lines a vertical wall ``|`` or an opening `` `` at each
corner column with three spaces of cell interior between. The outer boundary
must be closed and every cell reachable from the start cell.

Settings: ``preset`` (``rrl`` or ``rmrc``, default ``rrl``), ``cell_size_m``,
``wall_height_m``, ``wall_thickness_m`` (these override the preset), ``name``,
``start: ROW COL HEADING`` with HEADING one of north/east/south/west or a
number of degrees (counter-clockwise from east). Without ``start`` the robot
starts in cell (0, 0) facing its first open neighbour in the order east,
south, north, west.

World frame (metres, z up): cell (r, c) has its centre at
x = (c + 0.5) s, y = (rows - r - 0.5) s for cell size s; row 0 is the top line
of the drawing (north, +y), column 0 the left (west). Headings are measured
from +x counter-clockwise (east 0, north pi/2).

>>> m = parse_maze('''
... +---+---+
... |       |
... +   +---+
... |       |
... +---+---+
... ''')
>>> (m.rows, m.cols), m.size_m
((2, 2), (2.4, 2.4))
>>> m.cell_center(1, 0).tolist()  # (0.5 * 1.2, (2 - 1 - 0.5) * 1.2)
[0.6, 0.6]
>>> m.open_neighbours(0, 0)
[(0, 1), (1, 0)]
>>> [w.name for w in m.wall_segments()][:3]
['wall_0_0_n', 'wall_0_1_n', 'wall_1_1_n']
"""

from __future__ import annotations

import math
import re
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from maze_assets import MAZES_DIR

FORMAT_HEADER = "# poibench maze v1"
MAZE_SUFFIX = ".maze"
# rows and cols of a maze, drawn in a file or generated: set-up grows with the cells (its route, the
# tracker's drift), a 64 x 64 maze takes about 2 minutes and its route hours of simulated time
MAX_MAZE_SIDE = 64

# Direction name -> (d_row, d_col) in the grid; north is row - 1 (up the drawing).
DIRECTIONS: dict[str, tuple[int, int]] = {"n": (-1, 0), "e": (0, 1), "s": (1, 0), "w": (0, -1)}

# Heading words -> angle from +x counter-clockwise, radians, in (-pi, pi].
HEADINGS_RAD: dict[str, float] = {
    "east": 0.0,
    "north": math.pi / 2,
    "west": math.pi,
    "south": -math.pi / 2,
}

# Preference order when the start heading is not given: face the first open neighbour.
DEFAULT_HEADING_ORDER = ("east", "south", "north", "west")
_HEADING_DIR = {"north": "n", "east": "e", "south": "s", "west": "w"}


class MazeError(ValueError):
    """A maze that is not valid (bad arrays, a cell outside the grid, ...)."""


class MazeFormatError(MazeError):
    """A maze file that cannot be read; the message is ``FILE:LINE:COL: what, expected``."""


@dataclass(kw_only=True, frozen=True)
class MazeSettings:
    """Physical sizes of a maze, metres."""

    cell_size_m: float
    wall_height_m: float
    wall_thickness_m: float

    def __post_init__(self) -> None:
        for key in ("cell_size_m", "wall_height_m", "wall_thickness_m"):
            value = getattr(self, key)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise MazeError(f"MazeSettings.{key}: expected a positive number, got {value!r}")
        if self.wall_thickness_m >= self.cell_size_m / 2:
            raise MazeError(
                f"MazeSettings.wall_thickness_m: {self.wall_thickness_m} m must be less than half "
                f"the cell size ({self.cell_size_m} m)"
            )


PRESETS: dict[str, MazeSettings] = {
    # RoboCupRescue Robot League: 1.2 m lanes, walls 1.2 m high (docs/FACTS.md "Arenas").
    "rrl": MazeSettings(cell_size_m=1.2, wall_height_m=1.2, wall_thickness_m=0.05),
    # RMRC small-robot arena: 30 cm lanes with 300 mm walls (docs/FACTS.md "Arenas").
    "rmrc": MazeSettings(cell_size_m=0.3, wall_height_m=0.3, wall_thickness_m=0.012),
}
DEFAULT_PRESET = "rrl"


@dataclass(kw_only=True, frozen=True)
class WallSegment:
    """One cell-length wall piece on its centre line, from (x0, y0) to (x1, y1).

    The centre line runs between two grid corners; a box of this length leaves a
    ``thickness`` square gap at a corner where two walls meet, so a scene builder
    extends each box by ``thickness / 2`` at both ends (or adds corner posts).
    """

    name: str
    x0: float
    y0: float
    x1: float
    y1: float
    thickness: float

    @property
    def length_m(self) -> float:
        return math.hypot(self.x1 - self.x0, self.y1 - self.y0)

    @property
    def center_xy(self) -> np.ndarray:
        return np.array([(self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2])


@dataclass(kw_only=True, eq=False)
class WallFace:
    """One face of a wall piece seen from a cell inside the maze.

    ``center_xy`` lies on the face (half the wall thickness from the centre line,
    toward the cell); ``normal_xy`` is the unit normal pointing into the cell;
    ``length_m`` is the span clear of any wall meeting it at either end
    (cell size minus wall thickness).
    """

    wall: str
    cell: tuple[int, int]
    center_xy: np.ndarray
    normal_xy: np.ndarray
    length_m: float


@dataclass(kw_only=True, eq=False)
class Opening:
    """A passage between two adjacent cells (no wall between them).

    ``cell_a`` is the north or west cell, ``cell_b`` the south or east one;
    ``center_xy`` is the middle of the missing wall, ``normal_xy`` the unit vector
    from ``cell_a`` toward ``cell_b``; ``width_m`` the clear width (cell size minus
    wall thickness).
    """

    cell_a: tuple[int, int]
    cell_b: tuple[int, int]
    center_xy: np.ndarray
    normal_xy: np.ndarray
    width_m: float


def default_start_heading(h_walls: np.ndarray, v_walls: np.ndarray, cell: tuple[int, int]) -> float:
    """Heading (radians) facing the first open neighbour of ``cell`` (east, south, north, west).

    East (0.0) when the cell has no open neighbour.

    >>> h = np.ones((2, 2), bool); v = np.ones((1, 3), bool); v[0, 1] = False
    >>> default_start_heading(h, v, (0, 0))
    0.0
    >>> default_start_heading(h, v, (0, 1))
    3.141592653589793
    """
    rows, cols = v_walls.shape[0], h_walls.shape[1]
    r, c = cell
    for word in DEFAULT_HEADING_ORDER:
        dr, dc = DIRECTIONS[_HEADING_DIR[word]]
        if (
            0 <= r + dr < rows
            and 0 <= c + dc < cols
            and not _wall_between(h_walls, v_walls, (r, c), (r + dr, c + dc))
        ):
            return HEADINGS_RAD[word]
    return HEADINGS_RAD["east"]


def _wall_between(h_walls: np.ndarray, v_walls: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> bool:
    """True when the grid-adjacent cells a and b are separated by a wall."""
    (ra, ca), (rb, cb) = a, b
    if ca == cb:  # vertically adjacent: the h wall on the north side of the lower cell
        return bool(h_walls[max(ra, rb), ca])
    return bool(v_walls[ra, max(ca, cb)])


@dataclass(kw_only=True, eq=False)
class Maze:
    """A rows x cols grid of square cells with thin walls.

    ``h_walls[r, c]`` (shape (rows+1, cols)) is the wall on the north side of cell
    (r, c) (``h_walls[rows, c]`` the south boundary); ``v_walls[r, c]`` (shape
    (rows, cols+1)) the wall on the west side of cell (r, c) (``v_walls[r, cols]``
    the east boundary). Row 0 is the north (top) row.
    """

    rows: int
    cols: int
    h_walls: np.ndarray
    v_walls: np.ndarray
    settings: MazeSettings
    start_cell: tuple[int, int]
    start_heading_rad: float
    name: str

    def __post_init__(self) -> None:
        if not (isinstance(self.rows, int | np.integer) and isinstance(self.cols, int | np.integer)):
            raise MazeError(f"maze {self.name!r}: rows and cols must be integers")
        if self.rows < 1 or self.cols < 1:
            raise MazeError(f"maze {self.name!r}: expected at least 1x1 cells, got {self.rows}x{self.cols}")
        self.rows, self.cols = int(self.rows), int(self.cols)
        self.h_walls = np.array(self.h_walls, dtype=bool)
        self.v_walls = np.array(self.v_walls, dtype=bool)
        if self.h_walls.shape != (self.rows + 1, self.cols):
            raise MazeError(
                f"maze {self.name!r}: h_walls shape {self.h_walls.shape}, expected {(self.rows + 1, self.cols)}"
            )
        if self.v_walls.shape != (self.rows, self.cols + 1):
            raise MazeError(
                f"maze {self.name!r}: v_walls shape {self.v_walls.shape}, expected {(self.rows, self.cols + 1)}"
            )
        self.start_cell = (int(self.start_cell[0]), int(self.start_cell[1]))
        self.check_cell(self.start_cell)
        self.start_heading_rad = float(self.start_heading_rad)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Maze):
            return NotImplemented
        return (
            self.rows == other.rows
            and self.cols == other.cols
            and np.array_equal(self.h_walls, other.h_walls)
            and np.array_equal(self.v_walls, other.v_walls)
            and self.settings == other.settings
            and self.start_cell == other.start_cell
            and math.isclose(self.start_heading_rad, other.start_heading_rad, abs_tol=1e-12)
            and self.name == other.name
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays: not hashable

    # ----- grid --------------------------------------------------------------------------
    @property
    def cell_size_m(self) -> float:
        return self.settings.cell_size_m

    @property
    def size_m(self) -> tuple[float, float]:
        """(width along x, height along y) in metres."""
        s = self.settings.cell_size_m
        return (self.cols * s, self.rows * s)

    def cells(self) -> list[tuple[int, int]]:
        """All cells in row-major order."""
        return [(r, c) for r in range(self.rows) for c in range(self.cols)]

    def contains(self, cell: tuple[int, int]) -> bool:
        r, c = cell
        return 0 <= r < self.rows and 0 <= c < self.cols

    def check_cell(self, cell: tuple[int, int]) -> None:
        """Raise MazeError when ``cell`` is outside the grid."""
        if not self.contains(cell):
            raise MazeError(
                f"maze {self.name!r}: cell {tuple(cell)} is outside the maze "
                f"(rows 0..{self.rows - 1}, cols 0..{self.cols - 1})"
            )

    def cell_center(self, r: int, c: int) -> np.ndarray:
        """World (x, y) of the centre of cell (r, c): ((c + 0.5) s, (rows - r - 0.5) s)."""
        self.check_cell((r, c))
        s = self.settings.cell_size_m
        return np.array([(c + 0.5) * s, (self.rows - r - 0.5) * s])

    def cell_at(self, x: float, y: float) -> tuple[int, int] | None:
        """The cell containing world point (x, y), or None outside the maze."""
        s = self.settings.cell_size_m
        c = math.floor(x / s)
        r = self.rows - 1 - math.floor(y / s)
        return (r, c) if self.contains((r, c)) else None

    @property
    def start_xy(self) -> np.ndarray:
        return self.cell_center(*self.start_cell)

    # ----- connectivity ------------------------------------------------------------------
    def is_open(self, a: tuple[int, int], b: tuple[int, int]) -> bool:
        """True when a and b are adjacent cells with no wall between them."""
        self.check_cell(a)
        self.check_cell(b)
        if abs(a[0] - b[0]) + abs(a[1] - b[1]) != 1:
            return False
        return not _wall_between(self.h_walls, self.v_walls, a, b)

    def open_neighbours(self, r: int, c: int) -> list[tuple[int, int]]:
        """Adjacent cells reachable in one step, in the order north, east, south, west."""
        self.check_cell((r, c))
        out = []
        for dr, dc in DIRECTIONS.values():
            nb = (r + dr, c + dc)
            if self.contains(nb) and not _wall_between(self.h_walls, self.v_walls, (r, c), nb):
                out.append(nb)
        return out

    def reachable_from(self, cell: tuple[int, int]) -> dict[tuple[int, int], int]:
        """Breadth-first step counts from ``cell`` to every cell it can reach."""
        self.check_cell(cell)
        dist = {tuple(cell): 0}
        queue = deque([tuple(cell)])
        while queue:
            cur = queue.popleft()
            for nb in self.open_neighbours(*cur):
                if nb not in dist:
                    dist[nb] = dist[cur] + 1
                    queue.append(nb)
        return dist

    def passage_count(self) -> int:
        """Number of open internal passages between adjacent cells."""
        return int((~self.h_walls[1:-1, :]).sum() + (~self.v_walls[:, 1:-1]).sum())

    # ----- geometry ----------------------------------------------------------------------
    def _h_wall_name(self, r: int, c: int) -> str:
        return f"wall_{r}_{c}_n" if r < self.rows else f"wall_{r - 1}_{c}_s"

    def _v_wall_name(self, r: int, c: int) -> str:
        return f"wall_{r}_{c}_w" if c < self.cols else f"wall_{r}_{c - 1}_e"

    def wall_segments(self) -> list[WallSegment]:
        """Every wall piece, one cell long, on its centre line.

        Horizontal pieces are named by the cell to their south (``wall_{r}_{c}_n``)
        except the south boundary, named by the cell above (``wall_{rows-1}_{c}_s``);
        vertical pieces by the cell to their east (``wall_{r}_{c}_w``) except the east
        boundary (``wall_{r}_{cols-1}_e``). Order: horizontal pieces row by row, then
        vertical pieces row by row.
        """
        s, t = self.settings.cell_size_m, self.settings.wall_thickness_m
        out = []
        for r in range(self.rows + 1):
            y = (self.rows - r) * s
            for c in range(self.cols):
                if self.h_walls[r, c]:
                    name = self._h_wall_name(r, c)
                    out.append(WallSegment(name=name, x0=c * s, y0=y, x1=(c + 1) * s, y1=y, thickness=t))
        for r in range(self.rows):
            y_top, y_bottom = (self.rows - r) * s, (self.rows - r - 1) * s
            for c in range(self.cols + 1):
                if self.v_walls[r, c]:
                    name = self._v_wall_name(r, c)
                    out.append(WallSegment(name=name, x0=c * s, y0=y_top, x1=c * s, y1=y_bottom, thickness=t))
        return out

    def wall_faces(self) -> list[WallFace]:
        """Every face of every wall piece that faces a cell inside the maze.

        A face of the wall on the north side of cell (r, c) toward that cell has its
        centre at (x_c, y_n - t/2) with normal (0, -1), where y_n = (rows - r) s is the
        wall's centre line; the other faces follow by symmetry.
        """
        s, t = self.settings.cell_size_m, self.settings.wall_thickness_m
        length = s - t
        out = []
        for r in range(self.rows + 1):
            y = (self.rows - r) * s
            for c in range(self.cols):
                if not self.h_walls[r, c]:
                    continue
                name, x = self._h_wall_name(r, c), (c + 0.5) * s
                if r > 0:  # face toward the cell to the north, pointing +y
                    out.append(_face(name, (r - 1, c), (x, y + t / 2), (0.0, 1.0), length))
                if r < self.rows:  # face toward the cell to the south, pointing -y
                    out.append(_face(name, (r, c), (x, y - t / 2), (0.0, -1.0), length))
        for r in range(self.rows):
            y = (self.rows - r - 0.5) * s
            for c in range(self.cols + 1):
                if not self.v_walls[r, c]:
                    continue
                name, x = self._v_wall_name(r, c), c * s
                if c > 0:  # face toward the cell to the west, pointing -x
                    out.append(_face(name, (r, c - 1), (x - t / 2, y), (-1.0, 0.0), length))
                if c < self.cols:  # face toward the cell to the east, pointing +x
                    out.append(_face(name, (r, c), (x + t / 2, y), (1.0, 0.0), length))
        return out

    def openings(self) -> list[Opening]:
        """Every passage between adjacent cells (row-major by ``cell_a``; east before south)."""
        s, t = self.settings.cell_size_m, self.settings.wall_thickness_m
        out = []
        for r, c in self.cells():
            if c + 1 < self.cols and not self.v_walls[r, c + 1]:
                centre = ((c + 1) * s, (self.rows - r - 0.5) * s)
                out.append(_opening((r, c), (r, c + 1), centre, (1.0, 0.0), s - t))
            if r + 1 < self.rows and not self.h_walls[r + 1, c]:
                centre = ((c + 0.5) * s, (self.rows - r - 1) * s)
                out.append(_opening((r, c), (r + 1, c), centre, (0.0, -1.0), s - t))
        return out

    # ----- text --------------------------------------------------------------------------
    def drawing_lines(self) -> list[str]:
        """The maze drawn with '+', '---' and '|' (no settings)."""
        lines = []
        for r in range(self.rows + 1):
            lines.append("+" + "+".join("---" if w else "   " for w in self.h_walls[r]) + "+")
            if r < self.rows:
                v = self.v_walls[r]
                lines.append("   ".join("|" if w else " " for w in v))
        return lines

    def to_text(self) -> str:
        """The maze in the file format; ``parse_maze(m.to_text()) == m``."""
        st = self.settings
        lines = [FORMAT_HEADER, f"name: {self.name}"]
        preset = next((k for k, v in PRESETS.items() if v == st), None)
        if preset is not None:
            lines.append(f"preset: {preset}")
        else:
            lines += [
                f"cell_size_m: {st.cell_size_m!r}",
                f"wall_height_m: {st.wall_height_m!r}",
                f"wall_thickness_m: {st.wall_thickness_m!r}",
            ]
        word = next((k for k, v in HEADINGS_RAD.items() if _angle_close(v, self.start_heading_rad)), None)
        heading = word if word is not None else repr(math.degrees(self.start_heading_rad))
        lines.append(f"start: {self.start_cell[0]} {self.start_cell[1]} {heading}")
        lines += self.drawing_lines()
        return "\n".join(lines) + "\n"


def _angle_close(a: float, b: float) -> bool:
    d = (a - b + math.pi) % (2 * math.pi) - math.pi
    return abs(d) < 1e-12


def _face(name, cell, centre, normal, length) -> WallFace:
    return WallFace(
        wall=name,
        cell=cell,
        center_xy=np.array(centre),
        normal_xy=np.array(normal),
        length_m=length,
    )


def _opening(a, b, centre, normal, width) -> Opening:
    return Opening(cell_a=a, cell_b=b, center_xy=np.array(centre), normal_xy=np.array(normal), width_m=width)


# ----- parser -------------------------------------------------------------------------------
_SETTING_RE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*:(.*)$")
_NUMBER_KEYS = ("cell_size_m", "wall_height_m", "wall_thickness_m")
_SETTING_KEYS = ("preset", *_NUMBER_KEYS, "start", "name")


class _Parser:
    def __init__(self, text: str, source: str) -> None:
        self.source = source
        self.lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        if self.lines and self.lines[0].startswith("\ufeff"):
            self.lines[0] = self.lines[0][1:]

    def error(self, line: int, col: int, message: str) -> MazeFormatError:
        """line and col are 1-based."""
        return MazeFormatError(f"{self.source}:{line}:{col}: {message}")

    def parse(self) -> Maze:
        settings: dict[str, tuple[str, int, int]] = {}  # key -> (value, line, value col)
        drawing: list[tuple[int, str]] = []  # (1-based line number, text)
        after_drawing = False
        for i, raw in enumerate(self.lines, start=1):
            stripped = raw.strip()
            if stripped.startswith("#"):
                continue
            if not stripped:
                after_drawing = after_drawing or bool(drawing)
                continue
            indent = len(raw) - len(raw.lstrip())
            if after_drawing:
                raise self.error(i, indent + 1, "text after the maze drawing; expected only blank or '#' lines")
            if drawing and _SETTING_RE.match(raw):  # a drawing line starts with '+', '|' or a space
                raise self.error(
                    i, 1, f"setting {raw.split(':', 1)[0]!r} after the maze drawing; expected settings before it"
                )
            if drawing or raw.startswith("+"):
                drawing.append((i, raw.rstrip()))
                continue
            self._setting(i, raw, settings)
        if not drawing:
            raise self.error(len(self.lines), 1, "no maze drawing found; expected lines starting with '+'")
        return self._build(settings, drawing)

    def _setting(self, i: int, raw: str, settings: dict[str, tuple[str, int, int]]) -> None:
        body = raw.split("#", 1)[0].rstrip()
        indent = len(body) - len(body.lstrip())
        m = _SETTING_RE.match(body.strip())
        if m is None:
            raise self.error(
                i,
                indent + 1,
                f"cannot read {body.strip()!r}; expected a 'key: value' setting, a '#' comment "
                "or the drawing (a line starting with '+')",
            )
        key, value = m.group(1), m.group(2)
        if key not in _SETTING_KEYS:
            raise self.error(
                i,
                indent + 1,
                f"unknown setting {key!r}; expected one of: {', '.join(_SETTING_KEYS)}",
            )
        if key in settings:
            raise self.error(
                i,
                indent + 1,
                f"setting {key!r} given twice (first on line {settings[key][1]}); expected each setting once",
            )
        colon = body.index(":", indent)
        value_col = colon + 2 + len(value) - len(value.lstrip())  # 1-based column of the value
        value = value.strip()
        if not value:
            raise self.error(i, value_col, f"setting {key!r} has no value")
        settings[key] = (value, i, value_col)

    def _settings(self, settings: dict[str, tuple[str, int, int]]) -> MazeSettings:
        preset = DEFAULT_PRESET
        if "preset" in settings:
            preset, line, col = settings["preset"]
            if preset not in PRESETS:
                raise self.error(line, col, f"unknown preset {preset!r}; expected one of: {', '.join(PRESETS)}")
        values = {
            "cell_size_m": PRESETS[preset].cell_size_m,
            "wall_height_m": PRESETS[preset].wall_height_m,
            "wall_thickness_m": PRESETS[preset].wall_thickness_m,
        }
        for key in _NUMBER_KEYS:
            if key not in settings:
                continue
            text, line, col = settings[key]
            try:
                value = float(text)
            except ValueError:
                value = math.nan
            if not (math.isfinite(value) and value > 0):
                raise self.error(line, col, f"{key}: expected a positive number of metres, got {text!r}")
            values[key] = value
        if values["wall_thickness_m"] >= values["cell_size_m"] / 2:
            key = "wall_thickness_m" if "wall_thickness_m" in settings else "cell_size_m"
            _, line, col = settings[key]
            raise self.error(
                line,
                col,
                f"wall_thickness_m {values['wall_thickness_m']} must be less than half of "
                f"cell_size_m {values['cell_size_m']}; expected a thinner wall or a larger cell",
            )
        return MazeSettings(**values)

    def _start(self, settings, rows: int, cols: int):
        """(cell, heading or None, line, col) from the ``start`` setting, or None."""
        if "start" not in settings:
            return None
        text, line, col = settings["start"]
        parts = text.split()
        expected = "expected 'start: ROW COL HEADING', HEADING north/east/south/west or degrees"
        if len(parts) not in (2, 3):
            raise self.error(line, col, f"cannot read start {text!r}; {expected}")
        try:
            r, c = int(parts[0]), int(parts[1])
        except ValueError:
            raise self.error(line, col, f"cannot read start {text!r}; {expected}") from None
        if not (0 <= r < rows and 0 <= c < cols):
            raise self.error(
                line,
                col,
                f"start cell ({r}, {c}) is outside the maze; expected row 0..{rows - 1} and col 0..{cols - 1}",
            )
        heading = None
        if len(parts) == 3:
            word = parts[2].lower()
            if word in HEADINGS_RAD:
                heading = HEADINGS_RAD[word]
            else:
                try:
                    degrees = float(word)
                except ValueError:
                    degrees = math.nan
                if not math.isfinite(degrees):
                    raise self.error(
                        line,
                        col + text.index(parts[2]),
                        f"unknown heading {parts[2]!r}; {expected}",
                    )
                heading = math.radians(degrees)
        return (r, c), heading

    def _build(self, settings, drawing: list[tuple[int, str]]) -> Maze:
        first_line, first = drawing[0]
        width = len(first)
        for line, text in drawing:
            if "\t" in text:
                raise self.error(line, text.index("\t") + 1, "tab character; expected spaces")
        if width < 5 or (width - 1) % 4 != 0:
            raise self.error(
                first_line,
                width + 1,
                f"first drawing line is {width} characters wide; expected 4 * cols + 1 "
                "(a '+' every 4 characters, at least one cell)",
            )
        rows, cols = (len(drawing) - 1) // 2, (width - 1) // 4
        if rows > MAX_MAZE_SIDE or cols > MAX_MAZE_SIDE:
            raise self.error(
                first_line,
                1,
                f"the maze is {rows}x{cols} cells; expected at most {MAX_MAZE_SIDE}x{MAX_MAZE_SIDE}",
            )
        for k, (line, text) in enumerate(drawing):
            if k % 2 == 1 and len(text) < width and (len(text) - 1) % 4 == 0:
                # A cell line that stops at a wall column: trailing openings, not a ragged row
                # (editors strip trailing spaces); the boundary check reports an open east side.
                text = text.ljust(width)
                drawing[k] = (line, text)
            if len(text) != width:
                raise self.error(
                    line,
                    min(len(text), width) + 1,
                    f"drawing line is {len(text)} characters wide; expected {width} like line "
                    f"{first_line} (every line must end at the east boundary)",
                )
        if len(drawing) < 3 or len(drawing) % 2 == 0:
            line = drawing[-1][0]
            raise self.error(
                line + 1,
                1,
                f"the drawing has {len(drawing)} lines; expected an odd number (2 * rows + 1) "
                "ending with a line of corners",
            )
        rows, cols = (len(drawing) - 1) // 2, (width - 1) // 4
        h_walls = np.zeros((rows + 1, cols), dtype=bool)
        v_walls = np.zeros((rows, cols + 1), dtype=bool)
        for k, (line, text) in enumerate(drawing):
            if k % 2 == 0:
                self._corner_line(line, text, h_walls[k // 2])
            else:
                self._cell_line(line, text, v_walls[k // 2])
        self._check_boundary(drawing, h_walls, v_walls)
        st = self._settings(settings)
        start = self._start(settings, rows, cols)
        cell, heading = start if start is not None else ((0, 0), None)
        if heading is None:
            heading = default_start_heading(h_walls, v_walls, cell)
        name = settings["name"][0] if "name" in settings else _default_name(self.source)
        maze = Maze(
            rows=rows,
            cols=cols,
            h_walls=h_walls,
            v_walls=v_walls,
            settings=st,
            start_cell=cell,
            start_heading_rad=heading,
            name=name,
        )
        reached = maze.reachable_from(cell)
        for r, c in maze.cells():
            if (r, c) not in reached:
                raise self.error(
                    first_line + 2 * r + 1,
                    4 * c + 3,
                    f"cell ({r}, {c}) cannot be reached from the start cell {cell}; "
                    "expected every cell to be connected (open a wall)",
                )
        return maze

    def _corner_line(self, line: int, text: str, walls: np.ndarray) -> None:
        for c in range(len(walls) + 1):
            x = 4 * c
            if text[x] != "+":
                what = "unknown character" if text[x] not in "+-| " else "character"
                raise self.error(line, x + 1, f"{what} {text[x]!r} at a corner; expected '+'")
            if c == len(walls):
                break
            seg = text[x + 1 : x + 4]
            if seg == "---":
                walls[c] = True
            elif seg != "   ":
                unknown = [j for j, ch in enumerate(seg) if ch not in "- "]
                bad = unknown[0] if unknown else next(j for j in (1, 2) if seg[j] != seg[0])
                ch = seg[bad]
                what = "unknown character" if unknown else "broken wall"
                raise self.error(
                    line,
                    x + 2 + bad,
                    f"{what} {ch!r} in {seg!r} between corners; expected '---' or '   '",
                )

    def _cell_line(self, line: int, text: str, walls: np.ndarray) -> None:
        for x, ch in enumerate(text):
            if x % 4 == 0:
                if ch == "|":
                    walls[x // 4] = True
                elif ch != " ":
                    what = "unknown character" if ch not in "+-| " else "character"
                    raise self.error(
                        line,
                        x + 1,
                        f"{what} {ch!r} between cells; expected '|' (wall) or ' ' (open)",
                    )
            elif ch != " ":
                what = "unknown character" if ch not in "+-| " else "character"
                raise self.error(line, x + 1, f"{what} {ch!r} inside a cell; expected ' '")

    def _check_boundary(self, drawing, h_walls: np.ndarray, v_walls: np.ndarray) -> None:
        rows, cols = v_walls.shape[0], h_walls.shape[1]
        for r, side in ((0, "north"), (rows, "south")):
            for c in range(cols):
                if not h_walls[r, c]:
                    raise self.error(
                        drawing[2 * r][0],
                        4 * c + 2,
                        f"the {side} boundary is open above cell column {c}; "
                        "expected '---' (the outer boundary must be closed)",
                    )
        for r in range(rows):
            for c, side in ((0, "west"), (cols, "east")):
                if not v_walls[r, c]:
                    raise self.error(
                        drawing[2 * r + 1][0],
                        4 * c + 1,
                        f"the {side} boundary is open at row {r}; "
                        "expected '|' (the outer boundary must be closed)",
                    )


def _default_name(source: str) -> str:
    if source.startswith("<"):
        return "maze"
    return Path(source).stem


def parse_maze(text: str, source: str = "<string>") -> Maze:
    """Parse the text of a maze file; errors name ``source:line:col``.

    >>> parse_maze("+---+\\n|   |\\n+   +\\n", source="x.maze")
    Traceback (most recent call last):
    ...
    sim.world.maze.MazeFormatError: x.maze:3:2: the south boundary is open above cell column 0; \
expected '---' (the outer boundary must be closed)
    """
    return _Parser(text, source).parse()


def load_maze(path: str | Path) -> Maze:
    """Read a ``.maze`` file; the maze is named by its ``name`` setting or the file stem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise MazeFormatError(f"{path}:1:1: not UTF-8 text ({exc.reason}); expected a UTF-8 .maze file") from None
    return parse_maze(text, source=str(path))


def find_maze(name_or_path: str | Path) -> Path:
    """Resolve a maze file: an existing path, or a bare name like ``rrl_arena`` in MAZES_DIR.

    >>> find_maze("rrl_small").name
    'rrl_small.maze'
    """
    path = Path(name_or_path)
    if path.is_file():
        return path
    text = str(name_or_path)
    if "/" not in text and "\\" not in text:
        stem = text[: -len(MAZE_SUFFIX)] if text.endswith(MAZE_SUFFIX) else text
        candidate = MAZES_DIR / f"{stem}{MAZE_SUFFIX}"
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(
        f"maze {text!r}: no such file, and no shipped maze by that name; expected a path or "
        f"one of: {', '.join(available_mazes())}"
    )


def available_mazes() -> list[str]:
    """Names of the mazes shipped in maze_assets/mazes/."""
    return sorted(p.stem for p in MAZES_DIR.glob(f"*{MAZE_SUFFIX}"))
