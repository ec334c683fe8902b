"""What ``poibench run --log mcap`` costs a frame with each ``--log-images`` mode, and whether a
replay of each log gives the raw log's pois.csv.

The default trial (the shipped scenario and detector) runs ``--max-frames`` frames (default 60)
once per mode (raw, png, jpeg), each writing ``trial_mcap/``; printed per mode: the log's bytes
a frame (the MCAP file over the frames), the log writer thread's CPU milliseconds a frame (as
``poibench run`` reports it) and whether ``poibench replay`` of the log, with the trial's
config, writes the same pois.csv as the replay of the raw log (byte for byte; otherwise the
lines that differ). Then, on the raw log's frames, the bytes and CPU milliseconds (process
time) a frame for colour and depth of each PNG zlib level with zlib's default strategy, and
of the settings ``eval.ros.compression`` uses (Huffman coding only, one row filter).
Run: ``MUJOCO_GL=egl python bench/bench_log.py [--frames 60] [--modes raw,png] [--no-levels]``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from eval.cli.main import main

MODES = ("raw", "png", "jpeg")
PNG_LEVELS = (1, 3, 6)  # 9: colour as 6, depth 12x the CPU of 6 for 3% fewer bytes


def _quiet_main(argv: list[str]) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    if rc != 0:
        raise SystemExit(f"poibench {' '.join(argv)}: exit {rc}")
    return buf.getvalue()


def _log_bytes(trial: Path) -> int:
    return sum(f.stat().st_size for f in (trial / "trial_mcap").iterdir() if f.suffix == ".mcap")


def _png_levels(trial: Path, frames: int) -> None:
    from eval.ros.reader import open_recording
    from poi.core.depth_units import to_z16

    rec = open_recording(trial / "trial_mcap")
    images = [(f.rgb[..., ::-1].copy(), to_z16(f.depth_m)) for f in rec.frames()][:frames]
    print(f"\nPNG level on {len(images)} frames: bytes and CPU ms a frame (colour | depth)")
    from eval.ros.compression import COLOUR_PNG, DEPTH_PNG

    settings = [
        (f"level {v}", [cv2.IMWRITE_PNG_COMPRESSION, v], [cv2.IMWRITE_PNG_COMPRESSION, v]) for v in PNG_LEVELS
    ]
    for name, colour_params, depth_params in [*settings, ("poibench", COLOUR_PNG, DEPTH_PNG)]:
        sizes = np.zeros(2)
        cpu = np.zeros(2)
        for bgr, z in images:
            for k, (img, params) in enumerate(((bgr, colour_params), (z, depth_params))):
                c0 = time.process_time()
                ok, buf = cv2.imencode(".png", img, params)
                cpu[k] += time.process_time() - c0
                sizes[k] += buf.size
        n = len(images)
        print(
            f"  {name:8s}: colour {sizes[0] / n / 1e3:7.1f} kB {1e3 * cpu[0] / n:6.1f} ms | "
            f"depth {sizes[1] / n / 1e3:7.1f} kB {1e3 * cpu[1] / n:6.1f} ms"
        )


def run(frames: int, modes: tuple[str, ...] = MODES, levels: bool = True) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        replays: dict[str, bytes] = {}
        for mode in modes:
            trial = root / f"t_{mode}"
            out = _quiet_main(
                ["run", "--max-frames", str(frames), "--no-video", "--no-live-record", "--quiet"]
                + ["--log", "mcap", "--log-images", mode, "--out", str(trial)]
            )
            m = re.search(r"ROS log .*?: (\d+) frames?, ([\d.]+) ms CPU a frame", out)
            n, cpu_ms = (int(m[1]), float(m[2])) if m else (frames, float("nan"))
            size = _log_bytes(trial)
            r = root / f"r_{mode}"
            _quiet_main(
                ["replay", str(trial / "trial_mcap"), "--config", str(trial / "config.yaml")]
                + ["--out", str(r), "--quiet", "--no-video", "--no-live-record"]
            )
            replays[mode] = (r / "pois.csv").read_bytes()
            same = replays[mode] == replays["raw"]
            diff = ""
            if not same:
                a, b = replays["raw"].splitlines(), replays[mode].splitlines()
                diff = f" ({sum(x != y for x, y in zip(a, b, strict=False)) + abs(len(a) - len(b))} lines differ)"
            print(
                f"{mode:5s}: {size / n / 1e6:6.3f} MB a frame ({size / 1e6:.1f} MB, {n} frames), writer "
                f"{cpu_ms:5.1f} ms CPU a frame; replay pois.csv {'== raw' if same else '!= raw'}{diff}"
            )
            if not same:  # each line that differs, the raw log's replay's first
                for x, y in zip(replays["raw"].splitlines(), replays[mode].splitlines(), strict=False):
                    if x != y:
                        print(f"         raw:  {x.decode()}\n         {mode}: {y.decode()}")
        if levels:
            _png_levels(root / "t_raw", frames)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60, help="frames of the default trial (default 60)")
    ap.add_argument("--no-levels", action="store_true", help="skip the PNG levels")
    ap.add_argument("--modes", default=",".join(MODES), help="raw first, then any of png, jpeg (default all)")
    args = ap.parse_args()
    run(args.frames, tuple(args.modes.split(",")), not args.no_levels)
