"""The 2D map of a scored run, in the competition's conventions (docs/FACTS.md, "Competition map
conventions").

A 1 m checkerboard background (226,226,227)/(237,237,238) with grid lines every
0.5 m (190,190,191); walls as occupied cells (0,40,120); the robot path
(120,0,240), 3 px, with an arrow at the start; each report a filled marker of
radius 0.175 m with its id: victims (baby dolls) and QR codes circles, hazards and other
objects diamonds, Landolt-C targets squares, as the conventions shape them. Each is in its
type's colour from the one table of type colours (``poi.annotate.TYPE_COLORS_RGB``, the
live view's too): the conventions' red victims (240,10,10), blue QR codes (10,10,240) and
orange hazmat placards (255,100,30), and the other types (doors, valves, signs, fire
extinguishers, heat sources), which the conventions draw as one orange diamond, in colours
of their own, with a legend entry a type. Light colours (white heat sources, yellow
extinguishers) are edged in a darker shade of themselves so they show on the light floor.

On top of the conventions, for scoring: ground truth as outlines of the same shapes; false
reports crossed with a black X and labelled ``false``; missed objects with a dashed outline
labelled ``miss``; reports identified but not located edged in black. The 1 m circle (the
locate radius of ex3) is drawn, thin and light, only round an object no report of its type
located while one that located nothing (false, or identified only) came within twice the
radius (:func:`circled`): there it shows by how much the report missed.
Round every object, the circles of a 4 x 4 m maze's ten or so objects overlapped into a web;
round a located object the circle only repeats what its filled marker says, and round an
object nothing came near it says nothing at all.

A false report and its X lie under the other reports' markers, so the X never hides a
marker; every label (ids, ``false``, ``miss``) is placed where it overlaps no other label
nor a marker (:class:`_Labeller`: the first free place of a few round its anchor, in its
rendered size), an id in its own marker when that is free, else beside it in black.
Everything is in the map frame, metres, equal aspect. Drawing uses matplotlib's Agg canvas
directly (no pyplot state).

RMRC mapping fiducials (``fiducial``, [RMRC2025]_; docs/RULES.md "QR mapping by fiducials") are
landmarks, not scored objects: the true ones are drawn as what the rule asks a map to show,
"at least half a circle ... seen from above", a filled grey half-disc of the pipe's diameter
(its truth text, :func:`sim.world.placement.fiducial_text`) whose flat side lies on the nearest wall;
a reported one as a dark grey half-disc of the middle diameter, 0.30 m.

The TurtleBot goal arena's objects (not in the competition's conventions) are
circles in their own colours: blue, red and green pillars, a yellow ball. A
map-error result (eval/map_error.py) draws the truth circles at its pairing
distance, and the goal: a dashed line between the two truth goal pillars, the
truth centre as a black cross and the reported centre as a filled black dot joined
to it (:class:`MapGoal`). :func:`score_layers` gives ``draw_map`` all of that from
a score result of either kind.

References
----------
Full entries in docs/SOURCES.md.

.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Polygon, Wedge
from matplotlib.text import Text
from matplotlib.transforms import Bbox

from eval.scoring.map_error import STATUS_PAIRED, MapErrorResult
from eval.scoring.scorer import STATUS_FALSE, STATUS_IGNORED, STATUS_LOCATED, ScoreResult
from maze_assets.objects import fiducial_diameter_m
from poi.annotate import DEFAULT_COLOR_RGB, TYPE_COLORS_RGB
from poi.core.names import display_name, in_type_order

GRID_STEP_M = 0.5
MARKER_RADIUS_M = 0.175
LOCATE_CIRCLE_M = 1.0
WALL_WIDTH_M = 0.05
PATH_WIDTH_PX = 3.0

CHECKER_RGB = ((226, 226, 227), (237, 237, 238))
GRID_RGB = (190, 190, 191)
WALL_RGB = (0, 40, 120)
PATH_RGB = (120, 0, 240)
FALSE_RGB = (0, 0, 0)
# The conventions' shapes: victims and QR codes circles, Landolt-C targets (not in the conventions)
# squares, every other type a diamond; the colours are the type table's (module docstring).
MARKER_SHAPES = {"baby-doll": "circle", "qr": "circle", "landolt-c": "square"}
LIGHT_LUMINANCE = 180  # an edge or outline of a colour lighter than this is drawn darker (INK_SHADE)
INK_SHADE = 0.6
# The goal arena's objects: circles in the colours they are painted (maze_assets/models.py), not the
# type table's, which picks a hue that contrasts with the paint so a box shows on the camera image;
# a map has no paint to contrast with, and a red pillar drawn magenta would mislead.
ARENA_RGB: dict[str, tuple[int, int, int]] = {
    "pillar-blue": (20, 60, 220),
    "pillar-red": (220, 30, 20),
    "pillar-green": (30, 160, 50),
    "ball": (245, 210, 10),
}
ARENA_LABELS = {"pillar-blue": "blue pillar", "pillar-red": "red pillar", "pillar-green": "green pillar"}
GOAL_RGB = (0, 0, 0)
FIDUCIAL_RGB = (150, 152, 156)  # grey PVC (maze_assets.models.FIDUCIAL_RGBA)
FIDUCIAL_REPORT_RGB = (70, 72, 76)
FIDUCIAL_DEFAULT_DIAMETER_M = 0.30

# Figure layout in pixels: axes margins, with the legend in the right margin.
_MARGIN_LEFT_PX, _MARGIN_BOTTOM_PX, _MARGIN_TOP_PX, LEGEND_WIDTH_PX = 60, 50, 40, 230

Segment = tuple[tuple[float, float], tuple[float, float]]


@dataclass(kw_only=True)
class MapReport:
    """A report on the map; ``status`` is located, identified, false or ignored."""

    id: int | None
    type: str | None
    x: float
    y: float
    status: str
    text: str = ""


@dataclass(kw_only=True)
class MapTruth:
    """A ground-truth object on the map; ``found`` False draws it as a miss."""

    x: float
    y: float
    type: str
    found: bool
    id: int | None = None
    text: str = ""


@dataclass(kw_only=True)
class MapFiducial:
    """A mapping fiducial on the map: where it is, its pipe diameter, truth or reported."""

    x: float
    y: float
    diameter_m: float = FIDUCIAL_DEFAULT_DIAMETER_M
    reported: bool = False


@dataclass(kw_only=True)
class MapGoal:
    """The goal on the map: its truth posts (2, 2) and the reported centre (None if unknown)."""

    truth_posts: tuple[tuple[float, float], tuple[float, float]]
    reported_center: tuple[float, float] | None = None


def markers_from_score(result: ScoreResult | MapErrorResult) -> tuple[list[MapReport], list[MapTruth]]:
    """Map markers of a score result: readable reports, scored objects (a paired map-error
    report is drawn as located)."""
    reports = [
        MapReport(
            id=r.id,
            type=r.type,
            text=getattr(r, "text", ""),
            x=r.x,
            y=r.y,
            status=STATUS_LOCATED if r.status == STATUS_PAIRED else r.status,
        )
        for r in result.reports
        if r.x is not None and r.y is not None
    ]
    truth = [
        MapTruth(x=o.x, y=o.y, type=o.type, text=getattr(o, "text", ""), id=o.id, found=o.found_by is not None)
        for o in result.objects
        if o.status != STATUS_IGNORED
    ]
    return reports, truth


def score_layers(result: ScoreResult | MapErrorResult) -> dict[str, Any]:
    """``draw_map`` keyword arguments for a score result: ``reports``, ``truth``, ``fiducials``
    (true and reported mapping fiducials, when there are any) and, for a map-error result,
    ``truth_circle_m`` (its pairing distance) and ``goal``."""
    reports, truth = markers_from_score(result)
    fiducials = [
        MapFiducial(x=o.x, y=o.y, diameter_m=_diameter(getattr(o, "text", "")))
        for o in result.objects
        if o.type == "fiducial"
    ] + [MapFiducial(x=r.x, y=r.y, reported=True) for r in reports if r.type == "fiducial"]
    reports = [r for r in reports if r.type != "fiducial"]
    layers: dict[str, Any] = {"reports": reports, "truth": truth}
    if fiducials:
        layers["fiducials"] = fiducials
    if isinstance(result, MapErrorResult):
        layers["truth_circle_m"] = result.rules.max_pair_distance_m
        posts = [o for o in result.objects if o.type == result.rules.goal_type]
        if result.goal is not None and len(posts) == 2:
            layers["goal"] = MapGoal(
                truth_posts=((posts[0].x, posts[0].y), (posts[1].x, posts[1].y)),
                reported_center=result.goal.reported_center,
            )
    return layers


def style_of(type_: str | None) -> tuple[str, tuple[int, int, int]]:
    """(shape, RGB) of a type: the conventions' shape in the type table's colour
    (``poi.annotate.TYPE_COLORS_RGB``); the goal arena's objects circles in their paint.

    >>> style_of("baby-doll"), style_of("qr"), style_of("hazmat")
    (('circle', (240, 10, 10)), ('circle', (10, 10, 240)), ('diamond', (255, 100, 30)))
    >>> style_of("valve"), style_of("ball"), style_of("landolt-c")
    (('diamond', (220, 0, 220)), ('circle', (245, 210, 10)), ('square', (0, 140, 120)))
    >>> style_of(None)
    ('diamond', (200, 200, 200))
    """
    if type_ in ARENA_RGB:
        return "circle", ARENA_RGB[type_]
    rgb = TYPE_COLORS_RGB.get(type_, DEFAULT_COLOR_RGB) if type_ is not None else DEFAULT_COLOR_RGB
    return MARKER_SHAPES.get(type_ or "", "diamond"), rgb


def ink(rgb: tuple[int, int, int]) -> tuple[int, int, int]:
    """The colour of a type's edges and outlines: its own, or a darker shade of a light one.

    >>> ink((10, 10, 240)), ink((255, 255, 255))
    ((10, 10, 240), (153, 153, 153))
    """
    if 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2] <= LIGHT_LUMINANCE:
        return rgb
    return (round(rgb[0] * INK_SHADE), round(rgb[1] * INK_SHADE), round(rgb[2] * INK_SHADE))


def circled(objs: Sequence[MapTruth], reps: Sequence[MapReport], circle_m: float) -> list[bool]:
    """Which objects get the locate circle: those no report of their type located (none within
    ``circle_m``) while a report of their type that located nothing (false, or identified
    only) lies within twice that (module docstring). A located report belongs to its own
    object, so it puts no circle round a neighbour.

    >>> objs = [MapTruth(x=0, y=0, type="qr", found=False), MapTruth(x=5, y=0, type="qr", found=True)]
    >>> circled(objs, [MapReport(id=1, type="qr", x=1.4, y=0, status="false"),
    ...                MapReport(id=2, type="qr", x=5.1, y=0, status="located")], 1.0)
    [True, False]
    """
    out = []
    for o in objs:
        near = [(math.hypot(r.x - o.x, r.y - o.y), r.status) for r in reps if r.type == o.type]
        located = any(d <= circle_m for d, _ in near)
        missed_by = [d for d, status in near if status != STATUS_LOCATED and d <= 2.0 * circle_m]
        out.append(not located and bool(missed_by))
    return out


def draw_map(path_png: str | Path, **kw: Any) -> Path:
    """Draw the map (:func:`map_figure`, the same keywords) and write it as a PNG of exactly
    ``size_px`` (width, height) pixels."""
    path_png = Path(path_png)
    fig = map_figure(**kw)
    fig.savefig(path_png, dpi=fig.dpi, format="png")
    return path_png


def map_figure(
    *,
    walls: Iterable[Segment],
    robot_path: np.ndarray | Sequence[Sequence[float]],
    reports: Iterable[MapReport | Mapping[str, Any]],
    truth: Iterable[MapTruth | Mapping[str, Any]],
    title: str = "",
    size_px: tuple[int, int] = (1200, 900),
    dpi: int = 100,
    truth_circle_m: float = LOCATE_CIRCLE_M,
    goal: MapGoal | None = None,
    fiducials: Iterable[MapFiducial] = (),
) -> Figure:
    """The map as a matplotlib Figure of ``size_px`` (width, height) pixels at ``dpi``.

    ``walls`` are ((x0, y0), (x1, y1)) segments and ``robot_path`` an (N, 2) array,
    both in the map frame (metres). ``reports`` and ``truth`` are :class:`MapReport` /
    :class:`MapTruth` records or mappings with the same keys. ``truth_circle_m`` is the
    radius of the circle round a truth object (drawn where :func:`circled` says); ``goal``
    draws the goal arena's goal; ``fiducials`` the mapping fiducials as half-discs against
    their nearest wall.
    """
    fids = list(fiducials)
    width_px, height_px = int(size_px[0]), int(size_px[1])
    if width_px < _MARGIN_LEFT_PX + LEGEND_WIDTH_PX + 100 or height_px < 200:
        raise ValueError(f"size_px {size_px} too small; expected at least (390, 200)")
    segs = np.asarray([np.asarray(s, dtype=float).reshape(2, 2) for s in walls]).reshape(-1, 2, 2)
    path_xy = np.asarray(robot_path, dtype=float).reshape(-1, 2)  # (N, 2)
    reps = [_as_report(r) for r in reports]
    objs = [_as_truth(t) for t in truth]

    # Axes rectangle (pixels) and a view that fills it at equal aspect.
    ax_w_px = width_px - _MARGIN_LEFT_PX - LEGEND_WIDTH_PX
    ax_h_px = height_px - _MARGIN_BOTTOM_PX - _MARGIN_TOP_PX
    xlim, ylim = _view(segs, path_xy, reps, objs, ax_w_px / ax_h_px, truth_circle_m)
    px_per_m = ax_w_px / (xlim[1] - xlim[0])

    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_axes(
        (
            _MARGIN_LEFT_PX / width_px,
            _MARGIN_BOTTOM_PX / height_px,
            ax_w_px / width_px,
            ax_h_px / height_px,
        )
    )
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal", adjustable="box")
    pt_per_px = 72.0 / dpi

    _draw_background(ax, xlim, ylim, pt_per_px)
    if len(segs):
        wall_px = max(3.0, WALL_WIDTH_M * px_per_m)
        ax.add_collection(
            LineCollection(
                segs,
                colors=[_rgb(WALL_RGB)],
                linewidths=wall_px * pt_per_px,
                zorder=2,
                capstyle="projecting",
            )
        )
    for f, facing in zip(fids, fiducial_facings(fids, segs), strict=True):
        _draw_fiducial(ax, f, facing, pt_per_px)
    rings = circled(objs, reps, truth_circle_m)
    for o, ring in zip(objs, rings, strict=True):
        _draw_truth(ax, o, pt_per_px, truth_circle_m if ring else None)
    if goal is not None:
        _draw_goal(ax, goal, pt_per_px)
    if len(path_xy):
        _draw_path(ax, path_xy, pt_per_px, px_per_m)
    for r in reps:
        _draw_report(ax, r, pt_per_px)

    # Labels last, each where it overlaps no other label nor a marker (module docstring).
    ax.apply_aspect()
    labels = _Labeller(ax, fig.canvas.get_renderer(), MARKER_RADIUS_M * px_per_m)
    for r in reps:
        labels.block_marker(r.x, r.y)
    font_pt = float(np.clip(0.9 * MARKER_RADIUS_M * px_per_m * pt_per_px, 4.0, 12.0))
    # ids of the markers on top first (a false report's lies under the others, _draw_report)
    for r in sorted(reps, key=lambda r: r.status == STATUS_FALSE):
        if r.id is not None:
            rgb = style_of(r.type)[1]
            light = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2] > 170  # the yellow ball: dark digits
            labels.place_id(r.x, r.y, str(r.id), "black" if light else "white", fontsize=font_pt)
    for r in reps:
        if r.status == STATUS_FALSE:
            labels.place_beside(r.x, r.y, "false", fontsize=8)
    for o in objs:
        if not o.found:
            labels.place_beside(o.x, o.y, "miss", fontsize=8, first="below")

    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title)
    types = {*(r.type for r in reps), *(o.type for o in objs)} - {None, "fiducial"}
    statuses = {r.status for r in reps}
    drawn = {
        "path": len(path_xy) > 0,
        "identified": bool(statuses - {STATUS_LOCATED, STATUS_FALSE}),
        "false": STATUS_FALSE in statuses,
        "truth": bool(objs),
        "circle": any(rings),
        "missed": any(not o.found for o in objs),
    }
    ax.legend(
        handles=_legend_handles(pt_per_px, drawn, truth_circle_m, types, goal is not None, bool(fids)),
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize=8,
        framealpha=1.0,
    )
    return fig


class _Labeller:
    """Places text labels where they overlap no label placed before and no blocked marker:
    the first free one of a few places round the anchor (8 directions, then twice as far),
    measured in the text's rendered size; the first place when none is free."""

    # (dx, dy) directions, the first the preferred; a label's near edge is beside the marker
    _AROUND = ((1, 1), (1, -1), (-1, 1), (-1, -1), (1, 0), (-1, 0), (0, 1), (0, -1))
    _FIRST = {"upper right": (1, 1), "below": (0, -1)}

    def __init__(self, ax: Any, renderer: Any, marker_px: float) -> None:
        self.ax, self.renderer, self.marker_px = ax, renderer, marker_px
        self.labels: list[Bbox] = []
        self.markers: list[tuple[float, float, Bbox]] = []  # (x, y) in metres, box in pixels

    def block_marker(self, x: float, y: float) -> None:
        cx, cy = self.ax.transData.transform((x, y))
        r = self.marker_px
        self.markers.append((x, y, Bbox.from_extents(cx - r, cy - r, cx + r, cy + r)))

    def _free(self, box: Bbox, own: tuple[float, float]) -> bool:
        """Whether ``box`` overlaps no placed label and no marker but the one at ``own``."""
        shrunk = box.expanded(0.98, 0.9)  # glyph boxes carry some empty margin: touching is not overlapping
        if any(shrunk.overlaps(b) for b in self.labels):
            return False
        return not any(shrunk.overlaps(b) for x, y, b in self.markers if (x, y) != own)

    def _text(self, x: float, y: float, s: str, **kw: Any) -> Text:
        return self.ax.text(x, y, s, zorder=8, **kw)

    def place_id(self, x: float, y: float, s: str, colour: str, fontsize: float) -> None:
        """An id in its marker when no other label or marker is there, else beside it in black."""
        t = self._text(x, y, s, color=colour, fontsize=fontsize, fontweight="bold", ha="center", va="center")
        box = t.get_window_extent(self.renderer)
        if self._free(box, own=(x, y)):
            self.labels.append(box)
            return
        t.remove()
        self.place_beside(x, y, s, fontsize=fontsize, fontweight="bold")

    def place_beside(self, x: float, y: float, s: str, first: str = "upper right", **kw: Any) -> None:
        """A label next to the marker at (x, y), at the first free place round it."""
        dirs = [self._FIRST[first], *(d for d in self._AROUND if d != self._FIRST[first])]
        ax = self.ax
        t = self._text(x, y, s, color="black", **kw)
        cx, cy = ax.transData.transform((x, y))
        tried: list[tuple[tuple[float, float], str, str, Bbox]] = []
        for reach in (1.25, 2.5):
            for dx, dy in dirs:
                gap = reach * self.marker_px
                pos = ax.transData.inverted().transform((cx + dx * gap, cy + dy * gap))
                ha = {1: "left", -1: "right", 0: "center"}[dx]
                va = {1: "bottom", -1: "top", 0: "center"}[dy]
                t.set_position((float(pos[0]), float(pos[1])))
                t.set_ha(ha)
                t.set_va(va)
                box = t.get_window_extent(self.renderer)
                tried.append(((float(pos[0]), float(pos[1])), ha, va, box))
                if self._free(box, own=(x, y)):
                    self.labels.append(box)
                    return
        pos, ha, va, box = tried[0]  # nowhere free: the preferred place
        t.set_position(pos)
        t.set_ha(ha)
        t.set_va(va)
        self.labels.append(box)


