"""Box-for-box parity of poibench's ONNX detector with Ultralytics' own ``predict``.

For YOLO11n and YOLO26n (built from their ``.yaml``, random init, a short warm-up
training on a ``poibench dataset``, then :func:`spread_outputs`, so that there are
hundreds of boxes of distinct scores, many crossing the image edge) this exports
ONNX once per option set: the raw (1, 4+C, N) head at imgsz 320, 640 and a static
256x320; ``nms=True`` (NMS in the graph, (1, 300, 6)); YOLO26's NMS-free
one-to-one head, ``nms=False`` (``end2end=True`` in older Ultralytics), (1, 300, 6);
``dynamic=True``, alone and with ``nms=True``; FP16, ``quantize=16`` (``half=True``
in older Ultralytics; on a CPU it keeps float32 inputs and outputs) and, as a GPU
export writes it, with float16 inputs and outputs. It then runs on the same images
both Ultralytics' ``YOLO(file).predict(image, conf, iou, imgsz, max_det)`` (``rect``
is predict's default, so a dynamic model gets the minimal letterbox) and
:class:`poi.detectors.onnx_yolo.OnnxYoloDetector` with the same ``conf``, ``nms_iou``
and ``max_det`` (and ``letterbox: rect`` for a dynamic model where the detector has
that option).

Ultralytics returns boxes that lie wholly outside the image (in the letterbox
padding) clipped to zero area; poibench drops them. They are counted in ``off``
and left out of the comparison. The other boxes are matched per image and class,
greedily by IoU (>= 0.5); a row passes when every box of both sides is matched,
no corner differs by 0.5 px or more and no score by 0.001 or more. ``edge`` counts
Ultralytics' boxes that touch the image border (clipped there). The script exits 1
when a row fails.

It is never run by CI (the project's core install has no torch). Make the
training environment in its own venv and run it (about 3 minutes on two CPU
cores)::

    python -m venv /tmp/ulenv
    /tmp/ulenv/bin/pip install torch torchvision  # a CPU build is enough
    /tmp/ulenv/bin/pip install ultralytics onnx onnxruntime onnxslim
    /tmp/ulenv/bin/pip install -e .
    MUJOCO_GL=egl poibench dataset --out /tmp/ulpar/ds --images 32 --seed 3
    MUJOCO_GL=egl poibench render default --frames 20 --out /tmp/ulpar/frames
    /tmp/ulenv/bin/python bench/bench_ultralytics_parity.py --data /tmp/ulpar/ds \\
        --images /tmp/ulpar/frames/color --work /tmp/ulpar/work

Trained weights and exports are cached in ``--work`` (delete it to start over).
"""

from __future__ import annotations

import argparse
import dataclasses
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from poi.core.geometry import iou_matrix
from poi.core.loader import safe_load_file
from poi.core.types import Frame, Intrinsics
from poi.detectors.base import canonical_class
from poi.detectors.onnx_yolo import OnnxYoloDetector

MAX_BOX_DIFF_PX = 0.5
MAX_SCORE_DIFF = 0.001
MATCH_IOU = 0.5


@dataclass(frozen=True)
class Variant:
    """One export: a label and Ultralytics ``export`` keyword arguments (imgsz included)."""

    label: str
    kwargs: dict[str, Any]
    fp16_io: bool = False  # convert the FP32 export to float16 inputs and outputs, as a GPU export is

    @property
    def dynamic(self) -> bool:
        return bool(self.kwargs.get("dynamic"))


@dataclass
class Boxes:
    """One image's detections: class names (K,), xyxy (K, 4) in image pixels, scores (K,)."""

    names: list[str]
    xyxy: np.ndarray
    scores: np.ndarray


