"""`poibench run --log mcap|bag`: the log read back by readers independent of the writer
(mcap-ros2-support for the MCAP, Debian's ROS 1 rosbag for the bag), and replayed by
`poibench replay` into the same pois.csv (coordinates within the millimetre the log's 16UC1 depth
rounds to)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections import Counter, defaultdict
from datetime import timezone
from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip("rosbags")

from eval.cli.main import main
from eval.trial.run import MISSION_START

DETECTORS = Path(__file__).resolve().parents[2] / "poi" / "detectors"  # red_detector.py
# the earlier sweeping tour (robot.pan.mode: sweep): its first frames drive past the objects
SCENE = [
    "--set",
    "maze.file=rrl_small",
    "--set",
    "objects.generate.counts={fire-extinguisher: 2, valve: 1}",
    "--set",
    "robot.pan.mode=sweep",
]
# T265 dropouts, so that some frames have no pose: no odometry for them. 90 a minute of
# 0.1-0.2 s: about 6 in the 4 s (none with probability e^-6) covering about a quarter of
# the frames, so the objects are still seen from posed frames
DROPOUTS = [
    "--set",
    "sensors.t265.dropouts.rate_per_min=90",
    "--set",
    "sensors.t265.dropouts.duration_s=[0.1, 0.2]",
]
RED = "python:red_detector:RedBlobDetector"
FRAMES = 40
START_NS = int(MISSION_START.replace(tzinfo=timezone.utc).timestamp()) * 1_000_000_000
PER_FRAME = (
    "/camera/color/image_raw",
    "/camera/color/camera_info",
    "/camera/aligned_depth_to_color/image_raw",
    "/camera/aligned_depth_to_color/camera_info",
    "/thermal/image_raw",
    "/thermal/camera_info",
    "/poibench/detections",
    "/poibench/confirmed",
)
TYPES = {
    "/camera/color/image_raw": "sensor_msgs/Image",
    "/camera/color/camera_info": "sensor_msgs/CameraInfo",
    "/camera/aligned_depth_to_color/image_raw": "sensor_msgs/Image",
    "/camera/aligned_depth_to_color/camera_info": "sensor_msgs/CameraInfo",
    "/thermal/image_raw": "sensor_msgs/Image",
    "/thermal/camera_info": "sensor_msgs/CameraInfo",
    "/t265/odom/sample": "nav_msgs/Odometry",
    "/tf": "tf2_msgs/TFMessage",
    "/tf_static": "tf2_msgs/TFMessage",
    "/poibench/truth": "visualization_msgs/MarkerArray",
    "/poibench/detections": "visualization_msgs/MarkerArray",
    "/poibench/confirmed": "visualization_msgs/MarkerArray",
}
ENCODINGS = {
    "/camera/color/image_raw": "rgb8",
    "/camera/aligned_depth_to_color/image_raw": "16UC1",
    "/thermal/image_raw": "32FC1",
}


def _trial(tmp: Path, fmt: str) -> Path:
    sys.path.insert(0, str(DETECTORS))
    try:
        import red_detector

        weights = red_detector.write_weights(tmp / "red.npz")
        out = tmp / f"t_{fmt}"
        argv = ["run", "--detector", RED, "--set", f"detector.options.weights={weights}", "--log", fmt]
        assert (
            main(
                [*argv, "--max-frames", str(FRAMES), "--no-video", "--quiet", "--out", str(out), *SCENE, *DROPOUTS]
            )
            == 0
        )
    finally:
        sys.path.remove(str(DETECTORS))
    return out


@pytest.fixture(scope="module")
def mcap_trial(tmp_path_factory) -> Path:
    return _trial(tmp_path_factory.mktemp("mcap"), "mcap")


@pytest.fixture(scope="module")
def bag_trial(tmp_path_factory) -> Path:
    return _trial(tmp_path_factory.mktemp("bag"), "bag")


def _expected(trial: Path) -> dict:
    cfg = yaml.safe_load((trial / "config.yaml").read_text())
    live = [json.loads(line) for line in (trial / "live" / "frames.jsonl").read_text().splitlines()]
    assert len(live) == FRAMES
    s = cfg["scenario"]["sensors"]
    d = s["d435"]
    K = [d["fx"], 0.0, d["ppx"], 0.0, d["fy"], d["ppy"], 0.0, 0.0, 1.0]
    th = s["thermal"]
    sx, sy = th["width"] / d["width"], th["height"] / d["height"]  # Intrinsics.scaled
    K_th = [
        d["fx"] * sx,
        0.0,
        (d["ppx"] + 0.5) * sx - 0.5,
        0.0,
        d["fy"] * sy,
        (d["ppy"] + 0.5) * sy - 0.5,
        0,
        0,
        1,
    ]
    return {
        "size": (d["width"], d["height"]),
        "K": K,
        "K_thermal": K_th,
        "thermal_size": (th["width"], th["height"]),
        "stamps": [START_NS + round(k / s["fps"] * 1e9) for k in range(FRAMES)],
        "truth": len([r for r in (trial / "truth.csv").read_text().splitlines()[8:] if r.strip()]),
        # the frames the pipeline had a pose for, as the trial's live record has them
        "posed": [k for k, m in enumerate(live) if m["pose"] is not None],
    }


def _check(summary: dict, trial: Path) -> None:
    """The properties both readers must find, from a summary of what each read:
    counts[topic], types[topic], stamps[topic], encodings[topic], info[topic] = (w, h, K, D, model),
    tf edges [(parent, child)], truth markers, the first image's bytes."""
    exp = _expected(trial)
    counts, types = summary["counts"], summary["types"]
    assert set(types) == set(TYPES)
    for topic, t in TYPES.items():
        assert types[topic].replace("/msg/", "/") == t, topic
    for topic in PER_FRAME:
        assert counts[topic] == FRAMES, topic
        assert summary["stamps"][topic] == exp["stamps"], topic
    assert counts["/tf_static"] == 1 and counts["/poibench/truth"] == 1
    # the odometry and /tf on every frame with a pose, none on a dropout
    posed = [exp["stamps"][k] for k in exp["posed"]]
    assert 0 < len(posed) < FRAMES
    assert summary["stamps"]["/t265/odom/sample"] == summary["stamps"]["/tf"] == posed
    for topic, enc in ENCODINGS.items():
        assert summary["encodings"][topic] == {enc}, topic
    for topic in ("/camera/color/camera_info", "/camera/aligned_depth_to_color/camera_info"):
        w, h, K, D, model = summary["info"][topic]
        assert (w, h) == exp["size"] and model == "plumb_bob" and D == [0.0] * 5
        assert np.allclose(K, exp["K"], rtol=0, atol=1e-12), topic
    w, h, K, _, _ = summary["info"]["/thermal/camera_info"]
    assert (w, h) == exp["thermal_size"] and np.allclose(K, exp["K_thermal"], rtol=0, atol=1e-9)
    assert summary["truth_markers"] == 2 * exp["truth"]  # a sphere and a label per object
    # the TF tree is connected: every frame reaches the map
    parent = {}
    for p, c in summary["tf_edges"]:
        parent[c] = p
    for frame in set(parent) | set(parent.values()):
        f, seen = frame, 0
        while f in parent and seen < 20:
            f, seen = parent[f], seen + 1
        assert f == "map", f"{frame} does not reach the map (stops at {f})"
    assert {"map", "odom", "base_link", "t265_pose_frame", "camera_color_optical_frame"} <= set(parent) | set(
        parent.values()
    )
    assert "camera_aligned_depth_to_color_frame" in parent and "thermal_optical_frame" in parent


