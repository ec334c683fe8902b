"""``points.png``: where a suite's points went, every lost point of each maze by its cause.

The funnel (eval/scoring/funnel.py; docs/RULES.md "The funnel") charges each point a trial
lost to one cause, so that a trial's score and its lost points add up to its maximum:

    max - score = sum over the false-report causes + sum over the object causes   (funnel check)

Each bar of the upper panel is that sum laid end to end: first the points the false reports
took back, then the points the objects never won, each cause its own segment and colour, with
the score and maximum written beside it. Points lost but charged to no cause, which the
funnel's check reports as a fault, are drawn as a white segment, and points charged beyond
what was lost are written beside the bar, so that a fault shows.

A suite run draws a bar a maze, in its trials.csv order; a sweep a bar a setting combination,
its mazes summed. The lower panel sums the bars' lost points per object type: where the
points went.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from eval.scoring.funnel import FALSE_CAUSES, OBJECT_CAUSES, lost_by_type

if TYPE_CHECKING:
    from matplotlib.figure import Figure

POINTS_PNG = "points.png"
UNCHARGED = "not charged to a cause"
# a colour a cause: the object causes in blues and greys by stage, the false reports in reds and oranges
CAUSE_COLOURS: dict[str, str] = {
    "not in view": "#c7c7c7",
    "not boxed": "#1f4e79",
    "wrong type": "#2e75b6",
    "not localised": "#5b9bd5",
    "not read": "#9dc3e6",
    "not confirmed": "#7f6fb0",
    "reported wrong": "#b4a7d6",
    "misplaced": "#8c564b",
    "taken": "#c49c94",
    "not located": "#bcbd22",
    "autonomy withheld": "#dbdb8d",
    "false: background": "#d62728",
    "false: other object": "#ff7f0e",
    "false: wrong label": "#f4a261",
    "false: duplicate": "#e377c2",
    "false: misplaced": "#9e3d3d",
    "false: unknown": "#7f7f7f",
}
# the segments' order along a bar: what false reports took back, then what objects never won
BAR_ORDER = (*FALSE_CAUSES, *OBJECT_CAUSES)


@dataclass(kw_only=True)
class PointsBar:
    """One bar: a label, the score and maximum, and the points lost per cause."""

    label: str
    score: float
    max_score: float
    lost: dict[str, float]  # cause -> points, causes that lost nothing left out

    @property
    def uncharged(self) -> float:
        """max - score - the charged points: 0 when the funnel's check holds."""
        return self.max_score - self.score - sum(self.lost.values())

    def segments(self) -> list[tuple[str, float, float]]:
        """(name, left, width) of each segment, left to right (module docstring)."""
        out = cause_segments(self.lost)
        if self.uncharged > 1e-9:
            end = out[-1][1] + out[-1][2] if out else 0.0
            out.append((UNCHARGED, end, self.uncharged))
        return out


def cause_segments(lost: dict[str, float]) -> list[tuple[str, float, float]]:
    """(cause, left, width) of each cause that lost points, laid end to end in :data:`BAR_ORDER`."""
    out, x = [], 0.0
    for cause in BAR_ORDER:
        if lost.get(cause):
            out.append((cause, x, lost[cause]))
            x += lost[cause]
    return out


def _draw_bar(ax, row: int, segments: list[tuple[str, float, float]], used: list[str]) -> float:
    """Draw one bar's segments on row ``row`` of ``ax``, add their names to ``used`` (the
    legend's, in first-drawn order); returns where the bar ends."""
    end = 0.0
    for name, left, width in segments:
        ax.barh(
            row,
            width,
            left=left,
            color=CAUSE_COLOURS.get(name, "white"),
            height=0.75,
            edgecolor="black" if name == UNCHARGED else "white",
            linewidth=0.5,
        )
        end = left + width
        if name not in used:
            used.append(name)
    return end


def points_figure(bars: list[PointsBar], per_type: dict[str, dict[str, float]], title: str) -> Figure | None:
    """The matplotlib Figure of ``bars`` above and the lost points of ``per_type`` (summed
    over the bars) below (module docstring); None without bars."""
    if not bars:
        return None
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    by_type = sorted(lost_by_type(per_type).items(), key=lambda kv: (-sum(kv[1].values()), kv[0]))
    rows_top, rows_bottom = len(bars), max(len(by_type), 1)
    fig = Figure(figsize=(9, 1.6 + 0.32 * (rows_top + rows_bottom) + 1.2))
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, gridspec_kw={"height_ratios": [rows_top + 1, rows_bottom + 1]})
    used: list[str] = []
    ends = []
    for i, bar in enumerate(bars):
        x = _draw_bar(top, i, bar.segments(), used)
        ends.append(x)
        note = "" if abs(bar.uncharged) < 1e-9 else f", {bar.uncharged:+g} not charged"
        top.text(x, i, f"  {bar.score:g} / {bar.max_score:g}{note}", va="center", fontsize=8)
    top.set_yticks(range(rows_top), [b.label for b in bars], fontsize=8)
    top.invert_yaxis()  # the first bar on top, as trials.csv lists it
    top.set_xlabel("points lost, by cause (the score / the maximum at the right)")
    top.set_xlim(0.0, 1.25 * max([1.0, *ends]) + 1.0)
    top.set_title(title, fontsize=10)
    for j, (_, lost) in enumerate(by_type):
        x = _draw_bar(bottom, j, cause_segments(lost), used)
        bottom.text(x, j, f"  {x:g}", va="center", fontsize=8)
    if by_type:
        bottom.set_yticks(range(len(by_type)), [t for t, _ in by_type], fontsize=8)
        bottom.set_xlim(0.0, 1.12 * max(sum(lost.values()) for _, lost in by_type) + 1.0)
    else:
        bottom.set_yticks([])
        bottom.text(0.5, 0.5, "no point lost", ha="center", va="center", transform=bottom.transAxes)
    bottom.invert_yaxis()
    bottom.set_xlabel("points lost per type, all bars above summed")
    order = [c for c in (*BAR_ORDER, UNCHARGED) if c in used]
    handles = [
        Patch(facecolor=CAUSE_COLOURS.get(c, "white"), edgecolor="black" if c == UNCHARGED else "none", label=c)
        for c in order
    ]
    fig.legend(handles=handles, loc="center left", bbox_to_anchor=(0.74, 0.5), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0.0, 0.0, 0.74, 1.0))
    return fig


def write_points_png(path: Path, bars: list[PointsBar], per_type: dict[str, dict[str, float]], title: str) -> bool:
    """Write :func:`points_figure` to ``path``; False (nothing written) without bars."""
    fig = points_figure(bars, per_type, title)
    if fig is None:
        return False
    fig.savefig(path, dpi=100)
    return True
