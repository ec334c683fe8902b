"""The checkpoint rebuilt from the shipped ONNX computes what onnxruntime computes."""

from pathlib import Path

import numpy as np
import pytest

from eval.detector.rebuild import RebuildError, read_onnx
from eval.detector.train import TrainError, TrainSpec

SHIPPED = (
    Path(__file__).resolve().parents[3] / "poi" / "models" / "default_fp32.onnx"
)  # the float export default.onnx is quantised from


def test_the_shipped_model_names_its_architecture_classes_and_size():
    src = read_onnx(SHIPPED)
    assert src.arch_yaml == "yolo11n.yaml"
    assert src.imgsz == (320, 320)
    assert src.names[0] == "hazmat" and len(src.names) == 9
    # 88 convolutions, each a fused weight and bias, plus the head's strides
    assert sum(k.endswith(".weight") for k in src.tensors) == 88


def test_a_model_without_ultralytics_metadata_is_refused(tmp_path):
    onnx = pytest.importorskip("onnx")
    from onnx import TensorProto, helper

    graph = helper.make_graph(
        [helper.make_node("Relu", ["x"], ["y"])],
        "g",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1])],
    )
    path = tmp_path / "relu.onnx"
    onnx.save(helper.make_model(graph), str(path))
    with pytest.raises(RebuildError, match=r"relu\.onnx: metadata lacks description, names, imgsz"):
        read_onnx(path)
    (tmp_path / "junk.onnx").write_bytes(b"not a model")
    with pytest.raises(RebuildError, match=r"junk\.onnx: not an ONNX model"):
        read_onnx(tmp_path / "junk.onnx")


def test_fine_tuning_needs_the_checkpoint_and_a_sane_rate(tmp_path):
    with pytest.raises(TrainError, match=r"--model .*missing\.onnx: no such file"):
        TrainSpec(data="d", out="o", model=str(tmp_path / "missing.onnx"))
    with pytest.raises(TrainError, match=r"--lr0 must be in \(0, 1\), got 0"):
        TrainSpec(data="d", out="o", lr0=0)
    assert TrainSpec(data="d", out="o", model=str(SHIPPED)).fine_tune
    assert not TrainSpec(data="d", out="o").fine_tune


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """Eight rendered training images (poibench dataset), the frames the models are fed."""
    from eval.detector.dataset import DatasetSpec, write_dataset

    out = tmp_path_factory.mktemp("ds")
    write_dataset(DatasetSpec(images=8, seed=5, images_per_scenario=8), out)
    return sorted((out / "images" / "train").glob("*.jpg"))


@pytest.mark.slow
@pytest.mark.train
def test_the_rebuilt_model_boxes_as_onnxruntime_does(rendered, tmp_path):
    torch = pytest.importorskip("torch")
    pytest.importorskip("ultralytics")
    import onnxruntime as ort

    from eval.detector.rebuild import image_batches, rebuild, save_checkpoint

    model, src = rebuild(SHIPPED, rendered)
    x = next(image_batches(rendered, src.imgsz, batch=len(rendered)))  # (8, 3, 320, 320)
    session = ort.InferenceSession(str(SHIPPED), providers=["CPUExecutionProvider"])
    want = np.concatenate([session.run(None, {"images": x[i : i + 1].numpy()})[0] for i in range(len(x))])
    with torch.no_grad():
        got = model(x)[0].numpy()  # (8, 4 + 9, 2100): box centre and size in px, class scores
    assert got.shape == want.shape
    assert np.abs(got[:, :4] - want[:, :4]).max() < 1e-2  # px
    assert np.abs(got[:, 4:] - want[:, 4:]).max() < 1e-4
    # the BatchNorms carry the images' statistics, not the identity: training starts from there
    bn = model.model[0].bn
    assert not torch.allclose(bn.running_var, torch.ones_like(bn.running_var))
    # and Ultralytics loads the checkpoint as the same function
    from ultralytics import YOLO

    path = save_checkpoint(model, src, tmp_path / "rebuilt.pt")
    reloaded = YOLO(str(path)).model.eval()
    with torch.no_grad():
        again = reloaded(x)[0].numpy()
    assert np.abs(again[:, :4] - want[:, :4]).max() < 1e-2
    assert YOLO(str(path)).names == src.names


def test_the_int8_model_is_refused_naming_the_float_export():
    # default.onnx is quantised (eval/detector/quantize.py): its weights cannot be copied back
    with pytest.raises(RebuildError, match=r"default\.onnx: an int8 model .*poi/models/default_fp32\.onnx"):
        read_onnx(SHIPPED.with_name("default.onnx"))


