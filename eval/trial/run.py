"""One scored trial, end to end: simulate, run the pipeline, write the POI file, score, draw.

``run_trial`` leaves in the output folder:

* ``pois.csv``   the competition file; rows are appended and flushed as objects
                 are confirmed, so a killed run leaves a valid file of what it had;
                 at the end it is rewritten atomically with the final positions;
* ``truth.csv``  the ground truth (mode GT, map frame);
* ``score.json`` the score report, the same for the same seed and config;
* ``cost.json``  what the trial cost, wall and CPU seconds (:mod:`eval.trial.cost`), the
                 one output that differs between reruns; ``map.png`` the 2D map; ``trial.mp4`` the
                 annotated camera view; ``config.yaml`` everything needed to rerun;
                 ``live/`` the record ``poibench view`` replays.

With a perception cache (sweeps, tune, regress and suite run: ``--cache``) the trial's
perception is recorded once per scenario and detector and replayed for every setting read
only after detection (:mod:`eval.trial.perception_cache`); the files are the same.

A write that fails (a full disk) does not stop the others: the trial goes on without its
video or live record, the end writes every file it still can (the small ones first) and
then raises :class:`eval.trial.outputs.TrialOutputError` naming the file that failed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import yaml

from eval.live.video import H264Writer
from eval.scoring.funnel import Funnel, funnel_json
from eval.scoring.map_error import MapErrorResult
from eval.scoring.map_plot import draw_map, score_layers
from eval.scoring.report import live_summary, to_json_dict
from eval.scoring.rules import AnyRules
from eval.scoring.scorer import ScoreResult, score
from eval.scoring.truth import write_truth_csv
from eval.trial.cost import CostClock, TrialCost
from eval.trial.episode import run_episode
from eval.trial.funnel_recorder import FunnelRecorder, funnel_objects, write_funnel_csv
from eval.trial.observers import (
    FrameHook,
    FunnelObserver,
    InterruptCheck,
    LiveObserver,
    PoiStream,
    PoseError,
    SkipCounter,
    VideoObserver,
)
from eval.trial.outputs import TrialOutputs
from eval.trial.pipeline_config import check_trial_settings, trial_pipeline_config
from eval.trial.sources import RecordSource, SimulationSource, cached_perception
from poi.core.poi_file import parse_poi_text, read_poi_file
from poi.models import detector_label
from sim.scenario import Scenario

# The competition file carries a date and a start time; a simulated mission starts at a
# fixed instant so the same seed and config give the same file, byte for byte.
MISSION_START = datetime(2026, 7, 1, 9, 0, 0)


@dataclass(kw_only=True)
class TrialResult:
    out_dir: Path
    score: ScoreResult | MapErrorResult
    n_frames: int
    sim_duration_s: float
    cost: TrialCost  # wall and CPU seconds, as cost.json gives them (eval.trial.cost)
    detector: str
    notes: list[str] = field(default_factory=list)
    skipped_frames: int = 0
    pose_error: dict[str, float] = field(default_factory=dict)
    written: list[str] = field(default_factory=list)  # the outputs in out_dir, e.g. "pois.csv", "live/"
    funnel: Funnel | None = None  # which stage lost each point (eval.scoring.funnel); None for a map-error preset


@dataclass(kw_only=True)
class _Trial:
    """What one trial's steps share: its scenario and choices, its folder and its notes."""

    sc: Scenario
    out: Path
    outputs: TrialOutputs
    detector: str
    pipeline_sets: list[str]
    rules: AnyRules
    rules_name: str
    max_frames: int | None
    notes: list[str] = field(default_factory=list)


def open_source(t: _Trial, perception_cache):
    """The trial's frame source: its perception record from ``perception_cache`` where the trial
    can be replayed (:func:`eval.trial.sources.cached_perception`), else the simulation. The
    record is keyed by the trial's configuration resolved without its sensors, which no detector reads."""
    if perception_cache is not None:
        key_cfg = trial_pipeline_config(t.detector, t.pipeline_sets, rules=t.rules)
        record = cached_perception(perception_cache, t.sc, key_cfg, t.detector, t.max_frames)
        if record is not None:
            return RecordSource(record, t.sc)
    return SimulationSource(t.sc, t.max_frames)


def trial_pipeline(t: _Trial, source):
    """(pipeline config, pipeline) of the trial: the configuration of
    :func:`eval.trial.pipeline_config.trial_pipeline_config` with the sensors as the source tells
    them, resolved again without the shipped calibration where the oracle runs in the shipped
    detector's place (known once the detectors are built), and the source's detectors."""
    from poi.pipeline import Pipeline

    sensor_sets = source.sensor_settings()
    cfg = trial_pipeline_config(
        t.detector, t.pipeline_sets, rules=t.rules, sensor_sets=sensor_sets, runs_oracle=source.uses_oracle
    )
    detectors = source.detectors(t.detector, cfg, t.notes)
    if source.uses_oracle:
        cfg = trial_pipeline_config(
            t.detector, t.pipeline_sets, rules=t.rules, sensor_sets=sensor_sets, runs_oracle=True
        )
    return cfg, Pipeline(cfg, detectors, qr_reader=source.pipeline_qr_reader())


