"""Label classifier on photo folders: the seeded holdout split and evaluate-labels' counts, by hand.

Torch-free: the classifier is a tiny ONNX graph naming a crop by its mean colour
(tests/poi/detectors/onnx_models.py), so every count below follows from the
colours painted in the synthetic photos.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from eval.cli.main import main
from eval.detector.label_data import (
    HOLDOUT_NAME,
    holdout_split,
    image_key,
    read_holdout,
    training_images,
    write_holdout,
)
from eval.detector.label_eval import fold_confusion, wilson
from eval.detector.photos import load_folder
from eval.detector.quality import DetectorQualityError
from eval.detector.train_labels import PHOTO_FOLDERS_METADATA_KEY, LabelTrainSpec
from poi.core.names import CLASS_INDEX
from poi.detectors.hazmat_labels import LABEL_CLASSES

sys.path.insert(0, str(Path(__file__).parents[2] / "poi" / "detectors"))
import onnx_models  # noqa: E402

L = LABEL_CLASSES.index
RED, GREEN, BLUE = (255, 0, 0), (0, 255, 0), (0, 0, 255)  # RGB


def _photo(
    root: Path, name: str, objects: list[tuple[str, tuple[int, int, int], tuple[int, int, int, int]]]
) -> None:
    """A 200 x 200 black photo with solid squares (class, RGB colour, xyxy) and its YOLO labels."""
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "labels").mkdir(parents=True, exist_ok=True)
    rgb = np.zeros((200, 200, 3), np.uint8)
    lines = []
    for cls, colour, (x0, y0, x1, y1) in objects:
        rgb[y0:y1, x0:x1] = colour
        cx, cy, w, h = (x0 + x1) / 400, (y0 + y1) / 400, (x1 - x0) / 200, (y1 - y0) / 200
        lines.append(f"{CLASS_INDEX[cls]} {cx} {cy} {w} {h}")
    assert cv2.imwrite(str(root / "images" / f"{name}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    (root / "labels" / f"{name}.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")


def _colour_model(path: Path, metadata: dict[str, str] | None = None) -> Path:
    """Mean red -> explosive, mean green -> oxygen, mean blue -> background, then poison (weights
    30 and 15: a square filling 1/1.44 of its crop gives logits about 21 and 10 against 0)."""
    W = np.zeros((3, len(LABEL_CLASSES)))
    W[0, L("explosive")] = W[1, L("oxygen")] = W[2, L("background")] = 30.0
    W[2, L("poison")] = 15.0
    return onnx_models.make_colour_label_model(path, W, metadata=metadata)


@pytest.fixture
def photos(tmp_path) -> Path:
    """a: red explosive (right), green oxidizer (named oxygen); b: green oxygen (right), blue poison
    (named background); c: a 5 px red explosive (too small) and a green qr (not a placard)."""
    root = tmp_path / "photos"
    _photo(root, "a", [("explosive", RED, (10, 10, 60, 60)), ("oxidizer", GREEN, (100, 100, 150, 150))])
    _photo(root, "b", [("oxygen", GREEN, (20, 20, 80, 80)), ("poison", BLUE, (120, 30, 180, 90))])
    _photo(root, "c", [("explosive", RED, (10, 10, 15, 15)), ("qr", GREEN, (100, 100, 150, 150))])
    return root


def _many(root: Path, n: int, step: int = 3) -> Path:
    """``n`` photos numbered ``step`` apart: with step 3 each is a run of its own (RUN_GAP 2)."""
    for k in range(n):
        _photo(root, f"im{step * k:02d}", [("poison", BLUE, (10, 10, 60, 60))])
    return root


def test_holdout_split_is_seeded_disjoint_and_by_name(tmp_path):
    root = _many(tmp_path / "p", 10)
    images = load_folder(root).images
    train, held = holdout_split(images, root, 0.3, seed=5)
    names = lambda ims: [image_key(root, im) for im in ims]  # noqa: E731
    assert len(held) == 3 and len(train) == 7
    assert set(names(train)).isdisjoint(names(held))
    assert sorted(names(train) + names(held)) == [f"im{3 * k:02d}.png" for k in range(10)]
    # the same seed gives the same split whatever the order the images come in
    again = holdout_split(list(reversed(images)), root, 0.3, seed=5)
    assert names(again[1]) == names(held) and names(again[0]) == names(train)
    # another seed draws other images (10 choose 3 = 120 possible draws; these two differ)
    assert {tuple(names(holdout_split(images, root, 0.3, seed=s)[1])) for s in range(4)} != {tuple(names(held))}


def test_holdout_split_keeps_a_scenes_shots_on_one_side(tmp_path):
    """Photos numbered within RUN_GAP of each other are one scene shot again: never split."""
    root = tmp_path / "p"
    for name in ["scene1", "scene2", "scene4", "scene9", "scene10", "other7", "x"]:
        _photo(root, name, [("poison", BLUE, (10, 10, 60, 60))])
    images = load_folder(root).images
    runs = [{"scene1", "scene2", "scene4"}, {"scene9", "scene10"}, {"other7"}, {"x"}]
    for seed in range(6):
        train, held = holdout_split(images, root, 0.3, seed=seed)
        held_names = {Path(image_key(root, im)).stem for im in held}
        assert all(run <= held_names or not run & held_names for run in runs)
        assert len(held_names) >= 2  # runs are held back until round(0.3 * 7) = 2 images are


def test_holdout_split_refuses_fractions_that_leave_a_side_empty(tmp_path):
    root = _many(tmp_path / "p", 3)
    images = load_folder(root).images
    with pytest.raises(DetectorQualityError, match="between 0 and 1"):
        holdout_split(images, root, 1.0, seed=0)
    with pytest.raises(DetectorQualityError, match="leaves no training or no held-back image"):
        holdout_split(images, root, 0.1, seed=0)  # round(0.3) = 0 held back


def test_training_images_hold_back_photos_and_keep_dataset_splits(tmp_path):
    root = _many(tmp_path / "p", 10)
    with pytest.raises(DetectorQualityError, match="give --holdout FRACTION"):
        training_images([root], None, 0)
    got = training_images([root], 0.2, 4)
    assert len(got.train) == 8 and len(got.val) == 2
    assert got.holdout == {
        "fraction": 0.2,
        "seed": 4,
        "folders": {str(root.resolve()): [image_key(root, im) for im in got.val]},
    }
    run = tmp_path / "run"
    run.mkdir()
    write_holdout(run, got.holdout)
    assert read_holdout(run) == {str(root.resolve()): {image_key(root, im) for im in got.val}}
    write_holdout(run, got.holdout)  # a resumed run holds back the same images
    with pytest.raises(DetectorQualityError, match="holds back other images"):
        write_holdout(run, training_images([root], 0.2, 5).holdout)


def test_train_labels_checks_the_holdout_before_needing_torch(tmp_path, capsys):
    with pytest.raises(ValueError, match="--holdout must be between 0 and 1"):
        LabelTrainSpec(data=["x"], out="y", holdout=1.5)
    root = _many(tmp_path / "p", 4)
    assert main(["train-labels", "--data", str(root), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert "is a folder of photos (no train/val splits): give --holdout" in err and len(err.splitlines()) == 1


@pytest.mark.train
def test_train_labels_on_photos_holds_back_and_names_them(tmp_path):
    """One tiny epoch on 10 photos: the run lists the 2 held-back images, the model names the folder,
    and a rerun with another seed is refused (torch: the 'train' extra)."""
    pytest.importorskip("torch")
    import onnx

    from eval.detector.train_labels import PATH_SEPARATOR, train_labels

    root = _many(tmp_path / "p", 10)
    run = tmp_path / "run"
    spec = dict(data=[str(root)], out=str(run), epochs=1, samples_per_epoch=16, batch=8, threads=1, holdout=0.2)
    onnx_path = train_labels(LabelTrainSpec(**spec, seed=3), log=lambda _: None)
    held = read_holdout(run)[str(root.resolve())]
    expected = holdout_split(load_folder(root).images, root, 0.2, 3)[1]
    assert held == {image_key(root, im) for im in expected} and len(held) == 2
    meta = {p.key: p.value for p in onnx.load(str(onnx_path)).metadata_props}
    assert meta[PHOTO_FOLDERS_METADATA_KEY].split(PATH_SEPARATOR) == [str(root.resolve())]
    onnx_path.unlink()  # an unfinished run: a rerun resumes, with the same holdout only
    with pytest.raises(ValueError, match="holds back other images"):
        train_labels(LabelTrainSpec(**spec, seed=4), log=lambda _: None)


def test_train_labels_refuses_a_crop_size_its_stages_cannot_halve(tmp_path, capsys):
    with pytest.raises(ValueError, match="--imgsz 80 does not halve 5 times"):
        LabelTrainSpec(data=["x"], out="y", imgsz=80, widths=(8, 8, 8, 8, 8))
    with pytest.raises(ValueError, match="--widths must be one or more positive"):
        LabelTrainSpec(data=["x"], out="y", widths=(16, 0))
    root = _many(tmp_path / "p", 4)
    argv = ["train-labels", "--data", str(root), "--out", str(tmp_path / "r"), "--holdout", "0.2", "--imgsz", "80"]
    argv += ["--widths", "8", "8", "8", "8", "8"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "--imgsz 80 does not halve 5 times" in err and len(err.splitlines()) == 1


@pytest.mark.train
def test_train_labels_at_another_crop_size_exports_it_and_resumes_only_at_it(tmp_path):
    """A 96 px classifier of three stages: the ONNX reads 96 x 96 crops and says so in its
    metadata; resuming its run at 64 px is refused in one line (torch: the 'train' extra)."""
    pytest.importorskip("torch")
    import onnx

    from eval.detector.train_labels import train_labels

    root = _many(tmp_path / "p", 10)
    spec = dict(data=[str(root)], out=str(tmp_path / "run"), epochs=1, samples_per_epoch=16, batch=8)
    shape = dict(imgsz=96, widths=(8, 16, 32))
    onnx_path = train_labels(LabelTrainSpec(**spec, threads=1, holdout=0.2, **shape), log=lambda _: None)
    m = onnx.load(str(onnx_path))
    dims = [d.dim_value for d in m.graph.input[0].type.tensor_type.shape.dim[1:]]
    assert dims == [3, 96, 96] and {p.key: p.value for p in m.metadata_props}["imgsz"] == "96"
    onnx_path.unlink()
    with pytest.raises(ValueError, match="was trained with --imgsz 96 --widths 8 16 32: resume with those"):
        train_labels(LabelTrainSpec(**spec, threads=1, holdout=0.2), log=lambda _: None)


def test_fold_confusion_drops_or_maps_the_labels_the_real_set_lacks():
    conf = np.zeros((17, 17), int)
    conf[L("oxygen"), L("oxygen")] = 3
    conf[L("oxygen"), L("oxidizer")] = 1
    conf[L("oxidizer"), L("oxygen")] = 2
    conf[L("poison"), L("inhalation-hazard")] = 4
    assert fold_confusion(conf, "keep").tolist() == conf.tolist()
    drop = fold_confusion(conf, "drop")
    assert drop.sum() == 6 and drop[L("oxidizer"), L("oxygen")] == 2  # a name of oxygen stays wrong
    m = fold_confusion(conf, "map")
    assert m.sum() == 10 and m[L("oxidizer"), L("oxidizer")] == 6 and m[L("poison"), L("poison")] == 4
    assert np.trace(m) == 10
    with pytest.raises(DetectorQualityError, match="--absent must be one of"):
        fold_confusion(conf, "merge")


def test_wilson_interval_by_hand():
    # k = 8, n = 10, z = 1.96: centre (0.8 + 0.19208) / 1.38416, half 1.96 sqrt(0.016 + 0.0096040) / 1.38416
    lo, hi = wilson(8, 10)
    assert lo == pytest.approx(0.4902, abs=1e-4) and hi == pytest.approx(0.9433, abs=1e-4)
    assert wilson(0, 0) is None


@pytest.mark.parametrize(
    ("absent", "crops", "right", "per_class", "labels_only"),
    [
        ("keep", 4, 2, {"explosive": (1, 1), "oxidizer": (1, 0), "oxygen": (1, 1), "poison": (1, 0)}, 0.75),
        ("drop", 3, 1, {"explosive": (1, 1), "oxidizer": (1, 0), "poison": (1, 0)}, 0.6667),
        ("map", 4, 3, {"explosive": (1, 1), "oxidizer": (2, 2), "poison": (1, 0)}, 1.0),
    ],
)
def test_evaluate_labels_counts_by_hand(tmp_path, photos, absent, crops, right, per_class, labels_only):
    """The blue poison is named background; with background not allowed, poison (right)."""
    model = _colour_model(tmp_path / "colour.onnx")
    out = tmp_path / "out"
    argv = ["evaluate-labels", "--label-model", str(model), "--data", str(photos), str(photos)]
    assert main([*argv, "--absent", absent, "--out", str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    a, b = s["folders"]
    assert (a["name"], b["name"]) == ("photos", "photos-2")
    assert a["confusion"] == b["confusion"]
    assert (a["crops"], a["right"], a["small_left_out"], a["images"]) == (crops, right, 1, 3)
    assert {k: (v["crops"], v["right"]) for k, v in a["per_class"].items()} == per_class
    assert a["accuracy_labels_only"] == labels_only
    # the unfolded matrix is the same whatever --absent says
    raw = np.array(a["confusion_unfolded"])
    assert raw[L("oxidizer"), L("oxygen")] == 1 and raw[L("poison"), L("background")] == 1 and raw.sum() == 4
    top = [(c["true"], c["named"], c["count"]) for c in a["top_confusions"]]
    expected = {
        "keep": [("oxidizer", "oxygen", 1), ("poison", "background", 1)],
        "map": [("poison", "background", 1)],
    }
    assert top == expected.get(absent, [("oxidizer", "oxygen", 1), ("poison", "background", 1)])
    assert (out / "confusion_photos.png").stat().st_size > 0 and (out / "confusion_photos-2.png").exists()
    report = (out / "report.md").read_text()
    assert f"**{100 * right / crops:.1f}%** ({right}/{crops};" in report


def test_evaluate_labels_holdout_of_scores_only_the_held_back_images(tmp_path, photos, capsys):
    trained = str(photos.resolve())
    model = _colour_model(tmp_path / "colour.onnx", {PHOTO_FOLDERS_METADATA_KEY: trained})
    out = tmp_path / "out"
    argv = ["evaluate-labels", "--label-model", str(model), "--data", str(photos), "--out", str(out), "--quiet"]
    assert main(argv) == 2  # trained on part of the folder: refuses to score all of it
    assert "was trained on part of" in capsys.readouterr().err
    run = tmp_path / "run"
    run.mkdir()
    (run / HOLDOUT_NAME).write_text(json.dumps({"fraction": 0.34, "seed": 0, "folders": {trained: ["b.png"]}}))
    assert main([*argv, "--holdout-of", str(run)]) == 0
    (f,) = json.loads((out / "summary.json").read_text())["folders"]
    assert (f["images"], f["crops"], f["right"], f["held_back_only"]) == (1, 2, 1, True)


def test_evaluate_labels_errors_are_one_line(tmp_path, photos, capsys):
    model = _colour_model(tmp_path / "colour.onnx")
    base = ["evaluate-labels", "--label-model", str(model), "--out", str(tmp_path / "o"), "--quiet"]
    cases = [
        ([*base, "--data", str(tmp_path / "nowhere")], "nowhere: no such folder"),
        (
            [
                "evaluate-labels",
                "--label-model",
                str(tmp_path / "x.onnx"),
                "--data",
                str(photos),
                "--out",
                str(tmp_path / "o"),
            ],
            "x.onnx: no such model file",
        ),
        ([*base, "--data", str(photos), "--holdout-of", str(tmp_path)], "holdout.json: no such file"),
        ([*base, "--data", str(photos), "--min-px", "-1"], "--min-px must be at least 0"),
    ]
    (photos / "labels" / "c.txt").write_text("0 0.5 0.5\n")
    cases.append(([*base, "--data", str(photos)], "c.txt:1: expected 'class cx cy w h'"))
    for argv, msg in cases[-1:] + cases[:-1]:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert msg in err and len(err.splitlines()) == 1, err
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / HOLDOUT_NAME).write_text("[1, 2]")
    (photos / "labels" / "c.txt").write_text("")
    assert main([*base, "--data", str(photos), "--holdout-of", str(bad)]) == 2
    assert "not a holdout file" in capsys.readouterr().err
    other = tmp_path / "other"
    other.mkdir()
    (other / HOLDOUT_NAME).write_text(json.dumps({"folders": {"/elsewhere": ["a.png"]}}))
    assert main([*base, "--data", str(photos), "--holdout-of", str(other)]) == 2
    assert "none of which is a --data folder" in capsys.readouterr().err


def test_evaluate_labels_by_box_size_and_at_the_first_folders_sizes(tmp_path):
    """ref: a 30 px explosive (right), 100 px explosive (right) and 100 px poison (named
    background): 20-40 px 1 of 1, 80+ px 1 of 2. other: 30 px explosive (right) and poison
    (wrong), 100 px explosive (right): 1 of 2 and 1 of 1, 2 of 3 in all, and at ref's sizes
    (1/3 of its crops 20-40 px, 2/3 80+) 1/3 * 0.5 + 2/3 * 1.0 = 0.8333."""
    ref, other = tmp_path / "ref", tmp_path / "other"
    _photo(ref, "a", [("explosive", RED, (10, 10, 40, 40)), ("explosive", RED, (90, 90, 190, 190))])
    _photo(ref, "b", [("poison", BLUE, (50, 50, 150, 150))])
    _photo(other, "a", [("explosive", RED, (10, 10, 40, 40)), ("poison", BLUE, (100, 10, 130, 40))])
    _photo(other, "b", [("explosive", RED, (50, 50, 150, 150))])
    model = _colour_model(tmp_path / "colour.onnx")
    out = tmp_path / "out"
    argv = ["evaluate-labels", "--label-model", str(model), "--data", str(ref), str(other), "--out", str(out)]
    assert main([*argv, "--quiet"]) == 0
    a, b = json.loads((out / "summary.json").read_text())["folders"]
    assert [(r["band_px"], r["crops"], r["right"]) for r in a["by_size"]] == [
        ("0-20", 0, 0),
        ("20-40", 1, 1),
        ("40-80", 0, 0),
        ("80+", 2, 1),
    ]
    assert [(r["crops"], r["right"]) for r in b["by_size"]] == [(0, 0), (2, 1), (0, 0), (1, 1)]
    assert (b["right"], b["crops"]) == (2, 3)
    assert b["size_matched_accuracy"] == pytest.approx(0.8333)
    assert a["size_matched_accuracy"] == pytest.approx(2 / 3, abs=1e-4)  # itself at its own sizes
    report = (out / "report.md").read_text()
    assert "| all, at ref's box sizes | (reference) | 83.3% |" in report
    assert "| boxes 80+ px | 50% (1/2) | 100% (1/1) |" in report


def _split_folder(root: Path, train: int, val: int, route_frames: bool = False) -> Path:
    """A 'poibench dataset' folder (or, with ``route_frames``, a 'poibench route-frames' one:
    its dataset.yaml under that key, its val split empty) of black 64 px images."""
    for split, n in (("train", train), ("val", val)):
        (root / "images" / split).mkdir(parents=True, exist_ok=True)
        (root / "labels" / split).mkdir(parents=True, exist_ok=True)
        for i in range(n):
            assert cv2.imwrite(str(root / "images" / split / f"{i:03d}.jpg"), np.zeros((64, 64, 3), np.uint8))
    key = "route_frames" if route_frames else "dataset"
    (root / "dataset.yaml").write_text(f"{key}:\n  seed: 0\n", encoding="utf-8")
    return root


def test_training_images_take_route_frames_folders_for_training_only(tmp_path):
    data = _split_folder(tmp_path / "data", 3, 2)
    mined = _split_folder(tmp_path / "mined", 4, 0, route_frames=True)
    with pytest.raises(DetectorQualityError, match="--holdout 0.2: holds back part of a folder of photos"):
        training_images([data, mined], 0.2, 0)
    got = training_images([data, mined], None, 0)
    assert (len(got.train), len(got.val)) == (7, 2)
    assert {Path(im.path).parent.parent.parent.name for im in got.val} == {"data"}
    with pytest.raises(DetectorQualityError, match="no validation images in .*mined.*add a 'poibench dataset'"):
        training_images([mined], None, 0)
    # a dataset folder keeps needing its val split
    with pytest.raises(DetectorQualityError, match="val: no images"):
        training_images([_split_folder(tmp_path / "empty", 3, 0), mined], None, 0)
    # a dataset.yaml that is not YAML is named, not a traceback
    bad = _split_folder(tmp_path / "bad", 1, 1)
    (bad / "dataset.yaml").write_text("route_frames: [unclosed\n", encoding="utf-8")
    with pytest.raises(DetectorQualityError, match=r"bad/dataset.yaml"):
        training_images([bad], None, 0)


@pytest.mark.train
def test_train_labels_fine_tunes_from_a_checkpoint_and_keeps_its_shape_and_seeds(tmp_path, capsys):
    """A run's label_model.pt starts a second run: its weights are the start (at a learning rate
    of ~0 the second run ends with the first's convolution and linear weights; only the batch
    norms' running statistics move), its shape is kept, another shape is refused in one line,
    and the seeds it was trained on stay in the metadata (torch: the 'train' extra)."""
    pytest.importorskip("torch")
    import onnx
    import torch

    from eval.detector.train_labels import CHECKPOINT_NAME, SEEDS_METADATA_KEY, read_checkpoint, train_labels

    root = _many(tmp_path / "p", 10)
    spec = dict(data=[str(root)], epochs=1, samples_per_epoch=16, batch=8, threads=1, holdout=0.2)
    first = train_labels(LabelTrainSpec(**spec, out=str(tmp_path / "a"), widths=(8, 16)), log=lambda _: None)
    ck_path = first.parent / CHECKPOINT_NAME
    ck = torch.load(ck_path, weights_only=True)
    ck["seeds"] = [8400]  # as if trained on a rendered dataset of seed 8400 too
    torch.save(ck, ck_path)
    tuned = LabelTrainSpec(**spec, out=str(tmp_path / "b"), model=str(ck_path), lr=1e-12)
    assert (tuned.imgsz, tuned.widths) == (64, (8, 16))
    # the checkpoint's own widths, given as a list, are its shape, not another one
    assert LabelTrainSpec(**spec, out=str(tmp_path / "d"), model=str(ck_path), widths=[8, 16]).widths == (8, 16)
    second = train_labels(tuned, log=lambda _: None)
    after = read_checkpoint(second.parent / CHECKPOINT_NAME).state
    learnt = [k for k, v in ck["model"].items() if k.endswith("weight") and v.dim() > 1]
    assert len(learnt) == 3  # two convolutions and the linear layer
    for k in learnt:
        torch.testing.assert_close(after[k], ck["model"][k], atol=1e-8, rtol=0)
    meta = {p.key: p.value for p in onnx.load(str(second)).metadata_props}
    assert meta[SEEDS_METADATA_KEY] == "8400" and read_checkpoint(second.parent / CHECKPOINT_NAME).seeds == (8400,)
    argv = ["train-labels", "--data", str(root), "--out", str(tmp_path / "c"), "--holdout", "0.2"]
    assert main([*argv, "--model", str(ck_path), "--widths", "8", "32"]) == 2
    err = capsys.readouterr().err.strip()
    assert "was trained with --imgsz 64 --widths 8 16: leave --imgsz and --widths out" in err
    assert len(err.splitlines()) == 1
    assert main([*argv, "--model", str(tmp_path / "none.pt")]) == 2
    assert "none.pt: no such checkpoint" in capsys.readouterr().err


@pytest.mark.train
def test_train_labels_starts_from_a_float_onnx_export_at_the_exported_function(tmp_path):
    """A label_model.onnx (BatchNorms folded into the convolutions) read back as a checkpoint
    computes what onnxruntime computes; with its BatchNorm statistics estimated on a batch, the
    network in train mode gives that batch the same features as in eval mode, so training starts
    at the exported function. A detector's ONNX is refused in one line (torch: the 'train' extra)."""
    pytest.importorskip("torch")
    import onnxruntime as ort
    import torch

    from eval.detector.label_checkpoint import build_model, conv_blocks, read_checkpoint
    from eval.detector.rebuild import estimate_batchnorm
    from eval.detector.train import TrainError
    from eval.detector.train_labels import train_labels

    root = _many(tmp_path / "p", 10)
    spec = dict(data=[str(root)], epochs=1, samples_per_epoch=32, batch=8, threads=1, holdout=0.2)
    exported = train_labels(LabelTrainSpec(**spec, out=str(tmp_path / "a"), widths=(8, 16)), log=lambda _: None)
    ck = read_checkpoint(exported)
    assert ck.fused and (ck.imgsz, ck.widths) == (64, (8, 16))
    model = build_model(ck.widths, ck.imgsz, len(LABEL_CLASSES))
    model.load_state_dict(ck.state)
    x = torch.from_numpy(np.random.default_rng(0).random((6, 3, 64, 64), dtype=np.float32))
    want = ort.InferenceSession(str(exported)).run(None, {"images": x.numpy()})[0]
    model.eval()
    with torch.no_grad():
        np.testing.assert_allclose(torch.softmax(model(x), 1).numpy(), want, atol=1e-5)
        estimate_batchnorm(model, [x], conv_blocks(model))
        np.testing.assert_allclose(torch.softmax(model(x), 1).numpy(), want, atol=1e-5)
        eval_features = model[0](x)
        model.train()
        np.testing.assert_allclose(model[0](x).numpy(), eval_features.numpy(), rtol=1e-3, atol=1e-4)
    # a whole fine-tune from the export runs and keeps its shape
    tuned = train_labels(LabelTrainSpec(**spec, out=str(tmp_path / "b"), model=str(exported)), log=lambda _: None)
    assert read_checkpoint(tuned).widths == (8, 16)
    detector = Path(__file__).parents[3] / "poi" / "models" / "default_fp32.onnx"
    with pytest.raises(TrainError, match=r"default_fp32.onnx: not a label classifier"):
        read_checkpoint(detector)