@dataclass
class Row:
    model: str
    variant: str
    shape: str
    n_ultralytics: int = 0
    n_poibench: int = 0
    n_matched: int = 0
    n_edge: int = 0
    n_off: int = 0
    box_diff: float = 0.0
    score_diff: float = 0.0
    letterbox: str = "square"
    error: str = ""

    @property
    def matched_fraction(self) -> float:
        total = max(self.n_ultralytics, self.n_poibench)
        return 1.0 if total == 0 else self.n_matched / total

    @property
    def ok(self) -> bool:
        return (
            not self.error
            and self.n_ultralytics > 0
            and self.n_matched == self.n_ultralytics == self.n_poibench
            and self.box_diff < MAX_BOX_DIFF_PX
            and self.score_diff < MAX_SCORE_DIFF
        )


def export_kwargs(option: str) -> dict[str, Any]:
    """The export keyword for ``option`` ('end2end' or 'half') in the installed Ultralytics."""
    from ultralytics.cfg import DEFAULT_CFG_DICT

    if option == "end2end":
        return {"nms": False} if "end2end" not in DEFAULT_CFG_DICT else {"end2end": True}
    if option == "half":
        return {"quantize": 16} if "quantize" in DEFAULT_CFG_DICT else {"half": True}
    raise ValueError(f"unknown option {option!r}")


def variants(arch: str) -> list[Variant]:
    """The option sets exported for ``arch``."""
    out = [
        Variant("raw 320", {"imgsz": 320}),
        Variant("raw 640", {"imgsz": 640}),
        Variant("raw 256x320", {"imgsz": [256, 320]}),
        Variant("nms=True", {"imgsz": 320, "nms": True}),
        Variant("dynamic", {"imgsz": 320, "dynamic": True}),
        Variant("dynamic nms=True", {"imgsz": 320, "dynamic": True, "nms": True, "batch": 1}),
        Variant("half", {"imgsz": 320, **export_kwargs("half")}),
        Variant("half fp16 io", {"imgsz": 320}, fp16_io=True),
    ]
    if arch.startswith("yolo26"):
        e2e = export_kwargs("end2end")
        out += [
            Variant("end2end", {"imgsz": 320, **e2e}),
            Variant("end2end dynamic", {"imgsz": 320, "dynamic": True, **e2e}),
            Variant("end2end half", {"imgsz": 320, **e2e, **export_kwargs("half")}),
            Variant("end2end half fp16 io", {"imgsz": 320, **e2e}, fp16_io=True),
        ]
    return out


def train_base(arch: str, data: Path, work: Path, epochs: int, seed: int) -> Path:
    """``arch``.yaml trained ``epochs`` epochs on ``data`` (cached as work/arch/weights/last.pt)."""
    from ultralytics import YOLO

    last = work / arch / "weights" / "last.pt"
    if last.exists():
        return last
    YOLO(f"{arch}.yaml").train(
        data=str(warmup_yaml(data, work)),
        epochs=epochs,
        imgsz=320,
        batch=8,
        workers=0,
        device="cpu",
        seed=seed,
        deterministic=True,
        val=False,
        plots=False,
        amp=False,
        optimizer="SGD",
        lr0=0.02,
        warmup_epochs=0,
        project=str(work),
        name=arch,
        exist_ok=True,
        verbose=False,
    )
    return last


