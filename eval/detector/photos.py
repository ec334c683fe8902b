"""``poibench evaluate-photos``: a detector on folders of labelled photos, real or rendered.

Measures how a detector (with its hazmat label classifier) trained on
simulated frames does on real photos, and, given a rendered folder beside
them, the gap between the two (sim-to-real). A folder is in YOLO format
(Redmon et al., "You Only Look Once", 2016; the Ultralytics layout):
``images/NAME.jpg|png`` and ``labels/NAME.txt`` with one ``class cx cy w h``
line a box (normalised, class indices of :data:`poi.core.names.RESCUE_CLASSES`),
or a ``poibench dataset`` folder (``images/{train,val}/``, with ``ignore/``),
whose splits are all used. Images of any size are run at their own size: the
detector letterboxes them and the label classifier crops the full frame.

Matching, per image, of the detections at the operating confidence with the
labelled boxes at IoU >= 0.5, one to one
(:func:`eval.detector.metrics.match_classes_first`): right-class pairs first,
then the rest class-agnostically. A labelled box is then

* found with the right label: paired with a detection of its class;
* found as a placard: paired with a detection of any hazmat label;
* found: paired with a detection of any class.

A **false detection** is a detection at the operating confidence paired with
no labelled box: it sits on no labelled object or repeats one already
paired. It is counted for every class, as the issue's first measurement
counted (115 false detections in 249 photos, 0.46 an image), and reported by
the detected class, for hazmat labels and other types apart. The real photos
label only hazmat placards, so a false detection of another type (a QR code,
a door) may be an object really there but unlabelled; one of a hazmat label
is false for certain, since every placard is labelled. A detection paired
with a labelled box of another class is a misnamed placard, not a false
detection: it costs recall with the right label instead. Detections of
objects too hidden to be labelled (``ignore/`` of a rendered folder) count
neither way (:func:`eval.detector.metrics.drop_ignored`). An image without a
labels file shows no object (every detection on it is false); the count of
such images is reported.
"""

from __future__ import annotations

import csv
import json
import math
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from eval.detector.metrics import ImageBoxes, match_classes_first, recall_by_size, scaled_boxes
from eval.detector.quality import DetectorQualityError, LabelledImage, labelled_image
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
HAZMAT_IDS = frozenset(range(len(HAZMAT_LABELS)))  # the hazmat labels lead RESCUE_CLASSES
IOU_MIN = 0.5
FALSE_DETECTION = (
    "false detection: a detection at the operating confidence paired with no labelled box "
    "(one-to-one at IoU >= 0.5, right-class pairs first), any class; on photos that label only "
    "placards, other types (qr, door...) may be objects really there but unlabelled, so they are "
    "also given apart (false_other_per_image); a detection on a box of another class is misnamed, not false"
)
# overlay colours (BGR)
RIGHT_BGR = (60, 200, 60)
MISNAMED_BGR = (0, 165, 255)
MISSED_BGR = (40, 40, 230)
FALSE_BGR = (220, 60, 220)
TILE_PX = 300


@dataclass(kw_only=True)
class PhotoFolder:
    """The labelled images of one folder."""

    root: Path
    name: str
    images: list[LabelledImage]
    without_labels: int  # images with no labels file, taken as showing no object
    total_images: int  # before --limit


