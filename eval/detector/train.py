"""``poibench train``: a small YOLO trained with the Ultralytics trainer, exported to ONNX.

[Bouda2025]_ trained its detector with Ultralytics; so does this, on a dataset
from ``poibench dataset``. Ultralytics and torch are the optional ``train``
extra: the core install and the pipeline never import them (inference is
onnxruntime only). No pretrained weights are fetched (the machines reach only
the package registries): the default model is built from ``yolo11n.yaml``.

The run folder holds Ultralytics' own files (``weights/last.pt`` after every
epoch, ``weights/best.pt``, ``results.csv``, plots) and, at the end,
``model.onnx`` exported at the training size (or ``--export-imgsz H W``: a 640x480 frame
letterboxed into a square input leaves a quarter of it grey, and 320 x 416 reads it at 416 px
wide for 1.3 times the 320 px square's pixels) with the class names in its metadata.
Running the same command again resumes an interrupted run from
``weights/last.pt``; a finished run (``model.onnx`` present) is left alone.

``--model`` may be an exported ``.onnx`` (the shipped float export ``poi/models/default_fp32.onnx``): it is
rebuilt into an Ultralytics checkpoint (``RUN/rebuilt.pt``, :mod:`eval.detector.rebuild`)
and fine-tuned from there. A ``.pt`` is fine-tuned from directly. Fine-tuning runs AdamW at
``lr0`` (``FINE_TUNE_LR0`` unless given) with a flat warm-up: Ultralytics' default schedule
(SGD or AdamW chosen by the run's length, biases warmed up from 0.1) took the rebuilt
shipped model from mAP50 0.914 to 0.813 in one epoch.

``placards="one"`` (``--placards one``) trains one class, ``hazmat``, for the 16
labels: the model finds placards and the label classifier (``poibench train-labels``)
names them from the full-resolution crop, as the pipeline does anyway. The labels are
rewritten into ``RUN/data-placards`` (the images are hard-linked, not copied), so each
placard class no longer has a sixteenth of the examples to learn from.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from eval.detector.label_data import is_photo_folder
from poi.core.atomic_file import atomic_path
from poi.core.loader import safe_load_file
from poi.core.names import HAZMAT_LABELS, RESCUE_CLASSES

PLACARD_CLASS = "hazmat"  # the one class for every label with --placards one
PLACARD_MODES = ("named", "one")
FINE_TUNE_LR0 = 2e-4  # AdamW's rate when fine-tuning a checkpoint (module docstring)
CHECKPOINT_SUFFIXES = (".pt", ".onnx")


class TrainError(ValueError):
    """Training cannot start as asked (one line)."""


@dataclass(kw_only=True)
class TrainSpec:
    data: str | list[str]  # one dataset folder, or several trained on together
    out: str
    model: str = "yolo11n.yaml"
    epochs: int = 60
    imgsz: int = 320
    batch: int = 16
    seed: int = 0
    device: str = "cpu"
    workers: int = 2
    threads: int = field(default_factory=lambda: os.cpu_count() or 1)
    placards: str = "named"  # 'one': one class for the 16 labels, named by the label classifier
    hours: float | None = None  # a time budget: Ultralytics fits the epochs into it (overrides epochs)
    lr0: float | None = None  # None: FINE_TUNE_LR0 for a checkpoint, Ultralytics' own choice from scratch
    holdout: float | None = None  # a photo folder's held-back fraction (RUN/holdout.json)
    export_imgsz: tuple[int, int] | None = None  # (H, W) of model.onnx's fixed input; None: imgsz x imgsz

    @property
    def fine_tune(self) -> bool:
        return Path(self.model).suffix in CHECKPOINT_SUFFIXES

    def __post_init__(self) -> None:
        for name in ("epochs", "imgsz", "batch", "threads"):
            if getattr(self, name) < 1:
                raise TrainError(f"--{name} must be at least 1, got {getattr(self, name)}")
        if self.hours is not None and not self.hours > 0:
            raise TrainError(f"--hours must be above 0, got {self.hours}")
        if self.placards not in PLACARD_MODES:
            raise TrainError(f"--placards must be one of {', '.join(PLACARD_MODES)}, got {self.placards!r}")
        if self.lr0 is not None and not 0 < self.lr0 < 1:
            raise TrainError(f"--lr0 must be in (0, 1), got {self.lr0}")
        if self.fine_tune and not Path(self.model).exists():
            raise TrainError(f"--model {self.model}: no such file")
        if Path(self.model).suffix not in (".pt", ".onnx", ".yaml", ".yml"):
            raise TrainError(
                f"--model {self.model}: expected a YOLO checkpoint (.pt), an exported detector (.onnx) or a model "
                "definition (.yaml)"
            )
        if not re.fullmatch(r"cpu|\d+(,\d+)*", str(self.device)):
            raise TrainError(f"--device {self.device}: expected cpu or a CUDA device index (0, or 0,1)")
        if self.holdout is not None and not 0 < self.holdout < 1:
            raise TrainError(f"--holdout must be between 0 and 1 (both excluded), got {self.holdout}")
        if self.imgsz % 32:
            raise TrainError(f"--imgsz must be a multiple of 32 (the model's stride), got {self.imgsz}")
        if self.export_imgsz is not None:
            check_export_size(self.export_imgsz, "--export-imgsz")

    @property
    def export_size_hw(self) -> tuple[int, int]:
        """The exported model's input (H, W): ``export_imgsz``, else the square training size."""
        return tuple(self.export_imgsz) if self.export_imgsz is not None else (self.imgsz, self.imgsz)