def spread_outputs(weights: Path, data: Path) -> Path:
    """``weights`` with the head's outputs standardised so that boxes are many, varied and distinct.

    A briefly trained model's class scores are all ~5e-4 and nearly equal (no box passes any
    useful conf, and equal scores make NMS order arbitrary), and its boxes all span most of
    the image. Each output z of the last conv of every head branch is standardised over the
    anchors of four training images, z' = s (z - mean) / std + o, folded into that conv's
    weights and bias: class logits (``cv3``, and ``one2one_cv3`` of an NMS-free head) with
    s = 0.7, o = -6, so scores spread over (0, 1) with a long tail; box outputs (``cv2``,
    ``one2one_cv2``) so that boxes are a few strides wide: DFL bin logits with s = 1,
    o = -bin, a DFL-free distance with s = 0.5, o = 2 strides. The result: hundreds of boxes
    of distinct scores per image, inside the frame, across its edge and in the letterbox
    padding. Cached as ``spread.pt`` beside ``weights``.
    """
    import torch
    from ultralytics import YOLO
    from ultralytics.data.augment import LetterBox

    out = weights.with_name("spread.pt")
    if out.exists():
        return out
    model = YOLO(str(weights))
    net = model.model.eval()
    head = net.model[-1]
    reg_max = int(head.reg_max)
    if reg_max > 1:
        box_scale, box_offset = 1.0, -torch.arange(reg_max, dtype=torch.float32).repeat(4)  # (4 reg_max,)
    else:
        box_scale, box_offset = 0.5, torch.full((4,), 2.0)
    targets = {}  # id(conv) -> (conv, scale, offset)
    for names, scale, offset in (
        (("cv3", "one2one_cv3"), 0.7, torch.full((head.nc,), -6.0)),
        (("cv2", "one2one_cv2"), box_scale, box_offset),
    ):
        for name in names:
            for seq in getattr(head, name, None) or []:
                targets[id(seq[-1])] = (seq[-1], scale, offset)
    seen: dict[int, list[Any]] = {}
    hooks = [
        c.register_forward_hook(lambda m, i, o: seen.setdefault(id(m), []).append(o.detach()))
        for c, _, _ in targets.values()
    ]
    calib = [cv2.imread(str(p)) for p in sorted((data / "images" / "train").glob("*.jpg"))[:4]]
    with torch.no_grad():
        for end2end in (False, True):  # each branch runs only in its own mode
            if hasattr(head, "end2end"):
                head.end2end = end2end
            for bgr in calib:
                x = LetterBox(320, auto=False)(image=bgr)[..., ::-1].transpose(2, 0, 1).copy()  # (3, 320, 320) RGB
                net(torch.from_numpy(x)[None].float() / 255)
        for hook in hooks:
            hook.remove()
        for key, (c, scale, offset) in targets.items():
            z = torch.cat([o.permute(1, 0, 2, 3).reshape(o.shape[1], -1) for o in seen[key]], 1)  # (channels, n)
            mean, std = z.mean(1), z.std(1).clamp_min(1e-6)
            c.weight.mul_((scale / std)[:, None, None, None])
            c.bias.copy_((c.bias - mean) * scale / std + offset)
        if hasattr(head, "end2end"):
            head.end2end = False
    model.save(str(out))
    return out


def warmup_yaml(data: Path, work: Path) -> Path:
    """work/data.yaml: ``data``'s data.yaml, validating on the training images when it has no val split."""
    import yaml

    spec = safe_load_file(data / "data.yaml")
    spec["path"] = str(data.resolve())
    if not any((data / str(spec.get("val", "images/val"))).glob("*.*")):
        spec["val"] = spec["train"]
    work.mkdir(parents=True, exist_ok=True)
    (work / "data.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return work / "data.yaml"


def export(weights: Path, arch: str, variant: Variant, work: Path, conf: float, iou: float) -> Path:
    """The ONNX file of ``variant`` (cached under work/onnx/); an embedded NMS gets ``conf`` and ``iou``."""
    from ultralytics import YOLO

    name = f"{arch}_{variant.label.replace(' ', '_').replace('=', '')}"
    dest = work / "onnx" / (f"{name}_conf{conf}_iou{iou}.onnx" if variant.kwargs.get("nms") else f"{name}.onnx")
    if dest.exists():
        return dest
    dest.parent.mkdir(parents=True, exist_ok=True)
    nms = {"conf": conf, "iou": iou} if variant.kwargs.get("nms") else {}
    made = YOLO(str(weights)).export(format="onnx", device="cpu", **variant.kwargs, **nms)
    shutil.move(str(made), dest)
    if variant.fp16_io:  # a CPU export keeps float32 inputs and outputs; device=0 half=True gives float16 ones
        import onnx
        from onnxruntime.transformers import float16

        onnx.save(float16.convert_float_to_float16(onnx.load(dest), keep_io_types=False), dest)
    return dest


def output_shape(path: Path) -> str:
    import onnxruntime as ort

    shape = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]).get_outputs()[0].shape
    return "(" + ", ".join(str(d) for d in shape) + ")"


