"""``poibench dataset`` and ``poibench train``: the detector's training data and its training."""

from __future__ import annotations

import argparse
import os
from collections import Counter
from dataclasses import replace
from pathlib import Path

from eval.detector.dataset import DISTANCE_DRAWS, HAZMAT_PER_SCENARIO, DatasetSpec
from eval.detector.quality import EVAL_SEED
from eval.detector.quantize import CALIBRATION_IMAGES
from eval.detector.train import PLACARD_MODES
from poi.config import DetectorConfig

OPERATING_CONF = DetectorConfig().conf
# 16 scenes of 40 views showed 531 placards of hazmat-photos-dev's 12 labels, 36-61 a label; 20 show
# 682, 49-75 a label (seed 1000)
SIM2REAL_SCENES = 20
SIM2REAL_VIEWS = 40


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser("dataset", help="render a YOLO-format detection dataset from randomised scenarios")
    d.add_argument("--out", required=True, help="output folder (a rerun with the same settings resumes)")
    d.add_argument("--images", type=int, required=True, help="number of images")
    d.add_argument("--seed", type=int, default=0, help="seed of every scenario and view (default 0)")
    d.add_argument("--per-scenario", type=int, default=40, help="images per scenario (default 40)")
    d.add_argument("--val-every", type=int, default=5, help="every Nth scenario is validation (default 5)")
    d.add_argument(
        "--hazmat",
        type=int,
        default=HAZMAT_PER_SCENARIO,
        help=f"hazmat placards per scenario (default {HAZMAT_PER_SCENARIO}; 16: every label in every scenario)",
    )
    d.add_argument(
        "--hazmat-on-floor",
        type=float,
        default=DatasetSpec.hazmat_on_floor,
        help=f"share of the placards laid face up on the floor (default {DatasetSpec.hazmat_on_floor}; "
        "trials keep theirs on walls)",
    )
    d.add_argument(
        "--hazmat-on-doors",
        type=int,
        default=DatasetSpec.hazmat_on_doors,
        help=f"placards per scenario stuck on door faces, "
        f"two a door at most (default {DatasetSpec.hazmat_on_doors})",
    )
    d.add_argument(
        "--hazmat-in-crates",
        type=int,
        default=DatasetSpec.hazmat_in_crates,
        help=f"placards per scenario moved into open crates on the floor (default {DatasetSpec.hazmat_in_crates})",
    )
    d.add_argument(
        "--hazmat-on-ramps",
        type=int,
        default=DatasetSpec.hazmat_on_ramps,
        help=f"placards per scenario laid on ramps against their walls (default {DatasetSpec.hazmat_on_ramps})",
    )
    d.add_argument(
        "--hazmat-on-boards",
        type=int,
        default=DatasetSpec.hazmat_on_boards,
        help="boards per scenario holding a placard with a QR code beside it "
        f"(default {DatasetSpec.hazmat_on_boards})",
    )
    d.add_argument(
        "--shadows",
        type=float,
        default=DatasetSpec.shadow_fraction,
        help=f"share of the scenarios whose lamps cast shadows (default {DatasetSpec.shadow_fraction}; "
        "trials have none, for their cost)",
    )
    d.add_argument(
        "--distance",
        choices=DISTANCE_DRAWS,
        default=DatasetSpec.distance_draw,
        help="how the camera's distance to its target is drawn over 0.3-5 m: uniform (default), or "
        "log-uniform (log: about 4 views in 10 closer than 1 m, as in hand-held photos)",
    )
    d.add_argument(
        "--free-roll",
        type=float,
        default=DatasetSpec.free_roll,
        help=f"share of views with the camera rolled anywhere in +-180 deg instead of +-5 deg "
        f"(default {DatasetSpec.free_roll}; hand-held photos show placards at any angle)",
    )
    d.add_argument(
        "--camera",
        choices=("random", "trial"),
        default="random",
        help="random: each image draws its colour camera from wide ranges (for training, default); "
        "trial: the trial's D435 defaults on a still camera (to compare renders with real photos)",
    )
    d.add_argument(
        "--floor-textures",
        type=float,
        default=DatasetSpec.floor_textures,
        help=f"share of the scenarios with a terrazzo, concrete, carpet or glazed tile floor "
        f"(default {DatasetSpec.floor_textures}; real photos show placards lying on such floors)",
    )
    d.add_argument(
        "--print-saturation",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        default=DatasetSpec.print_saturation,
        help="fraction of a placard's colour saturation kept, drawn per placard (default %(default)s; "
        "real crops' median saturation is 60 against 88 rendered)",
    )
    d.add_argument(
        "--print-black",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        default=DatasetSpec.print_black,
        help="a placard's ink black level (0-255), drawn per placard (default %(default)s: deeper "
        "and more washed out than the renders' own)",
    )
    d.add_argument(
        "--glossy",
        type=float,
        default=DatasetSpec.glossy_fraction,
        help=f"share of the placards on glossy paper (lamp highlights and glare; "
        f"default {DatasetSpec.glossy_fraction})",
    )
    d.add_argument(
        "--msaa",
        type=int,
        default=DatasetSpec.msaa,
        help=f"MSAA samples of the renders, 0 2 4 or 8 (default {DatasetSpec.msaa}; trials render with 0)",
    )
    d.add_argument(
        "--closeups",
        type=float,
        default=DatasetSpec.closeup_fraction,
        help=f"share of the views that are close-ups, the target a third of the image high, with motion "
        f"blur (default {DatasetSpec.closeup_fraction})",
    )
    d.add_argument(
        "--landolt-targets",
        type=int,
        default=DatasetSpec.landolt_targets,
        help=f"Landolt-C targets an RRL scenario, never labelled (no detector class; one on the placard board, "
        f"the rest by themselves; default {DatasetSpec.landolt_targets})",
    )
    d.add_argument(
        "--milk-crates",
        type=int,
        default=DatasetSpec.milk_crates,
        help=f"open plastic crates a scenario standing near placards, unlabelled (RRL mazes; "
        f"default {DatasetSpec.milk_crates})",
    )
    d.add_argument("--quiet", action="store_true", help="no progress bar")
    d.set_defaults(func=cmd_dataset)

    rf = sub.add_parser(
        "route-frames", help="training frames from the robot's tours through generated mazes, truth-labelled"
    )
    rf.add_argument("--out", required=True, help="output folder (a rerun with the same settings resumes)")
    rf.add_argument("--mazes", type=int, required=True, help="generated RRL mazes to tour")
    rf.add_argument("--every", type=int, default=10, help="one frame in this many (default 10: one a second)")
    rf.add_argument("--seed", type=int, default=0, help="seed of the mazes (default 0)")
    rf.add_argument("--quiet", action="store_true", help="no progress bar")
    rf.set_defaults(func=cmd_route_frames)

    t = sub.add_parser("train", help="train the YOLO detector on a dataset and export ONNX (extra 'train')")
    t.add_argument(
        "--data",
        required=True,
        nargs="+",
        help="dataset folders ('poibench dataset', 'poibench route-frames') or their data.yaml, or folders of "
        "labelled photos (images/, labels/; need --holdout), trained on as one",
    )
    t.add_argument("--out", required=True, help="run folder: weights, plots, model.onnx (resumes if interrupted)")
    t.add_argument(
        "--holdout",
        type=float,
        help="for photo folders: hold back this fraction of each, by run of one scene's shots, as the "
        "validation split, listed in RUN/holdout.json (evaluate-photos and sim2real --holdout-of RUN); "
        "the model exported is the last epoch's, not the one best on them",
    )
    t.add_argument(
        "--model",
        default="yolo11n.yaml",
        help="yolo11n.yaml (from scratch, the default), a checkpoint .pt, or an exported .onnx "
        "(e.g. poi/models/default_fp32.onnx: rebuilt into RUN/rebuilt.pt) to fine-tune",
    )
    t.add_argument(
        "--lr0",
        type=float,
        help="AdamW learning rate (default: 2e-4 when fine-tuning a .pt or .onnx; "
        "from scratch, Ultralytics' own choice)",
    )
    t.add_argument("--epochs", type=int, default=60)
    t.add_argument("--imgsz", type=int, default=320, help="training and export input size (default 320)")
    t.add_argument("--batch", type=int, default=16)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--device", default="cpu", help="cpu or a CUDA device index (default cpu)")
    t.add_argument("--workers", type=int, default=2)
    t.add_argument(
        "--threads", type=int, default=os.cpu_count() or 1, help="torch CPU threads (default: every core)"
    )
    t.add_argument(
        "--hours",
        type=float,
        help="train for this long instead of --epochs: the epochs are fitted to the time after the first",
    )
    t.add_argument(
        "--placards",
        choices=PLACARD_MODES,
        default="named",
        help="named: a class per hazmat label (default); one: one class 'hazmat' that finds placards, "
        "named by the label classifier (train-labels)",
    )
    t.set_defaults(func=cmd_train)

    lt = sub.add_parser(
        "train-labels", help="train the hazmat label classifier (second stage) and export ONNX (extra 'train')"
    )
    lt.add_argument(
        "--data",
        required=True,
        nargs="+",
        help="dataset folders from 'poibench dataset' (best with --hazmat 16) or labelled photo folders "
        "(images/, labels/; need --holdout)",
    )
    lt.add_argument("--out", required=True, help="run folder: last.pt, history, label_model.onnx (resumes)")
    lt.add_argument("--epochs", type=int, default=16)
    lt.add_argument("--samples", type=int, default=32000, help="crops per epoch (default 32000)")
    lt.add_argument("--seed", type=int, default=0, help="seed of the training and of --holdout's draw (default 0)")
    lt.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    lt.add_argument(
        "--holdout",
        type=float,
        help="fraction of each photo folder's images held back (by image, drawn with --seed) as validation; "
        "listed in RUN/holdout.json for evaluate-labels --holdout-of",
    )
    lt.set_defaults(func=cmd_train_labels)

    el = sub.add_parser(
        "evaluate-labels",
        help="a hazmat label classifier on the labelled placard boxes of folders: accuracy, per class, confusions",
    )
    el.add_argument("--label-model", required=True, help="the classifier (label_model.onnx of train-labels)")
    el.add_argument(
        "--data",
        required=True,
        nargs="+",
        metavar="DIR",
        help="YOLO folders (images/, labels/; or a 'poibench dataset' folder, all splits); several: side by side",
    )
    el.add_argument(
        "--holdout-of",
        metavar="RUN",
        help="a train-labels run folder: its photo folders are scored on their held-back images only",
    )
    el.add_argument(
        "--absent",
        choices=("keep", "drop", "map"),
        default="keep",
        help="the 4 labels the real photo set lacks (oxygen, inhalation-hazard, fuel-oil, blasting-agent): "
        "keep as themselves, drop their crops, or map them (truth and name) to the real set's class "
        "oxidizer, poison, flammable-gas, explosive (default keep)",
    )
    el.add_argument(
        "--min-px", type=float, default=8.0, help="boxes with a side under this are left out (default 8)"
    )
    el.add_argument("--threads", type=int, default=1, help="onnxruntime threads (default 1)")
    el.add_argument("--out", required=True, help="folder for summary.json, report.md and confusion_NAME.png")
    el.add_argument("--quiet", action="store_true", help="no progress bars")
    el.set_defaults(func=cmd_evaluate_labels)

    ph = sub.add_parser(
        "evaluate-photos",
        help="a detector on folders of labelled photos (real or rendered): recall, false detections, overlay",
    )
    ph.add_argument(
        "--images",
        required=True,
        nargs="+",
        metavar="DIR",
        help="YOLO folders (images/, labels/; or a 'poibench dataset' folder); two or more: side by side",
    )
    ph.add_argument("--out", required=True, help="folder for summary.json, per_class.csv, report.md and plots")
    _add_photo_detector_args(ph)
    ph.add_argument(
        "--conf",
        type=float,
        default=OPERATING_CONF,
        help=f"operating confidence (default {OPERATING_CONF}, the pipeline's detector.conf)",
    )
    ph.add_argument(
        "--absent",
        default="keep",
        choices=("keep", "map"),
        help="map: fold labels a coarser photo set lacks into its class, truth and detections alike "
        "(oxygen->oxidizer, inhalation-hazard->poison, fuel-oil->flammable-gas, blasting-agent->explosive); "
        "default keep",
    )
    ph.add_argument("--limit", type=int, help="at most this many images a folder, drawn with --seed")
    ph.add_argument(
        "--holdout-of",
        metavar="RUN",
        help="a train or train-labels run folder: its photo folders are scored on their held-back images only",
    )
    ph.add_argument("--seed", type=int, default=0, help="seed of --limit's and the overlay's draws (default 0)")
    ph.add_argument("--overlay", type=int, default=12, help="images a folder on overlay.png (default 12; 0: none)")
    ph.add_argument("--quiet", action="store_true", help="no progress bars")
    ph.set_defaults(func=cmd_evaluate_photos)

    sr = sub.add_parser(
        "sim2real",
        help="a detector on labelled real photos and on poibench renders of the same labels, side by side at "
        "the photos' box sizes: recall, false detections, gaps per label, photometry (card.md, card.json)",
    )
    sr.add_argument(
        "--photos",
        required=True,
        nargs="+",
        metavar="DIR",
        help="YOLO folders of labelled photos (images/, labels/), pooled; their hazmat labels are rendered",
    )
    sr.add_argument("--out", required=True, help="folder for card.md, card.json, misses.jpg and the renders")
    _add_photo_detector_args(sr)
    sr.add_argument(
        "--holdout-of",
        metavar="RUN",
        help="a train or train-labels run folder: its photo folders are scored on their held-back images only "
        "(RUN/holdout.json)",
    )
    sr.add_argument(
        "--scenes",
        type=int,
        default=SIM2REAL_SCENES,
        help=f"generated scenes to render, each hanging every label of the photos once (default "
        f"{SIM2REAL_SCENES}: 682 placards, 49-75 a label, for 12 labels at 40 views; 0.09 CPU-s an image)",
    )
    sr.add_argument("--views", type=int, default=SIM2REAL_VIEWS, help=f"views a scene (default {SIM2REAL_VIEWS})")
    sr.add_argument(
        "--seed",
        type=int,
        default=EVAL_SEED,
        help=f"seed of the rendered scenes and the bootstrap (default {EVAL_SEED}; refused if the model trained "
        "on it)",
    )
    sr.add_argument(
        "--conf",
        type=float,
        default=OPERATING_CONF,
        help=f"operating confidence (default {OPERATING_CONF}, the pipeline's detector.conf)",
    )
    sr.add_argument(
        "--absent",
        default="keep",
        choices=("keep", "map"),
        help="map: fold labels a coarser photo set lacks into its class on both sides, truth and detections "
        "(as evaluate-photos); default keep",
    )
    sr.add_argument("--overlay", type=int, default=12, help="images a side on misses.jpg (default 12; 0: none)")
    sr.add_argument("--quiet", action="store_true", help="no progress bars")
    sr.set_defaults(func=cmd_sim2real)

    for name, helptext in (
        ("evaluate-detector", "mAP50, mAP50-95, per-class AP and recall, confusion matrix image"),
        ("calibrate", "fit the centre-error model and the misclassification table ([Avevor2022] 2.1.4-2.1.5)"),
    ):
        e = sub.add_parser(name, help=helptext)
        e.add_argument(
            "--model",
            required=True,
            help="an ONNX detector, python:MODULE:CLASS or a poibench.detectors entry point name",
        )
        e.add_argument(
            "--option",
            action="append",
            default=[],
            metavar="KEY=VALUE",
            help="a keyword argument of a Python detector (VALUE read as YAML); repeatable",
        )
        e.add_argument(
            "--label-model", help="a hazmat label classifier (poibench train-labels) to name the placards"
        )
        e.add_argument("--data", help="a 'poibench dataset' folder to use (its val split) instead of fresh scenes")
        e.add_argument("--images", type=int, default=400, help="fresh evaluation images (default 400)")
        e.add_argument(
            "--seed", type=int, default=EVAL_SEED, help=f"seed of the fresh scenes (default {EVAL_SEED})"
        )
        e.add_argument(
            "--conf",
            type=float,
            default=OPERATING_CONF,
            help=f"operating confidence (default {OPERATING_CONF}, the pipeline's detector.conf)",
        )
        e.add_argument("--quiet", action="store_true", help="no progress bars")
        if name == "evaluate-detector":
            e.add_argument("--out", required=True, help="folder for evaluation.json and confusion.png")
            e.set_defaults(func=cmd_evaluate)
        else:
            e.add_argument(
                "--out", required=True, help="calibration file to write (YAML); its plot goes beside it"
            )
            e.set_defaults(func=cmd_calibrate, out_is_file=True)

    qz = sub.add_parser(
        "quantize-detector",
        help="an int8 copy of a float YOLO ONNX export, by onnxruntime's static quantiser (QDQ)",
    )
    qz.add_argument("--model", required=True, help="the float ONNX export (e.g. poi/models/default_fp32.onnx)")
    qz.add_argument("--data", required=True, help="a 'poibench dataset' folder whose images calibrate the ranges")
    qz.add_argument(
        "--images",
        type=int,
        default=CALIBRATION_IMAGES,
        help=f"calibration images, the first by name (default {CALIBRATION_IMAGES})",
    )
    qz.add_argument("--out", required=True, help="the int8 ONNX model to write")
    qz.set_defaults(func=cmd_quantize, out_is_file=True)


