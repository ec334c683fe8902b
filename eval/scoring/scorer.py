"""Score a POI report against ground truth: docs/RULES.md "ex3", rules 1-5, for any points preset.

1. A report's identity is its type, plus its text where the rules say
   ``identity_uses_text`` (hazmat: the canonical label; qr: the exact string).
2. Per identity, reports and objects are paired one to one by an optimal
   assignment over 3D distances, using only pairs at most ``identify_radius_m``
   apart (``null``: any distance). The assignment first makes as many allowed
   pairs as possible, then, among those, has the least total distance (see
   :func:`optimal_pairs`).
3. A paired report scores the type's ``points``, or ``located_points`` when the
   distance is at most ``locate_radius_m``.
4. An unpaired report is a false report: it loses the type's points (or 0 under
   ``false_report_penalty: zero``), with the reason it paired with nothing.
5. Unpaired objects are misses (no points, listed).

A POI 1.3 file without a type column (``PoiFile.typed`` False, docs/RULES.md "Version 1.3")
cannot say what it found: its reports are paired with every scored object by location alone
(one optimal assignment within ``identify_radius_m``), a paired report scores as a report of
its object's type, an unpaired one is false and loses nothing (its type is unknown), and the
result says that types could not be checked (``types_checked`` False).

Where the preset scores autonomy (``autonomy_multiplier``, docs/RULES.md "Autonomy"), the
points of every paired report whose mode is ``A`` are multiplied by it after pairing, unless
``autonomy_requires_no_false_or_multiple`` is set and the run has a false report (a duplicate,
a multiple detection, is one), or the report is a QR code and ``qr_mapping_replaces_autonomy``.

Where the preset judges the QR mapping bonus by fiducials (``qr_mapping: fiducials``,
[RMRC2025]_, docs/RULES.md "QR mapping by fiducials"), a paired QR report is located (scores
``located_points``) when, for each of the two ground-truth fiducials closest to its object
(horizontal distance), the horizontal distance from the reported QR position to that
fiducial's position on the map differs from the true distance by at most
``fiducial_tolerance_m``. A fiducial's position on the map is the reported fiducial paired with
it (an optimal assignment within ``fiducial_match_radius_m``), or its true position when the
report has none for it (the result's ``qr_mapping`` block counts those). With fewer than two
fiducials in the ground truth the radius rule decides, and the block says so. This runs after
pairing and before autonomy.

QR codes whose text the preset's ``qr_text_filter`` does not match (the finals' larger codes)
are ignored, reports and objects alike.

A Landolt-C target's identity is the gap directions of the preset's ``landolt_rings`` only
(docs/RULES.md "Landolt-C": the 3rd ring under rmrc2026, the 3rd and 4th in the finals), so a
report pairs with a target whose required rings it gives right, within ``landolt_radius_m``;
a report with a required ring wrong, missing or too far from every such target is false.

Types the rules do not list are ignored (their reports and objects are listed
with status ``ignored`` and count for nothing). A hazmat report whose label is
not one of the 16, or a text-identity report with empty text, pairs with nothing.
An unreadable report row is a false report of the type it names (0 when unknown).

Rules of another kind (``scoring: map_error``, the TurtleBot arena) are scored by
:func:`eval.scoring.map_error.score_map_error`, which :func:`score` hands them to.

Distances are compared with the radii with a tolerance of ``EPS_M`` = 1e-9 m
(:mod:`eval.scoring.pairing`, which holds what this module shares with map_error).

References
----------
Full entries in docs/SOURCES.md.

.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from eval.scoring.map_error import MapErrorResult, score_map_error
from eval.scoring.pairing import (
    EPS_M,
    STATUS_FALSE,
    STATUS_IDENTIFIED,
    STATUS_IGNORED,
    STATUS_LOCATED,
    STATUS_MISSED,
    ObjectOutcome,
    ReportOutcome,
    ScoreProblem,
    object_outcome,
    optimal_pairs,
    reader_problems,
    report_outcome,
    unreadable_outcome,
)
from eval.scoring.rules import AnyRules, Rules, TypeRule
from eval.text import counted
from poi.core.names import HAZMAT_LABELS
from poi.core.poi_file import PoiFile, PoiRow

Identity = tuple[str, str]


@dataclass(kw_only=True)
class TypeTotals:
    """Totals of one scored type; ``points`` = ``points_won`` - ``points_lost``."""

    type: str
    reports: int = 0
    identified: int = 0
    located: int = 0
    false_reports: int = 0
    points_won: float = 0
    points_lost: float = 0
    points: float = 0
    objects: int = 0
    found: int = 0
    missed: int = 0
    max_points: float = 0


@dataclass(kw_only=True)
class ScoreResult:
    """Everything the score report lists (docs/RULES.md "Score report": per report, per object, totals)."""

    rules: Rules
    reports: list[ReportOutcome]
    objects: list[ObjectOutcome]
    per_type: dict[str, TypeTotals]
    total: float
    max_total: float
    identified: int
    located: int
    false_reports: int
    misses: int
    ignored_reports: int
    problems: list[ScoreProblem] = field(default_factory=list)
    types_checked: bool = True
    autonomy: dict[str, Any] | None = None
    qr_mapping: dict[str, Any] | None = None

    def headline(self) -> str:
        """One line: ``12 / 20 points``."""
        return f"{self.total:g} / {self.max_total:g} points"


def identity_of(type_: str, text: str, rules: Rules) -> Identity | None:
    """The identity of rule 1, or None when the row can pair with nothing.

    >>> from eval.scoring.rules import load_rules
    >>> ex3 = load_rules("ex3")
    >>> identity_of("qr", "Chart M", ex3), identity_of("door", "left", ex3)
    (('qr', 'Chart M'), ('door', ''))
    >>> identity_of("hazmat", "banana", ex3) is None
    True
    """
    rule = rules.types[type_]
    if not rule.identity_uses_text:
        return (type_, "")
    if type_ == "landolt-c":
        ident = rules.landolt_identity(text)
        return None if ident is None else (type_, ident)
    if not text or (type_ == "hazmat" and text not in HAZMAT_LABELS):
        return None
    return (type_, text)


def score(reports: PoiFile, truth: PoiFile, rules: AnyRules) -> ScoreResult | MapErrorResult:
    """Score ``reports`` against ``truth`` under ``rules`` (module docstring, rules 1-5); a
    map-error preset gives a :class:`eval.scoring.map_error.MapErrorResult` instead."""
    if rules.scoring == "map_error":
        return score_map_error(reports, truth, rules)
    report_scores: dict[int, ReportOutcome] = {}  # by report line
    object_scores: list[ObjectOutcome] = []
    groups_r: dict[Identity, list[PoiRow]] = {}
    groups_o: dict[Identity, list[int]] = {}  # indices into truth.rows
    scored_objects: list[int] = []

    for k, obj in enumerate(truth.rows):
        scored = rules.is_scored(obj.type) and rules.text_is_scored(obj.type, obj.text)
        status = STATUS_MISSED if scored else STATUS_IGNORED
        object_scores.append(object_outcome(obj, status))
        if status == STATUS_IGNORED:
            continue
        scored_objects.append(k)
        ident = identity_of(obj.type, obj.text, rules)
        if ident is not None:
            groups_o.setdefault(ident, []).append(k)

    untyped: list[PoiRow] = []
    for rep in reports.rows:
        if rep.type is None:
            untyped.append(rep)  # POI 1.3 without a type column: paired by location below
            continue
        if not rules.is_scored(rep.type):
            why = f"type {rep.type} is not scored by {rules.name}"
            if rep.type == "fiducial" and rules.qr_mapping == "fiducials":
                why = "a fiducial: not scored; its map position is used by the QR mapping test"
            report_scores[rep.line] = report_outcome(rep, STATUS_IGNORED, why)
            continue
        if not rules.text_is_scored(rep.type, rep.text):
            why = f"text {rep.text!r} is not scored by {rules.name} (qr_text_filter {rules.qr_text_filter!r})"
            report_scores[rep.line] = report_outcome(rep, STATUS_IGNORED, why)
            continue
        ident = identity_of(rep.type, rep.text, rules)
        if ident is None:
            if rep.type == "landolt-c":
                rings = ", ".join(str(k) for k in rules.landolt_rings or ())
                why = f"Landolt-C text {rep.text!r} does not give the gap direction of ring(s) {rings}"
            elif rep.text:
                why = f"unknown hazmat label {rep.text!r}"
            else:
                why = f"no text: a {rep.type} report is identified by its text"
            report_scores[rep.line] = report_outcome(rep, STATUS_FALSE, why, points=-rules.penalty(rep.type))
            continue
        groups_r.setdefault(ident, []).append(rep)

    for prob in reports.problems:
        report_scores[prob.line] = unreadable_outcome(prob, rules, rules.penalty(prob.type))

    for ident in sorted(groups_r):
        reps = groups_r[ident]
        objs = groups_o.get(ident, [])
        rule = rules.types[ident[0]]
        radius = rules.pair_radius(ident[0])
        P = np.array([[r.x, r.y, r.z] for r in reps])  # (n, 3)
        Q = np.array([[truth.rows[k].x, truth.rows[k].y, truth.rows[k].z] for k in objs])
        with np.errstate(over="ignore"):  # far-off coordinates give an inf distance: capped in optimal_pairs
            D = np.linalg.norm(P[:, None, :] - Q[None, :, :], axis=2) if objs else np.zeros((0, 0))
        pairs = optimal_pairs(D, radius) if objs else []
        paired_obj = {j: i for i, j in pairs}
        for i, j in pairs:
            report_scores[reps[i].line] = _pair(reps[i], objs[j], float(D[i, j]), rule, truth, object_scores, "")
        paired_rep = {i for i, _ in pairs}
        for i, rep in enumerate(reps):
            if i in paired_rep:
                continue
            if objs:
                reason = _unpaired_reason(D[i], objs, paired_obj, reps, truth, ident, radius)
            else:
                reason = _no_identity_reason(rep, ident, truth, rules)
            report_scores[rep.line] = report_outcome(rep, STATUS_FALSE, reason, points=-rules.penalty(rep.type))

    if untyped:
        _pair_by_location(untyped, truth, scored_objects, object_scores, report_scores, rules)
    mapping = _apply_fiducial_mapping(rules, report_scores, object_scores, reports, truth)
    autonomy = _apply_autonomy(rules, report_scores, object_scores, {r.line: r.mode for r in reports.rows})
    result = _totals(rules, report_scores, object_scores, scored_objects, reports, truth)
    result.types_checked = reports.typed
    result.autonomy = autonomy
    result.qr_mapping = mapping
    return result


def _apply_fiducial_mapping(
    rules: Rules,
    report_scores: dict[int, ReportOutcome],
    object_scores: list[ObjectOutcome],
    reports: PoiFile,
    truth: PoiFile,
) -> dict[str, Any] | None:
    """The QR mapping bonus by fiducials (module docstring), applied in place to the paired QR
    reports and their objects; what was done, for the report, or None under the radius rule."""
    if rules.qr_mapping != "fiducials":
        return None
    tol = float(rules.fiducial_tolerance_m)
    fids = [o for o in truth.rows if o.type == "fiducial"]
    block: dict[str, Any] = {
        "rule": "fiducials",
        "tolerance_m": tol,
        "fiducials_truth": len(fids),
        "fiducials_reported": sum(r.type == "fiducial" for r in reports.rows),
    }
    if len(fids) < 2:
        block["reason"] = (
            f"the ground truth has {len(fids)} fiducial(s), fewer than two: the radius rule decided "
            f"(within {rules.types['qr'].locate_radius_m:g} m)"
        )
        return block
    F = np.array([[o.x, o.y] for o in fids])  # (f, 2) true positions
    reported = [r for r in reports.rows if r.type == "fiducial"]
    on_map = F.copy()  # (f, 2) each fiducial where the map has it
    from_report = np.zeros(len(fids), dtype=bool)
    if reported:
        R = np.array([[r.x, r.y] for r in reported])  # (n, 2)
        with np.errstate(over="ignore"):
            D = np.linalg.norm(R[:, None, :] - F[None, :, :], axis=2)
        for i, j in optimal_pairs(D, rules.fiducial_match_radius_m):
            on_map[j], from_report[j] = R[i], True
    block["fiducials_paired"] = int(from_report.sum())
    obj_by_line = {o.report_line: o for o in object_scores if o.report_line is not None}
    rule = rules.types["qr"]
    located = tested = 0
    used_truth: set[int] = set()
    for r in report_scores.values():
        if r.type != "qr" or r.status not in (STATUS_LOCATED, STATUS_IDENTIFIED):
            continue
        o = obj_by_line[r.line]
        q_true = np.array([o.x, o.y])
        q_map = np.array([r.x, r.y])
        d_true = np.linalg.norm(F - q_true, axis=1)  # (f,)
        nearest = np.argsort(d_true, kind="stable")[:2]
        errors = [abs(float(np.linalg.norm(q_map - on_map[j])) - float(d_true[j])) for j in nearest]
        ok = max(errors) <= tol + EPS_M
        used_truth |= {int(j) for j in nearest if not from_report[j]}
        tested += 1
        located += ok
        names = " and ".join(
            f"{fids[j].id} ({'reported' if from_report[j] else 'true position'}) {e:.2f} m"
            for j, e in zip(nearest, errors, strict=True)
        )
        r.status = o.status = STATUS_LOCATED if ok else STATUS_IDENTIFIED
        r.points = o.points = rule.located_points if ok else rule.points
        o.located = ok
        verdict = "mapped" if ok else "not mapped"
        r.reason = f"{verdict}: distance errors to fiducials {names}, limit {tol:g} m"
    block["qr_tested"] = tested
    block["qr_mapped"] = located
    if used_truth:
        block["fiducials_from_truth"] = len(used_truth)
        block["reason"] = (
            f"{located} of {tested} QR code(s) mapped; the report lacks {len(used_truth)} of the fiducials "
            "the test needs: their true positions were used as the map's"
        )
    elif tested:
        block["reason"] = f"{located} of {tested} QR code(s) mapped, against the reported fiducials"
    else:
        block["reason"] = "no QR code was paired: nothing to test"
    return block


def _pair(
    rep: PoiRow, k: int, d: float, rule: TypeRule, truth: PoiFile, object_scores: list[ObjectOutcome], reason: str
) -> ReportOutcome:
    """Rule 3 for the pair (report, truth object ``k``) at distance ``d``: the report's outcome;
    the object's outcome is updated in place."""
    located = rule.locate_radius_m is not None and d <= rule.locate_radius_m + EPS_M
    points = rule.located_points if located else rule.points
    status = STATUS_LOCATED if located else STATUS_IDENTIFIED
    o = object_scores[k]
    o.found_by, o.report_line, o.distance_m = rep.id, rep.line, d
    o.points, o.located, o.status = points, located, status
    return report_outcome(rep, status, reason, points=points, object_id=truth.rows[k].id, distance_m=d)


