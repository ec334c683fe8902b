"""An ONNX detector's input is bounded before anything is allocated: at most MAX_INPUT_PX a side
(declared, from metadata ``imgsz`` or from the ``imgsz`` setting) and float32 or float16, each
refused with one line naming the file and what was expected."""

from __future__ import annotations

import sys
from pathlib import Path

import onnx
import pytest
from onnx import TensorProto

sys.path.insert(0, str(Path(__file__).parent))

from onnx_models import make_constant_model, yolov8_output  # noqa: E402

from poi.detectors import DetectorConfigError, OnnxModelError, OnnxYoloDetector  # noqa: E402
from poi.detectors.onnx_yolo import MAX_INPUT_PX  # noqa: E402

META = {"names": "{0: 'oxidizer', 1: 'qr', 2: 'door'}", "task": "detect", "stride": "32"}
OUTPUT = yolov8_output([[10, 10, 4, 4]], [[0.9, 0.0, 0.0]], 8)


def _model(tmp_path, name="m.onnx", **kw) -> Path:
    return make_constant_model(tmp_path / name, OUTPUT, metadata=META | kw.pop("meta", {}), **kw)


def _one_line(info) -> str:
    text = str(info.value)
    assert "\n" not in text
    return text


def test_a_declared_input_larger_than_the_bound_is_refused_before_it_is_allocated(tmp_path):
    path = _model(tmp_path, input_hw=(20000, 20000))  # ran out of memory
    with pytest.raises(OnnxModelError) as info:
        OnnxYoloDetector(model=str(path))
    assert _one_line(info) == (
        f"{path}: input has shape [1, 3, 20000, 20000]; expected (1, 3, H, W) with H and W at most {MAX_INPUT_PX}"
    )
    OnnxYoloDetector(model=str(_model(tmp_path, "ok.onnx", input_hw=(MAX_INPUT_PX, 320))))  # at the bound


def test_a_metadata_or_setting_imgsz_larger_than_the_bound_is_refused(tmp_path):
    path = _model(tmp_path, input_hw=None, meta={"imgsz": "[100000, 100000]"})  # OpenCV asked for 22.5 GB
    with pytest.raises(DetectorConfigError) as info:
        OnnxYoloDetector(model=str(path))
    assert _one_line(info) == f"{path}: metadata imgsz: 100000x100000; expected at most {MAX_INPUT_PX} px a side"
    with pytest.raises(DetectorConfigError, match=r"imgsz: 640x5000; expected at most 4096 px a side"):
        OnnxYoloDetector(model=str(_model(tmp_path, "d.onnx", input_hw=None)), imgsz=[640, 5000])


def test_an_input_that_is_not_float_is_refused_by_name(tmp_path):
    path = _model(tmp_path)
    model = onnx.load(str(path))
    model.graph.input[0].type.tensor_type.elem_type = TensorProto.INT8  # the Cast after it takes any type
    onnx.save(model, str(path))
    with pytest.raises(OnnxModelError) as info:  # was onnxruntime's InvalidArgument traceback at the first frame
        OnnxYoloDetector(model=str(path))
    assert (
        _one_line(info)
        == f"{path}: input is tensor(int8); expected an image as tensor(float) or tensor(float16), 0..1"
    )
    OnnxYoloDetector(model=str(_model(tmp_path, "half.onnx", half=True)))  # float16 is taken
