"""Mapping fiducials from depth: half-cylinders standing against walls, found in the map.

The RMRC labyrinth's fiducials ([RMRC2025]_, docs/RULES.md "QR mapping by fiducials") are half
of a 250-350 mm PVC pipe, 500 mm long, standing on the floor with the cut face on a wall. Seen
from above they are half a circle; nothing else in a labyrinth is a low, round bump on a wall.
:class:`FiducialMapper` finds them from the depth images and poses alone (**poibench**'s own
simple method; no detector class, no ground truth):

1. every ``every_n_frames``-th frame with a pose and depth, every ``stride_px``-th pixel within
   ``max_range_m`` is deprojected into the map frame (the camera pose is the frame's tracker
   pose times the mount, as the pipeline localises with);
2. points ``low_m`` above the floor (below a fiducial's top) and points ``high_m`` above it
   (walls, never a fiducial) are counted in two floor grids of ``cell_m`` cells, and the low
   points in the top ``top_m`` of the low band are marked in a third;
3. at the end, cells hit ``min_hits`` times low and never high (within two cells) are what
   stands low in front of the walls; each 8-connected group of at least ``min_cells`` such
   cells is the visible arc of one candidate, if at least ``min_top_fraction`` of its cells
   reach the top of the band (a 500 mm pipe does; a doll lying on the floor does not);
4. a circle is fitted to the group's cell centres (an algebraic fit [Kasa1976]_ to start, then
   least squares on the geometric distance with the radius bounded to ``radius_m``); a fit
   whose RMS residual is at most ``max_rms_m`` is a fiducial, reported at the circle's
   centre (on the wall face, the axis) at half the pipe's length above the floor.

Its limits: anything low, round and at least 0.3 m tall against a wall passes (in the default
scenario under ``--rules rmrc2026`` with the oracle detector it reports nothing; without the
top-of-band check it reported the baby doll and the fire extinguisher); a fiducial seen only
edge-on gives too short an arc to fit; pose drift moves the arcs of later passes.

>>> m = FiducialMapper(FiducialConfig(enabled=True))
>>> m.landmarks(start_id=0)
[]

References
----------
Full entries in docs/SOURCES.md.

.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
.. [Kasa1976] I. Kåsa, "A circle fitting procedure and its error analysis", IEEE Transactions on
   Instrumentation and Measurement, 1976.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares

from poi.config import FiducialConfig
from poi.core.types import Frame, TrackSnapshot

FIDUCIAL_HALF_LENGTH_M = 0.25  # the reported height: half the 500 mm pipe


@dataclass(kw_only=True)
class FiducialFit:
    """One circle fitted to a group of low cells: centre (x, y) in the map, radius, RMS residual."""

    x: float
    y: float
    radius_m: float
    rms_m: float
    cells: int
    first_seen_s: float


def fit_circle(xy: np.ndarray, radius_m: tuple[float, float]) -> tuple[np.ndarray, float, float]:
    """Centre (2,), radius and RMS residual of the circle through points ``xy`` (n, 2), the
    radius bounded to ``radius_m`` (module docstring, step 4).

    >>> a = np.linspace(-1.4, 1.4, 30)  # an arc of a 0.15 m circle centred at (1, 2)
    >>> c, r, rms = fit_circle(np.c_[1 + 0.15 * np.cos(a), 2 + 0.15 * np.sin(a)], (0.12, 0.18))
    >>> np.round(c, 4).tolist(), round(r, 4), rms < 1e-6
    ([1.0, 2.0], 0.15, True)
    """
    A = np.c_[2 * xy, np.ones(len(xy))]  # (n, 3)
    b = (xy**2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)  # Kasa: x^2 + y^2 = 2 a x + 2 b y + c
    r0 = float(np.sqrt(max(sol[2] + sol[0] ** 2 + sol[1] ** 2, 0.0)))
    lo, hi = radius_m
    x0 = [sol[0], sol[1], float(np.clip(r0, lo + 1e-6, hi - 1e-6))]
    res = least_squares(
        lambda q: np.linalg.norm(xy - q[:2], axis=1) - q[2],
        x0=x0,
        bounds=([-np.inf, -np.inf, lo], [np.inf, np.inf, hi]),
    )
    return res.x[:2], float(res.x[2]), float(np.sqrt(np.mean(res.fun**2)))


class FiducialMapper:
    """Accumulates depth into floor grids and finds the fiducials at the end (module docstring)."""

    def __init__(self, cfg: FiducialConfig) -> None:
        self.cfg = cfg
        self._low: dict[tuple[int, int], int] = {}
        self._high: set[tuple[int, int]] = set()
        self._top: set[tuple[int, int]] = set()
        self._first_seen: dict[tuple[int, int], float] = {}
        self._frames = 0

    def add(self, frame: Frame, T_map_camera: np.ndarray) -> None:
        """Count one frame's depth (every ``every_n_frames``-th call is used)."""
        self._frames += 1
        if frame.depth_m is None or (self._frames - 1) % self.cfg.every_n_frames:
            return
        s = self.cfg.stride_px
        K = frame.intrinsics
        d = np.asarray(frame.depth_m, dtype=np.float64)[::s, ::s]  # (h, w)
        v, u = np.mgrid[0 : d.shape[0], 0 : d.shape[1]]
        z = d.ravel()
        ok = np.isfinite(z) & (z > 0.1) & (z < self.cfg.max_range_m)
        u = u.ravel()[ok] * s + 0.5 * (s - 1)
        v = v.ravel()[ok] * s + 0.5 * (s - 1)
        z = z[ok]
        P = np.c_[(u - K.ppx) / K.fx * z, (v - K.ppy) / K.fy * z, z]  # (n, 3) optical frame
        P = P @ T_map_camera[:3, :3].T + T_map_camera[:3, 3]  # (n, 3) map frame
        cell = np.floor(P[:, :2] / self.cfg.cell_m).astype(np.int64)  # (n, 2)
        lo_m, hi_m = self.cfg.low_m, self.cfg.high_m
        low = (P[:, 2] >= lo_m[0]) & (P[:, 2] <= lo_m[1])
        high = (P[:, 2] >= hi_m[0]) & (P[:, 2] <= hi_m[1])
        keys, counts = np.unique(cell[low], axis=0, return_counts=True)
        for (i, j), c in zip(keys.tolist(), counts.tolist(), strict=True):
            self._low[(i, j)] = self._low.get((i, j), 0) + c
            self._first_seen.setdefault((i, j), frame.timestamp_s)
        self._high.update(map(tuple, np.unique(cell[high], axis=0).tolist()))
        top = low & (P[:, 2] >= lo_m[1] - self.cfg.top_m)
        self._top.update(map(tuple, np.unique(cell[top], axis=0).tolist()))

    def fits(self) -> list[FiducialFit]:
        """The fiducials found so far (module docstring, steps 3 and 4), west to east."""
        cfg = self.cfg
        cells = [k for k, c in self._low.items() if c >= cfg.min_hits]
        if not cells:
            return []
        ij = np.array(cells)  # (n, 2)
        hi = np.array(sorted(self._high)).reshape(-1, 2)
        lo_corner = ij.min(axis=0) - 3
        shape = tuple(ij.max(axis=0) - lo_corner + 4)
        low = np.zeros(shape, np.uint8)
        low[ij[:, 0] - lo_corner[0], ij[:, 1] - lo_corner[1]] = 1
        high = np.zeros(shape, np.uint8)
        inside = np.all((hi >= lo_corner) & (hi < lo_corner + np.array(shape)), axis=1)
        high[hi[inside, 0] - lo_corner[0], hi[inside, 1] - lo_corner[1]] = 1
        high = cv2.dilate(high, np.ones((5, 5), np.uint8))  # two cells round every wall hit
        n, lab, stats, _ = cv2.connectedComponentsWithStats(low & (1 - high), connectivity=8)
        out = []
        for k in range(1, n):
            if stats[k, cv2.CC_STAT_AREA] < cfg.min_cells:
                continue
            g = np.argwhere(lab == k)  # (m, 2) grid indices
            keys = [(int(i), int(j)) for i, j in g + lo_corner]  # (m,) grid cells
            if sum(key in self._top for key in keys) < cfg.min_top_fraction * len(keys):
                continue  # nothing of it reaches the top of the band: lower than a pipe
            xy = (g + lo_corner + 0.5) * cfg.cell_m  # (m, 2) cell centres, map frame
            if np.ptp(xy, axis=0).max() > 2.5 * cfg.radius_m[1]:
                continue  # longer than any pipe: a low wall or a box
            c, r, rms = fit_circle(xy, cfg.radius_m)
            if rms > cfg.max_rms_m:
                continue
            seen = min(self._first_seen[key] for key in keys)
            out.append(
                FiducialFit(x=float(c[0]), y=float(c[1]), radius_m=r, rms_m=rms, cells=len(g), first_seen_s=seen)
            )
        return sorted(out, key=lambda f: (f.x, f.y))

    def landmarks(self, start_id: int) -> list[TrackSnapshot]:
        """The fiducials as confirmed snapshots for the POI file, report ids from ``start_id``."""
        return [
            TrackSnapshot(
                track_id=-1 - k,
                report_id=start_id + k,
                type="fiducial",
                text="",
                position_map=np.array([f.x, f.y, FIDUCIAL_HALF_LENGTH_M]),
                covariance=np.diag([f.rms_m**2 + self.cfg.cell_m**2] * 2 + [0.01]),
                first_seen_s=f.first_seen_s,
                support=1.0,
                n_detections=f.cells,
                confirmed=True,
                extra={"radius_m": round(f.radius_m, 4), "rms_m": round(f.rms_m, 4)},
            )
            for k, f in enumerate(self.fits())
        ]
