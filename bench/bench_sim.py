"""Milliseconds per frame for the simulated sensors at 640x480 on the RRL example maze.

Prints the render passes (colour and depth share one rasterisation; one
full-size segmentation pass serves the ground-truth boxes and the thermal
camera), the whole sensor set (noisy colour
+ aligned noisy depth + thermal + pose) per frame, and the same with per-frame
ground-truth boxes, and the cost of each colour-camera effect alone
(sim/sensors/d435_color.py) on top of exposure and tone. The whole-sensor-set lines read
consecutive frames, as a trial does (the auto-exposure's lag reads the meters of the frames
before, cached when they were rendered). ``--shadows`` adds the whole sensor set with and without
shadow-casting lamps for the ``bright`` and ``uneven`` presets, side by side, wall and CPU time.
Run: ``python bench/bench_sim.py [--shadows]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from dataclasses import replace

import numpy as np

# isort: off
import sim.gl  # noqa: F401  (chooses MUJOCO_GL before mujoco is imported)
import mujoco

# isort: on
from sim.scenario import apply_settings, load_scenario  # noqa: E402
from sim.sensors.d435_color import ColourCamera  # noqa: E402
from sim.simulator import Simulation  # noqa: E402
from sim.world.world import CAMERA_NAME  # noqa: E402


def _ms(fn, n):
    fn()  # warm up
    t = time.perf_counter()
    for i in range(n):
        fn(i)
    return (time.perf_counter() - t) / n * 1e3


def _wall_cpu_ms(fn, n) -> tuple[float, float]:
    """(wall, CPU of the whole process, every thread) ms per call of ``fn(i)`` over n calls."""
    fn()  # warm up
    t, c = time.perf_counter(), time.process_time()
    for i in range(n):
        fn(i)
    return (time.perf_counter() - t) / n * 1e3, (time.process_time() - c) / n * 1e3


def _stream_ms(sim: Simulation, n: int) -> float:
    """ms per frame through ``frames()``, over n consecutive frames mid-route (a trial's stream)."""
    start = (sim.n_frames - n) // 2 + n  # frames the direct measurement did not render
    start = min(start, max(sim.n_frames - n, 0))
    t = time.perf_counter()
    count = sum(1 for _ in sim.frames(start, start + n))
    return (time.perf_counter() - t) / count * 1e3


def _colour_effects_ms(s: Simulation, k: int, n: int) -> dict[str, float]:
    """ms per frame of the colour model with exposure and tone only, and with each effect
    alone on top of that (the effect's cost is the difference), on frame k's render."""
    spec = s.scenario.sensors.d435.colour
    raw = s.on_gl_thread(s._render_colour_depth, k)
    exposure = s.exposure(k, raw.rgb)
    motion = s.motion_px(k, exposure.exposure_ms, raw.z_m)
    pool = s._pools[0]
    off = replace(
        spec,
        shot_noise=False,
        read_noise_e=0.0,
        motion_blur=False,
        defocus_sigma_px=0.0,
        vignetting=0.0,
        jpeg_quality=0,
    )
    i = s.intrinsics
    jpeg = spec.jpeg_quality or 90  # off by default: its cost when a robot turns it on
    effects = {
        "exposure + tone only": off,
        "+ shot and read noise": replace(off, shot_noise=True, read_noise_e=spec.read_noise_e),
        f"+ motion blur ({np.hypot(*motion):.1f} px on this frame)": replace(off, motion_blur=True),
        f"+ defocus (sigma {spec.defocus_sigma_px} px)": replace(off, defocus_sigma_px=spec.defocus_sigma_px),
        f"+ vignetting ({spec.vignetting})": replace(off, vignetting=spec.vignetting),
        f"+ JPEG (quality {jpeg})": replace(off, jpeg_quality=jpeg),
        "all effects (the defaults)": spec,
    }
    out = {}
    for name, sp in effects.items():
        cam = ColourCamera(sp, i.width, i.height, i.fx, i.fy, i.ppx, i.ppy)
        rng = np.random.default_rng(0)
        out[f"colour model: {name}"] = _ms(
            lambda j=0, cam=cam, rng=rng: cam.render(
                raw.rgb, exposure, s.colour_lux, rng=rng, pool=pool, motion_px=motion
            ),
            n,
        )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--maze", default="rrl_arena")
    ap.add_argument("--shadows", action="store_true", help="also the cost of shadows, per lighting preset")
    args = ap.parse_args()
    sc = apply_settings(load_scenario("default"), [f"maze.file={args.maze}"])
    n = args.frames
    with Simulation(sc) as s:
        ks = np.linspace(0, s.n_frames - 1, n).astype(int)
        r = s.on_gl_thread(s._renderer_ready)
        d = s.world.data

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
        }
        s.on_gl_thread(ref.close)
        sensors = apply_settings(sc, ["sensors.truth_boxes=false"])
    with Simulation(sensors) as s2:
        ks2 = np.arange(n) + (s2.n_frames - n) // 2  # consecutive frames, as a trial reads them
        res["whole sensor set (colour+depth+thermal+pose)"] = _ms(lambda i=0: s2.frame(int(ks2[i % n])), n)
        res["  the same, streamed (frames() renders ahead)"] = _stream_ms(s2, n)
        res.update(_colour_effects_ms(s2, int(ks2[n // 2]), n))
    with Simulation(sc) as s3:
        ks3 = np.arange(n) + (s3.n_frames - n) // 2
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
    if args.shadows:
        print("shadows (sim/world/world.py SHADOW_MAP_PX), whole sensor set, off and on side by side:")
        for preset in ("bright", "uneven"):
            cost = {}
            for on in (False, True):
                sc_l = apply_settings(sensors, [f"lighting={preset}", f"shadows={str(on).lower()}"])
                with Simulation(sc_l) as s4:
                    ks4 = np.arange(n) + (s4.n_frames - n) // 2
                    cost[on] = _wall_cpu_ms(lambda i=0, s4=s4, ks4=ks4: s4.frame(int(ks4[i % n])), n)
                    lamps = int(np.sum(s4.world.model.light_castshadow)) if on else 0
            (w0, c0), (w1, c1) = cost[False], cost[True]
            print(
                f"  {preset:6s} ({lamps} shadow-casting lamps): off {w0:6.1f} ms wall {c0:6.1f} ms CPU, "
                f"on {w1:6.1f} / {c1:6.1f}, CPU x{c1 / c0:.2f} (+{c1 - c0:.1f} ms)"
            )


if __name__ == "__main__":
    main()
