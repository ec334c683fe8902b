"""Milliseconds per frame for each pipeline stage at 640x480 with 30 live tracks.

Frames are the default trial's, in order at its 10 frames per second (rendered
in chunks of ``CHUNK`` frames before each chunk is timed, so rendering never
shares the CPU with the timed code); 30 tracks are seeded in the tracker so
gating and the in-view test work at that size; the
detector is the oracle (ground-truth boxes), so "detect" here is near zero and
the figures are the pipeline's own cost. With ``--model FILE.onnx`` (and
``--label-model``; ``--model default``: the shipped detector and label
classifier) it also times the ONNX detector on every tenth frame, stage by
stage (letterbox, network, decoding and NMS, placard labels); with ``--slam`` the pipeline runs in ``localize.mode:
slam``. At the end it times the UKF-SLAM alone ([Bouda2025]_ 2.2) with ``--landmarks``
mapped landmarks (default 40), five of them observed per step, without and with view biases
(observations with a shared part). Run:
``python bench/bench_pipeline.py``.

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from poi.config import apply_overrides, load_config
from poi.core.geometry import matrix_to_quat_wxyz
from poi.core.names import CLASSES, MAPPING_TYPES, TYPES, class_to_identity
from poi.core.types import Detection, Observation
from poi.pipeline import Pipeline
from sim.oracle import OracleDetector, OracleSettings
from sim.scenario import load_scenario
from sim.simulator import Simulation

CHUNK = 100


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, help="time only the first N frames (default: all)")
    ap.add_argument("--tracks", type=int, default=30)
    ap.add_argument("--model", help="an ONNX detector to time as well ('default': the shipped one)")
    ap.add_argument("--label-model", help="a hazmat label classifier for --model")
    ap.add_argument("--slam", action="store_true", help="run the pipeline with localize.mode=slam")
    ap.add_argument("--landmarks", type=int, default=40, help="landmarks in the SLAM-alone timing (default 40)")
    args = ap.parse_args()
    sim = Simulation(load_scenario("default"))
    n = sim.n_frames if args.frames is None else min(args.frames, sim.n_frames)
    T = sim.T_tracker_optical_nominal
    q = matrix_to_quat_wxyz(T[:3, :3])
    cfg = apply_overrides(
        load_config(),
        [
            f"mount.T_tracker_camera.translation_m=[{T[0, 3]}, {T[1, 3]}, {T[2, 3]}]",
            f"mount.T_tracker_camera.quaternion_wxyz=[{q[0]}, {q[1]}, {q[2]}, {q[3]}]",
        ]
        + (["localize.mode=slam"] if args.slam else []),
    )
    oracle = OracleDetector(OracleSettings(seed=0))
    DETECTED_TYPES = tuple(t for t in TYPES if t not in MAPPING_TYPES)  # the map's landmarks have no class
    pipe = Pipeline(cfg, [oracle])
    # seed live tracks spread over the maze
    rng = np.random.default_rng(0)
    seeds = []
    for i in range(args.tracks):
        # every type, spread over the maze but under the floor: gated against and tested for
        # view every frame, never seen, so all of them stay alive
        typ = DETECTED_TYPES[i % len(DETECTED_TYPES)]
        cls = next(c for c in CLASSES if class_to_identity(c)[0] == typ)
        det = Detection(class_name=cls, type=typ, text="", box_xyxy=(0, 0, 10, 10), confidence=0.9)
        p = np.array([rng.uniform(-1, 8), rng.uniform(-8, 1), -2.0])
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
    onnx = None
    if args.model:
        from poi.detectors import build_detector

        spec = {"name": "onnx", "model": args.model}
        if args.model == "default":
            from eval.trial.run import DEFAULT_LABEL_MODEL, DEFAULT_MODEL

            spec["model"] = str(DEFAULT_MODEL)
            if DEFAULT_LABEL_MODEL.exists():
                spec["label_model"] = str(DEFAULT_LABEL_MODEL)
        if args.label_model:
            spec["label_model"] = args.label_model
        onnx = build_detector(spec)
        print(f"onnx detector: {spec['model']}" + (f" + {spec['label_model']}" if "label_model" in spec else ""))
    onnx_ms = []
    onnx_stages: dict[str, list[float]] = {}
    onnx_boxes = []
    with sim:
        for start in range(0, n, CHUNK):
            data = list(sim.frames(start, min(start + CHUNK, n)))
            for frame, truth in data:
                oracle.set_truth(truth)
                t = time.perf_counter()
                res = pipe.process(frame)
                total.append(1e3 * (time.perf_counter() - t))
                for k, v in res.timing_ms.items():
                    stages.setdefault(k, []).append(v)
            if onnx is not None:
                for frame, _ in data[:: max(1, len(data) // 10)]:
                    t = time.perf_counter()
                    dets = onnx.detect(frame)
                    onnx_ms.append(1e3 * (time.perf_counter() - t))
                    onnx_boxes.append(sum(d.type == "hazmat" for d in dets))
                    for k, v in onnx.last_timing_ms.items():
                        onnx_stages.setdefault(k, []).append(v)
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; {n} frames at 640x480, "
        f"{len(pipe.tracks())} live tracks at the end ({args.tracks} seeded out of sight)"
    )
    for k, v in stages.items():
        print(f"{k:28s} mean {np.mean(v):7.3f} ms   p90 {np.percentile(v, 90):7.3f} ms")
    print(
        f"{'whole pipeline (oracle)':28s} mean {np.mean(total):7.3f} ms   p90 {np.percentile(total, 90):7.3f} ms"
    )
    if onnx_ms:
        # the first call includes onnxruntime's warm-up and is left out
        ms = onnx_ms[1:]
        print(
            f"{'onnx detector':28s} mean {np.mean(ms):7.3f} ms   p90 {np.percentile(ms, 90):7.3f} ms"
            f"   ({len(onnx_ms) - 1} frames, {np.mean(onnx_boxes[1:]):.2f} placards a frame)"
        )
        for k, v in onnx_stages.items():
            print(f"  {k:26s} mean {np.mean(v[1:]):7.3f} ms   p90 {np.percentile(v[1:], 90):7.3f} ms")
    for shared in (False, True):
        bench_slam(args.landmarks, shared)


def bench_slam(n_landmarks: int, shared: bool, visible: int = 5, steps: int = 500) -> None:
    """The UKF-SLAM's predict and update with ``n_landmarks`` in the state, ``visible`` of
    them observed per step, on a robot driving a circle among them. ``shared``: each
    observation's R has a shared part (half of it), so every landmark carries a view bias
    (n = r + 4L, r the robot's states); otherwise n = r + 2L."""
    from poi.config import SlamConfig
    from poi.estimation.slam import LandmarkObservation, UkfSlam, rot2

    rng = np.random.default_rng(0)
    names = [f"lm{i}" for i in range(n_landmarks)]
    truth = rng.uniform(-6, 6, (n_landmarks, 2))
    slam = UkfSlam(SlamConfig(n_min=1))
    S = 0.5 if shared else None
    slam.observe(
        [
            LandmarkObservation(
                class_name=c, xy=p, R=0.01 * np.eye(2), R_shared=None if S is None else S * 0.01 * np.eye(2)
            )
            for c, p in zip(names, truth, strict=True)
        ],
        0.0,
    )
    robot = np.zeros(3)
    step = np.array([0.03, 0.0, 0.01])
    t_pred, t_obs = [], []
    for k in range(steps):
        robot = robot + np.r_[rot2(robot[2]) @ step[:2], step[2]]
        seen = np.argsort(np.linalg.norm(truth - robot[:2], axis=1))[:visible]
        obs = [
            LandmarkObservation(
                class_name=names[i],
                xy=rot2(robot[2]).T @ (truth[i] - robot[:2]) + rng.normal(0, 0.03, 2),
                R=0.03**2 * np.eye(2),
                R_shared=None if S is None else S * 0.03**2 * np.eye(2),
            )
            for i in seen
        ]
        t0 = time.perf_counter()
        slam.predict(step)
        t1 = time.perf_counter()
        slam.observe(obs, 0.1 * (k + 1))
        t2 = time.perf_counter()
        t_pred.append(1e3 * (t1 - t0))
        t_obs.append(1e3 * (t2 - t1))
    tot = np.add(t_pred, t_obs)
    what = "with view biases" if shared else "without shared parts"
    print(
        f"UKF-SLAM alone, {what}: {len(slam.landmarks)} of {n_landmarks} landmarks mapped at the end "
        f"(state n = {slam.n}), {visible} seen per step, {steps} steps"
    )
    for name, v in (("slam predict", t_pred), ("slam update", t_obs), ("slam predict + update", tot)):
        print(f"{name:28s} mean {np.mean(v):7.3f} ms   p90 {np.percentile(v, 90):7.3f} ms")


if __name__ == "__main__":
    main()
