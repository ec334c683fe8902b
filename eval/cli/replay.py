"""`poibench replay RECORDING`: the pipeline over a robot's recording (a ROS 1 bag, the RealSense
Viewer's too, or a rosbag2 folder), with a trial's outputs; scored with ``--truth``."""

from __future__ import annotations

import argparse
import sys

from eval.cli.args import RULES_HELP, positive_int
from eval.text import counted
from eval.trial.scenarios import split_settings


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="run the pipeline over a ROS recording (bag, rosbag2 sqlite3/MCAP) and write pois.csv",
        description="Read a ROS 1 bag (realsense-ros topics or the RealSense Viewer's layout) or a rosbag2 "
        "folder (sqlite3 or MCAP), run the pipeline on its frames and write pois.csv, map.png, trial.mp4, "
        "live/ (poibench view replays it) and replay.json; with --truth, score.json and funnel.csv.",
    )
    p.add_argument("recording", help="a .bag file or a rosbag2 folder (with metadata.yaml)")
    p.add_argument("--out", default="replay", help="output folder (default: ./replay)")
    p.add_argument("--truth", metavar="TRUTH.csv", help="ground truth (POI file, mode GT) to score against")
    p.add_argument("--rules", help=f"{RULES_HELP}, to score against --truth (default: ex3)")
    p.add_argument(
        "--config",
        metavar="CONFIG.yaml",
        help="a trial's config.yaml: its pipeline settings, detector and mission name (the round trip of "
        "poibench run --log)",
    )
    p.add_argument("--detector", help="default | FILE.onnx | python:MODULE:CLASS | an installed detector's name")
    p.add_argument(
        "--topic",
        action="append",
        default=[],
        metavar="NAME=/TOPIC",
        help="where a stream is: color, color_info, depth, depth_info, odom, thermal, thermal_info, tf, "
        "tf_static (default: realsense-ros names, or the RealSense Viewer's layout; an image stream's "
        "camera info defaults to camera_info beside it); repeatable",
    )
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a pipeline setting; repeatable"
    )
    p.add_argument("--max-frames", type=positive_int, help="stop after this many frames (at least 1)")
    p.add_argument("--no-video", action="store_true", help="do not write trial.mp4")
    p.add_argument("--no-live-record", action="store_true", help="do not write live/")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_replay, locks_out=True)


def cmd_replay(args) -> int:
    from eval.ros import require_rosbags

    require_rosbags("poibench replay")
    from eval.ros.reader import open_recording
    from eval.ros.replay import ReplayError, replay
    from eval.ros.topics import TopicError, parse_overrides
    from eval.scoring.report import format_tables
    from eval.scoring.rules import load_rules
    from eval.scoring.truth import read_truth_file

    topics = parse_overrides(args.topic)
    given = {item.partition("=")[0] for item in args.topic}
    written = sorted(given & {"truth", "detections", "confirmed"})
    if written:
        raise TopicError(
            f"--topic {', '.join(written)}: streams poibench run --log writes, which replay does not read "
            "(it reads color, depth, their camera infos, odom, thermal and tf)"
        )
    scenario_sets, pipe_sets = split_settings(args.set)
    if scenario_sets:
        raise ReplayError(f"--set {scenario_sets[0]}: a scenario setting; a recording has no scenario")
    if args.detector:
        from eval.cli.run import check_detector

        check_detector(args.detector)
    if args.rules and not args.truth:
        raise ReplayError(f"--rules {args.rules}: scores against ground truth; it needs --truth TRUTH.csv")
    rules = load_rules(args.rules or "ex3") if args.truth else None
    truth = read_truth_file(args.truth) if args.truth else None
    rec = open_recording(args.recording, topics, given)
    res = replay(
        rec,
        args.out,
        config_path=args.config,
        detector=args.detector,
        pipeline_sets=pipe_sets,
        truth=truth,
        rules=rules,
        video=not args.no_video,
        record_live=not args.no_live_record,
        progress=not args.quiet,
        max_frames=args.max_frames,
    )
    for note in res.notes:
        print(f"note: {note}", file=sys.stderr)
    if res.score is not None:
        print(format_tables(res.score))
    if res.funnel is not None:
        from eval.scoring.funnel import format_funnel

        print("\n" + format_funnel(res.funnel.per_type(), res.funnel.lost, res.funnel.max_minus_score))
    print(
        f"{rec.path.name} ({rec.layout} layout, pose from {rec.pose_source}): {res.n_frames} frames in "
        f"{res.wall_s:.1f} s ({res.frames_per_s:.1f} frames/s, {res.cpu_ms_per_frame:.0f} ms CPU a frame), "
        f"{counted(res.confirmed, 'report')}" + (f"; {res.score.headline()}" if res.score is not None else "")
    )
    print(f"wrote {res.out_dir}/: {' '.join(res.written)}")
    return 0
