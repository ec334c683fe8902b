"""``poibench evaluate-labels``: a hazmat label classifier on the placard boxes of labelled folders.

Every labelled hazmat box (its ground truth, not a detection) of a folder is
cut as the pipeline cuts a detector's box (:func:`poi.detectors.hazmat_labels.crop_box`
through :meth:`~poi.detectors.hazmat_labels.HazmatLabelClassifier.classify`,
with the model's input size and crop margin) and named by the classifier's
most probable class of :data:`~poi.detectors.hazmat_labels.LABEL_CLASSES`;
``background`` counts as a wrong name; the accuracy with background not
allowed (the most probable of the 16 labels) is given beside it, telling a
classifier that cannot read a placard from one that does not take it for
one. Boxes with a side under ``min_px``
(default :data:`eval.detector.label_data.MIN_BOX_PX`, the training cut-off)
are left out and counted. A folder is read by :func:`eval.detector.photos.load_folder`:
flat ``images/`` + ``labels/`` (labelled photos) or a ``poibench dataset``
folder (all its splits). Several folders are reported side by side, so a
classifier trained on real crops can be scored on rendered ones and the
reverse (sim-to-real in both directions).

The real photo set (``hazmat-photos-dev``) labels 12 of the 16 labels, and
its classes are coarser: its ``oxidizer`` boxes include OXYGEN placards, its
``poison`` ones INHALATION HAZARD placards, ``flammable-gas`` FUEL OIL and
``explosive`` 1.5 BLASTING AGENTS (:data:`REAL_SET_FOLD`). The ``absent``
option says what becomes of the other 4 labels' crops (in a rendered folder)
and names:

* ``keep``: every label as itself;
* ``drop``: crops of the 4 labels are left out (a name of one of them stays wrong);
* ``map``: the 4 labels are folded into the real set's class, for the truth and
  the name alike, so naming an oxygen placard ``oxidizer`` is right.

Reported per folder: crops, right names, accuracy with its 95% Wilson
interval ([Wilson1927]_), per-class recall with the most frequent wrong name, and the most
frequent confusions; the accuracy in each band of box size (the shorter side of the
labelled box: 0-20, 20-40, 40-80, 80+ px, the bands of ``evaluate-photos``), and for
every folder after the first its accuracy at the first folder's mix of box sizes
(:func:`size_matched_accuracy`): rendered frames show many placards far smaller than
hand-held photos do, and a classifier that cannot read a 15 px placard says nothing
about how real the renders look. ``summary.json``, ``report.md`` (the printed Markdown
table) and one ``confusion_NAME.png`` a folder.

References
----------
Full entries in docs/SOURCES.md.

.. [Wilson1927] E. B. Wilson, "Probable inference, the law of succession, and statistical
   inference", Journal of the American Statistical Association 22, 1927.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from eval.detector.label_data import BACKGROUND_INDEX, MIN_BOX_PX, RESCUE_TO_LABEL, image_key, read_holdout
from eval.detector.metrics import SIZE_BINS_PX, size_band_label
from eval.detector.photos import REAL_SET_FOLD, PhotoFolder, load_folder
from eval.detector.quality import DetectorQualityError, LabelledImage, plot_confusion
from poi.detectors.hazmat_labels import LABEL_CLASSES, HazmatLabelClassifier

ABSENT_MODES = ("keep", "drop", "map")
TOP_CONFUSIONS = 10
Z95 = 1.959963984540054  # two-sided 95% normal quantile


def label_confusion(
    classifier: HazmatLabelClassifier,
    images: Sequence[LabelledImage],
    min_px: float = MIN_BOX_PX,
    progress: Callable[[int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """((B, 17, 17) counts per band of box size (:data:`SIZE_BINS_PX`, B bands), rows true
    label, columns the classifier's name; (17, 17) counts with the most probable label named,
    background not allowed; boxes left out as too small) over every labelled hazmat box of
    ``images``."""
    n = len(LABEL_CLASSES)
    conf = np.zeros((len(SIZE_BINS_PX) - 1, n, n), dtype=np.int64)
    conf_labels = np.zeros((n, n), dtype=np.int64)
    small = 0
    for im in images:
        labels = RESCUE_TO_LABEL[im.classes]  # (G,)
        keep = labels != BACKGROUND_INDEX
        if keep.any():
            bgr = cv2.imread(str(im.path))
            if bgr is None:
                raise DetectorQualityError(f"{im.path}: not a readable image")
            rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            px = im.boxes_px(rgb.shape[1], rgb.shape[0])  # (G, 4)
            side = np.minimum(px[:, 2] - px[:, 0], px[:, 3] - px[:, 1])  # (G,)
            small += int(np.sum(keep & (side < min_px)))
            keep &= side >= min_px
            if keep.any():
                q = classifier.classify(rgb, px[keep])  # (K, 17)
                band = np.searchsorted(SIZE_BINS_PX, side[keep], side="right") - 1  # (K,)
                np.add.at(conf, (band, labels[keep], q.argmax(axis=1)), 1)
                np.add.at(conf_labels, (labels[keep], np.delete(q, BACKGROUND_INDEX, axis=1).argmax(axis=1)), 1)
        if progress:
            progress(1)
    return conf, conf_labels, small


def fold_confusion(conf: np.ndarray, absent: str) -> np.ndarray:
    """The (17, 17) counts with the 4 labels the real set lacks handled as ``absent`` says
    (module docstring): ``drop`` empties their rows, ``map`` moves their rows and columns onto
    the real set's class."""
    if absent not in ABSENT_MODES:
        raise DetectorQualityError(f"--absent must be one of {', '.join(ABSENT_MODES)}, got {absent!r}")
    out = np.array(conf, dtype=np.int64)
    if absent == "drop":
        for label in REAL_SET_FOLD:
            out[LABEL_CLASSES.index(label)] = 0
    elif absent == "map":
        M = np.eye(len(LABEL_CLASSES), dtype=np.int64)  # (17, 17) class -> folded class
        for label, into in REAL_SET_FOLD.items():
            i = LABEL_CLASSES.index(label)
            M[i, i], M[i, LABEL_CLASSES.index(into)] = 0, 1
        out = M.T @ out @ M
    return out


