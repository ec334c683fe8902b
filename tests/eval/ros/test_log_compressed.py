"""`poibench run --log-images png`: colour and depth as sensor_msgs/CompressedImage, read back by
the replay as the raw log is, into the same pois.csv; and the codecs' round trips."""

from __future__ import annotations

import struct
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from eval.cli.main import main
from eval.ros.compression import (
    DEPTH_HEADER,
    CodecError,
    decode_colour,
    decode_depth,
    encode_colour,
    encode_depth,
)
from eval.ros.messages import MessageError, colour_of, compressed_image_msg, depth_of, typestore

DETECTORS = Path(__file__).resolve().parents[2] / "poi" / "detectors"  # red_detector.py
RED = "python:red_detector:RedBlobDetector"
# the sweeping tour of rrl_small: its first frames drive past the objects (as tests/eval/ros/test_log.py)
SCENE = [
    "--set",
    "maze.file=rrl_small",
    "--set",
    "objects.generate.counts={fire-extinguisher: 2, valve: 1}",
    "--set",
    "robot.pan.mode=sweep",
]
FRAMES = 30


def _rng() -> np.random.Generator:
    return np.random.default_rng(62)


def test_depth_round_trips_exactly_through_compressed_depth():
    rng = _rng()
    z = rng.integers(0, 65536, size=(48, 64), dtype=np.uint16)  # (H, W) millimetres, every value possible
    z[0, :2] = (0, 65535)  # no depth and the largest count
    e = encode_depth(z)
    assert e.format == "16UC1; compressedDepth png"
    # the header as compressed_depth_image_transport writes it for 16UC1: INV_DEPTH, no quantisation
    assert DEPTH_HEADER.unpack_from(e.data) == (0, 0.0, 0.0) and e.data[12:16] == b"\x89PNG"
    back = decode_depth(e.data, e.format, "/d")
    assert back.dtype == np.uint16 and np.array_equal(back, z)
    # a bare 16-bit PNG (the compressed plugin's way) reads the same
    assert np.array_equal(decode_depth(e.data[12:], "16UC1; png compressed mono16", "/d"), z)


def test_colour_png_is_lossless_and_jpeg_is_close():
    rng = _rng()
    rgb = rng.integers(0, 256, size=(48, 64, 3), dtype=np.uint8)  # (H, W, 3) noise: the hardest case
    png = encode_colour(rgb, "png")
    assert png.format == "rgb8; png compressed bgr8"
    assert np.array_equal(decode_colour(png.data, png.format, "/c"), rgb)
    smooth = np.repeat(np.linspace(0, 255, 64, dtype=np.uint8)[None, :, None], 48, axis=0).repeat(3, axis=2)
    jpg = encode_colour(smooth, "jpeg")
    assert jpg.format == "rgb8; jpeg compressed bgr8" and jpg.data[:2] == b"\xff\xd8"
    # quality 90 on a smooth ramp: within a few counts of 255 (lossy, so not exact)
    err = np.abs(decode_colour(jpg.data, jpg.format, "/c").astype(int) - smooth.astype(int))
    assert err.max() <= 4


def test_bad_compressed_images_are_one_line_errors():
    with pytest.raises(CodecError, match=r"^/c: a compressed colour image .* that OpenCV cannot decode"):
        decode_colour(b"not an image", "rgb8; png compressed bgr8", "/c")
    rvl = struct.pack("<iff", 0, 0.0, 0.0) + b"\x00" * 20
    with pytest.raises(CodecError, match=r"^/d: compressedDepth '16UC1; compressedDepth rvl'; only its PNG"):
        decode_depth(rvl, "16UC1; compressedDepth rvl", "/d")
    with pytest.raises(CodecError, match="only 16UC1 depth is read"):
        decode_depth(rvl, "32FC1; compressedDepth png", "/d")
    colour_png = encode_colour(np.zeros((4, 4, 3), np.uint8), "png")
    with pytest.raises(CodecError, match="expected one 16-bit channel"):
        decode_depth(colour_png.data, "16UC1; png compressed mono16", "/d")
    with pytest.raises(CodecError, match="colour codec 'webp'"):
        encode_colour(np.zeros((4, 4, 3), np.uint8), "webp")