def _pair_by_location(
    reps: list[PoiRow],
    truth: PoiFile,
    scored_objects: list[int],
    object_scores: list[ObjectOutcome],
    report_scores: dict[int, ReportOutcome],
    rules: Rules,
) -> None:
    """Reports without a type (POI 1.3, module docstring) paired with every scored object by
    3D distance within ``identify_radius_m``; a paired report takes its object's type."""
    radius = rules.identify_radius_m
    P = np.array([[r.x, r.y, r.z] for r in reps])  # (n, 3)
    Q = np.array([[truth.rows[k].x, truth.rows[k].y, truth.rows[k].z] for k in scored_objects]).reshape(-1, 3)
    with np.errstate(over="ignore"):
        D = np.linalg.norm(P[:, None, :] - Q[None, :, :], axis=2)  # (n, m)
    pairs = optimal_pairs(D, radius) if scored_objects else []
    paired = {i: j for i, j in pairs}
    rep_of_obj = {j: i for i, j in pairs}
    for i, rep in enumerate(reps):
        if i in paired:
            k = scored_objects[paired[i]]
            obj = truth.rows[k]
            typed = PoiRow(**{**vars(rep), "type": obj.type})
            why = "no type column: paired by location, type not checked"
            d = float(D[i, paired[i]])
            report_scores[rep.line] = _pair(typed, k, d, rules.types[obj.type], truth, object_scores, why)
            continue
        if not scored_objects:
            reason = "no type column, and no scored object in the ground truth"
        else:
            j = int(np.argmin(D[i]))
            d, obj = float(D[i, j]), truth.rows[scored_objects[j]]
            if radius is not None and d > radius + EPS_M:
                reason = f"too far: nearest object {obj.id} ({obj.type}) is {d:.2f} m away, limit {radius:g} m"
            else:
                other = reps[rep_of_obj[j]] if j in rep_of_obj else None
                by = f"report {other.id} (line {other.line})" if other is not None else "another report"
                reason = f"duplicate: nearest object {obj.id} ({obj.type}) already paired to {by}"
        report_scores[rep.line] = report_outcome(rep, STATUS_FALSE, reason)


