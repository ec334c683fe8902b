"""`poibench replay` reads real recordings: the D435 RealSense Viewer fixture, and broken bags
give one clear line naming the file and the topic."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from eval.cli.main import main
from eval.ros.align import align_depth_to_color
from eval.ros.messages import build, camera_info_msg, header, image_msg, pose_msg, transform_msg, typestore
from eval.ros.reader import open_recording
from poi.core.poi_file import read_poi_file
from poi.core.types import Intrinsics

ROOT = Path(__file__).resolve().parents[3]
FIXTURE_NAME = Path("realdata", "realsense", "single_depth_color_640x480.bag")


def _fixture() -> Path | None:
    """The real D435 recording, from POIBENCH_REALDATA or the shared folder beside the checkout."""
    roots = [Path(os.environ["POIBENCH_REALDATA"]).parent] if os.environ.get("POIBENCH_REALDATA") else []
    roots += [ROOT.parent / "shared", Path("/", "work", "shared")]
    return next((r / FIXTURE_NAME for r in roots if (r / FIXTURE_NAME).exists()), None)


# the colour stream's CameraInfo of the fixture as the file holds it (float32 values, read once with
# `rosbag info`-style tools and written down here)
FIXTURE_COLOUR_K = (640, 480, 613.2036743164062, 613.4193115234375, 319.9388427734375, 239.18299865722656)


def test_replay_of_the_real_d435_recording_writes_a_valid_poi_file(tmp_path, capsys):
    bag = _fixture()
    if bag is None:
        pytest.skip("the D435 fixture (realdata/realsense) is not on this machine")
    rec = open_recording(bag)
    assert rec.layout == "viewer" and not rec.aligned and rec.n_frames == 1
    frames = list(rec.frames())
    assert len(frames) == 1
    k = frames[0].intrinsics
    assert (k.width, k.height, k.fx, k.fy, k.ppx, k.ppy) == FIXTURE_COLOUR_K
    # the depth (its own 390 px focal length) aligned to colour: the colour image's size, most pixels valid,
    # at the range of the scene (about 1.5 m to the desk in front of the camera)
    z = frames[0].depth_m
    assert z.shape == (480, 640) and (z > 0).mean() > 0.9
    assert 1.0 < float(np.median(z[z > 0])) < 2.0
    # no pose in the file: the camera's first pose is the map frame, and the output says so
    assert rec.pose_source == "none"
    out = tmp_path / "r"
    assert main(["replay", str(bag), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "the camera's first pose is the map frame" in err
    # no --truth: the funnel says in one line that it has nothing to check against
    funnel_lines = [line for line in err.splitlines() if "funnel" in line]
    assert funnel_lines == [
        "note: funnel: no ground truth (--truth), so no stage can be checked against the objects"
    ]
    assert not (out / "funnel.csv").exists()
    poi = read_poi_file(out / "pois.csv")
    assert not poi.problems and not poi.warnings and poi.header.mission == bag.stem
    info = json.loads((out / "replay.json").read_text())
    ki = info["intrinsics"]
    assert (ki["width"], ki["height"], ki["fx"], ki["fy"], ki["ppx"], ki["ppy"]) == FIXTURE_COLOUR_K
    for name in ("map.png", "trial.mp4", "live/frames.jsonl", "live/init.json"):
        assert (out / name).stat().st_size > 0, name
    from eval.live.server import ReplaySource

    assert len(ReplaySource(out).frames) == 1  # what poibench view replays


def test_depth_aligned_to_a_colour_camera_of_other_optics():
    """A wall 2 m away seen by a 320x240 depth camera (f = 195 px) and a 640x480 colour camera (f = 613 px)
    15 mm to its left: every colour pixel of the wall gets 2 m (no holes from the finer grid), and the
    wall's left edge moves by f_c * 0.015 / 2 = 4.6 px."""
    kd = Intrinsics(width=320, height=240, fx=195.0, fy=195.0, ppx=159.5, ppy=119.5)
    kc = Intrinsics(width=640, height=480, fx=613.0, fy=613.0, ppx=319.5, ppy=239.5)
    z = np.zeros((240, 320), np.float32)
    z[:, 160:] = 2.0  # the wall fills the right half: its left edge is on the optical axis (x = 0)
    T = np.eye(4)
    T[0, 3] = 0.015  # p_c = p_d + (0.015, 0, 0)
    a = align_depth_to_color(z, kd, kc, T)
    row = a[240]
    edge = int(np.flatnonzero(row)[0])
    # x = 0 at the depth image's edge (u = 159.5 - 0.5... the pixel boundary at 159.5 + 0.5 - 0.5 = 159.5)
    # projects to u_c = 319.5 + 613 * 0.015 / 2 = 324.1: the first colour centre at or after it is 325
    assert edge == 325
    assert np.all(row[edge:] == np.float32(2.0))
    assert np.all(a[5:-5, 330:] == np.float32(2.0))


