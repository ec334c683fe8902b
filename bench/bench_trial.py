"""Wall time and real-time factor of a default trial (simulated seconds per wall second).

Runs ``poibench run`` on the built-in default scenario at 10 camera frames per
simulated second with the default detector (the oracle until a trained model
ships), without and with the video. Run: ``python bench/bench_trial.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile

from eval.rules import load_rules
from eval.trial import run_trial
from sim.scenario import apply_settings, load_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--detector", default="default")
    ap.add_argument("--video", action="store_true", help="also write trial.mp4")
    args = ap.parse_args()
    sc = apply_settings(load_scenario("default"), ["sensors.fps=10"])
    with tempfile.TemporaryDirectory() as d:
        r = run_trial(
            sc,
            d,
            detector=args.detector,
            rules=load_rules("ex3"),
            rules_name="ex3",
            video=args.video,
            progress=False,
        )
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; detector {r.detector}; video {args.video}")
    print(
        f"frames {r.n_frames}, simulated {r.sim_duration_s:.1f} s, wall {r.wall_s:.1f} s, "
        f"real-time factor {r.real_time_factor:.2f}x, score {r.score.total:g}/{r.score.max_total:g}"
    )


if __name__ == "__main__":
    main()