def _as_report(row: MapReport | Mapping[str, Any]) -> MapReport:
    if isinstance(row, MapReport):
        return row
    return MapReport(
        id=row.get("id"),
        type=row.get("type"),
        text=row.get("text", "") or "",
        x=float(row["x"]),
        y=float(row["y"]),
        status=str(row["status"]),
    )


def _as_truth(row: MapTruth | Mapping[str, Any]) -> MapTruth:
    if isinstance(row, MapTruth):
        return row
    return MapTruth(
        x=float(row["x"]),
        y=float(row["y"]),
        type=str(row["type"]),
        found=bool(row["found"]),
        id=row.get("id"),
        text=row.get("text", "") or "",
    )


def _view(
    segs: np.ndarray,
    path_xy: np.ndarray,
    reps: list[MapReport],
    objs: list[MapTruth],
    aspect: float,
    circle_m: float = LOCATE_CIRCLE_M,
) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y limits: everything plus the truth circles, whole metres, at ``aspect``."""
    pts = [segs.reshape(-1, 2), path_xy]
    pts += [np.array([[r.x, r.y]]) for r in reps]
    pts += [np.array([[o.x - circle_m, o.y - circle_m], [o.x + circle_m, o.y + circle_m]]) for o in objs]
    allp = np.concatenate([p for p in pts if p.size], axis=0) if any(p.size for p in pts) else None
    if allp is None:
        lo, hi = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    else:
        lo = np.floor(allp.min(axis=0) - 0.25)
        hi = np.ceil(allp.max(axis=0) + 0.25)
    w, h = hi - lo
    # Grow the short side about its centre so the view has the axes' aspect.
    if w / h < aspect:
        grow = aspect * h - w
        lo[0], hi[0] = lo[0] - grow / 2, hi[0] + grow / 2
    else:
        grow = w / aspect - h
        lo[1], hi[1] = lo[1] - grow / 2, hi[1] + grow / 2
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def _draw_background(ax: Any, xlim: tuple, ylim: tuple, pt_per_px: float) -> None:
    x0, x1 = math.floor(xlim[0]), math.ceil(xlim[1])
    y0, y1 = math.floor(ylim[0]), math.ceil(ylim[1])
    jj, ii = np.meshgrid(np.arange(x0, x1), np.arange(y0, y1))  # (ny, nx) cell corners
    board = np.where(((ii + jj) % 2 == 0)[..., None], CHECKER_RGB[0], CHECKER_RGB[1])
    ax.imshow(
        board.astype(np.uint8),  # (ny, nx, 3)
        extent=(x0, x1, y0, y1),
        origin="lower",
        interpolation="nearest",
        zorder=0,
    )
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    grid = _rgb(GRID_RGB)
    xs = np.arange(math.floor(xlim[0] / GRID_STEP_M), math.ceil(xlim[1] / GRID_STEP_M) + 1)
    ys = np.arange(math.floor(ylim[0] / GRID_STEP_M), math.ceil(ylim[1] / GRID_STEP_M) + 1)
    ax.vlines(xs * GRID_STEP_M, *ylim, colors=[grid], linewidths=pt_per_px, zorder=1)
    ax.hlines(ys * GRID_STEP_M, *xlim, colors=[grid], linewidths=pt_per_px, zorder=1)


def _marker(shape: str, x: float, y: float, r: float, **kw: Any) -> Any:
    if shape == "circle":
        return Circle((x, y), r, **kw)
    if shape == "square":
        a = r / math.sqrt(2.0)  # the same area as the diamond's
        return Polygon([(x + a, y + a), (x - a, y + a), (x - a, y - a), (x + a, y - a)], closed=True, **kw)
    return Polygon([(x + r, y), (x, y + r), (x - r, y), (x, y - r)], closed=True, **kw)


def _draw_truth(ax: Any, o: MapTruth, pt_per_px: float, circle_m: float | None) -> None:
    """A truth object's outline, dashed when missed, and its locate circle when ``circle_m``."""
    shape, rgb = style_of(o.type)
    colour = _rgb(ink(rgb))
    style = "solid" if o.found else (0, (4, 3))
    if circle_m is not None:
        # thin and light: it shows where a report fell short, and should not hide the floor's grid
        ax.add_patch(
            Circle(
                (o.x, o.y),
                circle_m,
                fill=False,
                edgecolor=colour,
                alpha=0.4,
                linewidth=0.8 * pt_per_px,
                linestyle=style,
                zorder=3,
            )
        )
    ax.add_patch(
        _marker(
            shape,
            o.x,
            o.y,
            MARKER_RADIUS_M * 1.35,
            fill=False,
            edgecolor=colour,
            linewidth=2.0 * pt_per_px,
            linestyle=style,
            zorder=3,
        )
    )