@pytest.mark.slow
def test_mcap_log_decodes_with_mcap_ros2_support(mcap_trial):
    mcap_reader = pytest.importorskip("mcap.reader")
    decoder = pytest.importorskip("mcap_ros2.decoder")
    folder = mcap_trial / "trial_mcap"
    meta = yaml.safe_load((folder / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and meta["relative_file_paths"] == ["trial_mcap.mcap"]
    summary = _empty_summary()
    with open(folder / "trial_mcap.mcap", "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[decoder.DecoderFactory()])
        for schema, channel, message, msg in reader.iter_decoded_messages():
            assert message.log_time == message.publish_time
            _summarise(summary, channel.topic, schema.name, msg, message.log_time)
    assert meta["message_count"] == sum(summary["counts"].values())
    _check(summary, mcap_trial)


def _empty_summary() -> dict:
    return {
        "counts": Counter(),
        "types": {},
        "stamps": defaultdict(list),
        "encodings": defaultdict(set),
        "info": {},
        "tf_edges": [],
        "truth_markers": 0,
    }


def _summarise(s: dict, topic: str, msgtype: str, msg, log_time: int) -> None:
    """Add one ROS 2 message (as mcap-ros2-support decodes it) to the summary."""
    s["counts"][topic] += 1
    s["types"][topic] = msgtype
    if hasattr(msg, "header"):
        st = msg.header.stamp
        assert st.sec * 1_000_000_000 + st.nanosec == log_time
    s["stamps"][topic].append(log_time)
    if msgtype.endswith("Image"):
        s["encodings"][topic].add(msg.encoding)
        assert len(msg.data) == msg.step * msg.height
    if msgtype.endswith("CameraInfo"):
        K, D = list(msg.k), list(msg.d)
        s["info"][topic] = (msg.width, msg.height, K, D, msg.distortion_model)
    if msgtype.endswith("TFMessage"):
        s["tf_edges"] += [(t.header.frame_id, t.child_frame_id) for t in msg.transforms]
    if topic == "/poibench/truth":
        s["truth_markers"] = len(msg.markers)


ROSBAG_READ = r"""
import json, sys, rosbag
out = {"counts": {}, "types": {}, "stamps": {}, "encodings": {}, "info": {}, "tf_edges": [], "truth_markers": 0}
with rosbag.Bag(sys.argv[1]) as bag:
    for topic, msg, t in bag.read_messages():
        out["counts"][topic] = out["counts"].get(topic, 0) + 1
        out["types"][topic] = msg._type
        out["stamps"].setdefault(topic, []).append(t.to_nsec())
        if hasattr(msg, "header"):
            assert t.to_nsec() == msg.header.stamp.to_nsec()
        if msg._type == "sensor_msgs/Image":
            out["encodings"].setdefault(topic, []).append(msg.encoding)
            assert len(msg.data) == msg.step * msg.height
        if msg._type == "sensor_msgs/CameraInfo":
            out["info"][topic] = [msg.width, msg.height, list(msg.K), list(msg.D), msg.distortion_model]
        if msg._type == "tf2_msgs/TFMessage":
            out["tf_edges"] += [[x.header.frame_id, x.child_frame_id] for x in msg.transforms]
        if topic == "/poibench/truth":
            out["truth_markers"] = len(msg.markers)
print(json.dumps(out))
"""


def _system_rosbag() -> tuple[str, str]:
    """Debian's ROS 1 tools (apt-get install python3-rosbag): the rosbag command and a python3 that
    imports rosbag; the test is skipped only when they are not installed."""
    cmd = shutil.which("rosbag")
    py = shutil.which("python3", path="/usr/bin")
    if cmd is None or py is None:
        pytest.skip("Debian's ROS 1 tools are not installed (apt-get install python3-rosbag)")
    if subprocess.run([py, "-c", "import rosbag"], capture_output=True).returncode != 0:
        pytest.skip("/usr/bin/python3 cannot import rosbag (apt-get install python3-rosbag)")
    return cmd, py


@pytest.mark.slow
def test_bag_reads_with_debians_rosbag(bag_trial):
    cmd, py = _system_rosbag()
    bag = bag_trial / "trial.bag"
    info = subprocess.run([cmd, "info", "--yaml", str(bag)], capture_output=True, text=True, timeout=120)
    assert info.returncode == 0, info.stderr
    doc = yaml.safe_load(info.stdout)
    assert {t["topic"]: t["type"] for t in doc["topics"]} == TYPES
    assert doc["start"] == pytest.approx(START_NS / 1e9)
    read = subprocess.run([py, "-c", ROSBAG_READ, str(bag)], capture_output=True, text=True, timeout=300)
    assert read.returncode == 0, read.stderr
    raw = json.loads(read.stdout)
    summary = {
        "counts": Counter(raw["counts"]),
        "types": raw["types"],
        "stamps": raw["stamps"],
        "encodings": {k: set(v) for k, v in raw["encodings"].items()},
        "info": {k: tuple(v) for k, v in raw["info"].items()},
        "tf_edges": [tuple(e) for e in raw["tf_edges"]],
        "truth_markers": raw["truth_markers"],
    }
    assert {t["topic"]: t["messages"] for t in doc["topics"]} == dict(summary["counts"])
    _check(summary, bag_trial)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["mcap", "bag"])
def test_round_trip_replay_gives_the_same_poi_file(fmt, mcap_trial, bag_trial, tmp_path, capsys):
    trial = mcap_trial if fmt == "mcap" else bag_trial
    log = trial / ("trial_mcap" if fmt == "mcap" else "trial.bag")
    out = tmp_path / "replay"
    sys.path.insert(0, str(DETECTORS))
    try:
        argv = ["replay", str(log), "--config", str(trial / "config.yaml"), "--truth", str(trial / "truth.csv")]
        assert main([*argv, "--out", str(out), "--quiet", "--no-video"]) == 0
    finally:
        sys.path.remove(str(DETECTORS))
    captured = capsys.readouterr()
    assert "pose from odometry /t265/odom/sample" in captured.out
    original = (trial / "pois.csv").read_text().splitlines()
    replayed = (out / "pois.csv").read_text().splitlines()
    assert len(original) >= 9  # the seven header lines, the column line and at least one object
    # The same file but for the last digit of a coordinate: the log holds depth as realsense-ros publishes
    # it, 16UC1 millimetres, so each depth pixel the trial saw (float32 metres) moves by up to 0.5 mm, and
    # a position by about as much; with the file's 1 mm rounding that is at most 2 mm in x, y or z.
    # (In this scenario the two files are the same, byte for byte.)
    assert replayed[:8] == original[:8] and len(replayed) == len(original)
    for a, b in zip(original[8:], replayed[8:], strict=True):
        fa, fb = a.split(","), b.split(",")
        assert fa[:3] + fa[6:] == fb[:3] + fb[6:]
        assert np.allclose([float(v) for v in fa[3:6]], [float(v) for v in fb[3:6]], rtol=0, atol=0.002 + 1e-9)
    # scored against the trial's truth as the trial was, with the funnel of the replay
    doc = json.loads((out / "score.json").read_text())
    assert doc["total"] == json.loads((trial / "score.json").read_text())["total"]
    assert doc["funnel"]["check"] == "ok" and (out / "funnel.csv").exists()
    assert "Funnel (objects passing each stage" in captured.out


def test_renamed_topics_and_the_tf_chain_give_the_pose_and_mount(tmp_path):
    """LogWriter alone on two synthetic frames, colour renamed: reading the log back, the TF chain
    map -> ... -> colour optical frame equals pose @ mount, and the replay reader recovers both."""
    from eval.ros.reader import open_recording
    from eval.ros.topics import Topics, parse_overrides
    from eval.ros.writer import LogWriter
    from poi.core.geometry import make_transform, rot_x, rot_z
    from poi.core.types import Frame, Intrinsics

    k = Intrinsics(width=8, height=6, fx=10.0, fy=10.0, ppx=3.5, ppy=2.5)
    mount = make_transform(rot_x(-1.2), [0.05, -0.02, 0.1])
    poses = [make_transform(rot_z(0.3) @ rot_x(0.02), [1.0, 2.0, 0.9]), None]
    topics = parse_overrides(["color=/front/rgb", "color_info=/front/rgb_info"])
    w = LogWriter(tmp_path / "t.bag", "bag", start_ns=START_NS, T_tracker_camera=mount, truth=[], topics=topics)
    gyro = np.array([0.1, -0.4, 2.1])  # rad/s, the tracker's axes
    for i, pose in enumerate(poses):
        z = np.full((6, 8), 1.234, np.float32)
        f = Frame(
            index=i,
            timestamp_s=0.1 * i,
            rgb=np.zeros((6, 8, 3), np.uint8),
            intrinsics=k,
            depth_m=z,
            pose=pose,
            angular_velocity=gyro,
        )
        w.write(f, [], [])
    w.close()
    assert w.stats.counts["/front/rgb"] == 2 and Topics().color not in w.stats.counts
    assert w.stats.counts["/t265/odom/sample"] == 1  # none for the frame without a pose
    given = {"color", "color_info"}
    rec = open_recording(tmp_path / "t.bag", topics, given)
    assert rec.pose_source == "odometry /t265/odom/sample"
    assert np.allclose(rec.T_tracker_camera, mount, atol=1e-12)
    frames = list(rec.frames())
    assert np.allclose(frames[0].pose, poses[0], atol=1e-12) and frames[1].pose is None
    # the gyro rides in the odometry's twist (the QR reader's deblurring reads it back)
    assert np.allclose(frames[0].angular_velocity, gyro) and frames[1].angular_velocity is None
    assert frames[0].depth_m[0, 0] == np.float32(1.234)  # 1234 mm
    # the /tf chain: map -> odom -> base_link -> t265_pose_frame -> colour optical frame
    from rosbags.highlevel import AnyReader

    from eval.ros.reader import TfTree

    tree = TfTree()
    with AnyReader([tmp_path / "t.bag"]) as r:
        for c, _, raw in r.messages([c for c in r.connections if c.topic in ("/tf", "/tf_static")]):
            tree.add(r.deserialize(raw, c.msgtype), c.topic == "/tf_static")
    tree.sort()
    T = tree.between("map", "camera_color_optical_frame", START_NS, 0)
    assert np.allclose(T, poses[0] @ mount, atol=1e-12)
    base = tree.between("map", "base_link", START_NS, 0)
    assert abs(base[2, 3]) < 1e-12 and np.allclose(base[:3, 2], [0, 0, 1])  # the base on the floor, upright


def test_an_image_topic_named_alone_has_its_camera_info_beside_it(tmp_path):
    """`--log-topic color=/front/color/image_raw --log-images png` writes the colour camera's info on
    /front/color/camera_info (beside the image, not its compressed transport topic), and `replay
    --topic color=/front/color/image_raw` (the README's example) reads the log there without naming
    the info or the transport; an info that is not beside its image is said to be looked for there,
    and two streams that would share a topic are refused."""
    from eval.cli.main import main
    from eval.ros.reader import RecordingError, open_recording
    from eval.ros.topics import TopicError, Topics, parse_overrides
    from eval.ros.writer import LogWriter
    from poi.core.types import Frame, Intrinsics

    names = ["color=/front/color/image_raw", "depth=/front/depth/image_rect_raw"]
    topics = parse_overrides(names)
    assert (topics.color_info, topics.depth_info) == ("/front/color/camera_info", "/front/depth/camera_info")
    assert topics.thermal_info == Topics().thermal_info  # a stream not named keeps its default
    k = Intrinsics(width=8, height=6, fx=10.0, fy=10.0, ppx=3.5, ppy=2.5)

    def write(bag: Path, topics: Topics) -> LogWriter:
        w = LogWriter(
            bag, "bag", start_ns=START_NS, T_tracker_camera=np.eye(4), truth=[], topics=topics, images="png"
        )
        rgb = np.full((6, 8, 3), 77, np.uint8)
        w.write(
            Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=k, depth_m=np.ones((6, 8), np.float32)), [], []
        )
        w.close()
        return w

    w = write(tmp_path / "t.bag", topics)
    assert w.stats.counts["/front/color/camera_info"] == 1 and Topics().color_info not in w.stats.counts
    assert w.stats.counts["/front/color/image_raw/compressed"] == 1
    (frame,) = open_recording(tmp_path / "t.bag", topics, {"color", "depth"}).frames()
    assert frame.intrinsics.fx == 10.0 and frame.rgb[0, 0, 0] == 77
    # the info written elsewhere: the reader names where it looked and why
    write(tmp_path / "u.bag", parse_overrides([*names, "color_info=/front/rgb_info"]))
    with pytest.raises(
        RecordingError, match=r"no camera info beside --topic color: no colour camera info on /front/"
    ):
        open_recording(tmp_path / "u.bag", topics, {"color", "depth"})
    with pytest.raises(TopicError, match="color_info and thermal_info would both be /front/camera_info"):
        parse_overrides(["color=/front/rgb", "thermal=/front/thermal"])
    argv = ["replay", str(tmp_path / "t.bag"), "--topic", "color=/front/rgb", "--topic", "depth=/front/rgb_info"]
    assert main([*argv, "--out", str(tmp_path / "r")]) == 2  # depth's info would be color's: refused, one line


def _full_frame_log(path: Path, fmt: str, n: int) -> None:
    """A log of ``n`` 640x480 frames, each its own grey, depth and pose: a frame and a half a chunk
    (rosbags closes a chunk of either format past 1 MiB)."""
    from eval.ros.writer import LogWriter
    from poi.core.geometry import make_transform, rot_z
    from poi.core.types import Frame, Intrinsics

    k = Intrinsics(width=640, height=480, fx=600.0, fy=600.0, ppx=319.5, ppy=239.5)
    w = LogWriter(path, fmt, start_ns=START_NS, T_tracker_camera=np.eye(4), truth=[])
    for i in range(n):
        rgb = np.full((480, 640, 3), 10 * i, np.uint8)
        depth = np.full((480, 640), 1.0 + 0.1 * i, np.float32)
        pose = make_transform(rot_z(0.1 * i), [0.2 * i, 0.0, 0.5])
        w.write(Frame(index=i, timestamp_s=0.1 * i, rgb=rgb, intrinsics=k, depth_m=depth, pose=pose), [], [])
    w.close()


def _count_scans(monkeypatch) -> list[int]:
    """A list that gets a 1 each time an unclosed log's file is scanned from its start."""
    from eval.ros.unclosed import UnclosedBag

    scans: list[int] = []
    scan = UnclosedBag._scan

    def counted(self):
        scans.append(1)
        yield from scan(self)

    monkeypatch.setattr(UnclosedBag, "_scan", counted)
    return scans


def test_a_killed_runs_mcap_log_replays_up_to_where_it_stopped(tmp_path, capsys):
    """A run killed mid-trial leaves its rosbag2 folder without metadata.yaml and its MCAP file without
    summary or footer: the data section written so far, whole chunks (rosbags closes a chunk past 1 MiB)
    and then the chunk cut short. Cut a closed log's file inside its data section: each cut reads back as
    the closed log's first frames, up to the last stamp in the whole chunks (its frame left out as
    possibly incomplete: the chunk indexes of the closed file say where that is), and replays with a
    note saying so."""
    from mcap.reader import make_reader

    from eval.ros.reader import RecordingError, open_recording

    n = 8
    _full_frame_log(tmp_path / "full", "mcap", n)
    full = open_recording(tmp_path / "full")
    want = list(full.frames())
    assert len(want) == n and not any("never closed" in note for note in full.notes)
    stored = next((tmp_path / "full").glob("*.mcap"))
    with open(stored, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    data = stored.read_bytes()
    assert len(chunks) >= 4
    stamps = [START_NS + round(0.1 * i * 1e9) for i in range(n)]
    # a chunk holds a frame and a half: cut inside each chunk from the third (the first frame whole before
    # it) to the last but one
    for c in chunks[2:-1]:
        cut = c.chunk_start_offset + c.chunk_length // 2
        folder = tmp_path / f"cut{cut}"
        folder.mkdir()
        (folder / "cut_0.mcap").write_bytes(data[:cut])
        rec = open_recording(folder)
        got = list(rec.frames())
        assert any(note.startswith(f"{folder}: a recording never closed") for note in rec.notes), rec.notes
        # the messages of the last stamp in the whole chunks are left out
        last = max(x.message_end_time for x in chunks if x.chunk_start_offset + x.chunk_length <= cut)
        assert len(got) == sum(s < last for s in stamps) > 0
        for g, f in zip(got, want[: len(got)], strict=True):
            assert g.timestamp_s == f.timestamp_s
            assert np.array_equal(g.rgb, f.rgb) and np.array_equal(g.depth_m, f.depth_m)
            assert np.allclose(g.pose, f.pose, atol=1e-12)
    # cut inside the second chunk: the depth camera info's channel was not written yet, and the error says why
    cut = chunks[1].chunk_start_offset + chunks[1].chunk_length // 2
    (tmp_path / "early").mkdir()
    (tmp_path / "early" / "early_0.mcap").write_bytes(data[:cut])
    with pytest.raises(RecordingError, match=r"no camera info.*\(a recording never closed or cut short"):
        open_recording(tmp_path / "early")
    assert main(["replay", str(folder), "--out", str(tmp_path / "r"), "--quiet", "--no-video"]) == 0
    assert f"{folder}: a recording never closed" in capsys.readouterr().err


def test_a_killed_runs_bag_log_replays_up_to_where_it_stopped(tmp_path, capsys, monkeypatch):
    """A ROS 1 bag whose run was killed has no index (its header's index_pos still 0) or, cut, one past
    its end: cut a closed 8-frame bag inside its chunks (rosbags closes a chunk past 1 MiB), each cut
    reads back as its first frames, up to the last stamp in the whole chunks (the closed bag's chunk
    infos, read by rosbags, say where they end), that stamp's frame left out; and a bag whose header
    still says index_pos 0 reads the same."""
    from rosbags.rosbag1 import Reader

    from eval.ros.reader import open_recording

    n = 8
    _full_frame_log(tmp_path / "full.bag", "bag", n)
    want = list(open_recording(tmp_path / "full.bag").frames())
    with Reader(tmp_path / "full.bag") as r:
        chunks = [(c.pos, c.end_time - 1) for c in r.chunk_infos]  # end_time: one past the last stamp
    data = (tmp_path / "full.bag").read_bytes()
    stamps = [START_NS + round(0.1 * i * 1e9) for i in range(n)]
    assert len(chunks) >= 4
    for j in range(2, len(chunks) - 1):
        cut = chunks[j][0] + 1000  # inside chunk j: chunks 0 .. j - 1 whole
        bag = tmp_path / f"cut{j}.bag"
        bag.write_bytes(data[:cut])
        rec = open_recording(bag)
        got = list(rec.frames())
        assert any(note.startswith(f"{bag}: a recording never closed (no index") for note in rec.notes), rec.notes
        last = max(end for _, end in chunks[:j])
        assert len(got) == sum(s < last for s in stamps) > 0
        for g, f in zip(got, want[: len(got)], strict=True):
            assert g.timestamp_s == f.timestamp_s
            assert np.array_equal(g.rgb, f.rgb) and np.array_equal(g.depth_m, f.depth_m)
            assert np.allclose(g.pose, f.pose, atol=1e-12)
    # as a killed run leaves it: the header's index_pos never written (0), the file whole up to the index
    index_pos = data.index(b"index_pos=") + len(b"index_pos=")
    unindexed = bytearray(data)
    unindexed[index_pos : index_pos + 8] = bytes(8)
    (tmp_path / "killed.bag").write_bytes(bytes(unindexed))
    scans = _count_scans(monkeypatch)
    got = list(open_recording(tmp_path / "killed.bag").frames())
    assert len(got) == n - 1 and all(np.array_equal(g.rgb, f.rgb) for g, f in zip(got, want, strict=False))
    # the file read three times, as a closed log is read twice plus the scan for its connections and
    # last stamp: opening it finds them once, and reading the frames uses what it found
    assert scans == [1, 1, 1]
    assert (
        main(["replay", str(tmp_path / "killed.bag"), "--out", str(tmp_path / "r"), "--quiet", "--no-video"]) == 0
    )
    assert "a recording never closed (no index" in capsys.readouterr().err
