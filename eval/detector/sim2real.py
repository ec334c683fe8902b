"""``poibench sim2real``: one detector on labelled real photos and on poibench renders of the same
labels, side by side at the photos' mix of box sizes (the card).

The photos are read and matched as ``evaluate-photos`` reads and matches them
(:mod:`eval.detector.photos`: one to one at IoU >= 0.5, right-class pairs first). The renders
are fresh trial-looking scenes (``DatasetSpec.trial_looks`` with the trial's still colour
camera) hanging only the hazmat labels the photos show. Per label and over all labels the card
gives, for each side:

* right-label recall: the share of labelled placards paired with a detection of their label;
* recall as a placard: paired with a detection of any hazmat label;
* false detections an image: detections paired with no labelled box
  (:data:`eval.detector.photos.FALSE_DETECTION`), of any class and of a hazmat label;
* what each label's placards were named: the share of each outcome, its own label, another
  class, or missed (:func:`named_shares`), the renders' at the photos' size mix: where a gap is
  a confusion (one label read as another on one side only) rather than a miss.

Renders show placards at other sizes than hand-held photos do (more far away), and recall
depends on size, so the renders' shares are also given **at the photos' size mix**
(post-stratification): a rendered placard of label c whose box's shorter side falls in size
bin b (:data:`SIZE_BINS_PX`, at the scale of a frame whose long side is 640 px, as a detector that
letterboxes by the long side sees it: :func:`eval.detector.quality.frame_scales`) weighs

    w_cb = p_photo(c, b) / p_render(c, b)

with p the share of each side's placards in cell (c, b), so the weighted renders have the
photos' mix of labels and, within a label, of sizes; cells with photos but no renders are left
out, and the share of photo placards in them is given (``covered``).

A robot sees more placards obliquely than a photographer shoots them, and a foreshortened
placard is harder to find, so the card also weighs the renders to the photos' mix of sizes **and
box shapes**: the cells are (label, size bin, shape bin), the shape the box's shorter side over
its longer (:data:`SHAPE_BINS`; a diamond seen face on is 1, one seen at 60 degrees off its
normal about 0.5). That column compares like views with like, which is what says whether the
renders look real; the size-matched one keeps the views a robot gets.

Intervals (95%): a share of n placards, k hits, is given Wilson's score interval
([Wilson1927]_); a weighted share p_w = sum w h / sum w the same interval at Kish's effective
sample size n_eff = (sum w)^2 / sum w^2 ([Kish1965]_, section 11.7), with p_w n_eff hits; both
lie in [0, 1] and hold their point. Placards of one image are not independent (one lighting,
one camera), which these intervals ignore, so they are somewhat narrow. The gap of a label,
render (at the photos' mix) minus photo right-label recall, has Newcombe's hybrid score
interval from the two ([Newcombe1998]_, method 10). False detections an image get the seeded
bootstrap percentile interval of their mean over images ([Efron1993]_, section 13.3). Labels
with fewer than :data:`TOO_FEW` placards on either side are flagged.

The photometry of the two sets of placard crops (labelled boxes with a shorter side of at
least :data:`PHOTOMETRY_MIN_PX`, as the project's earlier sharpness figures were taken):
brightness (mean grey, ITU-R BT.601 luma as OpenCV's ``COLOR_RGB2GRAY``), saturation (mean
HSV saturation, 0-255), black and white levels (5th and 95th percentile of grey, as
``docs/guides/training.md`` measured lifted blacks), sharpness (variance of the grey crop's
Laplacian, OpenCV's 3x3 aperture-1 kernel); medians of each side, the renders' also weighted
to the photos' mix.

References
----------
Full entries in docs/SOURCES.md.

.. [Wilson1927] E. B. Wilson, "Probable inference, the law of succession, and statistical
   inference", Journal of the American Statistical Association 22, 1927.
.. [Kish1965] L. Kish, "Survey Sampling", Wiley, 1965.
.. [Newcombe1998] R. G. Newcombe, "Interval estimation for the difference between independent
   proportions: comparison of eleven methods", Statistics in Medicine 17, 1998.
.. [Efron1993] B. Efron, R. J. Tibshirani, "An Introduction to the Bootstrap", Chapman & Hall,
   1993.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from eval.detector.label_eval import wilson
from eval.detector.metrics import ImageBoxes, recall_by_size, scaled_boxes, size_band_label
from eval.detector.photos import (
    FALSE_DETECTION,
    HAZMAT_IDS,
    IOU_MIN,
    REAL_SET_FOLD,
    PhotoFolder,
    outcome,
    write_overlay,
)
from eval.detector.quality import FRAME_LONG_SIDE_PX, DetectorQualityError, LabelledImage
from eval.detector.sim2real_paste import GAP_PARTS, format_decomposition
from eval.stats import bootstrap_means
from eval.text import signed_interval
from poi.core.names import RESCUE_CLASSES

SIZE_BINS_PX: tuple[float, ...] = (0.0, 20.0, 40.0, 80.0, 160.0, float("inf"))  # shorter box side
SHAPE_BINS: tuple[float, ...] = (0.0, 0.75, 0.9, float("inf"))  # shorter / longer box side
TOO_FEW = 20  # placards a side below which a label's gap is flagged
MISSED = -1  # Side.named of a placard no detection is paired with
NAMED_SHOWN = 3  # outcomes a side the card's Markdown names per label (card.json keeps them all)
PHOTOMETRY_MIN_PX = 40.0  # crops with a shorter side under this are left out of the photometry
BOOTSTRAP_RESAMPLES = 2000
GROUPS = ["hazmat label" if i in HAZMAT_IDS else "other type" for i in range(len(RESCUE_CLASSES))]
PHOTOMETRY_KEYS = ("brightness", "saturation", "black", "white", "sharpness")
INTERVALS = (
    "95%: recall, Wilson's score interval (Wilson 1927), the renders at the photos' mix at Kish's "
    "effective n = (sum w)^2 / sum w^2 (Kish 1965); gap, Newcombe's hybrid score interval (Newcombe "
    "1998, method 10); false detections an image, seeded bootstrap percentile over images (Efron and "
    "Tibshirani 1993, 13.3); with --decompose, the gap's parts, the same over each side's placards"
)


# ---------------------------------------------------------------------------- the maths


@dataclass(kw_only=True)
class Share:
    """A share of placards with its 95% interval; ``n_eff`` equals ``n`` when unweighted."""

    value: float
    lo: float
    hi: float
    n: int
    n_eff: float

    def to_dict(self) -> dict:
        return {
            "value": round(self.value, 4),
            "ci95": [round(self.lo, 4), round(self.hi, 4)],
            "n": self.n,
            "n_eff": round(self.n_eff, 1),
        }


def kish_n_eff(w: np.ndarray) -> float:
    """Kish's effective sample size of weights ``w`` ([Kish1965]_, 11.7): n_eff = (sum w)^2 / sum w^2.

    >>> kish_n_eff(np.ones(4)), kish_n_eff(np.array([1.0, 1.0, 2.0, 0.0]))
    (4.0, 2.6666666666666665)
    """
    w = np.asarray(w, dtype=float)
    s2 = float(np.sum(w * w))
    return float(np.sum(w)) ** 2 / s2 if s2 > 0 else 0.0


def weighted_share(hits: np.ndarray, w: np.ndarray | None = None) -> Share | None:
    """The share p_w = sum w h / sum w of ``hits`` (bool, one a placard) and its Wilson interval at
    Kish's effective n ([Wilson1927]_, [Kish1965]_): wilson(p_w n_eff, n_eff). Unweighted
    (``w`` None) it is k / n with Wilson's interval. None without placards of positive weight.

    >>> s = weighted_share(np.array([True, True, False, False]), np.array([1.0, 1.0, 2.0, 0.0]))
    >>> round(s.value, 4), round(s.n_eff, 4), s.n, 0 <= s.lo <= s.value <= s.hi <= 1
    (0.5, 2.6667, 4, True)
    """
    h = np.asarray(hits, dtype=bool)
    w = np.ones(len(h)) if w is None else np.asarray(w, dtype=float)
    total = float(w.sum())
    if len(h) == 0 or total <= 0:
        return None
    p = float(np.sum(w * h)) / total
    n_eff = kish_n_eff(w)
    lo, hi = wilson(p * n_eff, n_eff)
    # the score interval holds its point; keep it so in the last bit
    return Share(value=p, lo=min(lo, p), hi=max(hi, p), n=len(h), n_eff=n_eff)


def newcombe_gap(a: Share, b: Share) -> tuple[float, float, float]:
    """a - b with Newcombe's hybrid score interval from the two Wilson intervals ([Newcombe1998]_,
    method 10): d - sqrt((a - lo_a)^2 + (hi_b - b)^2), d + sqrt((hi_a - a)^2 + (b - lo_b)^2); it
    lies in [-1, 1].

    >>> a = Share(value=0.8, lo=0.7, hi=0.9, n=50, n_eff=50.0)
    >>> [round(x, 4) for x in newcombe_gap(a, Share(value=0.5, lo=0.4, hi=0.6, n=50, n_eff=50.0))]
    [0.3, 0.1586, 0.4414]
    """
    d = a.value - b.value
    lo = d - math.sqrt((a.value - a.lo) ** 2 + (b.hi - b.value) ** 2)
    hi = d + math.sqrt((a.hi - a.value) ** 2 + (b.value - b.lo) ** 2)
    return d, max(-1.0, lo), min(1.0, hi)


def size_bins(side_px: np.ndarray, bins: Sequence[float] = SIZE_BINS_PX) -> np.ndarray:
    """The bin of each box's shorter side in ``bins`` (pixels, the last open-ended).

    >>> size_bins(np.array([5.0, 20.0, 79.9, 80.0, 500.0])).tolist()
    [0, 1, 2, 3, 4]
    """
    b = np.searchsorted(np.asarray(bins), np.asarray(side_px, dtype=float), side="right") - 1
    return np.clip(b, 0, len(bins) - 2)


@dataclass(kw_only=True)
class CellWeights:
    """Post-stratification of the renders on (label, size bin) cells to the photos' mix."""

    photo: np.ndarray  # (C, B) photo placards a cell
    render: np.ndarray  # (C, B) rendered placards a cell
    weight: np.ndarray  # (C, B) w_cb = p_photo(c, b) / p_render(c, b); 0 where no renders

    def covered(self, c: int | None = None) -> float | None:
        """The share of photo placards (of label row ``c``, or all) in cells the renders have."""
        ph = self.photo if c is None else self.photo[c]
        rd = self.render if c is None else self.render[c]
        total = int(ph.sum())
        return float(ph[rd > 0].sum() / total) if total else None