@pytest.mark.parametrize("ros1", [False, True])
def test_compressed_messages_serialise_and_decode_in_both_dialects(ros1):
    ts = typestore(ros1=ros1)
    rng = _rng()
    rgb = rng.integers(0, 256, size=(6, 8, 3), dtype=np.uint8)
    z = rng.integers(0, 5000, size=(6, 8), dtype=np.uint16)
    ser, de = (ts.serialize_ros1, ts.deserialize_ros1) if ros1 else (ts.serialize_cdr, ts.deserialize_cdr)
    kind = "sensor_msgs/msg/CompressedImage"
    c = de(ser(compressed_image_msg(ts, 5, "cam", encode_colour(rgb, "png")), kind), kind)
    d = de(ser(compressed_image_msg(ts, 5, "cam", encode_depth(z)), kind), kind)
    assert np.array_equal(colour_of(c, "/c/compressed"), rgb)
    assert np.array_equal(depth_of(d, "/d/compressedDepth"), z.astype(np.float32) / 1000.0)
    with pytest.raises(MessageError, match="^/c/compressed: a compressedDepth image"):
        colour_of(d, "/c/compressed")


# ----------------------------------------------------------------------- a trial logged both ways


def _trial(tmp: Path, images: str) -> Path:
    import red_detector

    tmp.mkdir(parents=True, exist_ok=True)
    weights = red_detector.write_weights(tmp / "red.npz")
    out = tmp / f"t_{images}"
    argv = ["run", "--detector", RED, "--set", f"detector.options.weights={weights}", "--log", "mcap"]
    argv += ["--log-images", images, "--max-frames", str(FRAMES), "--no-video", "--quiet", "--out", str(out)]
    assert main([*argv, *SCENE]) == 0
    return out


def _replay(trial: Path, out: Path) -> Path:
    argv = ["replay", str(trial / "trial_mcap"), "--config", str(trial / "config.yaml")]
    assert main([*argv, "--truth", str(trial / "truth.csv"), "--out", str(out), "--quiet", "--no-video"]) == 0
    return out


def _topics(log: Path) -> dict[str, str]:
    from rosbags.highlevel import AnyReader

    with AnyReader([log]) as r:
        return {c.topic: c.msgtype for c in r.connections}


@pytest.mark.slow
def test_a_compressed_log_replays_into_the_raw_logs_pois_csv(tmp_path, capsys):
    sys.path.insert(0, str(DETECTORS))
    try:
        raw, png = _trial(tmp_path / "r", "raw"), _trial(tmp_path / "p", "png")
        topics = _topics(png / "trial_mcap")
        assert topics["/camera/color/image_raw/compressed"] == "sensor_msgs/msg/CompressedImage"
        assert (
            topics["/camera/aligned_depth_to_color/image_raw/compressedDepth"] == "sensor_msgs/msg/CompressedImage"
        )
        assert "/camera/color/image_raw" not in topics and "/camera/aligned_depth_to_color/image_raw" not in topics
        # the two trials are the same trial: the images differ only in how they are stored
        assert (raw / "pois.csv").read_bytes() == (png / "pois.csv").read_bytes()
        a, b = _replay(raw, tmp_path / "ra"), _replay(png, tmp_path / "pa")
    finally:
        sys.path.remove(str(DETECTORS))
    replayed = (b / "pois.csv").read_bytes()
    assert replayed == (a / "pois.csv").read_bytes()
    assert len(replayed.splitlines()) >= 9  # the header lines and at least one object
    size = {
        k: sum(f.stat().st_size for f in (t / "trial_mcap").iterdir()) for k, t in (("raw", raw), ("png", png))
    }
    assert size["png"] < 0.75 * size["raw"], size
    assert "error" not in capsys.readouterr().err


def test_log_images_without_a_log_is_refused(tmp_path, capsys):
    assert main(["run", "--log-images", "png", "--max-frames", "1", "--out", str(tmp_path / "t")]) == 2
    assert capsys.readouterr().err.strip().endswith("error: --log-images png needs --log mcap|bag")
    assert not (tmp_path / "t" / "pois.csv").exists()


def test_a_bad_log_topic_is_named_by_its_flag(tmp_path, capsys):
    argv = ["run", "--log", "mcap", "--log-topic", "nosuch=/x", "--max-frames", "1", "--out", str(tmp_path / "t")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error: --log-topic nosuch=/x: unknown stream 'nosuch'; expected one of")
    assert not (tmp_path / "t" / "pois.csv").exists()