def cmd_dataset(args) -> int:
    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.progress import progress_bar

    spec = DatasetSpec(
        images=args.images,
        seed=args.seed,
        images_per_scenario=args.per_scenario,
        val_every=args.val_every,
        counts={**DatasetSpec.default_counts(), "hazmat": args.hazmat},
        hazmat_on_floor=args.hazmat_on_floor,
        hazmat_on_doors=args.hazmat_on_doors,
        hazmat_in_crates=args.hazmat_in_crates,
        hazmat_on_ramps=args.hazmat_on_ramps,
        hazmat_on_boards=args.hazmat_on_boards,
        shadow_fraction=args.shadows,
        distance_draw=args.distance,
        free_roll=args.free_roll,
        floor_textures=args.floor_textures,
        print_saturation=tuple(args.print_saturation),
        print_black=tuple(args.print_black),
        glossy_fraction=args.glossy,
        msaa=args.msaa,
        closeup_fraction=args.closeups,
        landolt_targets=args.landolt_targets,
        milk_crates=args.milk_crates,
        **({"camera": None, "blur_fraction": 0.0} if args.camera == "trial" else {}),
    )
    with progress_bar(total=spec.images, desc="dataset", unit="img", quiet=args.quiet) as bar:
        summary = write_dataset(spec, args.out, progress=bar.update)
    n = summary["images"]
    inst = summary["instances"]
    print(f"{args.out}: {n['train']} train and {n['val']} val images from {spec.n_scenarios} scenarios")
    print(f"{'class':26s} {'train':>6s} {'val':>6s}")
    for c in inst["train"]:
        print(f"{c:26s} {inst['train'][c]:6d} {inst['val'][c]:6d}")
    print(f"data.yaml, manifest.csv and classes.png in {args.out}")
    return 0


