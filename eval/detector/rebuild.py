"""An Ultralytics checkpoint rebuilt from an exported YOLO ONNX model, to fine-tune from.

Ultralytics' ONNX export folds each BatchNorm into the convolution before it
and keeps the module names on the initializers (``model.0.conv.weight``,
``model.0.conv.bias``, ..., ``model.23.cv3.0.2.bias``). A ``DetectionModel``
built from the architecture's yaml (``yolo11n.yaml``, named in the model's
``description``) with those tensors copied back by name computes the same
function, once each convolution's BatchNorm is made to pass its input through
with the fused bias added.

A BatchNorm in eval mode computes

    y = gamma (x - mu) / sqrt(var + eps) + beta                      (1)

[Ioffe2015]_ eq. (1) with the running mean ``mu`` and variance ``var``. Any
``(mu, var)`` with ``gamma = sqrt(var + eps)`` and ``beta = mu + b`` gives
``y = x + b``: the fused function. Fine-tuning trains in train mode, where (1)
uses the batch's own statistics: with ``mu = 0, var = 1`` the first batches are
rescaled by their unit-less spread until the running statistics settle, and the
start point is lost. So ``mu`` and ``var`` are set to each channel's mean and
variance of the convolution's output over sample images (the model in eval
mode, which is the fused function, so the statistics are those of the shipped
model): training then starts at the shipped function and its batch statistics
agree with the running ones.

References
----------
Full entries in docs/SOURCES.md.

.. [Ioffe2015] S. Ioffe, C. Szegedy, "Batch Normalization: Accelerating Deep Network Training
   by Reducing Internal Covariate Shift", ICML 2015.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from eval.detector.quantize import QUANTIZED_METADATA_KEY

ARCH_PATTERN = re.compile(r"YOLO(\w+?)([nslmx])\b", re.IGNORECASE)  # "YOLO11n" in the description
STATS_IMAGES = 96  # sample images for the BatchNorm statistics (section above)


class RebuildError(ValueError):
    """An exported model cannot be rebuilt (one line, names the file and what was expected)."""


@dataclass(frozen=True)
class OnnxYolo:
    """What an exported YOLO model says of itself, and its weights by name."""

    path: Path
    arch_yaml: str  # e.g. "yolo11n.yaml"
    names: dict[int, str]
    imgsz: tuple[int, int]
    tensors: dict[str, np.ndarray]


def read_onnx(path: str | Path) -> OnnxYolo:
    """The architecture, class names, input size and named weights of an exported model."""
    import onnx
    from onnx import numpy_helper

    p = Path(path)
    if not p.exists():
        raise RebuildError(f"{p}: no such file")
    try:
        model = onnx.load(str(p))
    except Exception as e:  # onnx raises DecodeError and others for a file that is not a model
        raise RebuildError(f"{p}: not an ONNX model ({type(e).__name__})") from None
    meta = {m.key: m.value for m in model.metadata_props}
    missing = [k for k in ("description", "names", "imgsz") if k not in meta]
    if missing:
        raise RebuildError(
            f"{p}: metadata lacks {', '.join(missing)}; only a model exported by Ultralytics can be rebuilt"
        )
    if QUANTIZED_METADATA_KEY in meta:  # its weights are int8 with scales, not the trained floats
        raise RebuildError(
            f"{p}: an int8 model ({meta[QUANTIZED_METADATA_KEY]}); rebuild from the float export "
            "(the shipped one: poi/models/default_fp32.onnx)"
        )
    m = ARCH_PATTERN.search(meta["description"])
    if m is None:
        raise RebuildError(f"{p}: description {meta['description']!r} names no YOLO architecture (e.g. YOLO11n)")
    names = {int(k): str(v) for k, v in ast.literal_eval(meta["names"]).items()}
    imgsz = tuple(int(v) for v in ast.literal_eval(meta["imgsz"]))
    tensors = {t.name: numpy_helper.to_array(t) for t in model.graph.initializer if t.name.startswith("model.")}
    return OnnxYolo(
        path=p,
        arch_yaml=f"yolo{m.group(1).lower()}{m.group(2).lower()}.yaml",
        names=names,
        imgsz=(imgsz[0], imgsz[1]),
        tensors=tensors,
    )


def _conv_blocks(model) -> dict[str, tuple]:
    """Every convolution followed by a BatchNorm, by the module name the export keeps."""
    import torch.nn as nn

    blocks = {}
    for name, mod in model.named_modules():
        conv, bn = getattr(mod, "conv", None), getattr(mod, "bn", None)
        if isinstance(conv, nn.Conv2d) and isinstance(bn, nn.BatchNorm2d):
            blocks[name] = (conv, bn)
    return blocks


def load_fused_conv(conv, bn, weight: np.ndarray, bias: np.ndarray) -> None:
    """One convolution and its BatchNorm from the export's fused weight and bias: the weight into
    the convolution, the BatchNorm the identity plus the bias (mu = 0, var = 1, gamma = sqrt(1 +
    eps), beta = b; eq. (1)) until :func:`estimate_batchnorm` gives it statistics."""
    import torch

    with torch.no_grad():
        conv.weight.copy_(torch.from_numpy(np.array(weight, dtype=np.float32)))
        bn.running_mean.zero_()
        bn.running_var.fill_(1.0)
        bn.weight.fill_(float(np.sqrt(1.0 + bn.eps)))
        bn.bias.copy_(torch.from_numpy(np.array(bias, dtype=np.float32)))


def load_fused(model, tensors: dict[str, np.ndarray], where: Path) -> None:
    """Copy the fused weights into an unfused DetectionModel; every BatchNorm is the identity
    plus the fused bias (mu = 0, var = 1, gamma = sqrt(1 + eps), beta = b; eq. (1)).

    Every tensor of the export must land, and every weight of the model must be given."""
    import torch

    state = model.state_dict()
    blocks = _conv_blocks(model)
    given: set[str] = set()
    with torch.no_grad():
        for name, (conv, bn) in blocks.items():
            w, b = tensors.get(f"{name}.conv.weight"), tensors.get(f"{name}.conv.bias")
            if w is None or b is None:
                raise RebuildError(f"{where}: no fused weights for {name} (expected {name}.conv.weight and .bias)")
            if tuple(w.shape) != tuple(conv.weight.shape):
                raise RebuildError(
                    f"{where}: {name}.conv.weight is {tuple(w.shape)}, the architecture expects "
                    f"{tuple(conv.weight.shape)}"
                )
            load_fused_conv(conv, bn, w, b)
            given.update({f"{name}.conv.weight", f"{name}.conv.bias"})
        for key, value in tensors.items():
            if key in given:
                continue
            if key.endswith(".strides"):  # the head's stride per anchor, exported as a constant
                if set(np.unique(value).tolist()) != set(model.stride.tolist()):
                    raise RebuildError(f"{where}: strides {np.unique(value)} differ from the architecture's")
                continue
            if key not in state:
                raise RebuildError(f"{where}: tensor {key} has no place in the architecture")
            if tuple(value.shape) != tuple(state[key].shape):
                raise RebuildError(f"{where}: {key} is {tuple(value.shape)}, expected {tuple(state[key].shape)}")
            state[key].copy_(torch.from_numpy(value))
            given.add(key)
    fused_bn = {f"{n}.bn.{s}" for n in blocks for s in ("weight", "bias", "running_mean", "running_var")}
    learnt = {k for k, v in model.named_parameters()} | {
        k for k, v in model.named_buffers() if k.endswith(("running_mean", "running_var"))
    }
    left = sorted(k for k in learnt - fused_bn - given if not k.endswith(".dfl.conv.weight"))
    if left:
        raise RebuildError(f"{where}: the export gives no value for {len(left)} weights, e.g. {left[0]}")


def estimate_batchnorm(model, batches: Iterable, blocks: dict[str, tuple] | None = None) -> int:
    """Set each BatchNorm's running statistics to its input's per-channel mean and variance over
    ``batches`` (the model's input tensors, e.g. (B, 3, H, W) in [0, 1]) and keep the function (eq. (1):
    gamma = sqrt(var + eps), beta = mu + b). ``blocks`` names each (conv, BatchNorm) pair whose
    BatchNorm holds a fused bias (default: a DetectionModel's, by module name). Returns the number
    of inputs seen."""
    import torch

    blocks = _conv_blocks(model) if blocks is None else blocks
    sums: dict[str, list] = {}
    hooks = []
    for name, (_conv, bn) in blocks.items():

        def hook(_mod, args, _out, name=name):
            x = args[0].detach().double()  # (B, C, H, W)
            s = sums.setdefault(name, [0.0, 0.0, 0])
            s[0] = s[0] + x.sum(dim=(0, 2, 3))
            s[1] = s[1] + (x * x).sum(dim=(0, 2, 3))
            s[2] += x.shape[0] * x.shape[2] * x.shape[3]

        hooks.append(bn.register_forward_hook(hook))
    model.eval()
    seen = 0
    try:
        with torch.no_grad():
            for x in batches:
                model(x)
                seen += x.shape[0]
    finally:
        for h in hooks:
            h.remove()
    if not seen:
        raise RebuildError("no images to estimate the BatchNorm statistics from")
    with torch.no_grad():
        for name, (_conv, bn) in blocks.items():
            s1, s2, n = sums[name]
            # the BN's input is the bias-free conv(x); its bias b is the fused bias (load_fused)
            b = bn.bias.detach().double()
            mean = s1 / n
            var = (s2 / n - (s1 / n) ** 2).clamp_min(0.0)
            bn.running_mean.copy_(mean.float())
            bn.running_var.copy_(var.float())
            bn.weight.copy_(torch.sqrt(var + bn.eps).float())
            bn.bias.copy_((mean + b).float())
    return seen


def image_batches(images: list[Path], imgsz: tuple[int, int], batch: int = 16):
    """Letterboxed RGB batches of ``images`` as the pipeline feeds the model (poi.detectors)."""
    import cv2
    import torch

    from poi.detectors.onnx_yolo import letterbox

    for i in range(0, len(images), batch):
        xs = []
        for p in images[i : i + batch]:
            bgr = cv2.imread(str(p), cv2.IMREAD_COLOR)
            if bgr is None:
                raise RebuildError(f"{p}: not an image")
            img, _, _ = letterbox(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB), imgsz)
            xs.append(img.transpose(2, 0, 1))
        yield torch.from_numpy(np.stack(xs)).float() / 255.0


def rebuild(onnx_path: str | Path, images: list[Path]):
    """A DetectionModel computing what ``onnx_path`` computes, its BatchNorms estimated on
    ``images`` (section above). Returns (model, OnnxYolo)."""
    from ultralytics.nn.tasks import DetectionModel

    src = read_onnx(onnx_path)
    model = DetectionModel(src.arch_yaml, nc=len(src.names), verbose=False)
    model.names = dict(src.names)
    load_fused(model, src.tensors, src.path)
    estimate_batchnorm(model, image_batches(images[:STATS_IMAGES], src.imgsz))
    model.eval()
    return model, src


def save_checkpoint(model, src: OnnxYolo, out: str | Path) -> Path:
    """Write ``model`` as an Ultralytics checkpoint (what ``YOLO(path)`` and ``--model`` load)."""
    import copy
    from datetime import datetime, timezone

    import torch
    import ultralytics

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    m = copy.deepcopy(model).float()
    m.args = {"imgsz": src.imgsz[0], "task": "detect"}
    ckpt = {
        "date": datetime.fromtimestamp(0, tz=timezone.utc).isoformat(),  # fixed: same input, same bytes
        "version": ultralytics.__version__,
        "epoch": -1,
        "best_fitness": None,
        "model": m,
        "ema": None,
        "updates": None,
        "optimizer": None,
        "train_args": {"model": str(src.path), "imgsz": src.imgsz[0], "task": "detect"},
        "rebuilt_from": str(src.path),
    }
    torch.save(ckpt, out)
    return out
