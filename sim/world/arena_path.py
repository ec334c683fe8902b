"""Free space of an open floor and a shortest path through it for a disc-shaped robot.

A :class:`FloorPlan` is a rectangle ``[0, W] x [0, H]`` (world x, y, metres) bounded by
walls, with round (discs) and axis-aligned square (boxes) things standing on it.
:func:`plan_path` finds a path for a robot of radius ``r``: A* over an 8-connected grid
of ``grid_m`` cells whose centres have clearance >= r, then line-of-sight shortcuts
(each kept segment checked every ``CHECK_STEP_M`` along its length), so the result is a
few straight legs, each clear of everything by r. No randomness; ties in the search are
broken by insertion order, so the same plan gives the same path.

>>> plan = FloorPlan(size_m=(4.0, 2.0), discs=[(np.array([2.0, 1.0]), 0.3)])
>>> path = plan_path(plan, np.array([0.5, 1.0]), np.array([3.5, 1.0]), radius_m=0.2)
>>> len(path) >= 3, bool(all(plan.segment_clear(a, b, 0.2) for a, b in zip(path[:-1], path[1:])))
(True, True)
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np

CHECK_STEP_M = 0.01  # clearance is checked this often along a leg
GRID_M = 0.05  # A* cell size


def point_box_distance(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` (..., 2) to the axis-aligned box [lo, hi] (0 inside).

    >>> float(point_box_distance(np.array([3.0, 4.0]), np.zeros(2), np.ones(2)))
    3.605551275463989
    """
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)  # (..., 2)
    return np.linalg.norm(d, axis=-1)


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` (..., 2) to the segment ab.

    >>> float(point_segment_distance(np.array([1.0, 1.0]), np.zeros(2), np.array([2.0, 0.0])))
    1.0
    """
    ab = b - a
    L2 = float(ab @ ab)
    t = np.zeros(np.shape(p)[:-1]) if L2 == 0.0 else np.clip(((p - a) @ ab) / L2, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)


def segment_box_distance(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float:
    """Distance between the segment ab and the axis-aligned box [lo, hi] (0 if they meet).

    Two disjoint convex sets are closest at a vertex of one of them, so the distance is
    the least of the endpoints' distances to the box and the corners' to the segment;
    a segment crossing the box (Liang-Barsky clip) is at distance 0.

    >>> segment_box_distance(np.array([-1.0, 0.5]), np.array([2.0, 0.5]), np.zeros(2), np.ones(2))
    0.0
    >>> segment_box_distance(np.array([-1.0, 2.0]), np.array([2.0, 2.0]), np.zeros(2), np.ones(2))
    1.0
    """
    t0, t1 = 0.0, 1.0
    d = b - a
    crosses = True
    for k in range(2):
        if abs(d[k]) < 1e-15:
            if a[k] < lo[k] or a[k] > hi[k]:
                crosses = False
                break
            continue
        u0, u1 = sorted(((lo[k] - a[k]) / d[k], (hi[k] - a[k]) / d[k]))
        t0, t1 = max(t0, u0), min(t1, u1)
        if t0 > t1:
            crosses = False
            break
    if crosses:
        return 0.0
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    ends = np.stack([a, b])
    return float(min(point_box_distance(ends, lo, hi).min(), point_segment_distance(corners, a, b).min()))


@dataclass(kw_only=True)
class FloorPlan:
    """A walled rectangle ``size_m`` with discs (centre, radius) and boxes (lo, hi) on it.

    ``wall_m`` is the walls' half thickness inside the rectangle's edges.
    """

    size_m: tuple[float, float]
    discs: list[tuple[np.ndarray, float]] = field(default_factory=list)
    boxes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    wall_m: float = 0.0

    def clearance(self, p: np.ndarray) -> np.ndarray:
        """Distance from points ``p`` (..., 2) to the nearest wall, disc or box."""
        p = np.asarray(p, dtype=float)
        W, H = self.size_m
        c = np.minimum(np.minimum(p[..., 0], W - p[..., 0]), np.minimum(p[..., 1], H - p[..., 1])) - self.wall_m
        for centre, r in self.discs:
            c = np.minimum(c, np.linalg.norm(p - centre, axis=-1) - r)
        for lo, hi in self.boxes:
            c = np.minimum(c, point_box_distance(p, lo, hi))
        return c

    def segment_clear(self, a: np.ndarray, b: np.ndarray, radius_m: float) -> bool:
        """Whether a disc of ``radius_m`` moved along ab touches nothing."""
        n = max(2, int(math.ceil(float(np.linalg.norm(b - a)) / CHECK_STEP_M)) + 1)
        pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)  # (n, 2)
        return bool(np.all(self.clearance(pts) >= radius_m))


_STEPS = [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]


def plan_path(
    plan: FloorPlan, start: np.ndarray, goal: np.ndarray, *, radius_m: float, grid_m: float = GRID_M
) -> list[np.ndarray] | None:
    """Waypoints from ``start`` to ``goal`` (both included) for a disc of ``radius_m``, or
    None when either end is not clear or no path exists (see the module docstring)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    if plan.clearance(start) < radius_m or plan.clearance(goal) < radius_m:
        return None
    if plan.segment_clear(start, goal, radius_m):
        return [start, goal]
    W, H = plan.size_m
    nx, ny = int(math.floor(W / grid_m)), int(math.floor(H / grid_m))
    xs = (np.arange(nx) + 0.5) * grid_m
    ys = (np.arange(ny) + 0.5) * grid_m
    centres = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)  # (nx, ny, 2)
    free = plan.clearance(centres) >= radius_m  # (nx, ny)

    def cell(p: np.ndarray) -> tuple[int, int]:
        return (int(np.clip(p[0] // grid_m, 0, nx - 1)), int(np.clip(p[1] // grid_m, 0, ny - 1)))

    s, g = cell(start), cell(goal)
    free[s] = free[g] = True  # the exact ends are clear; their cells' centres may be a hair less so

    # A* with the octile distance as an admissible heuristic; ties in insertion order
    def h(c: tuple[int, int]) -> float:
        dx, dy = abs(c[0] - g[0]), abs(c[1] - g[1])
        return (max(dx, dy) + (math.sqrt(2.0) - 1.0) * min(dx, dy)) * grid_m

    best = {s: 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(h(s), 0, s)]
    counter = 1
    done: set[tuple[int, int]] = set()
    while heap:
        _, _, cur = heapq.heappop(heap)
        if cur in done:
            continue
        if cur == g:
            break
        done.add(cur)
        for dx, dy in _STEPS:
            nb = (cur[0] + dx, cur[1] + dy)
            if not (0 <= nb[0] < nx and 0 <= nb[1] < ny) or not free[nb] or nb in done:
                continue
            if dx and dy and not (free[cur[0] + dx, cur[1]] and free[cur[0], cur[1] + dy]):
                continue  # no corner cutting
            cost = best[cur] + grid_m * (math.sqrt(2.0) if dx and dy else 1.0)
            if cost < best.get(nb, math.inf):
                best[nb] = cost
                parent[nb] = cur
                heapq.heappush(heap, (cost + h(nb), counter, nb))
                counter += 1
    if g not in best:
        return None
    cells = [g]
    while cells[-1] != s:
        cells.append(parent[cells[-1]])
    cells.reverse()
    pts = [start] + [centres[c] for c in cells[1:-1]] + [goal]
    # line-of-sight shortcuts: from each kept point, the farthest later point in view
    out = [pts[0]]
    i = 0
    while i < len(pts) - 1:
        j = len(pts) - 1
        while j > i + 1 and not plan.segment_clear(pts[i], pts[j], radius_m):
            j -= 1
        out.append(pts[j])
        i = j
    return out