def cmd_route_frames(args) -> int:
    from eval.detector.route_frames import RouteFramesSpec, write_route_frames
    from eval.progress import progress_bar

    spec = RouteFramesSpec(mazes=args.mazes, seed=args.seed, every=args.every)
    with progress_bar(desc="frames", unit="frame", quiet=args.quiet) as bar:
        summary = write_route_frames(spec, args.out, progress=bar.update)
    print(
        f"{args.out}: {summary['frames']} frames of {spec.mazes} tours, {summary['frames_with_labels']} "
        f"with a labelled object ({summary['boxes']} boxes)"
    )
    return 0


def cmd_train(args) -> int:
    from eval.detector.train import TrainSpec, train

    out = train(
        TrainSpec(
            data=args.data,
            out=args.out,
            model=args.model,
            epochs=args.epochs,
            imgsz=args.imgsz,
            batch=args.batch,
            seed=args.seed,
            device=args.device,
            workers=args.workers,
            threads=args.threads,
            placards=args.placards,
            hours=args.hours,
            lr0=args.lr0,
            holdout=args.holdout,
        )
    )
    print(f"model: {out}")
    print(
        f"to make it the default detector: cp it to poi/models/default_fp32.onnx, quantise that "
        "(poibench quantize-detector --out poi/models/default.onnx, or cp it there as it is), and "
        f"{out.parent}/weights/best.pt to"
    )
    print("poi/models/default.pt (the checkpoint later training fine-tunes from)")
    return 0