@pytest.mark.slow
@pytest.mark.train
def test_poibench_train_fine_tunes_the_shipped_onnx_from_its_own_function(tmp_path):
    """`poibench train --model default_fp32.onnx`, end to end: it rebuilds the checkpoint, trains an
    epoch at a rate too small to move a weight, and exports at --export-imgsz, with the shipped
    class names, a model that boxes what the shipped one does (one trained from scratch the same
    way misplaces those boxes by 95-143 px and its scores by 0.87-0.96)."""
    pytest.importorskip("torch")
    pytest.importorskip("ultralytics")
    import onnxruntime as ort

    from eval.cli.main import main
    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.detector.quality import model_metadata
    from eval.detector.rebuild import image_batches

    data = tmp_path / "ds"
    write_dataset(DatasetSpec(images=8, seed=5, images_per_scenario=2, val_every=2), data)
    run = tmp_path / "run"
    argv = ["train", "--data", str(data), "--out", str(run), "--model", str(SHIPPED), "--placards", "one"]
    argv += ["--epochs", "1", "--imgsz", "64", "--export-imgsz", "320", "320", "--lr0", "1e-12"]
    assert main(argv + ["--batch", "64", "--workers", "0", "--threads", "1"]) == 0
    assert (run / "rebuilt.pt").is_file() and (run / "weights" / "best.pt").is_file()
    tuned = run / "model.onnx"
    assert model_metadata(tuned)["names"] == model_metadata(SHIPPED)["names"]
    images = sorted((data / "images" / "val").glob("*.jpg"))
    x = next(image_batches(images, (320, 320), batch=len(images))).numpy()

    def outputs(path: Path) -> np.ndarray:
        session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        return np.concatenate([session.run(None, {"images": x[i : i + 1]})[0] for i in range(len(x))])

    want, got = outputs(SHIPPED), outputs(tuned)
    assert got.shape == want.shape  # (4, 4 + 9, 2100) at 320 x 320
    sure = want[:, 4:].max(axis=1) > 0.4  # (4, 2100): the anchors the pipeline would keep
    assert sure.sum() >= 10
    # the epoch moves the BatchNorms' running statistics a little (towards 64 px images), no weight
    assert np.abs(got[:, :4] - want[:, :4]).transpose(0, 2, 1)[sure].max() < 1.5  # px
    assert np.abs(got[:, 4:] - want[:, 4:]).max() < 0.15


@pytest.mark.train
def test_export_detector_gives_the_shipped_float_model_from_the_shipped_checkpoint(tmp_path, capsys):
    """`poibench export-detector` of default.pt at the shipped float model's input computes what
    default_fp32.onnx computes, with its training stamps (copied from the export beside the
    checkpoint, which stays as it was: Ultralytics would have written its export there)."""
    pytest.importorskip("torch")
    pytest.importorskip("ultralytics")
    import shutil

    import onnxruntime as ort

    from eval.cli.main import main
    from eval.detector.quality import model_metadata

    ckpt = tmp_path / "default.pt"
    shutil.copyfile(SHIPPED.with_name("default.pt"), ckpt)
    shutil.copyfile(SHIPPED.with_name("default.onnx"), tmp_path / "default.onnx")
    beside = (tmp_path / "default.onnx").read_bytes()
    h, w = read_onnx(SHIPPED).imgsz
    out = tmp_path / "out" / "x.onnx"
    assert main(["export-detector", "--model", str(ckpt), "--imgsz", str(h), str(w), "--out", str(out)]) == 0
    assert (tmp_path / "default.onnx").read_bytes() == beside and sorted(p.name for p in tmp_path.iterdir()) == [
        "default.onnx",
        "default.pt",
        "out",
    ]
    shipped, got = model_metadata(SHIPPED), model_metadata(out)
    for key in ("names", "imgsz", "poibench_dataset_seeds", "poibench_photo_folders"):
        assert got[key] == shipped[key], key
    x = np.random.default_rng(0).random((1, 3, h, w), dtype=np.float32)

    def run(path: Path) -> np.ndarray:
        return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).run(None, {"images": x})[0]

    assert np.abs(run(out) - run(SHIPPED)).max() < 1e-3
    # H x W in that order: a 4:3 input
    wide = tmp_path / "wide.onnx"
    assert main(["export-detector", "--model", str(ckpt), "--imgsz", "288", "384", "--out", str(wide)]) == 0
    session = ort.InferenceSession(str(wide), providers=["CPUExecutionProvider"])
    assert session.get_inputs()[0].shape == [1, 3, 288, 384] and model_metadata(wide)["imgsz"] == "[288, 384]"
    # a checkpoint that is not a YOLO detector's (the label classifier's) is one line
    labels = ["export-detector", "--model", str(SHIPPED.with_name("default_labels.pt")), "--imgsz", "320", "320"]
    capsys.readouterr()
    assert main([*labels, "--out", str(tmp_path / "z.onnx")]) == 2
    err = capsys.readouterr().err.strip()
    assert "default_labels.pt: not a loadable YOLO model" in err and len(err.splitlines()) == 1
