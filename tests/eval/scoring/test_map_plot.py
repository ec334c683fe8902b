"""The map PNG: its size, the type table's colours with a legend, circles, crosses and labels
that do not hide one another."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from eval.scoring.map_plot import (
    ARENA_RGB,
    CHECKER_RGB,
    GRID_RGB,
    LEGEND_WIDTH_PX,
    PATH_RGB,
    WALL_RGB,
    MapReport,
    MapTruth,
    draw_map,
    map_figure,
    markers_from_score,
    style_of,
)
from eval.scoring.rules import load_rules
from eval.scoring.scorer import score
from poi.annotate import TYPE_COLORS_RGB
from poi.core.names import ARENA_TYPES, TYPES
from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text, parse_poi_text

VICTIM_RGB, QR_RGB, HAZARD_RGB = (TYPE_COLORS_RGB[t] for t in ("baby-doll", "qr", "hazmat"))

WALLS = [
    ((-1, -1), (5, -1)),
    ((5, -1), (5, 3)),
    ((5, 3), (-1, 3)),
    ((-1, 3), (-1, -1)),
    ((1, -1), (1, 1.5)),
]


def _count(img: np.ndarray, rgb: tuple[int, int, int]) -> int:
    """Pixels of exactly this colour left of the legend (edges blend, interiors are exact)."""
    the_map = img[:, : img.shape[1] - LEGEND_WIDTH_PX]  # (H, W - legend, 3)
    return int(np.all(the_map == np.array(rgb, dtype=np.uint8), axis=2).sum())


def _draw(tmp_path: Path, reports, truth, **kw) -> np.ndarray:
    t = np.linspace(0.0, 1.0, 40)
    path = np.stack([4.0 * t, 2.0 * np.sin(3.0 * t)], axis=1)  # (40, 2)
    out = draw_map(
        tmp_path / "map.png",
        walls=WALLS,
        robot_path=path,
        reports=reports,
        truth=truth,
        title="trial 1",
        **kw,
    )
    assert out.is_file()
    return np.asarray(Image.open(out).convert("RGB"))


def test_map_size_and_colours(tmp_path: Path) -> None:
    reports = [
        MapReport(id=0, type="qr", text="Chart M", x=0.5, y=0.3, status="located"),
        MapReport(id=1, type="baby-doll", x=2.2, y=2.0, status="identified"),
        {"id": 2, "type": "hazmat", "text": "poison", "x": 4.0, "y": -0.5, "status": "false"},
    ]
    truth = [
        MapTruth(x=0.6, y=0.4, type="qr", found=True),
        {"x": -0.5, "y": 2.2, "type": "door", "found": False},
    ]
    img = _draw(tmp_path, reports, truth, size_px=(1000, 700))
    assert img.shape == (700, 1000, 3)
    # Scale: the view is about 8 x 6 m in 710 x 610 px, ~90 px/m, so a 0.175 m marker
    # is ~30 px across (~700 px of area): require a clear interior of each colour.
    for rgb in (QR_RGB, VICTIM_RGB, HAZARD_RGB):
        assert _count(img, rgb) > 150, rgb
    assert _count(img, PATH_RGB) > 200  # 3 px wide, ~6 m long
    assert _count(img, WALL_RGB) > 1000  # 22 m of walls, >= 3 px wide
    for rgb in (*CHECKER_RGB, GRID_RGB):
        assert _count(img, rgb) > 1000, rgb


def test_map_without_reports_has_no_marker_colours(tmp_path: Path) -> None:
    img = _draw(tmp_path, [], [])
    assert img.shape == (900, 1200, 3)  # the default size
    for rgb in (QR_RGB, VICTIM_RGB, HAZARD_RGB):
        assert _count(img, rgb) == 0, rgb
    assert _count(img, PATH_RGB) > 200


def test_markers_from_score(tmp_path: Path) -> None:
    header = PoiHeader(team="t", country="c", date="2025-01-01", start_time="10:00:00", mission="m")

    def row(i: int, type_: str, x: float) -> PoiRow:
        return PoiRow(
            line=0,
            id=i,
            time="10:00:00",
            text="",
            x=x,
            y=0.0,
            z=0.0,
            robot="r",
            mode="T",
            type=type_,
        )

    truth = parse_poi_text(format_poi_text(header, [row(1, "door", 0.0), row(2, "valve", 3.0)]))
    reps = parse_poi_text(format_poi_text(header, [row(0, "door", 0.2), row(1, "door", 1.0)]))
    result = score(reps, truth, load_rules("ex3"))
    m_reports, m_truth = markers_from_score(result)
    assert [(r.id, r.status) for r in m_reports] == [(0, "located"), (1, "false")]
    assert [(t.type, t.found) for t in m_truth] == [("door", True), ("valve", False)]
    img = _draw(tmp_path, m_reports, m_truth)
    assert _count(img, TYPE_COLORS_RGB["door"]) > 150


def test_too_small_size_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="too small"):
        draw_map(
            tmp_path / "x.png",
            walls=[],
            robot_path=np.zeros((0, 2)),
            reports=[],
            truth=[],
            size_px=(300, 100),
        )


# ------------------------------------------------------------------ type colours, circles, X, labels

SCATTER = [(0.5, 0.5), (2.0, 0.5), (3.5, 0.5), (0.5, 2.0), (2.0, 2.0), (3.5, 2.0), (0.5, -0.5), (2.0, -0.5)]
COMPETITION_TYPES = [t for t in TYPES if t not in ARENA_TYPES and t != "fiducial"]


def test_map_colours_are_the_type_tables():
    """Every scored type is drawn in the one table of type colours (poi.annotate, the live view's)."""
    for t in COMPETITION_TYPES:
        assert style_of(t)[1] == TYPE_COLORS_RGB[t], t
    for t in ARENA_TYPES:  # the goal arena's objects in their paint (map_plot's docstring says why)
        assert style_of(t)[1] == ARENA_RGB[t], t


def test_each_type_is_drawn_in_its_colour_with_a_legend_entry(tmp_path: Path) -> None:
    spots = [(x, y) for y in (2.2, 0.9, -0.4) for x in (-0.3, 1.6, 3.4)]  # (9, 2): one type a spot
    reports = [
        MapReport(id=i, type=t, x=x, y=y, status="located")
        for i, (t, (x, y)) in enumerate(zip(COMPETITION_TYPES, spots, strict=False))
    ]
    assert len(reports) == 9
    img = _draw(tmp_path, reports, [], size_px=(1000, 700))
    for r in reports:
        assert _count(img, TYPE_COLORS_RGB[r.type]) > 150, r.type  # ~700 px of a marker, less its id
    fig = map_figure(walls=WALLS, robot_path=np.zeros((0, 2)), reports=reports, truth=[])
    legend = fig.axes[0].get_legend()
    labels = [t.get_text() for t in legend.get_texts()]
    swatches = dict(zip(labels, legend.legend_handles, strict=True))
    for name, t in (("Hazmat", "hazmat"), ("Valve", "valve"), ("Exit sign", "exit-sign"), ("QR code", "qr")):
        rgb = tuple(round(255 * c) for c in swatches[name].get_markerfacecolor()[:3])
        assert rgb == TYPE_COLORS_RGB[t], name


def _circles(fig) -> int:
    from matplotlib.patches import Circle

    ax = fig.axes[0]
    return sum(1 for p in ax.patches if isinstance(p, Circle) and p.get_radius() == pytest.approx(1.0))


def test_locate_circles_only_round_objects_a_report_just_missed():
    # eight objects in a 4 x 4 m maze: a circle round each overlapped into a web; located ones and
    # ones no report came near get none (a neighbour's located report 1 m away included); the one
    # a false report fell 1.3 m from keeps it
    truth = [MapTruth(x=x, y=y, type="hazmat", found=i < 6) for i, (x, y) in enumerate(SCATTER)]
    reports = [
        MapReport(id=i, type="hazmat", x=x + 0.1, y=y, status="located") for i, (x, y) in enumerate(SCATTER[:6])
    ]
    reports.append(MapReport(id=9, type="hazmat", x=3.3, y=-0.5, status="false"))  # 1.3 m from (2.0, -0.5)
    fig = map_figure(walls=WALLS, robot_path=np.zeros((0, 2)), reports=reports, truth=truth)
    assert _circles(fig) == 1


def test_a_false_reports_x_does_not_hide_another_marker(tmp_path: Path) -> None:
    qr = MapReport(id=None, type="qr", x=2.0, y=1.0, status="located")
    alone = _count(_draw(tmp_path, [qr], []), QR_RGB)
    # a false hazmat report 6 cm away: its marker and X lie under the located QR code's marker
    under = MapReport(id=None, type="hazmat", x=2.06, y=1.0, status="false")
    for order in ([qr, under], [under, qr]):
        assert _count(_draw(tmp_path, order, []), QR_RGB) >= 0.97 * alone  # only edge blending differs


def test_labels_do_not_overlap(tmp_path: Path) -> None:
    # crowded: false reports and misses side by side, two reports on one spot
    reports = [MapReport(id=10 + i, type="hazmat", x=x, y=y, status="false") for i, (x, y) in enumerate(SCATTER)]
    reports += [
        MapReport(id=3, type="qr", x=2.0, y=2.05, status="located"),
        MapReport(id=4, type="valve", x=2.05, y=2.0, status="identified"),
    ]
    truth = [MapTruth(x=x + 0.2, y=y - 0.15, type="door", found=False) for x, y in SCATTER]
    fig = map_figure(walls=WALLS, robot_path=np.zeros((0, 2)), reports=reports, truth=truth, size_px=(1000, 700))
    renderer = fig.canvas.get_renderer()
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in fig.axes[0].texts]
    assert len(boxes) == 2 * len(SCATTER) + 2 + len(SCATTER)  # ids, "false" and "miss" labels
    overlapping = [
        (a, b)
        for i, (a, box_a) in enumerate(boxes)
        for b, box_b in boxes[i + 1 :]
        # glyph boxes carry empty margins: 1 px of touch is not an overlap
        if box_a.expanded(0.98, 0.9).overlaps(box_b.expanded(0.98, 0.9))
    ]
    assert not overlapping, overlapping