def _diameter(text: str) -> float:
    """A fiducial's diameter from its truth text ("300 mm"), else the middle one."""
    d = fiducial_diameter_m(text)
    return FIDUCIAL_DEFAULT_DIAMETER_M if d is None else d


def fiducial_facing_deg(x: float, y: float, segs: np.ndarray) -> float:
    """Which way a fiducial at (x, y) faces, degrees: away from the nearest wall segment (its
    flat side is on the wall); 0 (+x) without walls.

    >>> fiducial_facing_deg(0.5, 0.025, np.array([[[0.0, 0.0], [1.2, 0.0]]]))
    90.0
    """
    if not len(segs):
        return 0.0
    a, b = segs[:, 0, :], segs[:, 1, :]  # (n, 2) each
    p = np.array([x, y])
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    near = a + t[:, None] * ab  # (n, 2) the closest point of each segment
    k = int(np.argmin(np.linalg.norm(p - near, axis=1)))
    d = p - near[k]
    if np.linalg.norm(d) < 1e-9:  # on the centre line: either normal will do
        d = np.array([-ab[k, 1], ab[k, 0]])
    return float(np.degrees(np.arctan2(d[1], d[0])))


def fiducial_facings(fids: Sequence[MapFiducial], segs: np.ndarray, near_m: float = 1.0) -> list[float]:
    """Which way each fiducial faces, degrees: a true one away from its nearest wall
    (:func:`fiducial_facing_deg`); a reported one, whose centre may fall a few centimetres on
    either side of the wall, as the nearest true one within ``near_m`` does, else as its wall.

    >>> wall = np.array([[[0.0, 0.0], [2.0, 0.0]]])
    >>> fiducial_facings([MapFiducial(x=1.0, y=0.025), MapFiducial(x=1.02, y=-0.01, reported=True)], wall)
    [90.0, 90.0]
    """
    own = [fiducial_facing_deg(f.x, f.y, segs) for f in fids]
    truth = [(f, a) for f, a in zip(fids, own, strict=True) if not f.reported]
    out = []
    for f, a in zip(fids, own, strict=True):
        near = [(math.hypot(f.x - t.x, f.y - t.y), ta) for t, ta in truth] if f.reported else []
        near = [na for na in near if na[0] <= near_m]
        out.append(min(near)[1] if near else a)
    return out


