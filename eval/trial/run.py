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

import contextlib
import dataclasses
import json
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

import numpy as np
import yaml

from eval.live.video import H264Writer
from eval.progress import progress_bar
from eval.scoring.funnel import Funnel, ObjectView, funnel_json, funnel_rows
from eval.scoring.map_error import MapErrorResult
from eval.scoring.map_plot import draw_map, score_layers
from eval.scoring.report import live_summary, to_json_dict
from eval.scoring.rules import AnyRules
from eval.scoring.scorer import ScoreResult, score
from eval.scoring.truth import truth_rows, write_truth_csv
from eval.trial.cost import CostClock
from eval.trial.funnel_recorder import FunnelRecorder
from eval.trial.outputs import TrialOutputs
from eval.trial.sensor_settings import mean_drift_multiplier, sensor_settings, simulation_sensor_settings
from poi.core.geometry import planar_pose, wrap_angle
from poi.core.poi_file import parse_poi_text, read_poi_file
from sim.scenario import Scenario

MODELS_DIR = Path(__file__).resolve().parents[2] / "poi" / "models"
DEFAULT_MODEL = MODELS_DIR / "default.onnx"
DEFAULT_LABEL_MODEL = MODELS_DIR / "default_labels.onnx"  # names the placards DEFAULT_MODEL finds
DEFAULT_CALIBRATION = MODELS_DIR / "default_calibration.yaml"  # poibench calibrate of the two
# The competition file carries a date and a start time; a simulated mission starts at a
# fixed instant so the same seed and config give the same file, byte for byte.
MISSION_START = datetime(2026, 7, 1, 9, 0, 0)


@dataclass(kw_only=True)
class TrialResult:
    out_dir: Path
    score: ScoreResult | MapErrorResult
    n_frames: int
    sim_duration_s: float
    wall_s: float
    cpu_s: float  # process CPU, all threads, plus reaped children (ffmpeg): eval.trial.cost
    cpu_children_s: float
    detector: str
    notes: list[str] = field(default_factory=list)
    skipped_frames: int = 0
    pose_error: dict[str, float] = field(default_factory=dict)
    written: list[str] = field(default_factory=list)  # the outputs in out_dir, e.g. "pois.csv", "live/"
    funnel: Funnel | None = None  # which stage lost each point (eval.scoring.funnel); None for a map-error preset

    @property
    def real_time_factor(self) -> float:
        return self.sim_duration_s / self.wall_s if self.wall_s > 0 else float("inf")

    @property
    def cpu_s_per_sim_s(self) -> float:
        return self.cpu_s / self.sim_duration_s if self.sim_duration_s > 0 else float("nan")


def detector_label(choice: str) -> str:
    if choice == "default":
        if not DEFAULT_MODEL.exists():
            return "oracle"
        labels = f"+{DEFAULT_LABEL_MODEL.name}" if DEFAULT_LABEL_MODEL.exists() else ""
        return f"onnx:{DEFAULT_MODEL.name}{labels}"
    return choice


DETECTOR_CHOICES = "default | oracle | FILE.onnx | python:MODULE:CLASS | an installed detector's name"


def check_detector_choice(choice: str) -> None:
    """Refuse a ``--detector`` that names nothing, before the trial starts: a team's Python
    detector must import and be callable, anything else but default and oracle is an ONNX file."""
    from poi.detectors import DetectorConfigError, entry_point_names, is_team_detector
    from poi.detectors.plugins import resolve_factory

    if choice in ("default", "oracle"):
        return
    if is_team_detector(choice):
        resolve_factory(choice)
    elif not choice.endswith(".onnx") and not Path(choice).exists():
        installed = ", ".join(entry_point_names()) or "none installed"
        raise DetectorConfigError(
            f"unknown detector {choice!r}; expected {DETECTOR_CHOICES} (installed: {installed})"
        )


def onnx_settings_set(det_cfg) -> list[str]:
    """The ``detector.*`` settings other than ``options`` that differ from the default config's, dotted."""
    from poi.config import DetectorConfig, load_config

    default = load_config().detector
    return [
        f"detector.{f.name}"
        for f in dataclasses.fields(DetectorConfig)
        if f.name not in ("name", "options") and getattr(det_cfg, f.name) != getattr(default, f.name)
    ]


