"""The funnel (eval/scoring/funnel.py, eval/trial/funnel_recorder.py): hand-built trials in which
one object is lost at each stage in turn, each charged to that stage, the charges adding up to
max minus score."""

from __future__ import annotations

import numpy as np
import pytest

from eval.scoring.funnel import (
    DetectorActivity,
    ObjectView,
    format_funnel,
    funnel_json,
    funnel_rows,
    sum_per_type,
)
from eval.scoring.rules import load_rules
from eval.scoring.scorer import score
from eval.trial.funnel_recorder import FunnelRecorder, match_boxes
from poi.config import load_config
from poi.core.in_view import IN_VIEW_FRACTION
from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text, parse_poi_text
from poi.core.types import Detection, Frame, Intrinsics, TrackSnapshot
from poi.pipeline import FrameResult

EX3 = load_rules("ex3")
RMRC = load_rules("rmrc2025")
HEADER = PoiHeader(team="t", country="c", date="2025-01-01", start_time="10:00:00", mission="m")
INTR = Intrinsics(width=640, height=480, fx=600.0, fy=600.0, ppx=320.0, ppy=240.0)
BOX = (100.0, 100.0, 160.0, 160.0)  # every object's visible box in the hand-built frames (60 px)


def row(id_: int, type_: str, x: float, y: float = 0.0, text: str = "", mode: str = "T") -> PoiRow:
    return PoiRow(line=0, id=id_, time="10:00:01", text=text, x=x, y=y, z=0.0, robot="r", mode=mode, type=type_)


def poi(*rows: PoiRow):
    return parse_poi_text(format_poi_text(HEADER, list(rows)))


def det(type_: str, text: str = "", track: int | None = None, box=BOX) -> Detection:
    return Detection(class_name=text or type_, type=type_, text=text, box_xyxy=box, confidence=0.9, track_id=track)


def snap(track: int, report: int | None, type_: str, n: int = 3) -> TrackSnapshot:
    return TrackSnapshot(
        track_id=track,
        report_id=report,
        type=type_,
        text="",
        position_map=np.zeros(3),
        covariance=np.eye(3),
        first_seen_s=0.0,
        support=1.0,
        n_detections=n,
        confirmed=report is not None,
    )


def frame(k: int, depth: float = 1.0) -> Frame:
    return Frame(
        index=k,
        timestamp_s=0.1 * k,
        rgb=np.zeros((0, 0, 3), np.uint8),
        intrinsics=INTR,
        depth_m=np.full((480, 640), depth, np.float32),
        pose=np.eye(4),
    )


def view(oid: int, fraction: float = 1.0, box=BOX) -> ObjectView:
    return ObjectView(id=oid, box_xyxy=box, visible_fraction=fraction, distance_m=1.0, angle_deg=10.0)


def result(k: int, dets: list[Detection], observed: list[int], confirmed=(), qr_tried=()) -> FrameResult:
    return FrameResult(
        frame_index=k,
        timestamp_s=0.1 * k,
        detections=dets,
        observations=[],
        newly_confirmed=list(confirmed),
        observed=list(observed),
        qr_tried=list(qr_tried),
    )


# The truth: one object lost at each stage, and the objects the false reports lie on.
TRUTH = [
    (0, "door", "", 10.0),  # never in view: "not in view"
    (1, "valve", "", 20.0),  # in view, never boxed: "not boxed"
    (2, "baby-doll", "", 30.0),  # boxed as a door: "wrong type"
    (3, "fire-extinguisher", "", 40.0),  # boxed as its type, no depth in its box: "not localised"
    (4, "qr", "Chart A", 50.0),  # localised, its text never read: "not read"
    (5, "hazmat", "explosive", 60.0),  # read, its track never confirmed: "not confirmed"
    (6, "hazmat", "flammable-gas", 70.0),  # its track reported as poison: "reported wrong"
    (7, "exit-sign", "", 80.0),  # reported 1.5 m off: paired, "not located"
    (8, "exit-sign", "", 90.0),  # reported 3 m off: "misplaced"
    (9, "fire-extinguisher-sign", "", 100.0),  # two tracks reported: one pairs, one a duplicate
]


def truth_file():
    return poi(*(row(i, t, x, text=text) for i, t, text, x in TRUTH))