def _images_in(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def load_folder(root: str | Path, limit: int | None = None, seed: int = 0, name: str | None = None) -> PhotoFolder:
    """The images and labels of a YOLO folder (flat ``images/`` or a ``poibench dataset``'s splits);
    with ``limit``, that many images drawn without replacement by ``np.random.default_rng(seed)``.

    Raises :class:`DetectorQualityError` (one line, naming the path) for a missing folder, no
    images, a malformed label line (file and line) or a class index outside RESCUE_CLASSES.
    """
    root = Path(root)
    img_root = root / "images"
    if not root.is_dir():
        raise DetectorQualityError(f"{root}: {'a file, not a folder' if root.is_file() else 'no such folder'}")
    if not img_root.is_dir():
        raise DetectorQualityError(f"{root}: no images/ folder; expected a YOLO folder (images/, labels/)")
    splits = [""] if _images_in(img_root) else sorted(p.name for p in img_root.iterdir() if p.is_dir())
    pairs = [(split, p) for split in splits for p in _images_in(img_root / split)]
    if not pairs:
        raise DetectorQualityError(f"{img_root}: no .jpg or .png images (nor in a split folder)")
    if not (root / "labels").is_dir():
        raise DetectorQualityError(f"{root}: no labels/ folder; expected a YOLO folder (images/, labels/)")
    total = len(pairs)
    if limit is not None and limit < total:
        pick = np.sort(np.random.default_rng(seed).choice(total, size=limit, replace=False))
        pairs = [pairs[i] for i in pick]
    images, without = [], 0
    for split, img in pairs:
        without += not (root / "labels" / split / f"{img.stem}.txt").exists()
        images.append(labelled_image(root, split, img))
    return PhotoFolder(
        root=root, name=name or root.name, images=images, without_labels=without, total_images=total
    )


# The real photo set's coarser classes: a label absent there -> the real class holding it
# (its README: oxidizer boxes include OXYGEN placards, poison ones INHALATION HAZARD, the
# source's "flammable" FUEL OIL, explosive 1.5 BLASTING AGENTS).
REAL_SET_FOLD: dict[str, str] = {
    "oxygen": "oxidizer",
    "inhalation-hazard": "poison",
    "fuel-oil": "flammable-gas",
    "blasting-agent": "explosive",
}
FOLD_MODES = ("keep", "map")


def fold_lut(absent: str) -> np.ndarray:
    """(len(RESCUE_CLASSES),) the class index each class is counted as under ``absent``
    (:func:`fold_classes`): itself with ``keep``, the real set's class holding it with ``map``."""
    if absent not in FOLD_MODES:
        raise DetectorQualityError(f"--absent must be one of {', '.join(FOLD_MODES)}, got {absent!r}")
    lut = np.arange(len(RESCUE_CLASSES))
    if absent == "map":
        for label, into in REAL_SET_FOLD.items():
            lut[RESCUE_CLASSES.index(label)] = RESCUE_CLASSES.index(into)
    return lut


def fold_classes(results: list[ImageBoxes], absent: str) -> list[ImageBoxes]:
    """``results`` with labelled and detected classes folded as ``absent`` says.

    ``keep``: unchanged. ``map``: each label of :data:`REAL_SET_FOLD` becomes the real set's
    class that holds it, in the truth and in the detections alike, so a detector naming an
    INHALATION HAZARD placard ``inhalation-hazard`` is right where the set says ``poison``.
    """
    lut = fold_lut(absent)
    if absent == "keep":
        return results
    return [
        replace(
            im, gt_classes=lut[np.asarray(im.gt_classes, int)], det_classes=lut[np.asarray(im.det_classes, int)]
        )
        for im in results
    ]


@dataclass(kw_only=True)
class ImageOutcome:
    """One image's detections at the operating confidence, paired with its labelled boxes."""

    boxes: ImageBoxes  # detections already at the operating confidence
    pairs: list[tuple[int, int]]  # (labelled box, detection)

    @property
    def false(self) -> list[int]:
        paired = {d for _, d in self.pairs}
        return [d for d in range(len(self.boxes.det_boxes)) if d not in paired]


def outcome(im: ImageBoxes, conf: float, iou_min: float = IOU_MIN) -> ImageOutcome:
    """``im``'s detections scoring at least ``conf``, paired right-class first."""
    keep = im.det_scores >= conf
    kept = ImageBoxes(
        gt_boxes=im.gt_boxes,
        gt_classes=im.gt_classes,
        det_boxes=im.det_boxes[keep],
        det_classes=im.det_classes[keep],
        det_scores=im.det_scores[keep],
    )
    pairs = match_classes_first(kept.gt_boxes, kept.gt_classes, kept.det_boxes, kept.det_classes, iou_min)
    return ImageOutcome(boxes=kept, pairs=pairs)


def _ratio(a: int, b: int) -> float | None:
    return round(a / b, 4) if b else None


def folder_report(results: list[ImageBoxes], conf: float, scales: np.ndarray | None = None) -> dict:
    """Every number of one folder (module docstring for the definitions); its recall by box size at
    ``scales`` (:func:`eval.detector.quality.frame_scales`: the sizes a detector sees, comparable
    across image sets; each image's own pixels when not given).

    >>> gt = np.array([[0, 0, 30, 30], [100, 0, 130, 30.0]])
    >>> im = ImageBoxes(gt_boxes=gt, gt_classes=np.array([0, 2]),
    ...     det_boxes=np.array([[0, 0, 30, 30], [100, 0, 130, 30], [200, 0, 230, 30.0]]),
    ...     det_classes=np.array([0, 3, 16]), det_scores=np.array([0.9, 0.8, 0.7]))
    >>> r = folder_report([im], 0.5)
    >>> h = r["hazmat"]
    >>> h["recall_right"], h["recall_placard"], h["misnamed"], r["false_per_image"], r["false_hazmat_per_image"]
    (0.5, 1.0, 1, 1.0, 0.0)
    """
    n_cls = len(RESCUE_CLASSES)
    n = np.zeros(n_cls, int)
    right = np.zeros(n_cls, int)
    placard = np.zeros(n_cls, int)
    found = np.zeros(n_cls, int)
    dets = np.zeros(n_cls, int)
    false = np.zeros(n_cls, int)
    misnamed_as = np.zeros(n_cls, int)
    confusions: Counter[tuple[str, str]] = Counter()
    for im in results:
        o = outcome(im, conf)
        b = o.boxes
        np.add.at(n, b.gt_classes.astype(int), 1)
        np.add.at(dets, b.det_classes.astype(int), 1)
        np.add.at(false, b.det_classes[o.false].astype(int), 1)
        for g, d in o.pairs:
            t, p = int(b.gt_classes[g]), int(b.det_classes[d])
            found[t] += 1
            placard[t] += p in HAZMAT_IDS
            right[t] += p == t
            if p != t:
                misnamed_as[p] += 1
                confusions[(RESCUE_CLASSES[t], RESCUE_CLASSES[p])] += 1
    n_img = len(results)
    hz = np.array([i in HAZMAT_IDS for i in range(n_cls)])

    def group(sel: np.ndarray, as_placard: bool) -> dict:
        g = {
            "boxes": int(n[sel].sum()),
            "right": int(right[sel].sum()),
            "recall_right": _ratio(int(right[sel].sum()), int(n[sel].sum())),
            "recall_found": _ratio(int(found[sel].sum()), int(n[sel].sum())),
            "misnamed": int((found[sel] - right[sel]).sum()),
        }
        if as_placard:
            g["recall_placard"] = _ratio(int(placard[sel].sum()), int(n[sel].sum()))
        return g

    return {
        "images": n_img,
        "boxes": int(n.sum()),
        "detections": int(dets.sum()),
        "hazmat": group(hz, True),
        "other": group(~hz, False),
        "false": int(false.sum()),
        "false_per_image": _ratio(int(false.sum()), n_img),
        "false_hazmat_per_image": _ratio(int(false[hz].sum()), n_img),
        "false_other_per_image": _ratio(int(false[~hz].sum()), n_img),
        "top_confusions": [
            {"true": t, "detected": p, "n": k}
            for (t, p), k in sorted(confusions.items(), key=lambda kv: (-kv[1], kv[0]))[:10]
        ],
        "classes": {
            c: {
                "n": int(n[i]),
                "right": int(right[i]),
                "placard": int(placard[i]),
                "found": int(found[i]),
                "recall_right": _ratio(int(right[i]), int(n[i])),
                "recall_placard": _ratio(int(placard[i]), int(n[i])) if i in HAZMAT_IDS else None,
                "recall_found": _ratio(int(found[i]), int(n[i])),
                "detections": int(dets[i]),
                "false": int(false[i]),
                "misnamed_as_this": int(misnamed_as[i]),
            }
            for i, c in enumerate(RESCUE_CLASSES)
        },
        "by_size": recall_by_size(
            results if scales is None else [scaled_boxes(im, f) for im, f in zip(results, scales, strict=True)],
            ["hazmat label" if i in HAZMAT_IDS else "other type" for i in range(n_cls)],
            conf,
            iou_min=IOU_MIN,
            classes_first=True,
        ),
    }


# ---------------------------------------------------------------------------- output


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def _num(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def format_markdown(summary: dict) -> str:
    """The side-by-side tables (one column per folder) as Markdown."""
    folders = summary["folders"]
    names = [f["name"] for f in folders]
    head = "| | " + " | ".join(names) + " |\n|---|" + "---|" * len(names)
    rows = [
        (
            "images",
            lambda f: f"{f['images']}" + (f" of {f['total_images']}" if f["images"] < f["total_images"] else ""),
        ),
        ("hazmat placards labelled", lambda f: str(f["hazmat"]["boxes"])),
        (
            "placards found with the right label (IoU >= 0.5)",
            lambda f: f"{_pct(f['hazmat']['recall_right'])} ({f['hazmat']['right']})",
        ),
        ("placards found as a placard (any hazmat label)", lambda f: _pct(f["hazmat"]["recall_placard"])),
        ("placards found by a box of any class", lambda f: _pct(f["hazmat"]["recall_found"])),
        ("placards misnamed (paired, wrong class)", lambda f: str(f["hazmat"]["misnamed"])),
        (
            "other objects labelled: right class / any class",
            lambda f: (
                "-"
                if not (o := f["other"])["boxes"]
                else f"{_pct(o['recall_right'])} / {_pct(o['recall_found'])} ({o['boxes']})"
            ),
        ),
        ("false detections per image, any class", lambda f: f"{_num(f['false_per_image'])} ({f['false']})"),
        ("- of a hazmat label", lambda f: _num(f["false_hazmat_per_image"])),
        ("- of another type (may be unlabelled objects)", lambda f: _num(f["false_other_per_image"])),
        ("images without a labels file", lambda f: str(f["without_labels"])),
    ]
    out = [
        f"Detector {summary['model']}"
        + (f" with {summary['label_model']}" if summary.get("label_model") else "")
        + f", confidence >= {summary['conf']}"
        + (", labels folded into the real set's classes (--absent map)" if summary.get("absent") == "map" else ""),
        "",
        head,
        *(f"| {label} | " + " | ".join(fn(f) for f in folders) + " |" for label, fn in rows),
    ]
    bands = sorted(
        {r["band_px"] for f in folders for r in f["by_size"] if r["group"] == "hazmat label"},
        key=lambda b: float(b.split("-")[0].rstrip("+")),
    )
    if bands:
        out += [
            "",
            "Hazmat placards by box size (shorter side, px of a frame 640 px on its long side): right label / "
            "any class (boxes)",
            "",
            head,
        ]
        for band in bands:
            cells = []
            for f in folders:
                r = next((r for r in f["by_size"] if r["group"] == "hazmat label" and r["band_px"] == band), None)
                cells.append("-" if r is None else f"{_pct(r['right_class'])} / {_pct(r['found'])} ({r['n']})")
            out.append(f"| {band} | " + " | ".join(cells) + " |")
    classes = [c for c in RESCUE_CLASSES if any(f["classes"][c]["n"] for f in folders)]
    out += ["", "Per class: right label / as a placard / any class (labelled boxes)", "", head]
    for c in classes:
        cells = []
        for f in folders:
            m = f["classes"][c]
            cells.append(
                "-"
                if not m["n"]
                else " / ".join(_pct(m[k]) for k in ("recall_right", "recall_placard", "recall_found"))
                + f" ({m['n']})"
            )
        out.append(f"| {c} | " + " | ".join(cells) + " |")
    detected = [c for c in RESCUE_CLASSES if any(f["classes"][c]["false"] for f in folders)]
    if detected:
        out += ["", "False detections by detected class: count (per image)", "", head]
        for c in detected:
            cells = [
                f"{f['classes'][c]['false']} ({_num(_ratio(f['classes'][c]['false'], f['images']), 3)})"
                for f in folders
            ]
            out.append(f"| {c} | " + " | ".join(cells) + " |")
    for f in folders:
        if f["top_confusions"]:
            top = ", ".join(f"{x['true']} as {x['detected']} {x['n']}" for x in f["top_confusions"][:5])
            out += ["", f"Most misnamed in {f['name']}: {top}"]
    out += ["", f"Definition: {FALSE_DETECTION}."]
    return "\n".join(out)


def write_per_class_csv(path: Path, summary: dict) -> None:
    """One row per folder and class with labelled boxes or detections."""
    fields = [
        "folder",
        "class",
        "n",
        "right",
        "placard",
        "found",
        "recall_right",
        "recall_placard",
        "recall_found",
        "detections",
        "false",
        "misnamed_as_this",
    ]
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        w.writeheader()
        for f in summary["folders"]:
            for c, m in f["classes"].items():
                if m["n"] or m["detections"]:
                    w.writerow({"folder": f["name"], "class": c, **m})


def plot_by_size(path: Path, summary: dict) -> None:
    """Recall of hazmat placards by box size, right label (solid) and any class (hatched), per folder."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folders = summary["folders"]
    bands = sorted(
        {r["band_px"] for f in folders for r in f["by_size"] if r["group"] == "hazmat label"},
        key=lambda b: float(b.split("-")[0].rstrip("+")),
    )
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.8 / max(len(folders), 1)
    for k, f in enumerate(folders):
        rows = {r["band_px"]: r for r in f["by_size"] if r["group"] == "hazmat label"}
        x = np.arange(len(bands)) + k * width
        found = [rows[b]["found"] if b in rows else 0.0 for b in bands]
        right = [rows[b]["right_class"] if b in rows else 0.0 for b in bands]
        ax.bar(x, found, width, color=f"C{k}", alpha=0.35, hatch="//", label=f"{f['name']}: any class")
        ax.bar(x, right, width, color=f"C{k}", label=f"{f['name']}: right label")
        for xi, b in zip(x, bands, strict=True):
            if b in rows:
                ax.text(xi, 1.01, str(rows[b]["n"]), ha="center", fontsize=7)
    ax.set_xticks(np.arange(len(bands)) + width * (len(folders) - 1) / 2, bands)
    ax.set_xlabel("placard box, shorter side (px, at a 640 px long side); numbers: boxes")
    ax.set_ylabel("fraction found at IoU >= 0.5")
    ax.set_ylim(0, 1.35)
    ax.set_yticks(np.linspace(0, 1, 6))
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _short(name: str) -> str:
    return name if len(name) <= 14 else name[:13] + "."


def draw_tile(path: Path, im: ImageBoxes, conf: float, tile_px: int = TILE_PX) -> np.ndarray:
    """The image letterboxed into tile_px x tile_px with its labelled boxes coloured by outcome
    (right label green, misnamed orange, missed red) and its false detections magenta, each
    box named (detections with their confidence)."""
    bgr = cv2.imread(str(path))
    if bgr is None:
        raise DetectorQualityError(f"{path}: not a readable image")
    h, w = bgr.shape[:2]
    s = tile_px / max(h, w)
    small = cv2.resize(bgr, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    tile = np.full((tile_px, tile_px, 3), 40, np.uint8)
    tile[: small.shape[0], : small.shape[1]] = small
    o = outcome(im, conf)
    b = o.boxes
    paired = dict(o.pairs)

    def box(xyxy, colour, text, thick, below=False):
        x0, y0, x1, y1 = (int(round(v * s)) for v in xyxy)
        cv2.rectangle(tile, (x0, y0), (x1, y1), colour, thick)
        ty = min(y1 + 11, tile_px - 2) if below else max(y0 - 3, 10)
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.36, 1)
        tx = min(max(x0, 0), tile_px - tw)
        cv2.rectangle(tile, (tx - 1, ty - th - 2), (tx + tw + 1, ty + 2), (0, 0, 0), -1)
        cv2.putText(tile, text, (tx, ty), cv2.FONT_HERSHEY_SIMPLEX, 0.36, colour, 1, cv2.LINE_AA)

    for g, xyxy in enumerate(b.gt_boxes):
        t = int(b.gt_classes[g])
        if g not in paired:
            box(xyxy, MISSED_BGR, _short(RESCUE_CLASSES[t]), 2)
            continue
        d = paired[g]
        p = int(b.det_classes[d])
        colour = RIGHT_BGR if p == t else MISNAMED_BGR
        box(xyxy, colour, _short(RESCUE_CLASSES[t]), 2)
        if p != t:
            box(b.det_boxes[d], colour, f"{_short(RESCUE_CLASSES[p])} {b.det_scores[d]:.2f}", 1, below=True)
    for d in o.false:
        box(b.det_boxes[d], FALSE_BGR, f"{_short(RESCUE_CLASSES[int(b.det_classes[d])])} {b.det_scores[d]:.2f}", 1)
    cv2.putText(
        tile, path.name[:40], (3, tile_px - 4), cv2.FONT_HERSHEY_SIMPLEX, 0.33, (255, 255, 255), 1, cv2.LINE_AA
    )
    return tile


def write_overlay(
    path: Path,
    folders: list[PhotoFolder],
    results: list[list[ImageBoxes]],
    conf: float,
    per_folder: int,
    seed: int,
    columns: int = 6,
) -> None:
    """A contact sheet: ``per_folder`` images of each folder (drawn with ``np.random.default_rng(seed)``),
    a header line per folder and a colour key on top."""
    rng = np.random.default_rng(seed)
    width = columns * TILE_PX
    rows = []

    def strip(text: str, colour=(255, 255, 255)) -> np.ndarray:
        s = np.full((24, width, 3), 20, np.uint8)
        cv2.putText(s, text, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, colour, 1, cv2.LINE_AA)
        return s

    key = np.full((24, width, 3), 20, np.uint8)
    x = 6
    for text, colour in (
        ("labelled, right label", RIGHT_BGR),
        ("labelled, misnamed (thin: the detection)", MISNAMED_BGR),
        ("labelled, missed", MISSED_BGR),
        (f"false detection (conf >= {conf})", FALSE_BGR),
    ):
        cv2.rectangle(key, (x, 6), (x + 14, 18), colour, -1)
        cv2.putText(key, text, (x + 20, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv2.LINE_AA)
        x += 20 + 9 * len(text) + 20
    rows.append(key)
    for folder, res in zip(folders, results, strict=True):
        k = min(per_folder, len(folder.images))
        pick = np.sort(rng.choice(len(folder.images), size=k, replace=False))
        rows.append(strip(f"{folder.name} ({folder.root}): {k} of {len(folder.images)} images"))
        tiles = [draw_tile(folder.images[i].path, res[i], conf) for i in pick]
        for r in range(math.ceil(k / columns)):
            line = tiles[r * columns : (r + 1) * columns]
            line += [np.full((TILE_PX, TILE_PX, 3), 20, np.uint8)] * (columns - len(line))
            rows.append(np.hstack(line))
    cv2.imwrite(str(path), np.vstack(rows))


def write_outputs(
    out: Path,
    summary: dict,
    folders: list[PhotoFolder],
    results: list[list[ImageBoxes]],
    overlay_images: int,
    seed: int,
) -> str:
    """summary.json, per_class.csv, report.md, recall_by_size.png and overlay.png in ``out``;
    returns the Markdown."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    write_per_class_csv(out / "per_class.csv", summary)
    md = format_markdown(summary)
    (out / "report.md").write_text(md + "\n", encoding="utf-8")
    plot_by_size(out / "recall_by_size.png", summary)
    if overlay_images > 0:
        write_overlay(out / "overlay.png", folders, results, summary["conf"], overlay_images, seed)
    return md
