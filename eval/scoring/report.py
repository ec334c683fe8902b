"""The score report (docs/RULES.md "Score report") as JSON data and text tables.

Per report: the paired object (or why none), the distance, the points; per object:
found or missed; totals per type; the total; the maximum possible total. A map-error
result (eval/map_error.py, the TurtleBot arena) lists instead: per report its object
and 2D distance (or why none), per object found or missed, per type the counts and the
mean and max error, the goal's centre error, and the mean and max error over all.
"""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

from eval.scoring.map_error import MapErrorResult, format_m
from eval.scoring.pairing import MAP_ERROR_OMITS, ObjectOutcome, ReportOutcome
from eval.scoring.scorer import STATUS_IGNORED, ScoreResult
from eval.text import counted
from poi.core.names import in_type_order

_NUMERIC = ("line", "id", "x", "y", "z", "object", "found_by", "dist_m", "points")


def to_json_dict(result: ScoreResult | MapErrorResult) -> dict[str, Any]:
    """A JSON-ready dict: total, max_total, counts, rows, per-type totals, problems, rules.

    Counts (``false_reports``, ``misses``, ``located``, ``identified``,
    ``ignored_reports``) are integers; the rows say which reports and objects they are.
    A map-error result gives :func:`map_error_json` instead.
    """
    if isinstance(result, MapErrorResult):
        return map_error_json(result)
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
        # only where they say something: a 1.3 file without types, a preset that scores autonomy
        **({} if result.types_checked else {"types_checked": False, "types_note": TYPES_NOTE}),
        **({} if result.autonomy is None else {"autonomy": result.autonomy}),
        **({} if result.qr_mapping is None else {"qr_mapping": result.qr_mapping}),
    }


def map_error_json(result: MapErrorResult) -> dict[str, Any]:
    """A JSON-ready dict of a map-error result: ``scoring: map_error``, the mean and max
    error (m, null when nothing was paired), the goal's centre error (null when it is
    missing, with the reason), the counts, the rows, per-type figures, problems, rules."""
    goal = None if result.goal is None else asdict(result.goal)
    if goal is not None:
        for k in ("truth_center", "reported_center"):
            goal[k] = None if goal[k] is None else [round(v, 4) for v in goal[k]]
    return {
        "scoring": "map_error",
        "mean_error_m": _round(result.mean_error_m),
        "max_error_m": _round(result.max_error_m),
        "goal_center_error_m": None if result.goal is None else _round(result.goal.error_m),
        "paired": result.paired,
        "misses": result.misses,
        "false_reports": result.false_reports,
        "ignored_reports": result.ignored_reports,
        "goal": goal,
        "per_type": {
            t: {k: _round(v) if k.endswith("_m") else v for k, v in asdict(tt).items() if k != "type"}
            for t, tt in result.per_type.items()
        },
        "reports": [_map_error_row(r) for r in result.reports],
        "objects": [_map_error_row(o) for o in result.objects],
        "problems": [asdict(p) for p in result.problems],
        "rules": result.rules.to_dict(),
    }


def _map_error_row(row: ReportOutcome | ObjectOutcome) -> dict[str, Any]:
    """A row of a map-error result without the fields only points are about (text, points, located)."""
    return {k: _num(v) for k, v in asdict(row).items() if k not in MAP_ERROR_OMITS}


def live_summary(result: ScoreResult | MapErrorResult) -> dict[str, Any]:
    """What the live view shows as the running score: ``{"total", "max"}`` of a points
    result, ``{"text"}`` (the headline) of a map-error one."""
    if isinstance(result, MapErrorResult):
        return {"text": result.headline()}
    return {"total": result.total, "max": result.max_total}


TYPES_NOTE = (
    "the POI file has no type column (POI 1.3): reports were paired by location; types could not be checked"
)


# what the text column holds for the types whose text is not a name or a code's content
TEXT_MEANING = {
    "fiducial": "the mapping pipe's diameter",
    "landolt-c": "each ring's gap direction, ring:direction, ring 1 the outermost",
}
REPORTS_TITLE = "Reports (line: in the report file; object: the id of the object it pairs with; x, y, z: metres)"
OBJECTS_TITLE = "Objects (line: in the truth file; found_by: the id of the report paired with it; x, y, z: metres)"


def _ignored(result: ScoreResult | MapErrorResult) -> str:
    """', ignored: N reports, M objects (...)' for what the preset does not score, or ''."""
    objects = sum(o.status == STATUS_IGNORED for o in result.objects)
    if not (result.ignored_reports or objects):
        return ""
    which = f"{counted(result.ignored_reports, 'report')}, {counted(objects, 'object')}"
    return f", ignored: {which} (of types the rules do not score)"


