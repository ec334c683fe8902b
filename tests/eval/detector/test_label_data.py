"""Training crops for the hazmat label classifier: which samples, cut as the pipeline cuts them."""

import sys
from pathlib import Path

import numpy as np
import pytest

from eval.cli.main import main
from eval.detector.dataset import DatasetError, DatasetSpec, write_dataset
from eval.detector.label_data import (
    BACKGROUND_INDEX,
    MAX_BOX_PX,
    MIN_BOX_PX,
    balanced_draw,
    collect_crops,
    crops_from_images,
    sample_crop,
    turned,
)
from eval.detector.quality import LabelledImage, load_split
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES
from poi.detectors.hazmat_labels import LABEL_CLASSES, crop_box

sys.path.insert(0, str(Path(__file__).parents[2] / "poi" / "detectors"))
import onnx_models  # noqa: E402


@pytest.fixture(scope="module")
def placards(tmp_path_factory):
    """Eight images of two scenarios, each scenario hanging all 16 labels."""
    out = tmp_path_factory.mktemp("ds") / "hz"
    spec = DatasetSpec(
        images=8, images_per_scenario=4, seed=21, counts={**DatasetSpec.default_counts(), "hazmat": 16}
    )
    write_dataset(spec, out)
    return out


def _expected(root: Path, split: str) -> tuple[int, int]:
    """(placards, labelled or ignored non-placard objects) with both box sides >= MIN_BOX_PX."""
    n_hz = n_other = 0
    placard_classes = [RESCUE_CLASSES.index(c) for c in HAZMAT_LABELS]
    for im in load_split(root, split):
        for px, classes, counted in (
            (im.boxes_px(640, 480), im.classes, True),
            (im.ignore_px(640, 480), im.ignore_classes, False),  # ignored placards are no sample
        ):
            big = np.minimum(px[:, 2] - px[:, 0], px[:, 3] - px[:, 1]) >= MIN_BOX_PX
            hz = np.isin(classes, placard_classes)
            n_hz += int(np.sum(big & hz)) if counted else 0
            n_other += int(np.sum(big & ~hz))
    return n_hz, n_other


@pytest.mark.slow
def test_every_placard_and_object_becomes_a_sample(placards):
    crops = collect_crops([placards], "train", seed=0)
    n_hz, n_other = _expected(placards, "train")
    assert n_hz > 0
    counts = crops.counts()
    assert counts[:BACKGROUND_INDEX].sum() == n_hz
    # background: every other labelled or ignored object and at most one random box per image
    n_images = len(load_split(placards, "train"))
    assert n_other <= counts[BACKGROUND_INDEX] <= n_other + n_images
    assert len(crops.patches) == len(crops.boxes) == len(crops.labels)


def test_an_ignored_object_is_background_and_an_ignored_placard_no_sample(tmp_path):
    """A box a detector may make on something evaluation ignores (a door seen in part, a QR
    chart's whole page) is a background sample; a placard too hidden to label is none."""
    import cv2

    path = tmp_path / "frame.jpg"
    cv2.imwrite(str(path), np.random.default_rng(0).integers(0, 255, (480, 640, 3), dtype=np.uint8))
    poison, qr, door = (RESCUE_CLASSES.index(c) for c in ("poison", "qr", "door"))
    labelled = dict(path=path, boxes_norm=np.array([[0.1, 0.1, 0.2, 0.2]]), classes=np.array([poison]))
    ignore = dict(
        ignore_norm=np.array([[0.5, 0.5, 0.6, 0.7], [0.7, 0.1, 0.8, 0.5], [0.3, 0.6, 0.4, 0.7]]),
        ignore_classes=np.array([qr, door, poison]),
    )
    without = crops_from_images([LabelledImage(**labelled)], "train", seed=3)
    crops = crops_from_images([LabelledImage(**labelled, **ignore)], "train", seed=3)
    added = crops.counts() - without.counts()
    assert added[BACKGROUND_INDEX] == 2 and added.sum() == 2  # the page and the door; not the placard
    # each around its own box: the page 64 x 96 px, the door 64 x 192 stored at half size (MAX_BOX_PX)
    sizes = sorted(tuple(np.round(b[2:] - b[:2])) for b in crops.boxes)
    for b in without.boxes:
        sizes.remove(tuple(np.round(b[2:] - b[:2])))
    assert sizes == [(32.0, 96.0), (64.0, 96.0)]


@pytest.mark.slow
def test_an_exact_crop_equals_the_pipelines_crop_of_the_frame(placards):
    import cv2

    crops = collect_crops([placards], "train", seed=0)
    k = 0
    for im in load_split(placards, "train"):
        rgb = cv2.cvtColor(cv2.imread(str(im.path)), cv2.COLOR_BGR2RGB)
        for box, c in zip(im.boxes_px(640, 480), im.classes, strict=True):
            if RESCUE_CLASSES[c] not in HAZMAT_LABELS or min(box[2] - box[0], box[3] - box[1]) < MIN_BOX_PX:
                continue
            i = next(j for j in range(k, len(crops)) if crops.labels[j] != BACKGROUND_INDEX)
            k = i + 1
            assert LABEL_CLASSES[crops.labels[i]] == RESCUE_CLASSES[c]
            if max(box[2] - box[0], box[3] - box[1]) <= MAX_BOX_PX:  # stored at full resolution
                want = crop_box(rgb, tuple(box), 64)
                assert np.array_equal(sample_crop(crops.patches[i], crops.boxes[i], 64, None), want)


