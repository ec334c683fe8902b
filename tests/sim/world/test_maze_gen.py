"""Tests for sim/world/maze_gen.py: determinism, connectivity, loops."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.world.maze import PRESETS, MazeError, parse_maze
from sim.world.maze_gen import generate_maze


def test_same_seed_same_maze() -> None:
    a = generate_maze(6, 7, np.random.default_rng(123))
    b = generate_maze(6, 7, np.random.default_rng(123))
    assert np.array_equal(a.h_walls, b.h_walls)
    assert np.array_equal(a.v_walls, b.v_walls)
    assert a == b


def test_different_seed_different_maze() -> None:
    # 6x7 has far too many spanning trees for two seeds to collide by chance.
    a = generate_maze(6, 7, np.random.default_rng(1))
    b = generate_maze(6, 7, np.random.default_rng(2))
    assert not (np.array_equal(a.h_walls, b.h_walls) and np.array_equal(a.v_walls, b.v_walls))


@pytest.mark.parametrize(("rows", "cols"), [(1, 1), (1, 5), (5, 1), (2, 2), (8, 8), (12, 5)])
@pytest.mark.parametrize("seed", [0, 7])
def test_connected_closed_and_valid(rows: int, cols: int, seed: int) -> None:
    m = generate_maze(rows, cols, np.random.default_rng(seed))
    assert (m.rows, m.cols) == (rows, cols)
    assert len(m.reachable_from((0, 0))) == rows * cols
    # Outer boundary closed.
    assert m.h_walls[0].all() and m.h_walls[-1].all()
    assert m.v_walls[:, 0].all() and m.v_walls[:, -1].all()
    # It survives the file format (which checks boundary and connectivity again).
    assert parse_maze(m.to_text()) == m


def test_perfect_maze_without_loops() -> None:
    # loop_fraction 0: a spanning tree, exactly cells - 1 passages.
    m = generate_maze(9, 9, np.random.default_rng(5), loop_fraction=0.0)
    assert m.passage_count() == 81 - 1


def test_loops_exist() -> None:
    # 10x10: 180 internal walls, 99 opened by the tree, 81 left; 15% of them is round(12.15) = 12.
    m = generate_maze(10, 10, np.random.default_rng(3))
    assert m.passage_count() == 99 + 12
    assert m.passage_count() > m.rows * m.cols - 1


def test_loop_fraction_one_removes_every_internal_wall() -> None:
    m = generate_maze(4, 5, np.random.default_rng(0), loop_fraction=1.0)
    assert not m.h_walls[1:-1].any() and not m.v_walls[:, 1:-1].any()


def test_start_and_settings() -> None:
    m = generate_maze(3, 3, np.random.default_rng(4), settings=PRESETS["rmrc"], name="g")
    assert m.name == "g"
    assert m.settings == PRESETS["rmrc"]
    assert m.start_cell == (0, 0)
    # The start heading points at an open neighbour: east (0) or south (-pi/2).
    step = {0.0: (0, 1), -math.pi / 2: (1, 0)}[m.start_heading_rad]
    assert m.is_open((0, 0), step)
    assert generate_maze(2, 3, np.random.default_rng(0)).name == "generated_2x3"


@pytest.mark.parametrize(
    ("kwargs", "phrase"),
    [
        ({"rows": 0, "cols": 3}, "rows must be an integer >= 1"),
        ({"rows": 2, "cols": 2.5}, "cols must be an integer >= 1"),
        ({"rows": 2, "cols": 2, "loop_fraction": 1.5}, r"loop_fraction must be in \[0, 1\]"),
    ],
)
def test_bad_arguments(kwargs: dict, phrase: str) -> None:
    rows, cols = kwargs.pop("rows"), kwargs.pop("cols")
    with pytest.raises(MazeError, match=phrase):
        generate_maze(rows, cols, np.random.default_rng(0), **kwargs)


def test_rng_is_required() -> None:
    with pytest.raises(MazeError, match="rng must be a numpy.random.Generator"):
        generate_maze(2, 2, 42)  # type: ignore[arg-type]
