"""Where a sim-to-real gap lies (``poibench sim2real --decompose``): each labelled placard of the
photos and of the renders is replaced, one at a time, by poibench's own drawing of its label
(:func:`maze_assets.hazmat.draw_hazmat`), and the detector is asked again whether it names it.

The drawing fills the diamond inscribed in the placard's box (the box's edge midpoints are its
corners; anti-aliased), so what lies around the placard, and the box's size and shape, stay the
frame's own. Three versions of each placard, right-label recall of each:

* as it is (the photo's print, the render's placard);
* the drawing, canonical and cleanly printed;
* the drawing with a trial's print (paper, ink, fading, wear and creases of
  :func:`maze_assets.hazmat.placard_style`, drawn from the card's seed and the placard's place).

Read across a row, the columns say what the placard itself costs on that side: on the photos,
a drawing named as often as the real prints says the detector learnt the designs and not only
the photo set's sheets. Read down a column, a drawing named less often in the renders than in
the photos says what the frame around the placard costs (its scene, light and view); the
renders' first column below their second, what the render's drawing of the placard costs.
Only placards whose box lies wholly inside the image and whose shorter side is at least
:data:`PASTE_MIN_PX` (at the frame's scale, :func:`eval.detector.quality.frame_scales`) are
pasted: smaller ones hold too few pixels to show a drawing.

The gap of the placards as they are splits into three parts that add up to it exactly
(:func:`eval.detector.sim2real.gap_parts`). With A, D and T a side's recall as it is, with the
drawing and with the drawing in a trial's print (p the photos, r the renders):

    A_r - A_p = (D_r - D_p) + [(T_r - D_r) - (T_p - D_p)] + [(A_r - T_r) - (A_p - T_p)]

the frame around the placard (the same drawing on both sides), a trial's print (what it costs in
the renders beyond what it costs in the photos), and the placard (the render's placard against
its print pasted flat, beyond the real print against a trial's print pasted flat: the render's
light, view, sampling and camera on the placard, less how far the real prints are from the
print model). Each with a 95% bootstrap percentile interval over the placards of each side.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import cv2
import numpy as np

from eval.detector.label_eval import wilson
from eval.detector.metrics import ImageBoxes
from eval.detector.photos import HAZMAT_IDS, IOU_MIN, fold_lut
from eval.detector.quality import ImageDetector, LabelledImage, read_rgb
from eval.text import signed_interval
from poi.core.geometry import iou_matrix
from poi.core.names import RESCUE_CLASSES

PASTE_MIN_PX = 40.0  # shorter side at the frame's scale below which a placard is not pasted
DRAWING_PX = 256  # the drawing's side before it is scaled into the box
SUPERSAMPLE = 8  # the diamond mask's anti-aliasing
VARIANTS = ("as it is", "the drawing", "the drawing, a trial's print")
# the parts of the gap (module note), in the order of the equation's terms: name -> what it compares
GAP_PARTS = {
    "the frame around the placard": "the drawing in the renders against the drawing in the photos",
    "a trial's print": "what a trial's print costs the drawing in the renders, beyond what it costs in the photos",
    "the placard": "the rendered placard against its print pasted flat, beyond the real print against a trial's "
    "print pasted flat",
}


def diamond_mask(width: int, height: int) -> np.ndarray:
    """(height, width, 1) float32 coverage of the diamond inscribed in a ``width`` x ``height`` box
    (corners at the edge midpoints), anti-aliased by supersampling.

    >>> m = diamond_mask(40, 20)
    >>> float(m[10, 20, 0]), float(m[0, 0, 0])
    (1.0, 0.0)
    """
    s, shift = SUPERSAMPLE, 4  # the corners to 1/16 of a supersampled pixel
    pts = np.array([[width / 2, 0], [width, height / 2], [width / 2, height], [0, height / 2]]) * s - 0.5
    big = np.zeros((height * s, width * s), np.uint8)
    cv2.fillPoly(big, [np.round(pts * (1 << shift)).astype(np.int32)], 255, cv2.LINE_8, shift)
    small = cv2.resize(big.astype(np.float32) / 255.0, (width, height), interpolation=cv2.INTER_AREA)
    return small[..., None]


def paste(rgb: np.ndarray, box: tuple[int, int, int, int], picture: np.ndarray) -> np.ndarray:
    """A copy of ``rgb`` with the diamond inscribed in ``box`` (x1, y1, x2, y2, whole pixels)
    replaced by ``picture`` (RGB, any size) scaled to the box."""
    x1, y1, x2, y2 = box
    w, h = x2 - x1, y2 - y1
    m = diamond_mask(w, h)
    scaled = cv2.resize(picture, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)
    out = rgb.copy()
    region = out[y1:y2, x1:x2].astype(np.float32)
    out[y1:y2, x1:x2] = np.clip(np.round(scaled * m + region * (1.0 - m)), 0, 255).astype(np.uint8)
    return out


def drawings(label: str, seed: int) -> dict[str, np.ndarray]:
    """The pictures pasted in place of a placard of ``label``: the canonical drawing and the same
    design with the print a trial would give it (``placard_style(label, seed)``'s look)."""
    from maze_assets.hazmat import canonical_style, draw_hazmat, placard_style

    canonical = canonical_style(label)
    printed = replace(canonical, look=placard_style(label, seed).look)
    return {VARIANTS[1]: draw_hazmat(label, DRAWING_PX), VARIANTS[2]: draw_hazmat(label, DRAWING_PX, printed)}


def _named(det_boxes: np.ndarray, det_classes: np.ndarray, box: np.ndarray, label: int) -> bool:
    """A detection of class ``label`` (boxes (D, 4), classes (D,), all folded alike) at IoU >=
    IOU_MIN with ``box``."""
    right = np.asarray(det_boxes, float).reshape(-1, 4)[np.asarray(det_classes) == label]
    return bool(len(right)) and bool((iou_matrix(right, box[None, :]) >= IOU_MIN).any())


def decompose_side(
    detect: ImageDetector,
    images: Sequence[LabelledImage],
    results: Sequence[ImageBoxes],
    scales: np.ndarray,
    absent: str,
    seed: int,
    progress: Callable[[int], object] | None = None,
) -> tuple[dict[str, dict], np.ndarray, list[str]]:
    """Right-label recall of each of :data:`VARIANTS` over the placards of ``images`` that are
    pasted (module note), each with Wilson's interval: ``{variant: {"value", "ci95", "n"}}``; each
    pasted placard's outcomes, (n, 3) bool in the order of :data:`VARIANTS`; and each one's label
    (as ``absent`` folds it).
    ``results`` are ``detect``'s detections on ``images`` as they are (the card's, classes folded
    as ``absent`` says): the first version's, not run again. The trial's print of the k-th pasted
    placard is drawn from ``seed`` and k."""
    lut = fold_lut(absent)
    rows: list[list[bool]] = []
    labels: list[str] = []
    n = 0
    for im, found, scale in zip(images, results, scales, strict=True):
        rgb = None
        for box_norm, label in zip(im.boxes_norm, im.classes, strict=True):
            if int(label) not in HAZMAT_IDS:
                continue
            if rgb is None:
                rgb = read_rgb(im.path)
                h_img, w_img = rgb.shape[:2]
            box = np.round(box_norm * np.array([w_img, h_img, w_img, h_img])).astype(int)
            x1, y1, x2, y2 = (int(v) for v in box)
            inside = x1 >= 0 and y1 >= 0 and x2 <= w_img and y2 <= h_img
            if not inside or min(x2 - x1, y2 - y1) * scale < PASTE_MIN_PX:
                continue
            pictures = drawings(RESCUE_CLASSES[int(label)], seed * 100_003 + n)
            n += 1
            want, at = int(lut[int(label)]), box.astype(float)
            labels.append(RESCUE_CLASSES[want])
            row = [_named(found.det_boxes, found.det_classes, at, want)]
            for picture in pictures.values():
                dets = detect(paste(rgb, (x1, y1, x2, y2), picture), im.path)
                classes = lut[np.array([RESCUE_CLASSES.index(d.class_name) for d in dets], int)]
                row.append(_named(np.array([d.box_xyxy for d in dets], float), classes, at, want))
            rows.append(row)
        if progress:
            progress(1)
    hits = np.array(rows, dtype=bool).reshape(-1, len(VARIANTS))
    out = {}
    for j, variant in enumerate(VARIANTS):
        k = int(hits[:, j].sum())
        ci = wilson(k, n)
        out[variant] = {
            "value": round(k / n, 4) if n else None,
            "ci95": None if ci is None else [round(ci[0], 4), round(ci[1], 4)],
            "n": n,
        }
    return out, hits, labels


def format_decomposition(d: dict, too_few: int) -> list[str]:
    """The card's Markdown section for ``card["decomposition"]``; ``too_few``: the placards a side
    a label needs for its own row (the card's)."""
    out = [
        "",
        f"## Where the gap lies: each placard replaced by poibench's drawing of its label (placards of "
        f"{d['min_side_px']:g} px or more, whole in the image)",
        "",
        "| | " + " | ".join(VARIANTS) + " |",
        "|---|---|---|---|",
    ]
    for side in ("photos", "renders"):
        cells = []
        for variant in VARIANTS:
            r = d[side][variant]
            if r["value"] is None:
                cells.append("-")
                continue
            lo, hi = (100 * v for v in r["ci95"])
            cells.append(f"{100 * r['value']:.1f}% ({lo:.1f}-{hi:.1f}; n {r['n']})")
        out.append(f"| {side} | " + " | ".join(cells) + " |")
    out += [
        "",
        "Across a row: what the placard itself costs on that side (on the photos, a drawing named as often as "
        "the real prints: the detector knows the designs, not only the photo set's sheets). Down a column: a "
        "drawing named less often in the renders than in the photos is what the frame around the placard costs "
        "(scene, light, view); the renders' placards below their drawing, what the render's placard costs.",
    ]

    def pts(e: dict) -> str:
        return signed_interval(e["value"], *e["ci95"])

    parts = d.get("gap_parts")
    if parts:
        out += [
            "",
            f"The gap of these placards as they are, {pts(parts['gap'])} points (renders minus photos, 95% "
            "bootstrap interval), in three parts that add up to it:",
            "",
            "| part | points | what it compares |",
            "|---|---|---|",
            *(f"| {name} | {pts(parts[name])} | {meaning} |" for name, meaning in GAP_PARTS.items()),
        ]
    rows = d.get("by_label")
    if rows:
        out += [
            "",
            f"By label (labels with at least {too_few} pasted placards on each side; the same parts, each "
            "label's adding up to its gap):",
            "",
            "| label | placards: photos / renders | gap | " + " | ".join(GAP_PARTS) + " |",
            "|---|---|---|" + "---|" * len(GAP_PARTS),
            *(
                f"| {r['label']} | {r['n']['photos']} / {r['n']['renders']} | {pts(r['gap'])} | "
                + " | ".join(pts(r[name]) for name in GAP_PARTS)
                + " |"
                for r in rows
            ),
        ]
    return out
