"""``poibench replay``: the pipeline over a robot's recording, with a trial's outputs.

The frames come from :func:`eval.ros.reader.open_recording`; the pipeline is
:class:`poi.pipeline.Pipeline` with the detectors :func:`eval.trial.detectors.make_detectors` builds,
in an episode (:mod:`eval.trial.episode`) whose source is the recording (:class:`RecordingSource`),
and the outputs are written by the observers :func:`eval.trial.run.run_trial` attaches (one
:class:`eval.trial.outputs.TrialOutputs`): ``pois.csv`` (streamed, then finished atomically),
``trial.mp4`` (the annotated view), ``live/`` (what ``poibench view`` replays), ``map.png`` (the
path and the reports), ``replay.json`` (what was read and how fast) and, with a ground truth,
``score.json`` and ``funnel.csv`` (docs/RULES.md "The funnel": a recording has no truth boxes, so
an object is in view where its true position projects into the image by the recording's own pose
and nothing nearer stands in the depth there, and boxed by a box that holds that point).

The POI file's date and start time are the first colour frame's stamp (UTC); its mission name is
the trial config's scenario (``--config``), else the recording's name.
"""

from __future__ import annotations

import itertools
import json
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from eval.live.video import H264Writer
from eval.ros.reader import Recording
from eval.scoring.map_plot import MapReport, draw_map, score_layers
from eval.scoring.report import live_summary, to_json_dict
from eval.scoring.scorer import score
from eval.trial.episode import Step, run_episode
from eval.trial.observers import FunnelObserver, LiveObserver, PoiStream, RobotPath, SkipCounter, VideoObserver
from eval.trial.outputs import TrialOutputs
from poi.core.geometry import matrix_to_quat_wxyz
from poi.core.poi_file import PoiFile, read_poi_file
from poi.models import detector_label, shipped_settings


class ReplayError(ValueError):
    """A replay that cannot run as asked (the oracle detector); one line."""


@dataclass(kw_only=True)
class ReplayResult:
    out_dir: Path
    n_frames: int
    wall_s: float
    frames_per_s: float
    cpu_ms_per_frame: float
    notes: list[str]
    written: list[str]
    score: object | None = None
    confirmed: int = 0
    funnel: object | None = None  # eval.scoring.funnel.Funnel, with a ground truth


@dataclass
class _NoWorld:
    """What :func:`eval.trial.detectors.make_detectors` and :class:`eval.live.record.LiveRecorder` ask of a
    simulation, for a recording: no known objects, no walls, its frame count and rate."""

    n_frames: int
    fps: float
    scenario: object = field(init=False)

    def __post_init__(self) -> None:
        sensors = type("Sensors", (), {"fps": self.fps})()
        self.scenario = type("Scenario", (), {"sensors": sensors})()

    def truth_objects(self) -> list:
        return []

    def walls_in_map(self) -> list:
        return []


def mount_sets(T: np.ndarray) -> list[str]:
    """Pipeline settings that give the mount ``T`` (full float precision)."""
    q = [float(v) for v in matrix_to_quat_wxyz(T[:3, :3])]
    t = [float(v) for v in T[:3, 3]]
    return [
        f"mount.T_tracker_camera.translation_m=[{t[0]!r}, {t[1]!r}, {t[2]!r}]",
        f"mount.T_tracker_camera.quaternion_wxyz=[{q[0]!r}, {q[1]!r}, {q[2]!r}, {q[3]!r}]",
    ]