def format_tables(result: ScoreResult | MapErrorResult) -> str:
    """Plain-text tables for a terminal: reports, objects, totals per type, problems."""
    if isinstance(result, MapErrorResult):
        return format_map_error_tables(result)
    rules = result.rules
    out: list[str] = [
        f"Score {_fmt(result.total)} of {_fmt(result.max_total)} "
        f"(rules {rules.name}{f': {rules.source}' if rules.source else ''})",
        f"identified {result.identified}, located {result.located}, "
        f"false reports {result.false_reports}, misses {result.misses}" + _ignored(result),
        *([] if result.types_checked else [f"note: {TYPES_NOTE}"]),
        *(
            []
            if result.autonomy is None
            else [f"autonomy x{result.autonomy['multiplier']:g}: {result.autonomy['reason']}"]
        ),
        *([] if result.qr_mapping is None else [f"QR mapping by fiducials: {result.qr_mapping['reason']}"]),
        "",
        REPORTS_TITLE,
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
    out += ["", OBJECTS_TITLE]
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
    shown = {o.type for o in result.objects} | {r.type for r in result.reports}
    out += [f"text of a {t}: {TEXT_MEANING[t]}" for t in in_type_order(shown & set(TEXT_MEANING))]
    out += ["", "Totals per type"]

    def locates(type_: str) -> bool:  # the preset gives the type a locate bonus ('-' where it gives none)
        rule = rules.types.get(type_)
        return rule is not None and rule.located_points is not None

    rows = [
        [
            t.type,
            t.reports,
            t.identified,
            t.located if locates(t.type) else "-",
            t.false_reports,
            _fmt(t.points_won),
            _fmt(t.points_lost),
            _fmt(t.points),
            t.objects,
            t.missed,
            _fmt(t.max_points),
        ]
        for t in (result.per_type[name] for name in in_type_order(result.per_type))
        if t.reports or t.objects
    ]
    rows.append(
        [
            "TOTAL",
            sum(t.reports for t in result.per_type.values()),
            result.identified,
            result.located if any(locates(t) for t in result.per_type) else "-",
            result.false_reports,
            _fmt(sum(t.points_won for t in result.per_type.values())),
            _fmt(sum(t.points_lost for t in result.per_type.values())),
            _fmt(result.total),
            sum(t.objects for t in result.per_type.values()),
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
            "penalty",
            "points",
            "objects",
            "missed",
            "max",
        ],
        rows,
    )
    out += _problem_lines(result.problems)
    return "\n".join(out) + "\n"


def format_map_error_tables(result: MapErrorResult) -> str:
    """Plain-text tables of a map-error result: reports, objects, per type, the goal, problems."""
    rules = result.rules
    n_obj = sum(t.objects for t in result.per_type.values())
    out: list[str] = [
        f"Map error: mean {format_m(result.mean_error_m)}, max {format_m(result.max_error_m)}"
        + ("" if result.goal is None else f"; goal centre error {format_m(result.goal.error_m)}")
        + f" (rules {rules.name}{f': {rules.source}' if rules.source else ''})",
        f"paired {result.paired} of {n_obj} objects (2D, at most {rules.max_pair_distance_m:g} m apart), "
        f"misses {result.misses}, false reports {result.false_reports}" + _ignored(result),
        "",
        "Reports",
    ]
    out += _table(
        ["line", "id", "type", "x", "y", "z", "object", "dist_m", "status", "reason"],
        [
            [
                r.line,
                r.id,
                r.type or "?",
                _fmt(r.x, 3),
                _fmt(r.y, 3),
                _fmt(r.z, 3),
                r.object_id,
                _fmt(r.distance_m, 3),
                r.status,
                r.reason,
            ]
            for r in result.reports
        ],
    )
    out += ["", "Objects"]
    out += _table(
        ["line", "id", "type", "x", "y", "z", "found_by", "dist_m", "status"],
        [
            [
                o.line,
                o.id,
                o.type,
                _fmt(o.x, 3),
                _fmt(o.y, 3),
                _fmt(o.z, 3),
                o.found_by,
                _fmt(o.distance_m, 3),
                o.status,
            ]
            for o in result.objects
        ],
    )
    out += ["", "Per type"]
    rows = [
        [
            t.type,
            t.objects,
            t.reports,
            t.paired,
            t.missed,
            t.false_reports,
            _fmt(t.mean_error_m, 3),
            _fmt(t.max_error_m, 3),
        ]
        for t in result.per_type.values()
    ]
    rows.append(
        [
            "TOTAL",
            n_obj,
            sum(t.reports for t in result.per_type.values()),
            result.paired,
            result.misses,
            result.false_reports,
            _fmt(result.mean_error_m, 3),
            _fmt(result.max_error_m, 3),
        ]
    )
    out += _table(["type", "objects", "reports", "paired", "missed", "false", "mean_m", "max_m"], rows)
    g = result.goal
    if g is not None:
        out += ["", f"Goal ({rules.goal_type} pair)"]
        truth = "-" if g.truth_center is None else f"({g.truth_center[0]:.3f}, {g.truth_center[1]:.3f})"
        rep = "-" if g.reported_center is None else f"({g.reported_center[0]:.3f}, {g.reported_center[1]:.3f})"
        out.append(f"truth centre {truth}, reported centre {rep}, error {format_m(g.error_m)}")
        if g.reason:
            out.append(f"no goal error: {g.reason}")
    out += _problem_lines(result.problems)
    return "\n".join(out) + "\n"


def _problem_lines(problems: list) -> list[str]:
    """The "Problems" section (nothing when there are none)."""
    if not problems:
        return []
    where = [f"{p.source} line {p.line}" if p.line else p.source for p in problems]
    return ["", "Problems"] + [f"{w} {p.severity}: {p.message}" for w, p in zip(where, problems, strict=True)]


def _round(value: float | None, decimals: int = 4) -> float | None:
    return None if value is None else round(float(value), decimals)


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
