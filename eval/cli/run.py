"""`poibench run`: one scored trial."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from datetime import timezone
from pathlib import Path

from eval.cli.args import RULES_HELP, port, positive_int
from eval.text import counted
from eval.trial.scenarios import (
    SettingError,
    UnknownScenarioError,
    check_scenario_name,
    large_maze_note,
    resolve_config_scenario,
    resolve_scenario,
    split_settings,
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run a scored trial (simulate, detect, track, write pois.csv, score)",
        description="Simulate a scenario, run the pipeline on its frames, write the POI file and score it. "
        "With no SCENARIO: the built-in default maze with every object type.",
    )
    p.add_argument(
        "scenario",
        nargs="?",
        help="scenario YAML file or shipped name (default: the built-in default)",
    )
    p.add_argument("--out", default="trial", help="output folder (default: ./trial)")
    p.add_argument("--seed", type=int, help="generate the scenario from seed N instead of the default")
    p.add_argument(
        "--detector",
        help="default | oracle | FILE.onnx | python:MODULE:CLASS (its keyword arguments: --set "
        "detector.options.KEY=VALUE) | a name installed in the poibench.detectors entry point group "
        "(default: default, or --config's)",
    )
    p.add_argument(
        "--rules",
        default=None,
        help=f"{RULES_HELP} (default: the scenario's own rules, else ex3)",
    )
    p.add_argument("--noise", choices=["on", "off"], help="switch all sensor noise on or off")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a pipeline setting (tracker.gate=4) or a scenario setting (sensors.fps=15); repeatable",
    )
    p.add_argument(
        "--poi-version",
        choices=["1.2", "1.3"],
        help="POI file version to write (default 1.2; the same as --set report.poi_version='V')",
    )
    p.add_argument(
        "--config",
        help="rerun a trial from its config.yaml; --detector, --max-frames, --rules, --noise and --set "
        "given beside it apply on top (SCENARIO and --seed cannot: the config holds its scenario)",
    )
    p.add_argument("--max-frames", type=positive_int, help="stop after this many frames (at least 1)")
    p.add_argument("--no-video", action="store_true", help="do not write trial.mp4")
    p.add_argument(
        "--no-live-record",
        action="store_true",
        help="do not write live/ (the record poibench view replays); --live still serves the view",
    )
    p.add_argument(
        "--log",
        choices=["mcap", "bag"],
        help="also write the trial as a ROS log: mcap (a rosbag2 folder trial_mcap/, for ros2 bag play and "
        "Foxglove) or bag (a ROS 1 trial.bag, for rosbag play); either is about 1.6 MB a frame at 640x480 "
        "(colour, depth and thermal images uncompressed): 4 GB for the default trial's 2514 frames; "
        "about 0.77 MB a frame with --log-images png",
    )
    p.add_argument(
        "--log-images",
        choices=["raw", "png", "jpeg"],
        help="with --log: colour and depth as sensor_msgs/Image (raw, the default) or as "
        "sensor_msgs/CompressedImage on image_transport's topics (.../compressed, .../compressedDepth): "
        "colour PNG (lossless: a replay gives the raw log's pois.csv; about 0.77 MB a frame, raw 1.6) or "
        "JPEG (0.31 MB a frame; lossy, so a replay's pois.csv may differ: in 60 frames of the default trial "
        "three coordinates by 1-2 mm), depth always a lossless 16-bit PNG",
    )
    p.add_argument(
        "--log-topic",
        action="append",
        default=[],
        metavar="NAME=/TOPIC",
        help="a log topic name other than realsense-ros's (color, depth, odom, thermal, truth, detections, "
        "confirmed, ... ; an image's camera info goes beside it unless named too); repeatable",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--live", action="store_true", help="serve the live view on 127.0.0.1 while the trial runs")
    p.add_argument("--port", type=port, default=0, help="live view port, 0-65535 (default 0: a free one, printed)")
    p.set_defaults(func=cmd_run, locks_out=True)

    v = sub.add_parser("view", help="replay a finished trial in the browser (time slider)")
    v.add_argument("trial_dir", help="a folder written by poibench run")
    v.add_argument(
        "--port", type=port, default=0, help="port on 127.0.0.1, 0-65535 (default 0: a free one, printed)"
    )
    v.set_defaults(func=cmd_view)


def seconds(s: float) -> str:
    """Seconds to the tenth under 100 s, whole above: the figures a ratio beside them is read from.

    >>> seconds(5.94), seconds(251.3)
    ('5.9 s', '251 s')
    """
    return f"{s:.1f} s" if s < 100 else f"{s:.0f} s"


def check_detector(choice: str) -> None:
    """Refuse a ``--detector`` that names nothing before the trial starts. A ``python:`` module is
    also looked for in the working folder (a console script does not have it on sys.path)."""
    from eval.trial.detectors import check_detector_choice

    here = os.getcwd()
    if choice.startswith("python:") and here not in sys.path and "" not in sys.path:
        sys.path.append(here)
    check_detector_choice(choice)


def check_run_scenario(arg: str) -> None:
    """Refuse a scenario argument that is no file and no shipped scenario, listing the shipped
    scenarios, and naming the shipped suite it looks like (``rrl``, ``rrl-01``, ``rrl-1``):
    suites have a command of their own."""
    from eval.experiments.suites import load_suite, shipped_suites

    try:
        check_scenario_name(arg)
    except UnknownScenarioError as e:
        suites = [load_suite(name) for name in shipped_suites()]
        exact = [x for x in suites if x.name == arg or any(entry.name == arg for entry in x.scenarios)]
        prefix = sorted((x for x in suites if arg.startswith(x.name + "-")), key=lambda x: -len(x.name))
        if not exact + prefix:
            raise
        suite = (exact + prefix)[0]
        first, last = suite.scenarios[0].name, suite.scenarios[-1].name
        raise UnknownScenarioError(
            f"{e}; the suite {suite.name} (scenarios {first} to {last}) runs with poibench suite run {suite.name}"
        ) from None


def cmd_view(args) -> int:
    import time

    from eval.live.server import LiveServer, ReplaySource

    source = ReplaySource(args.trial_dir)
    if source.warning:
        print(f"warning: {source.warning}", file=sys.stderr)
    server = LiveServer(args.port, replay=source)
    url = server.start()
    print(f"replay of {args.trial_dir}: {url}  (Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        server.stop()
    return 0


def refuse_unused_flags(args, sim_sets: list[str], pipe_sets: list[str]) -> None:
    """Refuse flags of ``poibench run`` that could not take effect or that ``--set`` contradicts:
    ``--port`` without ``--live``, ``--poi-version`` beside ``--set report.poi_version``,
    ``--noise`` beside ``--set sensors.noise``."""
    if args.port and not args.live:
        raise SettingError(f"--port {args.port}: the live view's port; it needs --live")

    def keyed(sets: list[str], key: str) -> str | None:
        return next((s for s in sets if s.split("=", 1)[0].strip() == key), None)

    for flag, value, sets, key in (
        ("--poi-version", args.poi_version, pipe_sets, "report.poi_version"),
        ("--noise", args.noise, sim_sets, "sensors.noise"),
    ):
        if value is not None and keyed(sets, key):
            raise SettingError(f"{flag} {value} and --set {keyed(sets, key)} set one thing; choose one")


def clear_stale_outputs(out: Path, args) -> list[str]:
    """After a trial into an earlier trial's folder, remove the earlier video and live record
    this run did not write (``--no-video``, ``--no-live-record``): beside the new results they
    would show the earlier trial, and ``poibench view`` would replay it. An earlier ROS log is
    kept (it may be large and costly to make again) and named. The lines to print, one per
    stale output."""
    notes = []
    for name, stale in (("trial.mp4", args.no_video), ("live", args.no_live_record)):
        path = out / name
        if stale and path.exists():
            if path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink()
            notes.append(f"removed {path}, the earlier trial's (this run writes none)")
    for name, fmt in (("trial_mcap", "mcap"), ("trial.bag", "bag")):
        if (out / name).exists() and args.log != fmt:
            notes.append(f"{out / name} is the earlier trial's log (this run writes none); kept")
    return notes


def cmd_run(args) -> int:
    import yaml

    from eval.scoring.funnel import format_funnel
    from eval.scoring.map_error import MapErrorResult
    from eval.scoring.report import format_tables
    from eval.scoring.rules import load_rules, trial_rules
    from eval.trial.interrupt import DeferredInterrupt
    from eval.trial.run import run_trial
    from eval.trial.trial_config import load_trial_config
    from poi.config import flatten_config

    sim_sets, pipe_sets = split_settings(args.set)
    refuse_unused_flags(args, sim_sets, pipe_sets)
    if args.poi_version is not None:
        pipe_sets = [*pipe_sets, f"report.poi_version='{args.poi_version}'"]  # quoted: YAML reads 1.3 as a number
    detector, rules_name, max_frames = args.detector or "default", args.rules, args.max_frames
    detector_from = None  # the config file that named the detector, when one did
    rules_note = None
    if args.config:
        if args.scenario is not None or args.seed is not None:
            given_here = f"SCENARIO {args.scenario}" if args.scenario is not None else f"--seed {args.seed}"
            raise SettingError(
                f"{given_here} cannot be combined with --config {args.config}: the config holds its scenario "
                "(edit its scenario, or use --set for a scenario setting)"
            )
        doc, given = load_trial_config(args.config)
        sc = resolve_config_scenario(doc.scenario, args.set, args.noise)
        pipe_sets = [
            f"{k}={yaml.safe_dump(v, default_flow_style=True).strip()}"
            for k, v in flatten_config(given.get("pipeline") or {})
        ] + pipe_sets
        if args.detector is None and "detector" in given:
            detector, detector_from = doc.detector, args.config
        rules_name = rules_name or doc.rules
        if max_frames is None and "max_frames" in given:
            max_frames = doc.max_frames
    else:
        if args.scenario is not None:
            check_run_scenario(args.scenario)
        sc = resolve_scenario(args.scenario, args.seed, args.set, args.noise)
    if rules_name is None:
        rules_name = trial_rules(None, sc.rules)
        if sc.rules is not None:
            rules_note = f"scoring with the '{sc.rules}' rules, the scenario's own (--rules to choose others)"
    try:
        check_detector(detector)
    except ValueError as e:
        if detector_from is None:
            raise
        raise SettingError(f"{detector_from}: detector: {e}") from None  # the config's own: say where
    rules = load_rules(rules_name)
    if rules_note:
        print(f"note: {rules_note}", file=sys.stderr)
    setup_note = large_maze_note(sc)
    if setup_note:
        print(f"note: {setup_note}", file=sys.stderr, flush=True)
    logger = None
    if args.log:
        from eval.ros import require_rosbags
        from eval.ros.topics import parse_overrides

        require_rosbags(f"poibench run --log {args.log}")
        from eval.ros.writer import TrialLogger
        from eval.trial.run import MISSION_START

        start_ns = int(MISSION_START.replace(tzinfo=timezone.utc).timestamp()) * 1_000_000_000
        topics = parse_overrides(args.log_topic, flag="--log-topic")
        logger = TrialLogger(Path(args.out), args.log, start_ns, topics=topics, images=args.log_images or "raw")
    elif args.log_topic:
        raise SettingError("--log-topic needs --log mcap|bag")
    elif args.log_images:
        raise SettingError(f"--log-images {args.log_images} needs --log mcap|bag")
    earlier_trial = (Path(args.out) / "config.yaml").is_file()  # its outputs go once this trial has run
    server = None
    if args.live:
        from eval.live.server import LiveServer

        server = LiveServer(args.port)
        print(f"live view: {server.start()}", flush=True)
    from sim.world.placement import PlacementError

    try:
        with DeferredInterrupt() as stop:  # Ctrl-C ends the trial between two frames
            res = run_trial(
                sc,
                args.out,
                pipeline_sets=pipe_sets,
                detector=detector,
                rules=rules,
                rules_name=rules_name,
                video=not args.no_video,
                record_live=not args.no_live_record,
                progress=not args.quiet,
                max_frames=max_frames,
                live_server=server,
                on_frame=logger,
                interrupt=stop,
            )
    except PlacementError as e:  # the scenario's objects do not fit its maze: name the scenario
        raise SettingError(f"{args.config or args.scenario or 'the default scenario'}: {e}") from None
    finally:
        if server is not None:
            server.stop()
        log = logger.close() if logger is not None else None
    for note in [*res.notes, *(clear_stale_outputs(Path(args.out), args) if earlier_trial else [])]:
        print(f"note: {note}", file=sys.stderr)
    print(format_tables(res.score))
    if res.funnel is not None:
        f = res.funnel
        print("\n" + format_funnel(f.per_type(), f.lost, f.max_minus_score))
    s = res.score
    if isinstance(s, MapErrorResult):
        outcome = s.headline()
    else:
        frac = s.total / s.max_total if s.max_total else 0.0
        outcome = (
            f"{s.headline()} ({frac:.0%}), {counted(s.false_reports, 'false report')}, "
            f"{counted(s.misses, 'miss', 'misses')}"
        )
    c = res.cost
    if res.sim_duration_s > 0:
        cost = (
            f"{seconds(res.sim_duration_s)} simulated in {seconds(c.wall_s)} "
            f"({c.real_time_factor:.1f}x real time), "
            f"{seconds(c.cpu_s)} of CPU ({c.cpu_s_per_sim_s:.2f} CPU s per simulated s)"
        )
    else:  # one frame: no simulated time to divide by
        cost = f"0 s simulated, {seconds(c.wall_s)}, {seconds(c.cpu_s)} of CPU"
    print(
        f"\n{sc.name} (seed {sc.seed}), detector {res.detector}, rules {rules_name}: {outcome}; "
        f"{counted(res.n_frames, 'frame')}, {cost}"
    )
    written = list(res.written)
    if log is not None:
        written.append(log.path.name + ("/" if log.path.is_dir() else ""))
        cpu, wait = log.caller_ms_per_frame
        print(
            f"ROS log {log.path}: {counted(log.stats.frames, 'frame')}, {log.cpu_ms_per_frame:.1f} ms CPU a "
            f"frame on the writer thread; the trial's thread {cpu:.2f} ms CPU a frame, {wait:.2f} ms waiting "
            "for the writer"
        )
    print(f"wrote {res.out_dir}/: {' '.join(written)}")
    return 0