def cmd_train_labels(args) -> int:
    from eval.detector.train_labels import LabelTrainSpec, train_labels

    out = train_labels(
        LabelTrainSpec(
            data=args.data,
            out=args.out,
            epochs=args.epochs,
            samples_per_epoch=args.samples,
            seed=args.seed,
            threads=args.threads,
            holdout=args.holdout,
        )
    )
    print(f"label model: {out}")
    print("to use it with the default detector: cp it to poi/models/default_labels.onnx")
    return 0


def cmd_evaluate_labels(args) -> int:
    """``poibench evaluate-labels``: eval.detector.label_eval on each --data folder, side by side."""
    import numpy as np

    from eval.detector.label_eval import (
        accuracy_by_size,
        confusion_summary,
        fold_confusion,
        label_confusion,
        load_folders,
        size_matched_accuracy,
        write_outputs,
    )
    from eval.detector.quality import DetectorQualityError, model_training_seeds
    from eval.detector.train import dataset_seed
    from eval.progress import progress_bar
    from poi.detectors.hazmat_labels import LABEL_CLASSES, HazmatLabelClassifier

    if args.min_px < 0:
        raise DetectorQualityError(f"--min-px must be at least 0, got {args.min_px}")
    if args.threads < 1:
        raise DetectorQualityError(f"--threads must be at least 1, got {args.threads}")
    if not Path(args.label_model).is_file():
        raise DetectorQualityError(f"{args.label_model}: no such model file")
    classifier = HazmatLabelClassifier(model=args.label_model, threads=args.threads)
    seeds = model_training_seeds(args.label_model)
    folders = load_folders(args.data, args.holdout_of)
    _refuse_trained_photos((args.label_model,), folders)
    rows = []
    for folder, cut in folders:
        seed = dataset_seed(folder.root)
        if seed is not None and seed in seeds:
            print(f"note: {args.label_model} was trained on scenes of seed {seed}, as {folder.root} was rendered")
        with progress_bar(total=len(folder.images), desc=folder.name, unit="img", quiet=args.quiet) as bar:
            by_size, conf_labels, small = label_confusion(classifier, folder.images, args.min_px, bar.update)
        conf = by_size.sum(axis=0)
        labels_only = fold_confusion(conf_labels, args.absent)
        sizes = accuracy_by_size(np.array([fold_confusion(c, args.absent) for c in by_size]))
        rows.append(
            {
                "name": folder.name,
                "path": str(folder.root),
                "images": len(folder.images),
                "held_back_only": cut,
                "small_left_out": small,
                **confusion_summary(fold_confusion(conf, args.absent)),
                "accuracy_labels_only": round(float(np.trace(labels_only) / max(labels_only.sum(), 1)), 4),
                "by_size": sizes,
                "size_matched_accuracy": size_matched_accuracy(sizes, rows[0]["by_size"] if rows else sizes),
                "confusion_unfolded": conf.tolist(),
            }
        )
    summary = {
        "label_model": str(args.label_model),
        "holdout_of": args.holdout_of,
        "absent": args.absent,
        "min_px": args.min_px,
        "labels": list(LABEL_CLASSES),
        "folders": rows,
    }
    print(write_outputs(args.out, summary))
    print(f"summary.json, report.md and confusion_NAME.png in {args.out}")
    return 0