def poi_writer(cfg, mission: str, start: datetime, path: Path):
    """The POI file's writer (``poi.report.PoiWriter``) with the header the config gives."""
    from poi.report import PoiWriter, ReportHeader

    header = ReportHeader(
        team=cfg.report.team,
        country=cfg.report.country,
        mission=mission,
        start=start,
        version=cfg.report.poi_version,
    )
    return PoiWriter(path, header, robot=cfg.report.robot, mode=cfg.report.mode)


def live_observer(t: _Trial, source, truth_file, writer, pipe, *, server, record: bool) -> LiveObserver:
    """The live view, with the running score of the reports as they stand (the ``pois.csv``
    that ``writer`` would end with for ``pipe``'s objects now)."""
    from eval.live.record import LiveRecorder

    out, rules = t.out, t.rules

    def running_score() -> dict:
        # the reports as they stand now (the file the trial would end with), not as streamed
        text = writer.text(pipe.confirmed() + pipe.landmarks())
        now = parse_poi_text(text, source=str(out / "pois.csv"))
        return live_summary(score(now, truth_file, rules))

    live = LiveRecorder(
        out,
        source.sim,
        title=f"{t.sc.name} (seed {t.sc.seed})",
        score_fn=running_score,
        server=server,
        record=record,
        n_frames=source.n_frames,
    )
    return LiveObserver(live, t.outputs, record=record)


def score_doc(
    t: _Trial, result, funnel: Funnel, pose_error: dict, n: int, sim_duration: float, skipped: int
) -> dict:
    """``score.json``: the score report, the funnel, the pose error and what the trial was."""
    doc = to_json_dict(result)
    if isinstance(result, ScoreResult):
        doc["funnel"] = funnel_json(funnel)
    doc["pose_error"] = pose_error
    doc["trial"] = {
        "scenario": t.sc.name,
        "seed": t.sc.seed,
        "detector": detector_label(t.detector),
        "frames": n,
        "sim_duration_s": round(sim_duration, 3),
        "skipped_frames": skipped,
        "notes": t.notes,
    }
    return doc


def write_config(t: _Trial, cfg) -> None:
    """``config.yaml``: everything needed to rerun the trial."""
    from poi.config import config_to_dict

    config = {
        "poibench_trial": 1,
        "scenario": t.sc.to_dict(),
        "pipeline": config_to_dict(cfg),
        "detector": t.detector,
        "rules": t.rules_name,
        "max_frames": t.max_frames,
    }
    text = "# everything needed to rerun this trial: poibench run --config config.yaml\n" + yaml.safe_dump(
        config, sort_keys=False
    )
    t.outputs.write("config.yaml", lambda path: path.write_text(text, encoding="utf-8"))


def write_json(t: _Trial, name: str, doc: dict, *, allow_nan: bool = True) -> None:
    """``name``: ``doc`` as indented JSON."""
    text = json.dumps(doc, indent=2, allow_nan=allow_nan) + "\n"
    t.outputs.write(name, lambda path: path.write_text(text, encoding="utf-8"))


@dataclass(kw_only=True)
class _Recorders:
    """The observers whose records the end of a trial reads: ``pois.csv``'s writer, the funnel,
    the frames skipped, the pose error."""

    writer: object  # poi.report.PoiWriter
    funnel: FunnelRecorder
    skips: SkipCounter = field(default_factory=SkipCounter)
    pose: PoseError = field(default_factory=PoseError)

    def observers(self) -> list:
        return [FunnelObserver(self.funnel), self.skips, self.pose, PoiStream(self.writer)]