def run_recorder(rules=EX3):
    """Twelve frames through the recorder, each object seen as its comment in TRUTH says."""
    objects = [(i, t, text, 10 if t == "qr" else None) for i, t, text, _ in TRUTH]  # QR: 5 px a module
    rec = FunnelRecorder(objects, load_config(), rules)
    confirmed_at = {6: [snap(16, 1, "hazmat")], 7: [snap(17, 2, "exit-sign"), snap(18, 3, "exit-sign")]}
    for k in range(12):
        # each object in a 50 px box of its own, 60 px apart; object 0 under the in-view fraction
        views = [
            view(i, IN_VIEW_FRACTION - 0.1 if i == 0 else 1.0, box=(60.0 * i, 0.0, 60.0 * i + 50, 50.0))
            for i in range(10)
        ]
        box = {v.id: v.box_xyxy for v in views}
        dets = [
            det("door", box=box[2]),  # on the doll, as a door; not localised
            det("fire-extinguisher", box=box[3]),  # not localised (frame has no depth there)
            det("qr", "", track=14, box=box[4]),
            det("hazmat", "explosive", track=15, box=box[5]),
            det("hazmat", "flammable-gas", track=16, box=box[6]),
            det("exit-sign", track=17, box=box[7]),
            det("exit-sign", track=18, box=box[8]),
            det("fire-extinguisher-sign", track=19, box=box[9]),
            det("valve", track=21, box=(500.0, 400.0, 560.0, 460.0)),  # on nothing: background
        ]
        observed = [2, 3, 4, 5, 6, 7, 8]  # the door box and the extinguisher's give no observation
        conf = confirmed_at.get(k, [])
        if k == 8:
            conf = [snap(19, 4, "fire-extinguisher-sign"), snap(21, 5, "valve")]
        f = frame(k, depth=0.0)  # no valid depth anywhere: why the extinguisher is not localised
        rec.on_frame(views, 2.5, f, result(k, dets, observed, conf, qr_tried=[2]))
        # the duplicate track 20: a second box on object 9, in frames of its own
        second = det("fire-extinguisher-sign", track=20, box=(box[9][0] + 2, 2.0, box[9][2] + 2, 52.0))
        rec.on_frame(views[9:], 0.0, frame(100 + k), result(100 + k, [second], [0], [snap(20, 6, "x")] * (k == 9)))
    return rec


REPORTS = [
    row(1, "hazmat", 70.0, text="poison"),  # track 16: object 6 read as poison
    row(2, "exit-sign", 80.0, 1.5),  # track 17: 1.5 m off object 7
    row(3, "exit-sign", 90.0, 3.0),  # track 18: 3 m off object 8
    row(4, "fire-extinguisher-sign", 100.0),  # track 19: object 9
    row(5, "valve", 500.0, 500.0),  # track 21: background
    row(6, "fire-extinguisher-sign", 100.0, 0.1),  # track 20: object 9 again
]
FINAL = [
    snap(16, 1, "hazmat"),
    snap(17, 2, "exit-sign"),
    snap(18, 3, "exit-sign"),
    snap(19, 4, "fire-extinguisher-sign"),
    snap(21, 5, "valve"),
    snap(20, 6, "fire-extinguisher-sign"),
]


def test_each_object_is_charged_to_the_stage_it_was_lost_at_and_the_charges_add_up() -> None:
    rec = run_recorder()
    res = score(poi(*REPORTS), truth_file(), EX3)
    f = rec.funnel(FINAL, res)
    by_object = {c.object_id: (c.cause, c.points) for c in f.charges if c.object_id is not None}
    assert by_object == {
        0: ("not in view", 10),
        1: ("not boxed", 6),
        2: ("wrong type", 10),
        3: ("not localised", 6),
        4: ("not read", 2),
        5: ("not confirmed", 2),
        6: ("reported wrong", 2),
        7: ("not located", 1),  # 2 located - 1 identified
        8: ("misplaced", 2),
    }
    by_report = {c.report_line: (c.cause, c.points) for c in f.charges if c.report_line is not None}
    line = {r.id: r.line for r in res.reports}
    assert by_report == {
        line[1]: ("false: wrong label", 1),
        line[3]: ("false: misplaced", 1),
        line[5]: ("false: background", 3),
        line[6]: ("false: duplicate", 1),
    }
    # hand-computed: max 10+6+10+6+2+2+2+2+2+2 = 44; won 1 (object 7) + 2 (object 9); lost 1+1+3+1 = 6
    assert res.max_total == 44 and res.total == 3 - 6
    assert f.lost == pytest.approx(44 - (3 - 6))
    assert f.check_ok
    assert f.by_cause()["not in view"] == 10