def refuse_detector_model(cfg) -> None:
    """Refuse a config that names ``detector.model``: a trial's (or replay's) detector is the
    ``--detector`` choice, which also picks the label model, the calibration and the perception
    cache's key, so the file ``detector.model`` names could never take effect."""
    from poi.detectors import DetectorConfigError

    model = cfg.detector.model
    if model is not None:
        raise DetectorConfigError(
            f"detector.model={model}: a trial's detector is chosen with --detector FILE.onnx, not "
            "detector.model (a sweep compares detectors by one run per --detector)"
        )


def check_trial_settings(pipeline_sets) -> None:
    """Refuse, before a trial starts, pipeline ``--set`` items that cannot take effect in a
    trial (``detector.model``: :func:`refuse_detector_model`)."""
    from poi.config import apply_overrides, load_config

    refuse_detector_model(apply_overrides(load_config(), list(pipeline_sets)))


def make_detectors(choice: str, cfg, sim, notes: list[str]):
    """The detectors for a trial and the oracle (when used, it needs the truth of each frame).

    In a world with Landolt-C targets the oracle gives their boxes (their rings are read from
    the pixels by the pipeline); any other detector runs with the Landolt-C finder beside it.
    A config naming ``detector.model`` is refused (:func:`refuse_detector_model`)."""
    from poi.detectors import build_detector, build_python_detector, is_team_detector
    from sim.oracle import oracle_for

    refuse_detector_model(cfg)
    oracle = None
    dets = []
    if choice == "default" and not DEFAULT_MODEL.exists():
        notes.append(
            "no trained default detector is shipped yet: using the oracle detector (ground-truth boxes "
            "with a noise model)"
        )
        choice = "oracle"
    if choice == "oracle":
        oracle = oracle_for(sim)  # seeded by the scenario, knowing its world's classes
        dets.append(oracle)
    elif choice != "default" and is_team_detector(choice):  # the built-in names come first
        dets.append(build_python_detector(choice, cfg.detector.options))
        unused = onnx_settings_set(cfg.detector)
        if unused:
            notes.append(
                f"{choice} takes its settings from detector.options only; {', '.join(unused)} "
                "(the ONNX detector's) do not reach it"
            )
    else:
        model = DEFAULT_MODEL if choice == "default" else Path(choice)
        spec = dict(cfg.detector_spec()) if hasattr(cfg, "detector_spec") else dict(cfg.detector)
        spec["name"] = "onnx"
        spec["model"] = str(model)
        onnx = build_detector(spec)
        notes.extend(onnx.notes)  # e.g. an execution provider this onnxruntime lacks, one line
        wanted = {o.type for o in sim.truth_objects()}
        if cfg.thermal.enabled:
            wanted.discard("heat-source")  # the thermal detector reports those
        wanted.discard("landolt-c")  # the Landolt-C finder reports those
        unknown = sorted(wanted - onnx.known_types)
        if choice == "default" and wanted and not wanted & onnx.known_types:
            # the shipped model is the rescue maze's; this world holds nothing it knows
            notes.append(
                f"the default detector ({model.name}) knows none of this scenario's types "
                f"({', '.join(sorted(wanted))}): using the oracle detector"
            )
            oracle = oracle_for(sim)
            dets.append(oracle)
        else:
            if unknown:
                notes.append(f"the detector ({model.name}) cannot report this scenario's {', '.join(unknown)}")
            dets.append(onnx)
    if cfg.thermal.enabled:
        dets.append(build_detector({"name": "thermal"}))
    if oracle is None and any(o.type == "landolt-c" for o in sim.truth_objects()):
        # an RMRC test with Landolt-C targets: the finder proposes and reads them from pixels
        dets.append(build_detector({"name": "landolt"}))
        notes.append(
            "the scenario has Landolt-C targets: the Landolt-C finder (poi/detectors/landolt.py) runs too"
        )
    return dets, oracle


def _with_default_label_model(cfg, detector: str):
    """The shipped label classifier with the shipped detector, unless the config names one."""
    from poi.config import apply_overrides

    if detector == "default" and cfg.detector.label_model is None and DEFAULT_LABEL_MODEL.exists():
        return apply_overrides(cfg, [f"detector.label_model={DEFAULT_LABEL_MODEL}"])
    return cfg