# --- broken recordings: one line naming the file and the topic ----------------------------------------


def _write_bag(path: Path, *, colour_encoding="rgb8", with_depth=True, with_info=True, unaligned=False) -> Path:
    """A tiny ROS 1 bag on the realsense-ros topics: three 8x6 frames, depth 1.5 m everywhere; with
    ``unaligned`` the depth is on /camera/depth/image_rect_raw in frame "d", 0.15 m to the right of the
    colour frame "c" (p_c = p_d + (0.15, 0, 0), in /tf_static)."""
    from rosbags.rosbag1 import Writer

    ts = typestore(ros1=True)
    k = Intrinsics(width=8, height=6, fx=10.0, fy=10.0, ppx=3.5, ppy=2.5)
    with Writer(path) as w:
        conns = {}

        def put(topic, msgtype, t, msg):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_ros1(msg, msgtype))

        for i in range(3):
            t = 1_000_000_000 + i * 100_000_000
            rgb = np.full((6, 8, 3), 100, np.uint8)
            msg = image_msg(ts, t, "c", rgb, "rgb8")
            msg.encoding = colour_encoding
            put("/camera/color/image_raw", "sensor_msgs/msg/Image", t, msg)
            if with_info:
                put("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", t, camera_info_msg(ts, t, "c", k))
            if with_depth:
                mm = np.full((6, 8), 1500, np.uint16)
                stem, frame = ("/camera/depth/", "d") if unaligned else ("/camera/aligned_depth_to_color/", "c")
                image = stem + ("image_rect_raw" if unaligned else "image_raw")
                put(image, "sensor_msgs/msg/Image", t, image_msg(ts, t, frame, mm, "16UC1"))
                if with_info:
                    put(stem + "camera_info", "sensor_msgs/msg/CameraInfo", t, camera_info_msg(ts, t, frame, k))
        if unaligned:
            T = np.eye(4)
            T[0, 3] = 0.15
            stamped = build(
                ts,
                "geometry_msgs/msg/TransformStamped",
                header=header(ts, 1_000_000_000, "c"),
                child_frame_id="d",
                transform=transform_msg(ts, T),
            )
            static = build(ts, "tf2_msgs/msg/TFMessage", transforms=[stamped])
            put("/tf_static", "tf2_msgs/msg/TFMessage", 1_000_000_000, static)
        pose = build(ts, "geometry_msgs/msg/PoseWithCovariance", pose=pose_msg(ts, np.eye(4)))
        odom = build(
            ts, "nav_msgs/msg/Odometry", header=header(ts, 1_000_000_000, "odom"), child_frame_id="t", pose=pose
        )
        put("/t265/odom/sample", "nav_msgs/msg/Odometry", 1_000_000_000, odom)
    return path