def test_the_recorder_counts_the_stages_and_why_a_box_gave_no_observation() -> None:
    rec = run_recorder()
    t = rec.traces
    assert t[0].in_view_frames == 0  # under the in-view fraction every frame
    assert t[1].in_view_frames == 12 and t[1].boxed_frames == 0
    assert t[2].boxed_as == {"door": 12} and t[2].typed_frames == 0
    assert t[3].typed_frames == 12 and t[3].not_localised == {"depth fill": 12}
    assert t[4].localised_frames == 12 and t[4].read_frames == 0
    assert (t[4].qr_views, t[4].qr_decoded) == (12, 0)  # 50 px / 10 modules: given to the reader, not read
    assert t[5].read_frames == 12 and t[5].tracks == {15: 12}
    assert t[9].boxed_frames == 24 and set(t[9].tracks) == {19, 20}
    assert rec.tracks[21].main_object() is None  # its boxes lay on nothing
    assert rec.tracks[16].confirmed_frame == 6 and rec.tracks[16].observations_at_confirmation == 3


def test_a_qr_view_counts_towards_the_read_rate_from_three_pixels_a_module_whole_and_still_apart() -> None:
    asked = []

    def reader(frame, d):  # the reader, for the views the pipeline did not ask about
        asked.append(frame.index)
        return "Chart A"

    rec = FunnelRecorder([(0, "qr", "Chart A", 29)], load_config(), EX3, qr_reader=reader)
    small = (0.0, 0.0, 86.0, 86.0)  # 86 / 29 = 2.97 px a module: not counted
    large = (0.0, 0.0, 88.0, 88.0)  # 3.03 px
    cases = [  # box, text the pipeline read, asked, visible fraction, blur px
        (small, "", True, 1.0, 0.0),
        (large, "", True, 1.0, 0.0),  # asked, not read
        (large, "Chart A", True, 1.0, 0.0),  # read
        (large, "Chart B", True, 1.0, 0.0),  # read wrong
        (large, "", False, 1.0, 0.0),  # not asked (a settled track): the reader reads it
        (large, "Chart A", True, 0.5, 0.0),  # cut by the border: counted, not whole
        (large, "", True, 1.0, 4.0),  # smeared over more than a module: whole (the reader deblurs), not read
    ]
    for k, (b, text, tried, fraction, blur) in enumerate(cases):
        res = result(k, [det("qr", text, track=1, box=b)], [0], qr_tried=[0] if tried else [])
        rec.on_frame([view(0, fraction, box=b)], blur, frame(k), res)
    o = rec.traces[0]
    assert asked == [4]
    assert (o.qr_views, o.qr_decoded) == (6, 3)
    assert (o.qr_whole_views, o.qr_whole_decoded) == (5, 2)
    assert o.read_frames == 2  # what the pipeline itself read right


def test_autonomy_withheld_is_charged_to_the_multiplier_and_a_false_report_to_its_track() -> None:
    truth = poi(row(0, "hazmat", 0.0, text="explosive"), row(1, "hazmat", 5.0, text="poison"))
    reports = poi(
        row(1, "hazmat", 0.0, text="explosive", mode="A"), row(2, "hazmat", 5.0, text="corrosive", mode="A")
    )
    rec = FunnelRecorder([(0, "hazmat", "explosive", None), (1, "hazmat", "poison", None)], load_config(), RMRC)
    b1 = (300.0, 100.0, 360.0, 160.0)
    dets = [det("hazmat", "explosive", track=1), det("hazmat", "corrosive", track=2, box=b1)]
    rec.on_frame([view(0), view(1, box=b1)], 0.0, frame(0), result(0, dets, [0, 1]))
    res = score(reports, truth, RMRC)
    f = rec.funnel([snap(1, 1, "hazmat"), snap(2, 2, "hazmat")], res)
    causes = sorted((c.cause, c.points) for c in f.charges)
    # rmrc2025: a label scores 1, x4 autonomous; a false report withholds the multiplier and costs 0
    assert causes == [("autonomy withheld", 3), ("not read", 4)]  # its boxes read corrosive
    assert f.check_ok and f.lost == res.max_total - res.total == 7


def test_boxes_pair_one_to_one_by_iou_from_half() -> None:
    v = [view(0, box=(0, 0, 10, 10)), view(1, box=(20, 0, 30, 10))]
    d = [det("door", box=(0, 0, 10, 12)), det("door", box=(1, 0, 10, 10)), det("door", box=(24, 0, 34, 10))]
    # d1 (IoU 0.9) wins object 0 over d0 (0.83); d2 overlaps object 1 at IoU 0.43 < 0.5: background
    assert match_boxes(d, v) == {1: 0}