def finish_trial(t: _Trial, source, cfg, pipe, rec: _Recorders, truth_file):
    """The files written at the end of a trial, in turn: ``pois.csv`` (rewritten with the final
    positions, and scored as it is on disk: if this rewrite failed, the rows streamed so far),
    ``score.json``, ``funnel.csv``, ``config.yaml``, ``map.png`` (``cost.json`` is written by
    :func:`run_trial` once the frame source is closed). Returns (score, funnel, pose error summary)."""
    sc = t.sc
    t.outputs.write("pois.csv", lambda _: rec.writer.finalize(pipe.confirmed() + pipe.landmarks()), atomic=False)
    n, sim_duration = source.n_frames, source.sim_duration_s()
    result = score(read_poi_file(t.out / "pois.csv"), truth_file, t.rules)
    funnel = rec.funnel.funnel(pipe.confirmed(), result, pipe.detectors)
    silent = funnel.activity.note()
    if silent:
        t.notes.append(silent)
    pose_error = rec.pose.summary()
    write_json(t, "score.json", score_doc(t, result, funnel, pose_error, n, sim_duration, rec.skips.skipped))
    t.outputs.write("funnel.csv", lambda path: write_funnel_csv(path, funnel))
    write_config(t, cfg)
    t.outputs.write(
        "map.png",
        lambda path: draw_map(
            path,
            walls=source.walls_map(),
            robot_path=source.robot_path_map(),
            **score_layers(result),
            title=f"{sc.name} (seed {sc.seed}): {result.headline()}",
        ),
    )
    return result, funnel, pose_error


def run_trial(
    sc: Scenario,
    out_dir: str | Path,
    *,
    pipeline_sets: list[str] = (),
    detector: str = "default",
    rules: AnyRules,
    rules_name: str,
    video: bool = True,
    progress: bool = True,
    max_frames: int | None = None,
    on_frame=None,
    interrupt=None,
    live_server=None,
    record_live: bool = True,
    perception_cache=None,
) -> TrialResult:
    """Run one trial into ``out_dir`` (module docstring): an episode (:mod:`eval.trial.episode`)
    of the trial's frame source (:func:`open_source`) through its pipeline (:func:`trial_pipeline`)
    with the observers that write its files, then the score and the files written at the end.

    With ``perception_cache`` (an :class:`eval.trial.perception_cache.PerceptionCache`) the
    trial's perception is recorded once, or taken from the cache, and the pipeline after
    detection replays it (no video, live view or ``on_frame``: those need the pixels); a
    detector the cache cannot cover, or ``detector.conf`` below its floor, runs in full.
    ``interrupt`` (an :class:`eval.trial.interrupt.DeferredInterrupt`) is checked after each
    frame, so a Ctrl-C ends the trial between frames (``poibench run``).
    """
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"run_trial: max_frames must be at least 1, got {max_frames}")
    check_trial_settings(pipeline_sets, detector)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t = _Trial(
        sc=sc,
        out=out,
        outputs=TrialOutputs(out),
        detector=detector,
        pipeline_sets=list(pipeline_sets),
        rules=rules,
        rules_name=rules_name,
        max_frames=max_frames,
    )
    clock = CostClock.start()
    if perception_cache is not None and (video or record_live or live_server is not None or on_frame is not None):
        raise ValueError("run_trial: a perception cache replays trials without video, live view or on_frame")
    source = open_source(t, perception_cache)
    try:
        cfg, pipe = trial_pipeline(t, source)
        rows = source.truth_rows()
        t.outputs.write("truth.csv", lambda path: write_truth_csv(path, rows, sc.name))
        t.outputs.check()  # no trial without its truth
        truth_file = read_poi_file(out / "truth.csv")
        rec = _Recorders(
            writer=poi_writer(cfg, sc.name, MISSION_START, out / "pois.csv"),
            funnel=FunnelRecorder(funnel_objects(rows), cfg, rules, qr_reader=source.funnel_qr_reader(cfg)),
        )
        observers = rec.observers()
        if video:
            k = source.intrinsics
            observers.append(
                VideoObserver(H264Writer(out / "trial.mp4", k.width, k.height, sc.sensors.fps), t.outputs)
            )
        if record_live or live_server is not None:
            observers.append(
                live_observer(t, source, truth_file, rec.writer, pipe, server=live_server, record=record_live)
            )
        if on_frame is not None:
            observers.append(FrameHook(on_frame))
        if interrupt is not None:  # a Ctrl-C ends the trial here, between two frames
            observers.append(InterruptCheck(interrupt))
        run_episode(source, pipe, observers, progress=progress, desc="trial")
        result, funnel, pose_error = finish_trial(t, source, cfg, pipe, rec, truth_file)
        n, sim_duration = source.n_frames, source.sim_duration_s()
    finally:
        source.close()
    # What the whole trial cost, read once, after its last file: the one output that differs between
    # reruns, so it has a file of its own and score.json stays the same, byte for byte, for the same
    # seed and config; `poibench run` prints the same figures.
    cost = clock.read(sim_duration)
    write_json(t, "cost.json", cost.to_dict(), allow_nan=False)
    t.outputs.check()
    return TrialResult(
        out_dir=out,
        score=result,
        n_frames=n,
        sim_duration_s=sim_duration,
        cost=cost,
        detector=detector_label(detector),
        notes=t.notes,
        skipped_frames=rec.skips.skipped,
        pose_error=pose_error,
        written=t.outputs.names(),
        funnel=funnel if isinstance(result, ScoreResult) else None,
    )
