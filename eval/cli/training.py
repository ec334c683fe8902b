"""``poibench train`` and ``poibench train-labels``: training the detector and the hazmat label classifier."""

from __future__ import annotations

import argparse
import os

from eval.detector.train import PLACARD_MODES


def register(sub: argparse._SubParsersAction) -> None:
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
    t.add_argument(
        "--epochs", type=int, default=60, help="training epochs (default 60; --hours instead fits them)"
    )
    t.add_argument("--imgsz", type=int, default=320, help="training and export input size (default 320)")
    t.add_argument(
        "--export-imgsz",
        type=int,
        nargs=2,
        metavar=("H", "W"),
        help="model.onnx's fixed input height and width, multiples of 32 (default: --imgsz square); "
        "e.g. 320 416 for 4:3 frames",
    )
    t.add_argument("--batch", type=int, default=16, help="images a batch (default 16)")
    t.add_argument("--seed", type=int, default=0, help="seed of the training and of --holdout's draw (default 0)")
    t.add_argument("--device", default="cpu", help="cpu or a CUDA device index (default cpu)")
    t.add_argument("--workers", type=int, default=2, help="data-loading worker processes (default 2)")
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
    lt.add_argument("--epochs", type=int, default=16, help="training epochs (default 16)")
    lt.add_argument("--samples", type=int, default=32000, help="crops per epoch (default 32000)")
    lt.add_argument("--seed", type=int, default=0, help="seed of the training and of --holdout's draw (default 0)")
    lt.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    lt.add_argument("--imgsz", type=int, help="crop side in px the classifier reads (multiple of 16; default 64)")
    lt.add_argument(
        "--widths",
        type=int,
        nargs="+",
        help="channels of each conv + max-pool stage (default 32 64 128 256)",
    )
    lt.add_argument(
        "--model",
        help="a classifier to fine-tune from: a run's label_model.pt or last.pt, or a float label_model.onnx "
        "(e.g. poi/models/default_labels.pt or .onnx); its crop size and widths are kept",
    )
    lt.add_argument(
        "--lr",
        type=float,
        help="peak of the one-cycle learning rate (default 3e-3 from scratch, 1e-3 fine-tuning --model)",
    )
    lt.add_argument(
        "--holdout",
        type=float,
        help="fraction of each photo folder's images held back (by image, drawn with --seed) as validation; "
        "listed in RUN/holdout.json for evaluate-labels --holdout-of",
    )
    lt.set_defaults(func=cmd_train_labels)

    ex = sub.add_parser(
        "export-detector",
        help="export a detector checkpoint (.pt) to ONNX at another fixed input size (extra 'train')",
    )
    ex.add_argument("--model", required=True, help="a YOLO checkpoint, e.g. poi/models/default.pt")
    ex.add_argument(
        "--imgsz",
        type=int,
        nargs=2,
        required=True,
        metavar=("H", "W"),
        help="the input height and width, multiples of 32; e.g. 288 384 takes a 640x480 frame at 0.6",
    )
    ex.add_argument("--out", required=True, help="the ONNX model to write")
    ex.set_defaults(func=cmd_export, out_is_file=True)


def cmd_train(args) -> int:
    from eval.detector.train import TrainSpec, exported_checkpoint, train

    spec = TrainSpec(
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
        export_imgsz=None if args.export_imgsz is None else tuple(args.export_imgsz),
    )
    out = train(spec)
    print(f"model: {out}")
    print(
        f"to make it the default detector: cp it to poi/models/default_fp32.onnx, quantise that "
        "(poibench quantize-detector --out poi/models/default.onnx, or cp it there as it is), and "
        f"{exported_checkpoint(spec)} (the weights it was exported from) to"
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
            imgsz=args.imgsz,
            widths=args.widths,
            holdout=args.holdout,
            model=args.model,
            lr=args.lr,
        )
    )
    print(f"label model: {out}")
    print(
        "to use it with the default detector: cp it to poi/models/default_labels.onnx and "
        f"{out.parent}/label_model.pt to poi/models/default_labels.pt"
    )
    return 0


def cmd_export(args) -> int:
    from pathlib import Path

    from eval.detector.train import TrainError, check_export_size, export_detector, export_of

    check_export_size(tuple(args.imgsz), "--imgsz")
    model = Path(args.model)
    if model.suffix == ".onnx":
        raise TrainError(
            f"--model {args.model}: an export; give its checkpoint (.pt; the shipped detector's is "
            "poi/models/default.pt), or rebuild one from it with poibench train --model"
        )
    if model.suffix != ".pt" or not model.is_file():
        raise TrainError(f"--model {args.model}: expected a YOLO checkpoint (.pt) that exists")
    start = export_of(model)
    if start is not None and Path(args.out).resolve() == start.resolve():
        raise TrainError(
            f"--out {args.out}: the checkpoint's own export, whose stamps it copies; give another name"
        )
    out = export_detector(model, tuple(args.imgsz), Path(args.out), start=start)
    said = f"; what it trained on copied from {start}" if start is not None else ""
    print(f"{out}: {args.imgsz[0]}x{args.imgsz[1]} input{said}")
    print(
        f"quantise it for the pipeline's speed: poibench quantize-detector --model {out} --data DIR --out Q.onnx"
    )
    return 0