def test_a_silent_detector_is_named_in_one_line() -> None:
    a = DetectorActivity(frames=400, boxes=0, conf=0.4, highest_score=0.07)
    assert a.note() == "detector: 0 boxes at conf >= 0.4 in 400 frames (highest score 0.07)"
    assert DetectorActivity(frames=400, boxes=3, conf=0.4).note() is None


def test_the_outputs_carry_every_charge_and_a_suite_sums_per_type() -> None:
    rec = run_recorder()
    res = score(poi(*REPORTS), truth_file(), EX3)
    f = rec.funnel(FINAL, res)
    rows = funnel_rows(f)
    assert len([r for r in rows if r["kind"] == "object"]) == 10
    assert sum(float(r["points_lost"] or 0) for r in rows) == pytest.approx(f.lost)
    doc = funnel_json(f)
    assert doc["check"] == "ok" and doc["lost"] == pytest.approx(f.lost)
    # counts are whole numbers in score.json (1, not 1.0), the points lost to each cause are not
    from eval.scoring.funnel import STAGES

    for counts in doc["per_type"].values():
        assert all(type(counts[k]) is int for k in ("objects", *STAGES)), counts
    twice = sum_per_type([f.per_type(), f.per_type()])
    assert twice["exit-sign"]["objects"] == 4 and twice["exit-sign"]["misplaced"] == 4
    text = format_funnel(twice, 2 * f.lost, 2 * f.max_minus_score)
    assert text.splitlines()[-1].endswith(": ok")


def test_an_object_whose_place_went_to_a_report_of_another_type_says_so() -> None:
    """A placard boxed twice as itself (a track never confirmed) and three times as an exit sign
    (reported): its lost points are charged to `not confirmed`, naming the exit-sign report on
    it, and the report to `false: other object`."""
    truth = poi(row(0, "hazmat", 0.0, text="explosive"))
    rec = FunnelRecorder([(0, "hazmat", "explosive", None)], load_config(), EX3)
    for k in range(5):
        d = det("hazmat", "explosive", track=6) if k < 2 else det("exit-sign", track=5)
        rec.on_frame([view(0)], 0.0, frame(k), result(k, [d], [0]))
    res = score(poi(row(1, "exit-sign", 0.0)), truth, EX3)
    f = rec.funnel([snap(5, 1, "exit-sign")], res)
    (obj,) = [c for c in f.charges if c.object_id == 0]
    assert obj.cause == "not confirmed"
    assert obj.detail == (
        "2 observations with its identity in 1 track(s), none confirmed; reported as exit-sign there"
    )
    assert [c.cause for c in f.charges if c.report_line is not None] == ["false: other object"]
    assert f.check_ok


@pytest.mark.parametrize("shift_px, cause", [(30.0, "false: other object"), (52.0, "false: background")])
def test_a_false_reports_box_lies_on_an_object_from_a_tenth_of_iou(shift_px, cause) -> None:
    """A box half off a placard (IoU 0.33 with its 60 px box) still lies on it (TIDE's background
    threshold 0.1); one 52 px off (IoU 0.07) lies on the background."""
    truth = poi(row(0, "hazmat", 0.0, text="explosive"))
    rec = FunnelRecorder([(0, "hazmat", "explosive", None)], load_config(), EX3)
    x1, y1, x2, y2 = BOX
    off = (x1 + shift_px, y1, x2 + shift_px, y2)
    for k in range(3):
        rec.on_frame([view(0)], 0.0, frame(k), result(k, [det("exit-sign", track=5, box=off)], [0]))
    res = score(poi(row(1, "exit-sign", 0.0)), truth, EX3)
    f = rec.funnel([snap(5, 1, "exit-sign")], res)
    assert [(c.cause, c.points) for c in f.charges if c.report_line is not None] == [(cause, 1)]
    assert f.check_ok


def test_a_qr_code_never_seen_at_3_px_a_module_is_said_so() -> None:
    """Without a view at >= 3 px a module the QR reader has no read rate: the table says why its line
    is missing, and the object's cause says how close it came, in plain words."""
    from eval.scoring.funnel import STAGES, ObjectTrace, _perception_detail

    row = {"objects": 1, **{s: 0 for s in STAGES}, "in_view": 1, "not read": 2.0, "qr_views": 0}
    text = format_funnel({"qr": row}, 2.0, 2.0)
    assert "QR reader: no view of a QR code at >= 3 px a module (the views its read rate counts)" in text
    o = ObjectTrace(id=4, type="qr", text="Chart A", modules=29, best_px=32.0, localised_frames=6)
    assert _perception_detail("not read", o) == (
        "localised 6 frames; no view at >= 3 px a module (best 1.1 px a module); the pipeline's reads: none right"
    )