def _draw_fiducial(ax: Any, f: MapFiducial, facing: float, pt_per_px: float) -> None:
    rgb = FIDUCIAL_REPORT_RGB if f.reported else FIDUCIAL_RGB
    ax.add_patch(
        Wedge(
            (f.x, f.y),
            f.diameter_m / 2,
            facing - 90.0,
            facing + 90.0,
            facecolor=_rgb(rgb),
            edgecolor="black",
            linewidth=1.0 * pt_per_px,
            alpha=0.8 if f.reported else 1.0,
            zorder=4 if f.reported else 3,
        )
    )


def _draw_goal(ax: Any, goal: MapGoal, pt_per_px: float) -> None:
    """The goal line between the truth posts (dashed), its truth centre (a cross) and the
    reported centre (a dot) joined to it."""
    (x0, y0), (x1, y1) = goal.truth_posts
    colour = _rgb(GOAL_RGB)
    ax.plot([x0, x1], [y0, y1], color=colour, linestyle=(0, (5, 3)), linewidth=1.5 * pt_per_px, zorder=3)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ax.plot([cx], [cy], marker="x", markersize=10, markeredgewidth=2.0, color=colour, zorder=6)
    if goal.reported_center is not None:
        rx, ry = goal.reported_center
        ax.plot([cx, rx], [cy, ry], color=colour, linewidth=1.0 * pt_per_px, zorder=6)
        ax.plot([rx], [ry], marker="o", markersize=6, color=colour, zorder=6)


