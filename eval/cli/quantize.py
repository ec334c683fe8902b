"""``poibench quantize-detector``: an int8 copy of a float detector."""

from __future__ import annotations

import argparse

from eval.detector.quantize import CALIBRATION_IMAGES


def register(sub: argparse._SubParsersAction) -> None:
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