def onnx_model_file(choice: str) -> Path | None:
    """The ONNX file a detector choice runs (None: the oracle, or a team's Python detector)."""
    if choice == "default":
        return DEFAULT_MODEL if DEFAULT_MODEL.exists() else None
    if choice.endswith(".onnx"):
        return Path(choice)
    return None


def planar_pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """Distance on the floor (m) and absolute heading difference (degrees) of two poses."""
    est, true = planar_pose(T_est), planar_pose(T_true)
    return float(np.linalg.norm(est[:2] - true[:2])), abs(float(np.degrees(wrap_angle(est[2] - true[2]))))


def pose_error_summary(errors: list[tuple[float, float]]) -> dict[str, float]:
    """Median, 90th percentile, max and last of the per-frame planar position error (m) of the
    pose the pipeline mapped with against the true tracker pose, and the median heading error
    (degrees); frames with a pose only."""
    if not errors:
        return {"frames": 0}
    e = np.asarray([d for d, _ in errors])
    yaw = np.asarray([a for _, a in errors])
    return {
        "frames": int(e.size),
        "median_m": round(float(np.median(e)), 4),
        "p90_m": round(float(np.percentile(e, 90)), 4),
        "max_m": round(float(e.max()), 4),
        "final_m": round(float(e[-1]), 4),
        "heading_median_deg": round(float(np.median(yaw)), 3),
    }


def object_views(truth) -> list[ObjectView]:
    """The funnel's views of the objects a frame's ground truth (``sim.simulator.FrameTruth``) shows."""
    return [
        ObjectView(
            id=v.id,
            box_xyxy=tuple(round(float(c), 2) for c in v.box_xyxy),
            visible_fraction=round(float(v.visible_fraction), 4),
            distance_m=round(float(np.linalg.norm(v.position_cam)), 4),
            angle_deg=round(float(v.view_angle_deg), 2),
        )
        for v in truth.visible
    ]


def funnel_objects(rows) -> list[tuple[int, str, str, int | None]]:
    """(id, type, text, modules across) of each truth row; modules for a QR code only (its
    quiet zone included, maze_assets.qr), None where the text cannot be drawn."""
    from maze_assets.qr import QUIET_MODULES, QrTextureError, qr_modules

    out = []
    for r in rows:
        modules = None
        if r.type == "qr" and r.text:
            try:
                modules = int(qr_modules(r.text).shape[0]) + 2 * QUIET_MODULES
            except (QrTextureError, ValueError):
                modules = None
        out.append((int(r.id), str(r.type), str(r.text), modules))
    return out


def _funnel_qr_reader(replay):
    """(frame, QR box) -> the QR reader's text, for the funnel's views the pipeline did not ask
    about: the text recorded for the box in a replay, else the reader on the frame's pixels."""
    if replay is not None:
        return lambda frame, det: replay.current.qr_texts.get(tuple(det.box_xyxy), "")
    from poi.pipeline import find_qr_reader

    reader = find_qr_reader()
    if reader is None:
        return None
    return lambda frame, det: reader(frame.rgb, [det])[0].text


def write_funnel_csv(path: Path, funnel: Funnel) -> None:
    """``funnel.csv``: one row an object, one a charged false report (eval.scoring.funnel.CSV_COLUMNS)."""
    import csv

    from eval.scoring.funnel import CSV_COLUMNS

    with open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(CSV_COLUMNS), lineterminator="\n")
        w.writeheader()
        w.writerows(funnel_rows(funnel))


