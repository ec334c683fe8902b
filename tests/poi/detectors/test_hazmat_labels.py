"""The hazmat label stage: crops, the classifier contract, and placards renamed in the detector.

The classifier here is softmax(mean_rgb @ W) of the crop (tests/poi/onnx_models.py) with
W zero but for 8 on (red, explosive), (green, oxidizer) and (blue, background): a pure red
crop gets q_explosive = e^8 / (e^8 + 16) and 1 / (e^8 + 16) for each other class.
The detector model is the constant 320x320 one of test_onnx_yolo.py on a 640x480 frame
(input pixel x_in -> x = x_in / 0.5, y = (y_in - 40) / 0.5).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from onnx_models import make_colour_label_model, make_constant_model, yolov8_output  # noqa: E402

from poi.core.names import CLASS_INDEX, CLASSES, RESCUE_CLASSES  # noqa: E402
from poi.core.types import Frame, Intrinsics  # noqa: E402
from poi.detectors import DetectorConfigError, OnnxYoloDetector  # noqa: E402
from poi.detectors.hazmat_labels import (  # noqa: E402
    LABEL_CLASSES,
    HazmatLabelClassifier,
    LabelModelError,
    crop_box,
)

META = {"names": "{0: 'oxidizer', 1: 'oxygen', 2: 'door'}", "task": "detect", "imgsz": "[320, 320]"}
Q_TOP = np.exp(8.0) / (np.exp(8.0) + 16.0)
Q_REST = 1.0 / (np.exp(8.0) + 16.0)


def _weights() -> np.ndarray:
    W = np.zeros((3, len(LABEL_CLASSES)))
    W[0, LABEL_CLASSES.index("explosive")] = 8.0
    W[1, LABEL_CLASSES.index("oxidizer")] = 8.0
    W[2, LABEL_CLASSES.index("background")] = 8.0
    return W


def _frame(rgb: np.ndarray) -> Frame:
    K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    return Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=K)


def _detector(tmp_path: Path, label_model: Path | None) -> OnnxYoloDetector:
    # oxidizer 0.8 at input (100, 140, 40, 60) -> frame (160, 140, 240, 260); oxygen 0.6 two
    # pixels right (IoU 0.9); a door 0.9 at input (250, 200, 40, 40) -> (460, 280, 540, 360).
    boxes = [[100, 140, 40, 60], [102, 140, 40, 60], [250, 200, 40, 40]]
    scores = [[0.8, 0, 0], [0, 0.6, 0], [0, 0, 0.9]]
    model = make_constant_model(tmp_path / "det.onnx", yolov8_output(boxes, scores, 50), metadata=META)
    return OnnxYoloDetector(model=model, label_model=label_model, read_qr=False)


def _painted(colour: tuple[int, int, int]) -> np.ndarray:
    rgb = np.zeros((480, 640, 3), np.uint8)
    rgb[100:300, 120:280] = colour  # the placard box and its 10% margin, and more
    return rgb


def test_crop_box_takes_the_box_and_its_margin():
    rgb = np.zeros((100, 200, 3), np.uint8)
    rgb[20:60, 40:80] = (255, 0, 0)  # a 40 x 40 red square
    inner = crop_box(rgb, (40, 20, 80, 60), 20, margin=0.0)
    assert inner.shape == (20, 20, 3) and np.all(inner == (255, 0, 0))
    # margin 0.5: the crop spans 20..100 x 0..80, the red square is its middle half
    outer = crop_box(rgb, (40, 20, 80, 60), 40, margin=0.5)
    assert np.all(outer[12:28, 12:28] == (255, 0, 0)) and np.all(outer[:8] == 0) and np.all(outer[:, -8:] == 0)
    # a box across the image edge: the outside is the letterbox grey
    edge = crop_box(rgb, (-40, 0, 40, 40), 8, margin=0.0)
    assert np.all(edge[:, :4] == 114) and np.all(edge[:, 4:] == 0)


def test_classifier_gives_hand_computed_probabilities(tmp_path):
    clf = HazmatLabelClassifier(model=make_colour_label_model(tmp_path / "l.onnx", _weights()))
    assert clf.imgsz == 64 and clf.crop_margin == pytest.approx(0.1)
    q = clf.classify(_painted((255, 0, 0)), np.array([[160, 140, 240, 260], [400, 400, 440, 440]]))
    assert q.shape == (2, 17)
    assert q[0, LABEL_CLASSES.index("explosive")] == pytest.approx(Q_TOP, rel=1e-5)
    assert q[0, LABEL_CLASSES.index("poison")] == pytest.approx(Q_REST, rel=1e-4)
    assert np.allclose(q[1], 1.0 / 17.0, atol=1e-6)  # a black crop: all logits 0
    assert clf.classify(_painted((255, 0, 0)), np.zeros((0, 4))).shape == (0, 17)


def test_classifier_contract_is_checked(tmp_path):
    with pytest.raises(LabelModelError, match="not found"):
        HazmatLabelClassifier(model=tmp_path / "missing.onnx")
    wrong_order = list(LABEL_CLASSES[::-1])
    with pytest.raises(LabelModelError, match="16 hazmat labels and 'background'"):
        HazmatLabelClassifier(model=make_colour_label_model(tmp_path / "a.onnx", _weights(), names=wrong_order))
    with pytest.raises(LabelModelError, match=r"output has shape \['n', 16\]; expected \(N, 17\)"):
        make = make_colour_label_model(tmp_path / "b.onnx", np.zeros((3, 16)), names=LABEL_CLASSES)
        HazmatLabelClassifier(model=make)
    bad_margin = make_colour_label_model(tmp_path / "c.onnx", _weights(), metadata={"crop_margin": "wide"})
    with pytest.raises(LabelModelError, match="crop_margin is not a number"):
        HazmatLabelClassifier(model=bad_margin)


def test_without_a_label_model_both_hazmat_guesses_stay(tmp_path):
    out = _detector(tmp_path, None).detect(_frame(_painted((255, 0, 0))))
    assert [d.class_name for d in out] == ["door", "oxidizer", "oxygen"]


def test_placards_are_merged_then_named_by_the_classifier(tmp_path):
    det = _detector(tmp_path, make_colour_label_model(tmp_path / "l.onnx", _weights()))
    out = det.detect(_frame(_painted((255, 0, 0))))
    # NMS treats oxidizer and oxygen as one class (IoU 0.9): the 0.8 box stays, named explosive
    assert [d.class_name for d in out] == ["door", "explosive"]
    placard = out[1]
    assert (placard.type, placard.text) == ("hazmat", "explosive")
    assert np.allclose(placard.box_xyxy, (160, 140, 240, 260), atol=1e-4)
    assert placard.confidence == pytest.approx(0.8 * Q_TOP, rel=1e-5)
    p = placard.class_probs
    assert p.sum() == pytest.approx(1.0, abs=1e-9)
    assert p[CLASS_INDEX["explosive"]] == pytest.approx(0.8 * Q_TOP, rel=1e-5)
    assert p[CLASS_INDEX["oxygen"]] == pytest.approx(0.8 * Q_REST, rel=1e-4)
    # the model gave no other score: 1 - s (1 - q_background) spread evenly over the 8 other
    # rescue classes, nothing on the arena's
    rest = (1.0 - 0.8 * (1.0 - Q_REST)) / 8.0
    assert p[CLASS_INDEX["door"]] == pytest.approx(rest, rel=1e-4)
    assert all(p[CLASS_INDEX[c]] == 0.0 for c in CLASSES if c not in RESCUE_CLASSES)
    assert out[0].confidence == pytest.approx(0.9, abs=1e-6)  # the door is not touched
    assert det.last_timing_ms["labels"] > 0.0


def test_a_box_the_classifier_calls_background_is_dropped(tmp_path):
    det = _detector(tmp_path, make_colour_label_model(tmp_path / "l.onnx", _weights()))
    out = det.detect(_frame(_painted((0, 0, 255))))  # confidence 0.8 / (e^8 + 16) < 0.25
    assert [d.class_name for d in out] == ["door"]


def test_label_model_needs_a_detector_of_placards(tmp_path):
    meta = {"names": "{0: 'door', 1: 'valve'}", "task": "detect", "imgsz": "[320, 320]"}
    model = make_constant_model(
        tmp_path / "d.onnx", yolov8_output([[50, 50, 10, 10]], [[0.9, 0]], 50), metadata=meta
    )
    label = make_colour_label_model(tmp_path / "l.onnx", _weights())
    with pytest.raises(DetectorConfigError, match="reports none"):
        OnnxYoloDetector(model=model, label_model=label)


def test_a_qr_box_the_classifier_reads_as_a_placard_becomes_one(tmp_path):
    # qr 0.7 and oxidizer 0.5 on one box: one survives NMS (qr and placards compete as one)
    meta = {"names": "{0: 'oxidizer', 1: 'qr', 2: 'door'}", "task": "detect", "imgsz": "[320, 320]"}
    out = yolov8_output([[100, 140, 40, 60], [101, 140, 40, 60]], [[0, 0.7, 0], [0.5, 0, 0]], 50)
    model = make_constant_model(tmp_path / "det.onnx", out, metadata=meta)
    label = make_colour_label_model(tmp_path / "l.onnx", _weights())
    det = OnnxYoloDetector(model=model, label_model=label, read_qr=False)
    (red,) = det.detect(_frame(_painted((255, 0, 0))))
    assert red.class_name == "explosive" and red.confidence == pytest.approx(0.7 * Q_TOP, rel=1e-5)
    assert red.class_probs.sum() == pytest.approx(1.0, abs=1e-9)
    # background (which includes QR codes) beats every label: the box stays the model's qr
    (blue,) = det.detect(_frame(_painted((0, 0, 255))))
    assert blue.class_name == "qr" and blue.confidence == pytest.approx(0.7, abs=1e-6)


def test_a_model_that_finds_placards_without_naming_them_needs_and_uses_the_classifier(tmp_path):
    # one 'hazmat' class: the classifier names the green box oxidizer; s q_top as for a named one
    meta = {"names": "{0: 'hazmat', 1: 'door'}", "task": "detect", "imgsz": "[320, 320]"}
    out = yolov8_output([[100, 140, 40, 60], [250, 200, 40, 40]], [[0.8, 0], [0, 0.9]], 50)
    model = make_constant_model(tmp_path / "det.onnx", out, metadata=meta)
    with pytest.raises(DetectorConfigError, match="model class 'hazmat' finds placards without naming"):
        OnnxYoloDetector(model=model, read_qr=False)
    label = make_colour_label_model(tmp_path / "l.onnx", _weights())
    det = OnnxYoloDetector(model=model, label_model=label, read_qr=False)
    door, green = det.detect(_frame(_painted((0, 255, 0))))
    assert (green.type, green.text) == ("hazmat", "oxidizer") and door.class_name == "door"
    assert green.confidence == pytest.approx(0.8 * Q_TOP, rel=1e-5)
    assert green.class_probs[CLASS_INDEX["explosive"]] == pytest.approx(0.8 * Q_REST, rel=1e-4)
    assert green.class_probs.sum() == pytest.approx(1.0, abs=1e-9)
