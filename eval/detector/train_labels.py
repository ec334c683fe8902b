"""``poibench train-labels``: the hazmat label classifier, trained with torch, exported to ONNX.

The second stage of :mod:`poi.detectors.hazmat_labels`: a small convolutional
network over 64 x 64 crops, 17 outputs (the 16 labels and ``background``)
passed through a softmax. Four stages of 3x3 convolution, batch norm and ReLU
(32, 64, 128, 256 channels at 64, 32, 16 and 8 px by default, ``--widths``), each
followed by 2x2 max pooling, then a linear layer over the 4 x 4 x 256 map: the
layout of a placard (symbol on top, text across the middle, class number at the
bottom) stays in the features. About 120 MFLOPs a crop (16, 32, 64, 128 channels:
about 32, and 5 points less validation accuracy on the same crops, docs/FACTS.md).

Training: crops from :mod:`eval.detector.label_data` (every class drawn equally often,
half of them turned in their plane to any angle, with box, light, noise and resolution
changes), cross-entropy with label
smoothing 0.05, AdamW with a one-cycle learning rate, batch 128. Seeded: the
same data and spec give the same weights on the same machine. After every
epoch the run folder gets ``last.pt`` (model, optimiser, schedule, history) and
a row of ``history.csv`` (loss, train and validation accuracy); running the
same command again resumes from ``last.pt``. At the end it writes
``label_model.onnx`` (names, input size, crop margin and the dataset seeds
in its metadata), ``label_model.pt`` (the weights alone, with the shape, classes
and seeds: the checkpoint to fine-tune from), ``confusion.png`` (validation) and
``history.png``. A finished run (``label_model.onnx`` present) is left alone.

``model`` fine-tunes instead of starting over: the weights of a ``label_model.pt``,
a run's ``last.pt`` or a float ``label_model.onnx`` (:mod:`eval.detector.label_checkpoint`)
start the network, its crop size and widths are the run's, and the learning rate peaks
at ``FINE_TUNE_LR`` unless ``lr`` is given; the seeds of the data it was trained on stay
in the new model's metadata.

A ``--data`` folder of labelled photos (flat ``images/``, ``labels/``) has no
splits: ``holdout`` of its images (by image, seeded by ``seed``) are held back
as the validation crops and listed in ``holdout.json``
(:func:`eval.detector.label_data.holdout_split`); the rest are trained on.
Labels with no training crop (the real photos have 12 of the 16) are then
left out of the draw, so the classifier never names them; with rendered
folders only, a missing label is an error. The photo folders are named in the
model's metadata (``poibench_photo_folders``) so ``poibench evaluate-labels``
can refuse to score their images without the holdout list.

Torch is part of the ``train`` extra; the pipeline runs the ONNX file with
onnxruntime only.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from eval.detector.label_checkpoint import (
    CHECKPOINT_NAME,
    LabelCheckpoint,
    build_model,
    conv_blocks,
    read_checkpoint,
    torch_or_error,
)
from eval.detector.label_data import (
    CropSet,
    balanced_draw,
    crops_from_images,
    is_photo_folder,
    sample_crop,
    training_images,
    write_holdout,
)
from eval.detector.quality import (
    PATH_SEPARATOR,
    PHOTO_FOLDERS_METADATA_KEY,
    SEEDS_METADATA_KEY,
    DetectorQualityError,
    plot_confusion,
)
from eval.detector.rebuild import estimate_batchnorm
from eval.detector.train import TrainError, dataset_seed
from poi.detectors.hazmat_labels import DEFAULT_CROP_MARGIN, LABEL_CLASSES, TASK, crops_to_input

ONNX_NAME = "label_model.onnx"
DEFAULT_IMGSZ = 64
DEFAULT_WIDTHS = (32, 64, 128, 256)
SCRATCH_LR = 3e-3  # one-cycle peak from random weights
FINE_TUNE_LR = 1e-3  # one-cycle peak from a trained classifier
BN_STATS_CROPS = 1024  # training crops that estimate the BatchNorms of an ONNX start (label_checkpoint)


@dataclass(kw_only=True)
class LabelTrainSpec:
    data: Sequence[str]
    out: str
    epochs: int = 16
    imgsz: int | None = None  # DEFAULT_IMGSZ, or the checkpoint's when fine-tuning
    batch: int = 128
    samples_per_epoch: int = 32000
    lr: float | None = None  # SCRATCH_LR, or FINE_TUNE_LR when fine-tuning
    weight_decay: float = 1e-4
    label_smoothing: float = 0.05
    seed: int = 0
    threads: int = 2
    margin: float = DEFAULT_CROP_MARGIN
    widths: tuple[int, ...] | None = None  # DEFAULT_WIDTHS, or the checkpoint's when fine-tuning
    holdout: float | None = None  # fraction of each photo folder's images held back
    model: str | None = None  # a classifier checkpoint to fine-tune from (read_checkpoint)
    photo_folders: list[str] = field(default_factory=list, init=False)  # set by train_labels
    start: LabelCheckpoint | None = field(default=None, init=False)  # the checkpoint read from model

    def __post_init__(self) -> None:
        if not self.data:
            raise TrainError("give at least one --data folder ('poibench dataset' or labelled photos)")
        if self.lr is not None and not self.lr > 0:
            raise TrainError(f"--lr must be positive, got {self.lr}")
        if self.holdout is not None and not 0.0 < self.holdout < 1.0:
            raise TrainError(f"--holdout must be between 0 and 1 (both excluded), got {self.holdout}")
        photos = [d for d in self.data if is_photo_folder(d)]
        if photos and self.holdout is None:
            raise TrainError(
                f"{photos[0]} is a folder of photos (no train/val splits): give --holdout FRACTION, e.g. 0.2"
            )
        for name in ("epochs", "batch", "samples_per_epoch", "threads"):
            if getattr(self, name) < 1:
                raise TrainError(f"--{name.replace('_', '-')} must be at least 1, got {getattr(self, name)}")
        if self.widths is not None:
            self.widths = tuple(self.widths)  # a list from the caller compares equal to the checkpoint's
        if self.model is not None:
            self.start = read_checkpoint(self.model)
            shape = self.start.imgsz, self.start.widths
            if self.imgsz not in (None, shape[0]) or self.widths not in (None, shape[1]):
                raise TrainError(
                    f"{self.model} was trained with --imgsz {shape[0]} --widths {' '.join(map(str, shape[1]))}: "
                    "leave --imgsz and --widths out to fine-tune it"
                )
            self.imgsz, self.widths = self.start.imgsz, self.start.widths
        self.imgsz = DEFAULT_IMGSZ if self.imgsz is None else self.imgsz
        self.widths = DEFAULT_WIDTHS if self.widths is None else self.widths
        if self.lr is None:
            self.lr = SCRATCH_LR if self.start is None else FINE_TUNE_LR
        if self.imgsz % 16 or self.imgsz < 32:
            raise TrainError(f"--imgsz must be a multiple of 16 and at least 32, got {self.imgsz}")
        if not self.widths or min(self.widths) < 1:
            raise TrainError(f"--widths must be one or more positive channel counts, got {list(self.widths)}")
        if self.imgsz % 2 ** len(self.widths):
            raise TrainError(
                f"--imgsz {self.imgsz} does not halve {len(self.widths)} times (one max-pool a --widths stage) "
                f"to whole pixels: give a multiple of {2 ** len(self.widths)}"
            )


def _batch(crops: CropSet, idx: np.ndarray, size: int, margin: float, rng: np.random.Generator | None):
    x = crops_to_input([sample_crop(crops.patches[i], crops.boxes[i], size, rng, margin) for i in idx])
    return x, crops.labels[idx]


def _evaluate(model, crops: CropSet, spec: LabelTrainSpec) -> np.ndarray:
    """(17, 17) confusion counts, rows true class, columns predicted, on the exact boxes."""
    torch = torch_or_error()
    conf = np.zeros((len(LABEL_CLASSES), len(LABEL_CLASSES)), dtype=np.int64)
    model.eval()
    with torch.no_grad():
        for start in range(0, len(crops), 512):
            idx = np.arange(start, min(start + 512, len(crops)))
            x, y = _batch(crops, idx, spec.imgsz, spec.margin, None)
            pred = model(torch.from_numpy(x)).argmax(1).numpy()
            np.add.at(conf, (y, pred), 1)
    return conf


def train_labels(spec: LabelTrainSpec, log: Callable[[str], None] = print) -> Path:
    """Train (or resume) and export; returns the path of ``label_model.onnx``. The data are
    checked before torch is loaded or ``spec.out`` is made: a wrong ``--data`` costs one line and
    leaves nothing behind."""
    out = Path(spec.out)
    onnx_path = out / ONNX_NAME
    if onnx_path.exists():
        log(f"{onnx_path} exists: the run is finished")
        return onnx_path
    log("cutting crops from " + ", ".join(str(d) for d in spec.data))
    try:
        images = training_images(spec.data, spec.holdout, spec.seed)
    except DetectorQualityError as e:
        raise TrainError(str(e)) from None
    torch = torch_or_error()
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(spec.seed)
    torch.set_num_threads(spec.threads)
    torch.use_deterministic_algorithms(True)
    if images.holdout:
        held = write_holdout(out, images.holdout)
        spec.photo_folders = images.photo_folders
        n_held = sum(len(names) for names in images.holdout["folders"].values())
        log(f"{n_held} photos held back (validation with the renders' val splits), listed in {held}")
    train_set = crops_from_images(images.train, "train", spec.seed)
    val_set = crops_from_images(images.val, "val", spec.seed)
    log(
        f"{len(train_set)} train and {len(val_set)} validation crops; per class (train): "
        + ", ".join(f"{c} {n}" for c, n in zip(LABEL_CLASSES, train_set.counts(), strict=True))
    )
    missing = [c for c, n in zip(LABEL_CLASSES, train_set.counts(), strict=True) if n == 0]
    if missing and not images.holdout:
        raise TrainError(f"no training crops of {missing}; render more images (poibench dataset --hazmat 16)")
    if missing:
        log(f"no training crops of {missing}: the classifier will not name them")

    model = build_model(spec.widths, spec.imgsz, len(LABEL_CLASSES))
    if spec.start is not None:
        model.load_state_dict(spec.start.state)
        if spec.start.fused:
            sample = np.random.default_rng(spec.seed).permutation(len(train_set))[:BN_STATS_CROPS]
            batches = (
                torch.from_numpy(_batch(train_set, sample[i : i + spec.batch], spec.imgsz, spec.margin, None)[0])
                for i in range(0, len(sample), spec.batch)
            )
            estimate_batchnorm(model, batches, conv_blocks(model))
        log(f"fine-tuning {spec.start.path} (peak learning rate {spec.lr:g})")
    steps = math.ceil(spec.samples_per_epoch / spec.batch)
    opt = torch.optim.AdamW(model.parameters(), lr=spec.lr, weight_decay=spec.weight_decay)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=spec.lr, total_steps=spec.epochs * steps)
    loss_fn = torch.nn.CrossEntropyLoss(label_smoothing=spec.label_smoothing)
    history: list[dict] = []
    start = 0
    last = out / "last.pt"
    if last.exists():
        ck = torch.load(last, weights_only=False)
        shape = {"imgsz": spec.imgsz, "widths": list(spec.widths)}
        saved = {k: ck.get(k, v) for k, v in shape.items()}
        if saved != shape:
            raise TrainError(
                f"{last} was trained with --imgsz {saved['imgsz']} "
                f"--widths {' '.join(map(str, saved['widths']))}: "
                "resume with those, or give another --out"
            )
        model.load_state_dict(ck["model"])
        opt.load_state_dict(ck["opt"])
        sched.load_state_dict(ck["sched"])
        history, start = ck["history"], ck["epoch"] + 1
        torch.set_rng_state(ck["torch_rng"])  # dropout continues as if never interrupted
        log(f"resuming from {last} after epoch {start}")

    for epoch in range(start, spec.epochs):
        rng = np.random.default_rng([spec.seed, epoch])
        idx = balanced_draw(train_set.labels, steps * spec.batch, rng)
        model.train()
        total, correct, loss_sum = 0, 0, 0.0
        for k in range(steps):
            x, y = _batch(train_set, idx[k * spec.batch : (k + 1) * spec.batch], spec.imgsz, spec.margin, rng)
            logits = model(torch.from_numpy(x))
            yt = torch.from_numpy(y)
            loss = loss_fn(logits, yt)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            loss_sum += loss.item() * len(y)
            correct += int((logits.argmax(1) == yt).sum())
            total += len(y)
        conf = _evaluate(model, val_set, spec)
        row = {
            "epoch": epoch + 1,
            "loss": round(loss_sum / total, 5),
            "train_acc": round(correct / total, 5),
            "val_acc": round(float(np.trace(conf) / max(conf.sum(), 1)), 5),
            "val_worst_recall": round(float(_recalls(conf).min()), 5),
        }
        history.append(row)
        log(
            f"epoch {row['epoch']}/{spec.epochs}: loss {row['loss']:.4f}, train {row['train_acc']:.3f}, "
            f"val {row['val_acc']:.3f} (worst class {row['val_worst_recall']:.3f})"
        )
        torch.save(
            {
                "model": model.state_dict(),
                "opt": opt.state_dict(),
                "sched": sched.state_dict(),
                "history": history,
                "epoch": epoch,
                "torch_rng": torch.get_rng_state(),
                "imgsz": spec.imgsz,
                "widths": list(spec.widths),
            },
            last,
        )
        _write_history(out / "history.csv", history)

    conf = _evaluate(model, val_set, spec)
    plot_confusion(
        out / "confusion.png",
        conf,
        list(LABEL_CLASSES),
        xlabel="predicted",
        ylabel="true",
        title=f"label classifier, validation crops: accuracy {np.trace(conf) / max(conf.sum(), 1):.3f}",
        figsize=(9, 8),
        tick_fontsize=8,
    )
    _plot_history(history, out / "history.png")
    seeds = trained_seeds(spec)  # each dataset.yaml read once, for the checkpoint and the export
    torch.save(
        {
            "model": model.state_dict(),
            "imgsz": spec.imgsz,
            "widths": list(spec.widths),
            "classes": list(LABEL_CLASSES),
            "seeds": seeds,
        },
        out / CHECKPOINT_NAME,
    )
    _export(model, spec, onnx_path, seeds)
    return onnx_path


def trained_seeds(spec: LabelTrainSpec) -> list[int]:
    """The seeds of every rendered dataset behind the weights: the run's folders and, when
    fine-tuning, those of the checkpoint (so evaluation refuses all of them)."""
    seeds = [s for s in map(dataset_seed, spec.data) if s is not None]
    return sorted({*seeds, *(spec.start.seeds if spec.start is not None else ())})


def _recalls(conf: np.ndarray) -> np.ndarray:
    rows = conf.sum(axis=1)
    present = rows > 0
    return np.diag(conf)[present] / rows[present]


def _write_history(path: Path, history: list[dict]) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=list(history[0]))
        w.writeheader()
        w.writerows(history)


def _plot_history(history: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ep = [h["epoch"] for h in history]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.5))
    a.plot(ep, [h["loss"] for h in history], marker="o")
    a.set_xlabel("epoch")
    a.set_ylabel("training loss")
    for key, name in (
        ("train_acc", "train"),
        ("val_acc", "validation"),
        ("val_worst_recall", "worst class (val)"),
    ):
        b.plot(ep, [h[key] for h in history], marker="o", label=name)
    b.set_xlabel("epoch")
    b.set_ylabel("accuracy")
    b.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _export(model, spec: LabelTrainSpec, path: Path, seeds: list[int]) -> None:
    """ONNX with a softmax output, a dynamic batch and the metadata the pipeline reads."""
    torch = torch_or_error()
    import onnx

    net = torch.nn.Sequential(model, torch.nn.Softmax(dim=1)).eval()
    tmp = path.with_suffix(".tmp.onnx")
    torch.onnx.export(
        net,
        (torch.zeros(1, 3, spec.imgsz, spec.imgsz),),
        str(tmp),
        input_names=["images"],
        output_names=["probs"],
        dynamic_axes={"images": {0: "n"}, "probs": {0: "n"}},
        opset_version=17,
        dynamo=False,
    )
    m = onnx.load(str(tmp))
    meta = {
        "task": TASK,
        "names": str(dict(enumerate(LABEL_CLASSES))),
        "imgsz": str(spec.imgsz),
        "crop_margin": str(spec.margin),
        SEEDS_METADATA_KEY: ",".join(map(str, seeds)),
    }
    if spec.photo_folders:
        meta[PHOTO_FOLDERS_METADATA_KEY] = PATH_SEPARATOR.join(spec.photo_folders)
    for k, v in meta.items():
        m.metadata_props.add(key=k, value=v)
    onnx.save(m, str(path))
    tmp.unlink()
