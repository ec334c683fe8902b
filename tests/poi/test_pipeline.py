"""poi.pipeline on synthetic frames with a fake detector; poi.annotate's drawing.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import poi.pipeline as pipeline_mod
from poi.annotate import annotate
from poi.config import apply_overrides, load_config
from poi.core.types import Detection, Frame, Intrinsics
from poi.detectors.base import make_detection
from poi.pipeline import Pipeline

K = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=319.5, ppy=239.5)
# box centre cx = 320 (corner convention) is pixel u = 319.5 = ppx: straight ahead
DOOR_BOX = (300.0, 220.0, 340.0, 260.0)
GHOST_BOX = (100.0, 100.0, 140.0, 140.0)


def synthetic_config(*sets: str):
    """The default settings for frames whose poses are at their own times: the latency that a
    T265 report has (``slam.odometry_latency_s``) would leave frame 0 unobserved (its pose
    cannot yet be brought forward; the latency's own test below)."""
    return apply_overrides(load_config(), ["slam.odometry_latency_s=0", *sets])


def make_det(class_name: str, box, conf: float = 0.9, text: str | None = None) -> Detection:
    return make_detection(class_name, box, conf, source="test", class_probs=None, text=text)


class FakeDetector:
    """Returns the detections scripted for each frame index (fresh objects each call)."""

    def __init__(self, script: dict[int, list[tuple]]) -> None:
        self.script = script

    def detect(self, frame: Frame) -> list[Detection]:
        return [make_det(*args) for args in self.script.get(frame.index, [])]


def make_frame(index: int, *, pose=True, depth=True) -> Frame:
    return Frame(
        index=index,
        timestamp_s=0.1 * index,
        rgb=np.full((K.height, K.width, 3), 40, np.uint8),
        intrinsics=K,
        depth_m=np.full((K.height, K.width), 2.0, np.float32) if depth else None,
        pose=np.eye(4) if pose else None,
    )


def test_static_object_seen_five_times_is_confirmed_once_at_the_right_place():
    cfg = synthetic_config("qr.enabled=false")
    pipe = Pipeline(cfg, [FakeDetector({i: [("door", DOOR_BOX)] for i in range(5)})])
    confirmed = []
    for i in range(5):
        res = pipe.process(make_frame(i))
        assert res.skipped_reason is None and len(res.observations) == 1
        assert set(res.timing_ms) == {"detect", "qr", "localize", "slam", "track"}
        confirmed += [(i, s.report_id) for s in res.newly_confirmed]
    assert confirmed == [(2, 0)]  # n_min = 3 detections
    (snap,) = pipe.confirmed()
    # p_c = (0, 0, 2) straight ahead, moved a door's surface_to_center_m further; default mount:
    # optical z -> tracker x, 45 mm up; identity pose: map = tracker frame
    x = 2.0 + cfg.localize.types["door"].surface_to_center_m
    assert snap.position_map.tolist() == pytest.approx([x, 0.0, 0.045], abs=1e-9)
    assert snap.type == "door" and snap.n_detections == 5
    assert res.detections[0].track_id == snap.track_id


def test_the_frame_result_carries_the_tracker_innovations():
    """Each paired update's innovation, S and NIS come out with the frame (no ground truth needed)."""
    pipe = Pipeline(
        synthetic_config("qr.enabled=false"), [FakeDetector({i: [("door", DOOR_BOX)] for i in range(3)})]
    )
    results = [pipe.process(make_frame(i)) for i in range(3)]
    assert [len(r.innovations) for r in results] == [0, 1, 1]  # frame 0 starts the track
    (track,) = pipe.tracks()
    for r in results[1:]:
        (inn,) = r.innovations
        assert inn.obs_index == 0 and inn.track_id == track.track_id
        assert inn.nu.shape == (3,) and inn.S.shape == (3, 3)
        # the same box from the same pose: the observation lands where the track is
        assert np.allclose(inn.nu, 0.0, atol=1e-9) and inn.d2 == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("latency_s", "observed"), [(0.01, 0), (0.0, 1)])
