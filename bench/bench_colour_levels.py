"""Placard whites, backgrounds, exposure and motion blur on the simulated D435 colour stream.

Renders every ~1/60 of the default scenario's frames (the trial ``poibench run`` runs) and
reports, for each hazmat placard and QR code in view with at least 400 pixels, the 90th
percentile of its pixels' grey level (its white paper), the median grey level of the pixels
that belong to no object, and the auto-exposure's exposure and gain and the motion blur's
length on every 5th frame. Compare the whites with real photos of printed placards
(docs/FACTS.md "D435 colour camera"). Run: ``python bench/bench_colour_levels.py
[--set key=value ...]``.
"""

from __future__ import annotations

import argparse

import numpy as np

import sim.gl  # noqa: F401  (chooses MUJOCO_GL before mujoco is imported)
from sim.scenario import apply_settings, load_scenario
from sim.simulator import Simulation

MIN_PIXELS = 400


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--set", action="append", default=[], help="a scenario setting key=value")
    ap.add_argument("--frames", type=int, default=60)
    args = ap.parse_args()
    sc = apply_settings(load_scenario("default"), args.set)
    whites, backgrounds, exposures, blur = [], [], [], []
    with Simulation(sc) as s:
        for k in range(0, s.n_frames, max(1, s.n_frames // args.frames)):
            f, t = s.frame(k)
            grey = f.rgb.astype(np.float32).mean(axis=2)
            for v in t.visible:
                if v.type in ("hazmat", "qr") and v.pixels >= MIN_PIXELS:
                    whites.append(np.percentile(grey[t.object_mask == v.id], 90))
            if (t.object_mask < 0).any():  # a close view an object fills has no background
                backgrounds.append(np.median(grey[t.object_mask < 0]))
        for k in range(0, s.n_frames, 5):
            raw = s.on_gl_thread(s._render_colour_depth, k)
            e = s.exposure(k, raw.rgb)
            exposures.append((e.exposure_ms, e.gain))
            blur.append(np.hypot(*s.motion_px(k, e.exposure_ms, raw.z_m)))
    w, ex = np.array(whites), np.array(exposures)
    print(
        f"placard whites (p90 of each of {len(w)} placards and QR codes): mean {w.mean():.1f}, "
        f"p10/p50/p90 {np.percentile(w, [10, 50, 90]).round(1)}"
    )
    print(f"non-object median grey level, mean over {len(backgrounds)} frames: {np.mean(backgrounds):.1f}")
    print(
        f"exposure ms p10/p50/p90 {np.percentile(ex[:, 0], [10, 50, 90]).round(2)}, "
        f"gain p10/p50/p90 {np.percentile(ex[:, 1], [10, 50, 90]).round(2)}"
    )
    print(f"motion blur px p10/p50/p90 {np.percentile(blur, [10, 50, 90]).round(1)}, max {max(blur):.1f}")


if __name__ == "__main__":
    main()