def _labelled_images(args, work: Path):
    """The val split of --data, or fresh scenes rendered from --seed into ``work``."""
    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.detector.quality import load_split
    from eval.progress import progress_bar

    if args.data:
        return load_split(args.data, "val")
    _refuse_training_seed(args)
    spec = DatasetSpec.trial_looks(images=args.images, seed=args.seed, val_every=1)
    with progress_bar(total=spec.images, desc="scenes", unit="img", quiet=args.quiet) as bar:
        write_dataset(spec, work, progress=bar.update)
    return load_split(work, "val")


def _refuse_training_seed(args) -> None:
    """Refuse fresh scenes from a --seed the detector or its label model was trained on (the seeds
    ``poibench train`` and ``train-labels`` write into the model's metadata)."""
    from eval.detector.quality import DetectorQualityError, model_training_seeds
    from poi.detectors import is_team_detector

    for model in (args.model, args.label_model):
        if model is None or is_team_detector(model):
            continue  # a Python detector carries no training metadata
        if args.seed in model_training_seeds(model):
            raise DetectorQualityError(
                f"{model} was trained on scenes from seed {args.seed}; evaluate on another --seed"
            )


def _detect(args, images, conf):
    from eval.detector.quality import detect_all
    from eval.progress import progress_bar

    with progress_bar(total=len(images), desc="detect", unit="img", quiet=args.quiet) as bar:
        return detect_all(
            args.model,
            images,
            conf,
            progress=bar.update,
            label_model=args.label_model,
            options=_options(args),
        )


