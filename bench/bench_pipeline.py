"""Milliseconds per frame for each pipeline stage at 640x480 with 30 live tracks.

Frames come from the default scenario (rendered once, before timing); 30 tracks
are seeded in the tracker so gating and the in-view test work at that size; the
detector is the oracle (ground-truth boxes), so "detect" here is near zero and
the figures are the pipeline's own cost. With ``--model FILE.onnx`` it also
times that model's inference. Run: ``python bench/bench_pipeline.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from poi.config import apply_overrides, load_config
from poi.geometry import matrix_to_quat_wxyz
from poi.pipeline import Pipeline
from poi.types import Detection, Observation
from sim.oracle import OracleDetector, OracleSettings
from sim.scenario import load_scenario
from sim.simulator import Simulation


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--tracks", type=int, default=30)
    ap.add_argument("--model", help="an ONNX detector to time as well")
    args = ap.parse_args()
    sc = load_scenario("default")
    with Simulation(sc) as sim:
        ks = np.linspace(0, sim.n_frames - 1, args.frames).astype(int)
        data = [sim.frame(int(k)) for k in ks]
        T = sim.T_tracker_optical_nominal
    q = matrix_to_quat_wxyz(T[:3, :3])
    cfg = apply_overrides(
        load_config(),
        [
            f"mount.T_tracker_camera.translation_m=[{T[0, 3]}, {T[1, 3]}, {T[2, 3]}]",
            f"mount.T_tracker_camera.quaternion_wxyz=[{q[0]}, {q[1]}, {q[2]}, {q[3]}]",
        ],
    )
    oracle = OracleDetector(OracleSettings(seed=0))
    pipe = Pipeline(cfg, [oracle])
    # seed live tracks spread over the maze
    rng = np.random.default_rng(0)
    seeds = []
    for _ in range(args.tracks):
        det = Detection(class_name="door", type="door", text="", box_xyxy=(0, 0, 10, 10), confidence=0.9)
        p = np.array([rng.uniform(-1, 5), rng.uniform(-4, 1), rng.uniform(0, 1.4)])
        seeds.append(
            Observation(
                detection=det,
                timestamp_s=0.0,
                position_map=p,
                R=0.01 * np.eye(3),
                position_cam=p,
                Sigma_c=0.01 * np.eye(3),
                depth_m=1.0,
            )
        )
    pipe.tracker.step(seeds, 0.0, set())
    pipe.tracker.cfg.t_max = 1e9  # keep them alive through the run
    stages: dict[str, list[float]] = {}
    total = []
    for frame, truth in data:
        oracle.set_truth(truth)
        t = time.perf_counter()
        res = pipe.process(frame)
        total.append(1e3 * (time.perf_counter() - t))
        for k, v in res.timing_ms.items():
            stages.setdefault(k, []).append(v)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; {args.frames} frames at 640x480, "
        f"{len(pipe.tracks())} live tracks at the end"
    )
    for k, v in stages.items():
        print(f"{k:28s} mean {np.mean(v):7.3f} ms   p90 {np.percentile(v, 90):7.3f} ms")
    print(
        f"{'whole pipeline (oracle)':28s} mean {np.mean(total):7.3f} ms   p90 {np.percentile(total, 90):7.3f} ms"
    )
    if args.model:
        from poi.detectors import build_detector

        det = build_detector({"name": "onnx", "model": args.model})
        det.detect(data[0][0])
        t = time.perf_counter()
        for frame, _ in data:
            det.detect(frame)
        print(f"{'onnx detector':28s} mean {1e3 * (time.perf_counter() - t) / len(data):7.3f} ms")


if __name__ == "__main__":
    main()
