"""Milliseconds per frame for the simulated sensors at 640x480 on the RRL example maze.

Prints the render passes (colour and depth share one rasterisation; the
segmentation pass runs at full size for ground-truth boxes and at twice the
thermal resolution for the thermal camera), the whole sensor set (noisy colour
+ aligned noisy depth + thermal + pose) per frame, and the same with per-frame
ground-truth boxes. Run: ``python bench/bench_sim.py``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

# isort: off
import sim.gl  # noqa: F401  (chooses MUJOCO_GL before mujoco is imported)
import mujoco

# isort: on
from sim.scenario import apply_settings, load_scenario  # noqa: E402
from sim.simulator import Simulation  # noqa: E402
from sim.world import CAMERA_NAME  # noqa: E402


def _ms(fn, n):
    fn()  # warm up
    t = time.perf_counter()
    for i in range(n):
        fn(i)
    return (time.perf_counter() - t) / n * 1e3


def _stream_ms(sim: Simulation, n: int) -> float:
    """ms per frame through ``frames()``, over n frames spread along the route as ``_ms`` uses."""
    step = max(1, (sim.n_frames - 1) // max(n - 1, 1))
    t = time.perf_counter()
    count = sum(1 for _ in sim.frames(0, sim.n_frames, step))
    return (time.perf_counter() - t) / count * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--maze", default="rrl_arena")
    args = ap.parse_args()
    sc = apply_settings(load_scenario("default"), [f"maze.file={args.maze}"])
    n = args.frames
    with Simulation(sc) as s:
        ks = np.linspace(0, s.n_frames - 1, n).astype(int)
        r = s.on_gl_thread(s._renderer_ready)
        d = s.world.data
        th = sc.sensors.thermal

        def on_gl(fn, i):
            def job():
                s._set_camera(int(ks[i % n]))
                r.update(d)
                fn()

            s.on_gl_thread(job)

        H, W = s.intrinsics.height, s.intrinsics.width
        ref = s.on_gl_thread(lambda: mujoco.Renderer(s.world.model, H, W))

        def ref_pass(mode):
            def fn():
                getattr(ref, f"enable_{mode}_rendering")() if mode else None
                ref.update_scene(d, CAMERA_NAME)
                ref.render()
                getattr(ref, f"disable_{mode}_rendering")() if mode else None

            return fn

        res = {
            "colour render (mujoco.Renderer, for reference)": _ms(lambda i=0: on_gl(ref_pass(None), i), n),
            "depth render (mujoco.Renderer, for reference)": _ms(lambda i=0: on_gl(ref_pass("depth"), i), n),
            "segmentation (mujoco.Renderer, for reference)": _ms(
                lambda i=0: on_gl(ref_pass("segmentation"), i), n
            ),
            "colour + depth render (one pass)": _ms(lambda i=0: on_gl(r.color_depth, i), n),
            "segmentation render 640x480": _ms(lambda i=0: on_gl(r.geom_segmentation, i), n),
            f"segmentation render {2 * th.width}x{2 * th.height} (thermal)": _ms(
                lambda i=0: on_gl(lambda: r.geom_segmentation(2 * th.width, 2 * th.height), i), n
            ),
        }
        s.on_gl_thread(ref.close)
        sensors = apply_settings(sc, ["sensors.truth_boxes=false"])
    with Simulation(sensors) as s2:
        ks2 = np.linspace(0, s2.n_frames - 1, n).astype(int)
        res["whole sensor set (colour+depth+thermal+pose)"] = _ms(lambda i=0: s2.frame(int(ks2[i % n])), n)
        res["  the same, streamed (frames() renders ahead)"] = _stream_ms(s2, n)
    with Simulation(sc) as s3:
        ks3 = np.linspace(0, s3.n_frames - 1, n).astype(int)
        res["sensor set + ground-truth boxes"] = _ms(lambda i=0: s3.frame(int(ks3[i % n])), n)
        res["  the same, streamed"] = _stream_ms(s3, n)
        print(
            f"maze {args.maze}: {s3.maze.rows}x{s3.maze.cols} cells, {len(s3.maze.wall_segments())} wall pieces, "
            f"{len(s3.objects)} objects, 640x480"
        )
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"MUJOCO_GL={os.environ.get('MUJOCO_GL')}, mujoco {mujoco.__version__}"
    )
    for k, v in res.items():
        print(f"{k:48s} {v:7.2f} ms/frame")


if __name__ == "__main__":
    main()