def _draw_path(ax: Any, path_xy: np.ndarray, pt_per_px: float, px_per_m: float) -> None:
    colour = _rgb(PATH_RGB)
    ax.plot(
        path_xy[:, 0],
        path_xy[:, 1],
        color=colour,
        linewidth=PATH_WIDTH_PX * pt_per_px,
        solid_capstyle="round",
        zorder=4,
    )
    # Arrow at the start, along the path's first 0.4 m (or what there is of it).
    steps = np.linalg.norm(np.diff(path_xy, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(steps)])
    k = int(np.searchsorted(along, 0.4))
    k = min(max(k, 1), len(path_xy) - 1) if len(path_xy) > 1 else 0
    if k and along[k] > 0:
        ax.annotate(
            "",
            xy=tuple(path_xy[k]),
            xytext=tuple(path_xy[0]),
            arrowprops={
                "arrowstyle": "-|>",
                "color": colour,
                "lw": PATH_WIDTH_PX * pt_per_px,
                "mutation_scale": max(12.0, 0.3 * px_per_m * pt_per_px),
            },
            zorder=4,
        )


def _draw_report(ax: Any, r: MapReport, pt_per_px: float) -> None:
    """A report's filled marker (its id is placed with the other labels); a false one with its X,
    both under every other report's marker (zorder 4.6 and 4.7 against 5), so no X hides one."""
    shape, rgb = style_of(r.type)
    false = r.status == STATUS_FALSE
    edge = "black" if r.status != STATUS_LOCATED and not false else _rgb(ink(rgb))
    z = 4.6 if false else 5.0
    ax.add_patch(
        _marker(
            shape,
            r.x,
            r.y,
            MARKER_RADIUS_M,
            facecolor=_rgb(rgb),
            edgecolor=edge,
            linewidth=(1.0 if edge != "black" else 1.5) * pt_per_px,
            zorder=z,
        )
    )
    if false:
        d = MARKER_RADIUS_M * 1.2
        for ys in ((r.y - d, r.y + d), (r.y + d, r.y - d)):
            ax.plot([r.x - d, r.x + d], ys, color=_rgb(FALSE_RGB), linewidth=2.0 * pt_per_px, zorder=z + 0.1)


