"""evaluate-photos: recall, false detections and size bands on labelled photo folders, hand-computed."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from eval.cli.main import main
from eval.detector.metrics import ImageBoxes
from eval.detector.photos import fold_classes, folder_report, load_folder
from eval.detector.quality import DetectorQualityError
from poi.core.names import CLASS_INDEX

DETECTORS = Path(__file__).resolve().parents[2] / "poi" / "detectors"  # red_detector.py
RED = "python:red_detector:RedBlobDetector"
C = CLASS_INDEX


def _im(gt, gt_cls, det, det_cls, scores) -> ImageBoxes:
    return ImageBoxes(
        gt_boxes=np.array(gt, float).reshape(-1, 4),
        gt_classes=np.array([C[c] for c in gt_cls], int),
        det_boxes=np.array(det, float).reshape(-1, 4),
        det_classes=np.array([C[c] for c in det_cls], int),
        det_scores=np.array(scores, float),
    )


def test_folder_report_counts_hits_misnamed_and_false_detections_by_hand():
    one = _im(
        [[0, 0, 30, 30], [100, 0, 200, 100], [300, 0, 350, 50]],
        ["poison", "explosive", "qr"],
        [
            [0, 0, 30, 30],
            [100, 0, 200, 90],
            [300, 0, 350, 50],
            [400, 0, 450, 50],
            [0, 0, 30, 28],
            [500, 0, 520, 20],
        ],
        ["poison", "radioactive", "door", "heat-source", "poison", "poison"],
        [0.9, 0.8, 0.7, 0.7, 0.6, 0.2],  # the last is below the operating confidence: not counted at all
    )
    empty = _im([], [], [[0, 0, 10, 10]], ["explosive"], [0.5])
    # the oxidizer detection overlaps less than the radioactive one but has the right class: it wins
    right_first = _im(
        [[0, 0, 40, 40]], ["oxidizer"], [[0, 0, 40, 40], [0, 0, 40, 38]], ["radioactive", "oxidizer"], [0.9, 0.5]
    )
    r = folder_report([one, empty, right_first], conf=0.4)
    assert r["images"] == 3 and r["detections"] == 8
    # placards: poison right, explosive named radioactive, oxidizer right
    assert r["hazmat"] == {
        "boxes": 3,
        "right": 2,
        "recall_right": 0.6667,
        "recall_found": 1.0,
        "misnamed": 1,
        "recall_placard": 1.0,
    }
    assert r["other"] == {"boxes": 1, "right": 0, "recall_right": 0.0, "recall_found": 1.0, "misnamed": 1}
    # false: heat-source on nothing, the second poison box on a paired placard, the explosive on the empty
    # image, and the radioactive box that lost the oxidizer to the right-class detection
    assert r["false"] == 4
    assert (r["false_per_image"], r["false_hazmat_per_image"], r["false_other_per_image"]) == (1.3333, 1.0, 0.3333)
    false = {c: m["false"] for c, m in r["classes"].items() if m["false"]}
    assert false == {"poison": 1, "explosive": 1, "radioactive": 1, "heat-source": 1}
    assert r["classes"]["radioactive"]["misnamed_as_this"] == 1 and r["classes"]["door"]["misnamed_as_this"] == 1
    assert r["classes"]["explosive"]["recall_placard"] == 1.0 and r["classes"]["explosive"]["recall_right"] == 0.0
    assert r["classes"]["qr"]["recall_placard"] is None  # not a placard class
    assert [(t["true"], t["detected"], t["n"]) for t in r["top_confusions"]] == [
        ("explosive", "radioactive", 1),
        ("qr", "door", 1),
    ]
    # shorter side 30 px, 40 px (the 40-80 band starts at 40), 100 px; the QR box 50 px
    bands = {(b["group"], b["band_px"]): (b["n"], b["found"], b["right_class"]) for b in r["by_size"]}
    assert bands == {
        ("hazmat label", "20-40"): (1, 1.0, 1.0),
        ("hazmat label", "40-80"): (1, 1.0, 1.0),
        ("hazmat label", "80+"): (1, 1.0, 0.0),
        ("other type", "40-80"): (1, 1.0, 0.0),
    }


def _write(path: Path, bgr: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), bgr)


def _grey(h: int = 300, w: int = 500) -> np.ndarray:
    return np.full((h, w, 3), 150, np.uint8)


def _yolo(cls: str, x0: float, y0: float, x1: float, y1: float, w: int = 500, h: int = 300) -> str:
    return f"{C[cls]} {(x0 + x1) / 2 / w:.6f} {(y0 + y1) / 2 / h:.6f} {(x1 - x0) / w:.6f} {(y1 - y0) / h:.6f}\n"


RED_BGR = (10, 13, 199)  # the simulator's extinguisher red, which red_detector finds


@pytest.fixture
def folders(tmp_path, monkeypatch):
    """A flat folder of two 500x300 photos and a 'poibench dataset' folder of one 640x480 image, and the
    red detector's weights.

    real/a.png: a labelled red box (found, right class) and a labelled explosive placard that is not
    drawn (missed, 30 px: band 20-40); real/b.jpg: an unlabelled red box (a false detection) and no
    labels file; rend/images/val/c.jpg: a labelled red box (found).
    """
    monkeypatch.syspath_prepend(str(DETECTORS))
    from red_detector import write_weights

    real = tmp_path / "real"
    a = _grey()
    a[40:160, 50:110] = RED_BGR
    _write(real / "images" / "a.png", a)
    (real / "labels").mkdir()
    (real / "labels" / "a.txt").write_text(
        _yolo("fire-extinguisher", 50, 40, 110, 160) + _yolo("explosive", 300, 50, 330, 80)
    )
    b = _grey()
    b[100:220, 300:360] = RED_BGR
    _write(real / "images" / "b.jpg", b)
    rend = tmp_path / "rend"
    c = _grey(480, 640)
    c[200:320, 400:460] = RED_BGR
    _write(rend / "images" / "val" / "c.jpg", c)
    (rend / "labels" / "val").mkdir(parents=True)
    (rend / "labels" / "val" / "c.txt").write_text(_yolo("fire-extinguisher", 400, 200, 460, 320, 640, 480))
    return real, rend, write_weights(tmp_path / "w.npz")


def test_evaluate_photos_side_by_side(folders, tmp_path, capsys):
    real, rend, weights = folders
    out = tmp_path / "ev"
    argv = ["evaluate-photos", "--images", str(real), str(rend), "--model", RED, "--option", f"weights={weights}"]
    assert main([*argv, "--conf", "0.3", "--out", str(out), "--quiet", "--overlay", "2"]) == 0
    s = json.loads((out / "summary.json").read_text())
    real_r, rend_r = s["folders"]
    assert (real_r["name"], real_r["images"], real_r["without_labels"]) == ("real", 2, 1)
    assert real_r["hazmat"]["boxes"] == 1 and real_r["hazmat"]["recall_found"] == 0.0
    assert real_r["other"]["right"] == 1 and real_r["false"] == 1
    assert (real_r["false_per_image"], real_r["false_other_per_image"]) == (0.5, 0.5)
    assert real_r["classes"]["fire-extinguisher"]["false"] == 1
    assert {(b["group"], b["band_px"]): b["n"] for b in real_r["by_size"]} == {
        ("hazmat label", "20-40"): 1,
        ("other type", "40-80"): 1,
    }
    assert (rend_r["images"], rend_r["other"]["recall_right"], rend_r["false"]) == (1, 1.0, 0)
    assert s["false_detection"].startswith("false detection: a detection at the operating confidence")
    with (out / "per_class.csv").open() as fh:
        rows = {(r["folder"], r["class"]): r for r in csv.DictReader(fh)}
    assert set(rows) == {("real", "explosive"), ("real", "fire-extinguisher"), ("rend", "fire-extinguisher")}
    assert rows[("real", "fire-extinguisher")]["false"] == "1"
    sheet = cv2.imread(str(out / "overlay.png"))
    assert sheet is not None and sheet.shape[1] == 6 * 300  # key, two headers, one row of tiles a folder
    assert sheet.shape[0] == 24 * 3 + 2 * 300
    printed = capsys.readouterr().out
    assert "| | real | rend |" in printed
    assert "| false detections per image, any class | 0.50 (1) | 0.00 (0) |" in printed
    assert "real: 1 images have no labels file; taken as showing no object" in printed


def test_a_team_detectors_bad_output_names_the_photo(folders, tmp_path, monkeypatch, capsys):
    real, _, _ = folders
    (tmp_path / "bad_det.py").write_text("class Dicts:\n    def detect(self, frame):\n        return {}\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    argv = [
        "evaluate-photos",
        "--images",
        str(real),
        "--model",
        "python:bad_det:Dicts",
        "--out",
        str(tmp_path / "o"),
    ]
    assert main([*argv, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"error: {real / 'images' / 'a.png'}: detector 'python:bad_det:Dicts': returned a dict" in err


def test_load_folder_limit_is_seeded(folders):
    real, _, _ = folders
    picks = {load_folder(real, limit=1, seed=s).images[0].path.name for s in range(8)}
    assert picks == {"a.png", "b.jpg"}
    assert load_folder(real, limit=1, seed=3).images[0].path == load_folder(real, limit=1, seed=3).images[0].path
    assert load_folder(real, limit=1, seed=3).total_images == 2


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("16 0.5 0.5 0.1\n", "{lab}:2: expected 'class cx cy w h', got 4 fields"),
        ("x 0.5 0.5 0.1 0.1\n", "{lab}:2: class index 'x' is not an integer"),
        ("0 0.5 0.5 0.1 a\n", "{lab}:2: expected 'class cx cy w h' with numbers, got '0 0.5 0.5 0.1 a'"),
        ("40 0.5 0.5 0.1 0.1\n", "{lab}:2: class index 40 is not in 0..23"),
        ("0 nan 0.5 0.1 0.1\n", "{lab}:2: cx nan: expected a number in [0, 1]"),
        ("0 1.5 0.5 0.1 0.1\n", "{lab}:2: cx 1.5: expected a number in [0, 1]"),
        ("0 0.5 0.5 0 0.1\n", "{lab}:2: w 0, h 0.1: expected a box larger than 0"),
    ],
)
def test_malformed_label_lines_name_file_and_line(folders, tmp_path, capsys, line, expected):
    real, _, _ = folders
    lab = real / "labels" / "a.txt"
    lab.write_text(lab.read_text().splitlines()[0] + "\n" + line)
    with pytest.raises(DetectorQualityError, match="^" + re.escape(expected.format(lab=lab)) + "$"):
        load_folder(real)
    argv = ["evaluate-photos", "--images", str(real), "--out", str(tmp_path / "o"), "--quiet"]
    assert main(argv) == 2
    assert capsys.readouterr().err == f"poibench evaluate-photos: error: {expected.format(lab=lab)}\n"


def test_missing_folder_and_empty_folder_are_one_line_errors(tmp_path):
    with pytest.raises(DetectorQualityError, match=r"nope: no such folder$"):
        load_folder(tmp_path / "nope")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(DetectorQualityError, match=r"afile: a file, not a folder$"):
        load_folder(tmp_path / "afile")
    (tmp_path / "e" / "images").mkdir(parents=True)
    with pytest.raises(DetectorQualityError, match=r"images: no \.jpg or \.png images \(nor in a split folder\)$"):
        load_folder(tmp_path / "e")
    _write(tmp_path / "e" / "images" / "x.jpg", _grey())
    with pytest.raises(DetectorQualityError, match=r"e: no labels/ folder"):
        load_folder(tmp_path / "e")


def test_absent_map_folds_labels_the_photo_set_lacks():
    # an INHALATION HAZARD placard the set labels poison, named inhalation-hazard; an OXYGEN
    # placard labelled oxidizer, named oxygen; a poison named poison; a corrosive named poison
    im = _im(
        [[0, 0, 40, 40], [100, 0, 140, 40], [200, 0, 240, 40], [300, 0, 340, 40]],
        ["poison", "oxidizer", "poison", "corrosive"],
        [[0, 0, 40, 40], [100, 0, 140, 40], [200, 0, 240, 40], [300, 0, 340, 40]],
        ["inhalation-hazard", "oxygen", "poison", "poison"],
        [0.9, 0.9, 0.9, 0.9],
    )
    kept = folder_report(fold_classes([im], "keep"), conf=0.4)
    mapped = folder_report(fold_classes([im], "map"), conf=0.4)
    assert kept["hazmat"]["right"] == 1  # only the poison named poison
    assert mapped["hazmat"]["right"] == 3  # inhalation-hazard -> poison, oxygen -> oxidizer
    assert mapped["hazmat"]["boxes"] == kept["hazmat"]["boxes"] == 4
    with pytest.raises(DetectorQualityError, match="--absent must be one of keep, map"):
        fold_classes([im], "drop")


def test_recall_by_size_is_at_the_frames_scale():
    """A 30 px placard of an image 320 px on its long side is counted with the 60 px ones, as the
    detector sees it; without scales, in the image's own pixels."""
    from eval.detector.metrics import ImageBoxes
    from eval.detector.photos import folder_report

    box = np.array([[10.0, 10.0, 40.0, 45.0]])  # 30 x 35 px
    two = np.array([2])
    im = ImageBoxes(gt_boxes=box, gt_classes=two, det_boxes=box, det_classes=two, det_scores=np.array([0.9]))

    def bands(report: dict) -> dict:
        return {b["band_px"]: b["n"] for b in report["by_size"] if b["group"] == "hazmat label"}

    assert bands(folder_report([im], 0.5, np.array([2.0])))["40-80"] == 1
    assert bands(folder_report([im], 0.5))["20-40"] == 1