def _apply_autonomy(
    rules: Rules,
    report_scores: dict[int, ReportOutcome],
    object_scores: list[ObjectOutcome],
    mode_of: dict[int, str],
) -> dict[str, Any] | None:
    """The autonomy multiplier (module docstring), applied in place to the paired reports of
    mode ``A`` and their objects; what was done, for the report, or None without autonomy scoring."""
    multiplier = rules.autonomy_multiplier
    if multiplier is None:
        return None
    false = [r for r in report_scores.values() if r.status == STATUS_FALSE]
    multiple = sum(r.reason.startswith("duplicate") for r in false)
    applied = not (rules.autonomy_requires_no_false_or_multiple and false)
    autonomous = [
        r
        for r in report_scores.values()
        if r.status in (STATUS_LOCATED, STATUS_IDENTIFIED) and mode_of.get(r.line) == "A"
    ]
    multiplied = 0
    if applied:
        object_of = {o.report_line: o for o in object_scores if o.report_line is not None}
        for r in autonomous:
            factor = rules.autonomy_factor(r.type)
            if factor == 1:
                continue
            r.points = r.points * factor
            r.reason = f"autonomous: points x{factor:g}"
            object_of[r.line].points = r.points
            multiplied += 1
        reason = f"{counted(multiplied, 'autonomous report')} (mode A) multiplied by {multiplier:g}"
    else:
        reason = (
            f"not applied: the run has {counted(len(false), 'false report')}, "
            f"{multiple} of them multiple "
            "detections; the multiplier requires none"
        )
    return {
        "multiplier": multiplier,
        "applied": applied,
        "autonomous_reports": len(autonomous),
        "multiplied_reports": multiplied,
        "reason": reason,
    }