def cell_weights(photo_cells: np.ndarray, render_cells: np.ndarray, shape: tuple[int, int]) -> CellWeights:
    """Weights w_cb = p_photo(c, b) / p_render(c, b) from the (label row, bin) cell of each photo
    and each rendered placard ((n, 2) integer arrays); 0 in cells without renders.

    >>> w = cell_weights(np.array([[0, 0], [0, 1], [0, 1], [0, 1]]), np.array([[0, 0], [0, 0], [0, 1]]), (1, 2))
    >>> w.weight.round(4).tolist(), w.covered()
    ([[0.375, 2.25]], 1.0)
    """
    photo = np.zeros(shape, dtype=np.int64)
    render = np.zeros(shape, dtype=np.int64)
    np.add.at(photo, tuple(np.asarray(photo_cells, int).reshape(-1, 2).T), 1)
    np.add.at(render, tuple(np.asarray(render_cells, int).reshape(-1, 2).T), 1)
    p_photo = photo / max(int(photo.sum()), 1)
    p_render = render / max(int(render.sum()), 1)
    # w_cb = p_photo(c, b) / p_render(c, b)
    weight = np.divide(p_photo, p_render, out=np.zeros(shape), where=render > 0)
    return CellWeights(photo=photo, render=render, weight=weight)


