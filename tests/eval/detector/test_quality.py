"""Detector evaluation and calibration: AP against hand-computed values, the fits, the commands."""

import importlib.util
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from eval.cli.main import main
from eval.detector.metrics import (
    ImageBoxes,
    average_precision,
    class_metrics,
    confusion_counts,
    mean_ap,
    recall_by_size,
)
from eval.detector.quality import (
    CenterSamples,
    calibration_doc,
    center_samples,
    detect_all,
    fit_variance,
    load_split,
)
from poi.core.names import RESCUE_CLASSES
from poi.estimation.covariance import load_calibration
from poi.models import model_file

_spec = importlib.util.spec_from_file_location(
    "onnx_models", Path(__file__).parents[2] / "poi" / "detectors" / "onnx_models.py"
)
onnx_models = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(onnx_models)


def _im(gt, gcls, det, dcls, scores):
    return ImageBoxes(
        gt_boxes=np.array(gt, float).reshape(-1, 4),
        gt_classes=np.array(gcls, int),
        det_boxes=np.array(det, float).reshape(-1, 4),
        det_classes=np.array(dcls, int),
        det_scores=np.array(scores, float),
    )


def test_ap_of_perfect_and_of_ranked_false_positive():
    assert average_precision(np.array([True, True]), 2) == 1.0
    # a false positive ranked first: P = 0, 1/2, 2/3 at R = 0, 1/2, 1; envelope 2/3 everywhere
    assert average_precision(np.array([False, True, True]), 2) == pytest.approx(2 / 3, abs=1e-6)
    # half the objects never found: precision 1 up to recall 0.5 (51 of 101 points)
    assert average_precision(np.array([True]), 2) == pytest.approx(51 / 101, abs=1e-6)
    assert average_precision(np.array([], bool), 3) == 0.0


def test_ap50_95_counts_the_thresholds_a_box_passes():
    # IoU of (0,0,100,100) with (0,0,100,62) is 0.62: a hit at 0.50, 0.55, 0.60 and a miss above
    im = _im([[0, 0, 100, 100]], [3], [[0, 0, 100, 62]], [3], [0.9])
    (m,) = [x for x in class_metrics([im], len(RESCUE_CLASSES), 0.5) if x.n_gt]
    assert m.ap50 == 1.0 and m.ap50_95 == pytest.approx(0.3)
    assert m.recall == 1.0 and m.precision == 1.0
    assert mean_ap(class_metrics([im], len(RESCUE_CLASSES), 0.5)) == pytest.approx((1.0, 0.3))


def test_recall_and_precision_at_the_operating_confidence():
    im = _im(
        [[0, 0, 10, 10], [20, 0, 30, 10]],
        [0, 0],
        [[0, 0, 10, 10], [20, 0, 30, 10], [50, 50, 60, 60]],
        [0, 0, 0],
        [0.9, 0.1, 0.8],
    )
    m = class_metrics([im], len(RESCUE_CLASSES), 0.5)[0]
    assert m.recall == 0.5 and m.precision == 0.5  # at conf 0.5: one hit, one false detection
    # ranking: TP 0.9, FP 0.8, TP 0.1 -> P 1, 1/2, 2/3 at R 1/2, 1/2, 1
    assert m.ap50 == pytest.approx((51 * 1.0 + 50 * 2 / 3) / 101, abs=1e-6)


def test_confusion_counts_misses_and_false_detections():
    C = len(RESCUE_CLASSES)
    im = _im(
        [[0, 0, 10, 10], [20, 0, 30, 10], [40, 0, 50, 10]],
        [0, 1, 2],
        [[0, 0, 10, 10], [20, 0, 30, 10], [70, 0, 80, 10], [40, 0, 50, 10]],
        [0, 5, 4, 2],
        [0.9, 0.9, 0.9, 0.1],
    )
    M = confusion_counts([im], C, conf=0.5)
    assert M[0, 0] == 1 and M[1, 5] == 1  # right, and class 1 detected as class 5
    assert M[2, C] == 1  # the class-2 object's only detection is below the threshold: missed
    assert M[C, 4] == 1  # a detection where nothing is
    assert M.sum() == 4


def test_recall_by_size_separates_seeing_from_naming():
    # three true boxes: 10 px (missed), 30 px (found, wrong class), 100 px (found, right);
    # a low-confidence detection of the 10 px one does not count
    im = _im(
        [[0, 0, 10, 10], [20, 0, 50, 30], [100, 0, 200, 100]],
        [0, 1, 20],
        [[0, 0, 10, 10], [20, 0, 50, 30], [100, 0, 200, 100]],
        [0, 3, 20],
        [0.1, 0.9, 0.9],
    )
    groups = ["hazmat label"] * 16 + ["other type"] * 8
    rows = {
        (r["group"], r["band_px"]): (r["n"], r["found"], r["right_class"])
        for r in recall_by_size([im], groups, 0.5)
    }
    assert rows == {
        ("hazmat label", "0-20"): (1, 0.0, 0.0),
        ("hazmat label", "20-40"): (1, 1.0, 0.0),
        ("other type", "80+"): (1, 1.0, 1.0),
    }