def record_perception(sc: Scenario, cfg, detector: str, max_frames: int | None, key: str):
    """Simulate the scenario and run its detectors (the ONNX one at the cache's floor) on every
    frame, keeping what the pipeline after detection reads (eval.trial.perception_cache)."""
    from eval.trial.perception_cache import CONF_FLOOR, FrameRecord, PerceptionRecord, TiledDepth
    from poi.config import apply_overrides
    from poi.detectors.landolt import attach_landolt_text
    from poi.pipeline import find_qr_reader
    from sim.simulator import Simulation

    rec_cfg = apply_overrides(cfg, [f"detector.conf={CONF_FLOOR}"])
    sim = Simulation(sc)
    try:
        notes: list[str] = []
        detectors, oracle = make_detectors(detector, rec_cfg, sim, notes)
        sim.truth_boxes = True  # the oracle's boxes and the funnel's views
        labelled = any(getattr(d, "label_model", None) is not None for d in detectors)
        reader = find_qr_reader()
        n = sim.n_frames if max_frames is None else min(max_frames, sim.n_frames)
        frames = []
        for frame, truth in sim.frames(0, n):
            if oracle is not None:
                oracle.set_truth(truth)
            dets = []
            for det in detectors:
                dets.extend(det.detect(frame))
            if any(d.type == "landolt-c" and not d.text for d in dets):  # read from pixels, as the pipeline does
                dets = attach_landolt_text(frame.rgb, dets)
            texts = {}
            unread = [d for d in dets if d.type == "qr" and not d.text]
            if reader is not None and unread:  # every QR box: a replay may ask for any of them
                for d, r in zip(unread, reader(frame.rgb, unread), strict=True):
                    texts[tuple(d.box_xyxy)] = r.text
            frames.append(
                FrameRecord(
                    index=frame.index,
                    timestamp_s=frame.timestamp_s,
                    pose=None if frame.pose is None else np.array(frame.pose),
                    pose_confidence=frame.pose_confidence,
                    pose_relocalised=frame.pose_relocalised,
                    depth=None if frame.depth_m is None else TiledDepth.from_array(frame.depth_m),
                    detections=dets,
                    qr_texts=texts,
                    T_map_tracker_true=np.array(truth.T_map_tracker),
                    views=object_views(truth),
                    blur_px=round(float(truth.blur_px), 3),
                )
            )
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
            uses_oracle=oracle is not None,
            labelled=labelled,
            qr_read=reader is not None,
            floor=CONF_FLOOR,
            frames=frames,
        )
    finally:
        sim.close()


