"""Hard-example mining: the frames on which a detector errs, by object type.

Online hard example mining ([Shrivastava2016], docs/SOURCES.md) trains on the examples the
current model gets wrong rather than on all of them; ``poibench route-frames --mine`` does it
per frame: it runs a detector on each tour frame and keeps the frames where it makes a mistake
a trial pays for, and a sample of the rest.

A frame's mistakes are counted by object type (the pipeline's identity; a placard's label is
the label classifier's business): each labelled object and each detection at the operating
confidence are paired one to one at IoU >= 0.5, each type's own pairs first
(:func:`eval.detector.metrics.match_classes_first`). Then

- ``missed T``: a labelled object of type T, at least ``min_px`` on its short side, with no
  detection on it;
- ``T as U``: a labelled object of type T boxed only as type U;
- ``false U``: a detection of type U on no labelled object and on no object too hidden to be
  labelled (the dataset's ignore boxes, :func:`eval.detector.metrics.drop_ignored`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from eval.detector.metrics import ImageBoxes, drop_ignored, match_classes_first
from poi.core.names import CLASS_TYPES, RESCUE_CLASSES

IOU_MIN = 0.5
MIN_MISSED_PX = 20.0  # a missed object counts from this short side (smaller ones trials rarely lose)
_RESCUE_TYPES = CLASS_TYPES[: len(RESCUE_CLASSES)]  # the type of each RESCUE_CLASSES class
TYPES: tuple[str, ...] = tuple(dict.fromkeys(_RESCUE_TYPES))
TYPE_OF_CLASS = np.array([TYPES.index(t) for t in _RESCUE_TYPES])  # class index -> index into TYPES


def frame_mistakes(
    gt_boxes: np.ndarray,
    gt_classes: Sequence[int],
    det_boxes: np.ndarray,
    det_classes: Sequence[int],
    ignore_boxes: np.ndarray | None = None,
    ignore_classes: Sequence[int] = (),
    min_px: float = MIN_MISSED_PX,
) -> list[str]:
    """The detector's mistakes on one frame (module docstring), sorted; classes are indices
    into ``RESCUE_CLASSES``, boxes (x1, y1, x2, y2) pixels, the detections those kept at the
    operating confidence.

    >>> box = np.array([[0, 0, 40, 40.0]])
    >>> valve, doll = RESCUE_CLASSES.index("valve"), RESCUE_CLASSES.index("baby-doll")
    >>> frame_mistakes(box, [valve], np.array([[1, 0, 40, 40.0], [100, 100, 130, 130]]), [doll, doll])
    ['false baby-doll', 'valve as baby-doll']
    >>> frame_mistakes(box, [valve], np.zeros((0, 4)), [])
    ['missed valve']
    >>> frame_mistakes(box / 4, [valve], np.zeros((0, 4)), [])  # 10 px: too small to count
    []
    """
    gt_t = TYPE_OF_CLASS[np.asarray(gt_classes, dtype=int)]
    det_t = TYPE_OF_CLASS[np.asarray(det_classes, dtype=int)]
    im = ImageBoxes(
        gt_boxes=np.asarray(gt_boxes, float).reshape(-1, 4),
        gt_classes=gt_t,
        det_boxes=np.asarray(det_boxes, float).reshape(-1, 4),
        det_classes=det_t,
        det_scores=np.ones(len(det_t)),
    )
    if ignore_boxes is not None and len(ignore_boxes):
        ign_t = TYPE_OF_CLASS[np.asarray(ignore_classes, dtype=int)]
        im = drop_ignored(im, np.asarray(ignore_boxes, float).reshape(-1, 4), ign_t)
    pairs = match_classes_first(im.gt_boxes, im.gt_classes, im.det_boxes, im.det_classes, IOU_MIN)
    out = []
    paired_gt = {g: d for g, d in pairs}
    paired_det = {d for _, d in pairs}
    for g, (x1, y1, x2, y2) in enumerate(im.gt_boxes):
        t = TYPES[int(im.gt_classes[g])]
        if g in paired_gt:
            u = TYPES[int(im.det_classes[paired_gt[g]])]
            if u != t:
                out.append(f"{t} as {u}")
        elif min(x2 - x1, y2 - y1) >= min_px:
            out.append(f"missed {t}")
    out += [f"false {TYPES[int(c)]}" for d, c in enumerate(im.det_classes) if d not in paired_det]
    return sorted(out)
