"""CPU seconds of sweeps and tuning with and without the perception cache, in one run.

Prints, each as CPU seconds of the command's processes (their own and their children's,
``resource.getrusage``: the spawned trial workers included), measured, not wall time (the
machine is shared):

1. a 3 x 3 sweep of ``tracker.gate`` x ``tracker.n_min`` on the ``smoke`` suite, with
   ``--no-cache`` and with a cold cache (an empty ``--cache`` folder), and whether their rows
   are the same (every column but the cost ones);
2. a 30-trial ``tune`` of the same two settings on ``smoke`` with a cold cache, against the
   same tune without the cache: run with ``--full-tune`` (it renders 60 trials, about 45 CPU
   minutes), else estimated as 60 times the mean CPU of a trial of the no-cache sweep (a tune
   trial without the cache is such a trial);
3. one trial of ``smoke-1`` run in full against the same trial replayed from the cache
   (``cost.json``'s CPU seconds, in this process).

Run: ``python bench/bench_sweep.py`` (``--workers 2`` by default; ``--keep DIR`` keeps the
folders). See eval/trial/perception_cache.py.
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

GRID = ["--set", "tracker.gate=4,9,16", "--set", "tracker.n_min=2,3,4"]
PARAMS = ["--param", "tracker.gate=float:2:20", "--param", "tracker.n_min=int:1:5"]
COST_COLUMNS = ("wall_s", "cpu_s", "cpu_s_per_sim_s")
TUNE_TRIALS = 30


def cpu_of(cmd: list[str]) -> float:
    """CPU seconds (user + system) of a command and its children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def poibench(*args: str) -> list[str]:
    return [sys.executable, "-m", "eval.cli.main", *args]


def rows_without_cost(path: Path):
    from eval.experiments.sweep import read_rows

    df = read_rows(path)
    return df.drop(columns=[c for c in COST_COLUMNS if c in df]).sort_values("trial").reset_index(drop=True)


def uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "uptime unavailable"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--full-tune", action="store_true", help="run the tune without the cache too (slow)")
    ap.add_argument("--keep", help="keep the sweep, tune and cache folders here")
    args = ap.parse_args()
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; workers {args.workers}")
    print(f"start: {uptime()}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep) if args.keep else Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        w = ["--workers", str(args.workers), "--quiet"]

        full = cpu_of(
            poibench("sweep", "--suite", "smoke", *GRID, "--out", str(root / "sweep_full"), "--no-cache", *w)
        )
        cold = cpu_of(
            poibench(
                "sweep",
                "--suite",
                "smoke",
                *GRID,
                "--out",
                str(root / "sweep_cold"),
                "--cache",
                str(root / "c1"),
                *w,
            )
        )
        a, b = (
            rows_without_cost(root / "sweep_full" / "trials.csv"),
            rows_without_cost(root / "sweep_cold" / "trials.csv"),
        )
        same = a.equals(b)
        n = len(a)
        print(
            f"sweep 3x3 on smoke ({n} trials): no cache {full:.1f} CPU-s, cold cache {cold:.1f} CPU-s: "
            f"{full / cold:.1f}x less; rows identical: {same}",
            flush=True,
        )

        tuned = cpu_of(
            poibench(
                "tune", "--suite", "smoke", *PARAMS, "--trials", str(TUNE_TRIALS), "--seed", "0",
                "--out", str(root / "tune_cold"), "--cache", str(root / "c2"), *w,
            )
        )  # fmt: skip
        if args.full_tune:
            tune_full = cpu_of(
                poibench(
                    "tune", "--suite", "smoke", *PARAMS, "--trials", str(TUNE_TRIALS), "--seed", "0",
                    "--out", str(root / "tune_full"), "--no-cache", *w,
                )
            )  # fmt: skip
            how = "measured"
        else:
            tune_full = full / n * TUNE_TRIALS * 2  # two scenarios per tune trial
            how = f"estimated: {TUNE_TRIALS * 2} x the no-cache sweep's {full / n:.1f} CPU-s per trial"
        print(
            f"tune, {TUNE_TRIALS} trials on smoke: no cache {tune_full:.1f} CPU-s ({how}), cold cache "
            f"{tuned:.1f} CPU-s: {tune_full / tuned:.1f}x less",
            flush=True,
        )

        from eval.experiments.suites import load_suite
        from eval.scoring.rules import load_rules
        from eval.trial.perception_cache import PerceptionCache
        from eval.trial.run import run_trial

        suite = load_suite("smoke")
        sc = suite.build(suite.scenarios[0])
        kw = dict(detector="default", rules=load_rules("ex3"), rules_name="ex3", video=False, progress=False)
        one_full = run_trial(sc, root / "one_full", record_live=False, **kw)
        one_replay = run_trial(
            sc, root / "one_replay", record_live=False, perception_cache=PerceptionCache(root / "c1"), **kw
        )
        same_one = all(
            (root / "one_full" / f).read_bytes() == (root / "one_replay" / f).read_bytes()
            for f in ("pois.csv", "score.json")
        )
        a, b = one_full.cost, one_replay.cost
        print(
            f"one trial ({sc.name}, {one_full.sim_duration_s:.0f} simulated s): full {a.cpu_s:.2f} CPU-s "
            f"({a.cpu_s_per_sim_s:.3f} per simulated s), replayed {b.cpu_s:.2f} CPU-s "
            f"({b.cpu_s_per_sim_s:.4f} per simulated s): {a.cpu_s / b.cpu_s:.1f}x less; "
            f"pois.csv and score.json identical: {same_one}"
        )
        size = sum(p.stat().st_size for p in (root / "c1").glob("*.pcache")) / 1e6
        print(f"cache: {size:.0f} MB for the suite's 2 scenarios")
    print(f"end: {uptime()}")


if __name__ == "__main__":
    main()