def test_the_first_frame_is_observed_only_when_its_pose_is_at_its_time(latency_s, observed):
    """With an odometry latency the first frame's pose is a report from before it, and no
    velocity yet brings it forward (poi.estimation.slam_localizer, step 1): placed with it, a
    placard 1.7 m away in a turn landed 3 cm off where R said millimetres, so the frame's
    observations are dropped, and its detections kept. Without a latency the pose is the
    frame's own."""
    cfg = apply_overrides(load_config(), ["qr.enabled=false", f"slam.odometry_latency_s={latency_s}"])
    pipe = Pipeline(cfg, [FakeDetector({0: [("door", DOOR_BOX)]})])
    res = pipe.process(make_frame(0))
    assert len(res.detections) == 1 and len(res.observations) == observed
    assert len(pipe.tracks()) == observed


def test_frames_without_pose_or_depth_are_detected_but_not_tracked():
    cfg = synthetic_config("qr.enabled=false")
    pipe = Pipeline(cfg, [FakeDetector({i: [("door", DOOR_BOX)] for i in range(3)})])
    res = pipe.process(make_frame(0, pose=False))
    assert res.skipped_reason == "no pose" and len(res.detections) == 1 and res.observations == []
    res = pipe.process(make_frame(1, depth=False))
    assert res.skipped_reason == "no depth" and len(res.detections) == 1
    assert pipe.tracks() == []


def test_a_false_detection_dies_by_the_negative_update():
    cfg = synthetic_config("qr.enabled=false")
    script = {i: [("door", DOOR_BOX)] for i in range(6)}
    script[0] = [("door", DOOR_BOX), ("valve", GHOST_BOX)]  # a one-frame false positive
    pipe = Pipeline(cfg, [FakeDetector(script)])
    alive = []
    for i in range(6):
        pipe.process(make_frame(i))
        alive.append(sorted(s.type for s in pipe.tracks()))
    # the valve is in view (box centre 120 px, 2 m, nothing in front) and not detected:
    # support 1 -> 0.5 -> 0.0 -> -0.5 < drop_support 0 at frame 3
    assert alive[:3] == [["door", "valve"]] * 3
    assert alive[3:] == [["door"]] * 3
    assert [s.type for s in pipe.confirmed()] == ["door"]


def test_qr_reader_fallback_when_module_missing(monkeypatch):
    monkeypatch.setattr(pipeline_mod, "QR_MODULE", "poi.detectors.no_such_module")
    pipe = Pipeline(synthetic_config(), [FakeDetector({0: [("qr", DOOR_BOX, 0.9, "")]})])
    assert any("QR text reading unavailable" in n for n in pipe.notes)
    res = pipe.process(make_frame(0))
    assert res.detections[0].text == ""


def test_qr_reader_only_sees_qr_detections_without_text(monkeypatch):
    seen = []

    def fake_reader(rgb, dets, motion=None):
        seen.append([(d.type, d.text) for d in dets])
        return [Detection(**{**d.__dict__, "text": "Chart X"}) for d in dets]

    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (fake_reader, None))
    script = {0: [("qr", DOOR_BOX, 0.9, ""), ("qr", GHOST_BOX, 0.9, "Chart Y"), ("door", (0, 0, 9, 9))]}
    pipe = Pipeline(synthetic_config(), [FakeDetector(script)])
    res = pipe.process(make_frame(0))
    assert seen == [[("qr", "")]]
    assert [d.text for d in res.detections] == ["Chart X", "Chart Y", ""]


def _counting_reader(calls: list[int], text: str = "Chart X"):
    def reader(rgb, dets, motion=None):
        calls.append(len(dets))
        return [Detection(**{**d.__dict__, "text": text}) for d in dets]

    return reader


@pytest.mark.parametrize(("settled_votes", "expected_reads"), [(3, 3), (0, 6), (1, 1)])
def test_a_settled_qr_code_is_not_decoded_again_but_still_tracked(monkeypatch, settled_votes, expected_reads):
    calls: list[int] = []
    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (_counting_reader(calls), None))
    cfg = synthetic_config(f"qr.settled_votes={settled_votes}")
    pipe = Pipeline(cfg, [FakeDetector({i: [("qr", DOOR_BOX, 0.9, "")] for i in range(6)})])
    for i in range(6):
        res = pipe.process(make_frame(i))
        assert len(res.observations) == 1 and res.detections[0].track_id is not None
    (snap,) = pipe.tracks()
    assert sum(calls) == expected_reads
    assert snap.text == "Chart X" and snap.n_detections == 6  # unread detections still update it
    assert snap.extra["text_votes"] == {"Chart X": expected_reads}


