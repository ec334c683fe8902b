"""``poibench evaluate-labels``, ``evaluate-photos`` and ``sim2real``: models on folders of labelled photos."""

from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import replace
from pathlib import Path

from eval.cli.args import non_negative_int, unit_interval
from eval.cli.detector_args import OPERATING_CONF, _detect, _options, _refuse_training_seed
from eval.detector.quality import EVAL_SEED

# 16 scenes of 40 views showed 531 placards of hazmat-photos-dev's 12 labels, 36-61 a label; 20 show
# 682, 49-75 a label (seed 1000)
SIM2REAL_SCENES = 20
SIM2REAL_VIEWS = 40


def register(sub: argparse._SubParsersAction) -> None:
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
        help="a train-labels run folder or its holdout.json: its photo folders are scored on their held-back "
        "images only",
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
        type=unit_interval,
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
        help="a train or train-labels run folder or its holdout.json: its photo folders are scored on their "
        "held-back images only",
    )
    ph.add_argument("--seed", type=int, default=0, help="seed of --limit's and the overlay's draws (default 0)")
    ph.add_argument(
        "--overlay", type=non_negative_int, default=12, help="images a folder on overlay.png (default 12; 0: none)"
    )
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
        help="a train or train-labels run folder (its holdout.json) or such a file (poi/models/"
        "photos_holdout.json): its photo folders are scored on their held-back images only",
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
        type=unit_interval,
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
    sr.add_argument(
        "--overlay", type=non_negative_int, default=12, help="images a side on misses.jpg (default 12; 0: none)"
    )
    sr.add_argument(
        "--decompose",
        action="store_true",
        help="also paste poibench's drawing of each placard's label over it, one at a time, on both sides: "
        "where the gap lies, in the placard or around it (a detector run a placard of 40 px or more, three "
        "versions each)",
    )
    sr.add_argument("--quiet", action="store_true", help="no progress bars")
    sr.set_defaults(func=cmd_sim2real)


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
    from eval.detector.quality import DetectorQualityError, model_photo_folders
    from poi.detectors import is_team_detector
    from poi.models import SHIPPED_HOLDOUT

    for model in models:
        if model is None or is_team_detector(model):
            continue
        trained_on = set(model_photo_folders(model))
        for folder, cut in folders:
            if listed_folder(folder.root, trained_on) is not None and not cut:
                raise DetectorQualityError(
                    f"{model} was trained on part of {folder.root}; give --holdout-of its run folder"
                    f" (the shipped models': {SHIPPED_HOLDOUT})"
                )


def cmd_evaluate_photos(args) -> int:
    """``poibench evaluate-photos``: eval.detector.photos on each --images folder, side by side."""
    import time

    from eval.detector.label_eval import load_folders
    from eval.detector.photos import FALSE_DETECTION, fold_classes, folder_report, load_folder, write_outputs
    from eval.detector.quality import DetectorQualityError, frame_scales

    if args.limit is not None and args.limit < 1:
        raise DetectorQualityError(f"--limit must be at least 1, got {args.limit}")
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
                **folder_report(r, args.conf, frame_scales(f.images)),
            }
            for f, r, c in zip(folders, results, cpu, strict=True)
        ],
    }
    out = Path(args.out)
    print(write_outputs(out, summary, folders, results, args.overlay, args.seed))
    for f in summary["folders"]:
        if f["without_labels"]:
            print(f"{f['name']}: {f['without_labels']} images have no labels file; taken as showing no object")
    overlay = " and overlay.png" if args.overlay else ""
    print(f"summary.json, per_class.csv, report.md, recall_by_size.png{overlay} in {out}")
    return 0


def cmd_sim2real(args) -> int:
    """``poibench sim2real``: eval.detector.sim2real's card of --photos against fresh renders."""
    import time

    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.detector.label_eval import load_folders
    from eval.detector.photos import fold_classes, load_folder
    from eval.detector.quality import DetectorQualityError, frame_scales
    from eval.detector.sim2real import (
        measure_photometry,
        photo_labels,
        render_labels,
        side_outcomes,
        sim2real_card,
        write_card,
    )
    from eval.progress import progress_bar

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
    photo_scales, render_scales = frame_scales(photo_images), frame_scales(renders.images)
    photos = side_outcomes(photo_results, args.conf, scales=photo_scales)
    rendered = side_outcomes(render_results, args.conf, scales=render_scales)
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
    if args.decompose:
        from eval.detector.quality import ImageDetector
        from eval.detector.sim2real import gap_parts, gap_parts_by_label
        from eval.detector.sim2real_paste import PASTE_MIN_PX, decompose_side

        t0 = time.process_time()
        detect = ImageDetector(args.model, args.conf, args.label_model, _options(args))
        card["decomposition"] = {"min_side_px": PASTE_MIN_PX}
        hits, pasted = {}, {}
        for side, images, results, scales in (
            ("photos", photo_images, photo_results, photo_scales),
            ("renders", renders.images, render_results, render_scales),
        ):
            with progress_bar(total=len(images), desc=f"paste, {side}", unit="img", quiet=args.quiet) as bar:
                card["decomposition"][side], hits[side], pasted[side] = decompose_side(
                    detect, images, results, scales, args.absent, args.seed, progress=bar.update
                )
        card["decomposition"]["gap_parts"] = gap_parts(hits["photos"], hits["renders"], args.seed)
        card["decomposition"]["by_label"] = gap_parts_by_label(hits, pasted, args.seed)
        cpu["decompose"] = time.process_time() - t0
    card["cpu_s"] = {k: round(v, 1) for k, v in cpu.items()} | {"total": round(time.process_time() - cpu0, 1)}
    sides = [
        (replace(folders[0][0], name="photos", images=photo_images), photo_results),
        (renders, render_results),
    ]
    print(write_card(out, card, sides, args.overlay, args.seed))
    if card["error"]:
        raise DetectorQualityError(card["error"])
    misses = " and misses.jpg" if args.overlay else ""
    print(f"card.md, card.json{misses} in {out}; the renders in {out / 'renders'}")
    return 0
