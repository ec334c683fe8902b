"""The hazmat label classifier's network and the checkpoints a ``train-labels --model`` run starts from.

The network (:func:`build_model`) is the one :mod:`eval.detector.train_labels` describes:
stages of 3x3 convolution, BatchNorm, ReLU and 2x2 max pooling, then a linear layer.
A run starts from either

- a ``label_model.pt`` (the weights, crop size, widths, classes and dataset seeds a
  finished run writes) or a run's ``last.pt``; or
- a float ``label_model.onnx``, such as the shipped ``poi/models/default_labels.onnx``.
  The export folds each BatchNorm into its convolution, so the graph holds one weight
  and one bias a convolution and the linear layer's weight and bias; the widths are the
  convolutions' output channels and the crop size is the metadata's ``imgsz``. Each
  convolution gets the fused weight, its BatchNorm the identity plus the fused bias, and
  before training the BatchNorms' statistics are estimated on training crops so that
  training starts at the exported function (:mod:`eval.detector.rebuild`, eq. (1)).
"""

from __future__ import annotations

import ast
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from eval.detector.quality import SEEDS_METADATA_KEY
from eval.detector.quantize import QUANTIZED_METADATA_KEY
from eval.detector.rebuild import load_fused_conv
from eval.detector.train import TrainError
from poi.detectors.hazmat_labels import LABEL_CLASSES, TASK

CHECKPOINT_NAME = "label_model.pt"


def torch_or_error():
    """torch, or a one-line TrainError naming the extra that installs it."""
    try:
        import torch
    except ImportError:
        raise TrainError(
            "poibench train-labels needs the 'train' extra (torch): pip install -e '.[train]' "
            "in its own environment (see the README)"
        ) from None
    return torch


def build_model(widths: Sequence[int], imgsz: int, n_classes: int):
    """The classifier network of :mod:`eval.detector.train_labels` (the export adds the softmax)."""
    nn = torch_or_error().nn
    layers: list = []
    c_in = 3
    for c in widths:
        layers += [nn.Conv2d(c_in, c, 3, padding=1, bias=False), nn.BatchNorm2d(c), nn.ReLU(inplace=True)]
        layers += [nn.MaxPool2d(2)]
        c_in = c
    side = imgsz // 2 ** len(widths)
    features = nn.Sequential(*layers)
    head = nn.Sequential(nn.Flatten(), nn.Dropout(0.2), nn.Linear(c_in * side * side, n_classes))
    return nn.Sequential(features, head)


def conv_blocks(model) -> dict[str, tuple]:
    """Each (convolution, BatchNorm) pair of :func:`build_model`'s network, by stage."""
    nn = torch_or_error().nn
    mods = list(model[0])
    pairs = [(m, n) for m, n in zip(mods, mods[1:], strict=False) if isinstance(m, nn.Conv2d)]
    return {f"stage{i}": pair for i, pair in enumerate(pairs)}


@dataclass(frozen=True)
class LabelCheckpoint:
    """A trained classifier's weights and what they need: crop size, widths and the seeds of
    the rendered data they were trained on. ``fused``: read from an ONNX export, its BatchNorms
    still to be estimated on training crops (module docstring)."""

    path: Path
    state: dict
    imgsz: int
    widths: tuple[int, ...]
    seeds: tuple[int, ...]
    fused: bool = False


def read_checkpoint(path: str | Path) -> LabelCheckpoint:
    """A ``label_model.pt``, a run's ``last.pt`` or a float ``label_model.onnx``, checked to be
    a classifier of today's classes; every failure is one TrainError line naming the file."""
    torch = torch_or_error()
    p = Path(path)
    if not p.is_file():
        raise TrainError(
            f"{p}: no such checkpoint; give a train-labels run's label_model.pt or last.pt, or a label_model.onnx"
        )
    if p.suffix.lower() == ".onnx":
        return _read_onnx(p)
    try:
        ck = torch.load(p, weights_only=True, map_location="cpu")
    except Exception as exc:  # a pickle of something else, a truncated file
        raise TrainError(f"{p}: not a train-labels checkpoint ({type(exc).__name__})") from None
    if not isinstance(ck, dict) or not {"model", "imgsz", "widths"} <= ck.keys():
        raise TrainError(f"{p}: not a train-labels checkpoint (expected the keys model, imgsz and widths)")
    _check_classes(p, list(ck.get("classes", LABEL_CLASSES)))
    return LabelCheckpoint(
        path=p,
        state=ck["model"],
        imgsz=int(ck["imgsz"]),
        widths=tuple(int(w) for w in ck["widths"]),
        seeds=tuple(int(s) for s in ck.get("seeds", ())),
    )