def replay_config(rec: Recording, config_path: str | None, detector: str | None, sets: list[str]):
    """(pipeline config, detector choice, mission name) for the replay of ``rec``: a trial's
    ``config.yaml`` as it is (it names its own label model and calibration) when its detector
    runs, else the config (or the defaults) with the chosen detector's shipped files
    (:func:`poi.models.shipped_settings`); the recording's mount and ``sets`` on top."""
    from poi.config import apply_overrides, load_config

    mission = rec.path.stem if rec.path.is_file() else rec.path.name
    asked, config_detector = detector, None
    if config_path:
        from eval.trial.trial_config import load_trial_config

        doc, given = load_trial_config(config_path)
        cfg = doc.pipeline
        config_detector = doc.detector if "detector" in given else "default"
        detector = detector or config_detector
        mission = doc.scenario.name
    else:
        cfg = load_config()
        detector = detector or "default"
    if detector == "oracle":
        where = "--detector oracle" if asked else f"{config_path}: detector oracle"
        raise ReplayError(f"{where} needs the simulator's ground truth; a recording has none (give --detector)")
    extra = list(sets)
    if rec.T_tracker_camera is not None:
        extra = mount_sets(rec.T_tracker_camera) + extra
    cfg = apply_overrides(cfg, extra)
    if not config_path or detector != config_detector:  # a detector the config did not run: its own files
        cfg = apply_overrides(cfg, shipped_settings(detector, cfg))
    return cfg, detector, mission


class RecordingSource:
    """A recording's frames (:class:`eval.ros.reader.Recording`), the first ``n_frames`` of them,
    as an episode's source (:mod:`eval.trial.episode`). With the truth's ``positions`` (id ->
    map position) each step carries the views of the objects by the recording's own pose
    (:func:`eval.trial.funnel_recorder.projected_views`: a recording has no truth boxes)."""

    def __init__(self, rec: Recording, n_frames: int, *, positions=None, T_tracker_camera=None, visibility=None):
        self.rec = rec
        self.n_frames = n_frames
        self.positions = positions
        self.T_tracker_camera = T_tracker_camera
        self.visibility = visibility

    def steps(self) -> Iterator[Step]:
        from eval.trial.funnel_recorder import projected_views

        for frame in itertools.islice(self.rec.frames(), self.n_frames):
            views = None
            if self.positions is not None:
                views = projected_views(self.positions, frame, self.T_tracker_camera, self.visibility)
            yield Step(frame=frame, views=views)


def report_layers(final) -> dict:
    """``map.png``'s layers without a ground truth: the confirmed objects, each identified."""
    reports = [
        MapReport(
            id=s.report_id,
            type=s.type,
            x=float(s.position_map[0]),
            y=float(s.position_map[1]),
            status="identified",
            text=s.text,
        )
        for s in final
    ]
    return {"reports": reports, "truth": []}