def accuracy_by_size(conf_by_size: np.ndarray) -> list[dict]:
    """Crops, right names and accuracy (None without crops) in each band of box size, from
    (B, 17, 17) counts per band (:func:`label_confusion`, folded)."""
    rows = []
    for b, conf in enumerate(conf_by_size):
        n, right = int(conf.sum()), int(np.trace(conf))
        rows.append(
            {
                "band_px": size_band_label(b),
                "crops": n,
                "right": right,
                "accuracy": round(right / n, 4) if n else None,
            }
        )
    return rows


def size_matched_accuracy(by_size: list[dict], reference: list[dict]) -> float | None:
    """The accuracy of ``by_size`` at ``reference``'s mix of box sizes (direct
    standardisation): sum_b w_b a_b, with a_b the accuracy in band b and w_b the reference's
    share of crops in it, over the bands where both have crops (weights renormalised to 1).
    None when they share no band.

    >>> ref = [{"crops": 1, "accuracy": 1.0}, {"crops": 2, "accuracy": 0.5}]
    >>> size_matched_accuracy([{"crops": 2, "accuracy": 0.5}, {"crops": 1, "accuracy": 1.0}], ref)
    0.8333
    """
    pairs = [
        (r["crops"], b["accuracy"]) for b, r in zip(by_size, reference, strict=True) if b["crops"] and r["crops"]
    ]
    total = sum(w for w, _ in pairs)
    if not total:
        return None
    return round(sum(w * a for w, a in pairs) / total, 4)


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float] | None:
    """The score interval of a proportion k / n ([Wilson1927]_); None for n = 0."""
    if n == 0:
        return None
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def confusion_summary(conf: np.ndarray, top: int = TOP_CONFUSIONS) -> dict:
    """Crops, right names, accuracy and its interval ([Wilson1927]_), per-class recall and the top confusions of
    (17, 17) counts (rows true, columns named)."""
    n, right = int(conf.sum()), int(np.trace(conf))
    ci = wilson(right, n)
    per_class = {}
    for i, label in enumerate(LABEL_CLASSES):
        row = conf[i]
        if row.sum() == 0:
            continue
        wrong = row.copy()
        wrong[i] = 0
        j = int(wrong.argmax())
        per_class[label] = {
            "crops": int(row.sum()),
            "right": int(row[i]),
            "recall": round(float(row[i] / row.sum()), 4),
            "most_named_wrongly_as": LABEL_CLASSES[j] if wrong[j] else None,
            "wrongly_named_count": int(wrong[j]),
        }
    off = [
        (int(conf[i, j]), i, j)
        for i in range(len(LABEL_CLASSES))
        for j in range(len(LABEL_CLASSES))
        if i != j and conf[i, j]
    ]
    off.sort(key=lambda t: (-t[0], t[1], t[2]))
    return {
        "crops": n,
        "right": right,
        "accuracy": round(right / n, 4) if n else None,
        "accuracy_ci95": [round(v, 4) for v in ci] if ci else None,
        "per_class": per_class,
        "top_confusions": [
            {
                "true": LABEL_CLASSES[i],
                "named": LABEL_CLASSES[j],
                "count": c,
                "share_of_true": round(c / int(conf[i].sum()), 4),
            }
            for c, i, j in off[:top]
        ],
        "confusion": conf.tolist(),
    }


def listed_folder(root: Path, listed: Iterable[str]) -> str | None:
    """The entry of ``listed`` (resolved folder paths, from a holdout file or a model's metadata)
    that is folder ``root``: its own resolved path, else the one entry with its folder name, so a
    photo set copied to another machine is still known (None: not listed)."""
    listed = list(listed)
    here = str(root.resolve())
    if here in listed:
        return here
    same_name = [k for k in listed if Path(k).name == root.resolve().name]
    return same_name[0] if len(same_name) == 1 else None


