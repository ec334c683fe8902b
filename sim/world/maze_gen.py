"""Random mazes: a perfect maze by randomised depth-first search, then loops.

1. Randomised DFS ("recursive backtracker", run with an explicit stack) from
   cell (0, 0): from the cell on top of the stack, knock down the wall to an
   unvisited neighbour chosen by ``rng`` and push it; pop when none is left.
   This gives a spanning tree: rows * cols - 1 passages, every cell reachable.
2. Of the internal walls still standing, remove ``round(loop_fraction * n)``
   chosen by ``rng`` without replacement; each one removed closes a loop.

All randomness comes from the ``rng`` argument, so the same seed gives the
same maze.

>>> m = generate_maze(3, 4, np.random.default_rng(7))
>>> (m.rows, m.cols, m.start_cell)
(3, 4, (0, 0))
>>> m == generate_maze(3, 4, np.random.default_rng(7))
True
>>> len(m.reachable_from((0, 0))) == 12
True
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from poi.core.loader import number
from sim.world.maze import DIRECTIONS, MAX_MAZE_SIDE, PRESETS, Maze, MazeError, MazeSettings, default_start_heading


@dataclass(kw_only=True)
class MazeGenerate:
    rows: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    cols: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    loop_fraction: float = 0.15
    preset: Literal["rrl", "rmrc"] = "rrl"

    def __post_init__(self) -> None:
        if not (1 <= self.rows <= MAX_MAZE_SIDE and 1 <= self.cols <= MAX_MAZE_SIDE):
            raise ValueError(
                f"maze size must be from 1x1 to {MAX_MAZE_SIDE}x{MAX_MAZE_SIDE}, got {self.rows}x{self.cols}"
            )
        if not 0.0 <= self.loop_fraction <= 1.0:
            raise ValueError(f"loop_fraction must be in [0, 1], got {self.loop_fraction}")


def generate_maze(
    rows: int,
    cols: int,
    rng: np.random.Generator,
    *,
    loop_fraction: float = 0.15,
    settings: MazeSettings = PRESETS["rrl"],
    name: str | None = None,
) -> Maze:
    """A random connected maze of ``rows`` x ``cols`` cells with some loops.

    ``loop_fraction`` (0..1) is the share of the internal walls left by the
    perfect maze that are removed afterwards (0: a perfect maze, no loops; 1: no
    internal walls). The robot starts in cell (0, 0) facing an open neighbour.
    ``name`` defaults to ``generated_{rows}x{cols}``.
    """
    for label, value in (("rows", rows), ("cols", cols)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise MazeError(f"generate_maze: {label} must be an integer >= 1, got {value!r}")
    if not isinstance(rng, np.random.Generator):
        raise MazeError(f"generate_maze: rng must be a numpy.random.Generator, got {type(rng).__name__}")
    if not (0.0 <= float(loop_fraction) <= 1.0):
        raise MazeError(f"generate_maze: loop_fraction must be in [0, 1], got {loop_fraction!r}")
    rows, cols = int(rows), int(cols)
    h_walls = np.ones((rows + 1, cols), dtype=bool)
    v_walls = np.ones((rows, cols + 1), dtype=bool)

    # 1. Randomised depth-first search: a spanning tree of the grid.
    visited = np.zeros((rows, cols), dtype=bool)
    visited[0, 0] = True
    stack = [(0, 0)]
    steps = list(DIRECTIONS.values())
    while stack:
        r, c = stack[-1]
        options = [
            (r + dr, c + dc)
            for dr, dc in steps
            if 0 <= r + dr < rows and 0 <= c + dc < cols and not visited[r + dr, c + dc]
        ]
        if not options:
            stack.pop()
            continue
        nb = options[int(rng.integers(len(options)))]
        _open(h_walls, v_walls, (r, c), nb)
        visited[nb] = True
        stack.append(nb)

    # 2. Loops: remove a share of the internal walls still standing.
    standing = _internal_walls(h_walls, v_walls)
    n_remove = int(round(float(loop_fraction) * len(standing)))
    if n_remove:
        for k in rng.choice(len(standing), size=n_remove, replace=False):
            _open(h_walls, v_walls, *standing[int(k)])

    return Maze(
        rows=rows,
        cols=cols,
        h_walls=h_walls,
        v_walls=v_walls,
        settings=settings,
        start_cell=(0, 0),
        start_heading_rad=default_start_heading(h_walls, v_walls, (0, 0)),
        name=name if name is not None else f"generated_{rows}x{cols}",
    )


def _open(h_walls: np.ndarray, v_walls: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> None:
    """Remove the wall between grid-adjacent cells a and b."""
    (ra, ca), (rb, cb) = a, b
    if ca == cb:
        h_walls[max(ra, rb), ca] = False
    else:
        v_walls[ra, max(ca, cb)] = False


def _internal_walls(h_walls: np.ndarray, v_walls: np.ndarray) -> list[tuple[tuple[int, int], ...]]:
    """Standing internal walls as (cell_a, cell_b) pairs, in a fixed (row-major) order."""
    rows, cols = v_walls.shape[0], h_walls.shape[1]
    out = []
    for r in range(rows):
        for c in range(cols):
            if c + 1 < cols and v_walls[r, c + 1]:
                out.append(((r, c), (r, c + 1)))
            if r + 1 < rows and h_walls[r + 1, c]:
                out.append(((r, c), (r + 1, c)))
    return out