def _legend_handles(
    pt_per_px: float,
    drawn: dict[str, bool],
    circle_m: float = LOCATE_CIRCLE_M,
    types: Iterable[str] = (),
    goal: bool = False,
    fiducials: bool = False,
) -> list[Line2D]:
    """The legend: the path and walls, an entry a type on the map (in the type table's order,
    its shape and colour, :func:`style_of`), then what outlines, crosses and circles mean; of the
    path, outlines, crosses, circles and dashes only those ``drawn`` says the map shows (keys
    ``path``, ``identified``, ``false``, ``truth``, ``circle``, ``missed``)."""

    def h(label: str, **kw: Any) -> Line2D:
        return Line2D([], [], label=label, **kw)

    ms = 9
    head = [h("wall", color=_rgb(WALL_RGB), linewidth=4 * pt_per_px)]
    if drawn["path"]:
        head.insert(0, h("robot path", color=_rgb(PATH_RGB), linewidth=PATH_WIDTH_PX * pt_per_px))
    present = set(types)
    marker_of = {"circle": "o", "square": "s", "diamond": "D"}
    kinds = []
    for t in in_type_order(present):
        shape, rgb = style_of(t)
        label = ARENA_LABELS.get(t, "victim (baby doll)" if t == "baby-doll" else display_name(t))
        kinds.append(_swatch(h, label, rgb, ms * (1.0 if shape == "circle" else 0.85), marker=marker_of[shape]))
    arena = any(t in ARENA_RGB for t in present)
    meanings = {
        "identified": h(
            "identified, not located",
            marker="o",
            linestyle="",
            markersize=ms,
            markerfacecolor="0.6",
            markeredgecolor="black",
        ),
        "false": h(
            "false report",
            marker="x",
            linestyle="",
            markersize=ms,
            color="black",
            markeredgewidth=2,
        ),
        "truth": h(
            "ground truth",
            marker="o",
            linestyle="",
            markersize=ms,
            markerfacecolor="none",
            markeredgecolor="0.3",
            markeredgewidth=1.5,
        ),
        "circle": h(
            f"{circle_m:g} m round an object a report just missed",
            marker="o",
            linestyle="",
            markersize=ms * 1.6,
            markerfacecolor="none",
            markeredgecolor="0.6",
            markeredgewidth=0.8,
        ),
        "missed": h("missed object (dashed)", color="0.3", linestyle=(0, (4, 3)), linewidth=1.5),
    }
    tail = [e for key, e in meanings.items() if drawn[key] and not (arena and key == "identified")]
    if fiducials:
        for label, rgb in (("fiducial (truth)", FIDUCIAL_RGB), ("fiducial (reported)", FIDUCIAL_REPORT_RGB)):
            tail.append(
                h(
                    label,
                    marker="o",
                    fillstyle="top",
                    linestyle="",
                    markersize=ms,
                    markerfacecolor=_rgb(rgb),
                    markerfacecoloralt="none",
                    markeredgecolor="black",
                )  # fmt: skip
            )
    if goal:
        tail += [
            h("goal line (truth)", color="black", linestyle=(0, (5, 3)), linewidth=1.5),
            h("goal centre: truth", marker="x", linestyle="", markersize=8, color="black", markeredgewidth=2),
            h("goal centre: reported", marker="o", linestyle="", markersize=6, color="black"),
        ]
    return head + kinds + tail


def _swatch(h: Any, label: str, rgb: tuple[int, int, int], ms: float, marker: str = "o") -> Line2D:
    """A legend entry: a marker filled in ``rgb`` and edged in its :func:`ink`."""
    return h(
        label,
        marker=marker,
        linestyle="",
        markersize=ms,
        markerfacecolor=_rgb(rgb),
        markeredgecolor=_rgb(ink(rgb)),
    )


def _rgb(rgb: tuple[int, int, int]) -> tuple[float, float, float]:
    return (rgb[0] / 255.0, rgb[1] / 255.0, rgb[2] / 255.0)