def check_export_size(size_hw: tuple[int, ...], flag: str) -> None:
    """Refuse an export input that is not two sides H W, each a positive multiple of the stride 32."""
    if len(size_hw) != 2 or any(v < 32 or v % 32 for v in size_hw):
        raise TrainError(
            f"{flag} must be two sides H W, each a positive multiple of 32 (the model's stride), "
            f"got {' '.join(map(str, size_hw))}"
        )


def data_yaml(data: str | Path) -> Path:
    """The dataset's data.yaml, checked to name poibench's classes in order."""
    p = Path(data)
    if p.is_dir():
        p = p / "data.yaml"
    if not p.exists():
        raise TrainError(f"{p}: no such file; give a folder written by 'poibench dataset' or its data.yaml")
    doc = safe_load_file(p, error=TrainError)
    names = doc.get("names") if isinstance(doc, dict) else None
    if isinstance(names, dict):
        names = [names[k] for k in sorted(names)]
    if list(names or []) != list(RESCUE_CLASSES):
        raise TrainError(
            f"{p}: 'names' must be poibench's {len(RESCUE_CLASSES)} classes in order "
            "(the rescue classes, poi.core.names.RESCUE_CLASSES)"
        )
    return p


def photo_dataset(root: Path, dst: Path, fraction: float, seed: int, run: Path) -> Path:
    """A training dataset in ``dst`` from a folder of labelled photos (flat ``images/`` and
    ``labels/``): the images held back by :func:`eval.detector.label_data.holdout_split` are its
    ``val`` split, the rest ``train`` (hard links, or copies across file systems), and their
    names go to ``RUN/holdout.json`` so that ``evaluate-photos --holdout-of RUN`` and
    ``poibench sim2real`` score the detector on exactly them. Returns the dataset's data.yaml."""

    from eval.detector.label_data import holdout_split, image_key, write_holdout
    from eval.detector.photos import load_folder
    from eval.detector.quality import DetectorQualityError

    try:
        folder = load_folder(root)
        train_images, held = holdout_split(folder.images, root, fraction, seed)
        write_holdout(
            run,
            {
                "fraction": fraction,
                "seed": seed,
                "folders": {str(root.resolve()): [image_key(root, im) for im in held]},
            },
        )
    except DetectorQualityError as exc:
        raise TrainError(str(exc)) from None
    for split, images in (("train", train_images), ("val", held)):
        for kind in ("images", "labels"):
            (dst / kind / split).mkdir(parents=True, exist_ok=True)
        for im in images:
            _link(im.path, dst / "images" / split / im.path.name)
            label = root / "labels" / f"{im.path.stem}.txt"
            rows = _label_rows(label, one=False) if label.exists() else []
            (dst / "labels" / split / label.name).write_text("".join(r + "\n" for r in rows))
        (dst / "labels" / f"{split}.cache").unlink(missing_ok=True)
    from eval.detector.dataset import write_data_yaml

    return write_data_yaml(dst)


def _link(src: Path, target: Path) -> None:
    """``target`` as a hard link to ``src`` (a copy across file systems): Ultralytics resolves
    folder links and would read the source's labels beside the source's images."""
    if target.exists():
        return
    try:
        os.link(src, target)
    except OSError:
        shutil.copy2(src, target)