def rate_interval(
    counts: np.ndarray, rng: np.random.Generator, resamples: int = BOOTSTRAP_RESAMPLES
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Means over images of ``counts`` ((n_img, K): false detections an image, K kinds) with their
    95% bootstrap percentile intervals ([Efron1993]_, 13.3): the images drawn with replacement
    ``resamples`` times (:func:`eval.stats.bootstrap_means`), the 2.5% and 97.5% quantiles of the means. Each
    end is a mean of counts, so it is >= 0 and within [min, max] of the counts.

    >>> m, lo, hi = rate_interval(np.array([[0], [0], [2], [2]]), np.random.default_rng(0))
    >>> m.tolist(), bool(0 <= lo[0] < 1 < hi[0] <= 2)
    ([1.0], True)
    """
    x = np.asarray(counts, dtype=float)  # (n, K)
    if len(x) == 0:
        nan = np.full(x.shape[1], np.nan)
        return nan, nan, nan
    lo, hi = np.quantile(bootstrap_means(x, rng, resamples), [0.025, 0.975], axis=0)  # (K,) each
    return x.mean(axis=0), np.clip(lo, x.min(axis=0), None), np.clip(hi, None, x.max(axis=0))


def _parts(photos: np.ndarray, renders: np.ndarray) -> np.ndarray:
    """(..., 4): the gap as it is and its three parts (:mod:`eval.detector.sim2real_paste`) from the
    recalls of each side, ``photos`` and ``renders`` (..., 3) in the order of its ``VARIANTS``:

        A_r - A_p = (D_r - D_p) + [(T_r - D_r) - (T_p - D_p)] + [(A_r - T_r) - (A_p - T_p)]
    """
    (a_p, d_p, t_p), (a_r, d_r, t_r) = np.moveaxis(photos, -1, 0), np.moveaxis(renders, -1, 0)
    frame = d_r - d_p
    printed = (t_r - d_r) - (t_p - d_p)
    placard = (a_r - t_r) - (a_p - t_p)
    return np.stack([a_r - a_p, frame, printed, placard], axis=-1)


def gap_parts(photos: np.ndarray, renders: np.ndarray, seed: int) -> dict | None:
    """The gap of the placards as they are (renders minus photos, points of recall) and its three
    parts (:mod:`eval.detector.sim2real_paste`'s note), each ``{"value", "ci95"}``: ``{"gap": ...,
    part: ...}`` for each of ``GAP_PARTS``; None where a side pasted no placard. ``photos``,
    ``renders``: (n, 3) bool per pasted placard (``decompose_side``); the 95% intervals are bootstrap
    percentile intervals ([Efron1993]_, 13.3), each side's placards resampled on their own.

    >>> p = np.array([[1, 1, 1], [1, 1, 0], [0, 1, 1], [0, 1, 1]], bool)  # A 0.5, D 1.0, T 0.75
    >>> r = np.array([[0, 1, 0], [0, 1, 1], [0, 0, 0], [1, 1, 0]], bool)  # A 0.25, D 0.75, T 0.25
    >>> d = gap_parts(p, r, seed=0)
    >>> [d[k]["value"] for k in ("gap", *GAP_PARTS)]  # -25 = -25 + (-50 + 25) + (0 - (-25))
    [-25.0, -25.0, -25.0, 25.0]
    """
    if not len(photos) or not len(renders):
        return None
    value = _parts(photos.mean(axis=0), renders.mean(axis=0))  # (4,)
    rng = np.random.default_rng(seed)
    boot_p, boot_r = (bootstrap_means(side, rng, BOOTSTRAP_RESAMPLES) for side in (photos, renders))  # (R, 3) each
    boot = _parts(boot_p, boot_r)  # (R, 4)
    lo, hi = np.quantile(boot, [0.025, 0.975], axis=0)
    return {
        name: {"value": round(100 * float(value[j]), 1), "ci95": [round(100 * lo[j], 1), round(100 * hi[j], 1)]}
        for j, name in enumerate(("gap", *GAP_PARTS))
    }


def gap_parts_by_label(hits: dict[str, np.ndarray], labels: dict[str, list[str]], seed: int) -> list[dict]:
    """:func:`gap_parts` of each label with at least :data:`TOO_FEW` pasted placards on both sides,
    the largest gap (either way) first: ``[{"label", "n": {"photos", "renders"}, "gap": ..., part: ...}]``.
    ``hits`` and ``labels`` by side (``"photos"``, ``"renders"``): each pasted placard's outcomes and
    label (``decompose_side``). A label's parts add up to its gap as the whole card's do.

    >>> h = {"photos": np.ones((20, 3), bool), "renders": np.zeros((25, 3), bool)}
    >>> rows = gap_parts_by_label(h, {"photos": ["poison"] * 20, "renders": ["poison"] * 25}, seed=0)
    >>> r = rows[0]
    >>> r["label"], r["n"]["renders"], r["gap"]["value"], r["the frame around the placard"]["value"]
    ('poison', 25, -100.0, -100.0)
    """
    by_side = {side: np.asarray(labels[side], dtype=object) for side in ("photos", "renders")}
    rows = []
    for label in sorted(set(labels["photos"]) & set(labels["renders"])):
        sel = {side: by_side[side] == label for side in by_side}
        n = {side: int(sel[side].sum()) for side in sel}
        if min(n.values()) < TOO_FEW:
            continue
        parts = gap_parts(hits["photos"][sel["photos"]], hits["renders"][sel["renders"]], seed)
        rows.append({"label": label, "n": n, **parts})
    rows.sort(key=lambda r: (-abs(r["gap"]["value"]), r["label"]))
    return rows


def weighted_median(x: np.ndarray, w: np.ndarray | None = None) -> float | None:
    """The weighted median: the smallest x whose cumulative weight reaches half the total; with
    no weights, np.median. None without a value of positive weight.

    >>> x = np.array([1.0, 2.0, 3.0])
    >>> weighted_median(x), weighted_median(x, np.array([1, 1, 4.0]))
    (2.0, 3.0)
    """
    x = np.asarray(x, dtype=float)
    if w is None:
        return float(np.median(x)) if len(x) else None
    w = np.asarray(w, dtype=float)
    keep = w > 0
    if not keep.any():
        return None
    order = np.argsort(x[keep], kind="stable")
    cum = np.cumsum(w[keep][order])
    return float(x[keep][order][np.searchsorted(cum, cum[-1] / 2)])


def crop_photometry(rgb: np.ndarray, box: np.ndarray) -> dict[str, float] | None:
    """Brightness, saturation, black and white levels and sharpness (module docstring) of the
    crop of ``rgb`` (H, W, 3) inside ``box`` (x1, y1, x2, y2 pixels); None for an empty crop.

    >>> rgb = np.zeros((60, 60, 3), np.uint8); rgb[:, 30:] = (255, 0, 0)
    >>> p = crop_photometry(rgb, np.array([0, 0, 60, 60.0]))
    >>> round(p["brightness"], 1), round(p["saturation"], 1), p["black"], p["white"], p["sharpness"] > 0
    (38.0, 127.5, 0.0, 76.0, True)
    """
    h, w = rgb.shape[:2]
    x0, y0 = max(0, int(math.floor(box[0]))), max(0, int(math.floor(box[1])))
    x1, y1 = min(w, int(math.ceil(box[2]))), min(h, int(math.ceil(box[3])))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    crop = np.ascontiguousarray(rgb[y0:y1, x0:x1])
    grey = cv2.cvtColor(crop, cv2.COLOR_RGB2GRAY)
    sat = cv2.cvtColor(crop, cv2.COLOR_RGB2HSV)[..., 1]
    black, white = np.percentile(grey, [5, 95])
    return {
        "brightness": float(grey.mean()),
        "saturation": float(sat.mean()),
        "black": float(black),
        "white": float(white),
        "sharpness": float(cv2.Laplacian(grey.astype(np.float64), cv2.CV_64F).var()),
    }


# ---------------------------------------------------------------------------- one side


@dataclass(kw_only=True)
class Side:
    """The labelled hazmat placards of one side (photos or renders), one entry each, and the
    false detections of each image."""

    label: np.ndarray  # (n,) class index
    side_px: np.ndarray  # (n,) shorter side of the labelled box, at the frame's scale (quality.frame_scales)
    aspect: np.ndarray  # (n,) shorter over longer side of the labelled box, in (0, 1]
    named: np.ndarray  # (n,) class index of the detection paired with it, MISSED where none is
    image: np.ndarray  # (n,) index of its image
    box: np.ndarray  # (n, 4) xyxy pixels
    false: np.ndarray  # (n_img, len(RESCUE_CLASSES)) false detections an image, by detected class
    detections: int  # at the operating confidence, every class
    by_size: list[dict]  # hazmat placards' unweighted recall a size band (recall_by_size)
    photometry: list[dict[str, float] | None] = field(default_factory=list)  # per placard; None: too small

    @property
    def images(self) -> int:
        return len(self.false)

    @property
    def right(self) -> np.ndarray:
        """(n,) paired with a detection of its own label."""
        return self.named == self.label

    @property
    def placard(self) -> np.ndarray:
        """(n,) paired with a detection of any hazmat label."""
        return np.isin(self.named, list(HAZMAT_IDS))


def side_outcomes(
    results: Sequence[ImageBoxes],
    conf: float,
    bins: Sequence[float] = SIZE_BINS_PX,
    scales: np.ndarray | None = None,
) -> Side:
    """Every labelled hazmat placard of ``results`` with its outcome at ``conf``
    (:func:`eval.detector.photos.outcome`), each image's false detections by detected class, and
    the placards' recall in each band of ``bins`` (:func:`eval.detector.metrics.recall_by_size`).
    Sizes (``Side.side_px``, the bands) are the boxes' at ``scales``
    (:func:`eval.detector.quality.frame_scales`; 1 when not given); the boxes themselves stay in
    the image's pixels."""
    scales = np.ones(len(results)) if scales is None else np.asarray(scales, dtype=float)
    label, side, aspect, named, image, boxes = [], [], [], [], [], []
    false = np.zeros((len(results), len(RESCUE_CLASSES)), dtype=np.int64)
    detections = 0
    for k, im in enumerate(results):
        o = outcome(im, conf)
        b = o.boxes
        detections += len(b.det_boxes)
        np.add.at(false[k], b.det_classes[o.false].astype(int), 1)
        paired = dict(o.pairs)
        for g, xyxy in enumerate(b.gt_boxes):
            t = int(b.gt_classes[g])
            if t not in HAZMAT_IDS:
                continue
            label.append(t)
            w, h = xyxy[2] - xyxy[0], xyxy[3] - xyxy[1]
            side.append(min(w, h) * scales[k])
            aspect.append(min(w, h) / max(w, h, 1e-9))
            named.append(int(b.det_classes[paired[g]]) if g in paired else MISSED)
            image.append(k)
            boxes.append(xyxy)
    return Side(
        label=np.array(label, dtype=np.int64),
        side_px=np.array(side, dtype=float),
        aspect=np.array(aspect, dtype=float),
        named=np.array(named, dtype=np.int64),
        image=np.array(image, dtype=np.int64),
        box=np.array(boxes, dtype=float).reshape(-1, 4),
        false=false,
        detections=detections,
        by_size=[
            r
            for r in recall_by_size(
                [scaled_boxes(im, f) for im, f in zip(results, scales, strict=True)],
                GROUPS,
                conf,
                tuple(bins),
                iou_min=IOU_MIN,
                classes_first=True,
            )
            if r["group"] == "hazmat label"
        ],
    )


def measure_photometry(side: Side, images: Sequence[LabelledImage], min_px: float = PHOTOMETRY_MIN_PX) -> None:
    """Fill ``side.photometry``: :func:`crop_photometry` of each placard with a shorter side of at
    least ``min_px``, None for the others; each image read once."""
    side.photometry = [None] * len(side.label)
    for k in np.unique(side.image[side.side_px >= min_px]):
        bgr = cv2.imread(str(images[k].path))
        if bgr is None:
            raise DetectorQualityError(f"{images[k].path}: not a readable image")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        for i in np.flatnonzero((side.image == k) & (side.side_px >= min_px)):
            side.photometry[i] = crop_photometry(rgb, side.box[i])


def photo_labels(folders: Sequence[PhotoFolder]) -> list[str]:
    """The hazmat labels the photo folders label, in RESCUE_CLASSES order; a folder with no
    labelled placard is an error naming it."""
    seen: set[int] = set()
    for f in folders:
        here = {int(c) for im in f.images for c in im.classes if int(c) in HAZMAT_IDS}
        if not here:
            raise DetectorQualityError(
                f"{f.root}: no labelled hazmat placard in {len(f.images)} images (labels/*.txt, classes 0-15)"
            )
        seen |= here
    return [RESCUE_CLASSES[c] for c in sorted(seen)]


def render_labels(labels: Sequence[str], absent: str) -> list[str]:
    """The hazmat labels the renders hang for photos that label ``labels``: those, and with
    ``absent == "map"`` also every label the photo set files under one of them
    (:data:`eval.detector.photos.REAL_SET_FOLD`: hazmat-photos-dev calls INHALATION HAZARD
    placards ``poison``), so each folded class shows on the renders the looks it holds on the
    photos. RESCUE_CLASSES order.

    >>> render_labels(["explosive", "poison"], "map")
    ['explosive', 'blasting-agent', 'inhalation-hazard', 'poison']
    >>> render_labels(["explosive", "poison"], "keep")
    ['explosive', 'poison']
    """
    wanted = set(labels)
    if absent == "map":
        wanted |= {label for label, into in REAL_SET_FOLD.items() if into in wanted}
    return [c for c in RESCUE_CLASSES if c in wanted]


# ---------------------------------------------------------------------------- the card


def _side_shares(side: Side, sel: np.ndarray, w: np.ndarray | None) -> dict:
    out = {}
    for key, hits in (("recall_right", side.right), ("recall_placard", side.placard)):
        s = weighted_share(hits[sel], None if w is None else w[sel])
        out[key] = None if s is None else s.to_dict()
    return out


def named_shares(named: np.ndarray, w: np.ndarray | None = None) -> dict | None:
    """What a label's placards were named: the (weighted) share of each outcome, a class name or
    ``"missed"`` (:data:`MISSED`), with its 95% interval (:func:`weighted_share`: Wilson's at Kish's
    effective n), largest first (equal shares, as rounded, by name); None without placards or
    weight. ``n`` counts every placard, those of weight 0 (sizes the photos lack) included, as
    :func:`weighted_share` does; ``n_eff`` is Kish's effective size (:func:`kish_n_eff`). Shares are
    rounded to 4 places and need not add up to exactly 1.

    >>> out = named_shares(np.array([12, 12, 12, 15, -1]))
    >>> out["n"], {c: s["value"] for c, s in out["shares"].items()}
    (5, {'poison': 0.6, 'infectious-substance': 0.2, 'missed': 0.2})
    >>> {c: s["value"] for c, s in named_shares(np.array([12, 15]), np.array([3.0, 1.0]))["shares"].items()}
    {'poison': 0.75, 'infectious-substance': 0.25}
    """
    named = np.asarray(named, dtype=np.int64)
    shares: dict[str, Share] = {}
    for k in np.unique(named):
        share = weighted_share(named == k, w)
        if share is None:
            return None
        if share.value > 0:
            shares["missed" if k == MISSED else RESCUE_CLASSES[int(k)]] = share
    if not shares:
        return None
    order = sorted(shares, key=lambda c: (-round(shares[c].value, 4), c))
    rows = {c: shares[c].to_dict() for c in order}  # every share has the label's n and n_eff
    first = rows[order[0]]
    return {
        "n": first["n"],
        "n_eff": first["n_eff"],
        "shares": {c: {"value": row["value"], "ci95": row["ci95"]} for c, row in rows.items()},
    }


def _rates(side: Side, rng: np.random.Generator, labels: list[str]) -> dict:
    """False detections an image: any class, a hazmat label, another type, and each of ``labels``
    (by detected class)."""
    hz = np.array([i in HAZMAT_IDS for i in range(len(RESCUE_CLASSES))])
    cols = [side.false.sum(axis=1), side.false[:, hz].sum(axis=1), side.false[:, ~hz].sum(axis=1)]
    cols += [side.false[:, RESCUE_CLASSES.index(c)] for c in labels]
    mean, lo, hi = rate_interval(np.stack(cols, axis=1), rng)  # (3 + L,) each

    def entry(j: int) -> dict:
        return {"value": round(float(mean[j]), 4), "ci95": [round(float(lo[j]), 4), round(float(hi[j]), 4)]}

    return {
        "images": side.images,
        "any": entry(0),
        "hazmat": entry(1),
        "other": entry(2),
        "by_label": {c: entry(3 + j) for j, c in enumerate(labels)},
    }


def _photometry(side: Side, w: np.ndarray | None) -> dict:
    ok = [i for i, p in enumerate(side.photometry) if p is not None]
    out: dict = {"crops": len(ok)}
    for key in PHOTOMETRY_KEYS:
        x = np.array([side.photometry[i][key] for i in ok])
        m = weighted_median(x, None if w is None else w[ok]) if ok else None
        out[key] = None if m is None else round(m, 1)
    return out


def _post_stratify(
    row_p: np.ndarray, row_r: np.ndarray, cell_p: np.ndarray, cell_r: np.ndarray, shape: tuple[int, int]
) -> tuple[CellWeights, np.ndarray]:
    """:func:`cell_weights` on (label row, cell) of the placards of a reported label (row >= 0),
    and each rendered placard's weight w_i (0 for a label the card does not report)."""
    keep_p, keep_r = row_p >= 0, row_r >= 0
    cw = cell_weights(
        np.stack([row_p[keep_p], cell_p[keep_p]], axis=1), np.stack([row_r[keep_r], cell_r[keep_r]], axis=1), shape
    )
    return cw, np.where(keep_r, cw.weight[np.maximum(row_r, 0), cell_r], 0.0)


def _gap_entry(key: str, renders: Share | None, photos: Share | None) -> dict:
    """``key`` and ``key_ci95``: the gap renders minus photos (:func:`newcombe_gap`), None without
    both shares."""
    gap = newcombe_gap(renders, photos) if renders is not None and photos is not None else None
    return {
        key: None if gap is None else round(gap[0], 4),
        f"{key}_ci95": None if gap is None else [round(gap[1], 4), round(gap[2], 4)],
    }


def shape_band_labels() -> list[str]:
    """The shape bins' names (:func:`eval.detector.metrics.size_band_label` on :data:`SHAPE_BINS`).

    >>> shape_band_labels()
    ['0-0.75', '0.75-0.9', '0.9+']
    """
    return [size_band_label(a, SHAPE_BINS) for a in range(len(SHAPE_BINS) - 1)]


def _shape_mix(aspect_p: np.ndarray, aspect_r: np.ndarray, right_p: np.ndarray, right_r: np.ndarray) -> list[dict]:
    """Placards and right-label recall of each side in each shape bin (:data:`SHAPE_BINS`), unweighted."""
    a_p, a_r = size_bins(aspect_p, SHAPE_BINS), size_bins(aspect_r, SHAPE_BINS)
    out = []
    for a, name in enumerate(shape_band_labels()):
        sp, sr = a_p == a, a_r == a
        out.append(
            {
                "shape": name,
                "photos": int(sp.sum()),
                "renders": int(sr.sum()),
                "p_photo": round(float(sp.mean()), 4) if len(sp) else None,
                "p_render": round(float(sr.mean()), 4) if len(sr) else None,
                "recall_photos": round(float(right_p[sp].mean()), 4) if sp.any() else None,
                "recall_renders": round(float(right_r[sr].mean()), 4) if sr.any() else None,
            }
        )
    return out


def sim2real_card(
    photos: Side,
    renders: Side,
    labels: list[str],
    *,
    seed: int,
    bins: Sequence[float] = SIZE_BINS_PX,
) -> dict:
    """Every figure of the card (module docstring), from the two sides' placards and images.

    ``labels`` are the hazmat labels the card reports (the photos'); placards of other labels
    on either side are left out of the recalls. Rows of the per-label table are sorted by the
    size of the gap, labels with too few placards last."""
    row_of = {RESCUE_CLASSES.index(c): j for j, c in enumerate(labels)}  # class index -> row of labels
    row_p = np.array([row_of.get(int(c), -1) for c in photos.label], dtype=np.int64)  # (n_photo,)
    row_r = np.array([row_of.get(int(c), -1) for c in renders.label], dtype=np.int64)  # (n_render,)
    keep_p, keep_r = row_p >= 0, row_r >= 0
    bin_p, bin_r = size_bins(photos.side_px, bins), size_bins(renders.side_px, bins)
    cw, w_r = _post_stratify(row_p, row_r, bin_p, bin_r, (len(labels), len(bins) - 1))
    # the (size, shape) cell: size bin b and shape bin a as one index b * A + a
    n_shape = len(SHAPE_BINS) - 1
    both_p = bin_p * n_shape + size_bins(photos.aspect, SHAPE_BINS)
    both_r = bin_r * n_shape + size_bins(renders.aspect, SHAPE_BINS)
    cws, w_rs = _post_stratify(row_p, row_r, both_p, both_r, (len(labels), (len(bins) - 1) * n_shape))
    rng = np.random.default_rng([seed, 59])
    rates_p, rates_r = _rates(photos, rng, labels), _rates(renders, rng, labels)
    per_label = []
    for j, c in enumerate(labels):
        sel_p, sel_r = row_p == j, row_r == j
        ph = weighted_share(photos.right[sel_p])
        rm = weighted_share(renders.right[sel_r], w_r[sel_r])
        rs = weighted_share(renders.right[sel_r], w_rs[sel_r])
        per_label.append(
            {
                "label": c,
                "photos": {**_side_shares(photos, sel_p, None), "false_per_image": rates_p["by_label"][c]},
                "renders": {**_side_shares(renders, sel_r, None), "false_per_image": rates_r["by_label"][c]},
                "renders_matched": _side_shares(renders, sel_r, w_r),
                "renders_matched_shape": _side_shares(renders, sel_r, w_rs),
                "covered": None if cw.covered(j) is None else round(cw.covered(j), 4),
                "covered_shape": None if cws.covered(j) is None else round(cws.covered(j), 4),
                **_gap_entry("gap", rm, ph),
                **_gap_entry("gap_shape", rs, ph),
                "named": {
                    "photos": named_shares(photos.named[sel_p]),
                    "renders_matched": named_shares(renders.named[sel_r], w_r[sel_r]),
                },
                "too_few": bool(sel_p.sum() < TOO_FEW or sel_r.sum() < TOO_FEW),
            }
        )
    per_label.sort(key=lambda r: (r["too_few"], r["gap"] is None, -abs(r["gap"] or 0.0), r["label"]))
    ph_all, rm_all = weighted_share(photos.right[keep_p]), weighted_share(renders.right[keep_r], w_r[keep_r])
    rs_all = weighted_share(renders.right[keep_r], w_rs[keep_r])
    photo_mix = cw.photo.sum(axis=0)
    render_mix = cw.render.sum(axis=0)
    return {
        "labels": labels,
        "size_bins_px": [size_band_label(b, tuple(bins)) for b in range(len(bins) - 1)],
        "frame_long_side_px": FRAME_LONG_SIDE_PX,
        "size_mix": [
            {
                "band_px": size_band_label(b, tuple(bins)),
                "photos": int(photo_mix[b]),
                "renders": int(render_mix[b]),
                "p_photo": round(float(photo_mix[b] / max(photo_mix.sum(), 1)), 4),
                "p_render": round(float(render_mix[b] / max(render_mix.sum(), 1)), 4),
            }
            for b in range(len(bins) - 1)
        ],
        "weights": {c: [round(float(v), 4) for v in cw.weight[j]] for j, c in enumerate(labels)},
        "shape_bins": shape_band_labels(),
        "shape_mix": _shape_mix(
            photos.aspect[keep_p], renders.aspect[keep_r], photos.right[keep_p], renders.right[keep_r]
        ),
        "covered": None if cw.covered() is None else round(cw.covered(), 4),
        "covered_shape": None if cws.covered() is None else round(cws.covered(), 4),
        "n_eff_renders_matched": round(kish_n_eff(w_r[keep_r]), 1),
        "n_eff_renders_matched_shape": round(kish_n_eff(w_rs[keep_r]), 1),
        "overall": {
            "photos": {**_side_shares(photos, keep_p, None), "false_per_image": _drop_labels(rates_p)},
            "renders": {**_side_shares(renders, keep_r, None), "false_per_image": _drop_labels(rates_r)},
            "renders_matched": _side_shares(renders, keep_r, w_r),
            "renders_matched_shape": _side_shares(renders, keep_r, w_rs),
            **_gap_entry("gap", rm_all, ph_all),
            **_gap_entry("gap_shape", rs_all, ph_all),
        },
        "per_label": per_label,
        "by_size": {
            "photos": photos.by_size,
            "renders": renders.by_size,
        },
        "photometry": {
            "min_side_px": PHOTOMETRY_MIN_PX,
            "photos": _photometry(photos, None),
            "renders": _photometry(renders, None),
            "renders_matched": _photometry(renders, w_r),
        },
        "intervals": INTERVALS,
        "false_detection": FALSE_DETECTION,
        "too_few": TOO_FEW,
    }


def _drop_labels(rates: dict) -> dict:
    return {k: v for k, v in rates.items() if k != "by_label"}


# ---------------------------------------------------------------------------- output

OVERLAY_NAME = "misses.jpg"


def misses(
    folder: PhotoFolder, results: Sequence[ImageBoxes], conf: float
) -> tuple[PhotoFolder, list[ImageBoxes]]:
    """``folder`` cut to its images with a labelled hazmat placard not found with its label, and
    their results (for :func:`eval.detector.photos.write_overlay`)."""
    keep = []
    for k, im in enumerate(results):
        o = outcome(im, conf)
        b = o.boxes
        paired = dict(o.pairs)
        if any(
            int(t) in HAZMAT_IDS and (g not in paired or int(b.det_classes[paired[g]]) != int(t))
            for g, t in enumerate(b.gt_classes)
        ):
            keep.append(k)
    cut = PhotoFolder(
        root=folder.root,
        name=f"{folder.name}: misses",
        images=[folder.images[k] for k in keep],
        without_labels=0,
        total_images=len(folder.images),
    )
    return cut, [results[k] for k in keep]


def _pct(s: dict | None, with_n: str = "n") -> str:
    if s is None:
        return "-"
    lo, hi = s["ci95"]
    n = f"n {s['n']}" if with_n == "n" else f"n_eff {s['n_eff']:.0f} of {s['n']}"
    return f"{100 * s['value']:.1f}% ({100 * lo:.1f}-{100 * hi:.1f}; {n})"


def _short_pct(s: dict | None) -> str:
    return "-" if s is None else f"{100 * s['value']:.0f}% ({100 * s['ci95'][0]:.0f}-{100 * s['ci95'][1]:.0f})"


def _share_pct(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.1f}%"


def _rate(r: dict | None) -> str:
    return "-" if r is None else f"{r['value']:.2f} ({r['ci95'][0]:.2f}-{r['ci95'][1]:.2f})"


def _points(gap: float | None, ci: list[float] | None) -> str:
    if gap is None or ci is None:
        return "-"
    return signed_interval(100 * gap, 100 * ci[0], 100 * ci[1])


def _label_cell(row: dict) -> str:
    """A per-label row's first cell: the label, marked when it has too few placards on a side."""
    return f"{row['label']}{' (too few)' if row['too_few'] else ''}"


def _named_cell(named: dict | None, label: str) -> str:
    """The commonest outcomes of one label's placards on one side, its own label as 'right'.

    >>> shares = {'poison': {'value': 0.6, 'ci95': [0.23, 0.88]}, 'missed': {'value': 0.4, 'ci95': [0.12, 0.77]}}
    >>> _named_cell({'n': 5, 'n_eff': 5.0, 'shares': shares}, 'poison')
    'right 60% (23-88), missed 40% (12-77)'
    """
    if named is None:
        return "-"
    top = list(named["shares"].items())[:NAMED_SHOWN]
    return ", ".join(f"{'right' if c == label else c} {_short_pct(s)}" for c, s in top)


def format_card(card: dict) -> str:
    """The card as Markdown: the headline, the gaps per label, what each label was named, the size
    and shape mixes, the photometry and, with --decompose, where the gap lies."""
    o = card["overall"]
    ph, rd, rm, rs = o["photos"], o["renders"], o["renders_matched"], o["renders_matched_shape"]
    src = card["photos"]
    rnd = card["renders"]
    held = f", held-back images of {card['holdout_of']} only" if card.get("holdout_of") else ""
    out = [
        "# sim2real card",
        "",
        f"Detector {card['model']}"
        + (f" with {card['label_model']}" if card.get("label_model") else "")
        + f", confidence >= {card['conf']}, matched at IoU >= {IOU_MIN}"
        + (", labels folded into the photo set's classes (--absent map)" if card.get("absent") == "map" else "")
        + ".",
        f"Photos: {', '.join(f['name'] for f in src['folders'])} ({src['images']} images, {src['placards']} "
        f"placards{held}). Renders: {rnd['scenes']} trial-looking scenes x {rnd['views']} views, trial camera, "
        f"seed {rnd['seed']} ({rnd['images']} images, {rnd['placards']} placards of the photos' "
        f"{len(card['labels'])} labels).",
        "",
    ]
    if card.get("error"):
        out += [f"**Error: {card['error']}**", ""]
    out += [
        "| | photos | renders | renders at the photos' sizes | at the photos' sizes and box shapes |",
        "|---|---|---|---|---|",
        f"| right-label recall | {_pct(ph['recall_right'])} | {_pct(rd['recall_right'])} "
        f"| {_pct(rm['recall_right'], 'n_eff')} | {_pct(rs['recall_right'], 'n_eff')} |",
        f"| recall as a placard (any hazmat label) | {_pct(ph['recall_placard'])} | {_pct(rd['recall_placard'])} "
        f"| {_pct(rm['recall_placard'], 'n_eff')} | {_pct(rs['recall_placard'], 'n_eff')} |",
        f"| false detections an image, any class | {_rate(ph['false_per_image']['any'])} "
        f"| {_rate(rd['false_per_image']['any'])} | - | - |",
        f"| - of a hazmat label | {_rate(ph['false_per_image']['hazmat'])} "
        f"| {_rate(rd['false_per_image']['hazmat'])} | - | - |",
        f"| - of another type (on photos: may be unlabelled objects) | {_rate(ph['false_per_image']['other'])} "
        f"| {_rate(rd['false_per_image']['other'])} | - | - |",
        f"| gap, right-label recall (points) | | | {_points(o['gap'], o['gap_ci95'])} "
        f"| {_points(o['gap_shape'], o['gap_shape_ci95'])} |",
        "",
        f"The renders at the photos' sizes weigh each rendered placard by p_photo(label, size bin) / "
        f"p_render(label, size bin), size bins of the box's shorter side {', '.join(card['size_bins_px'])} px "
        f"in a frame of {card['frame_long_side_px']:g} px on its long side (each image scaled so, as a detector "
        "letterboxing by the long side sees it); "
        f"{100 * (card['covered'] or 0):.1f}% of the photo placards fall in cells the renders have. "
        f"At the photos' sizes and box shapes the cells are (label, size bin, shape bin), the shape the box's "
        f"shorter side over its longer, bins {', '.join(card['shape_bins'])} (a face-on diamond 1; "
        f"{100 * (card['covered_shape'] or 0):.1f}% of the photo placards in cells the renders have): "
        "like views against like. False detections are not reweighted; on the photos, detections of other "
        "types (qr, door...) may be objects really there but unlabelled.",
        "",
        f"## Per label: the gap (renders at the photos' sizes minus photos, right label), largest first; "
        f"'too few': under {card['too_few']} placards on a side",
        "",
        "| label | placards: photos / renders | photos | renders | renders at photos' sizes | gap (points) "
        "| gap at sizes and shapes | as a placard: photos / renders at photos' sizes "
        "| false an image: photos / renders | covered |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in card["per_label"]:
        p, q, m = r["photos"], r["renders"], r["renders_matched"]
        n_p = p["recall_right"]["n"] if p["recall_right"] else 0
        n_r = q["recall_right"]["n"] if q["recall_right"] else 0
        covered = "-" if r["covered"] is None else f"{100 * r['covered']:.0f}%"
        out.append(
            f"| {_label_cell(r)} | {n_p} / {n_r} "
            f"| {_short_pct(p['recall_right'])} "
            f"| {_short_pct(q['recall_right'])} | {_short_pct(m['recall_right'])} "
            f"| {_points(r['gap'], r['gap_ci95'])} | {_points(r['gap_shape'], r['gap_shape_ci95'])} "
            f"| {_short_pct(p['recall_placard'])} / "
            f"{_short_pct(m['recall_placard'])} | {p['false_per_image']['value']:.3f} / "
            f"{q['false_per_image']['value']:.3f} | {covered} |"
        )
    out += [
        "",
        f"## What each label's placards were named: the {NAMED_SHOWN} commonest outcomes a side, with 95% "
        "intervals ('right': its own label; 'missed': no detection paired; card.json has them all)",
        "",
        "| label | photos | renders at the photos' sizes |",
        "|---|---|---|",
    ]
    for r in card["per_label"]:
        cells = [_named_cell(r["named"][s], r["label"]) for s in ("photos", "renders_matched")]
        out.append(f"| {_label_cell(r)} | " + " | ".join(cells) + " |")
    out += [
        "",
        "## Box sizes (shorter side, px): placards and right-label recall, unweighted",
        "",
        "| band | photos | renders | photos' share | renders' share |",
        "|---|---|---|---|---|",
    ]
    by_p = {r["band_px"]: r for r in card["by_size"]["photos"]}
    by_r = {r["band_px"]: r for r in card["by_size"]["renders"]}
    for m in card["size_mix"]:
        b = m["band_px"]
        cp = f"{m['photos']} ({100 * by_p[b]['right_class']:.0f}%)" if b in by_p else "0"
        cr = f"{m['renders']} ({100 * by_r[b]['right_class']:.0f}%)" if b in by_r else "0"
        out.append(f"| {b} | {cp} | {cr} | {100 * m['p_photo']:.1f}% | {100 * m['p_render']:.1f}% |")
    out += [
        "",
        "## Box shapes (shorter over longer side): placards and right-label recall, unweighted",
        "",
        "| shape | photos | renders | photos' share | renders' share |",
        "|---|---|---|---|---|",
    ]
    for m in card["shape_mix"]:
        cells = [(m["photos"], m["recall_photos"]), (m["renders"], m["recall_renders"])]
        cp, cr = (f"{n} ({100 * r:.0f}%)" if r is not None else str(n) for n, r in cells)
        shares = [m["p_photo"], m["p_render"]]
        out.append(f"| {m['shape']} | {cp} | {cr} | " + " | ".join(_share_pct(v) for v in shares) + " |")
    pm = card["photometry"]
    out += [
        "",
        f"## Photometry of the placard crops (shorter side >= {pm['min_side_px']:g} px), medians",
        "",
        "| | photos | renders | renders at the photos' sizes |",
        "|---|---|---|---|",
    ]
    for key, text in (
        ("crops", "crops"),
        ("brightness", "brightness (mean grey, 0-255)"),
        ("saturation", "saturation (mean HSV S, 0-255)"),
        ("black", "black level (5th percentile grey)"),
        ("white", "white level (95th percentile grey)"),
        ("sharpness", "sharpness (Laplacian variance)"),
    ):
        cells = [pm[s][key] for s in ("photos", "renders", "renders_matched")]
        out.append(f"| {text} | " + " | ".join("-" if v is None else f"{v:g}" for v in cells) + " |")
    if card.get("decomposition"):
        out += format_decomposition(card["decomposition"], card["too_few"])
    out += ["", f"Intervals: {card['intervals']}.", "", f"Definition: {card['false_detection']}."]
    if card.get("cpu_s"):
        c = card["cpu_s"]
        out += ["", "CPU seconds: " + ", ".join(f"{k} {v:.1f}" for k, v in c.items()) + "."]
    return "\n".join(out)


def write_card(
    out: Path,
    card: dict,
    sides: Sequence[tuple[PhotoFolder, Sequence[ImageBoxes]]],
    overlay_images: int,
    seed: int,
) -> str:
    """card.json, card.md and, with ``overlay_images`` > 0, misses.jpg (that many images of each
    side with a missed or misnamed placard, :func:`eval.detector.photos.write_overlay`) in ``out``;
    returns the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "card.json").write_text(json.dumps(card, indent=1) + "\n", encoding="utf-8")
    md = format_card(card)
    (out / "card.md").write_text(md + "\n", encoding="utf-8")
    if overlay_images > 0:
        cut = [misses(f, r, card["conf"]) for f, r in sides]
        write_overlay(
            out / OVERLAY_NAME, [f for f, _ in cut], [r for _, r in cut], card["conf"], overlay_images, seed
        )
    return md