def test_a_qr_code_elsewhere_is_decoded_even_when_another_is_settled(monkeypatch):
    calls: list[int] = []
    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (_counting_reader(calls), None))
    script = {i: [("qr", DOOR_BOX, 0.9, "")] for i in range(3)}
    script[3] = [("qr", DOOR_BOX, 0.9, ""), ("qr", GHOST_BOX, 0.9, "")]  # a second code, 0.9 m aside
    pipe = Pipeline(synthetic_config(), [FakeDetector(script)])
    for i in range(4):
        pipe.process(make_frame(i))
    assert calls == [1, 1, 1, 1]  # frame 3: only the new code is read


def test_a_code_beside_a_settled_one_inside_its_gate_is_read_and_tracked_apart(monkeypatch):
    # a chart's codes of different sizes sit side by side, closer than the tracker's gate: the
    # settled code's centre projects into its own box only, so the box beside it is read
    texts = iter(["Chart X"] * 3 + ["Chart Y"] * 3)
    calls: list[int] = []

    def reader(rgb, dets, motion=None):
        calls.append(len(dets))
        return [Detection(**{**d.__dict__, "text": next(texts)}) for d in dets]

    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (reader, None))
    beside = (332.0, 232.0, 348.0, 248.0)  # a smaller code 20 px right of DOOR_BOX's centre: 8 cm at 2 m
    script = {i: [("qr", DOOR_BOX, 0.9, "")] for i in range(3)}
    for i in range(3, 6):
        script[i] = [("qr", DOOR_BOX, 0.9, ""), ("qr", beside, 0.9, "")]
    pipe = Pipeline(synthetic_config(), [FakeDetector(script)])
    for i in range(3):
        pipe.process(make_frame(i))
    (settled,) = pipe.tracker.tracks.values()
    res = pipe.process(make_frame(3))
    # the premise: the code beside, its text unread, lies inside the settled track's gate
    unread = dataclasses.replace(res.observations[1], detection=make_det("qr", beside, 0.9, ""))
    assert np.isfinite(pipe.tracker.distances([unread], [settled])).all()
    for i in range(4, 6):
        pipe.process(make_frame(i))
    assert calls == [1, 1, 1, 1, 1, 1]  # frames 3-5: the settled code is not read again, the other is
    by_text = {t.text: t for t in pipe.tracks()}
    assert set(by_text) == {"Chart X", "Chart Y"}
    assert by_text["Chart X"].n_detections == 6 and by_text["Chart Y"].n_detections == 3


def test_qr_detections_without_depth_are_not_decoded_on_tracked_frames(monkeypatch):
    calls: list[int] = []
    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (_counting_reader(calls), None))
    pipe = Pipeline(
        synthetic_config(), [FakeDetector({0: [("qr", DOOR_BOX, 0.9, "")], 1: [("qr", DOOR_BOX, 0.9, "")]})]
    )
    frame = make_frame(0)
    frame.depth_m[:] = 0.0  # no valid depth anywhere: no observation
    res = pipe.process(frame)
    assert res.observations == [] and calls == [] and res.detections[0].text == ""
    res = pipe.process(make_frame(1, pose=False))  # skipped frame: read for display
    assert calls == [1] and res.detections[0].text == "Chart X"


def test_annotate_draws_and_leaves_the_input_alone():
    img = np.full((120, 160, 3), 40, np.uint8)
    before = img.copy()
    d = make_det("oxidizer", (40.0, 50.0, 100.0, 100.0), 0.87)
    d.track_id = 3
    out = annotate(img, [d], [], 12.5)
    assert np.array_equal(img, before)
    assert out.shape == img.shape and out.dtype == np.uint8
    # the box edges are drawn in the hazmat colour, the interior is untouched
    assert out[75, 40].tolist() == [255, 100, 30]
    assert out[75, 99].tolist() == [255, 100, 30]
    assert out[75, 70].tolist() == [40, 40, 40]
    # a label above the box and a HUD at the bottom
    assert np.any(out[30:50, 40:100] != 40)
    assert np.any(out[100:, :80] != 40)
    with pytest.raises(ValueError, match="RGB uint8"):
        annotate(np.zeros((10, 10), np.uint8), [])