def _label_rows(f: Path, one: bool) -> list[str]:
    """The YOLO lines of label file ``f`` (:func:`eval.detector.yolo_labels.read_yolo_labels`);
    with ``one``, the 16 hazmat labels as class 0 and class k >= 16 as k - 15."""
    from eval.detector.yolo_labels import read_yolo_labels

    n = len(HAZMAT_LABELS)
    return [b.line((0 if b.cls < n else b.cls - n + 1) if one else None) for b in read_yolo_labels(f, TrainError)]


def placard_dataset(data: Path, dst: Path) -> Path:
    """A copy of dataset ``data`` (its data.yaml) with the 16 hazmat labels as one class
    (:func:`training_dataset` of one source)."""
    return training_dataset([data], dst, placards="one")


def training_dataset(sources: list[Path], dst: Path, placards: str = "named") -> Path:
    """One dataset in ``dst`` from the data.yaml files ``sources`` (``poibench dataset`` and
    ``poibench route-frames`` folders): their images hard-linked (copied across file systems),
    those of the i-th source after the first named ``i-NAME``; with ``placards="one"`` the 16
    hazmat labels become one class: class k < 16 becomes 0 (``hazmat``), k >= 16 becomes
    k - 15. Labels are rewritten on every call (cheap), so they follow the sources. Returns the
    new data.yaml."""

    from eval.detector.route_frames import is_route_frames_folder

    n = len(HAZMAT_LABELS)
    one = placards == "one"
    names = [PLACARD_CLASS, *RESCUE_CLASSES[n:]] if one else list(RESCUE_CLASSES)
    val_images = 0
    for i, data in enumerate(sources):
        src = data.parent
        prefix = f"{i}-" if i else ""
        # route frames train only: their val split is empty by design
        for split in ("train",) if is_route_frames_folder(src, error=TrainError) else ("train", "val"):
            images = src / "images" / split
            if not images.is_dir():
                raise TrainError(f"{images}: no such folder; give a folder written by 'poibench dataset'")
            linked = dst / "images" / split
            linked.mkdir(parents=True, exist_ok=True)
            for img in sorted(images.iterdir()):
                if img.is_file():
                    _link(img, linked / f"{prefix}{img.name}")
                    val_images += split == "val"
            out = dst / "labels" / split
            out.mkdir(parents=True, exist_ok=True)
            for f in sorted((src / "labels" / split).glob("*.txt")):
                rows = _label_rows(f, one)
                (out / f"{prefix}{f.name}").write_text("".join(r + "\n" for r in rows))
            (out.parent / f"{split}.cache").unlink(missing_ok=True)  # Ultralytics' label cache
    if not val_images:
        raise TrainError(
            f"no validation images in {', '.join(str(d.parent) for d in sources)}: "
            "'poibench route-frames' folders have none; add a 'poibench dataset' folder"
        )
    from eval.detector.dataset import write_data_yaml

    return write_data_yaml(dst, names)


def _ultralytics():
    try:
        import ultralytics
    except ImportError:
        raise TrainError(
            "training and exporting detectors need the 'train' extra (Ultralytics and torch): "
            "pip install -e '.[train]' in its own environment (see the README)"
        ) from None
    return ultralytics


def _use_threads(model, threads: int) -> None:
    """Train on ``threads`` CPU threads.

    Ultralytics' ``select_device`` sets torch to ``cpu_count - 1`` threads for CPU training,
    which on a 2-core machine is one thread and leaves a core idle. Setting torch's count at
    the start of every epoch (a public trainer callback) undoes that; measured on 2 cores,
    YOLO11n at 320 px, batch 16: 1.5 s per batch with one thread, see the README for two."""
    import torch

    def set_threads(_trainer) -> None:
        torch.set_num_threads(threads)

    model.add_callback("on_train_epoch_start", set_threads)


def load_yolo(ul, path: str | Path, what: str):
    """Ultralytics' YOLO model of ``path``, or one line naming ``what`` where it is not a YOLO model
    or not a detector (a label classifier's checkpoint, a segmentation model)."""
    try:
        model = ul.YOLO(str(path))
    except Exception as e:  # Ultralytics' own errors for a file that is not a checkpoint
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise TrainError(f"{what}: not a loadable YOLO model ({reason[:150]})") from None
    if Path(path).suffix != ".yaml" and model.task != "detect":
        raise TrainError(f"{what}: a YOLO {model.task} model, not a detector")
    return model


