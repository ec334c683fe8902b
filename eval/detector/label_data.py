"""Training crops for the hazmat label classifier, cut from ``poibench dataset`` folders.

Every labelled placard of a split, and as ``background`` every labelled
non-placard object, every ignored one (``ignore/``: too hidden to label, or a QR
chart's page) and one random box per image clear of the placards, is
kept with its surroundings: the box grown by :data:`CONTEXT` of its size on
each side, in the image's own pixels (reduced when the box is larger than
:data:`MAX_BOX_PX`, which is still above the classifier's input). A training
sample is then cut from that patch by :func:`sample_crop` exactly as the
pipeline cuts a detector box from a frame (:func:`poi.detectors.hazmat_labels.crop_box`),
after moving and resizing the box the way a detector's box errs and changing
the light, noise and resolution the way the sensor does. Torch-free, so the
core test suite checks it.

A folder of labelled photos (flat ``images/`` and ``labels/``, as
:func:`eval.detector.photos.load_folder` reads it) has no splits of its own:
:func:`holdout_split` holds back a seeded fraction of its images, by run of
consecutively numbered photos (:func:`photo_runs`), and the classifier (or
``poibench train``'s detector) trains on the rest (:func:`training_images`). The held-back
names are written beside the run (``holdout.json``) so that ``poibench
evaluate-labels --holdout-of RUN`` scores exactly them.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from eval.detector.photos import IMAGE_SUFFIXES, load_folder
from eval.detector.quality import DetectorQualityError, LabelledImage, load_split
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES
from poi.detectors.hazmat_labels import (
    BACKGROUND,
    DEFAULT_CROP_MARGIN,
    LABEL_CLASSES,
    PAD_VALUE,
    crop_box,
    padded_region,
)

CONTEXT = 0.5  # of the box width / height kept on each side
MAX_BOX_PX = 96  # larger boxes are stored reduced to this
MIN_BOX_PX = 8  # smaller labelled boxes are skipped: nothing to read
JITTER_SHIFT = 0.05  # sd of the box centre error, as a fraction of the box size
JITTER_SCALE = 0.08  # sd of the log box-size error
TURN_SHARE = 0.5  # training crops turned in their plane to any angle first: placards hang at any angle
BACKGROUND_INDEX = LABEL_CLASSES.index(BACKGROUND)
HOLDOUT_NAME = "holdout.json"  # in a label classifier's run folder
HOLDOUT_STREAM = 7  # second key of the holdout draw's generator, apart from the crops' streams
RESCUE_TO_LABEL = np.array(
    [LABEL_CLASSES.index(c) if c in HAZMAT_LABELS else BACKGROUND_INDEX for c in RESCUE_CLASSES], dtype=np.int64
)


@dataclass(kw_only=True)
class CropSet:
    """Placards and background objects with their surroundings, one per sample."""

    patches: list[np.ndarray]  # each (h, w, 3) uint8 RGB
    boxes: np.ndarray  # (N, 4) xyxy of the object in its patch's pixels
    labels: np.ndarray  # (N,) index into LABEL_CLASSES

    def __len__(self) -> int:
        return len(self.patches)

    def counts(self) -> np.ndarray:
        """(17,) samples per class of LABEL_CLASSES."""
        return np.bincount(self.labels, minlength=len(LABEL_CLASSES))


def _patch(rgb: np.ndarray, box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The box's surroundings (grown by CONTEXT, grey outside the image) and the box in them."""
    x0, y0, x1, y1 = box
    bw, bh = x1 - x0, y1 - y0
    gx0, gy0 = math.floor(x0 - CONTEXT * bw), math.floor(y0 - CONTEXT * bh)
    gx1, gy1 = math.ceil(x1 + CONTEXT * bw), math.ceil(y1 + CONTEXT * bh)
    patch = padded_region(rgb, gx0, gy0, gx1, gy1)
    local = np.array([x0 - gx0, y0 - gy0, x1 - gx0, y1 - gy0], dtype=np.float64)
    scale = min(1.0, MAX_BOX_PX / max(bw, bh))
    if scale < 1.0:
        size = (max(1, round(patch.shape[1] * scale)), max(1, round(patch.shape[0] * scale)))
        sx, sy = size[0] / patch.shape[1], size[1] / patch.shape[0]
        patch = cv2.resize(patch, size, interpolation=cv2.INTER_AREA)
        local = local * np.array([sx, sy, sx, sy])
    return patch, local