def _options(args) -> dict:
    """``--option KEY=VALUE`` items as a Python detector's keyword arguments; checks the detector
    names something (its module imports) before any scene is rendered."""
    from eval.cli.run import check_detector
    from eval.detector.quality import DetectorQualityError
    from poi.core.loader import safe_load
    from poi.detectors import is_team_detector
    from poi.detectors.plugins import check_python_detector

    team = is_team_detector(args.model)
    if team:
        check_detector(args.model)
    elif args.option:
        raise DetectorQualityError(f"--option is for a Python detector; {args.model} is an ONNX model")
    out = {}
    for item in args.option:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise DetectorQualityError(f"--option {item!r}: expected KEY=VALUE, e.g. conf=0.3")
        out[key.strip()] = safe_load(text, f"--option {key.strip()}", error=DetectorQualityError)
    if team:
        check_python_detector(args.model, out)
    return out


def cmd_evaluate(args) -> int:
    from eval.detector.quality import AP_CONF, evaluation_report, format_evaluation, write_evaluation

    _options(args)
    out = Path(args.out)
    images = _labelled_images(args, out / "scenes")
    report = evaluation_report(_detect(args, images, AP_CONF), args.conf)
    report["model"] = str(args.model)
    if args.label_model:
        report["label_model"] = str(args.label_model)
    report["data"] = str(args.data or out / "scenes")
    write_evaluation(out, report)
    print(format_evaluation(report))
    print(f"evaluation.json and confusion.png in {out}")
    return 0


def cmd_quantize(args) -> int:
    from eval.detector.quantize import quantize_detector

    done = quantize_detector(args.model, args.data, args.out, args.images)
    print(
        f"{done['out']}: {done['bytes'] / 2**20:.1f} MiB, {done['how']}; "
        f"{done['float_nodes']} nodes kept in float (the head's decode, its last convolutions, "
        "the attention's q^T k)"
    )
    print("check it before use: poibench evaluate-detector --model OUT (mAP50 against the float model's)")
    return 0


def cmd_calibrate(args) -> int:
    from eval.detector.quality import center_samples, write_calibration

    _options(args)
    out = Path(args.out)
    images = _labelled_images(args, out.parent / f"{out.stem}_scenes")
    samples, mis = center_samples(_detect(args, images, args.conf))
    counts = write_calibration(out, samples, mis, args.model, args.label_model)
    fitted = [c for c, n in counts.items() if n >= 30]
    print(
        f"{out}: centre-error fits for default and {len(fitted)} classes from {len(samples.w)} detections; "
        f"{int(mis.sum())} misclassified"
    )
    print(f"plot: {out.with_suffix('.png')}; use it with --set calibration={out}")
    return 0