def _unpaired_reason(
    d_row: np.ndarray,
    objs: list[int],
    paired_obj: dict[int, int],
    reps: list[PoiRow],
    truth: PoiFile,
    ident: Identity,
    radius: float | None,
) -> str:
    """Why a report with objects of its identity stayed unpaired: too far or a duplicate."""
    nearest = int(np.argmin(d_row))
    d_near = float(d_row[nearest])
    name = _ident_name(ident)
    if radius is not None and d_near > radius + EPS_M:
        return (
            f"too far: nearest {name} (object {truth.rows[objs[nearest]].id}) is "
            f"{d_near:.2f} m away, limit {radius:g} m"
        )
    allowed = [j for j in range(len(objs)) if radius is None or d_row[j] <= radius + EPS_M]
    j = min(allowed, key=lambda j: d_row[j])
    other = reps[paired_obj[j]] if j in paired_obj else None
    by = f"report {other.id} (line {other.line})" if other is not None else "another report"
    return f"duplicate: object {truth.rows[objs[j]].id} ({name}) already paired to {by}"


def _no_identity_reason(rep: PoiRow, ident: Identity, truth: PoiFile, rules: Rules) -> str:
    """Why a report whose identity no object has is false: wrong text or wrong type."""
    name = _ident_name(ident)
    same_type = [o for o in truth.rows if o.type == rep.type]
    if ident[0] == "landolt-c" and same_type:
        reason = f"wrong orientation: no landolt-c target has {ident[1]!r}"
    elif ident[1] and same_type:
        reason = f"wrong text: no {rep.type} object reads {rep.text!r}"
    else:
        reason = f"no {name} in the ground truth"
    limit = rules.pair_radius(rep.type)
    near = [(math.dist((rep.x, rep.y, rep.z), (o.x, o.y, o.z)), o) for o in truth.rows if rules.is_scored(o.type)]
    near = [(d, o) for d, o in near if limit is None or d <= limit + EPS_M]
    if near:
        d, o = min(near, key=lambda t: t[0])
        text = f" {o.text!r}" if o.text else ""
        reason += f" (nearest object: {o.id}, {o.type}{text}, {d:.2f} m)"
    return reason