def cached_perception(perception_cache, sc: Scenario, cfg, detector: str, max_frames: int | None):
    """The trial's perception record from the cache, recorded and stored first when missing or
    unusable; None when the trial cannot be replayed (eval.trial.perception_cache.perception_key).
    ``cfg`` is the pipeline config with the trial's settings."""
    from eval.trial.perception_cache import load_or_record, perception_key

    key = perception_key(sc, detector, cfg, max_frames, onnx_model_file(detector))
    if key is None:
        return None
    return load_or_record(perception_cache, key, lambda k: record_perception(sc, cfg, detector, max_frames, k))


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
    """Run one trial into ``out_dir`` (module docstring).

    With ``perception_cache`` (an :class:`eval.trial.perception_cache.PerceptionCache`) the
    trial's perception is recorded once, or taken from the cache, and the pipeline after
    detection replays it (no video, live view or ``on_frame``: those need the pixels); a
    detector the cache cannot cover, or ``detector.conf`` below its floor, runs in full.
    ``interrupt`` (an :class:`eval.trial.interrupt.DeferredInterrupt`) is checked after each
    frame, so a Ctrl-C ends the trial between frames (``poibench run``).
    """

    from poi.annotate import annotate
    from poi.config import apply_overrides, config_to_dict, load_config
    from poi.pipeline import Pipeline
    from poi.report import PoiWriter, ReportHeader
    from sim.simulator import Simulation

    if max_frames is not None and max_frames < 1:
        raise ValueError(f"run_trial: max_frames must be at least 1, got {max_frames}")
    check_trial_settings(pipeline_sets)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    outputs = TrialOutputs(out)
    notes: list[str] = []
    clock = CostClock.start()
    record = None
    if perception_cache is not None:
        if video or record_live or live_server is not None or on_frame is not None:
            raise ValueError("run_trial: a perception cache replays trials without video, live view or on_frame")
        key_cfg = _with_default_label_model(apply_overrides(load_config(), list(pipeline_sets)), detector)
        record = cached_perception(perception_cache, sc, key_cfg, detector, max_frames)
    sim = Simulation(sc) if record is None else None
    try:
        cfg = load_config()
        # the pipeline is told its sensors as a team knows them (the nominal camera mount, the
        # simulator uses the true one)
        if record is None:
            sensor_sets = simulation_sensor_settings(sim)
        else:
            sensor_sets = sensor_settings(record.T_tracker_optical_nominal, sc, record.drift_multiplier)
        # a preset that judges the QR mapping bonus by fiducials asks the pipeline to map them
        wants_fiducials = getattr(rules, "qr_mapping", "radius") == "fiducials"
        # and one that scores Landolt-C rings has Landolt-C targets reported once those rings read
        rings = getattr(rules, "landolt_rings", None)
        landolt_sets = [] if rings is None else [f"tracker.landolt_required_rings={list(rings)}"]
        sets = sensor_sets + ["fiducials.enabled=true"] * wants_fiducials + landolt_sets + list(pipeline_sets)
        cfg = _with_default_label_model(apply_overrides(cfg, sets), detector)
        replay = None
        if record is None:
            detectors, oracle = make_detectors(detector, cfg, sim, notes)
            uses_oracle = oracle is not None
            sim.truth_boxes = True  # the oracle's boxes and the funnel's views of the objects
        else:
            from eval.trial.perception_cache import ReplayDetector

            oracle, replay = None, ReplayDetector(record, cfg.detector.conf)
            detectors, uses_oracle = [replay], record.uses_oracle
            notes.extend(record.notes)
        if detector == "default" and not uses_oracle and cfg.calibration is None and DEFAULT_CALIBRATION.exists():
            # the shipped model's own error model ([Avevor2022] 2.1.4-2.1.5), unless the config names one
            cfg = apply_overrides(cfg, [f"calibration={DEFAULT_CALIBRATION}"])
        pipe = Pipeline(cfg, detectors, qr_reader=replay.read_qr if replay and record.qr_read else None)
        rows = truth_rows(sim) if record is None else record.truth_rows
        outputs.write("truth.csv", lambda path: write_truth_csv(path, rows, sc.name))
        outputs.check()  # no trial without its truth
        header = ReportHeader(
            team=cfg.report.team,
            country=cfg.report.country,
            mission=sc.name,
            start=MISSION_START,
            version=cfg.report.poi_version,
        )
        writer = PoiWriter(out / "pois.csv", header, robot=cfg.report.robot, mode=cfg.report.mode)
        if record is None:
            n = sim.n_frames if max_frames is None else min(max_frames, sim.n_frames)
            frames = ((f, t, t.T_map_tracker, object_views(t), t.blur_px) for f, t in sim.frames(0, n))
        else:
            n = record.n_frames
            frames = (
                (f, None, T_true, fr.views, fr.blur_px)
                for (f, T_true), fr in zip(record.replay_frames(), record.frames, strict=True)
            )
        recorder = FunnelRecorder(funnel_objects(rows), cfg, rules, qr_reader=_funnel_qr_reader(replay))
        vid = (
            H264Writer(out / "trial.mp4", sim.intrinsics.width, sim.intrinsics.height, sc.sensors.fps)
            if video
            else None
        )
        skipped = 0
        streaming = True  # pois.csv takes each object as it is confirmed
        pose_errors: list[tuple[float, float]] = []
        truth_file = read_poi_file(out / "truth.csv")
        live = None
        if record_live or live_server is not None:
            from eval.live.record import LiveRecorder

            def running_score() -> dict:
                # the reports as they stand now (the file the trial would end with), not as streamed
                text = writer.text(pipe.confirmed() + pipe.landmarks())
                now = parse_poi_text(text, source=str(out / "pois.csv"))
                return live_summary(score(now, truth_file, rules))

            live = LiveRecorder(
                out,
                sim,
                title=f"{sc.name} (seed {sc.seed})",
                score_fn=running_score,
                server=live_server,
                record=record_live,
                n_frames=n,
            )
        try:
            for frame, truth, T_true, views, blur_px in progress_bar(
                frames, total=n, desc="trial", unit="frame", quiet=not progress
            ):
                if oracle is not None:
                    oracle.set_truth(truth)
                res = pipe.process(frame)
                recorder.on_frame(views, blur_px, frame, res)
                if res.skipped_reason:
                    skipped += 1
                if res.pose_map is not None:
                    pose_errors.append(planar_pose_error(res.pose_map, T_true))
                for snap in res.newly_confirmed:
                    if streaming:
                        try:
                            writer.append(snap)
                        except OSError:  # streaming stops; the end rewrites the file whole
                            streaming = False
                view = None
                if vid is not None or live is not None:
                    view = annotate(frame.rgb, res.detections, pipe.confirmed(), frame.timestamp_s)
                if vid is not None:
                    try:
                        vid.write(view)
                    except OSError as e:  # the trial goes on without its video
                        outputs.fail("trial.mp4", e)
                        with contextlib.suppress(OSError):
                            vid.close()
                        vid = None
                if live is not None:
                    live.on_frame(frame, res, pipe, view)
                if on_frame is not None:
                    on_frame(frame, truth, res, pipe)
                if interrupt is not None:  # a Ctrl-C ends the trial here, between two frames
                    interrupt.check()
        finally:
            if vid is not None:
                outputs.write("trial.mp4", lambda _: vid.close(), atomic=False)
            if live is not None and record_live:
                outputs.write("live/", lambda _: live.close(), atomic=False)
            elif live is not None:
                live.close()
        final = pipe.confirmed() + pipe.landmarks()
        # the file as it is on disk is scored (if this rewrite failed: the rows streamed so far)
        outputs.write("pois.csv", lambda _: writer.finalize(final), atomic=False)
        times_s = sim.times_s if record is None else record.times_s
        sim_duration = float(times_s[n - 1]) if n else 0.0
        result = score(read_poi_file(out / "pois.csv"), truth_file, rules)
        funnel = recorder.funnel(pipe.confirmed(), result, detectors)
        silent = funnel.activity.note()
        if silent:
            notes.append(silent)
        doc = to_json_dict(result)
        if isinstance(result, ScoreResult):
            doc["funnel"] = funnel_json(funnel)
        pose_error = pose_error_summary(pose_errors)
        doc["pose_error"] = pose_error
        doc["trial"] = {
            "scenario": sc.name,
            "seed": sc.seed,
            "detector": detector_label(detector),
            "frames": n,
            "sim_duration_s": round(sim_duration, 3),
            "skipped_frames": skipped,
            "notes": notes,
        }
        outputs.write(
            "score.json", lambda path: path.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
        )
        outputs.write("funnel.csv", lambda path: write_funnel_csv(path, funnel))
        # What the trial cost, up to its score: the one output that differs between reruns, so it has a
        # file of its own and score.json stays the same, byte for byte, for the same seed and config.
        cost_doc = clock.read(sim_duration).to_dict()
        outputs.write(
            "cost.json",
            lambda path: path.write_text(json.dumps(cost_doc, indent=2, allow_nan=False) + "\n", encoding="utf-8"),
        )
        config = {
            "poibench_trial": 1,
            "scenario": sc.to_dict(),
            "pipeline": config_to_dict(cfg),
            "detector": detector,
            "rules": rules_name,
            "max_frames": max_frames,
        }
        config_text = (
            "# everything needed to rerun this trial: poibench run --config config.yaml\n"
            + yaml.safe_dump(config, sort_keys=False)
        )
        outputs.write("config.yaml", lambda path: path.write_text(config_text, encoding="utf-8"))
        outputs.write(
            "map.png",
            lambda path: draw_map(
                path,
                walls=sim.walls_in_map() if record is None else record.walls_map,
                robot_path=sim.robot_path_map()[:n] if record is None else record.robot_path_map,
                **score_layers(result),
                title=f"{sc.name} (seed {sc.seed}): {result.headline()}",
            ),
        )
    finally:
        if sim is not None:
            sim.close()
    outputs.check()
    cost = clock.read(sim_duration)
    return TrialResult(
        out_dir=out,
        score=result,
        n_frames=n,
        sim_duration_s=sim_duration,
        wall_s=cost.wall_s,
        cpu_s=cost.cpu_s,
        cpu_children_s=cost.cpu_children_s,
        detector=detector_label(detector),
        notes=notes,
        skipped_frames=skipped,
        pose_error=pose_error,
        written=outputs.names(),
        funnel=funnel if isinstance(result, ScoreResult) else None,
    )