def _random_box(w: int, h: int, avoid: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
    """A box of a placard's typical size, anywhere in the image, overlapping no box of ``avoid``."""
    for _ in range(20):
        side = float(np.exp(rng.uniform(np.log(12.0), np.log(160.0))))
        aspect = float(np.exp(rng.uniform(-0.5, 0.5)))
        bw, bh = side * aspect, side / aspect
        if bw >= w or bh >= h:
            continue
        x0, y0 = rng.uniform(0, w - bw), rng.uniform(0, h - bh)
        box = np.array([x0, y0, x0 + bw, y0 + bh])
        if len(avoid):
            ix = np.clip(np.minimum(avoid[:, 2], box[2]) - np.maximum(avoid[:, 0], box[0]), 0, None)
            iy = np.clip(np.minimum(avoid[:, 3], box[3]) - np.maximum(avoid[:, 1], box[1]), 0, None)
            if np.any(ix * iy > 0):
                continue
        return box
    return None


def collect_crops(
    datasets: Sequence[str | Path], split: str, seed: int = 0, progress: Callable[[int], None] | None = None
) -> CropSet:
    """Placard and background samples of one split of every dataset folder."""
    images = [im for root in datasets for im in load_split(root, split)]
    return crops_from_images(images, split, seed, progress)


def crops_from_images(
    images: Sequence[LabelledImage], split: str, seed: int = 0, progress: Callable[[int], None] | None = None
) -> CropSet:
    """Placard and background samples of ``images`` (every labelled box at least MIN_BOX_PX a side,
    plus one random background box an image); the random boxes are drawn from a generator of
    ``seed`` and whether ``split`` is ``train``."""
    rng = np.random.default_rng([seed, 0 if split == "train" else 1])
    patches: list[np.ndarray] = []
    boxes: list[np.ndarray] = []
    labels: list[int] = []
    for im in images:
        bgr = cv2.imread(str(im.path))
        if bgr is None:
            raise DetectorQualityError(f"{im.path}: not a readable image")
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        h, w = rgb.shape[:2]
        px = im.boxes_px(w, h)  # (G, 4)
        lab = RESCUE_TO_LABEL[im.classes]  # (G,)
        placards = px[lab != BACKGROUND_INDEX]
        # what a detector may box but evaluation ignores: a hidden door, a QR chart's whole page;
        # the classifier must call those background (a partly hidden placard is left out)
        other = RESCUE_TO_LABEL[im.ignore_classes] == BACKGROUND_INDEX
        px = np.vstack([px, im.ignore_px(w, h)[other]])
        lab = np.append(lab, np.full(int(other.sum()), BACKGROUND_INDEX))
        extra = _random_box(w, h, placards, rng)
        if extra is not None:
            px, lab = np.vstack([px, extra[None]]), np.append(lab, BACKGROUND_INDEX)
        for box, c in zip(px, lab, strict=True):
            if min(box[2] - box[0], box[3] - box[1]) < MIN_BOX_PX:
                continue
            patch, local = _patch(rgb, box)
            patches.append(patch)
            boxes.append(local)
            labels.append(int(c))
        if progress:
            progress(1)
    return CropSet(
        patches=patches, boxes=np.array(boxes, dtype=np.float64).reshape(-1, 4), labels=np.array(labels, np.int64)
    )


def is_photo_folder(root: str | Path) -> bool:
    """Whether ``root`` is a flat YOLO folder (images directly in ``images/``), not a
    ``poibench dataset`` folder with ``images/train`` and ``images/val``."""
    img = Path(root) / "images"
    return img.is_dir() and any(p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES for p in img.iterdir())


def image_key(root: str | Path, image: LabelledImage) -> str:
    """An image's name in a holdout list: its path relative to the folder's ``images/``."""
    return Path(image.path).relative_to(Path(root) / "images").as_posix()


RUN_GAP = 2  # photos whose numbers differ by at most this (same prefix) are one run: one scene


def photo_runs(keys: Sequence[str]) -> list[list[int]]:
    """Indices of ``keys`` (image names) grouped into runs of one scene.

    A photo set holds scenes shot again and again (``image607``, ``image608``, ... of one
    board); near-identical shots on both sides of a split would let a detector be scored on
    what it trained on. A name's stem up to its first dot is read as prefix, last number,
    suffix (``image607_jpg.rf.3a...`` -> ``image``, 607, ``_jpg``); names with the same prefix
    and suffix whose numbers follow each other within :data:`RUN_GAP` are one run. A name
    without a number is a run of its own.

    >>> photo_runs(["image4_jpg.rf.a.jpg", "image5_jpg.rf.b.jpg", "image9_jpg.rf.c.jpg", "x.jpg"])
    [[0, 1], [2], [3]]
    """
    parsed = []
    for i, key in enumerate(keys):
        stem = Path(key).name.split(".", 1)[0]
        m = re.fullmatch(r"(.*?)(\d+)(\D*)", stem)
        parsed.append((m.group(1), m.group(3), int(m.group(2)), i) if m else (stem, "", -1, i))
    runs: list[list[int]] = []
    last: tuple[str, str, int] | None = None
    for prefix, suffix, number, i in sorted(parsed):
        if last is not None and number >= 0 and last[:2] == (prefix, suffix) and 0 <= number - last[2] <= RUN_GAP:
            runs[-1].append(i)
        else:
            runs.append([i])
        last = (prefix, suffix, number)
    return sorted(sorted(r) for r in runs)


def holdout_split(
    images: Sequence[LabelledImage], root: str | Path, fraction: float, seed: int
) -> tuple[list[LabelledImage], list[LabelledImage]]:
    """(training, held-back) images of one folder, split by run (:func:`photo_runs`): the runs,
    in the order ``np.random.default_rng([seed, HOLDOUT_STREAM]).permutation`` draws them, are
    held back while fewer than ``round(fraction * n)`` images are, so the split depends only on
    the names, the fraction and the seed, and every box of an image and every shot of a scene
    is on one side."""
    if not 0.0 < fraction < 1.0:
        raise DetectorQualityError(f"--holdout must be between 0 and 1 (both excluded), got {fraction}")
    ordered = sorted(images, key=lambda im: image_key(root, im))
    runs = photo_runs([image_key(root, im) for im in ordered])
    target = round(fraction * len(ordered))
    held: set[int] = set()
    for r in np.random.default_rng([seed, HOLDOUT_STREAM]).permutation(len(runs)):
        if len(held) >= target:
            break
        held.update(runs[r])
    if not 0 < len(held) < len(ordered):
        raise DetectorQualityError(
            f"{root}: --holdout {fraction} of {len(ordered)} images leaves no training or no held-back image"
        )
    train = [im for k, im in enumerate(ordered) if k not in held]
    return train, [im for k, im in enumerate(ordered) if k in held]


@dataclass(kw_only=True)
class TrainingImages:
    """The images a label classifier trains and validates on, and the held-back lists."""

    train: list[LabelledImage]
    val: list[LabelledImage]
    holdout: dict = field(default_factory=dict)  # the holdout.json document; empty without photo folders

    @property
    def photo_folders(self) -> list[str]:
        return list(self.holdout.get("folders", {}))


def training_images(data: Sequence[str | Path], holdout: float | None, seed: int) -> TrainingImages:
    """Training and validation images of every ``--data`` folder: a ``poibench dataset`` folder's
    train and val splits, a ``poibench route-frames`` folder's training frames (it has no val
    split), a photo folder's images less, and its held-back images (:func:`holdout_split`, which
    needs ``holdout``). Some folder must give validation images."""
    from eval.detector.route_frames import is_route_frames_folder

    train: list[LabelledImage] = []
    val: list[LabelledImage] = []
    folders: dict[str, list[str]] = {}
    for root in data:
        if not is_photo_folder(root):
            train += load_split(root, "train")
            if not is_route_frames_folder(root, error=DetectorQualityError):
                val += load_split(root, "val")
            continue
        if holdout is None:
            raise DetectorQualityError(
                f"{root} is a folder of photos (no train/val splits): give --holdout FRACTION, e.g. 0.2"
            )
        tr, held = holdout_split(load_folder(root).images, root, holdout, seed)
        train += tr
        val += held
        key = str(Path(root).resolve())
        if key in folders:
            raise DetectorQualityError(f"{root}: given twice in --data")
        folders[key] = [image_key(root, im) for im in held]
    if not val:
        raise DetectorQualityError(
            f"no validation images in {', '.join(str(d) for d in data)}: "
            "'poibench route-frames' folders have none; add a 'poibench dataset' folder"
        )
    if holdout is not None and not folders:
        given = ", ".join(map(str, data))
        raise DetectorQualityError(
            f"--holdout {holdout}: holds back part of a folder of photos; none of {given} is one "
            "(a rendered dataset brings its own val split)"
        )
    doc = {"fraction": holdout, "seed": seed, "folders": folders} if folders else {}
    return TrainingImages(train=train, val=val, holdout=doc)


def write_holdout(run: str | Path, doc: dict) -> Path:
    """``RUN/holdout.json``; a rerun (resume) must hold back the same images."""
    path = Path(run) / HOLDOUT_NAME
    if path.exists():
        old = json.loads(path.read_text(encoding="utf-8"))
        if old != doc:
            raise DetectorQualityError(
                f"{path} holds back other images (fraction {old.get('fraction')}, seed {old.get('seed')}); "
                "use a new --out or the same --data, --holdout and --seed"
            )
        return path
    path.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return path


def read_holdout(run: str | Path) -> dict[str, set[str]]:
    """Held-back image names by resolved folder path, from ``RUN/holdout.json`` (or that file)."""
    path = Path(run)
    if path.is_dir():
        path = path / HOLDOUT_NAME
    if not path.is_file():
        raise DetectorQualityError(
            f"{path}: no such file; --holdout-of takes a train or train-labels run folder, or its holdout.json"
        )
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        folders = doc["folders"]
        return {str(k): set(map(str, v)) for k, v in folders.items()}
    except (ValueError, KeyError, TypeError, AttributeError):
        raise DetectorQualityError(f"{path}: not a holdout file ('folders': folder -> image names)") from None


def turned(patch: np.ndarray, box: np.ndarray, angle_rad: float, tight: float) -> tuple[np.ndarray, np.ndarray]:
    """``patch`` turned by ``angle_rad`` (counter-clockwise as seen) about the box's centre, grey
    outside, and the axis-aligned box that then holds the object.

    A w x h box turned by a has corners within (|cos a| w + |sin a| h) / 2 across and
    (|sin a| w + |cos a| h) / 2 down of its centre: the box of a full sheet that filled it.
    A diamond that filled it (vertices at the sides' middles) reaches only max(|cos a|,
    |sin a|) / (|cos a| + |sin a|) of that (half of it at 45 degrees); ``tight`` in [0, 1]
    goes from the first to the second, since a placard may be either.

    >>> p = np.zeros((40, 40, 3), np.uint8)
    >>> turned(p, np.array([10.0, 10.0, 30.0, 30.0]), np.pi / 4, 1.0)[1].round(2).tolist()
    [12.93, 12.93, 27.07, 27.07]
    """
    x0, y0, x1, y1 = (float(v) for v in box)
    cx, cy, w, h = 0.5 * (x0 + x1), 0.5 * (y0 + y1), x1 - x0, y1 - y0
    M = cv2.getRotationMatrix2D((cx, cy), math.degrees(angle_rad), 1.0)
    out = cv2.warpAffine(
        patch,
        M,
        (patch.shape[1], patch.shape[0]),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=(PAD_VALUE,) * 3,
    )
    c, s = abs(math.cos(angle_rad)), abs(math.sin(angle_rad))
    f = 1.0 - tight * (1.0 - max(c, s) / (c + s))
    hw, hh = 0.5 * f * (c * w + s * h), 0.5 * f * (s * w + c * h)
    return out, np.array([cx - hw, cy - hh, cx + hw, cy + hh])


def sample_crop(
    patch: np.ndarray,
    box: np.ndarray,
    size: int,
    rng: np.random.Generator | None,
    margin: float = DEFAULT_CROP_MARGIN,
) -> np.ndarray:
    """A (size, size, 3) training crop of the object at ``box`` in ``patch``.

    With ``rng`` None the crop is the pipeline's crop of the exact box
    (validation). Otherwise, on ``TURN_SHARE`` of the crops, the patch is first
    turned to any angle about the box (:func:`turned`, ``tight`` uniform), since a
    placard may hang at any angle and a photo set shows each print at few; then
    the box centre moves by N(0, JITTER_SHIFT) of its
    size and each side scales by exp(N(0, JITTER_SCALE)); then brightness
    (x U(0.6, 1.3)), per-channel gain (x U(0.93, 1.07)), Gaussian noise
    (sd U(0, 6) grey levels) and, on a quarter of the crops, the resolution of a
    placard 10 px to ``size`` wide.
    """
    if rng is None:
        return crop_box(patch, tuple(box), size, margin)
    if rng.random() < TURN_SHARE:
        patch, box = turned(patch, box, float(rng.uniform(-math.pi, math.pi)), float(rng.random()))
    x0, y0, x1, y1 = box
    bw, bh = x1 - x0, y1 - y0
    cx = 0.5 * (x0 + x1) + rng.normal(0.0, JITTER_SHIFT) * bw
    cy = 0.5 * (y0 + y1) + rng.normal(0.0, JITTER_SHIFT) * bh
    bw *= math.exp(rng.normal(0.0, JITTER_SCALE))
    bh *= math.exp(rng.normal(0.0, JITTER_SCALE))
    crop = crop_box(patch, (cx - bw / 2, cy - bh / 2, cx + bw / 2, cy + bh / 2), size, margin)
    if rng.random() < 0.25:
        low = int(rng.integers(10, size))
        crop = cv2.resize(cv2.resize(crop, (low, low), interpolation=cv2.INTER_AREA), (size, size))
    gain = rng.uniform(0.6, 1.3) * rng.uniform(0.93, 1.07, size=3)  # (3,)
    noise = rng.normal(0.0, rng.uniform(0.0, 6.0), size=crop.shape)
    return np.clip(crop.astype(np.float64) * gain + noise, 0, 255).astype(np.uint8)


def balanced_draw(labels: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` sample indices drawn with replacement, every class of LABEL_CLASSES equally likely
    (a class with no samples is left out)."""
    counts = np.bincount(labels, minlength=len(LABEL_CLASSES)).astype(np.float64)
    if counts.sum() == 0:
        raise DetectorQualityError("no placard or background samples to draw from")
    w = 1.0 / counts[labels]
    return rng.choice(len(labels), size=n, replace=True, p=w / w.sum())
