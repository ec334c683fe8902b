"""The funnel: which stage lost each point of a trial (docs/RULES.md "The funnel").

Every ground-truth object passes, or stops at, the stages of the pipeline in order
(:data:`STAGES`): in view, boxed, boxed as its type, localised, read, confirmed in a track,
paired by the scorer, located. :class:`ObjectTrace` holds what a trial saw of one object at
each stage, frame by frame (:mod:`eval.trial.funnel_recorder` fills it), and
:class:`TrackTrace` which objects each track's boxes lay on.

:func:`attribute` then gives every lost point exactly one cause, in the manner of TIDE
([Bolya2020]_: an error is charged to the one fix that would recover its points, so the
charges add up to the loss):

* an object the scorer left unpaired loses its ``max_points`` to the first stage it did not
  pass (:data:`OBJECT_CAUSES`), or, when it passed them all, to what became of its report
  (read wrong in the file, misplaced, or taken by another object's pairing);
* a paired object that is not located loses the located bonus to ``not located``, and a run
  whose autonomy multiplier was withheld loses the rest to ``autonomy withheld``;
* a false report loses its penalty to what its track's boxes lay on
  (:data:`FALSE_CAUSES`): background, another object, the right object read with a wrong
  label, a second track of an object already reported, or a report too far from its object.

The sum of the charges equals ``max_total - total`` of the score (:attr:`Funnel.check_ok`);
the ``tests/eval/scoring/test_funnel.py`` scenarios lose an object at each stage in turn.

References
----------
Full entries in docs/SOURCES.md.

.. [Bolya2020] D. Bolya, S. Foley, J. Hays, J. Hoffman, "TIDE: A General Toolbox for
   Identifying Object Detection Errors", ECCV 2020.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

from eval.scoring.map_error import MapErrorResult
from eval.scoring.pairing import STATUS_FALSE, STATUS_IGNORED, STATUS_MISSED, ObjectOutcome, ReportOutcome
from eval.scoring.rules import Rules
from eval.scoring.scorer import ScoreResult, identity_of
from poi.core.in_view import IN_VIEW_FRACTION, IN_VIEW_LARGE_PX, IN_VIEW_MIN_PX, boxable_view
from poi.core.names import TEXT_IDENTITY_TYPES, in_type_order

# The stages, in the order an object passes them (Funnel.per_type counts the objects that passed each)
STAGES = ("in_view", "boxed", "typed", "localised", "read", "confirmed", "paired", "located")
# What an object's lost points are charged to; the first six are the first stage it did not pass
OBJECT_CAUSES = (
    "not in view",  # the tour never showed it well enough for a perfect detector (poi.core.in_view)
    "not boxed",  # in view, but no box overlapped it with IoU >= BOX_IOU
    "wrong type",  # boxed, never as its own type
    "not localised",  # boxed as its type, no box gave an observation (depth, border)
    "not read",  # localised, its text or label never read right (qr, hazmat, landolt-c)
    "not confirmed",  # read and localised, but no track of its boxes was confirmed
    "reported wrong",  # its track was reported with another identity (the tracker's vote)
    "misplaced",  # its track was reported too far from it to pair
    "taken",  # its track's report was paired with another object of its identity
    "not located",  # paired, but beyond the locate radius: the located bonus
    "autonomy withheld",  # paired, but the run's autonomy multiplier was withheld
)
FALSE_CAUSES = (
    "false: background",  # the track's boxes lay on no object
    "false: other object",  # on an object of another type
    "false: wrong label",  # on an object of its type, read with another text or label
    "false: duplicate",  # a second track of an object already paired
    "false: misplaced",  # on its object, but reported too far from it
    "false: unknown",  # no track behind the row (an unreadable row, a team's file)
)
CAUSES = OBJECT_CAUSES + FALSE_CAUSES
BOX_IOU = 0.5  # a box is on an object when their IoU is at least this ([Bolya2020]'s t_f)
# a false report's box lies on the object it overlaps most from this IoU on, on the background
# below it everywhere ([Bolya2020]'s t_b)
BACKGROUND_IOU = 0.1
QR_MIN_MODULE_PX = 3.0  # a QR view counts towards the read rate from this many pixels a module
# A QR code is read from its three finder patterns and every module between them ([ISO18004]): a view
# cut by the image border is unreadable by any decoder
QR_WHOLE_FRACTION = 0.9


@dataclass(kw_only=True)
class ObjectView:
    """One ground-truth object as one frame shows it: its visible pixels' box, the share of it
    visible, its distance (m) and, for a flat item, the angle (degrees) between its face normal
    and the ray to the camera (NaN otherwise)."""

    id: int
    box_xyxy: tuple[float, float, float, float]
    visible_fraction: float
    distance_m: float
    angle_deg: float = float("nan")
    # a recording's view (poibench replay): only the object's position, projected by the pose the
    # recording gives; in view when it projects into the image with nothing nearer in the depth,
    # boxed by a box that holds that point (eval.trial.funnel_recorder.projected_views)
    point: bool = False
    type: str = ""  # the object's type (the in-view test's large views are for some types only)
    pixels: int = 0  # its visible pixels

    @property
    def min_side_px(self) -> float:
        x1, y1, x2, y2 = self.box_xyxy
        return min(x2 - x1, y2 - y1)

    def in_view(self) -> bool:
        """The in-view test (:func:`poi.core.in_view.boxable_view`, the oracle's); a point view is in
        view by construction. A view without its type is judged by its visible share alone."""
        if self.point:
            return True
        return boxable_view(
            self.type,
            visible_fraction=self.visible_fraction,
            pixels=self.pixels if self.type else 0,
            min_side_px=self.min_side_px,
        )


@dataclass(kw_only=True)
class ObjectTrace:
    """What a trial saw of one ground-truth object, stage by stage (frame counts)."""

    id: int
    type: str
    text: str
    modules: int | None = None  # a QR code's modules across, quiet zone included
    # in view judged at its point by a recording's own pose (poibench replay: no box, no visible
    # share, and a drifted pose can miss it where the scorer still pairs its report)
    by_pose: bool = False
    in_view_frames: int = 0
    first_in_view: int | None = None  # frame index
    best_px: float = 0.0  # the largest short side of its box in view
    min_distance_m: float = math.inf
    min_angle_deg: float = math.nan
    blur_px: list[float] = field(default_factory=list)  # the camera's blur at each in-view frame
    boxed_frames: int = 0
    typed_frames: int = 0
    boxed_as: Counter = field(default_factory=Counter)  # type of the box on it -> frames
    localised_frames: int = 0
    not_localised: Counter = field(default_factory=Counter)  # why a box of its type gave no observation
    read_frames: int = 0
    read_as: Counter = field(default_factory=Counter)  # text of its localised boxes -> frames
    # The reader on its views (QR codes): every in-view frame at >= QR_MIN_MODULE_PX a module with a QR
    # box on it, and those whole in the image (>= QR_WHOLE_FRACTION visible): the views a decoder can
    # read at all (a slew's blur the reader undoes from the gyro, poi.detectors.qr). The reader's text on
    # each such box counts, whether or not the pipeline asked for it (it stops asking once a track's text
    # is settled).
    qr_views: int = 0
    qr_decoded: int = 0
    qr_whole_views: int = 0
    qr_whole_decoded: int = 0
    tracks: Counter = field(default_factory=Counter)  # track id -> observations of it with its identity
    confirmed_frame: int | None = None  # when the first track of its observations was confirmed (attribute)
    observations_at_confirmation: int | None = None

    def px_per_module(self) -> float | None:
        return None if not self.modules else self.best_px / self.modules


@dataclass(kw_only=True)
class TrackTrace:
    """One track: what its observations' boxes lay on (the object each overlaps most at IoU >=
    ``BACKGROUND_IOU``; None, the background, below it) and when it was confirmed."""

    track_id: int
    on: Counter = field(default_factory=Counter)
    confirmed_frame: int | None = None
    observations_at_confirmation: int | None = None
    report_id: int | None = None

    def main_object(self) -> int | None:
        """The object most of its boxes lay on (None: background); ties to an object, the lower id."""
        if not self.on:
            return None
        return min(self.on, key=lambda k: (-self.on[k], k is None, -1 if k is None else k))


@dataclass(kw_only=True)
class Charge:
    """Points lost to one cause: an object's (``object_id``) or a false report's (``report_line``)."""

    cause: str
    points: float
    type: str
    detail: str
    object_id: int | None = None
    report_line: int | None = None


@dataclass(kw_only=True)
class DetectorActivity:
    """What the detectors gave over a trial: boxes at the run's threshold and the best score."""

    frames: int = 0
    boxes: int = 0
    conf: float | None = None
    highest_score: float | None = None  # the ONNX detector's best score, kept or not (None: not known)

    def note(self) -> str | None:
        """One line when the detectors boxed nothing, None otherwise."""
        if self.boxes or not self.frames:
            return None
        at = f" at conf >= {self.conf:g}" if self.conf is not None else ""
        best = "" if self.highest_score is None else f" (highest score {self.highest_score:.2f})"
        return f"detector: 0 boxes{at} in {self.frames} frames{best}"