def test_the_live_view_marks_the_map_in_the_same_colours(tmp_path: Path) -> None:
    from types import SimpleNamespace

    from eval.live.record import LiveRecorder

    sim = SimpleNamespace(walls_in_map=lambda: [((0.0, 0.0), (1.0, 0.0))], n_frames=1)
    init = LiveRecorder(tmp_path, sim, title="t", record=False).init
    for t in COMPETITION_TYPES:
        assert init["marker_colors"][t] == "#{:02x}{:02x}{:02x}".format(*TYPE_COLORS_RGB[t]), t
        assert init["marker_shapes"][t] == style_of(t)[0]


def test_the_legend_lists_only_what_the_map_draws(tmp_path: Path) -> None:
    """No path, every report located, every object found, no circle: the legend names none of the
    path, the outlines, crosses, circles or dashes; a false report and a missed object bring theirs."""

    def labels(reports, truth, path) -> list[str]:
        fig = map_figure(walls=WALLS, robot_path=path, reports=reports, truth=truth)
        return [t.get_text() for t in fig.axes[0].get_legend().get_texts()]

    found = [MapTruth(x=0.5, y=0.3, type="qr", found=True)]
    located = [MapReport(id=0, type="qr", text="Chart M", x=0.5, y=0.3, status="located")]
    quiet = labels(located, found, np.zeros((0, 2)))
    assert quiet == ["wall", "QR code", "ground truth"]
    missed = [*found, MapTruth(x=3.0, y=0.0, type="qr", found=False)]
    false = [*located, MapReport(id=1, type="qr", text="Chart Z", x=4.4, y=0.0, status="false")]  # 1.4 m off
    busy = labels(false, missed, np.array([[0.0, 0.0], [1.0, 0.0]]))
    for entry in (
        "robot path",
        "false report",
        "missed object (dashed)",
        "1 m round an object a report just missed",
    ):
        assert entry in busy, entry
    assert "identified, not located" not in busy
