"""``poibench evaluate-detector`` and ``poibench calibrate``: a model against labelled images.

Both run the ONNX detector (onnxruntime, as the pipeline does) over a split of
a ``poibench dataset`` folder, by default one rendered from seeds the
training never used, and compare with the labels:

* evaluation (eval.detector.metrics): mAP50, mAP50-95, per-class AP, recall
  and precision at the operating confidence, and the confusion matrix as an
  image;
* calibration ([Avevor2022]_ sections 2.1.4 and 2.1.5): for detections paired
  one-to-one with a labelled box (IoU >= 0.5, any class), the squared centre
  errors du^2 against the box width w and dv^2 against its height h, fitted per
  class (classes with at least ``MIN_FIT_SAMPLES`` pairs; a ``default`` fit
  from all pairs covers the rest) as sigma^2(s) = c0 + c1 s + c2 s^2 with
  c >= 0 by non-negative least squares, which estimates E[du^2 | w] and keeps
  the variance positive for every size (c0 at least the 1/12 px^2 of whole-pixel
  labels); and Pr(actual B | detected A, A
  misclassified) from the pairs whose classes differ, with additive smoothing
  ``CONFUSION_ALPHA`` so no class is ever impossible. Written in the format
  poi.estimation.covariance.load_calibration reads, with a plot of the fits.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.optimize import nnls

from eval.detector.metrics import (
    ImageBoxes,
    class_metrics,
    confusion_counts,
    drop_ignored,
    match_boxes,
    mean_ap,
    recall_by_size,
)
from eval.detector.yolo_labels import read_yolo_labels
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES

EVAL_SEED = 1000  # default seed of evaluation scenes; 'poibench dataset' defaults to seed 0
EVAL_IMAGES = 400  # default count of fresh evaluation scenes (evaluate-detector, calibrate)
MIN_FIT_SAMPLES = 30
# The labelled boxes are whole pixels: a centre is known to +-0.5 px at best, a uniform error
# of variance 1/12 px^2; the fitted constant term never goes below it (and the pipeline's
# calibration loader needs it positive).
MIN_CENTER_VARIANCE_PX2 = 1.0 / 12.0
CONFUSION_ALPHA = 0.5
SEED_METADATA_KEY = "poibench_dataset_seed"  # one seed: what poibench train wrote before it listed them all
SEEDS_METADATA_KEY = "poibench_dataset_seeds"  # every rendered dataset a model trained on, comma-separated
PHOTO_FOLDERS_METADATA_KEY = "poibench_photo_folders"  # photo folders trained on (resolved), by PATH_SEPARATOR
PATH_SEPARATOR = "\n"
AP_CONF = 0.001  # detections kept for AP (the whole precision-recall curve)


class DetectorQualityError(ValueError):
    """Evaluation or calibration input is unusable (one line)."""


@dataclass(kw_only=True)
class LabelledImage:
    path: Path
    boxes_norm: np.ndarray  # (G, 4) xyxy as fractions of the image width and height
    classes: np.ndarray  # (G,)
    ignore_norm: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))  # (I, 4) objects too hidden
    ignore_classes: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # (I,) to label

    def boxes_px(self, width: int, height: int) -> np.ndarray:
        """(G, 4) xyxy pixels of an image ``width`` x ``height``."""
        return self.boxes_norm * np.array([width, height, width, height], dtype=float)

    def ignore_px(self, width: int, height: int) -> np.ndarray:
        """(I, 4) xyxy pixels of the ignored objects."""
        return self.ignore_norm * np.array([width, height, width, height], dtype=float)


# box sizes compared across image sets are those of a frame whose long side is the D435 colour frame's:
# a YOLO detector letterboxes every image by its long side, so a box of a 520 px photo is seen 640 / 520
# times as large as its pixels
FRAME_LONG_SIDE_PX = 640.0


def frame_scales(images: Sequence[LabelledImage]) -> np.ndarray:
    """(n,) per image, :data:`FRAME_LONG_SIDE_PX` over its long side (read from the file's header):
    what its box sizes are multiplied by to be compared with another image's, as a detector that
    letterboxes by the long side sees them (1 for the 640x480 renders)."""
    from PIL import Image

    scales = []
    for im in images:
        with Image.open(im.path) as f:
            scales.append(FRAME_LONG_SIDE_PX / max(f.size))
    return np.array(scales, dtype=float)


def model_metadata(model: str | Path) -> dict[str, str]:
    """An ONNX model's custom metadata, as onnxruntime reads it (one line for a file it cannot load)."""
    import onnxruntime as ort

    from poi.detectors.base import check_model_file

    check_model_file(model, DetectorQualityError)
    try:
        meta = ort.InferenceSession(str(model), providers=["CPUExecutionProvider"]).get_modelmeta()
    except Exception as e:  # onnxruntime's own exception types
        raise DetectorQualityError(
            f"{model}: not a loadable ONNX model ({str(e).splitlines()[0][:150]})"
        ) from None
    return dict(meta.custom_metadata_map)


def model_photo_folders(model: str | Path, meta: dict[str, str] | None = None) -> list[str]:
    """The photo folders a model was trained on part of (``poibench_photo_folders``), resolved
    paths in the order stamped; from ``meta`` (:func:`model_metadata`) when it was read already."""
    meta = model_metadata(model) if meta is None else meta
    return list(filter(None, meta.get(PHOTO_FOLDERS_METADATA_KEY, "").split(PATH_SEPARATOR)))


def _seed_of(value: str | None) -> int | None:
    return int(value) if value is not None and value.lstrip("-").isdigit() else None


def model_training_seeds(model: str | Path, meta: dict[str, str] | None = None) -> set[int]:
    """Every dataset seed a model was trained on: the comma-separated list
    (``poibench_dataset_seeds``) and an older detector's single seed (``poibench_dataset_seed``);
    from ``meta`` (:func:`model_metadata`) when it was read already."""
    meta = model_metadata(model) if meta is None else meta
    listed = [_seed_of(v.strip()) for v in meta.get(SEEDS_METADATA_KEY, "").split(",")]
    return {s for s in [*listed, _seed_of(meta.get(SEED_METADATA_KEY))] if s is not None}


def labelled_image(root: Path, split: str, img: Path) -> LabelledImage:
    """``img`` with its boxes from ``root/labels/split`` and ``root/ignore/split`` (same stem;
    a missing file: no boxes). ``split`` "" reads a flat folder's ``labels/``."""
    labels = _read_label_file(root / "labels" / split / f"{img.stem}.txt")
    ignore = _read_label_file(root / "ignore" / split / f"{img.stem}.txt")
    return LabelledImage(
        path=img,
        boxes_norm=labels[:, 1:],
        classes=labels[:, 0].astype(int),
        ignore_norm=ignore[:, 1:],
        ignore_classes=ignore[:, 0].astype(int),
    )


def load_split(dataset: str | Path, split: str) -> list[LabelledImage]:
    """Images (paths) and labels of one split of a YOLO dataset folder; the images are read
    once, by :func:`detect_all`."""
    root = Path(dataset)
    img_dir = root / "images" / split
    if not img_dir.is_dir():
        raise DetectorQualityError(f"{img_dir}: no such folder; give a folder written by 'poibench dataset'")
    out = [labelled_image(root, split, img) for img in sorted(img_dir.glob("*.jpg"))]
    if not out:
        raise DetectorQualityError(f"{img_dir}: no images")
    return out


def _read_label_file(lab: Path) -> np.ndarray:
    """(N, 5) rows class, x1, y1, x2, y2 (normalised) of a YOLO label file; none if it is missing."""
    boxes = read_yolo_labels(lab, DetectorQualityError) if lab.exists() else []
    return np.array([(b.cls, *b.xyxy) for b in boxes], dtype=float).reshape(-1, 5)


class ImageDetector:
    """The detector of the evaluation commands on one RGB image at a time: the ONNX detector
    (with its hazmat label classifier, when given) at ``conf``, or a team's Python detector
    (``model`` is ``python:MODULE:CLASS`` or an entry point name) built from ``options`` with its
    own threshold. Detections of classes outside RESCUE_CLASSES are dropped (the datasets are
    rescue mazes labelled with them; a model that also knows the arena's classes has nothing to
    find of those here)."""

    def __init__(
        self, model: str | Path, conf: float, label_model: str | Path | None = None, options: dict | None = None
    ) -> None:
        from poi.detectors import build_detector, build_python_detector, is_team_detector

        if is_team_detector(str(model)):
            if label_model is not None:
                raise DetectorQualityError(f"{model}: a label model goes behind an ONNX detector only")
            self.det = build_python_detector(str(model), options)
        else:
            spec = {"name": "onnx", "model": str(model), "conf": conf}
            if label_model is not None:
                spec["label_model"] = str(label_model)
            self.det = build_detector(spec)

    def __call__(self, rgb: np.ndarray, name: str | Path, index: int = 0) -> list:
        """The detections on ``rgb`` (its image ``name`` is what an error names)."""
        from poi.core.types import Frame, Intrinsics
        from poi.detectors.plugins import DetectorOutputError

        h, w = rgb.shape[:2]
        K = Intrinsics(width=w, height=h, fx=1.0, fy=1.0, ppx=w / 2, ppy=h / 2)
        try:
            dets = self.det.detect(Frame(index=index, timestamp_s=0.0, rgb=rgb, intrinsics=K))
        except DetectorOutputError as e:  # a team detector's bad output: name the image, not "frame k"
            raise DetectorOutputError(f"{name}: detector {e.detector!r}: {e.reason}") from None
        return [d for d in dets if d.class_name in RESCUE_CLASSES]


def read_rgb(path: Path) -> np.ndarray:
    """An image file as RGB uint8; one line naming it when it is not an image."""
    bgr = cv2.imread(str(path))
    if bgr is None:
        raise DetectorQualityError(f"{path}: not a readable image")
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


def detect_all(
    model: str | Path,
    images: list[LabelledImage],
    conf: float,
    progress=None,
    label_model: str | Path | None = None,
    options: dict | None = None,
) -> list[ImageBoxes]:
    """Run the detector (:class:`ImageDetector`) on every image; detections and labels as
    ImageBoxes."""
    detect = ImageDetector(model, conf, label_model, options)
    out = []
    for k, im in enumerate(images):
        rgb = read_rgb(im.path)
        h, w = rgb.shape[:2]
        dets = detect(rgb, im.path, k)
        boxes = ImageBoxes(
            gt_boxes=im.boxes_px(w, h),
            gt_classes=im.classes,
            det_boxes=np.array([d.box_xyxy for d in dets], float).reshape(-1, 4),
            det_classes=np.array([RESCUE_CLASSES.index(d.class_name) for d in dets], int),
            det_scores=np.array([d.confidence for d in dets], float),
        )
        out.append(drop_ignored(boxes, im.ignore_px(w, h), im.ignore_classes))
        if progress:
            progress(1)
    return out


# ------------------------------------------------------------------ evaluation


def evaluation_report(results: list[ImageBoxes], conf: float) -> dict:
    per = class_metrics(results, len(RESCUE_CLASSES), conf)
    m50, m5095 = mean_ap(per)

    def num(x: float):
        return None if np.isnan(x) else round(float(x), 4)

    return {
        "images": len(results),
        "operating_conf": conf,
        "mAP50": num(m50),
        "mAP50_95": num(m5095),
        "classes": {
            c: {
                "n": p.n_gt,
                "AP50": num(p.ap50),
                "AP50_95": num(p.ap50_95),
                "recall": num(p.recall),
                "precision": num(p.precision),
            }
            for c, p in zip(RESCUE_CLASSES, per, strict=True)
        },
        "by_size": recall_by_size(
            results, ["hazmat label" if c in HAZMAT_LABELS else "other type" for c in RESCUE_CLASSES], conf
        ),
        "confusion": confusion_counts(results, len(RESCUE_CLASSES), conf).tolist(),
    }


def plot_confusion(
    path: Path,
    counts: np.ndarray,
    labels: list[str] | None = None,
    *,
    xlabel: str = "detected",
    ylabel: str = "true (background row: false detections)",
    title: str | None = None,
    figsize: tuple[float, float] = (11, 10),
    tick_fontsize: float = 7,
) -> None:
    """Row-normalised confusion matrix (true class rows, detected class columns) as a PNG,
    each non-empty cell labelled with its count. ``labels`` name the rows and columns (default:
    the rescue classes and ``background``, as ``confusion_counts`` orders them)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = [*RESCUE_CLASSES, "background"] if labels is None else list(labels)
    M = np.asarray(counts, float)
    rows = M.sum(axis=1, keepdims=True)
    norm = np.divide(M, rows, out=np.zeros_like(M), where=rows > 0)
    fig, ax = plt.subplots(figsize=figsize)
    im = ax.imshow(norm, cmap="Blues", vmin=0, vmax=1)
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            if M[i, j]:
                ax.text(
                    j,
                    i,
                    int(M[i, j]),
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="white" if norm[i, j] > 0.5 else "black",
                )
    ax.set_xticks(range(len(labels)), labels, rotation=90, fontsize=tick_fontsize)
    ax.set_yticks(range(len(labels)), labels, fontsize=tick_fontsize)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    fig.colorbar(im, ax=ax, fraction=0.04, label="fraction of the true class")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_evaluation(out_dir: Path, report: dict) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "evaluation.json").write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
    plot_confusion(out_dir / "confusion.png", np.array(report["confusion"]))


def format_evaluation(report: dict) -> str:
    def f(x):
        return "   -  " if x is None else f"{x:6.3f}"

    lines = [
        f"{report['images']} images; mAP50 {f(report['mAP50'])}, mAP50-95 {f(report['mAP50_95'])}; "
        f"recall and precision at confidence {report['operating_conf']}",
        f"{'class':26s} {'n':>5s} {'AP50':>6s} {'AP50-95':>7s} {'recall':>6s} {'prec':>6s}",
    ]
    for c, m in report["classes"].items():
        lines.append(
            f"{c:26s} {m['n']:5d} {f(m['AP50'])} {f(m['AP50_95']):>7s} {f(m['recall'])} {f(m['precision'])}"
        )
    if report.get("by_size"):
        lines.append("by box size (shorter side, px): found by any class / with the right class")
        lines.append(f"{'group':14s} {'band':>8s} {'n':>5s} {'found':>6s} {'right':>6s}")
        for r in report["by_size"]:
            lines.append(f"{r['group']:14s} {r['band_px']:>8s} {r['n']:5d} {f(r['found'])} {f(r['right_class'])}")
    return "\n".join(lines)


# ----------------------------------------------------------------- calibration


@dataclass(kw_only=True)
class CenterSamples:
    cls: np.ndarray  # (N,) true class of the pair
    w: np.ndarray
    h: np.ndarray
    du2: np.ndarray
    dv2: np.ndarray


def center_samples(results: list[ImageBoxes]) -> tuple[CenterSamples, np.ndarray]:
    """Squared centre errors of paired detections, and (C, C) misclassification counts
    (row: detected class A, column: actual class B, A != B)."""
    cls, w, h, du2, dv2 = [], [], [], [], []
    mis = np.zeros((len(RESCUE_CLASSES), len(RESCUE_CLASSES)), dtype=np.int64)
    for im in results:
        for g, d in match_boxes(im.gt_boxes, im.det_boxes, 0.5):
            gb, db = im.gt_boxes[g], im.det_boxes[d]
            cls.append(int(im.gt_classes[g]))
            w.append(db[2] - db[0])
            h.append(db[3] - db[1])
            du2.append(((db[0] + db[2]) / 2 - (gb[0] + gb[2]) / 2) ** 2)
            dv2.append(((db[1] + db[3]) / 2 - (gb[1] + gb[3]) / 2) ** 2)
            a, b = int(im.det_classes[d]), int(im.gt_classes[g])
            if a != b:
                mis[a, b] += 1
    arr = [np.array(x, float) for x in (w, h, du2, dv2)]
    return CenterSamples(cls=np.array(cls, int), w=arr[0], h=arr[1], du2=arr[2], dv2=arr[3]), mis


def fit_variance(size_px: np.ndarray, sq_err: np.ndarray) -> list[float]:
    """c >= 0 minimising sum (c0 + c1 s + c2 s^2 - e^2)^2 (non-negative least squares), with
    c0 at least ``MIN_CENTER_VARIANCE_PX2``.

    >>> s = np.array([10.0, 20.0, 40.0, 80.0])
    >>> [round(c, 6) for c in fit_variance(s, 1.0 + 0.01 * s**2)]
    [1.0, 0.0, 0.01]
    """
    A = np.stack([np.ones_like(size_px), size_px, size_px**2], axis=1)
    scale = np.array([1.0, max(size_px.max(), 1.0), max(size_px.max(), 1.0) ** 2])
    coef, _ = nnls(A / scale, sq_err)
    coef = coef / scale
    coef[0] = max(coef[0], MIN_CENTER_VARIANCE_PX2)
    return [float(c) for c in coef]


def confusion_probabilities(mis: np.ndarray, alpha: float = CONFUSION_ALPHA) -> np.ndarray:
    """Row A: Pr(actual B | detected A, misclassified) = (n_AB + alpha) / sum_B'(n_AB' + alpha), B != A.

    >>> confusion_probabilities(np.array([[0, 3, 1], [0, 0, 0], [2, 0, 0]]), alpha=0.5).round(3).tolist()
    [[0.0, 0.7, 0.3], [0.5, 0.0, 0.5], [0.833, 0.167, 0.0]]
    """
    M = np.asarray(mis, float) + alpha
    np.fill_diagonal(M, 0.0)
    return M / M.sum(axis=1, keepdims=True)


def calibration_doc(samples: CenterSamples, mis: np.ndarray) -> tuple[dict, dict]:
    """(calibration YAML document, per-class sample counts)."""
    centers: dict[str, dict] = {}
    counts = {}
    if len(samples.w):
        centers["default"] = {"u": fit_variance(samples.w, samples.du2), "v": fit_variance(samples.h, samples.dv2)}
    for i, c in enumerate(RESCUE_CLASSES):
        sel = samples.cls == i
        counts[c] = int(sel.sum())
        if sel.sum() >= MIN_FIT_SAMPLES:
            centers[c] = {
                "u": fit_variance(samples.w[sel], samples.du2[sel]),
                "v": fit_variance(samples.h[sel], samples.dv2[sel]),
            }
    doc = {
        "poibench_calibration": 1,
        "center_variance_px2": centers,
        "confusion": {
            "classes": list(RESCUE_CLASSES),
            "matrix": [[round(float(x), 6) for x in row] for row in confusion_probabilities(mis)],
        },
    }
    return doc, counts


def plot_center_fits(path: Path, samples: CenterSamples, doc: dict) -> None:
    """Squared centre error against box size, per fitted class, with the fitted curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fitted = list(doc["center_variance_px2"])
    n = len(fitted)
    cols = min(4, max(n, 1))
    rows = max(1, -(-n // cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.9 * rows), squeeze=False)
    for ax, name in zip(axes.ravel(), fitted, strict=False):
        sel = np.ones(len(samples.w), bool) if name == "default" else samples.cls == RESCUE_CLASSES.index(name)
        coef = doc["center_variance_px2"][name]
        ax.scatter(samples.w[sel], samples.du2[sel], s=4, alpha=0.4, label="du² vs w")
        ax.scatter(samples.h[sel], samples.dv2[sel], s=4, alpha=0.4, label="dv² vs h")
        grid = np.linspace(0, max(samples.w[sel].max(), samples.h[sel].max()) if sel.any() else 1, 100)
        ax.plot(grid, np.polyval(coef["u"][::-1], grid), "C0", lw=2, label="σu²(w)")
        ax.plot(grid, np.polyval(coef["v"][::-1], grid), "C1", lw=2, label="σv²(h)")
        ax.set_title(f"{name} ({int(sel.sum())})", fontsize=9)
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xlabel("box size (px)", fontsize=8)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    axes.ravel()[0].legend(fontsize=7)
    fig.suptitle("squared centre error (px²) against box size, with the fitted variance")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_calibration(
    path: Path, samples: CenterSamples, mis: np.ndarray, model: str, label_model: str | None = None
) -> dict:
    doc, counts = calibration_doc(samples, mis)
    if not doc["center_variance_px2"]:
        raise DetectorQualityError("no detection paired with a labelled box: nothing to calibrate from")
    name = Path(model).name + (f" with {Path(label_model).name}" if label_model else "")
    header = (
        f"# poibench calibration of {name}: centre-error variance per class ([Avevor2022] 2.1.4)\n"
        f"# from {len(samples.w)} paired detections, and Pr(actual | detected, misclassified) (2.1.5).\n"
        f"# Pairs per class: {json.dumps(counts)}\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None), encoding="utf-8")
    plot_center_fits(path.with_suffix(".png"), samples, doc)
    return counts