@dataclass(kw_only=True)
class Funnel:
    """The funnel of one trial: each object's trace and stages, the charges, and their sum
    against the score's loss."""

    objects: list[ObjectTrace]
    stages: dict[int, dict[str, bool]]  # object id -> stage -> passed
    charges: list[Charge]
    lost: float  # the sum of the charges
    max_minus_score: float  # the score's max_total - total
    activity: DetectorActivity = field(default_factory=DetectorActivity)

    @property
    def check_ok(self) -> bool:
        return abs(self.lost - self.max_minus_score) < 1e-6

    def by_cause(self) -> dict[str, float]:
        """Points lost per cause, in :data:`CAUSES` order, causes that lost nothing left out."""
        out: dict[str, float] = {}
        for c in CAUSES:
            pts = sum(ch.points for ch in self.charges if ch.cause == c)
            if pts:
                out[c] = pts
        return out

    def per_type(self) -> dict[str, dict[str, float]]:
        """Per type: objects, how many passed each stage, and the points lost per cause."""
        out: dict[str, dict[str, float]] = {}
        for o in self.objects:
            if o.id not in self.stages:
                continue
            row = out.setdefault(o.type, {"objects": 0, **{s: 0 for s in STAGES}})
            row["objects"] += 1
            for s, ok in self.stages[o.id].items():
                row[s] += ok
            if o.type == "qr":
                for k, v in qr_read_rate([o]).items():
                    row["qr_" + k] = row.get("qr_" + k, 0) + v
        for ch in self.charges:
            row = out.setdefault(ch.type, {"objects": 0, **{s: 0 for s in STAGES}})
            row[ch.cause] = row.get(ch.cause, 0) + ch.points
        return out


