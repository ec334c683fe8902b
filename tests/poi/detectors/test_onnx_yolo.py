"""The ONNX YOLO detector on small constant-output models with hand-computed answers.

Every model here is 320x320 and its output ignores the image; the frame is
640x480, so the letterbox is r = min(320/480, 320/640) = 0.5, a 320x240 image
with left = 0 and top = (320 - 240) / 2 = 40 px of padding, and an input pixel
maps back as x = (x_in - 0) / 0.5, y = (y_in - 40) / 0.5.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from onnx_models import make_constant_model, yolov5_output, yolov8_output  # noqa: E402

from poi.core.names import CLASS_INDEX, CLASSES, RESCUE_CLASSES  # noqa: E402
from poi.core.types import Frame, Intrinsics  # noqa: E402
from poi.detectors import (  # noqa: E402
    DetectorConfigError,
    OnnxModelError,
    OnnxYoloDetector,
    build_detector,
    spread_class_probs,
)
from poi.detectors.model_names import parse_names_metadata  # noqa: E402
from poi.detectors.onnx_yolo import letterbox  # noqa: E402

NAMES3 = "{0: 'oxidizer', 1: 'qr', 2: 'door'}"
V8_META = {"names": NAMES3, "task": "detect", "imgsz": "[320, 320]", "stride": "32"}
V5_META = {"names": NAMES3, "stride": "32"}
N_ANCHORS = 50
EXACT = 1e-4  # float32 box arithmetic on numbers < 1000: errors below 1e-4 px


def _frame(rgb: np.ndarray | None = None) -> Frame:
    rng = np.random.default_rng(0)
    if rgb is None:
        rgb = rng.integers(0, 256, size=(480, 640, 3), dtype=np.uint8)
    K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    return Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=K)


def _v8(tmp_path: Path, boxes, scores, meta=V8_META, name="m.onnx", **kw) -> Path:
    return make_constant_model(tmp_path / name, yolov8_output(boxes, scores, N_ANCHORS), metadata=meta, **kw)


def test_letterbox_640x480_into_320():
    rgb = np.zeros((480, 640, 3), np.uint8)
    rgb[:, :, 0] = 200
    img, r, (left, top) = letterbox(rgb, (320, 320))
    assert (r, left, top) == (0.5, 0, 40)
    assert np.all(img[:40] == 114) and np.all(img[280:] == 114)  # grey pad top and bottom
    assert np.all(img[40:280, :, 0] == 200) and np.all(img[40:280, :, 1] == 0)
    assert rgb[0, 0, 0] == 200  # input untouched


def test_letterbox_odd_padding_goes_bottom_right():
    # 100x61 into 64x64: r = 64/100 = 0.64, 64 x round(39.04) = 39 rows, pad 25 -> top 12.
    img, r, (left, top) = letterbox(np.zeros((61, 100, 3), np.uint8), (64, 64))
    assert (r, left, top) == (0.64, 0, 12)
    assert np.all(img[:12] == 114) and np.all(img[12 + 39 :] == 114)
    assert np.all(img[12 : 12 + 39] == 0)


def test_yolov8_boxes_mapped_back_exactly(tmp_path):
    # door at input (cx, cy, w, h) = (100, 140, 40, 60): xyxy_in (80, 110, 120, 170)
    # -> original ((80-0)/0.5, (110-40)/0.5, (120-0)/0.5, (170-40)/0.5) = (160, 140, 240, 260).
    # oxidizer at (310, 60, 40, 20): x2_in 330 -> 660 clipped to 640; y (50, 70) -> (20, 60).
    path = _v8(tmp_path, [[100, 140, 40, 60], [310, 60, 40, 20]], [[0, 0, 0.9], [0.8, 0, 0]])
    det = OnnxYoloDetector(model=path, read_qr=False)
    assert det.output_layout == "yolov8" and det.input_hw == (320, 320)
    assert det.model_names == ["oxidizer", "qr", "door"]
    out = det.detect(_frame())
    assert [d.class_name for d in out] == ["door", "oxidizer"]
    assert np.allclose(out[0].box_xyxy, (160, 140, 240, 260), atol=EXACT)
    assert np.allclose(out[1].box_xyxy, (580, 20, 640, 60), atol=EXACT)
    assert (out[0].type, out[0].text) == ("door", "")
    assert (out[1].type, out[1].text) == ("hazmat", "oxidizer")
    assert out[0].confidence == pytest.approx(0.9, abs=1e-6)
    assert set(det.last_timing_ms) >= {"preprocess", "inference", "postprocess"}
    assert all(v >= 0 for v in det.last_timing_ms.values())


def test_box_wholly_in_padding_is_dropped(tmp_path):
    # y_in in (10, 30) lies in the top pad (< 40): after clipping the box has no height.
    path = _v8(tmp_path, [[100, 20, 40, 20]], [[0, 0, 0.9]])
    assert OnnxYoloDetector(model=path, read_qr=False).detect(_frame()) == []


def test_conf_threshold(tmp_path):
    boxes = [[50, 100, 20, 20], [150, 100, 20, 20], [250, 100, 20, 20]]
    path = _v8(tmp_path, boxes, [[0, 0, 0.2], [0, 0, 0.25], [0, 0, 0.3]])
    kept = OnnxYoloDetector(model=path, conf=0.25, read_qr=False).detect(_frame())
    # 0.2 < 0.25 dropped; 0.25 >= 0.25 kept (float32 0.25 is exact).
    assert [round(d.confidence, 6) for d in kept] == [0.3, 0.25]
    kept = OnnxYoloDetector(model=path, conf=0.26, read_qr=False).detect(_frame())
    assert len(kept) == 1


def test_type_conf_sets_one_types_threshold(tmp_path):
    # doors at 0.3, 0.5 and 0.7, an oxidizer placard at 0.3 and a qr at 0.2; conf 0.25 with
    # doors at 0.5: the 0.3 door goes, the 0.5 one stays (float32 0.5 is exact), the placard
    # keeps conf's 0.25; qr at 0.15, under conf, keeps its 0.2 box.
    boxes = [[40, 100, 20, 20], [100, 100, 20, 20], [160, 100, 20, 20], [220, 100, 20, 20], [280, 100, 20, 20]]
    scores = [[0, 0, 0.3], [0, 0, 0.5], [0, 0, 0.7], [0.3, 0, 0], [0, 0.2, 0]]
    path = _v8(tmp_path, boxes, scores)
    det = OnnxYoloDetector(model=path, conf=0.25, type_conf={"door": 0.5, "qr": 0.15}, read_qr=False)
    kept = [(d.class_name, round(d.confidence, 6)) for d in det.detect(_frame())]
    assert kept == [("door", 0.7), ("door", 0.5), ("oxidizer", 0.3), ("qr", 0.2)]
    plain = OnnxYoloDetector(model=path, conf=0.25, read_qr=False).detect(_frame())
    assert [d.class_name for d in plain] == ["door", "door", "door", "oxidizer"]


def test_type_conf_of_a_type_the_model_lacks_is_refused(tmp_path):
    path = _v8(tmp_path, [[50, 100, 20, 20]], [[0, 0, 0.9]])
    with pytest.raises(DetectorConfigError, match=r"type_conf names 'valve', which m.onnx cannot report"):
        OnnxYoloDetector(model=path, type_conf={"valve": 0.6})
    with pytest.raises(DetectorConfigError, match=r"type_conf.door must be in \[0, 1\]"):
        OnnxYoloDetector(model=path, type_conf={"door": 1.5})


def test_nms_same_class_vs_different_class(tmp_path):
    # A door (100..200)^2 0.9 and a door shifted 10 px 0.8: IoU = 9000 / 11000 = 0.818 > 0.45,
    # the 0.8 one goes. A valve... here 'oxidizer' on the same shifted box at 0.7 stays.
    # A door far away (0.6) overlaps nothing and stays.
    boxes = [[150, 150, 100, 100], [160, 150, 100, 100], [160, 150, 100, 100], [300, 250, 20, 20]]
    scores = [[0, 0, 0.9], [0, 0, 0.8], [0.7, 0, 0], [0, 0, 0.6]]
    out = OnnxYoloDetector(model=_v8(tmp_path, boxes, scores), read_qr=False).detect(_frame())
    got = [(d.class_name, round(d.confidence, 6)) for d in out]
    assert got == [("door", 0.9), ("oxidizer", 0.7), ("door", 0.6)]
    # With nms_iou above the overlap, both doors stay.
    out = OnnxYoloDetector(model=_v8(tmp_path, boxes, scores), nms_iou=0.85, read_qr=False).detect(_frame())
    assert len(out) == 4


def test_max_det_keeps_the_best(tmp_path):
    boxes = [[20 + 40 * i, 100, 20, 20] for i in range(5)]
    scores = [[0, 0, s] for s in (0.3, 0.9, 0.5, 0.7, 0.4)]
    out = OnnxYoloDetector(model=_v8(tmp_path, boxes, scores), max_det=2, read_qr=False).detect(_frame())
    assert [round(d.confidence, 6) for d in out] == [0.9, 0.7]


def test_class_probs_follow_seed_2_1_5(tmp_path):
    # Scores (oxidizer, qr, door) = (0.5, 0.3, 0.8): door keeps p = 0.8, the other 0.2 is split
    # 0.5 : 0.3 -> oxidizer 0.125, qr 0.075; every other class of CLASSES 0.
    # A second anchor with only door 0.7: the other 0.3 is spread uniformly over the other 23
    # classes of the model's domain (a rescue model: the rescue classes, none of the arena's).
    boxes = [[100, 100, 20, 20], [250, 200, 20, 20]]
    out = OnnxYoloDetector(model=_v8(tmp_path, boxes, [[0.5, 0.3, 0.8], [0, 0, 0.7]]), read_qr=False).detect(
        _frame()
    )
    p = out[0].class_probs
    assert p.shape == (len(CLASSES),) and p.sum() == pytest.approx(1.0, abs=1e-9)
    assert p[CLASS_INDEX["door"]] == pytest.approx(0.8, abs=1e-6)
    assert p[CLASS_INDEX["oxidizer"]] == pytest.approx(0.125, abs=1e-6)
    assert p[CLASS_INDEX["qr"]] == pytest.approx(0.075, abs=1e-6)
    assert np.count_nonzero(p) == 3
    mapped = np.zeros(len(CLASSES))
    mapped[[CLASS_INDEX["oxidizer"], CLASS_INDEX["qr"], CLASS_INDEX["door"]]] = (0.5, 0.3, 0.8)
    assert np.allclose(p, spread_class_probs(mapped, CLASS_INDEX["door"]), atol=1e-7)
    q = out[1].class_probs
    assert q[CLASS_INDEX["door"]] == pytest.approx(0.7, abs=1e-6)
    others = np.delete(q[: len(RESCUE_CLASSES)], CLASS_INDEX["door"])
    assert np.allclose(others, 0.3 / 23, atol=1e-7)
    assert np.all(q[len(RESCUE_CLASSES) :] == 0.0) and q.sum() == pytest.approx(1.0)


def test_an_arena_model_maps_by_name_and_spreads_over_the_arena_classes(tmp_path):
    # a model trained on the arena of [Bouda2025], its classes named as its team named them
    meta = dict(V8_META, names="{0: 'blue_pillar', 1: 'red pillar', 2: 'Ball'}")
    boxes = [[100, 100, 10, 60], [250, 200, 30, 30]]
    det = OnnxYoloDetector(model=_v8(tmp_path, boxes, [[0.9, 0, 0], [0, 0, 0.8]], meta=meta), read_qr=False)
    out = det.detect(_frame())
    assert [(d.class_name, d.type, d.text) for d in out] == [
        ("pillar-blue", "pillar-blue", ""),
        ("ball", "ball", ""),
    ]
    q = out[1].class_probs
    assert q[CLASS_INDEX["ball"]] == pytest.approx(0.8, abs=1e-6)
    # no scores on the others: 0.2 spread over the arena's other three classes, none on the rescue ones
    for c in ("pillar-blue", "pillar-red", "pillar-green"):
        assert q[CLASS_INDEX[c]] == pytest.approx(0.2 / 3, abs=1e-6)
    assert np.all(q[: len(RESCUE_CLASSES)] == 0.0)


def test_yolov5_objectness_multiplies(tmp_path):
    # score = obj * cls: 0.5 * 0.9 = 0.45 (kept, oxidizer), 0.3 * 0.8 = 0.24 < 0.25 (dropped
    # although cls 0.8 alone would pass), 0.9 * 0.5 = 0.45 for door vs 0.9 * 0.1 = 0.09 qr.
    boxes = [[100, 140, 40, 60], [200, 200, 20, 20], [250, 100, 20, 20]]
    obj = [0.5, 0.3, 0.9]
    cls = [[0.9, 0.1, 0.0], [0.0, 0.0, 0.8], [0.0, 0.1, 0.5]]
    path = make_constant_model(tmp_path / "v5.onnx", yolov5_output(boxes, obj, cls, N_ANCHORS), metadata=V5_META)
    det = OnnxYoloDetector(model=path, read_qr=False)
    assert det.output_layout == "yolov5"
    out = det.detect(_frame())
    assert [(d.class_name, round(d.confidence, 6)) for d in out] == [
        ("oxidizer", 0.45),
        ("door", 0.45),
    ]
    assert np.allclose(out[0].box_xyxy, (160, 140, 240, 260), atol=EXACT)
    # door's probs: p 0.45, rest 0.55 all on qr (its only other non-zero score 0.09).
    assert out[1].class_probs[CLASS_INDEX["qr"]] == pytest.approx(0.55, abs=1e-6)


def test_wrong_output_shape_refused(tmp_path):
    path = make_constant_model(tmp_path / "bad.onnx", np.zeros((1, 10, 100), np.float32), metadata=V5_META)
    with pytest.raises(OnnxModelError, match=r"\(1, 10, 100\).*4\+C=7.*5\+C=8"):
        OnnxYoloDetector(model=path)
    four_d = make_constant_model(tmp_path / "bad4.onnx", np.zeros((1, 7, 10, 10), np.float32), metadata=V8_META)
    with pytest.raises(
        OnnxModelError, match=rf"^{re.escape(str(four_d))}: model output has shape \(1, 7, 10, 10\)"
    ):
        OnnxYoloDetector(model=four_d)


def test_class_count_mismatch_refused(tmp_path):
    # Four names declared, output made for three classes (1, 7, N).
    meta = dict(V8_META, names="{0: 'oxidizer', 1: 'qr', 2: 'door', 3: 'valve'}")
    path = _v8(tmp_path, [[100, 100, 20, 20]], [[0, 0, 0.9]], meta=meta)
    with pytest.raises(OnnxModelError, match=r"C=4 class names must be \(1, 8, N\)"):
        OnnxYoloDetector(model=path)
    # An explicit layout that the shape does not fit is refused too.
    path = _v8(tmp_path, [[100, 100, 20, 20]], [[0, 0, 0.9]], name="ok.onnx")
    with pytest.raises(OnnxModelError, match=r"yolov5 output for C=3 .* \(1, N, 8\)"):
        OnnxYoloDetector(model=path, layout="yolov5")


def test_ambiguous_shape_needs_metadata_or_layout(tmp_path):
    # C = 3 and output (1, 7, 8): 7 = 4+C (yolov8 with N = 8) and 8 = 5+C (yolov5 with N = 7).
    # Without Ultralytics' 'task' key nothing says which: refused unless layout is given.
    out = np.zeros((1, 7, 8), np.float32)
    out[0, :, 0] = [100, 140, 40, 60, 0.0, 0.0, 0.9]  # as yolov8: anchor 0 is a door 0.9
    path = make_constant_model(tmp_path / "amb.onnx", out, metadata=V5_META)
    with pytest.raises(OnnxModelError, match="fits both yolov8 and yolov5 for C=3"):
        OnnxYoloDetector(model=path)
    det = OnnxYoloDetector(model=path, layout="yolov8", read_qr=False)
    (d,) = det.detect(_frame())
    assert d.class_name == "door"
    assert np.allclose(d.box_xyxy, (160, 140, 240, 260), atol=EXACT)
    v8 = make_constant_model(tmp_path / "amb8.onnx", out, metadata=V8_META)
    assert OnnxYoloDetector(model=v8).output_layout == "yolov8"


def test_names_from_metadata_and_files(tmp_path):
    assert parse_names_metadata("{0: 'person', 1: 'car'}") == ["person", "car"]
    assert parse_names_metadata("['a', 'b']") == ["a", "b"]
    with pytest.raises(OnnxModelError, match="not a dict or list literal"):
        parse_names_metadata("__import__('os').system('true')")
    with pytest.raises(OnnxModelError, match="0..1"):
        parse_names_metadata("{0: 'a', 2: 'b'}")

    bare = _v8(tmp_path, [[100, 140, 40, 60]], [[0, 0.9, 0]], meta={"task": "detect"})
    with pytest.raises(
        OnnxModelError, match=r"no 'names' in the model metadata.*--set detector\.options\.names=FILE"
    ):
        OnnxYoloDetector(model=bare)
    # the option the message names is the one the pipeline hands the detector
    from poi.config import apply_overrides, load_config

    spec = apply_overrides(load_config(), ["detector.options.names=names.txt"]).detector_spec()
    assert spec["names"] == "names.txt"
    files = {
        "names.yaml": "- Oxidizer\n- QR code\n- door\n",
        "dict.yaml": "0: oxidizer\n1: qr\n2: door\n",
        "data.yml": "path: x\nnames:\n  0: oxidizer\n  1: qr code\n  2: Door\n",
        "names.txt": "oxidizer\nqr\n\ndoor\n",
    }
    for fname, text in files.items():
        (tmp_path / fname).write_text(text)
        det = OnnxYoloDetector(model=bare, names=tmp_path / fname, read_qr=False)
        assert len(det.model_names) == 3, fname
        (d,) = det.detect(_frame())
        assert (d.class_name, d.type, d.text) == ("qr", "qr", ""), fname
    with pytest.raises(OnnxModelError, match="names file not found"):
        OnnxYoloDetector(model=bare, names=tmp_path / "missing.txt")


def test_unknown_class_names_and_class_map(tmp_path):
    meta = dict(V8_META, names="{0: 'person', 1: 'car', 2: 'door'}")
    path = _v8(tmp_path, [[100, 140, 40, 60], [250, 200, 20, 20]], [[0.9, 0, 0], [0, 0.8, 0]],
               meta=meta)  # fmt: skip
    with pytest.raises(OnnxModelError, match=rf"^{re.escape(str(path))}: .*\['person', 'car'\] are not known"):
        OnnxYoloDetector(model=path)
    det = OnnxYoloDetector(model=path, class_map={"person": "baby-doll", "car": None})
    out = det.detect(_frame())
    assert [(d.class_name, d.type) for d in out] == [("baby-doll", "baby-doll")]
    with pytest.raises(OnnxModelError, match=r"\['bus'\] are not model classes"):
        OnnxYoloDetector(model=path, class_map={"bus": "door", "person": "doll", "car": None})


def test_not_onnx_and_missing_file(tmp_path):
    junk = tmp_path / "junk.onnx"
    junk.write_bytes(b"this is not a protobuf\x00\xff" * 10)
    with pytest.raises(OnnxModelError, match="junk.onnx: not a loadable ONNX model"):
        OnnxYoloDetector(model=junk)
    with pytest.raises(OnnxModelError, match="model file not found"):
        OnnxYoloDetector(model=tmp_path / "nope.onnx")


def test_dynamic_input_uses_imgsz(tmp_path):
    path = _v8(tmp_path, [[100, 140, 40, 60]], [[0, 0, 0.9]], input_hw=None)
    assert OnnxYoloDetector(model=path).input_hw == (320, 320)  # metadata imgsz
    det = OnnxYoloDetector(model=path, imgsz=[320, 320])
    assert det.input_hw == (320, 320)
    (d,) = det.detect(_frame())
    assert np.allclose(d.box_xyxy, (160, 140, 240, 260), atol=EXACT)
    no_meta = _v8(tmp_path, [[1, 1, 1, 1]], [[0, 0, 0.9]], meta={"names": NAMES3, "task": "detect"},
                  name="d.onnx", input_hw=None)  # fmt: skip
    assert OnnxYoloDetector(model=no_meta).input_hw == (640, 640)
    static = _v8(tmp_path, [[1, 1, 1, 1]], [[0, 0, 0.9]], name="s.onnx")
    with pytest.raises(DetectorConfigError, match="differs from the model's fixed input 320x320"):
        OnnxYoloDetector(model=static, imgsz=640)


def test_non_finite_rows_are_dropped(tmp_path):
    out = yolov8_output([[100, 140, 40, 60], [250, 200, 20, 20]], [[0, 0, 0.9], [0, 0, 0.8]], 10)
    out[0, 0, 1] = np.nan  # second anchor's cx
    path = make_constant_model(tmp_path / "nan.onnx", out, metadata=V8_META)
    got = OnnxYoloDetector(model=path, read_qr=False).detect(_frame())
    assert len(got) == 1 and got[0].confidence == pytest.approx(0.9, abs=1e-6)


def test_build_detector_and_bad_settings(tmp_path):
    path = _v8(tmp_path, [[100, 140, 40, 60]], [[0, 0, 0.9]])
    det = build_detector({"name": "onnx", "model": str(path), "conf": 0.5, "nms_iou": 0.3})
    assert isinstance(det, OnnxYoloDetector) and det.conf == 0.5 and det.name == "onnx"
    with pytest.raises(DetectorConfigError, match="unknown key 'confidence'"):
        build_detector({"name": "onnx", "model": str(path), "confidence": 0.5})
    with pytest.raises(DetectorConfigError, match="unknown detector 'yolo9000'"):
        build_detector({"name": "yolo9000"})
    with pytest.raises(DetectorConfigError, match="conf must be in"):
        OnnxYoloDetector(model=path, conf=1.5)
    with pytest.raises(DetectorConfigError, match="layout must be one of"):
        OnnxYoloDetector(model=path, layout="yolov7")


def test_qr_box_gets_its_text(tmp_path):
    # A real QR pasted at original (200..300, 180..280) = input (100..150, 130..180);
    # the model's 'qr' box (125, 155, 50, 50) covers exactly that and read_qr decodes it.
    code = cv2.QRCodeEncoder.create().encode("Chart M")  # (25, 25) with its quiet zone
    rgb = np.full((480, 640, 3), 90, np.uint8)
    rgb[180:280, 200:300] = cv2.resize(code, (100, 100), interpolation=cv2.INTER_NEAREST)[..., None]
    path = _v8(tmp_path, [[125, 155, 50, 50]], [[0, 0.9, 0]])
    (d,) = OnnxYoloDetector(model=path, read_qr=True).detect(_frame(rgb))
    assert np.allclose(d.box_xyxy, (200, 180, 300, 280), atol=EXACT)
    assert (d.type, d.text) == ("qr", "Chart M")


def test_onnx_sessions_block_instead_of_spinning():
    """Every session the detectors open has its intra-op threads' spinning off (two spinning
    threads cost twice the CPU of one for the same boxes, issue 18) and the threads asked for."""
    from poi.detectors.base import open_onnx_session

    model = Path(__file__).parents[3] / "poi" / "models" / "default_labels.onnx"
    opts = open_onnx_session(model, 2, OnnxModelError).get_session_options()
    assert opts.get_session_config_entry("session.intra_op.allow_spinning") == "0"
    assert opts.intra_op_num_threads == 2