def replay(
    rec: Recording,
    out_dir: str | Path,
    *,
    config_path: str | None = None,
    detector: str | None = None,
    pipeline_sets: list[str] = (),
    truth: PoiFile | None = None,
    rules=None,
    video: bool = True,
    record_live: bool = True,
    progress: bool = False,
    max_frames: int | None = None,
) -> ReplayResult:
    """Run the pipeline over ``rec`` and write the outputs in ``out_dir``; with ``truth`` (a ground
    truth file, :func:`eval.scoring.truth.read_truth_file`), the funnel and the score too."""
    from eval.live.record import LiveRecorder
    from eval.scoring.funnel import funnel_json
    from eval.trial.detectors import make_detectors
    from eval.trial.funnel_recorder import FunnelRecorder, funnel_objects, write_funnel_csv
    from eval.trial.run import poi_writer
    from poi.pipeline import Pipeline

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    outputs = TrialOutputs(out)
    notes = list(rec.notes)
    cfg, detector, mission = replay_config(rec, config_path, detector, list(pipeline_sets))
    n = rec.n_frames if max_frames is None else min(max_frames, rec.n_frames)
    world = _NoWorld(n_frames=n, fps=rec.fps)
    detectors, _ = make_detectors(detector, cfg, world, notes)
    pipe = Pipeline(cfg, detectors)
    notes.extend(pipe.notes)
    observers = []
    recorder = positions = None
    if truth is not None:  # the funnel, with views of the truth's positions by the recording's pose
        recorder = FunnelRecorder(funnel_objects(truth.rows), cfg, rules, by_pose=True)
        notes.append(
            "funnel: an object is in view where its point, projected by the recording's own pose, lies in the "
            "image before the depth there; a drifted pose can count it boxed less often than the scorer pairs it"
        )
        positions = {int(r.id): np.array([r.x, r.y, r.z], dtype=float) for r in truth.rows}
        observers.append(FunnelObserver(recorder))
    else:
        notes.append("funnel: no ground truth (--truth), so no stage can be checked against the objects")
    source = RecordingSource(
        rec, n, positions=positions, T_tracker_camera=pipe.T_tracker_camera, visibility=cfg.visibility
    )
    writer = poi_writer(cfg, mission, rec.start, out / "pois.csv")
    skips, path = SkipCounter(), RobotPath()
    observers += [skips, path, PoiStream(writer)]
    if video:
        observers.append(
            VideoObserver(H264Writer(out / "trial.mp4", rec.color_k.width, rec.color_k.height, rec.fps), outputs)
        )

    def running_score() -> dict | None:
        if truth is None:
            return None
        return live_summary(score(read_poi_file(out / "pois.csv"), truth, rules))

    live = LiveRecorder(out, world, title=f"{mission} (replay)", score_fn=running_score, record=record_live)
    observers.append(LiveObserver(live, outputs, record=record_live))
    t0, c0 = time.perf_counter(), time.process_time()
    k = run_episode(source, pipe, observers, progress=progress, desc="replay")
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0  # all threads of the process (the encoder's ffmpeg is a child: not counted)
    skipped = skips.skipped
    skip_note = skips.note(k)
    if skip_note:
        notes.append(f"{rec.path.name}: {skip_note}")
    final = pipe.confirmed()
    outputs.write("pois.csv", lambda _: writer.finalize(final), atomic=False)
    result = funnel = None
    if truth is not None:
        result = score(read_poi_file(out / "pois.csv"), truth, rules)
        funnel = recorder.funnel(final, result, detectors)
        doc = to_json_dict(result)
        if hasattr(result, "max_total"):
            doc["funnel"] = funnel_json(funnel)
            outputs.write("funnel.csv", lambda p: write_funnel_csv(p, funnel))
        doc["replay"] = {"recording": str(rec.path), "frames": k, "skipped_frames": skipped, "notes": notes}
        outputs.write("score.json", lambda p: p.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8"))
    layers = score_layers(result) if result is not None else report_layers(final)
    info = {
        "recording": str(rec.path),
        "layout": rec.layout,
        "colour": rec.color_topic,
        "depth": rec.depth_topic,
        "depth_aligned_here": not rec.aligned,
        "pose": rec.pose_source,
        "intrinsics": rec.color_k.to_dict(),
        "detector": detector_label(detector),
        "frames": k,
        "skipped_frames": skipped,
        "wall_s": round(wall, 3),
        "frames_per_s": round(k / wall, 2) if wall > 0 else None,
        "cpu_ms_per_frame": round(1e3 * cpu / k, 2) if k else None,
        "notes": notes,
    }
    outputs.write("replay.json", lambda p: p.write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8"))
    title = f"{mission} (replay of {rec.path.name})" + (f": {result.headline()}" if result is not None else "")
    outputs.write(
        "map.png",
        lambda p: draw_map(p, walls=[], robot_path=path.array(), title=title, **layers),
    )
    outputs.check()
    return ReplayResult(
        out_dir=out,
        n_frames=k,
        wall_s=wall,
        frames_per_s=k / wall if wall > 0 else float("inf"),
        cpu_ms_per_frame=1e3 * cpu / k if k else float("nan"),
        notes=notes,
        written=outputs.names(),
        score=result,
        confirmed=len(final),
        funnel=funnel if result is not None and hasattr(result, "max_total") else None,
    )