def _check_classes(p: Path, classes: list[str]) -> None:
    if classes != list(LABEL_CLASSES):
        raise TrainError(f"{p}: its {len(classes)} classes are not the label classifier's {len(LABEL_CLASSES)}")


def _read_onnx(p: Path) -> LabelCheckpoint:
    """The weights of a float label classifier export (module docstring)."""
    import onnx
    from onnx import numpy_helper

    try:
        m = onnx.load(str(p))
    except Exception as exc:
        raise TrainError(f"{p}: not an ONNX model ({type(exc).__name__})") from None
    meta = {q.key: q.value for q in m.metadata_props}
    if meta.get("task") != TASK:
        raise TrainError(f"{p}: not a label classifier (metadata task {meta.get('task')!r}, expected {TASK!r})")
    if QUANTIZED_METADATA_KEY in meta:
        raise TrainError(f"{p}: an int8 model; fine-tune from the float export")
    try:
        names = ast.literal_eval(meta["names"])
        imgsz = int(meta["imgsz"])
    except (KeyError, ValueError, SyntaxError):
        raise TrainError(f"{p}: metadata lacks readable names and imgsz") from None
    _check_classes(p, [names[i] for i in sorted(names)])
    tensors = {t.name: numpy_helper.to_array(t) for t in m.graph.initializer}
    convs = [n for n in m.graph.node if n.op_type == "Conv"]
    gemms = [n for n in m.graph.node if n.op_type == "Gemm"]
    fused = all(len(n.input) == 3 and n.input[1] in tensors and n.input[2] in tensors for n in convs)
    if not convs or len(gemms) != 1 or not fused or not {*gemms[0].input[1:3]} <= tensors.keys():
        raise TrainError(
            f"{p}: expected convolutions with fused weights and biases and one linear layer "
            f"(found {len(convs)} Conv and {len(gemms)} Gemm nodes)"
        )
    widths = tuple(int(tensors[n.input[1]].shape[0]) for n in convs)
    model = build_model(widths, imgsz, len(LABEL_CLASSES))
    linear = model[1][2]
    w, b = tensors[gemms[0].input[1]], tensors[gemms[0].input[2]]
    if not any(a.name == "transB" and a.i == 1 for a in gemms[0].attribute):
        w = w.T
    if tuple(w.shape) != tuple(linear.weight.shape):
        raise TrainError(
            f"{p}: its linear layer is {tuple(w.shape)}, widths {widths} at {imgsz} px give "
            f"{tuple(linear.weight.shape)}"
        )
    torch = torch_or_error()
    blocks = list(conv_blocks(model).values())
    for node, (conv, bn) in zip(convs, blocks, strict=True):
        cw = tensors[node.input[1]]
        if tuple(cw.shape) != tuple(conv.weight.shape):
            raise TrainError(
                f"{p}: convolution {node.name} is {tuple(cw.shape)}, expected {tuple(conv.weight.shape)}"
            )
        load_fused_conv(conv, bn, cw, tensors[node.input[2]])
    with torch.no_grad():
        linear.weight.copy_(torch.from_numpy(w.copy()))
        linear.bias.copy_(torch.from_numpy(b.copy()))
    seeds = tuple(int(s) for s in meta.get(SEEDS_METADATA_KEY, "").split(",") if s.strip())
    return LabelCheckpoint(path=p, state=model.state_dict(), imgsz=imgsz, widths=widths, seeds=seeds, fused=True)
