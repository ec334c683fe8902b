"""The score report (RULES.md "Scoring presets": what it lists) as JSON data and text tables.

Per report: the paired object (or why none), the distance, the points; per object:
found or missed; totals per type; the total; the maximum possible total.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from eval.scorer import ScoreResult

_NUMERIC = ("line", "id", "x", "y", "z", "object", "found_by", "dist_m", "points")


def to_json_dict(result: ScoreResult) -> dict[str, Any]:
    """A JSON-ready dict: total, max_total, counts, rows, per-type totals, problems, rules.

    Counts (``false_reports``, ``misses``, ``located``, ``identified``,
    ``ignored_reports``) are integers; the rows say which reports and objects they are.
    """
    return {
        "total": _num(result.total),
        "max_total": _num(result.max_total),
        "identified": result.identified,
        "located": result.located,
        "false_reports": result.false_reports,
        "misses": result.misses,
        "ignored_reports": result.ignored_reports,
        "reports": [{k: _num(v) for k, v in asdict(r).items()} for r in result.reports],
        "objects": [{k: _num(v) for k, v in asdict(o).items()} for o in result.objects],
        "per_type": {
            t: {k: _num(v) for k, v in asdict(tt).items() if k != "type"} for t, tt in result.per_type.items()
        },
        "problems": [asdict(p) for p in result.problems],
        "rules": result.rules.to_dict(),
    }


def format_tables(result: ScoreResult) -> str:
    """Plain-text tables for a terminal: reports, objects, totals per type, problems."""
    rules = result.rules
    out: list[str] = [
        f"Score {_fmt(result.total)} of {_fmt(result.max_total)} "
        f"(rules {rules.name}{f': {rules.source}' if rules.source else ''})",
        f"identified {result.identified}, located {result.located}, "
        f"false reports {result.false_reports}, misses {result.misses}"
        + (f", ignored {result.ignored_reports}" if result.ignored_reports else ""),
        "",
        "Reports",
    ]
    out += _table(
        [
            "line",
            "id",
            "type",
            "text",
            "x",
            "y",
            "z",
            "object",
            "dist_m",
            "points",
            "status",
            "reason",
        ],
        [
            [
                r.line,
                r.id,
                r.type or "?",
                r.text,
                _fmt(r.x, 3),
                _fmt(r.y, 3),
                _fmt(r.z, 3),
                r.object_id,
                _fmt(r.distance_m, 2),
                _fmt(r.points),
                r.status,
                r.reason,
            ]
            for r in result.reports
        ],
    )
    out += ["", "Objects"]
    out += _table(
        ["line", "id", "type", "text", "x", "y", "z", "found_by", "dist_m", "points", "status"],
        [
            [
                o.line,
                o.id,
                o.type,
                o.text,
                _fmt(o.x, 3),
                _fmt(o.y, 3),
                _fmt(o.z, 3),
                o.found_by,
                _fmt(o.distance_m, 2),
                _fmt(o.points),
                o.status,
            ]
            for o in result.objects
        ],
    )
    out += ["", "Totals per type"]
    rows = [
        [
            t.type,
            t.reports,
            t.identified,
            t.located,
            t.false_reports,
            _fmt(t.points_won),
            _fmt(t.points_lost),
            _fmt(t.points),
            t.objects,
            t.found,
            t.missed,
            _fmt(t.max_points),
        ]
        for t in result.per_type.values()
        if t.reports or t.objects
    ]
    rows.append(
        [
            "TOTAL",
            sum(t.reports for t in result.per_type.values()),
            result.identified,
            result.located,
            result.false_reports,
            _fmt(sum(t.points_won for t in result.per_type.values())),
            _fmt(sum(t.points_lost for t in result.per_type.values())),
            _fmt(result.total),
            sum(t.objects for t in result.per_type.values()),
            sum(t.found for t in result.per_type.values()),
            result.misses,
            _fmt(result.max_total),
        ]
    )
    out += _table(
        [
            "type",
            "reports",
            "identified",
            "located",
            "false",
            "won",
            "lost",
            "points",
            "objects",
            "found",
            "missed",
            "max",
        ],
        rows,
    )
    if result.problems:
        out += ["", "Problems"]
        out += [
            f"{p.source} line {p.line} {p.severity}: {p.message}"
            if p.line
            else f"{p.source} {p.severity}: {p.message}"
            for p in result.problems
        ]
    return "\n".join(out) + "\n"


def _table(headers: list[str], rows: list[list[Any]]) -> list[str]:
    """Aligned columns: numbers right-aligned, text left-aligned, two spaces apart."""
    cells = [[("" if v is None else str(v)) for v in row] for row in rows]
    widths = [len(h) for h in headers]
    for row in cells:
        widths = [max(w, len(c)) for w, c in zip(widths, row, strict=True)]
    right = [h in _NUMERIC or h not in ("type", "text", "status", "reason") for h in headers]

    def line(values: list[str]) -> str:
        parts = [v.rjust(w) if r else v.ljust(w) for v, w, r in zip(values, widths, right, strict=True)]
        return "  ".join(parts).rstrip()

    return [line(headers), line(["-" * w for w in widths])] + [line(row) for row in cells]


def _num(value: Any) -> Any:
    """Integral floats as ints (points read as whole numbers), other values unchanged."""
    if isinstance(value, float) and value.is_integer() and abs(value) < 2**53:
        return int(value)
    return value


def _fmt(value: float | None, decimals: int | None = None) -> str:
    """Points as whole numbers where they are (``decimals`` None); else fixed decimals."""
    if value is None:
        return ""
    if decimals is None:
        return str(int(value)) if float(value).is_integer() else f"{value:g}"
    return f"{value:.{decimals}f}"