def test_variance_fit_recovers_a_known_model():
    rng = np.random.default_rng(0)
    w = rng.uniform(10, 200, 40000)
    var = 2.0 + 0.0004 * w**2
    du2 = (rng.standard_normal(w.size) * np.sqrt(var)) ** 2
    c = fit_variance(w, du2)
    assert c[0] == pytest.approx(2.0, rel=0.15) and c[2] == pytest.approx(0.0004, rel=0.1) and c[1] < 0.01


def test_center_samples_pair_by_iou_and_count_misclassifications():
    im = _im(
        [[0, 0, 40, 20], [100, 100, 140, 140]], [0, 7], [[2, 1, 42, 21], [100, 100, 140, 140]], [0, 9], [0.9, 0.8]
    )
    s, mis = center_samples([im])
    assert sorted(s.cls.tolist()) == [0, 7]
    i = s.cls.tolist().index(0)
    assert s.w[i] == 40 and s.du2[i] == pytest.approx(4.0) and s.dv2[i] == pytest.approx(1.0)
    assert mis[9, 7] == 1 and mis.sum() == 1  # detected class 9, actually class 7


def test_calibration_doc_loads_in_the_pipeline(tmp_path):
    rng = np.random.default_rng(1)
    n = 100
    s = CenterSamples(
        cls=np.r_[np.zeros(n, int), np.ones(5, int)],
        w=rng.uniform(10, 90, n + 5),
        h=rng.uniform(10, 90, n + 5),
        du2=rng.uniform(0, 4, n + 5),
        dv2=rng.uniform(0, 4, n + 5),
    )
    mis = np.zeros((len(RESCUE_CLASSES), len(RESCUE_CLASSES)), int)
    mis[3, 4] = 9
    doc, counts = calibration_doc(s, mis)
    assert set(doc["center_variance_px2"]) == {"default", RESCUE_CLASSES[0]}  # class 1 has 5 < 30 pairs
    assert counts[RESCUE_CLASSES[0]] == n and counts[RESCUE_CLASSES[1]] == 5
    import yaml

    p = tmp_path / "cal.yaml"
    p.write_text(yaml.safe_dump(doc))
    cal = load_calibration(p)
    assert cal.confusion[3, 4] == pytest.approx((9 + 0.5) / (9 + 0.5 * 23), abs=1e-5)  # 6 decimals in the file
    assert cal.center_model("door") is cal.center_variance["default"]


@pytest.fixture()
def hand_dataset(tmp_path):
    """Two grey 640x480 images; an oxidizer at (100, 80)-(180, 160) in both, a door in the second."""
    root = tmp_path / "ds"
    for d in ("images/val", "labels/val"):
        (root / d).mkdir(parents=True)
    ox = RESCUE_CLASSES.index("oxidizer")
    door = RESCUE_CLASSES.index("door")
    lab = f"{ox} {140 / 640:.6f} {120 / 480:.6f} {80 / 640:.6f} {80 / 480:.6f}\n"
    for name, extra in (("a", ""), ("b", f"{door} 0.5 0.5 0.25 0.5\n")):
        cv2.imwrite(str(root / "images/val" / f"{name}.jpg"), np.full((480, 640, 3), 90, np.uint8))
        (root / "labels/val" / f"{name}.txt").write_text(lab + extra)
    # a model that always finds the oxidizer, 2 px right of where it is: input 320x320, the
    # 640x480 image is scaled by 0.5 and padded 40 px at the top
    scores = np.zeros((1, len(RESCUE_CLASSES)), np.float32)
    scores[0, ox] = 0.9
    out = onnx_models.yolov8_output([[(142) * 0.5, 120 * 0.5 + 40, 40, 40]], scores, 8)
    model = onnx_models.make_constant_model(
        tmp_path / "m.onnx", out, metadata={"names": str(dict(enumerate(RESCUE_CLASSES)))}
    )
    return root, model


