"""CPU cost of hazmat label classifiers as the pipeline calls them, side by side.

Each ``--models`` file (a ``label_model.onnx`` of ``poibench train-labels``; default: the
shipped ``poi/models/default_labels.onnx``) is loaded as the pipeline loads it
(:class:`poi.detectors.hazmat_labels.HazmatLabelClassifier`, one onnxruntime thread) and
called on a 640x480 frame with K boxes of 20-120 px (K in ``--boxes``): crop, resize and
network, as :meth:`HazmatLabelClassifier.classify` does per detector call. The models take
turns call by call (``--calls`` each, after a warm-up), so a shared machine's load falls on
all of them alike; the figure is the process's CPU time (``time.process_time``) per call,
median over ``--rounds`` rounds. Run:
``python bench/bench_labels.py [--models A.onnx B.onnx] [--boxes 1 4] [--calls 200 --rounds 5]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from poi.detectors.hazmat_labels import HazmatLabelClassifier, LabelModelError

SHIPPED = Path(__file__).resolve().parents[1] / "poi" / "models" / "default_labels.onnx"


def boxes(k: int, rng: np.random.Generator) -> np.ndarray:
    """K boxes of 20-120 px side inside a 640x480 frame."""
    side = rng.uniform(20, 120, size=k)
    x0 = rng.uniform(0, 640 - side)
    y0 = rng.uniform(0, 480 - side)
    return np.stack([x0, y0, x0 + side, y0 + side], axis=1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", nargs="+", default=[str(SHIPPED)], help="label_model.onnx files")
    ap.add_argument("--boxes", nargs="+", type=int, default=[1, 4], help="boxes a call (default 1 4)")
    ap.add_argument("--calls", type=int, default=200, help="calls a model a round (default 200)")
    ap.add_argument("--rounds", type=int, default=5, help="rounds (default 5)")
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, size=(480, 640, 3), dtype=np.uint8)
    try:
        models = [HazmatLabelClassifier(model=m) for m in args.models]
    except LabelModelError as e:
        raise SystemExit(f"bench_labels: {e}") from None
    print(f"CPU ms a call (median of {args.rounds} rounds of {args.calls} calls, models in turn)")
    print("model".ljust(50) + "".join(f"{k} box{'es' if k > 1 else ''}".rjust(12) for k in args.boxes))
    table = {m.model: {} for m in models}
    for k in args.boxes:
        box = boxes(k, rng)
        for m in models:
            m.classify(frame, box)  # warm-up
        per: dict = {m.model: [] for m in models}
        for _ in range(args.rounds):
            for m in models:
                t = time.process_time()
                for _ in range(args.calls):
                    m.classify(frame, box)
                per[m.model].append((time.process_time() - t) / args.calls * 1000)
        for m in models:
            table[m.model][k] = statistics.median(per[m.model])
    for m in models:
        name = str(m.model)
        name = name if len(name) <= 48 else "..." + name[-45:]
        print(f"{name:<50}" + "".join(f"{table[m.model][k]:12.2f}" for k in args.boxes) + f"   (imgsz {m.imgsz})")


if __name__ == "__main__":
    main()