def ultralytics_boxes(
    path: Path, variant: Variant, images: list[np.ndarray], conf: float, iou: float, max_det: int
) -> list[Boxes]:
    """Ultralytics' ``predict`` on each BGR image (rect letterbox is its default)."""
    from ultralytics import YOLO

    model = YOLO(str(path), task="detect")
    out = []
    for bgr in images:
        imgsz = variant.kwargs["imgsz"]
        res = model.predict(bgr, conf=conf, iou=iou, imgsz=imgsz, max_det=max_det, device="cpu", verbose=False)[0]
        cls = res.boxes.cls.numpy().astype(int)
        names = [canonical_class(res.names[int(c)]) or res.names[int(c)] for c in cls]
        xyxy = res.boxes.xyxy.numpy().astype(np.float64)  # (K, 4)
        out.append(Boxes(names, xyxy, res.boxes.conf.numpy().astype(np.float64)))
    return out


def poibench_boxes(
    path: Path, images: list[np.ndarray], conf: float, iou: float, max_det: int, rect: bool
) -> list[Boxes]:
    """poibench's OnnxYoloDetector on each image (given RGB, as a Frame carries it)."""
    opts: dict[str, Any] = {"model": path, "conf": conf, "nms_iou": iou, "max_det": max_det, "threads": 2}
    if rect and "letterbox" in {f.name for f in dataclasses.fields(OnnxYoloDetector)}:
        opts["letterbox"] = "rect"
    det = OnnxYoloDetector(**opts)
    out = []
    for i, bgr in enumerate(images):
        h, w = bgr.shape[:2]
        k = Intrinsics(width=w, height=h, fx=600.0, fy=600.0, ppx=w / 2, ppy=h / 2)
        frame = Frame(index=i, timestamp_s=0.0, rgb=np.ascontiguousarray(bgr[..., ::-1]), intrinsics=k)
        dets = det.detect(frame)
        xyxy = np.array([d.box_xyxy for d in dets], dtype=np.float64).reshape(-1, 4)
        out.append(Boxes([d.class_name for d in dets], xyxy, np.array([d.confidence for d in dets])))
    return out


def match(ul: Boxes, pb: Boxes) -> tuple[int, float, float]:
    """Pairs matched (same class, greedy by IoU >= MATCH_IOU), max |corner diff| px, max |score diff|."""
    n, box_diff, score_diff = 0, 0.0, 0.0
    for name in set(ul.names) & set(pb.names):
        ia = np.array([i for i, c in enumerate(ul.names) if c == name])
        ib = np.array([j for j, c in enumerate(pb.names) if c == name])
        m = iou_matrix(ul.xyxy[ia], pb.xyxy[ib])
        while m.size and m.max() >= MATCH_IOU:
            i, j = np.unravel_index(np.argmax(m), m.shape)
            a, b = ia[i], ib[j]
            n += 1
            box_diff = max(box_diff, float(np.max(np.abs(ul.xyxy[a] - pb.xyxy[b]))))
            score_diff = max(score_diff, abs(float(ul.scores[a] - pb.scores[b])))
            m[i, :] = -1.0
            m[:, j] = -1.0
    return n, box_diff, score_diff