def test_evaluate_detector_command(hand_dataset, tmp_path, capsys):
    root, model = hand_dataset
    out = tmp_path / "ev"
    assert (
        main(["evaluate-detector", "--model", str(model), "--data", str(root), "--out", str(out), "--quiet"]) == 0
    )
    rep = json.loads((out / "evaluation.json").read_text())
    # oxidizer: found in both images (IoU 0.95) -> AP 1 at every threshold up to 0.95; the door never
    ox, door = rep["classes"]["oxidizer"], rep["classes"]["door"]
    assert ox["AP50"] == 1.0 and ox["recall"] == 1.0 and door["AP50"] == 0.0 and door["recall"] == 0.0
    assert rep["mAP50"] == pytest.approx(0.5)
    assert rep["mAP50_95"] == pytest.approx(0.5)
    assert (out / "confusion.png").stat().st_size > 5000
    assert {r["group"] for r in rep["by_size"]} <= {"hazmat label", "other type"}
    assert sum(r["n"] for r in rep["by_size"]) == sum(c["n"] for c in rep["classes"].values())
    printed = capsys.readouterr().out
    assert "oxidizer" in printed and "by box size" in printed


def test_calibrate_command(hand_dataset, tmp_path):
    root, model = hand_dataset
    out = tmp_path / "cal" / "calibration.yaml"
    assert main(["calibrate", "--model", str(model), "--data", str(root), "--out", str(out), "--quiet"]) == 0
    cal = load_calibration(out)
    u = cal.center_variance["default"]
    # two pairs, each 2 px off in u and 0 in v, both 80 px wide: the fit passes through 4 px^2 at
    # 80 px (give or take the 1/12 px^2 floor of its constant term); v sits at the floor
    assert u.variances(80.0, 80.0)[0] == pytest.approx(4.0, abs=1 / 12)
    assert u.variances(80.0, 80.0)[1] == pytest.approx(1 / 12, abs=1e-9)
    assert out.with_suffix(".png").exists()


@pytest.mark.slow
def test_calibrate_on_fresh_scenes_leaves_only_its_files(tmp_path):
    """The fresh scenes are rendered into a temporary folder, not beside the calibration file."""
    model, labels = model_file("default"), model_file("default").with_name("default_labels.onnx")
    out = tmp_path / "cal" / "calibration.yaml"
    args = ["calibrate", "--model", str(model), "--label-model", str(labels), "--images", "6", "--out", str(out)]
    assert main([*args, "--quiet"]) == 0
    assert sorted(p.name for p in out.parent.iterdir()) == ["calibration.png", "calibration.yaml"]


def test_evaluate_refuses_a_missing_dataset(tmp_path, capsys):
    model = onnx_models.make_constant_model(
        tmp_path / "m.onnx",
        onnx_models.yolov8_output([[1, 1, 1, 1]], [[0.5] * len(RESCUE_CLASSES)], 4),
        metadata={"names": str(dict(enumerate(RESCUE_CLASSES)))},
    )
    code = main(
        [
            "evaluate-detector",
            "--model",
            str(model),
            "--data",
            str(tmp_path / "nope"),
            "--out",
            str(tmp_path / "o"),
            "--quiet",
        ]
    )
    assert code == 2
    assert "no such folder" in capsys.readouterr().err


def test_evaluate_refuses_fresh_scene_flags_with_data_and_a_confidence_outside_0_1(hand_dataset, tmp_path, capsys):
    root, model = hand_dataset
    argv = [
        "evaluate-detector",
        "--model",
        str(model),
        "--data",
        str(root),
        "--out",
        str(tmp_path / "o"),
        "--quiet",
    ]
    assert main([*argv, "--images", "5", "--seed", "3"]) == 2
    err = capsys.readouterr().err
    assert (
        f"error: --images and --seed: for fresh scenes; --data {root} evaluates on that folder's val split" in err
    )
    with pytest.raises(SystemExit):
        main([*argv, "--conf", "1.5"])
    assert "argument --conf: expected a number from 0 to 1, got 1.5" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_detections_of_ignored_objects_are_neither_hits_nor_false(hand_dataset, tmp_path):
    root, model = hand_dataset
    # mark the oxidizer of image a as too hidden to label: its detection drops out, so the
    # oxidizer keeps AP 1 (found in b) instead of counting a's detection as a false one
    ox = RESCUE_CLASSES.index("oxidizer")
    lab = root / "labels/val/a.txt"
    line = lab.read_text()
    lab.write_text("")
    (root / "ignore/val").mkdir(parents=True)
    (root / "ignore/val/a.txt").write_text(line)
    images = load_split(root, "val")
    assert images[0].ignore_classes.tolist() == [ox] and images[1].ignore_classes.size == 0
    kept = detect_all(model, images, 0.25)
    assert len(kept[0].det_boxes) == 0 and len(kept[1].det_boxes) == 1
    out = tmp_path / "ev"
    assert (
        main(["evaluate-detector", "--model", str(model), "--data", str(root), "--out", str(out), "--quiet"]) == 0
    )
    rep = json.loads((out / "evaluation.json").read_text())
    assert rep["classes"]["oxidizer"]["AP50"] == 1.0 and rep["classes"]["oxidizer"]["n"] == 1