def _first_missing_stage(o: ObjectTrace, rules: Rules) -> str | None:
    """The object cause of the first of the six perception stages ``o`` did not pass."""
    if not o.in_view_frames:
        return "not in view"
    if not o.boxed_frames:
        return "not boxed"
    if not o.typed_frames:
        return "wrong type"
    if not o.localised_frames:
        return "not localised"
    if not o.read_frames:
        return "not read"
    return None


def _stages(o: ObjectTrace, outcome: ObjectOutcome, confirmed: bool) -> dict[str, bool]:
    paired = outcome.status not in (STATUS_MISSED, STATUS_IGNORED)
    return {
        "in_view": o.in_view_frames > 0,
        "boxed": o.boxed_frames > 0,
        "typed": o.typed_frames > 0,
        "localised": o.localised_frames > 0,
        "read": o.read_frames > 0,
        "confirmed": confirmed,
        "paired": paired,
        "located": bool(outcome.located),
    }


def _perception_detail(cause: str, o: ObjectTrace) -> str:
    if cause == "not in view":
        if o.by_pose:
            return "its point never in view by the recording's pose (inside the image, before the depth there)"
        whole = f"never at least {IN_VIEW_FRACTION:.0%} visible with a box of {IN_VIEW_MIN_PX:g} px"
        if o.type in TEXT_IDENTITY_TYPES:
            return whole
        return f"{whole}, nor a large view ({IN_VIEW_LARGE_PX} px or more)"
    blur = sorted(o.blur_px)
    median_blur = blur[len(blur) // 2] if blur else 0.0
    if o.by_pose:
        n, d = o.in_view_frames, o.min_distance_m
        seen = f"its point in view {n} frames by the recording's pose, nearest {d:.2f} m"
    else:
        seen = (
            f"in view {o.in_view_frames} frames, best {o.best_px:.0f} px, nearest {o.min_distance_m:.2f} m"
            + ("" if math.isnan(o.min_angle_deg) else f", angle from {o.min_angle_deg:.0f} deg")
            + f", blur {median_blur:.1f} px median"
        )
    if cause == "not boxed":
        return seen
    if cause == "wrong type":
        kind, n = o.boxed_as.most_common(1)[0]
        return f"boxed {o.boxed_frames} frames, as {kind} in {n}"
    if cause == "not localised":
        why = ", ".join(f"{k} {n}" for k, n in sorted(o.not_localised.items()))
        return f"boxed as {o.type} in {o.typed_frames} frames, no observation ({why or 'no reason recorded'})"
    if cause == "not read":
        if o.type == "qr":
            ppm = o.px_per_module()
            best = "" if ppm is None else f" (best {ppm:.1f} px a module)"
            at = f"at >= {QR_MIN_MODULE_PX:g} px a module{best}"
            if not o.qr_views:
                views = f"no view {at}"
            elif not o.qr_whole_views:
                views = f"{o.qr_views} views {at}, none whole in the image: no decoder could read it there"
            else:
                whole = f"{o.qr_whole_views} of them whole in the image, {o.qr_whole_decoded} read right there"
                views = f"{o.qr_views} views {at}, {whole}"
            return f"localised {o.localised_frames} frames; {views}; the pipeline's reads: none right"
        read = ", ".join(f"{t or 'nothing'} {n}" for t, n in o.read_as.most_common(3))
        return f"localised {o.localised_frames} frames, read as {read}"
    return seen


def attribute(
    traces: list[ObjectTrace],
    tracks: dict[int, TrackTrace],
    result: ScoreResult | MapErrorResult,
    truth_ids: dict[int, int],
    activity: DetectorActivity | None = None,
) -> Funnel:
    """Charge every point ``result`` lost to one cause (module docstring).

    ``traces`` are the ground-truth objects' traces, ``tracks`` the traces of the tracks by track
    id (with their ``report_id`` set for those reported), ``truth_ids`` maps the truth file's row
    id (``ObjectOutcome.id``) to the object id of the traces (the same in a trial). A map-error
    result (no points) gives the stages and no charges.
    """
    by_id = {o.id: o for o in traces}
    report_track = {t.report_id: t for t in tracks.values() if t.report_id is not None}
    confirmed_by_object: dict[int, list[TrackTrace]] = {}
    for t in tracks.values():
        if t.confirmed_frame is None:
            continue
        for oid in t.on:
            if oid is not None:
                confirmed_by_object.setdefault(oid, []).append(t)
    stages: dict[int, dict[str, bool]] = {}
    charges: list[Charge] = []
    points_result = isinstance(result, ScoreResult)
    rules = result.rules if points_result else None
    lying_on = _reports_of_other_types(result, report_track, by_id)
    reports_by_id = {r.id: r for r in result.reports if r.id is not None}
    for outcome in result.objects:
        if outcome.status == STATUS_IGNORED:
            continue
        oid = truth_ids.get(outcome.id, outcome.id)
        o = by_id.get(oid)
        if o is None:
            continue
        mine = [t for t in confirmed_by_object.get(oid, []) if o.tracks.get(t.track_id)]
        if mine:
            first = min(mine, key=lambda t: (t.confirmed_frame, t.track_id))
            o.confirmed_frame, o.observations_at_confirmation = (
                first.confirmed_frame,
                first.observations_at_confirmation,
            )
        stages[oid] = _stages(o, outcome, bool(mine))
        if rules is None:
            continue
        max_pts = rules.max_points(o.type)
        lost = max_pts - float(outcome.points)
        if lost <= 0:
            continue
        if outcome.status != STATUS_MISSED:
            charges.extend(_paired_charges(o, outcome, rules, lost, result))
            continue
        cause = _first_missing_stage(o, rules)
        detail = "" if cause is None else _perception_detail(cause, o)
        if cause is None:
            cause, detail = _report_fate(o, mine, reports_by_id, report_track, rules, lying_on.get(oid, []))
        charges.append(Charge(cause=cause, points=lost, type=o.type, detail=detail, object_id=oid))
    if rules is not None:
        for r in result.reports:
            if r.status == STATUS_FALSE and r.points:
                charges.append(_false_charge(r, report_track, by_id, result, rules))
    max_minus = float(result.max_total - result.total) if points_result else 0.0
    return Funnel(
        objects=traces,
        stages=stages,
        charges=charges,
        lost=float(sum(c.points for c in charges)),
        max_minus_score=max_minus,
        activity=activity or DetectorActivity(),
    )


def _paired_charges(
    o: ObjectTrace, outcome: ObjectOutcome, rules: Rules, lost: float, result: ScoreResult
) -> list[Charge]:
    """A paired object's loss: the located bonus to ``not located``, the multiplier to
    ``autonomy withheld`` (its points were not multiplied)."""
    rule = rules.types[o.type]
    plain = rule.located_points if outcome.located and rule.located_points is not None else rule.points
    out: list[Charge] = []
    if math.isclose(float(outcome.points), float(plain)):  # not multiplied
        bonus = 0.0 if outcome.located or rule.located_points is None else rule.located_points - rule.points
        rest = lost - bonus
    else:  # multiplied: all of the loss is the located bonus, times the multiplier
        bonus, rest = lost, 0.0
    if bonus > 0:
        d = "" if outcome.distance_m is None else f"reported {outcome.distance_m:.2f} m from it"
        out.append(Charge(cause="not located", points=bonus, type=o.type, detail=d, object_id=o.id))
    if rest > 0:
        why = (result.autonomy or {}).get("reason", "")
        out.append(Charge(cause="autonomy withheld", points=rest, type=o.type, detail=why, object_id=o.id))
    return out


def _reports_of_other_types(
    result: ScoreResult | MapErrorResult, report_track: dict[int, TrackTrace], by_id: dict[int, ObjectTrace]
) -> dict[int, list[str]]:
    """Object id -> the types of the false reports whose track's boxes lay on it, of another type."""
    out: dict[int, list[str]] = {}
    for r in result.reports:
        t = report_track.get(r.id) if r.id is not None and r.status == STATUS_FALSE else None
        oid = None if t is None else t.main_object()
        if oid in by_id and by_id[oid].type != r.type:
            out.setdefault(oid, []).append(r.type)
    return out


def _report_fate(
    o: ObjectTrace,
    mine: list[TrackTrace],
    reports_by_id: dict[int, ReportOutcome],
    report_track: dict[int, TrackTrace],
    rules: Rules,
    lying_on: list[str] = (),
) -> tuple[str, str]:
    """The cause of an object that passed every perception stage and still went unpaired;
    ``lying_on``, the types of false reports of another type on it (a track of that type won
    the place's vote, poi.estimation.tracker step 6, or was confirmed first)."""
    if not mine:
        n = sum(o.tracks.values())
        why = f"{n} observations with its identity in {len(o.tracks)} track(s), none confirmed"
        if lying_on:
            why += f"; reported as {' and '.join(sorted(set(lying_on)))} there"
        return "not confirmed", why
    want = identity_of(o.type, o.text, rules)
    best = max(mine, key=lambda t: (o.tracks[t.track_id], -t.track_id))
    rep = reports_by_id.get(best.report_id) if best.report_id is not None else None
    if rep is None:
        return "not confirmed", f"track {best.track_id} confirmed but not in the file"
    got = identity_of(rep.type, rep.text, rules) if rep.type in rules.types else None
    if got != want:
        return "reported wrong", f"track {best.track_id} reported as {rep.type} {rep.text!r}".rstrip()
    if rep.object_id is not None and rep.status != STATUS_FALSE:
        return "taken", f"its report {rep.id} was paired with object {rep.object_id}"
    return "misplaced", f"report {rep.id}: {rep.reason}"


def _false_charge(
    r: ReportOutcome,
    report_track: dict[int, TrackTrace],
    by_id: dict[int, ObjectTrace],
    result: ScoreResult,
    rules: Rules,
) -> Charge:
    """A false report's penalty, charged to what its track's boxes lay on."""
    pts = -float(r.points)
    kind = r.type or "unknown"
    t = report_track.get(r.id) if r.id is not None else None
    if t is None:
        return Charge(cause="false: unknown", points=pts, type=kind, detail=r.reason, report_line=r.line)
    oid = t.main_object()
    where = f"at ({r.x:.2f}, {r.y:.2f})" if r.x is not None and r.y is not None else ""
    if oid is None or oid not in by_id:
        return Charge(
            cause="false: background", points=pts, type=kind, detail=f"{kind} {where}", report_line=r.line
        )
    o = by_id[oid]
    if o.type != r.type:
        detail = f"{r.type} on object {oid} ({o.type})"
        return Charge(cause="false: other object", points=pts, type=kind, detail=detail, report_line=r.line)
    if identity_of(o.type, o.text, rules) != identity_of(r.type, r.text, rules):
        detail = f"object {oid} {o.text!r} read as {r.text!r}"
        return Charge(cause="false: wrong label", points=pts, type=kind, detail=detail, report_line=r.line)
    if r.reason.startswith("duplicate") or any(
        ob.status not in (STATUS_MISSED, STATUS_IGNORED) and ob.id == oid for ob in result.objects
    ):
        detail = f"a second track ({t.track_id}) of object {oid}"
        return Charge(cause="false: duplicate", points=pts, type=kind, detail=detail, report_line=r.line)
    return Charge(cause="false: misplaced", points=pts, type=kind, detail=r.reason, report_line=r.line)


# ------------------------------------------------------------------------------ output

CSV_COLUMNS = (
    "kind",
    "id",
    "type",
    "text",
    "in_view",
    "best_px",
    "min_distance_m",
    "min_angle_deg",
    "median_blur_px",
    "boxed",
    "typed",
    "localised",
    "read",
    "qr_views",
    "qr_decoded",
    "qr_whole_views",
    "qr_whole_decoded",
    "tracks",
    "confirmed_frame",
    "points_lost",
    "lost_to",
    "detail",
)


def _r(v: float | None, k: int = 2) -> Any:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return round(float(v), k)


def funnel_rows(f: Funnel) -> list[dict[str, Any]]:
    """One row an object, then one a charged false report (:data:`CSV_COLUMNS`)."""
    by_object: dict[int, list[Charge]] = {}
    for ch in f.charges:
        if ch.object_id is not None:
            by_object.setdefault(ch.object_id, []).append(ch)
    rows = []
    for o in f.objects:
        if o.id not in f.stages:
            continue
        chs = by_object.get(o.id, [])
        blur = sorted(o.blur_px)
        rows.append(
            {
                "kind": "object",
                "id": o.id,
                "type": o.type,
                "text": o.text,
                "in_view": o.in_view_frames,
                "best_px": _r(o.best_px, 1),
                "min_distance_m": _r(o.min_distance_m),
                "min_angle_deg": _r(o.min_angle_deg, 1),
                "median_blur_px": _r(blur[len(blur) // 2] if blur else None, 1),
                "boxed": o.boxed_frames,
                "typed": o.typed_frames,
                "localised": o.localised_frames,
                "read": o.read_frames,
                "qr_views": o.qr_views if o.type == "qr" else "",
                "qr_decoded": o.qr_decoded if o.type == "qr" else "",
                "qr_whole_views": o.qr_whole_views if o.type == "qr" else "",
                "qr_whole_decoded": o.qr_whole_decoded if o.type == "qr" else "",
                "tracks": len(o.tracks),
                "confirmed_frame": "" if o.confirmed_frame is None else o.confirmed_frame,
                "points_lost": _r(sum(c.points for c in chs), 3),
                "lost_to": "; ".join(c.cause for c in chs),
                "detail": "; ".join(c.detail for c in chs),
            }
        )
    for ch in f.charges:
        if ch.report_line is None:
            continue
        row = dict.fromkeys(CSV_COLUMNS, "")
        row.update(kind="false report", id=ch.report_line, type=ch.type, points_lost=_r(ch.points, 3))
        row.update(lost_to=ch.cause, detail=ch.detail)
        rows.append(row)
    return rows


def qr_read_rate(objects: list[ObjectTrace]) -> dict[str, int]:
    """The reader's score on the QR views of a trial (:class:`ObjectTrace`'s ``qr_*`` counts summed)."""
    qr = [o for o in objects if o.type == "qr"]
    return {
        "views": sum(o.qr_views for o in qr),
        "decoded": sum(o.qr_decoded for o in qr),
        "whole_views": sum(o.qr_whole_views for o in qr),
        "whole_decoded": sum(o.qr_whole_decoded for o in qr),
    }


def funnel_json(f: Funnel) -> dict[str, Any]:
    """The funnel as ``score.json`` carries it: per type, per cause, the check, the charges."""
    return {
        "stages": list(STAGES),
        # objects and stages are counts (whole numbers), the causes points
        "per_type": {
            t: {
                k: int(round(v)) if k == "objects" or k in STAGES or k.startswith("qr_") else _r(v, 3)
                for k, v in row.items()
            }
            for t, row in f.per_type().items()
        },
        "lost_by_cause": {k: _r(v, 3) for k, v in f.by_cause().items()},
        "lost": _r(f.lost, 3),
        "max_minus_score": _r(f.max_minus_score, 3),
        "check": "ok" if f.check_ok else "MISMATCH",
        "qr_reads": qr_read_rate(f.objects),
        "charges": [{k: v for k, v in asdict(c).items() if v is not None} for c in f.charges],
        "detector": {k: v for k, v in asdict(f.activity).items() if v is not None},
    }


def format_funnel(per_type: dict[str, dict[str, float]], lost: float, max_minus_score: float | None) -> str:
    """The compact per-type table printed after a score (or summed over a suite): objects, how
    many passed each stage, the points lost and to what; then the check line."""
    header = [
        "type",
        "objects",
        "in view",
        "boxed",
        "typed",
        "localised",
        "read",
        "confirmed",
        "paired",
        "located",
        "lost",
        "lost to",
    ]
    rows = []
    for t in in_type_order(per_type):
        row = per_type[t]
        causes = [(c, row[c]) for c in CAUSES if row.get(c)]
        lost_t = sum(v for _, v in causes)
        rows.append(
            [
                t,
                _g(row["objects"]),
                *(_g(row[s]) for s in STAGES),
                _g(lost_t),
                ", ".join(f"{c} {_g(v)}" for c, v in causes),
            ]
        )
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines = ["Funnel (objects passing each stage; points lost, each to one cause)"]
    lines.append("  ".join(str(h).ljust(w) for h, w in zip(header, widths, strict=True)).rstrip())
    lines.append("  ".join("-" * w for w in widths))
    for r in rows:
        lines.append("  ".join(str(v).ljust(w) for v, w in zip(r, widths, strict=True)).rstrip())
    qr = per_type.get("qr", {})
    if qr.get("qr_views"):
        lines.append(
            f"QR reader: {_g(qr['qr_decoded'])} of {_g(qr['qr_views'])} views at >= {QR_MIN_MODULE_PX:g} px "
            f"a module read right ({qr['qr_decoded'] / qr['qr_views']:.0%}); of those whole in the image, "
            f"{_g(qr['qr_whole_decoded'])} of {_g(qr['qr_whole_views'])}"
            + (f" ({qr['qr_whole_decoded'] / qr['qr_whole_views']:.0%})" if qr["qr_whole_views"] else "")
            + f"; the other {_g(qr['qr_views'] - qr['qr_whole_views'])} cut by the image's border"
        )
    elif qr.get("objects"):
        at = f">= {QR_MIN_MODULE_PX:g} px a module"
        lines.append(f"QR reader: no view of a QR code at {at} (the views its read rate counts)")
    if max_minus_score is not None:
        verdict = "ok" if abs(lost - max_minus_score) < 1e-6 else "MISMATCH"
        lines.append(f"lost {_g(lost)} = max - score {_g(max_minus_score)}: {verdict}")
    return "\n".join(lines)


def _g(v: float) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def lost_by_cause(per_type: dict[str, dict[str, float]]) -> dict[str, float]:
    """Points lost per cause, summed over a funnel's types (``Funnel.per_type`` or a sum of them).

    >>> lost_by_cause({"qr": {"objects": 2, "in_view": 2, "not read": 2}, "door": {"false: background": 5}})
    {'not read': 2.0, 'false: background': 5.0}
    """
    out: dict[str, float] = {}
    for cause in CAUSES:
        total = sum(float(row.get(cause) or 0.0) for row in per_type.values())
        if total and math.isfinite(total):
            out[cause] = total
    return out


def lost_by_type(per_type: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """Type -> cause -> points lost, types that lost nothing left out."""
    out = {t: lost_by_cause({t: row}) for t, row in per_type.items()}
    return {t: lost for t, lost in out.items() if lost}


def sum_per_type(tables: list[dict[str, dict[str, float]]]) -> dict[str, dict[str, float]]:
    """Several trials' :meth:`Funnel.per_type` tables summed type by type (a suite's funnel)."""
    out: dict[str, dict[str, float]] = {}
    for table in tables:
        for t, row in table.items():
            acc = out.setdefault(t, {"objects": 0, **{s: 0 for s in STAGES}})
            for k, v in row.items():
                acc[k] = acc.get(k, 0) + v
    return out
