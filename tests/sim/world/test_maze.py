"""Tests for sim/world/maze.py: the text format, world geometry and wall naming."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from maze_assets import MAZES_DIR
from sim.world.maze import (
    PRESETS,
    Maze,
    MazeError,
    MazeFormatError,
    MazeSettings,
    available_mazes,
    find_maze,
    load_maze,
    parse_maze,
)

# Exact binary fractions are not involved, so coordinates compare to 1e-12 m
# (far below any physical size; only float rounding of c * s is absorbed).
TOL_M = 1e-12

# The example drawing of the format: 2 rows x 3 cols of RRL cells (s = 1.2 m, t = 0.05 m).
EXAMPLE = """\
# poibench maze v1
preset: rrl            # trailing comments are allowed
start: 0 0 east
+---+---+---+
|       |   |
+   +---+   +
|           |
+---+---+---+
"""


@pytest.fixture()
def example() -> Maze:
    return parse_maze(EXAMPLE, source="example.maze")


def test_shipped_mazes_are_present() -> None:
    assert {"rrl_arena", "rrl_small", "rmrc_lanes", "default"} <= set(available_mazes())


@pytest.mark.parametrize(
    ("name", "rows", "cols", "preset", "passages", "dead_ends"),
    [
        # rrl_arena: 20 cells, 20 passages = one loop; dead ends at start and two in the south.
        ("rrl_arena", 4, 5, "rrl", 20, [(0, 0), (3, 2), (3, 4)]),
        # rrl_small: a tree (8 passages for 9 cells).
        ("rrl_small", 3, 3, "rrl", 8, [(0, 0), (0, 2), (2, 1), (2, 2)]),
        # rmrc_lanes: serpentine of six lanes plus one cross-over: 24 passages for 24 cells.
        ("rmrc_lanes", 4, 6, "rmrc", 24, [(0, 0), (0, 5)]),
        # default: a 12-cell loop and exactly two dead ends.
        ("default", 4, 4, "rrl", 16, [(1, 2), (3, 3)]),
    ],
)
def test_shipped_maze_parses(name, rows, cols, preset, passages, dead_ends) -> None:
    m = load_maze(find_maze(name))
    assert (m.rows, m.cols, m.name) == (rows, cols, name)
    assert m.settings == PRESETS[preset]
    assert m.passage_count() == passages
    assert [c for c in m.cells() if len(m.open_neighbours(*c)) == 1] == dead_ends
    assert len(m.reachable_from(m.start_cell)) == rows * cols
    assert m.start_cell == (0, 0)


def test_presets() -> None:
    assert PRESETS["rrl"] == MazeSettings(cell_size_m=1.2, wall_height_m=1.2, wall_thickness_m=0.05)
    assert PRESETS["rmrc"] == MazeSettings(cell_size_m=0.3, wall_height_m=0.3, wall_thickness_m=0.012)


def test_example_walls(example: Maze) -> None:
    m = example
    assert (m.rows, m.cols, m.name) == (2, 3, "example")
    # h_walls[r, c]: north side of cell (r, c); row 2 is the south boundary.
    assert m.h_walls.tolist() == [[True, True, True], [False, True, False], [True, True, True]]
    # v_walls[r, c]: west side of cell (r, c); column 3 is the east boundary.
    assert m.v_walls.tolist() == [[True, False, True, True], [True, False, False, True]]
    assert m.size_m == pytest.approx((3.6, 2.4), abs=TOL_M)
    assert m.open_neighbours(0, 0) == [(0, 1), (1, 0)]  # order N, E, S, W
    assert m.open_neighbours(0, 2) == [(1, 2)]
    assert m.is_open((0, 0), (0, 1))
    assert not m.is_open((0, 1), (0, 2))
    assert not m.is_open((0, 0), (1, 1))  # diagonal: never adjacent
    with pytest.raises(MazeError, match=r"cell \(2, 0\) is outside the maze"):
        m.is_open((1, 0), (2, 0))


def test_world_coordinates(example: Maze) -> None:
    m = example
    # x = (c + 0.5) * 1.2, y = (rows - r - 0.5) * 1.2 with rows = 2.
    assert m.cell_center(0, 0) == pytest.approx([0.6, 1.8], abs=TOL_M)
    assert m.cell_center(1, 2) == pytest.approx([3.0, 0.6], abs=TOL_M)
    assert m.cell_center(0, 2) == pytest.approx([3.0, 1.8], abs=TOL_M)
    for cell in m.cells():
        assert m.cell_at(*m.cell_center(*cell)) == cell
    assert m.cell_at(-0.01, 1.0) is None
    assert m.cell_at(1.0, 2.41) is None
    assert m.start_heading_rad == 0.0


def test_wall_segments(example: Maze) -> None:
    m = example
    segs = {w.name: w for w in m.wall_segments()}
    walls = int(m.h_walls.sum() + m.v_walls.sum())
    assert len(segs) == walls == 12  # 7 horizontal + 5 vertical pieces
    # North boundary above cell (0, 1): y = 2.4, x from 1.2 to 2.4.
    w = segs["wall_0_1_n"]
    assert (w.x0, w.y0, w.x1, w.y1, w.thickness) == pytest.approx((1.2, 2.4, 2.4, 2.4, 0.05))
    # Internal h wall north of cell (1, 1): y = 1.2.
    assert segs["wall_1_1_n"].y0 == pytest.approx(1.2, abs=TOL_M)
    # South boundary is named by the cell above it with side 's'.
    assert {"wall_1_0_s", "wall_1_1_s", "wall_1_2_s"} <= set(segs)
    assert segs["wall_1_2_s"].y0 == 0.0
    # East boundary named by the cell to its west with side 'e': x = 3.6, y from 2.4 to 1.2.
    w = segs["wall_0_2_e"]
    assert (w.x0, w.y0, w.x1, w.y1) == pytest.approx((3.6, 2.4, 3.6, 1.2), abs=TOL_M)
    # Internal v wall west of cell (0, 2): x = 2.4.
    assert segs["wall_0_2_w"].x0 == pytest.approx(2.4, abs=TOL_M)
    assert all(w.length_m == pytest.approx(1.2, abs=TOL_M) for w in segs.values())
    assert not any(n.endswith("_s") and not n.startswith("wall_1_") for n in segs)


def test_wall_faces(example: Maze) -> None:
    m = example
    faces = m.wall_faces()
    # Internal walls have two faces, boundary walls one (the outside is not listed).
    internal = int(m.h_walls[1:-1].sum() + m.v_walls[:, 1:-1].sum())
    boundary = 2 * (m.rows + m.cols)
    assert len(faces) == 2 * internal + boundary == 14
    by_key = {(f.wall, f.cell): f for f in faces}
    # North boundary of cell (0, 0): centre half a thickness (0.025 m) below y = 2.4, normal -y.
    f = by_key[("wall_0_0_n", (0, 0))]
    assert f.center_xy == pytest.approx([0.6, 2.375], abs=TOL_M)
    assert f.normal_xy.tolist() == [0.0, -1.0]
    assert f.length_m == pytest.approx(1.15, abs=TOL_M)  # 1.2 - 0.05
    # Wall between (0, 1) and (0, 2) at x = 2.4: one face into each cell.
    f = by_key[("wall_0_2_w", (0, 1))]
    assert f.center_xy == pytest.approx([2.375, 1.8], abs=TOL_M)
    assert f.normal_xy.tolist() == [-1.0, 0.0]
    f = by_key[("wall_0_2_w", (0, 2))]
    assert f.center_xy == pytest.approx([2.425, 1.8], abs=TOL_M)
    assert f.normal_xy.tolist() == [1.0, 0.0]
    # Wall north of cell (1, 1) at y = 1.2, facing up into (0, 1).
    f = by_key[("wall_1_1_n", (0, 1))]
    assert f.center_xy == pytest.approx([1.8, 1.225], abs=TOL_M)
    assert f.normal_xy.tolist() == [0.0, 1.0]
    # Every normal points from the face toward its cell's centre.
    for f in faces:
        to_centre = m.cell_center(*f.cell) - f.center_xy
        assert float(to_centre @ f.normal_xy) == pytest.approx(0.6 - 0.025, abs=TOL_M)


def test_openings(example: Maze) -> None:
    m = example
    ops = m.openings()
    assert len(ops) == m.passage_count() == 5
    # Row-major by cell_a, the east passage before the south one.
    assert [(o.cell_a, o.cell_b) for o in ops] == [
        ((0, 0), (0, 1)),
        ((0, 0), (1, 0)),
        ((0, 2), (1, 2)),
        ((1, 0), (1, 1)),
        ((1, 1), (1, 2)),
    ]
    # The passage between (0, 0) and (1, 0) is the gap in the h wall at y = 1.2, x = 0.6.
    assert ops[1].center_xy == pytest.approx([0.6, 1.2], abs=TOL_M)
    assert ops[1].normal_xy.tolist() == [0.0, -1.0]
    for o in m.openings():
        a, b = m.cell_center(*o.cell_a), m.cell_center(*o.cell_b)
        assert o.center_xy == pytest.approx((a + b) / 2, abs=TOL_M)
        assert o.normal_xy == pytest.approx((b - a) / 1.2, abs=TOL_M)
        assert o.width_m == pytest.approx(1.15, abs=TOL_M)


def test_openings_match_passages() -> None:
    m = load_maze(find_maze("rrl_arena"))
    pairs = {(o.cell_a, o.cell_b) for o in m.openings()}
    assert len(pairs) == m.passage_count()
    for a in m.cells():
        for b in m.open_neighbours(*a):
            assert (min(a, b), max(a, b)) in pairs


def test_round_trip_shipped() -> None:
    for name in available_mazes():
        m = load_maze(find_maze(name))
        again = parse_maze(m.to_text())
        assert again == m
        assert again.to_text() == m.to_text()


def test_round_trip_custom_settings_and_heading() -> None:
    text = EXAMPLE.replace("start: 0 0 east", "start: 1 2 30\ncell_size_m: 0.6\nname: custom")
    m = parse_maze(text)
    assert m.name == "custom"
    assert m.settings == MazeSettings(cell_size_m=0.6, wall_height_m=1.2, wall_thickness_m=0.05)
    assert m.start_cell == (1, 2)
    assert m.start_heading_rad == pytest.approx(math.radians(30), abs=1e-15)
    assert parse_maze(m.to_text()) == m
    assert "cell_size_m: 0.6" in m.to_text()


def test_default_start_faces_open_neighbour() -> None:
    # Cell (0, 0) is closed to the east, so the robot faces south (-pi/2).
    m = parse_maze("+---+---+\n|   |   |\n+   +   +\n|       |\n+---+---+\n")
    assert m.start_cell == (0, 0)
    assert m.start_heading_rad == pytest.approx(-math.pi / 2)
    # A 1x1 maze has no open neighbour: east.
    assert parse_maze("+---+\n|   |\n+---+\n").start_heading_rad == 0.0


def test_headings_by_word() -> None:
    for word, rad in (("north", math.pi / 2), ("west", math.pi), ("south", -math.pi / 2)):
        m = parse_maze(EXAMPLE.replace("east", word))
        assert m.start_heading_rad == pytest.approx(rad)


def test_crlf_and_bom_are_read() -> None:
    m = parse_maze("\ufeff" + EXAMPLE.replace("\n", "\r\n"))
    assert m == parse_maze(EXAMPLE)


def test_find_maze(tmp_path: Path) -> None:
    assert find_maze("rrl_arena") == MAZES_DIR / "rrl_arena.maze"
    assert find_maze("rrl_arena.maze") == MAZES_DIR / "rrl_arena.maze"
    p = tmp_path / "mine.maze"
    p.write_text(EXAMPLE)
    assert find_maze(str(p)) == p
    assert load_maze(p).name == "mine"
    with pytest.raises(FileNotFoundError, match="no shipped maze by that name.*rrl_arena"):
        find_maze("no_such_maze")


def test_load_error_names_the_file(tmp_path: Path) -> None:
    p = tmp_path / "bad.maze"
    p.write_text("colour: red\n+---+\n|   |\n+---+\n")
    with pytest.raises(MazeFormatError) as err:
        load_maze(p)
    assert str(err.value).startswith(f"{p}:1:1: unknown setting 'colour'")


def _lines(*lines: str) -> str:
    return "\n".join(lines) + "\n"


GOOD = ("+---+---+", "|       |", "+   +---+", "|       |", "+---+---+")

# (text, line, col, phrase): each must fail at exactly FILE:LINE:COL with a message saying why.
ERRORS = [
    # A row shorter than the first drawing line (7 characters, expected 9).
    (_lines("+---+---+", "|     |", "+---+---+"), 2, 8, "drawing line is 7 characters wide"),
    (_lines("+---+---+", "|       |   ", "+---+---+---+"), 3, 10, "expected 9 like line 1"),
    # A corner that is not '+'.
    (_lines("+--- ---+", "|       |", "+---+---+"), 1, 5, "at a corner; expected '+'"),
    (_lines("+---+---+", "|       |", "+---|---+"), 3, 5, "at a corner; expected '+'"),
    # Unknown characters inside a cell, in a wall and between cells.
    (_lines("+---+---+", "| * |   |", "+---+---+"), 2, 3, "unknown character '*' inside a cell"),
    (_lines("+---+-x-+", "|   |   |", "+---+---+"), 1, 7, "unknown character 'x'"),
    (_lines("+---+---+", "|   #   |", "+---+---+"), 2, 5, "unknown character '#' between cells"),
    (_lines("+---+---+", "|\t      |", "+---+---+"), 2, 2, "tab character"),
    # A broken wall.
    (_lines("+-- +---+", "|   |   |", "+---+---+"), 1, 4, "broken wall"),
    # Settings: unknown key, bad numbers, unknown preset, duplicate key, unreadable line.
    (_lines("colour: red", *GOOD), 1, 1, "unknown setting 'colour'; expected one of"),
    (_lines("cell_size_m: big", *GOOD), 1, 14, "cell_size_m: expected a positive number"),
    (_lines("  wall_height_m:  -1", *GOOD), 1, 19, "wall_height_m: expected a positive number"),
    (_lines("cell_size_m: nan", *GOOD), 1, 14, "expected a positive number"),
    (_lines("preset: rcll", *GOOD), 1, 9, "unknown preset 'rcll'; expected one of: rrl, rmrc"),
    (_lines("preset: rrl", "preset: rmrc", *GOOD), 2, 1, "given twice (first on line 1)"),
    (_lines("hello world", *GOOD), 1, 1, "expected a 'key: value' setting"),
    (_lines("wall_thickness_m: 0.7", *GOOD), 1, 19, "must be less than half of cell_size_m"),
    # Start: outside the maze, unreadable, unknown heading.
    (_lines("start: 2 0 east", *GOOD), 1, 8, "start cell (2, 0) is outside the maze"),
    (_lines("start: 0 -1", *GOOD), 1, 8, "start cell (0, -1) is outside the maze"),
    (_lines("start: a b", *GOOD), 1, 8, "cannot read start 'a b'"),
    (_lines("start: 0 0 up", *GOOD), 1, 12, "unknown heading 'up'"),
    # Outer boundary not closed (north, south, west, east).
    (_lines("+---+   +", "|       |", "+---+---+"), 1, 6, "north boundary is open"),
    (_lines("+---+---+", "|       |", "+   +---+"), 3, 2, "south boundary is open"),
    (_lines("+---+---+", "        |", "+---+---+"), 2, 1, "west boundary is open at row 0"),
    (
        _lines("+---+---+", "|   |   |", "+   +   +", "|        ", "+---+---+"),
        4,
        9,
        "east boundary",
    ),
    # An unreachable cell: (0, 1) is walled in; named at its place in the drawing.
    (_lines("+---+---+", "|   |   |", "+   +---+", "|       |", "+---+---+"), 2, 7, "cell (0, 1)"),
    # Structure: no drawing, an even number of lines, text after the drawing, too narrow.
    (_lines("preset: rrl"), 2, 1, "no maze drawing found"),
    (_lines("+---+", "|   |"), 3, 1, "expected an odd number"),
    (_lines(*GOOD, "", "start: 0 0 east"), 7, 1, "text after the maze drawing"),
    (_lines(*GOOD, "preset: rrl"), 6, 1, "setting 'preset' after the maze drawing; expected settings before it"),
    (_lines("+--+", "|  |", "+--+"), 1, 5, "expected 4 * cols + 1"),
]


@pytest.mark.parametrize(("text", "line", "col", "phrase"), ERRORS)
def test_format_errors(text: str, line: int, col: int, phrase: str) -> None:
    with pytest.raises(MazeFormatError) as err:
        parse_maze(text, source="bad.maze")
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"bad.maze:{line}:{col}: "), message
    assert phrase in message
    assert "expected" in message or "expected" in phrase
    assert isinstance(err.value, ValueError)


def test_maze_record_checks_shapes() -> None:
    st = PRESETS["rrl"]
    with pytest.raises(MazeError, match=r"h_walls shape \(2, 2\), expected \(3, 2\)"):
        Maze(
            rows=2,
            cols=2,
            h_walls=np.ones((2, 2)),
            v_walls=np.ones((2, 3)),
            settings=st,
            start_cell=(0, 0),
            start_heading_rad=0.0,
            name="x",
        )
    with pytest.raises(MazeError, match="less than half the cell size"):
        MazeSettings(cell_size_m=0.3, wall_height_m=0.3, wall_thickness_m=0.2)