def _add_photo_detector_args(parser) -> None:
    """--model, --option and --label-model, as evaluate-photos and sim2real take them (:func:`_photo_detector`)."""
    parser.add_argument(
        "--model",
        help="an ONNX detector, python:MODULE:CLASS or an entry point name (default: the shipped model)",
    )
    parser.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a keyword argument of a Python detector (VALUE read as YAML); repeatable",
    )
    parser.add_argument(
        "--label-model",
        help="hazmat label classifier; 'none' for the detector alone (default: the shipped one with the "
        "shipped detector, none otherwise)",
    )


def _photo_detector(args) -> None:
    """The detector of evaluate-photos and sim2real: --model (default the shipped one, with the
    shipped label model unless --label-model says otherwise; 'none': the detector alone), its
    files checked and a Python detector's --option items with it (:func:`_options`)."""
    from eval.detector.quality import DetectorQualityError
    from poi.models import DEFAULT_LABEL_MODEL, DEFAULT_MODEL

    shipped = args.model is None
    if shipped:
        args.model = str(DEFAULT_MODEL)
    if args.label_model is None and shipped and DEFAULT_LABEL_MODEL.exists():
        args.label_model = str(DEFAULT_LABEL_MODEL)
    elif args.label_model is not None and args.label_model.lower() == "none":
        args.label_model = None
    for m in (args.model, args.label_model):
        if m is not None and m.endswith(".onnx") and not Path(m).exists():
            raise DetectorQualityError(f"{m}: no such model file")
    _options(args)


def _refuse_trained_photos(models, folders) -> None:
    """Refuse a photo folder that a model (detector or label classifier) was trained on part of,
    unless it was cut to that training's held-back images (``--holdout-of RUN``)."""
    from eval.detector.label_eval import listed_folder
    from eval.detector.quality import (
        PATH_SEPARATOR,
        PHOTO_FOLDERS_METADATA_KEY,
        DetectorQualityError,
        _model_metadata,
    )
    from poi.detectors import is_team_detector

    for model in models:
        if model is None or is_team_detector(model):
            continue
        meta = _model_metadata(model).get(PHOTO_FOLDERS_METADATA_KEY, "")
        trained_on = set(filter(None, meta.split(PATH_SEPARATOR)))
        for folder, cut in folders:
            if listed_folder(folder.root, trained_on) is not None and not cut:
                raise DetectorQualityError(
                    f"{model} was trained on part of {folder.root}; give --holdout-of its run folder"
                )


def cmd_evaluate_photos(args) -> int:
    """``poibench evaluate-photos``: eval.detector.photos on each --images folder, side by side."""
    import time

    from eval.detector.label_eval import load_folders
    from eval.detector.photos import FALSE_DETECTION, fold_classes, folder_report, load_folder, write_outputs
    from eval.detector.quality import DetectorQualityError

    if args.limit is not None and args.limit < 1:
        raise DetectorQualityError(f"--limit must be at least 1, got {args.limit}")
    if not 0.0 <= args.conf <= 1.0:
        raise DetectorQualityError(f"--conf must be in [0, 1], got {args.conf}")
    _photo_detector(args)
    if args.holdout_of is not None:
        if args.limit is not None:
            raise DetectorQualityError("--limit does not go with --holdout-of: the held-back images are scored")
        cut = load_folders(args.images, args.holdout_of, "--images")
    else:
        names: Counter[str] = Counter()
        cut = []
        for k, d in enumerate(args.images):
            folder = load_folder(d, args.limit, args.seed)
            names[folder.name] += 1
            if names[folder.name] > 1:
                folder.name = f"{folder.name}-{k + 1}"
            cut.append((folder, False))
    _refuse_trained_photos((args.model, args.label_model), cut)
    folders = [f for f, _ in cut]
    results = []
    cpu = []
    for folder in folders:
        t0 = time.process_time()
        results.append(fold_classes(_detect(args, folder.images, args.conf), args.absent))
        cpu.append(time.process_time() - t0)
    summary = {
        "model": str(args.model),
        "label_model": args.label_model,
        "conf": args.conf,
        "absent": args.absent,
        "iou_min": 0.5,
        "seed": args.seed,
        "false_detection": FALSE_DETECTION,
        "folders": [
            {
                "name": f.name,
                "path": str(f.root),
                "total_images": f.total_images,
                "without_labels": f.without_labels,
                "detect_cpu_s": round(c, 1),
                **folder_report(r, args.conf),
            }
            for f, r, c in zip(folders, results, cpu, strict=True)
        ],
    }
    out = Path(args.out)
    print(write_outputs(out, summary, folders, results, args.overlay, args.seed))
    for f in summary["folders"]:
        if f["without_labels"]:
            print(f"{f['name']}: {f['without_labels']} images have no labels file; taken as showing no object")
    print(f"summary.json, per_class.csv, report.md, recall_by_size.png and overlay.png in {out}")
    return 0


