"""``poibench evaluate-detector`` and ``poibench calibrate``: a detector on fresh scenes or a val split."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from eval.cli.args import positive_int, unit_interval
from eval.cli.detector_args import OPERATING_CONF, _detect, _options, _refuse_training_seed
from eval.detector.quality import EVAL_IMAGES, EVAL_SEED, DetectorQualityError


def register(sub: argparse._SubParsersAction) -> None:
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
        e.add_argument(
            "--images", type=positive_int, help=f"fresh evaluation images (default {EVAL_IMAGES}; not with --data)"
        )
        e.add_argument("--seed", type=int, help=f"seed of the fresh scenes (default {EVAL_SEED}; not with --data)")
        e.add_argument(
            "--conf",
            type=unit_interval,
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


def _labelled_images(args, work: Path):
    """The val split of --data, or fresh scenes rendered from --seed into ``work``."""
    from eval.detector.dataset import DatasetSpec, write_dataset
    from eval.detector.quality import load_split
    from eval.progress import progress_bar

    if args.data:
        given = [flag for flag, value in (("--images", args.images), ("--seed", args.seed)) if value is not None]
        if given:
            raise DetectorQualityError(
                f"{' and '.join(given)}: for fresh scenes; --data {args.data} evaluates on that folder's val split"
            )
        return load_split(args.data, "val")
    args.images = EVAL_IMAGES if args.images is None else args.images
    args.seed = EVAL_SEED if args.seed is None else args.seed
    _refuse_training_seed(args)
    spec = DatasetSpec.trial_looks(images=args.images, seed=args.seed, val_every=1)
    with progress_bar(total=spec.images, desc="scenes", unit="img", quiet=args.quiet) as bar:
        write_dataset(spec, work, progress=bar.update)
    return load_split(work, "val")


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


def cmd_calibrate(args) -> int:
    from eval.detector.quality import center_samples, write_calibration

    _options(args)
    out = Path(args.out)
    # fresh scenes are rendered into a temporary folder (hundreds of MB), not beside the YAML:
    # `poibench dataset` and --data keep scenes to reuse
    with tempfile.TemporaryDirectory(prefix="poibench-calibrate-") as work:
        images = _labelled_images(args, Path(work) / "scenes")
        samples, mis = center_samples(_detect(args, images, args.conf))
    counts = write_calibration(out, samples, mis, args.model, args.label_model)
    fitted = [c for c, n in counts.items() if n >= 30]
    print(
        f"{out}: centre-error fits for default and {len(fitted)} classes from {len(samples.w)} detections; "
        f"{int(mis.sum())} misclassified"
    )
    print(f"plot: {out.with_suffix('.png')}; use it with --set calibration={out}")
    return 0
