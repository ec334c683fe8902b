"""A cell-by-cell route that visits every reachable cell of a maze.

The route walks a breadth-first (shortest-path) spanning tree of the maze from
the start cell, depth first. At every branch point it takes the shallower
subtrees first and the deepest last, so near side branches and dead ends are
explored before the robot moves on, and the walk can stop at the end of the
deepest branch instead of returning: with n reachable cells and a tree of
height H the route has 2 (n - 1) - H steps (every tree edge walked twice,
except those on the final branch). No randomness: ties go in the order north,
east, south, west.

>>> from sim.world.maze import parse_maze
>>> m = parse_maze('''
... +---+---+---+
... |           |
... +   +---+---+
... |           |
... +---+---+---+
... ''')
>>> plan_tour(m)  # the north branch (height 2) first, the south one (height 3) last
[(0, 0), (0, 1), (0, 2), (0, 1), (0, 0), (1, 0), (1, 1), (1, 2)]
"""

from __future__ import annotations

from collections import deque

from sim.world.maze import Maze


def plan_tour(maze: Maze, start_cell: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """Cells to visit in order, from ``start_cell`` (default: the maze's start).

    Consecutive cells are adjacent and open to each other; every cell reachable
    from the start appears at least once; the route does not return to the start
    at the end.
    """
    start = maze.start_cell if start_cell is None else (int(start_cell[0]), int(start_cell[1]))
    maze.check_cell(start)

    # Breadth-first spanning tree: parent links and children in N, E, S, W order.
    children: dict[tuple[int, int], list[tuple[int, int]]] = {start: []}
    order = [start]
    queue = deque([start])
    while queue:
        cur = queue.popleft()
        for nb in maze.open_neighbours(*cur):
            if nb not in children:
                children[nb] = []
                children[cur].append(nb)
                order.append(nb)
                queue.append(nb)

    # Height of each subtree (edges to its deepest leaf), leaves first.
    height = {cell: 0 for cell in order}
    for cell in reversed(order):
        for child in children[cell]:
            height[cell] = max(height[cell], height[child] + 1)
    for cell in order:  # stable sort keeps N, E, S, W order among equal heights
        children[cell].sort(key=lambda child: height[child])

    # Depth-first walk of the tree, iteratively: enter a child, come back after its subtree.
    route = [start]
    stack = [(start, iter(children[start]))]
    while stack:
        cell, pending = stack[-1]
        child = next(pending, None)
        if child is None:
            stack.pop()
            if stack:
                route.append(stack[-1][0])  # back to the parent
            continue
        route.append(child)
        stack.append((child, iter(children[child])))

    # Drop the walk back to the start after the last new cell.
    seen: set[tuple[int, int]] = set()
    last_new = 0
    for i, cell in enumerate(route):
        if cell not in seen:
            seen.add(cell)
            last_new = i
    return route[: last_new + 1]
