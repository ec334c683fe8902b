"""Detection metrics against labelled boxes: AP (COCO-style), recall, confusion, matching.

Boxes are (x1, y1, x2, y2) pixels. Per class and IoU threshold t, average
precision follows the COCO evaluation (Lin et al., "Microsoft COCO", 2014, and
its reference cocoeval): detections of the class over all images in
descending confidence; each is a true positive when its best-IoU unmatched
ground-truth box of the class (same image) has IoU >= t; precision is made
monotone (the running maximum from high recall down) and averaged over the 101
recall points 0, 0.01, ..., 1 (0 where a recall is never reached).
mAP50 is the mean over classes with ground truth of AP at t = 0.5; mAP50-95
the mean over t = 0.50, 0.55, ..., 0.95 as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from poi.core.geometry import greedy_pairs, iou_matrix

IOU_THRESHOLDS = np.round(np.arange(0.5, 0.951, 0.05), 2)
RECALL_POINTS = np.linspace(0.0, 1.0, 101)


@dataclass(kw_only=True)
class ImageBoxes:
    """Ground truth and detections of one image; classes are indices."""

    gt_boxes: np.ndarray  # (G, 4)
    gt_classes: np.ndarray  # (G,)
    det_boxes: np.ndarray  # (D, 4)
    det_classes: np.ndarray  # (D,)
    det_scores: np.ndarray  # (D,)


def scaled_boxes(im: ImageBoxes, f: float) -> ImageBoxes:
    """``im`` with its true and detected boxes multiplied by ``f`` (IoU and pairs unchanged)."""
    if f == 1.0:
        return im
    return ImageBoxes(
        gt_boxes=im.gt_boxes * f,
        gt_classes=im.gt_classes,
        det_boxes=im.det_boxes * f,
        det_classes=im.det_classes,
        det_scores=im.det_scores,
    )


def drop_ignored(im: ImageBoxes, ignore_boxes: np.ndarray, ignore_classes: np.ndarray) -> ImageBoxes:
    """``im`` without the detections of ignored objects (KITTI's DontCare).

    A detection is left out when it overlaps an ignored box of its class with IoU >= 0.5
    and no labelled box of its class with IoU >= 0.5: it found an object that is there
    but too hidden to be labelled, so it is neither a hit nor a false detection.

    >>> im = ImageBoxes(gt_boxes=np.array([[0, 0, 10, 10.0]]), gt_classes=np.array([0]),
    ...     det_boxes=np.array([[0, 0, 10, 10.0], [50, 0, 70, 20], [50, 0, 70, 20]]),
    ...     det_classes=np.array([0, 1, 2]), det_scores=np.array([0.9, 0.8, 0.7]))
    >>> drop_ignored(im, np.array([[51, 0, 70, 20.0]]), np.array([1])).det_classes.tolist()
    [0, 2]
    """
    if len(ignore_boxes) == 0 or len(im.det_boxes) == 0:
        return im
    same_ign = im.det_classes[:, None] == ignore_classes[None, :]  # (D, I)
    on_ignored = np.any((iou_matrix(im.det_boxes, ignore_boxes) >= 0.5) & same_ign, axis=1)  # (D,)
    if len(im.gt_boxes):
        same_gt = im.det_classes[:, None] == im.gt_classes[None, :]  # (D, G)
        on_ignored &= ~np.any((iou_matrix(im.det_boxes, im.gt_boxes) >= 0.5) & same_gt, axis=1)
    keep = ~on_ignored
    return ImageBoxes(
        gt_boxes=im.gt_boxes,
        gt_classes=im.gt_classes,
        det_boxes=im.det_boxes[keep],
        det_classes=im.det_classes[keep],
        det_scores=im.det_scores[keep],
    )


def average_precision(tp: np.ndarray, n_gt: int) -> float:
    """101-point interpolated AP from true-positive flags in descending-confidence order.

    >>> average_precision(np.array([True, False, True]), 2)  # P = 1, 1/2, 2/3 at R = 1/2, 1/2, 1
    0.834983
    """
    if n_gt == 0:
        return float("nan")
    if len(tp) == 0:
        return 0.0
    tps = np.cumsum(tp)
    fps = np.cumsum(~tp)
    recall = tps / n_gt
    precision = tps / (tps + fps)
    envelope = np.maximum.accumulate(precision[::-1])[::-1]
    idx = np.searchsorted(recall, RECALL_POINTS, side="left")
    values = np.where(idx < len(envelope), envelope[np.minimum(idx, len(envelope) - 1)], 0.0)
    return round(float(values.mean()), 6)


def _tp_flags(images: list[ImageBoxes], cls: int, t: float) -> tuple[np.ndarray, np.ndarray, int]:
    """(scores, tp flags) of class ``cls`` detections in descending score, and its GT count."""
    scores, flags = [], []
    n_gt = 0
    for im in images:
        gsel = im.gt_classes == cls
        dsel = im.det_classes == cls
        n_gt += int(gsel.sum())
        if not dsel.any():
            continue
        d_scores = im.det_scores[dsel]
        order = np.argsort(-d_scores, kind="stable")
        d_boxes = im.det_boxes[dsel][order]
        ious = iou_matrix(d_boxes, im.gt_boxes[gsel])
        taken = np.zeros(ious.shape[1], bool)
        for k in range(len(d_boxes)):
            best, best_iou = -1, t
            for g in range(ious.shape[1]):
                if not taken[g] and ious[k, g] >= best_iou:
                    best, best_iou = g, ious[k, g]
            if best >= 0:
                taken[best] = True
            flags.append(best >= 0)
        scores.extend(d_scores[order])
    scores_a = np.asarray(scores, float)
    flags_a = np.asarray(flags, bool)
    order = np.argsort(-scores_a, kind="stable")
    return scores_a[order], flags_a[order], n_gt


@dataclass(kw_only=True)
class ClassMetrics:
    n_gt: int
    ap50: float
    ap50_95: float
    recall: float  # at IoU 0.5 among detections scoring at least the operating threshold
    precision: float


def class_metrics(images: list[ImageBoxes], n_classes: int, conf: float) -> list[ClassMetrics]:
    """Per-class AP50, AP50-95, and recall and precision at confidence ``conf``."""
    out = []
    for c in range(n_classes):
        aps = []
        rec = prec = float("nan")
        n_gt = 0
        for t in IOU_THRESHOLDS:
            scores, tp, n_gt = _tp_flags(images, c, float(t))
            aps.append(average_precision(tp, n_gt))
            if t == 0.5:
                sel = scores >= conf
                hits = int(tp[sel].sum())
                rec = hits / n_gt if n_gt else float("nan")
                prec = hits / int(sel.sum()) if sel.any() else float("nan")
        out.append(
            ClassMetrics(
                n_gt=n_gt,
                ap50=aps[0],
                ap50_95=float(np.mean(aps)) if n_gt else float("nan"),
                recall=rec,
                precision=prec,
            )
        )
    return out


def mean_ap(metrics: list[ClassMetrics]) -> tuple[float, float]:
    """(mAP50, mAP50-95) over classes with ground truth."""
    m = [x for x in metrics if x.n_gt > 0]
    if not m:
        return float("nan"), float("nan")
    return float(np.mean([x.ap50 for x in m])), float(np.mean([x.ap50_95 for x in m]))


def match_boxes(gt_boxes: np.ndarray, det_boxes: np.ndarray, iou_min: float = 0.5) -> list[tuple[int, int]]:
    """Class-agnostic one-to-one (gt, det) pairs with IoU >= ``iou_min``, greedily by IoU."""
    return greedy_pairs(iou_matrix(gt_boxes, det_boxes), iou_min)


def match_classes_first(
    gt_boxes: np.ndarray,
    gt_classes: np.ndarray,
    det_boxes: np.ndarray,
    det_classes: np.ndarray,
    iou_min: float = 0.5,
) -> list[tuple[int, int]]:
    """One-to-one (gt, det) pairs with IoU >= ``iou_min``: first each class's detections with
    its true boxes (:func:`match_boxes` per class), then the rest class-agnostically. A true box
    with a right-class detection on it is never paired with a better-overlapping wrong one, so
    that detection does not end up a false detection and the box a misnamed one.

    >>> box = np.array([[0, 0, 10, 10.0]])
    >>> match_classes_first(box, np.array([3]), np.array([[0, 0, 10, 10], [0, 0, 10, 9.0]]),
    ...     np.array([5, 3]))  # the wrong class fits better
    [(0, 1)]
    >>> match_classes_first(box, np.array([3]), box, np.array([5]))
    [(0, 0)]
    """
    gt_classes = np.asarray(gt_classes)
    det_classes = np.asarray(det_classes)
    pairs: list[tuple[int, int]] = []
    for c in np.intersect1d(gt_classes, det_classes):
        gi, di = np.flatnonzero(gt_classes == c), np.flatnonzero(det_classes == c)
        pairs += [(int(gi[g]), int(di[d])) for g, d in match_boxes(gt_boxes[gi], det_boxes[di], iou_min)]
    gi = np.setdiff1d(np.arange(len(gt_boxes)), [g for g, _ in pairs])
    di = np.setdiff1d(np.arange(len(det_boxes)), [d for _, d in pairs])
    if len(gi) and len(di):
        pairs += [(int(gi[g]), int(di[d])) for g, d in match_boxes(gt_boxes[gi], det_boxes[di], iou_min)]
    return sorted(pairs)


def confusion_counts(images: list[ImageBoxes], n_classes: int, conf: float, iou_min: float = 0.5) -> np.ndarray:
    """(C + 1, C + 1) counts, rows the true class, columns the detected class; index C is
    background (a missed object in the last column, a false detection in the last row)."""
    M = np.zeros((n_classes + 1, n_classes + 1), dtype=np.int64)
    for im in images:
        keep = im.det_scores >= conf
        dboxes, dcls = im.det_boxes[keep], im.det_classes[keep]
        pairs = match_boxes(im.gt_boxes, dboxes, iou_min)
        for g, d in pairs:
            M[int(im.gt_classes[g]), int(dcls[d])] += 1
        matched_g = {g for g, _ in pairs}
        matched_d = {d for _, d in pairs}
        for g in range(len(im.gt_boxes)):
            if g not in matched_g:
                M[int(im.gt_classes[g]), n_classes] += 1
        for d in range(len(dboxes)):
            if d not in matched_d:
                M[n_classes, int(dcls[d])] += 1
    return M


SIZE_BINS_PX: tuple[float, ...] = (0.0, 20.0, 40.0, 80.0, float("inf"))


def size_band_label(band: int, bins: tuple[float, ...] = SIZE_BINS_PX) -> str:
    """The name of band ``band`` of ``bins`` (pixels): "20-40", or "80+" for the open last one.

    >>> [size_band_label(b) for b in (0, 3)]
    ['0-20', '80+']
    """
    lo, hi = bins[band], bins[band + 1]
    return f"{lo:g}+" if math.isinf(hi) else f"{lo:g}-{hi:g}"


def recall_by_size(
    images: list[ImageBoxes],
    group_of_class: list[str],
    conf: float,
    bins: tuple[float, ...] = SIZE_BINS_PX,
    iou_min: float = 0.5,
    classes_first: bool = False,
) -> list[dict]:
    """Per group of classes and band of box size (the shorter side of the true box, pixels):
    how many true boxes, the fraction found by a detection of any class (class-agnostic
    match at ``iou_min``, confidence >= ``conf``) and the fraction found with the right
    class. Tells whether a detector fails to see objects or to name them, and from how far.
    With ``classes_first`` the pairs are :func:`match_classes_first`'s (right-class pairs first).

    >>> im = ImageBoxes(gt_boxes=np.array([[0, 0, 10, 10], [0, 0, 50, 50]], float),
    ...     gt_classes=np.array([0, 1]), det_boxes=np.array([[0, 0, 50, 50]], float),
    ...     det_classes=np.array([0]), det_scores=np.array([0.9]))
    >>> [(r["group"], r["band_px"], r["n"], r["found"], r["right_class"])
    ...  for r in recall_by_size([im], ["a", "a"], 0.25, (0, 20, float("inf")))]
    [('a', '0-20', 1, 0.0, 0.0), ('a', '20+', 1, 1.0, 0.0)]
    """
    counts: dict[tuple[str, int], list[int]] = {}
    for im in images:
        keep = im.det_scores >= conf
        dcls = im.det_classes[keep]
        if classes_first:
            matched = dict(match_classes_first(im.gt_boxes, im.gt_classes, im.det_boxes[keep], dcls, iou_min))
        else:
            matched = dict(match_boxes(im.gt_boxes, im.det_boxes[keep], iou_min))
        for g, box in enumerate(im.gt_boxes):
            side = min(box[2] - box[0], box[3] - box[1])
            band = int(np.searchsorted(bins, side, side="right")) - 1
            c = int(im.gt_classes[g])
            key = (group_of_class[c], min(band, len(bins) - 2))
            n_found_right = counts.setdefault(key, [0, 0, 0])
            n_found_right[0] += 1
            if g in matched:
                n_found_right[1] += 1
                n_found_right[2] += int(dcls[matched[g]] == c)
    rows = []
    for (group, band), (n, found, right) in sorted(counts.items()):
        rows.append(
            {
                "group": group,
                "band_px": size_band_label(band, bins),
                "n": n,
                "found": round(found / n, 4),
                "right_class": round(right / n, 4),
            }
        )
    return rows
