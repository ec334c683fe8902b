"""A trial's frame sources (:mod:`eval.trial.episode`): the simulator, or a perception record.

:class:`SimulationSource` renders the scenario (``sim.simulator.Simulation``) and gives each
frame with its truth, feeding the oracle detector each frame's truth before the pipeline sees
the frame. :class:`RecordSource` replays a perception record (:mod:`eval.trial.perception_cache`):
the pipeline after detection reads the recorded detections, depth and poses, and the trial
the recorded truth. Both tell a trial the same things (its sensors, its detectors, its truth,
walls and path), so :func:`eval.trial.run.run_trial` is one composition for either.

:func:`record_perception` makes a record: an episode of the simulation whose stage is the
detectors alone (:class:`Perception`) and whose observer keeps each frame (:class:`FrameRecords`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from eval.scoring.funnel import ObjectView
from eval.scoring.truth import truth_rows
from eval.trial.detectors import make_detectors
from eval.trial.episode import Observer, Step, Tick, run_episode
from eval.trial.sensor_settings import mean_drift_multiplier, sensor_settings, simulation_sensor_settings


def object_views(truth) -> list[ObjectView]:
    """The funnel's views of the objects a frame's ground truth (``sim.simulator.FrameTruth``) shows."""
    return [
        ObjectView(
            id=v.id,
            box_xyxy=tuple(round(float(c), 2) for c in v.box_xyxy),
            visible_fraction=round(float(v.visible_fraction), 4),
            distance_m=round(float(np.linalg.norm(v.position_cam)), 4),
            angle_deg=round(float(v.view_angle_deg), 2),
            type=v.type,
            pixels=int(v.pixels),
        )
        for v in truth.visible
    ]


class SimulationSource:
    """The frames of a scenario as the simulator renders them, up to ``max_frames``; with
    ``chunk``, rendered that many at a time before any of them is given (so rendering never
    shares the CPU with the timed code: ``bench/bench_pipeline.py``)."""

    def __init__(self, sc, max_frames: int | None = None, *, chunk: int | None = None) -> None:
        from sim.simulator import Simulation

        self.sim = Simulation(sc)
        self.n_frames = self.sim.n_frames if max_frames is None else min(max_frames, self.sim.n_frames)
        self.chunk = chunk
        self.oracle = None  # fed each frame's truth (make_detectors' oracle)
        self.uses_oracle = False

    # what a trial asks of its world
    @property
    def intrinsics(self):
        return self.sim.intrinsics

    def sensor_settings(self) -> list[str]:
        return simulation_sensor_settings(self.sim)

    def detectors(self, choice: str, cfg, notes: list[str]) -> list:
        """The detectors of ``choice`` (:func:`eval.trial.detectors.make_detectors`); the
        simulation then renders truth boxes (the oracle's and the funnel's views)."""
        dets, self.oracle = make_detectors(choice, cfg, self.sim, notes)
        self.uses_oracle = self.oracle is not None
        self.sim.truth_boxes = True
        return dets

    def pipeline_qr_reader(self):
        return None  # the pipeline's own, on the pixels

    def funnel_qr_reader(self, cfg):
        """(frame, QR box) -> the QR reader's text on the frame's pixels, with the camera's motion
        as the pipeline of ``cfg`` reads it, for the funnel's views the pipeline did not ask
        about; None without a reader."""
        from poi.config import mount_matrix
        from poi.pipeline import find_qr_reader, qr_camera_motion

        reader = find_qr_reader()
        if reader is None:
            return None
        mount = mount_matrix(cfg)
        return lambda frame, det: reader(frame.rgb, [det], qr_camera_motion(frame, cfg, mount))[0].text

    def truth_rows(self) -> list:
        return truth_rows(self.sim)

    def walls_map(self) -> list:
        return self.sim.walls_in_map()

    def robot_path_map(self) -> np.ndarray:
        return self.sim.robot_path_map()[: self.n_frames]

    def sim_duration_s(self) -> float:
        return float(self.sim.times_s[self.n_frames - 1]) if self.n_frames else 0.0

    def _frames(self):
        if self.chunk is None:
            yield from self.sim.frames(0, self.n_frames)
            return
        for start in range(0, self.n_frames, self.chunk):
            yield from list(self.sim.frames(start, min(start + self.chunk, self.n_frames)))

    def steps(self) -> Iterator[Step]:
        for frame, truth in self._frames():
            if self.oracle is not None:
                self.oracle.set_truth(truth)
            views = object_views(truth)
            yield Step(
                frame=frame,
                truth=truth,
                T_map_tracker_true=truth.T_map_tracker,
                views=views,
                blur_px=truth.blur_px,
            )

    def close(self) -> None:
        self.sim.close()


class RecordSource:
    """A trial's frames replayed from its perception record (``eval.trial.perception_cache.PerceptionRecord``):
    no pixels, the recorded detections (:class:`eval.trial.perception_cache.ReplayDetector`)."""

    def __init__(self, record, sc) -> None:
        self.record = record
        self.sc = sc
        self.n_frames = record.n_frames
        self.uses_oracle = record.uses_oracle
        self.replay = None
        self.intrinsics = record.intrinsics

    def sensor_settings(self) -> list[str]:
        return sensor_settings(self.record.T_tracker_optical_nominal, self.sc, self.record.drift_multiplier)

    def detectors(self, choice: str, cfg, notes: list[str]) -> list:
        from eval.trial.perception_cache import ReplayDetector

        self.replay = ReplayDetector(self.record, cfg.detector.conf, cfg.detector.type_conf)
        notes.extend(self.record.notes)
        return [self.replay]

    def pipeline_qr_reader(self):
        return self.replay.read_qr if self.record.qr_read else None

    def funnel_qr_reader(self, cfg):
        """(frame, QR box) -> the text recorded for the box (read with the frame's motion then)."""
        return lambda frame, det: self.replay.current.qr_texts.get(tuple(det.box_xyxy), "")

    def truth_rows(self) -> list:
        return self.record.truth_rows

    def walls_map(self) -> list:
        return self.record.walls_map

    def robot_path_map(self) -> np.ndarray:
        return self.record.robot_path_map

    def sim_duration_s(self) -> float:
        n = self.n_frames
        return float(self.record.times_s[n - 1]) if n else 0.0

    def steps(self) -> Iterator[Step]:
        for (frame, T_true), fr in zip(self.record.replay_frames(), self.record.frames, strict=True):
            yield Step(frame=frame, T_map_tracker_true=T_true, views=fr.views, blur_px=fr.blur_px)

    def close(self) -> None:
        pass


class Perception:
    """The stage a perception record runs: every detector on the frame, the Landolt-C rings read
    from the pixels as the pipeline reads them, and the QR reader on every QR box without text
    (a replay may ask for any of them). ``process(frame) -> (detections, {box: text})``."""

    def __init__(self, detectors: list, reader, cfg) -> None:
        from poi.config import mount_matrix

        self.detectors = detectors
        self.reader = reader
        # the trial's pipeline configuration and its mount: the camera's motion as its pipeline reads it
        self.cfg, self.mount = cfg, mount_matrix(cfg)

    def process(self, frame):
        from poi.detectors.landolt import attach_landolt_text
        from poi.pipeline import qr_camera_motion

        dets = []
        for det in self.detectors:
            dets.extend(det.detect(frame))
        if any(d.type == "landolt-c" and not d.text for d in dets):  # read from pixels, as the pipeline does
            dets = attach_landolt_text(frame.rgb, dets)
        texts = {}
        unread = [d for d in dets if d.type == "qr" and not d.text]
        if self.reader is not None and unread:
            motion = qr_camera_motion(frame, self.cfg, self.mount)
            for d, r in zip(unread, self.reader(frame.rgb, unread, motion), strict=True):
                texts[tuple(d.box_xyxy)] = r.text
        return dets, texts


class FrameRecords(Observer):
    """Each frame of a perception record (``eval.trial.perception_cache.FrameRecord``); depth on
    the Z16 grid of ``unit_m`` is kept as its counts."""

    def __init__(self, unit_m: float | None = None) -> None:
        self.frames: list = []
        self.unit_m = unit_m

    def on_frame(self, tick: Tick) -> None:
        from eval.trial.perception_cache import FrameRecord, TiledDepth

        (dets, texts), frame, truth = tick.res, tick.frame, tick.step.truth
        self.frames.append(
            FrameRecord(
                index=frame.index,
                timestamp_s=frame.timestamp_s,
                pose=None if frame.pose is None else np.array(frame.pose),
                pose_confidence=frame.pose_confidence,
                pose_relocalised=frame.pose_relocalised,
                depth=None if frame.depth_m is None else TiledDepth.from_array(frame.depth_m, unit_m=self.unit_m),
                detections=dets,
                qr_texts=texts,
                T_map_tracker_true=np.array(truth.T_map_tracker),
                views=tick.step.views,
                blur_px=round(float(truth.blur_px), 3),
            )
        )


def record_perception(sc, cfg, detector: str, max_frames: int | None, key: str):
    """Simulate the scenario and run its detectors (the ONNX one at the cache's floor) on every
    frame, keeping what the pipeline after detection reads (eval.trial.perception_cache).
    ``cfg``: the trial's pipeline configuration (:func:`eval.trial.pipeline_config.trial_pipeline_config`)."""
    from eval.trial.perception_cache import CONF_FLOOR, PerceptionRecord
    from poi.config import apply_overrides
    from poi.pipeline import find_qr_reader

    source = SimulationSource(sc, max_frames)
    try:
        notes: list[str] = []
        at_floor = apply_overrides(cfg, [f"detector.conf={CONF_FLOOR}", "detector.type_conf={}"])
        detectors = source.detectors(detector, at_floor, notes)
        reader = find_qr_reader()
        records = FrameRecords(unit_m=sc.sensors.d435.depth.depth_unit_m)
        run_episode(source, Perception(detectors, reader, cfg), [records], desc="record")
        sim, n = source.sim, source.n_frames
        return PerceptionRecord(
            key=key,
            intrinsics=sim.intrinsics,
            T_tracker_optical_nominal=np.array(sim.T_tracker_optical_nominal),
            drift_multiplier=mean_drift_multiplier(sim),
            truth_rows=truth_rows(sim),
            walls_map=sim.walls_in_map(),
            robot_path_map=np.array(sim.robot_path_map()[:n]),
            times_s=np.array(sim.times_s),
            n_frames=n,
            notes=notes,
            uses_oracle=source.uses_oracle,
            labelled=any(getattr(d, "label_model", None) is not None for d in detectors),
            qr_read=reader is not None,
            floor=CONF_FLOOR,
            frames=records.frames,
        )
    finally:
        source.close()


def cached_perception(perception_cache, sc, cfg, detector: str, max_frames: int | None):
    """The trial's perception record from the cache, recorded and stored first when missing or
    unusable; None when the trial cannot be replayed (eval.trial.perception_cache.perception_key).
    ``cfg`` is the trial's pipeline configuration (:func:`eval.trial.pipeline_config.trial_pipeline_config`)."""
    from eval.trial.perception_cache import load_or_record, perception_key
    from poi.models import model_file

    key = perception_key(sc, detector, cfg, max_frames, model_file(detector))
    if key is None:
        return None
    return load_or_record(perception_cache, key, lambda k: record_perception(sc, cfg, detector, max_frames, k))