def start_model(spec: TrainSpec, data: Path, out: Path) -> str:
    """What training starts from: the yaml, a checkpoint, or the checkpoint rebuilt from an
    exported ONNX model (``RUN/rebuilt.pt``, its BatchNorms estimated on the dataset's
    training images). A checkpoint's classes must be the dataset's."""
    if not spec.fine_tune:
        return spec.model
    start = Path(spec.model)
    if start.suffix == ".onnx":
        from eval.detector.rebuild import read_onnx, rebuild, save_checkpoint

        names = list(read_onnx(start).names.values())
        _check_classes(start, names, data)
        rebuilt = out / "rebuilt.pt"
        if not rebuilt.exists():
            images = sorted((data.parent / "images" / "train").glob("*.jpg"))
            model, src = rebuild(start, images)
            save_checkpoint(model, src, rebuilt)
        return str(rebuilt)
    return str(start)


def _check_classes(model: Path, names: list[str], data: Path) -> None:
    want = safe_load_file(data, error=TrainError)["names"]
    want = [want[k] for k in sorted(want)] if isinstance(want, dict) else list(want)
    if names != want:
        hint = " (--placards one trains hazmat plus the other types)" if names[:1] == [PLACARD_CLASS] else ""
        raise TrainError(f"{model}: its {len(names)} classes are not the dataset's {len(want)}{hint}")


def sources_of(spec: TrainSpec) -> list[str]:
    return [spec.data] if isinstance(spec.data, str) else list(spec.data)


def train(spec: TrainSpec) -> Path:
    """Train (or resume) and export; returns the path of ``model.onnx``."""
    out = Path(spec.out).resolve()
    sources = []
    for d in sources_of(spec):
        if is_photo_folder(d):
            if spec.holdout is None:
                raise TrainError(f"{d} is a folder of photos (no train/val splits): give --holdout, e.g. 0.2")
            out.mkdir(parents=True, exist_ok=True)
            dst = out / f"data-photos-{len(sources)}"
            sources.append(photo_dataset(Path(d), dst, spec.holdout, spec.seed, out))
        else:
            sources.append(data_yaml(d))
    if spec.holdout is not None and not any(is_photo_folder(d) for d in sources_of(spec)):
        raise TrainError("--holdout is for a folder of photos (images/, labels/); no --data folder is one")
    ul = _ultralytics()
    data = sources[0]
    if spec.placards == "one":
        data = training_dataset(sources, out / "data-placards", placards="one")
    elif len(sources) > 1:
        data = training_dataset(sources, out / "data-merged")
    onnx_path = out / "model.onnx"
    if onnx_path.exists():
        return onnx_path
    last = out / "weights" / "last.pt"
    if last.exists():
        model = ul.YOLO(str(last))
        _use_threads(model, spec.threads)
        model.train(resume=True)
    else:
        start = start_model(spec, data, out)
        model = load_yolo(ul, start, f"--model {spec.model}")
        _use_threads(model, spec.threads)
        schedule = {}
        if spec.fine_tune or spec.lr0 is not None:
            lr0 = spec.lr0 if spec.lr0 is not None else FINE_TUNE_LR0
            # a flat start: no high bias rate, a short warm-up, a gentle decay to lr0 * lrf
            schedule = {"optimizer": "AdamW", "lr0": lr0, "warmup_bias_lr": lr0, "warmup_epochs": 0.5, "lrf": 0.1}
        model.train(
            data=str(data),
            epochs=spec.epochs,
            time=spec.hours,
            imgsz=spec.imgsz,
            batch=spec.batch,
            seed=spec.seed,
            deterministic=True,
            device=spec.device,
            workers=spec.workers,
            project=str(out.parent),
            name=out.name,
            exist_ok=True,
            # a checkpoint is fine-tuned from its weights; a .yaml one starts from scratch
            pretrained=start if spec.fine_tune else False,
            plots=True,
            # the scenes are rendered upright and placards carry text: no flips
            fliplr=0.0,
            **schedule,
        )
    best = exported_checkpoint(spec)
    if not best.exists():
        raise TrainError(f"{best}: training ended without that checkpoint")
    photo_roots = [str(Path(d).resolve()) for d in sources_of(spec) if is_photo_folder(d)]
    return export_detector(best, spec.export_size_hw, onnx_path, sources, photo_roots, start_export(spec))