@pytest.mark.slow
def test_augmented_crops_are_seeded_and_differ_from_the_exact_one(placards):
    crops = collect_crops([placards], "val", seed=0)
    i = int(np.flatnonzero(crops.labels != BACKGROUND_INDEX)[0])
    a = sample_crop(crops.patches[i], crops.boxes[i], 64, np.random.default_rng(5))
    b = sample_crop(crops.patches[i], crops.boxes[i], 64, np.random.default_rng(5))
    exact = sample_crop(crops.patches[i], crops.boxes[i], 64, None)
    assert a.shape == (64, 64, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b) and not np.array_equal(a, exact)


@pytest.mark.parametrize("deg", [0.0, 17.0, 45.0, 90.0, 133.0, -60.0])
def test_a_turned_patch_keeps_its_sheet_or_diamond_inside_the_turned_box(deg):
    """A white 40 x 40 square (a full sheet, tight 0) and a diamond with its vertices at that
    square's sides (tight 1), turned by ``deg``: the returned box is the white pixels' bounds,
    within the resampling's pixel."""
    import cv2

    box = np.array([40.0, 40.0, 80.0, 80.0])
    sheet = np.zeros((120, 120, 3), np.uint8)
    sheet[40:80, 40:80] = 255
    diamond = np.zeros((120, 120, 3), np.uint8)
    cv2.fillConvexPoly(diamond, np.array([[60, 40], [80, 60], [60, 80], [40, 60]], np.int32), (255, 255, 255))
    for img, tight in ((sheet, 0.0), (diamond, 1.0)):
        out, got = turned(img, box, np.radians(deg), tight)
        ys, xs = np.nonzero(out[..., 0] > 127)
        seen = np.array([xs.min(), ys.min(), xs.max() + 1, ys.max() + 1])
        assert got == pytest.approx(seen, abs=1.5), (tight, got, seen)
    # turned counter-clockwise as seen: the sheet's top-right corner rises to the top, 7 px
    # right of the centre (28.3 px from it at 45 + 30 degrees)
    out, _ = turned(sheet, box, np.radians(30.0), 0.0)
    ys, xs = np.nonzero(out[..., 0] > 127)
    assert xs[ys == ys.min()].mean() == pytest.approx(60 + 28.28 * np.cos(np.radians(75)), abs=1.5)


def test_balanced_draw_makes_every_class_equally_likely():
    labels = np.r_[np.zeros(900, int), np.full(100, 3), np.full(10, BACKGROUND_INDEX)]
    idx = balanced_draw(labels, 30000, np.random.default_rng(0))
    share = np.bincount(labels[idx], minlength=len(LABEL_CLASSES)) / idx.size
    assert share[[0, 3, BACKGROUND_INDEX]] == pytest.approx([1 / 3] * 3, abs=0.015)
    assert share.sum() == pytest.approx(1.0)


@pytest.mark.slow
def test_dataset_hazmat_count_option(tmp_path, capsys):
    with pytest.raises(DatasetError, match="whole numbers >= 0"):
        DatasetSpec(images=4, counts={"hazmat": -1})
    code = main(
        [
            "dataset",
            "--out",
            str(tmp_path / "d"),
            "--images",
            "2",
            "--per-scenario",
            "2",
            "--hazmat",
            "16",
            "--quiet",
        ]
    )
    assert code == 0
    import yaml

    spec = yaml.safe_load((tmp_path / "d" / "dataset.yaml").read_text())["spec"]
    assert spec["counts"]["hazmat"] == 16


def test_train_labels_without_data_is_one_line_and_leaves_nothing(tmp_path, capsys):
    # the data are checked first, with torch installed or not: nothing loaded, no run folder made
    code = main(["train-labels", "--data", str(tmp_path / "nothing"), "--out", str(tmp_path / "run")])
    assert code != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nothing" in err
    assert not (tmp_path / "run").exists()


def test_evaluate_detector_with_a_label_model(tmp_path, capsys):
    import json

    import cv2

    # one grey image with an oxidizer; the detector finds it and the classifier calls every
    # grey crop 'poison' (W: 8 on every channel for poison)
    root = tmp_path / "ds"
    for d in ("images/val", "labels/val"):
        (root / d).mkdir(parents=True)
    ox = RESCUE_CLASSES.index("oxidizer")
    cv2.imwrite(str(root / "images/val/a.jpg"), np.full((480, 640, 3), 90, np.uint8))
    (root / "labels/val/a.txt").write_text(f"{ox} {140 / 640:.6f} {120 / 480:.6f} {80 / 640:.6f} {80 / 480:.6f}\n")
    scores = np.zeros((1, len(RESCUE_CLASSES)), np.float32)
    scores[0, ox] = 0.9
    out = onnx_models.yolov8_output([[140 * 0.5, 120 * 0.5 + 40, 40, 40]], scores, 8)
    model = onnx_models.make_constant_model(
        tmp_path / "m.onnx", out, metadata={"names": str(dict(enumerate(RESCUE_CLASSES)))}
    )
    W = np.zeros((3, len(LABEL_CLASSES)))
    W[:, LABEL_CLASSES.index("poison")] = 8.0
    labels = onnx_models.make_colour_label_model(tmp_path / "l.onnx", W)
    ev = tmp_path / "ev"
    argv = ["evaluate-detector", "--model", str(model), "--label-model", str(labels), "--data", str(root)]
    assert main([*argv, "--out", str(ev), "--quiet"]) == 0
    rep = json.loads((ev / "evaluation.json").read_text())
    assert rep["label_model"] == str(labels)
    assert rep["classes"]["oxidizer"]["recall"] == 0.0  # renamed, so the oxidizer is missed
    (row,) = rep["by_size"]  # one placard, found but misnamed
    assert (row["group"], row["n"], row["found"], row["right_class"]) == ("hazmat label", 1, 1.0, 0.0)
