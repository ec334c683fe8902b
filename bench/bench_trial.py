"""CPU seconds per simulated second and real-time factor of a default trial, with where the CPU goes.

Runs ``poibench run`` on the built-in default scenario at 10 camera frames per
simulated second with the default detector (``--detector oracle`` for the
oracle), writing everything ``poibench run`` writes, the video included
(``--no-video`` leaves it out). Prints:

* the CPU seconds of the process (every thread) and of its children (the ffmpeg
  encoders), ``resource.getrusage`` ``RUSAGE_SELF`` + ``RUSAGE_CHILDREN``, per
  simulated second: the figure issue 62 sets targets for (at most 0.40 with the
  shipped detector, 0.30 with the oracle); wall time is noisy on a shared machine;
* the real-time factor measured (simulated over wall seconds) and the one two idle
  cores would allow at that CPU cost (2 / CPU-s per simulated second: an upper bound);
* the CPU per frame of each thread: the OpenGL thread and Mesa's llvmpipe
  rasteriser threads (rendering), the sensor-model thread (colour, depth and thermal
  models, truth boxes), the main thread (detector, pipeline, outputs, and the
  start: world build and imports) and the children (video and live-record ffmpeg),
  read from ``/proc/self/task`` once a second (Linux only; left out elsewhere).

Run: ``python bench/bench_trial.py [--detector oracle] [--no-video] [--no-record] [--max-frames N]
[--set KEY=VALUE ...]``
(``--max-frames 300``: the first 300 frames, a quick look at the per-frame figures; the start's
share of the main thread is then larger).
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import tempfile
import threading
from pathlib import Path

from eval.scoring.rules import load_rules
from eval.trial.run import run_trial
from sim.scenario import apply_settings, load_scenario

TARGET_CPU_PER_SIM_S = {"default": 0.40, "oracle": 0.30}  # issue 62


def _cpu_s(who: int) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


class ThreadCpu:
    """The CPU seconds of each thread of this process, sampled from ``/proc/self/task`` every
    ``period_s`` (a thread's last sample is kept after it exits): {name: seconds}."""

    def __init__(self, period_s: float = 1.0) -> None:
        self._seen: dict[int, tuple[str, float]] = {}
        self._stop = threading.Event()
        self._tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
        self._thread = threading.Thread(target=self._run, args=(period_s,), name="bench sampler", daemon=True)
        self.available = Path("/proc/self/task").is_dir()

    def _sample(self) -> None:
        names = {t.native_id: t.name for t in threading.enumerate()}
        for tid in os.listdir("/proc/self/task"):
            try:
                stat = Path(f"/proc/self/task/{tid}/stat").read_text()
            except OSError:  # the thread exited meanwhile
                continue
            comm = stat[stat.index("(") + 1 : stat.rindex(")")]
            fields = stat[stat.rindex(")") + 2 :].split()  # fields 14, 15: utime, stime (proc(5))
            self._seen[int(tid)] = (names.get(int(tid), comm), (int(fields[11]) + int(fields[12])) / self._tick)

    def _run(self, period_s: float) -> None:
        while not self._stop.wait(period_s):
            self._sample()

    def start(self) -> ThreadCpu:
        if self.available:
            self._sample()
            self._thread.start()
        return self

    def stop(self) -> dict[str, float]:
        if self.available:
            self._stop.set()
            self._thread.join()
            self._sample()
        out: dict[str, float] = {}
        for name, s in self._seen.values():
            group = "llvmpipe (rendering)" if name.startswith("llvmpipe") else name
            out[group] = out.get(group, 0.0) + s
        return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--detector", default="default", help="default | oracle | FILE.onnx (default: default)")
    ap.add_argument("--no-video", action="store_true", help="do not write trial.mp4")
    ap.add_argument(
        "--no-record",
        action="store_true",
        help="leave out the live record (the replayable live view and its H.264 insets)",
    )
    ap.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    ap.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario setting; repeatable"
    )
    ap.add_argument(
        "--live", action="store_true", help="serve the live view with a headless Chromium page open on it"
    )
    args = ap.parse_args()
    sc = apply_settings(load_scenario("default"), ["sensors.fps=10", *args.set])
    server = browser = pw = None
    if args.live:
        import shutil

        from playwright.sync_api import sync_playwright

        from eval.live.server import LiveServer

        server = LiveServer(0)
        url = server.start()
        pw = sync_playwright().start()
        browser = pw.chromium.launch(executable_path=shutil.which("chromium"), args=["--no-sandbox"])
        browser.new_page().goto(url)
    load0 = os.getloadavg()
    self0, children0 = _cpu_s(resource.RUSAGE_SELF), _cpu_s(resource.RUSAGE_CHILDREN)
    threads = ThreadCpu().start()
    with tempfile.TemporaryDirectory() as d:
        r = run_trial(
            sc,
            d,
            detector=args.detector,
            rules=load_rules("ex3"),
            rules_name="ex3",
            video=not args.no_video,
            record_live=not args.no_record,
            progress=False,
            live_server=server,
            max_frames=args.max_frames,
        )
    per_thread = threads.stop()
    cpu_self = _cpu_s(resource.RUSAGE_SELF) - self0
    cpu_children = _cpu_s(resource.RUSAGE_CHILDREN) - children0
    load1 = os.getloadavg()
    if server is not None:
        browser.close()
        pw.stop()
        server.stop()
    video = "with" if not args.no_video else "without"
    record = ", no live record" if args.no_record else ""
    live = "; live view open in Chromium" if args.live else ""
    cpu = cpu_self + cpu_children
    per_sim = cpu / r.sim_duration_s
    print(
        f"machine: {platform.machine()}, {os.cpu_count()} cores, load average {load0[0]:.1f} at the start, "
        f"{load1[0]:.1f} at the end; detector {r.detector}; {video} video{record}{live}"
    )
    print(
        f"frames {r.n_frames}, simulated {r.sim_duration_s:.1f} s, wall {r.cost.wall_s:.1f} s, "
        f"real-time factor {r.cost.real_time_factor:.2f}x, score {r.score.total:g}/{r.score.max_total:g}"
    )
    target = TARGET_CPU_PER_SIM_S.get(args.detector)
    aim = f" (target {target:.2f})" if target is not None else ""
    print(
        f"CPU {cpu:.1f} s (process {cpu_self:.1f} + children {cpu_children:.1f}): "
        f"{per_sim:.3f} CPU-s per simulated second{aim}, {1000 * cpu / max(r.n_frames, 1):.1f} ms a frame; "
        f"at most {2.0 / per_sim:.2f}x real time on 2 idle cores"
    )
    if per_thread:
        print("CPU per frame by thread (the main thread's includes the start: imports and world build):")
        rows = sorted(per_thread.items(), key=lambda kv: -kv[1]) + [("children (ffmpeg)", cpu_children)]
        for name, s in rows:
            if s >= 0.05:
                print(f"  {name:28s} {s:8.1f} s  {1000 * s / max(r.n_frames, 1):7.1f} ms a frame")


if __name__ == "__main__":
    main()
