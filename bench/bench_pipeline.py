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

from eval.trial.episode import Observer, Tick, run_episode
from eval.trial.sources import SimulationSource
from poi.config import apply_overrides, load_config
from poi.core.geometry import matrix_to_quat_wxyz
from poi.core.names import CLASSES, MAPPING_TYPES, TYPES, class_to_identity
from poi.core.types import Detection, Observation
from poi.models import DEFAULT_LABEL_MODEL, DEFAULT_MODEL
from poi.pipeline import Pipeline
from sim.oracle import OracleDetector, OracleSettings
from sim.scenario import load_scenario

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
    source = SimulationSource(load_scenario("default"), args.frames, chunk=CHUNK)
    sim, n = source.sim, source.n_frames
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
    source.oracle = OracleDetector(OracleSettings(seed=0))  # fed each frame's truth by the source
    pipe = Pipeline(cfg, [source.oracle])
    seed_tracks(pipe, args.tracks)
    timer = StageTimer()
    observers: list[Observer] = [timer]
    onnx = None
    if args.model:
        onnx = OnnxTimer(onnx_detector(args.model, args.label_model))
        observers.append(onnx)
    try:
        run_episode(source, pipe, observers, desc="bench")
    finally:
        source.close()
    stages, total = timer.stages, timer.total
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores; {n} frames at 640x480, "
        f"{len(pipe.tracks())} live tracks at the end ({args.tracks} seeded out of sight)"
    )
    for k, v in stages.items():
        print(f"{k:28s} mean {np.mean(v):7.3f} ms   p90 {np.percentile(v, 90):7.3f} ms")
    print(
        f"{'whole pipeline (oracle)':28s} mean {np.mean(total):7.3f} ms   p90 {np.percentile(total, 90):7.3f} ms"
    )
    if onnx is not None and onnx.ms:
        # the first call includes onnxruntime's warm-up and is left out
        ms = onnx.ms[1:]
        print(
            f"{'onnx detector':28s} mean {np.mean(ms):7.3f} ms   p90 {np.percentile(ms, 90):7.3f} ms"
            f"   ({len(onnx.ms) - 1} frames, {np.mean(onnx.boxes[1:]):.2f} placards a frame)"
        )
        for k, v in onnx.stages.items():
            print(f"  {k:26s} mean {np.mean(v[1:]):7.3f} ms   p90 {np.percentile(v[1:], 90):7.3f} ms")
    for shared in (False, True):
        bench_slam(args.landmarks, shared)


def seed_tracks(pipe: Pipeline, n_tracks: int) -> None:
    """``n_tracks`` live tracks of every type, spread over the maze but under the floor: gated
    against and tested for view every frame, never seen, so all of them stay alive."""
    detected_types = tuple(t for t in TYPES if t not in MAPPING_TYPES)  # the map's landmarks have no class
    rng = np.random.default_rng(0)
    seeds = []
    for i in range(n_tracks):
        typ = detected_types[i % len(detected_types)]
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


def onnx_detector(model: str, label_model: str | None):
    """The ONNX detector ``model`` names ('default': the shipped one, with its label classifier)."""
    from poi.detectors import build_detector

    spec = {"name": "onnx", "model": model}
    if model == "default":
        spec["model"] = str(DEFAULT_MODEL)
        if DEFAULT_LABEL_MODEL.exists():
            spec["label_model"] = str(DEFAULT_LABEL_MODEL)
    if label_model:
        spec["label_model"] = label_model
    print(f"onnx detector: {spec['model']}" + (f" + {spec['label_model']}" if "label_model" in spec else ""))
    return build_detector(spec)


class StageTimer(Observer):
    """Each frame's pipeline time and its stages' (``res.timing_ms``), in milliseconds."""

    def __init__(self) -> None:
        self.stages: dict[str, list[float]] = {}
        self.total: list[float] = []

    def on_frame(self, tick: Tick) -> None:
        self.total.append(tick.process_ms)
        for k, v in tick.res.timing_ms.items():
            self.stages.setdefault(k, []).append(v)


class OnnxTimer(Observer):
    """The ONNX detector timed, stage by stage, on every tenth frame."""

    EVERY = 10

    def __init__(self, detector) -> None:
        self.detector = detector
        self.ms: list[float] = []
        self.stages: dict[str, list[float]] = {}
        self.boxes: list[int] = []

    def on_frame(self, tick: Tick) -> None:
        if tick.frame.index % self.EVERY:
            return
        t = time.perf_counter()
        dets = self.detector.detect(tick.frame)
        self.ms.append(1e3 * (time.perf_counter() - t))
        self.boxes.append(sum(d.type == "hazmat" for d in dets))
        for k, v in self.detector.last_timing_ms.items():
            self.stages.setdefault(k, []).append(v)


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