def test_a_door_larger_than_the_frame_is_in_view_a_placard_so_seen_is_not() -> None:
    """Close by, a door fills the frame with a quarter of itself: in view as a large view; a placard
    needs its face (the in-view test, poi.core.in_view), and the cause of one never in view says
    which test it failed."""
    from eval.scoring.funnel import ObjectTrace, _perception_detail

    frame_filling = dict(
        box_xyxy=(0.0, 0.0, 640.0, 480.0), visible_fraction=0.26, distance_m=0.6, pixels=640 * 480
    )
    rec = FunnelRecorder([(0, "door", "", None), (1, "hazmat", "poison", None)], load_config(), EX3)
    views = [ObjectView(id=0, type="door", **frame_filling), ObjectView(id=1, type="hazmat", **frame_filling)]
    for k in range(3):
        rec.on_frame(views, 0.0, frame(k), result(k, [], []))
    assert (rec.traces[0].in_view_frames, rec.traces[1].in_view_frames) == (3, 0)
    assert _perception_detail("not in view", ObjectTrace(id=0, type="door", text="")) == (
        "never at least 35% visible with a box of 12 px, nor a large view (9216 px or more)"
    )
    assert _perception_detail("not in view", ObjectTrace(id=1, type="hazmat", text="poison")) == (
        "never at least 35% visible with a box of 12 px"
    )


def test_a_recordings_funnel_says_its_views_are_points_by_the_recordings_pose() -> None:
    """A replay judges in view at each object's point projected by the recording's pose: no box size
    or visible share to quote, so the causes say what was judged instead of '0 px'."""
    from eval.scoring.funnel import ObjectTrace, _perception_detail

    never = ObjectTrace(id=1, type="valve", text="", by_pose=True)
    assert _perception_detail("not in view", never) == (
        "its point never in view by the recording's pose (inside the image, before the depth there)"
    )
    seen = ObjectTrace(id=2, type="valve", text="", by_pose=True, in_view_frames=18, min_distance_m=1.25)
    assert (
        _perception_detail("not boxed", seen)
        == "its point in view 18 frames by the recording's pose, nearest 1.25 m"
    )
    rec = FunnelRecorder([(3, "door", "", None)], load_config(), EX3, by_pose=True)
    assert rec.traces[3].by_pose


def test_the_funnel_lists_types_in_the_order_the_score_table_does() -> None:
    """Both tables list types in poi.core.names.TYPES' order (the funnel listed them alphabetically)."""
    from eval.scoring.funnel import STAGES

    rows = {t: {"objects": 1, **{s: 1 for s in STAGES}} for t in ("qr", "door", "hazmat")}
    body = format_funnel(rows, 0.0, 0.0).splitlines()[3:6]
    assert [line.split()[0] for line in body] == ["hazmat", "qr", "door"]


def test_the_read_stage_follows_the_rules_identity_uses_text(tmp_path) -> None:
    """A rules file where a placard's text is not its identity and a door's is: a placard boxed
    with the wrong label is read (the scorer pairs its report), a door boxed without text is not."""
    path = tmp_path / "r.yaml"
    path.write_text(
        "name: r\nidentify_radius_m: 2.0\nfalse_report_penalty: type_points\nunscored_types: ignore\ntypes:\n"
        "  hazmat: {points: 1, locate_radius_m: null, located_points: null, identity_uses_text: false}\n"
        "  door: {points: 1, locate_radius_m: null, located_points: null, identity_uses_text: true}\n"
    )
    rules = load_rules(str(path))
    truth = poi(row(0, "hazmat", 0.0, text="explosive"), row(1, "door", 5.0, text="left"))
    rec = FunnelRecorder([(0, "hazmat", "explosive", None), (1, "door", "left", None)], load_config(), rules)
    b1 = (300.0, 100.0, 360.0, 160.0)
    dets = [det("hazmat", "poison", track=1), det("door", track=2, box=b1)]
    rec.on_frame([view(0), view(1, box=b1)], 0.0, frame(0), result(0, dets, [0, 1]))
    res = score(poi(row(1, "hazmat", 0.0, text="poison"), row(2, "door", 5.0)), truth, rules)
    assert [o.status for o in res.objects] == ["identified", "missed"]  # as the scorer reads them
    f = rec.funnel([snap(1, 1, "hazmat"), snap(2, 2, "door")], res)
    assert (f.stages[0]["read"], f.stages[1]["read"]) == (True, False)
    assert [c.cause for c in f.charges if c.object_id == 1] == ["not read"]
    assert f.check_ok