def export_detector(
    checkpoint: Path,
    size_hw: tuple[int, int],
    out: Path,
    data: list[Path] = (),
    photo_folders: list[str] = (),
    start: Path | None = None,
) -> Path:
    """Export ``checkpoint`` to ONNX at a fixed input of ``size_hw`` (height, width; multiples
    of the stride 32) as ``out``, stamped with what it was trained on (:func:`_stamp_metadata`).
    Ultralytics writes its export beside the checkpoint, where ``X.pt`` may have its shipped
    ``X.onnx``: it exports a copy in a folder of its own."""
    import shutil
    import tempfile

    ul = _ultralytics()
    out = Path(out)
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / Path(checkpoint).name
        shutil.copyfile(checkpoint, copy)
        model = load_yolo(ul, copy, f"--model {checkpoint}")
        exported = model.export(format="onnx", imgsz=list(size_hw), dynamic=False, simplify=False)
        exported = Path(exported)
        out.parent.mkdir(parents=True, exist_ok=True)
        _stamp_metadata(exported, out, list(data), list(photo_folders), start)
    return out


def exported_checkpoint(spec: TrainSpec) -> Path:
    """The weights ``model.onnx`` is exported from: ``best.pt``, or ``last.pt`` when held-back
    photos are the validation split (the model chosen on them would flatter them)."""
    return Path(spec.out) / "weights" / ("last.pt" if spec.holdout is not None else "best.pt")


def dataset_seed(root: str | Path) -> int | None:
    """The seed a 'poibench dataset' folder was rendered from (its dataset.yaml), if it says."""
    meta = Path(root) / "dataset.yaml"
    if not meta.exists():
        return None
    doc = safe_load_file(meta, error=TrainError)
    spec = doc.get("spec") if isinstance(doc, dict) else None
    return int(spec["seed"]) if isinstance(spec, dict) and "seed" in spec else None


def start_export(spec: TrainSpec) -> Path | None:
    """The ONNX export whose metadata says what a fine-tune's start was trained on: ``--model``
    itself when it is one; for a checkpoint, the export beside it (``X.onnx`` for ``X.pt``, as
    ``poi/models`` ships them) or its run's (``RUN/model.onnx`` for ``RUN/weights/*.pt``); None
    from scratch or where neither exists."""
    if not spec.fine_tune:
        return None
    start = Path(spec.model)
    return start if start.suffix == ".onnx" else export_of(start)


def export_of(checkpoint: Path) -> Path | None:
    """The ONNX export of a checkpoint: ``X.onnx`` beside ``X.pt`` (as ``poi/models`` ships them)
    or its run's ``RUN/model.onnx`` for ``RUN/weights/*.pt``; None where neither exists."""
    checkpoint = Path(checkpoint)
    beside = [checkpoint.with_suffix(".onnx")]
    if checkpoint.parent.name == "weights":
        beside.append(checkpoint.parent.parent / "model.onnx")
    return next((p for p in beside if p.is_file()), None)


def _stamp_metadata(
    src: Path, dst: Path, data: list[Path], photo_folders: list[str], start: Path | None = None
) -> None:
    """Copy the exported model, adding to its metadata the seed of every rendered dataset it
    trained on (``data``: each folder's data.yaml), so that evaluate-detector can refuse scenes
    the model was trained on, and the photo folders it trained on part of, so that
    evaluate-photos and sim2real score it on their held-back images only (``--holdout-of RUN``);
    a fine-tune's weights also hold what its ``start`` (:func:`start_export`) was trained on."""
    import onnx

    from eval.detector.quality import (
        PATH_SEPARATOR,
        PHOTO_FOLDERS_METADATA_KEY,
        SEED_METADATA_KEY,
        SEEDS_METADATA_KEY,
        model_metadata,
        model_photo_folders,
        model_training_seeds,
    )

    meta = model_metadata(start) if start is not None else {}
    trained = [*sorted(model_training_seeds(start, meta)), *(dataset_seed(d.parent) for d in data)]
    seeds = [str(s) for s in dict.fromkeys(trained) if s is not None]
    photo_folders = [*model_photo_folders(start, meta), *photo_folders]
    # a key stamped None is dropped: the single seed an earlier export of the model may carry too
    stamps = {SEED_METADATA_KEY: None, SEEDS_METADATA_KEY: ",".join(seeds) or None}
    stamps[PHOTO_FOLDERS_METADATA_KEY] = PATH_SEPARATOR.join(dict.fromkeys(photo_folders)) or None
    model = onnx.load(str(src))
    kept = [p for p in model.metadata_props if p.key not in stamps]
    del model.metadata_props[:]
    model.metadata_props.extend(kept)
    for key, value in stamps.items():
        if value is not None:
            model.metadata_props.add(key=key, value=value)
    # whole or not at all: a resumed run takes an existing model.onnx as its finished export
    with atomic_path(dst) as partial:
        onnx.save(model, str(partial))
