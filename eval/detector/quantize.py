"""``poibench quantize-detector``: an int8 YOLO detector made by onnxruntime's own quantiser.

Static quantisation in the QDQ format ([ORTQuant]_): every tensor a quantised node reads
or writes is stored as 8 bits, ``x = s (q - z)``, with ``s`` and ``z`` chosen so the range
the calibration images produced, [min, max], maps onto [0, 255] (activations, uint8,
asymmetric; ``CalibrationMethod.MinMax``), and each convolution's weights per output
channel onto [-64, 64] (int8, symmetric, 7 bits: ``reduce_range``). onnxruntime then fuses each
DequantizeLinear -> op -> QuantizeLinear group into its integer kernel (``QLinearConv``,
``QLinearMul``, ``QLinearSigmoid``, ...), which on a CPU with AVX-512 VNNI runs the
shipped YOLO11n at 320 px in 11 ms of CPU instead of 20 under the same load (issue 62).

Why 7 bits: x86 CPUs without VNNI (AVX2, and AVX-512 before Cascade Lake) multiply uint8
activations by int8 weights with ``vpmaddubsw``, which adds each pair of products in a
saturating int16 ([OneDNNInt8]_, [ORTQuant]_ FAQ): 255 * 127 * 2 = 64770 overflows 32767,
255 * 64 * 2 = 32640 does not. With full 8-bit weights the shipped model's outputs depended
on the CPU: on 24 frames of the default tour, an AVX-512 VNNI machine and the same
onnxruntime under an emulated AVX2 CPU (``qemu-x86_64 -cpu Haswell``) disagreed on 22 of the
127 anchors scoring 0.4 or more (one anchor 0.011 against 0.445); with 7-bit weights the two
gave the same outputs bit for bit, at 13 rather than 9 anchors of 132 crossing 0.4 away
from the float model.

What stays float, because one 8-bit scale cannot hold it:

* the detect head's decode (the DFL softmax and the box arithmetic after it, every node of
  the head's module whose name is not one of its ``cv2``/``cv3`` branches): its output
  concatenates box coordinates in pixels (0-320) and class probabilities (0-1);
* the last convolution of each ``cv2``/``cv3`` branch (box distributions and class logits:
  a logit's rounding step would move a score near the confidence threshold);
* the attention block's (C2PSA's) first MatMul, q^T k, whose products span several decades
  before the softmax (the second, the softmax's weights times v, is quantised).

The calibration images are a ``poibench dataset`` folder's images (letterboxed as the
detector does: :func:`poi.detectors.onnx_yolo.letterbox`), in name order, at most
``images`` of them; the same folder and count give the same model, byte for byte. The model
keeps its metadata (class names, input size, stride) and records how it was made under
``QUANTIZED_METADATA_KEY``.

References
----------
Full entries in docs/SOURCES.md.

.. [ORTQuant] ONNX Runtime, "Quantize ONNX models" (onnxruntime.ai/docs/performance/
   model-optimizations/quantization.html).
.. [OneDNNInt8] oneDNN Developer Guide, "Nuances of int8 computations" (the int16
   saturation of u8 x s8 products on CPUs without VNNI).
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import cv2
import numpy as np

from poi.detectors.onnx_yolo import letterbox

QUANTIZED_METADATA_KEY = "poibench_quantized"
CALIBRATION_IMAGES = 120  # about a minute of calibration; 60 gave the same mAP50 within 0.003
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")


class QuantizeError(ValueError):
    """A model or calibration folder that cannot be quantised (one line)."""


def calibration_images(data: str | Path, limit: int) -> list[Path]:
    """The first ``limit`` images (by path) under ``data``/images, any split."""
    root = Path(data) / "images"
    if not root.is_dir():
        raise QuantizeError(f"{data}: no images/ folder; expected a 'poibench dataset' folder")
    files = sorted(p for p in root.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
    if not files:
        raise QuantizeError(f"{root}: no .jpg or .png images to calibrate with")
    if limit < 1:
        raise QuantizeError(f"--images must be at least 1, got {limit}")
    return files[:limit]


def head_module(node_names: list[str]) -> str:
    """The detect head's module prefix, e.g. ``/model.23/``: the module holding the ``dfl``.

    >>> head_module(["/model.0/conv/Conv", "/model.23/dfl/Softmax", "/model.23/Concat_3"])
    '/model.23/'
    """
    for name in node_names:
        m = re.match(r"(/model\.\d+/)dfl/", name)
        if m:
            return m.group(1)
    raise QuantizeError("no detect head with a DFL (/model.N/dfl/...): not an Ultralytics YOLOv8/11 export")


def float_nodes(node_names: list[str]) -> list[str]:
    """The nodes kept in float (module docstring): the head's decode, the last convolution of
    each ``cv2``/``cv3`` branch and the attention's q^T k MatMul (named ``.../attn/MatMul``).

    >>> float_nodes(["/model.23/cv3.0/cv3.0.2/Conv", "/model.23/cv3.0/cv3.0.1/conv/Conv",
    ...              "/model.23/dfl/Softmax", "/model.23/Sigmoid", "/model.10/m/m.0/attn/MatMul",
    ...              "/model.10/m/m.0/attn/MatMul_1"])
    ['/model.23/cv3.0/cv3.0.2/Conv', '/model.23/dfl/Softmax', '/model.23/Sigmoid', '/model.10/m/m.0/attn/MatMul']
    """
    head = head_module(node_names)
    last_conv = re.compile(re.escape(head) + r"cv[23]\.\d+/cv[23]\.\d+\.2/")
    out = []
    for name in node_names:
        in_head = name.startswith(head)
        decode = in_head and not re.match(re.escape(head) + r"cv[23]\.", name)
        if decode or last_conv.match(name) or name.endswith("/attn/MatMul"):
            out.append(name)
    return out


def _input_array(path: Path, size_hw: tuple[int, int]) -> np.ndarray:
    """(1, 3, H, W) float32 in [0, 1]: the image letterboxed as the detector feeds it."""
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise QuantizeError(f"{path}: not a readable image")
    img, _, _ = letterbox(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), size_hw)  # (H, W, 3)
    return np.ascontiguousarray(img.transpose(2, 0, 1)[None], dtype=np.float32) / np.float32(255.0)


def quantize_detector(
    model: str | Path, data: str | Path, out: str | Path, images: int = CALIBRATION_IMAGES
) -> dict:
    """Write the int8 QDQ model of the float YOLO export ``model`` to ``out``, calibrated on
    ``data``'s images; returns what was done (for the CLI to print)."""
    import onnx
    from onnxruntime.quantization import (
        CalibrationDataReader,
        CalibrationMethod,
        QuantFormat,
        QuantType,
        quant_pre_process,
        quantize_static,
    )

    from poi.detectors.base import check_model_file

    model, out = Path(model), Path(out)
    check_model_file(model, QuantizeError)
    files = calibration_images(data, images)
    try:
        src = onnx.load(str(model))
    except Exception as e:  # protobuf's DecodeError, and others, for a file that is not a model
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise QuantizeError(f"{model}: not an ONNX model ({reason[:150]})") from None
    inputs = [i for i in src.graph.input if i.name not in {t.name for t in src.graph.initializer}]
    if len(inputs) != 1:
        raise QuantizeError(f"{model}: expected one input image, found {len(inputs)} inputs")
    dims = [d.dim_value for d in inputs[0].type.tensor_type.shape.dim]
    if len(dims) != 4 or dims[2] <= 0 or dims[3] <= 0:
        raise QuantizeError(f"{model}: input shape {dims}; expected a fixed (1, 3, H, W)")
    if inputs[0].type.tensor_type.elem_type != onnx.TensorProto.FLOAT:
        raise QuantizeError(f"{model}: the input is not float32 (a float16 export?)")
    if any(n.op_type in ("QuantizeLinear", "DequantizeLinear") for n in src.graph.node):
        raise QuantizeError(f"{model}: already quantised (it has QuantizeLinear nodes); give the float export")
    size_hw = (dims[2], dims[3])
    name = inputs[0].name

    class Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self._files = iter(files)

        def get_next(self) -> dict[str, np.ndarray] | None:
            f = next(self._files, None)
            return None if f is None else {name: _input_array(f, size_hw)}

    with tempfile.TemporaryDirectory() as tmp:
        pre = Path(tmp) / "pre.onnx"
        # shape inference and constant folding before quantisation, as onnxruntime advises
        quant_pre_process(str(model), str(pre), skip_symbolic_shape=True)
        keep_float = float_nodes([n.name for n in onnx.load(str(pre)).graph.node])
        quantize_static(
            str(pre),
            str(Path(tmp) / "q.onnx"),
            Reader(),
            quant_format=QuantFormat.QDQ,
            per_channel=True,
            activation_type=QuantType.QUInt8,
            weight_type=QuantType.QInt8,
            nodes_to_exclude=keep_float,
            calibrate_method=CalibrationMethod.MinMax,
            reduce_range=True,  # 7-bit weights: the same integers on every x86 CPU (module docstring)
            extra_options={"ActivationSymmetric": False, "WeightSymmetric": True},
        )
        q = onnx.load(str(Path(tmp) / "q.onnx"))
    how = (
        f"int8 QDQ (onnxruntime static, MinMax) of {model.name}, "
        f"calibrated on {len(files)} images of {Path(data).name}"
    )
    meta = {p.key: p.value for p in src.metadata_props}
    meta[QUANTIZED_METADATA_KEY] = how
    del q.metadata_props[:]
    for k, v in meta.items():
        q.metadata_props.add(key=k, value=v)
    out.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(q, str(out))
    return {
        "out": str(out),
        "bytes": out.stat().st_size,
        "calibration_images": len(files),
        "float_nodes": len(keep_float),
        "how": how,
    }