def restrict_to_holdout(folder: PhotoFolder, held: dict[str, set[str]]) -> bool:
    """Keep only ``folder``'s held-back images when the holdout lists it (:func:`listed_folder`);
    whether it did."""
    key = listed_folder(folder.root, held)
    if key is None:
        return False
    names = held[key]
    keys = {image_key(folder.root, im): im for im in folder.images}
    missing = sorted(names - set(keys))
    if missing:
        raise DetectorQualityError(
            f"{folder.root}: {len(missing)} held-back images are not in the folder (first: {missing[0]})"
        )
    folder.images = [keys[k] for k in sorted(names)]
    return True


def load_folders(
    data: Sequence[str | Path], holdout_of: str | Path | None, option: str = "--data"
) -> list[tuple[PhotoFolder, bool]]:
    """Each ``option`` folder (unique names) and whether it was cut to the run's held-back images."""
    held = read_holdout(holdout_of) if holdout_of is not None else {}
    seen: dict[str, int] = {}
    out = []
    for k, d in enumerate(data):
        folder = load_folder(d)
        seen[folder.name] = seen.get(folder.name, 0) + 1
        if seen[folder.name] > 1:
            folder.name = f"{folder.name}-{k + 1}"
        out.append((folder, restrict_to_holdout(folder, held)))
    if held and not any(cut for _, cut in out):
        raise DetectorQualityError(
            f"{holdout_of}: holds back images of {', '.join(sorted(held))}, none of which is a {option} folder"
        )
    return out


def _cell(entry: dict | None) -> str:
    if entry is None:
        return "-"
    return f"{100 * entry['recall']:.0f}% ({entry['right']}/{entry['crops']})"


def _band_cell(entry: dict) -> str:
    if not entry["crops"]:
        return "-"
    return f"{100 * entry['accuracy']:.0f}% ({entry['right']}/{entry['crops']})"


def format_markdown(summary: dict) -> str:
    """The per-class table (recall, right / crops) side by side across folders, then each
    folder's top confusions."""
    folders = summary["folders"]
    head = "| label | " + " | ".join(f["name"] for f in folders) + " |"
    lines = [
        f"label classifier {summary['label_model']}; absent labels: {summary['absent']}",
        "",
        head,
        "|" + "---|" * (len(folders) + 1),
    ]
    overall = []
    for f in folders:
        if f["crops"]:
            lo, hi = f["accuracy_ci95"]
            overall.append(
                f"**{100 * f['accuracy']:.1f}%** ({f['right']}/{f['crops']}; {100 * lo:.0f}-{100 * hi:.0f}%)"
            )
        else:
            overall.append("-")
    lines.append("| all | " + " | ".join(overall) + " |")
    no_bg = [f"{100 * f['accuracy_labels_only']:.1f}%" if f["crops"] else "-" for f in folders]
    lines.append("| all, background not allowed | " + " | ".join(no_bg) + " |")
    if len(folders) > 1:
        matched = ["(reference)"] + [
            "-" if f["size_matched_accuracy"] is None else f"{100 * f['size_matched_accuracy']:.1f}%"
            for f in folders[1:]
        ]
        lines.append(f"| all, at {folders[0]['name']}'s box sizes | " + " | ".join(matched) + " |")
    for b, band in enumerate(folders[0]["by_size"]):
        cells = [f["by_size"][b] for f in folders]
        lines.append(f"| boxes {band['band_px']} px | " + " | ".join(_band_cell(c) for c in cells) + " |")
    for label in LABEL_CLASSES:
        cells = [f["per_class"].get(label) for f in folders]
        if any(cells):
            lines.append(f"| {label} | " + " | ".join(_cell(c) for c in cells) + " |")
    for f in folders:
        small = f"{f['small_left_out']} boxes under {summary['min_px']:g} px left out"
        lines += ["", f"{f['name']} ({f['images']} images, {small}): top confusions"]
        for c in f["top_confusions"]:
            lines.append(
                f"- {c['true']} named {c['named']}: {c['count']} ({100 * c['share_of_true']:.0f}% of {c['true']})"
            )
        if not f["top_confusions"]:
            lines.append("- none")
    return "\n".join(lines)


def write_outputs(out: str | Path, summary: dict) -> str:
    """summary.json, report.md and confusion_NAME.png a folder in ``out``; returns the Markdown."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n", encoding="utf-8")
    text = format_markdown(summary)
    (out / "report.md").write_text(text + "\n", encoding="utf-8")
    for f in summary["folders"]:
        conf = np.array(f["confusion"])
        shown = (conf.sum(axis=0) + conf.sum(axis=1)) > 0
        names = [c for c, s in zip(LABEL_CLASSES, shown, strict=True) if s]
        acc = f"{f['accuracy']:.3f}" if f["crops"] else "-"
        plot_confusion(
            out / f"confusion_{f['name']}.png",
            conf[np.ix_(shown, shown)],
            names,
            xlabel="named",
            ylabel="true",
            title=f"{f['name']}: {f['crops']} placard crops, accuracy {acc}",
            figsize=(9, 8),
            tick_fontsize=8,
        )
    return text
