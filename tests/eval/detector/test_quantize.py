"""eval/detector/quantize.py: poibench quantize-detector, and the int8 model it shipped."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import onnx
import pytest
from onnx import numpy_helper

from eval.cli.main import main
from eval.detector.quantize import QUANTIZED_METADATA_KEY, QuantizeError, calibration_images, float_nodes
from poi.core.types import Frame, Intrinsics
from poi.detectors import OnnxYoloDetector
from poi.models import DEFAULT_LABEL_MODEL, DEFAULT_MODEL

FLOAT_MODEL = DEFAULT_MODEL.with_name("default_fp32.onnx")


def _dataset(root: Path, n: int) -> Path:
    """A folder laid out as 'poibench dataset' writes one, of smooth random pictures."""
    rng = np.random.default_rng(0)
    (root / "images" / "train").mkdir(parents=True)
    for i in range(n):
        img = cv2.resize(
            rng.integers(0, 256, (6, 8, 3), dtype=np.uint8), (640, 480), interpolation=cv2.INTER_CUBIC
        )
        cv2.imwrite(str(root / "images" / "train" / f"s{i:04d}.jpg"), img)
    return root


def _ops(model: onnx.ModelProto) -> dict[str, str]:
    return {n.name: n.op_type for n in model.graph.node}


def test_the_shipped_detector_is_the_int8_copy_of_the_float_export():
    q, f = onnx.load(str(DEFAULT_MODEL)), onnx.load(str(FLOAT_MODEL))
    meta_q = {p.key: p.value for p in q.metadata_props}
    meta_f = {p.key: p.value for p in f.metadata_props}
    assert "default_fp32.onnx" in meta_q[QUANTIZED_METADATA_KEY]
    # names, input size, stride and the training seed carried over, so the detector reads it as before
    assert {k: v for k, v in meta_q.items() if k != QUANTIZED_METADATA_KEY} == meta_f
    ops = list(_ops(q).values())
    assert ops.count("QuantizeLinear") > 80 and "QuantizeLinear" not in _ops(f).values()
    # every Conv of the float model is there, and the head's decode reads float tensors
    names_f = [n.name for n in f.graph.node]
    assert {n for n in names_f if _ops(f)[n] == "Conv"} <= set(_ops(q))
    assert DEFAULT_MODEL.stat().st_size < FLOAT_MODEL.stat().st_size / 3


def _int8_weights(model: onnx.ModelProto) -> list[np.ndarray]:
    return [numpy_helper.to_array(t) for t in model.graph.initializer if t.data_type == onnx.TensorProto.INT8]


def _assert_weights_in_7_bits(model: onnx.ModelProto) -> None:
    """x86 CPUs without VNNI add two uint8 x int8 products in a saturating int16 (vpmaddubsw):
    255 * 127 * 2 = 64770 overflows 32767, 255 * 64 * 2 = 32640 does not. With every weight in
    [-64, 64] the integer sums are exact on every CPU, so the detector's boxes do not depend on it."""
    weights = _int8_weights(model)
    assert len(weights) > 80  # every quantised convolution's
    assert min(int(w.min()) for w in weights) >= -64 and max(int(w.max()) for w in weights) <= 64
    assert max(int(np.abs(w).max()) for w in weights) == 64  # the 7 bits are used, not fewer


def test_the_shipped_int8_weights_fit_in_7_bits_so_no_x86_cpu_saturates_their_products():
    _assert_weights_in_7_bits(onnx.load(str(DEFAULT_MODEL)))


def test_float_nodes_keep_the_head_decode_its_last_convolutions_and_the_matmuls():
    names = [n.name for n in onnx.load(str(FLOAT_MODEL)).graph.node]
    kept = set(float_nodes(names))
    assert "/model.23/dfl/Softmax" in kept and "/model.23/Concat_3" in kept
    assert {f"/model.23/cv{a}.{b}/cv{a}.{b}.2/Conv" for a in (2, 3) for b in range(3)} <= kept
    # the attention's q^T k product before its softmax; the softmax's weights times v is quantised
    assert "/model.10/m/m.0/attn/MatMul" in kept and "/model.10/m/m.0/attn/MatMul_1" not in kept
    # the backbone and the branches' inner convolutions are quantised
    assert "/model.0/conv/Conv" not in kept and "/model.23/cv3.0/cv3.0.1/cv3.0.1.1/conv/Conv" not in kept


def test_calibration_images_are_the_first_by_name_and_a_folder_without_images_is_refused(tmp_path):
    data = _dataset(tmp_path / "d", 3)
    assert [p.name for p in calibration_images(data, 2)] == ["s0000.jpg", "s0001.jpg"]
    with pytest.raises(QuantizeError, match="no images/ folder"):
        calibration_images(tmp_path, 2)
    (tmp_path / "e" / "images").mkdir(parents=True)
    with pytest.raises(QuantizeError, match="no .jpg or .png"):
        calibration_images(tmp_path / "e", 2)


def test_quantize_detector_writes_a_model_the_detector_runs_and_the_same_twice(tmp_path, capsys):
    data = _dataset(tmp_path / "d", 3)
    outs = [tmp_path / "a.onnx", tmp_path / "b.onnx"]
    for out in outs:
        args = ["quantize-detector", "--model", str(FLOAT_MODEL), "--data", str(data), "--images", "3"]
        assert main([*args, "--out", str(out)]) == 0
    assert "calibrated on 3 images" in capsys.readouterr().out
    assert outs[0].read_bytes() == outs[1].read_bytes()  # same images, same model, byte for byte
    _assert_weights_in_7_bits(onnx.load(str(outs[0])))
    det = OnnxYoloDetector(model=outs[0], label_model=DEFAULT_LABEL_MODEL)
    float_det = OnnxYoloDetector(model=FLOAT_MODEL, label_model=DEFAULT_LABEL_MODEL)
    assert det.input_hw == (320, 320) and det.model_names == float_det.model_names
    rgb = cv2.imread(str(calibration_images(data, 1)[0]))[:, :, ::-1].copy()
    intr = Intrinsics(width=640, height=480, fx=384.0, fy=384.0, ppx=320.0, ppy=240.0)
    det.detect(Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=intr))  # runs on onnxruntime's CPU provider


def test_a_file_that_is_not_a_model_and_an_out_over_the_model_are_refused(tmp_path, capsys):
    data = _dataset(tmp_path / "d", 1)
    fake = tmp_path / "fake.onnx"
    fake.write_bytes(b"not a protobuf \xff\x00" * 20)
    argv = ["quantize-detector", "--data", str(data)]
    assert main([*argv, "--model", str(fake), "--out", str(tmp_path / "q.onnx")]) == 2
    assert f"error: {fake}: not an ONNX model (" in capsys.readouterr().err
    copy = tmp_path / "float.onnx"
    copy.write_bytes(FLOAT_MODEL.read_bytes())
    assert main([*argv, "--model", str(copy), "--out", str(copy)]) == 2
    assert f"error: --out {copy}: it is (or is in) --model {copy}; give another name" in capsys.readouterr().err
    assert copy.read_bytes() == FLOAT_MODEL.read_bytes()


def test_an_already_quantised_model_is_refused(tmp_path, capsys):
    data = _dataset(tmp_path / "d", 1)
    code = main(
        [
            "quantize-detector",
            "--model",
            str(DEFAULT_MODEL),
            "--data",
            str(data),
            "--out",
            str(tmp_path / "q.onnx"),
        ]
    )
    assert code == 2 and "quantize-detector: error:" in capsys.readouterr().err