def _ident_name(ident: Identity) -> str:
    return f"{ident[0]} {ident[1]!r}" if ident[1] else ident[0]


def _totals(
    rules: Rules,
    report_scores: dict[int, ReportOutcome],
    object_scores: list[ObjectOutcome],
    scored_objects: list[int],
    reports: PoiFile,
    truth: PoiFile,
) -> ScoreResult:
    per_type = {t: TypeTotals(type=t) for t in rules.types}
    rows = [report_scores[line] for line in sorted(report_scores)]
    for r in rows:
        if r.status == STATUS_IGNORED or r.type not in per_type:
            continue
        t = per_type[r.type]
        t.reports += 1
        if r.status == STATUS_FALSE:
            t.false_reports += 1
            t.points_lost += -r.points
        else:
            t.identified += 1
            t.located += r.status == STATUS_LOCATED
            t.points_won += r.points
    for k in scored_objects:
        o = object_scores[k]
        t = per_type[o.type]
        t.objects += 1
        t.max_points += rules.max_points(o.type)
        if o.status == STATUS_MISSED:
            t.missed += 1
        else:
            t.found += 1
    for t in per_type.values():
        t.points = t.points_won - t.points_lost
    problems = reader_problems(reports, truth)
    # Points lost to unreadable rows of unknown type are 0 by the rules, so the sum
    # of the per-type totals is the total.
    total = sum(r.points for r in rows)
    return ScoreResult(
        rules=rules,
        reports=rows,
        objects=object_scores,
        per_type=per_type,
        total=total + 0,
        max_total=sum(t.max_points for t in per_type.values()),
        identified=sum(t.identified for t in per_type.values()),
        located=sum(t.located for t in per_type.values()),
        false_reports=sum(r.status == STATUS_FALSE for r in rows),
        misses=sum(t.missed for t in per_type.values()),
        ignored_reports=sum(r.status == STATUS_IGNORED for r in rows),
        problems=problems,
    )