def compare(
    arch: str, variant: Variant, path: Path, images: list[np.ndarray], conf: float, iou: float, max_det: int
) -> Row:
    row = Row(arch, variant.label, output_shape(path), letterbox="rect" if variant.dynamic else "square")
    ul = ultralytics_boxes(path, variant, images, conf, iou, max_det)
    try:
        pb = poibench_boxes(path, images, conf, iou, max_det, rect=variant.dynamic)
    except ValueError as exc:  # OnnxModelError, DetectorConfigError
        row.error = str(exc).splitlines()[0]
        on = [np.all(b.xyxy[:, 2:] > b.xyxy[:, :2], axis=1) for b in ul]
        row.n_ultralytics, row.n_off = sum(int(o.sum()) for o in on), sum(int((~o).sum()) for o in on)
        return row
    for img, a_all, b in zip(images, ul, pb, strict=True):
        h, w = img.shape[:2]
        on = np.all(a_all.xyxy[:, 2:] > a_all.xyxy[:, :2], axis=1)  # (K,) False: wholly off the image
        row.n_off += int(np.sum(~on))
        a = Boxes([n for n, keep in zip(a_all.names, on, strict=True) if keep], a_all.xyxy[on], a_all.scores[on])
        row.n_ultralytics += len(a.names)
        row.n_poibench += len(b.names)
        row.n_edge += int(np.sum(np.any((a.xyxy[:, :2] <= 0) | (a.xyxy[:, 2:] >= [w, h]), axis=1)))
        n, bd, sd = match(a, b)
        row.n_matched += n
        row.box_diff = max(row.box_diff, bd)
        row.score_diff = max(row.score_diff, sd)
    return row


def print_table(rows: list[Row]) -> None:
    cols = ["model", "options", "output", "letterbox", "Ultralytics", "off", "poibench", "edge", "matched"]
    cols += ["max box px", "max score"]
    print("| " + " | ".join(cols) + " |")
    print("| --- " * len(cols) + "|")
    for r in rows:
        if r.error:
            lead = f"| {r.model} | {r.variant} | {r.shape} | {r.letterbox} | {r.n_ultralytics} | {r.n_off}"
            print(f"{lead} | refused: {r.error} |")
            continue
        print(
            f"| {r.model} | {r.variant} | {r.shape} | {r.letterbox} | {r.n_ultralytics} | {r.n_off} | "
            f"{r.n_poibench} | {r.n_edge} | {100 * r.matched_fraction:.1f}% | {r.box_diff:.4f} | "
            f"{r.score_diff:.2e} |" + ("" if r.ok else " FAIL")
        )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True, help="a poibench dataset folder (data.yaml) to warm up on")
    ap.add_argument("--images", type=Path, required=True, help="a folder of PNG/JPG frames to compare on")
    ap.add_argument("--work", type=Path, required=True, help="where weights and exports are cached")
    ap.add_argument("--archs", nargs="+", default=["yolo11n", "yolo26n"])
    ap.add_argument("--epochs", type=int, default=3, help="warm-up epochs (default 3)")
    ap.add_argument("--conf", type=float, default=0.01, help="confidence threshold on both sides (default 0.01)")
    ap.add_argument("--iou", type=float, default=0.7, help="NMS IoU on both sides (default 0.7, predict's)")
    ap.add_argument("--max-det", type=int, default=300, help="max_det on both sides (default 300, predict's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="+", help="only these option sets (e.g. 'raw 320' nms=True)")
    args = ap.parse_args()
    files = sorted(p for p in args.images.iterdir() if p.suffix.lower() in {".png", ".jpg", ".jpeg"})
    if not files:
        ap.error(f"{args.images}: no PNG or JPG images")
    images = [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in files]  # BGR, as Ultralytics reads files
    rows = []
    for arch in args.archs:
        trained = train_base(arch, args.data, args.work, args.epochs, args.seed)
        weights = spread_outputs(trained, args.data)
        for variant in variants(arch):
            if args.only and variant.label not in args.only:
                continue
            path = export(weights, arch, variant, args.work, args.conf, args.iou)
            rows.append(compare(arch, variant, path, images, args.conf, args.iou, args.max_det))
            print(f"done {arch} {variant.label}", file=sys.stderr, flush=True)
    print(f"{len(images)} images from {args.images}, conf {args.conf}, iou {args.iou}, max_det {args.max_det}")
    print_table(rows)
    failed = [f"{r.model} {r.variant}" for r in rows if not r.ok]
    print("all layouts match" if not failed else f"{len(failed)} of {len(rows)} fail: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