def cmd_sim2real(args) -> int:
    """``poibench sim2real``: eval.detector.sim2real's card of --photos against fresh renders."""
    import time

    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.detector.label_eval import load_folders
    from eval.detector.photos import fold_classes, load_folder
    from eval.detector.quality import DetectorQualityError
    from eval.detector.sim2real import (
        measure_photometry,
        photo_labels,
        render_labels,
        side_outcomes,
        sim2real_card,
        write_card,
    )
    from eval.progress import progress_bar

    if not 0.0 <= args.conf <= 1.0:
        raise DetectorQualityError(f"--conf must be in [0, 1], got {args.conf}")
    for flag, v in (("--scenes", args.scenes), ("--views", args.views)):
        if v < 1:
            raise DetectorQualityError(f"{flag} must be at least 1, got {v}")
    _photo_detector(args)
    _refuse_training_seed(args)
    cpu0 = time.process_time()
    folders = load_folders(args.photos, args.holdout_of, "--photos")
    _refuse_trained_photos((args.model, args.label_model), folders)
    labels = photo_labels([f for f, _ in folders])
    hung = render_labels(labels, args.absent)  # with --absent map, the labels folded into them too
    photo_images = [im for f, _ in folders for im in f.images]
    photo_results = fold_classes(_detect(args, photo_images, args.conf), args.absent)
    cpu = {"photos": time.process_time() - cpu0}
    out = Path(args.out)
    spec = DatasetSpec.trial_looks(
        images=args.scenes * args.views,
        images_per_scenario=args.views,
        seed=args.seed,
        val_every=1,
        camera=None,  # the trial's colour camera, still: what a trial shows
        blur_fraction=0.0,
        counts={**DatasetSpec.default_counts(), "hazmat": len(hung)},
        hazmat_labels=tuple(hung),
    )
    t0 = time.process_time()
    with progress_bar(total=spec.images, desc="renders", unit="img", quiet=args.quiet) as bar:
        write_dataset(spec, out / "renders", progress=bar.update)
    cpu["render"] = time.process_time() - t0
    t0 = time.process_time()
    renders = load_folder(out / "renders", name="renders")
    render_results = fold_classes(_detect(args, renders.images, args.conf), args.absent)
    cpu["detect_renders"] = time.process_time() - t0
    t0 = time.process_time()
    photos, rendered = side_outcomes(photo_results, args.conf), side_outcomes(render_results, args.conf)
    measure_photometry(photos, photo_images)
    measure_photometry(rendered, renders.images)
    card = {
        "model": str(args.model),
        "label_model": args.label_model,
        "conf": args.conf,
        "iou_min": 0.5,
        "absent": args.absent,
        "holdout_of": args.holdout_of,
        "photos": {
            "folders": [
                {"name": f.name, "path": str(f.root), "images": len(f.images), "held_back_only": cut}
                for f, cut in folders
            ],
            "images": photos.images,
            "placards": int(len(photos.label)),
        },
        "renders": {
            "path": str(out / "renders"),
            "scenes": args.scenes,
            "views": args.views,
            "seed": args.seed,
            "images": rendered.images,
            "placards": int(len(rendered.label)),
            "looks": "DatasetSpec.trial_looks, the trial's still colour camera, the photos' labels only",
            "labels": hung,
        },
        "error": None,
        **sim2real_card(photos, rendered, labels, seed=args.seed),
    }
    if photos.detections + rendered.detections == 0:
        card["error"] = (
            f"{args.model} boxed nothing at confidence >= {args.conf} on any of {photos.images} photos and "
            f"{rendered.images} renders; the recalls are 0 by default, not measured"
        )
    cpu["card"] = time.process_time() - t0
    card["cpu_s"] = {k: round(v, 1) for k, v in cpu.items()} | {"total": round(time.process_time() - cpu0, 1)}
    sides = [
        (replace(folders[0][0], name="photos", images=photo_images), photo_results),
        (renders, render_results),
    ]
    print(write_card(out, card, sides, args.overlay, args.seed))
    if card["error"]:
        raise DetectorQualityError(card["error"])
    print(f"card.md, card.json and misses.jpg in {out}; the renders in {out / 'renders'}")
    return 0
