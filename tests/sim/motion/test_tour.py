"""Tests for sim/motion/tour.py: a route through every reachable cell."""

from __future__ import annotations

import numpy as np
import pytest

from sim.motion.tour import plan_tour
from sim.world.maze import Maze, available_mazes, find_maze, load_maze, parse_maze
from sim.world.maze_gen import generate_maze


def _check_route(m: Maze, route: list[tuple[int, int]], start: tuple[int, int]) -> None:
    assert route[0] == start
    for a, b in zip(route, route[1:], strict=False):
        assert m.is_open(a, b), f"step {a} -> {b} crosses a wall or is not adjacent"
    assert set(route) == set(m.reachable_from(start))
    # The route stops at the last new cell: its final cell is visited there for the first time.
    assert route[-1] not in route[:-1]


def _tree_height(m: Maze, start: tuple[int, int]) -> int:
    return max(m.reachable_from(start).values())


@pytest.mark.parametrize("name", available_mazes())
def test_tour_of_shipped_mazes(name: str) -> None:
    m = load_maze(find_maze(name))
    route = plan_tour(m)
    _check_route(m, route, m.start_cell)


@pytest.mark.parametrize("seed", range(5))
def test_tour_of_generated_mazes(seed: int) -> None:
    m = generate_maze(7, 9, np.random.default_rng(seed))
    route = plan_tour(m)
    _check_route(m, route, (0, 0))
    # Walking a shortest-path tree and stopping at its deepest leaf:
    # 2 (n - 1) - H steps, n cells, H the largest BFS distance from the start.
    assert len(route) - 1 == 2 * (m.rows * m.cols - 1) - _tree_height(m, (0, 0))


def test_tour_is_deterministic_and_hand_checked() -> None:
    # rrl_small: a corridor (0, 0) -> (0, 1) -> (1, 1), where it branches east to (1, 2)
    # (two one-cell spurs, subtree height 1) and west to (1, 0) -> (2, 0) -> (2, 1) (height 2).
    # The shallower east branch comes first, its north spur before its south one, and the
    # route ends at (2, 1), the farthest cell, without walking back.
    m = load_maze(find_maze("rrl_small"))
    expected = [
        (0, 0), (0, 1), (1, 1),
        (1, 2), (0, 2), (1, 2), (2, 2), (1, 2), (1, 1),
        (1, 0), (2, 0), (2, 1),
    ]  # fmt: skip
    assert plan_tour(m) == expected
    assert plan_tour(m) == expected  # no hidden state
    # 9 cells, farthest cell 5 steps away: 2 * 8 - 5 = 11 steps.
    assert len(expected) - 1 == 11


def test_tour_from_other_start_and_unreachable_cells() -> None:
    # (0, 2) is walled in; a Maze built in code may have it, and the tour skips it.
    m = generate_maze(3, 3, np.random.default_rng(0), loop_fraction=0.0)
    h, v = m.h_walls.copy(), m.v_walls.copy()
    h[1, 2] = True
    v[0, 2] = True
    closed = Maze(
        rows=3,
        cols=3,
        h_walls=h,
        v_walls=v,
        settings=m.settings,
        start_cell=(2, 2),
        start_heading_rad=0.0,
        name="closed",
    )
    route = plan_tour(closed, start_cell=(2, 0))
    assert (0, 2) not in route
    _check_route(closed, route, (2, 0))


def test_one_cell_maze() -> None:
    assert plan_tour(parse_maze("+---+\n|   |\n+---+\n")) == [(0, 0)]