def _replay_error(bag: Path, tmp_path: Path, capsys) -> str:
    assert main(["replay", str(bag), "--out", str(tmp_path / "out"), "--quiet", "--no-video"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_good_tiny_bag_replays(tmp_path, capsys):
    bag = _write_bag(tmp_path / "ok.bag")
    rec = open_recording(bag)
    frames = list(rec.frames())
    assert [f.index for f in frames] == [0, 1, 2]
    assert [f.timestamp_s for f in frames] == [0.0, 0.1, 0.2]
    assert frames[0].depth_m[0, 0] == np.float32(1.5)  # 1500 mm
    # odometry on frame 0 only (identity pose); frames 1 and 2 have none within half a period
    assert frames[0].pose is not None and np.allclose(frames[0].pose, np.eye(4))
    assert frames[1].pose is None and frames[2].pose is None
    # a replay says so: the frames without a pose are skipped, in one note
    assert main(["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--no-video"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "skipped" in line]
    assert notes == ["note: ok.bag: 2 of 3 frames skipped (nothing localised or tracked on them): no pose 2"]


def test_rosbag2_sqlite3_with_the_pose_from_tf(tmp_path):
    """A rosbag2 folder in sqlite3 storage whose only pose is /tf (map -> base_link moving 0.1 m a frame
    along x, base_link -> the colour optical frame in /tf_static): each frame's pose is map -> colour."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from poi.core.geometry import R_BODY_OPTICAL, make_transform

    ts = get_typestore(Stores.ROS2_HUMBLE)
    k = Intrinsics(width=8, height=6, fx=10.0, fy=10.0, ppx=3.5, ppy=2.5)
    T_base_cam = make_transform(R_BODY_OPTICAL, [0.1, 0.0, 0.5])
    path = tmp_path / "rec"
    with Writer(path, version=9) as w:
        conns = {}

        def put(topic, msgtype, t, msg):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
            w.write(conns[topic], t, ts.serialize_cdr(msg, msgtype))

        def tf(t, parent, child, T):
            stamped = build(
                ts,
                "geometry_msgs/msg/TransformStamped",
                header=header(ts, t, parent),
                child_frame_id=child,
                transform=transform_msg(ts, T),
            )
            return build(ts, "tf2_msgs/msg/TFMessage", transforms=[stamped])

        put(
            "/tf_static",
            "tf2_msgs/msg/TFMessage",
            1_000_000_000,
            tf(1_000_000_000, "base_link", "cam", T_base_cam),
        )
        for i in range(3):
            t = 1_000_000_000 + i * 100_000_000
            put(
                "/tf",
                "tf2_msgs/msg/TFMessage",
                t,
                tf(t, "map", "base_link", make_transform(np.eye(3), [0.1 * i, 0, 0])),
            )
            put(
                "/camera/color/image_raw",
                "sensor_msgs/msg/Image",
                t,
                image_msg(ts, t, "cam", np.zeros((6, 8, 3), np.uint8), "rgb8"),
            )
            put("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", t, camera_info_msg(ts, t, "cam", k))
            z = np.full((6, 8), 2.0, np.float32)
            put(
                "/camera/aligned_depth_to_color/image_raw",
                "sensor_msgs/msg/Image",
                t,
                image_msg(ts, t, "cam", z, "32FC1"),
            )
            put(
                "/camera/aligned_depth_to_color/camera_info",
                "sensor_msgs/msg/CameraInfo",
                t,
                camera_info_msg(ts, t, "cam", k),
            )
    rec = open_recording(path)
    assert rec.pose_source == "tf map" and np.allclose(rec.T_tracker_camera, np.eye(4))
    frames = list(rec.frames())
    assert len(frames) == 3 and frames[2].depth_m[0, 0] == np.float32(2.0)
    for i, f in enumerate(frames):
        expected = make_transform(np.eye(3), [0.1 * i, 0, 0]) @ T_base_cam
        assert np.allclose(f.pose, expected, atol=1e-12), i


def test_unaligned_realsense_ros_depth_is_aligned_with_the_tf_between_the_optical_frames(tmp_path):
    """Depth 1.5 m on /camera/depth/image_rect_raw, its frame 0.15 m from the colour frame: in the colour
    image it moves by f * 0.15 / 1.5 = 1 px to the right, so column 0 has no depth and the rest 1.5 m."""
    rec = open_recording(_write_bag(tmp_path / "unaligned.bag", unaligned=True))
    assert rec.depth_topic == "/camera/depth/image_rect_raw" and not rec.aligned
    assert np.allclose(rec.T_color_depth[:3, 3], [0.15, 0.0, 0.0])
    z = next(rec.frames()).depth_m
    assert np.all(z[:, 0] == 0) and np.all(z[:, 1:] == np.float32(1.5))


def test_missing_topic(tmp_path, capsys):
    bag = _write_bag(tmp_path / "nodepth.bag", with_depth=False)
    line = _replay_error(bag, tmp_path, capsys)
    assert line.startswith(f"poibench replay: error: {bag}: missing topic: no depth image on ")
    assert "/camera/aligned_depth_to_color/image_raw" in line


def test_a_topic_named_by_flag_that_is_not_there(tmp_path, capsys):
    bag = _write_bag(tmp_path / "ok.bag")
    argv = ["replay", str(bag), "--topic", "color=/front/rgb", "--out", str(tmp_path / "o"), "--quiet"]
    assert main(argv) == 2
    assert "missing topic: no colour image on /front/rgb" in capsys.readouterr().err
    # any stream named by --topic must be there, not quietly replaced (odometry by tf, thermal by none)
    for item in ("odom=/nonexistent", "thermal=/nonexistent"):
        assert main([*argv[:2], "--topic", item, *argv[4:]]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith(f"poibench replay: error: {bag}: --topic {item}: no such topic in the recording")
    # the streams a log carries for others, which replay never reads, are refused by name
    assert main([*argv[:2], "--topic", "truth=/x", *argv[4:]]) == 2
    err = capsys.readouterr().err
    assert "--topic truth: streams poibench run --log writes, which replay does not read" in err


def test_rules_need_a_truth_and_a_truth_must_be_ground_truth(tmp_path, capsys):
    bag = _write_bag(tmp_path / "ok.bag")
    argv = ["replay", str(bag), "--out", str(tmp_path / "o"), "--quiet", "--no-video"]
    assert main([*argv, "--rules", "rmrc2026"]) == 2
    assert "--rules rmrc2026: scores against ground truth; it needs --truth TRUTH.csv" in capsys.readouterr().err
    from poi.core.poi_file import PoiHeader, PoiRow, write_poi_file

    report = tmp_path / "pois.csv"
    header = PoiHeader(team="t", country="c", date="2026-12-05", start_time="10:00:00", mission="m")
    row = PoiRow(line=0, id=1, time="10:00:01", text="", x=1.0, y=2.0, z=0.5, robot="r", mode="A", type="door")
    write_poi_file(report, header, [row])
    assert main([*argv, "--truth", str(report)]) == 2
    line = read_poi_file(report).rows[0].line
    expected = f"{report}: line {line}: mode 'A'; expected GT (a truth.csv, not a report: swapped with"
    assert expected in capsys.readouterr().err


def test_an_oracle_trials_config_needs_another_detector_which_brings_its_own_files(tmp_path, capsys):
    bag = _write_bag(tmp_path / "ok.bag")
    cfg = tmp_path / "config.yaml"
    cfg.write_text("poibench_trial: 1\ndetector: oracle\nscenario: {poibench_scenario: 1}\n")
    argv = ["replay", str(bag), "--config", str(cfg), "--out", str(tmp_path / "o"), "--quiet", "--no-video"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert (
        f"error: {cfg}: detector oracle needs the simulator's ground truth; a recording has none (give --detector)"
        in err
    )
    # the shipped detector named instead runs with its label model (the oracle's config names none)
    assert main([*argv, "--detector", "default"]) == 0


def test_unknown_encoding(tmp_path, capsys):
    bag = _write_bag(tmp_path / "yuv.bag", colour_encoding="yuv422")
    line = _replay_error(bag, tmp_path, capsys)
    assert line == (
        f"poibench replay: error: {bag}: /camera/color/image_raw: unknown colour encoding 'yuv422'; "
        "expected one of rgb8, bgr8, rgba8, bgra8"
    )


def test_no_camera_info(tmp_path, capsys):
    bag = _write_bag(tmp_path / "noinfo.bag", with_info=False)
    line = _replay_error(bag, tmp_path, capsys)
    assert line.startswith(f"poibench replay: error: {bag}: no camera info: no colour camera info on ")
    assert "/camera/color/camera_info" in line


def test_truncated_file(tmp_path, capsys):
    good = _write_bag(tmp_path / "good.bag")
    data = good.read_bytes()
    bag = tmp_path / "cut.bag"
    bag.write_bytes(data[: len(data) // 2])
    line = _replay_error(bag, tmp_path, capsys)
    # its one chunk is cut: nothing whole is left to read, and the line says why
    assert line == (
        f"poibench replay: error: {bag}: missing topic: no colour image on /camera/color/image_raw (--topic to "
        "name another; topics: none) (a recording never closed or cut short: read as far as it goes)"
    )


def test_what_is_not_a_recording_is_said_plainly(tmp_path, capsys):
    rand = tmp_path / "rand.bag"
    rand.write_bytes(bytes(range(256)) * 4)
    assert _replay_error(rand, tmp_path, capsys).endswith(
        f"{rand}: not a ROS 1 bag (it does not start with #ROSBAG V2.0)"
    )
    empty = tmp_path / "empty"
    empty.mkdir()
    line = _replay_error(empty, tmp_path, capsys)
    assert line.endswith(f"{empty}: not a recording (no rosbag2 metadata.yaml, no .mcap or .db3 in the folder)")
    (empty / "empty_0.mcap").write_bytes(b"\x89MCAP0\r\n")  # a run stopped before it wrote a record
    line = _replay_error(empty, tmp_path, capsys)
    assert line.endswith("topics: none) (a recording never closed or cut short: read as far as it goes)")
    (empty / "empty_1.mcap").write_bytes(b"\x89MCAP0\r\n")  # two files: not one recording's
    line = _replay_error(empty, tmp_path, capsys)
    assert f"{empty}: a rosbag2 folder without metadata.yaml beside empty_0.mcap, empty_1.mcap" in line


def test_no_such_recording(tmp_path, capsys):
    line = _replay_error(tmp_path / "absent.bag", tmp_path, capsys)
    assert line == f"poibench replay: error: {tmp_path / 'absent.bag'}: no such file or folder"


def test_a_never_closed_recording_without_the_mcap_library_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    folder = tmp_path / "killed"
    folder.mkdir()
    (folder / "killed_0.mcap").write_bytes(b"\x89MCAP0\r\n")
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "mcap" else real(name, *a))
    line = _replay_error(folder, tmp_path, capsys)
    assert line.endswith(
        f"{folder}: a recording never closed (no metadata.yaml); reading it needs the mcap library: "
        "pip install 'poibench[ros]' (or pip install mcap)"
    )
