"""poibench train's dataset preparation (the training itself needs the 'train' extra)."""

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from eval.detector.train import TrainError, TrainSpec, data_yaml, exported_checkpoint, placard_dataset
from poi.core.names import CLASS_INDEX, RESCUE_CLASSES


def _dataset(root, rows_by_file):
    for split in ("train", "val"):
        (root / "images" / split).mkdir(parents=True)
        (root / "labels" / split).mkdir(parents=True)
    for name, rows in rows_by_file.items():
        (root / "images" / "train" / f"{name}.png").write_bytes(b"png")
        (root / "labels" / "train" / f"{name}.txt").write_text("".join(r + "\n" for r in rows))
    (root / "images" / "val" / "v0.png").write_bytes(b"png")
    doc = {"path": str(root), "train": "images/train", "val": "images/val", "nc": 24}
    doc["names"] = dict(enumerate(RESCUE_CLASSES))
    (root / "data.yaml").write_text(yaml.safe_dump(doc))
    return data_yaml(root)


def test_one_placard_class_keeps_the_other_types_in_order(tmp_path):
    ox, door, qr = CLASS_INDEX["oxidizer"], CLASS_INDEX["door"], CLASS_INDEX["qr"]
    data = _dataset(
        tmp_path / "d",
        {"a": [f"{ox} 0.5 0.5 0.1 0.2", f"{door} 0.2 0.3 0.1 0.4"], "b": [f"{qr} 0.1 0.1 0.05 0.05"]},
    )
    out = placard_dataset(data, tmp_path / "run" / "data-placards")
    doc = yaml.safe_load(out.read_text())
    names = [doc["names"][k] for k in sorted(doc["names"])]
    assert names == ["hazmat", "qr", "door", "valve", "baby-doll", "fire-extinguisher", "exit-sign",
                     "fire-extinguisher-sign", "heat-source"]  # fmt: skip
    assert doc["nc"] == 9
    labels = out.parent / "labels" / "train"
    # oxidizer (a label) -> 0; door (index 17 of 24) -> 17 - 15 = 2; qr (16) -> 1
    assert (labels / "a.txt").read_text() == "0 0.5 0.5 0.1 0.2\n2 0.2 0.3 0.1 0.4\n"
    assert (labels / "b.txt").read_text() == "1 0.1 0.1 0.05 0.05\n"
    img = out.parent / "images" / "train" / "a.png"
    assert img.read_bytes() == b"png" and img.stat().st_nlink == 2  # hard-linked, not copied
    # no link Ultralytics could resolve back to the source folder and its 24-class labels
    assert not img.is_symlink() and not img.parent.is_symlink()
    placard_dataset(data, tmp_path / "run" / "data-placards")  # a rerun rewrites in place
    assert (labels / "a.txt").read_text().startswith("0 0.5")


def test_a_bad_label_line_names_its_file_and_line(tmp_path):
    data = _dataset(tmp_path / "d", {"a": ["3 0.5 0.5 0.1 0.1", "x 0.5 0.5 0.1 0.1"]})
    with pytest.raises(TrainError, match=r"a\.txt:2: class index 'x' is not an integer"):
        placard_dataset(data, tmp_path / "out")
    data = _dataset(tmp_path / "e", {"a": ["24 0.5 0.5 0.1 0.1"]})
    with pytest.raises(TrainError, match=r"a\.txt:1: class index 24 is not in 0\.\.23"):
        placard_dataset(data, tmp_path / "out2")
    data = _dataset(tmp_path / "f", {"a": ["3 0.5 0.5 0.1 0.1", "3 0.5 nan 0.1 0.1"]})
    with pytest.raises(TrainError, match=r"a\.txt:2: cy nan: expected a number in \[0, 1\]"):
        placard_dataset(data, tmp_path / "out3")
    data = _dataset(tmp_path / "g", {"a": ["3 0.5 0.5 0.1 wide"]})
    with pytest.raises(
        TrainError, match=r"a\.txt:1: expected 'class cx cy w h' with numbers, got '3 0.5 0.5 0.1 wide'"
    ):
        placard_dataset(data, tmp_path / "out4")


def test_hours_must_be_positive():
    with pytest.raises(TrainError, match="--hours must be above 0, got 0"):
        TrainSpec(data="d", out="o", hours=0)


def test_a_model_of_another_kind_and_a_device_that_is_not_one_are_refused(tmp_path):
    script = tmp_path / "detector.py"
    script.write_text("x = 1\n")
    with pytest.raises(
        TrainError, match=r"detector\.py: expected a YOLO checkpoint \(\.pt\), an exported detector"
    ):
        TrainSpec(data="d", out="o", model=str(script))
    with pytest.raises(TrainError, match="--device gpu: expected cpu or a CUDA device index"):
        TrainSpec(data="d", out="o", device="gpu")
    assert TrainSpec(data="d", out="o", device="0,1").device == "0,1"