def test_no_box_edge_is_drawn_through_a_label():
    """A label wider than its box reaches over a neighbour's box: the neighbour's edge stays under it."""
    img = np.full((120, 200, 3), 40, np.uint8)
    narrow = make_det("oxidizer", (20.0, 50.0, 30.0, 90.0), 0.87)  # its label runs ~100 px right
    door = make_det("door", (60.0, 10.0, 120.0, 110.0), 0.9)  # left edge x = 60 crosses that label
    out = annotate(img, [narrow, door], [], None)
    label_rows = out[36:48, 58:63]  # the label's band where the door's edge would cross it
    assert not np.all(label_rows == [150, 90, 40], axis=-1).any()  # no door-brown pixel in it
    assert out[70, 60].tolist() == [150, 90, 40]  # the door's edge below the label is drawn


def test_slam_mode_holds_the_pose_against_odometry_drift():
    """A static robot whose odometry creeps forward 3 mm a frame, watching an exit sign 2 m
    ahead: in t265 mode the map pose follows the odometry; in slam mode the mapped sign pins
    the pose ([Bouda2025]_ 2.2): its error stays bounded and shrinks (the filter learns the creep
    as the odometry's scale and drift), and the sign is reported once near where it is,
    where t265 mode splits it into several reports as the drift outgrows the gate."""
    SIGN_BOX = (310.0, 230.0, 330.0, 250.0)
    script = {i: [("exit-sign", SIGN_BOX)] for i in range(300)}
    results = {}
    for mode in ("t265", "slam"):
        cfg = synthetic_config("qr.enabled=false", f"localize.mode={mode}")
        pipe = Pipeline(cfg, [FakeDetector(script)])
        x = []
        for i in range(300):
            frame = make_frame(i)
            frame.pose = np.eye(4)
            frame.pose[0, 3] = 0.003 * i
            res = pipe.process(frame)
            x.append(res.pose_map[0, 3])
        results[mode] = (x[149], x[299], [snap.position_map[0] for snap in pipe.confirmed()])
        assert ("slam" in res.timing_ms) == (mode == "slam")
    assert results["t265"][:2] == pytest.approx((0.447, 0.897))  # the raw odometry
    assert len(results["t265"][2]) > 1
    x150, x300, (sign_x,) = results["slam"]
    # the robot stands at x = 0: the error stays bounded and shrinks as the filter learns that
    # the odometry's distances are spurious (its scale and drift are in the state)
    assert abs(x150) < 0.05 and abs(x300) < 0.03 and abs(x300) < abs(x150)
    assert sign_x == pytest.approx(2.0, abs=0.2)
    assert pipe.slam.n_landmarks == 1


def test_the_qr_reader_gets_the_camera_s_turn_from_the_frame_s_gyro(monkeypatch):
    # the frame's gyro rate (tracker axes) reaches the reader in the colour camera's axes, with the
    # frame's exposure where it gives one and the ladder below qr.max_exposure_ms where it does not
    seen = []

    def reader(rgb, dets, motion=None):
        seen.append(motion)
        return list(dets)

    monkeypatch.setattr(pipeline_mod, "_find_qr_reader", lambda: (reader, None))
    cfg = synthetic_config("qr.max_exposure_ms=8")
    pipe = Pipeline(cfg, [FakeDetector({i: [("qr", DOOR_BOX, 0.9, "")] for i in range(3)})])
    w = np.array([0.0, 0.0, 2.0])
    frames = [make_frame(0), make_frame(1), make_frame(2)]
    frames[1].angular_velocity = w
    frames[2].angular_velocity, frames[2].exposure_s = w, 0.004
    for f in frames:
        pipe.process(f)
    R = pipe.T_tracker_camera[:3, :3]
    assert seen[0] is None  # no gyro
    assert seen[1].omega_optical == pytest.approx(R.T @ w)
    assert seen[1].exposures_s[0] == pytest.approx(0.008) and len(seen[1].exposures_s) > 1
    assert seen[2].exposures_s == (0.004,)