def test_the_export_size_is_the_square_training_size_unless_given_and_strides_whole(capsys):
    assert TrainSpec(data="d", out="o", imgsz=416).export_size_hw == (416, 416)
    assert TrainSpec(data="d", out="o", imgsz=416, export_imgsz=(320, 416)).export_size_hw == (320, 416)
    with pytest.raises(TrainError, match="--export-imgsz must be two sides H W, each a positive multiple of 32"):
        TrainSpec(data="d", out="o", export_imgsz=(240, 320))
    from eval.cli.main import main

    assert main(["train", "--data", "d", "--out", "o", "--export-imgsz", "300", "416"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("got 300 416") and len(err.splitlines()) == 1


def test_placards_mode_is_checked():
    with pytest.raises(TrainError, match="--placards must be one of named, one, got 'some'"):
        TrainSpec(data="d", out="o", placards="some")


def test_two_datasets_train_as_one_with_the_second_ones_files_prefixed(tmp_path):
    from eval.detector.train import training_dataset

    ox, door = CLASS_INDEX["oxidizer"], CLASS_INDEX["door"]
    a = _dataset(tmp_path / "a", {"s0000_i000": [f"{ox} 0.5 0.5 0.1 0.2"]})
    b = _dataset(tmp_path / "b", {"s0000_i000": [f"{door} 0.2 0.3 0.1 0.4"]})  # the same image name
    out = training_dataset([a, b], tmp_path / "run" / "data-placards", placards="one")
    labels = out.parent / "labels" / "train"
    assert sorted(p.name for p in labels.iterdir()) == ["1-s0000_i000.txt", "s0000_i000.txt"]
    assert (labels / "s0000_i000.txt").read_text() == "0 0.5 0.5 0.1 0.2\n"
    assert (labels / "1-s0000_i000.txt").read_text() == "2 0.2 0.3 0.1 0.4\n"
    assert (out.parent / "images" / "train" / "1-s0000_i000.png").exists()
    named = training_dataset([a, b], tmp_path / "run" / "data-merged")
    assert (named.parent / "labels" / "train" / "1-s0000_i000.txt").read_text() == f"{door} 0.2 0.3 0.1 0.4\n"


def test_route_frames_folders_train_only_and_a_run_needs_validation_images(tmp_path):
    from eval.detector.route_frames import ROUTE_FRAMES_KEY
    from eval.detector.train import training_dataset

    ox = CLASS_INDEX["oxidizer"]
    mined = _dataset(tmp_path / "mined", {"m0": [f"{ox} 0.5 0.5 0.1 0.2"]})
    (tmp_path / "mined" / "dataset.yaml").write_text(yaml.safe_dump({ROUTE_FRAMES_KEY: {"mazes": 1}}))
    # a stray image in a route-frames folder's val split is not validation: it was mined
    data = _dataset(tmp_path / "data", {"s0": [f"{ox} 0.5 0.5 0.1 0.2"]})
    out = training_dataset([mined, data], tmp_path / "run" / "merged")
    assert sorted(p.name for p in (out.parent / "images" / "val").iterdir()) == ["1-v0.png"]
    assert sorted(p.name for p in (out.parent / "images" / "train").iterdir()) == ["1-s0.png", "m0.png"]
    with pytest.raises(TrainError, match=r"^no validation images in .*mined: 'poibench route-frames' folders"):
        training_dataset([mined], tmp_path / "run2" / "merged")
    (tmp_path / "data" / "images" / "val" / "v0.png").unlink()
    (tmp_path / "data" / "images" / "val").rmdir()
    with pytest.raises(TrainError, match=r"data/images/val: no such folder"):
        training_dataset([mined, data], tmp_path / "run3" / "merged")


def _photos(root, rows_by_name):
    (root / "images").mkdir(parents=True)
    (root / "labels").mkdir(parents=True)
    for name, rows in rows_by_name.items():
        cv2.imwrite(str(root / "images" / f"{name}.jpg"), np.full((40, 60, 3), 128, np.uint8))
        (root / "labels" / f"{name}.txt").write_text("".join(r + "\n" for r in rows))
    return root


def test_a_photo_folder_trains_on_all_but_its_held_back_runs(tmp_path):
    from eval.detector.label_data import read_holdout
    from eval.detector.train import photo_dataset

    ox = CLASS_INDEX["oxidizer"]
    names = ["img1", "img2", "img3", "img10", "img20", "img30", "img40", "img50", "img60", "img70"]
    root = _photos(tmp_path / "photos", {n: [f"{ox} 0.5 0.5 0.2 0.3"] for n in names})
    run = tmp_path / "run"
    run.mkdir()
    data = photo_dataset(root, run / "data-photos-0", 0.3, 0, run)
    assert data_yaml(data) == data  # poibench's 24 classes in order
    split = {s: sorted(p.stem for p in (data.parent / "images" / s).iterdir()) for s in ("train", "val")}
    held = read_holdout(run)[str(root.resolve())]
    assert sorted(held) == [f"{n}.jpg" for n in split["val"]]
    assert sorted(split["train"] + split["val"]) == sorted(names)
    # img1-3 are one scene: all on one side; about 0.3 of 10 held back
    assert len({"img1", "img2", "img3"} & set(split["val"])) in (0, 3) and len(split["val"]) >= 3
    assert (data.parent / "labels" / "val" / f"{split['val'][0]}.txt").read_text() == f"{ox} 0.5 0.5 0.2 0.3\n"
    assert (data.parent / "images" / "train" / f"{split['train'][0]}.jpg").stat().st_nlink == 2


def test_a_photo_folder_needs_a_holdout_and_valid_labels(tmp_path):
    from eval.detector.train import train

    root = _photos(tmp_path / "photos", {"a1": ["3 0.5 0.5 0.1 0.1"], "b5": ["3 0.5 0.5 0.1"], "c9": []})
    with pytest.raises(TrainError, match="is a folder of photos .*give --holdout"):
        train(TrainSpec(data=str(root), out=str(tmp_path / "run")))
    with pytest.raises(TrainError, match=r"b5\.txt:1: expected 'class cx cy w h'"):
        train(TrainSpec(data=str(root), out=str(tmp_path / "run"), holdout=0.5))
    with pytest.raises(TrainError, match="--holdout is for a folder of photos"):
        rendered = _dataset(tmp_path / "d", {"a": ["3 0.5 0.5 0.1 0.1"]}).parent
        train(TrainSpec(data=str(rendered), out=str(tmp_path / "run2"), holdout=0.5))


def test_the_export_is_made_from_last_pt_when_held_back_photos_validate():
    """Held-back photos as the validation split would flatter the checkpoint chosen on them: the
    run exports (and names, for poi/models/default.pt) last.pt then, best.pt otherwise."""
    assert exported_checkpoint(TrainSpec(data="d", out="o")) == Path("o/weights/best.pt")
    assert exported_checkpoint(TrainSpec(data="d", out="o", holdout=0.2)) == Path("o/weights/last.pt")


def test_export_detector_without_the_train_extra_says_what_to_install(tmp_path, capsys):
    import importlib.util

    from eval.cli.main import main

    if importlib.util.find_spec("ultralytics") is not None:
        pytest.skip("the train extra is installed here")
    model = Path(__file__).resolve().parents[3] / "poi" / "models" / "default.pt"
    argv = ["export-detector", "--model", str(model), "--imgsz", "288", "384", "--out", str(tmp_path / "x")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "need the 'train' extra" in err and "pip install -e '.[train]'" in err
    assert not (tmp_path / "x").exists()


def test_export_detector_refuses_what_it_cannot_export_before_writing(tmp_path, capsys):
    """An input off the stride, an export given for its checkpoint, or --out over the export whose
    stamps it copies: one line each, nothing written (no train extra needed to say so)."""
    from eval.cli.main import main

    ckpt = tmp_path / "m.pt"
    ckpt.write_bytes(b"a checkpoint")
    (tmp_path / "m.onnx").write_bytes(b"its export")
    cases = [
        (
            ["--model", str(ckpt), "--imgsz", "300", "400", "--out", str(tmp_path / "y")],
            "--imgsz must be two sides H W",
        ),
        (
            ["--model", str(tmp_path / "m.onnx"), "--imgsz", "288", "384", "--out", str(tmp_path / "y")],
            "an export; give",
        ),
        (
            ["--model", str(ckpt), "--imgsz", "288", "384", "--out", str(tmp_path / "m.onnx")],
            "whose stamps it copies",
        ),
    ]
    for argv, said in cases:
        assert main(["export-detector", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert said in err and len(err.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.onnx", "m.pt"]
    assert (tmp_path / "m.onnx").read_bytes() == b"its export"


def test_a_stamped_export_is_written_whole_or_not_at_all(tmp_path, monkeypatch):
    """A write that fails half way (a full disk, a kill) leaves no model.onnx, which a resumed run
    would take for its finished export, and no partial file."""
    import onnx
    from onnx import TensorProto, helper

    from eval.detector.train import _stamp_metadata

    graph = helper.make_graph(
        [helper.make_node("Relu", ["x"], ["y"])],
        "g",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1])],
    )
    src = tmp_path / "export.onnx"
    onnx.save(helper.make_model(graph), str(src))
    _stamp_metadata(src, tmp_path / "model.onnx", [], ["/photos"])
    meta = {p.key: p.value for p in onnx.load(str(tmp_path / "model.onnx")).metadata_props}
    assert meta["poibench_photo_folders"] == "/photos"
    (tmp_path / "model.onnx").unlink()

    def half_a_save(model, path):
        Path(path).write_bytes(model.SerializeToString()[:10])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(onnx, "save", half_a_save)
    with pytest.raises(OSError, match="No space left"):
        _stamp_metadata(src, tmp_path / "model.onnx", [], [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["export.onnx"]
