"""The simulated D435 depth against published figures, and its CPU cost per frame.

Prints a Markdown table (README "Depth as a D435 gives it"): the per-pixel temporal
sigma_z and the spatial (plane-fit) RMS at 0.5-4 m against Intel's formula
sigma_z = z^2 sigma_d / (f B) with sigma_d = 0.08 px ([IntelTuning]), the correlation of
neighbouring errors, the stereo shadow's side and width for a box 1 m before a wall 2 m
away against fx (B + b) (1/z_n - 1/z_f), the minimum range against f B / 126 and the
datasheet's 0.28 m at 1280x720 ([IntelD400]), the fill of a plain wall with distance, the
registration error, then the CPU milliseconds (``time.process_time``) of one 640x480 frame
of the model.

``--baseline FILE`` times another version of ``sim/sensors/d435_depth.py`` side by side
(e.g. ``git show HEAD~1:sim/sensors/d435_depth.py > /tmp/old_depth.py``), with its own
settings and the inputs it takes (the colour, the per-trial draws); a version from before the
minimum range was a setting (a990b77) runs with ``min_m=0.28``. Run: ``python
bench/bench_depth.py [--baseline FILE] [--frames N]``.

References
----------
Full entries in docs/SOURCES.md.

.. [IntelTuning] A. Grunnet-Jepsen, J. N. Sweetser, J. Woodfill, "Tuning depth cameras for
   best performance", Intel RealSense white paper.
.. [IntelD400] Intel Corporation, "Intel RealSense Product Family D400 Series" datasheet.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import os
import platform
import sys
import time
from dataclasses import replace

import numpy as np

from poi.core.sensor_noise import depth_sigma_m
from sim.sensors.d435_depth import DepthSpec, DepthTrial, simulate_depth
from sim.sensors.noise_pool import NoisePool

FX_COLOUR = 612.4  # sim/sensors/d435.py D435Spec.fx
SEED = 2026
DATASHEET_MIN_Z_1280_M = 0.28  # [IntelD400]: D435 minimum range at 1280x720
FX_1280_PX = 425.0 * 1280 / 848  # the 848x480 focal length (docs/FACTS.md) scaled to 1280 wide


def _pct(a: float, b: float) -> str:
    return f"{100.0 * (a / b - 1.0):+.1f}%"


def plane_stats(spec: DepthSpec, z_m: float, n: int = 30, shape=(200, 200)) -> tuple[float, float, float]:
    """(temporal sigma, mean spatial plane-fit RMS, lag-1 correlation) of n frames of a plane."""
    trial = DepthTrial.draw(spec, shape, np.random.default_rng([SEED, 2]))
    pool = NoisePool.standard_normal([SEED, 1], 3 * shape[0] * shape[1])
    z = np.full(shape, z_m, np.float32)
    frames = np.stack(
        [
            simulate_depth(z, spec, FX_COLOUR, np.random.default_rng([SEED, k]), True, pool, trial=trial)
            for k in range(n)
        ]
    ).astype(np.float64)
    ok = (frames > 0).all(axis=0)
    temporal = float(np.sqrt(frames[:, ok].var(axis=0, ddof=1).mean()))
    H, W = shape
    v, u = np.mgrid[0:H, 0:W]
    A = np.c_[np.ones(H * W), u.ravel(), v.ravel()][ok.ravel()]
    spatial = []
    for f in frames:
        y = f[ok]
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        spatial.append(np.sqrt(np.mean((y - A @ coef) ** 2)))
    e = np.where(ok, frames[0] - z_m, np.nan)
    pair = np.isfinite(e[:, :-1]) & np.isfinite(e[:, 1:])
    r = float(np.corrcoef(e[:, :-1][pair], e[:, 1:][pair])[0, 1])
    return temporal, float(np.mean(spatial)), r


def shadow_band(spec: DepthSpec) -> tuple[str, int]:
    """(side, columns) of the invalid band beside a box 1 m before a wall 2 m away (noise on)."""
    z = np.full((48, 640), 2.0, np.float32)
    z[:, 300:400] = 1.0
    quiet = replace(spec, dropout=0.0, flying_pixels=0.0, registration_error_px=0.0, texture=False)
    out = simulate_depth(z, quiet, FX_COLOUR, np.random.default_rng(SEED), True)
    holes = np.nonzero((out == 0).all(axis=0))[0]
    left, right = holes[holes < 300], holes[holes >= 400]
    side = "left" if len(left) > len(right) else "right" if len(right) else "none"
    return side, int(max(len(left), len(right)))


def min_range(spec: DepthSpec) -> float:
    """The nearest z (1 mm steps from 0.05 m) at which a plane reads depth."""
    zs = np.arange(0.05, 0.5, 0.001, dtype=np.float32)
    quiet = replace(spec, dropout=0.0, flying_pixels=0.0, registration_error_px=0.0, texture=False)
    out = simulate_depth(zs[None, :], quiet, FX_COLOUR, np.random.default_rng(SEED), True)
    return float(zs[np.nonzero(out[0] > 0)[0][0]])


def plain_wall_fill(spec: DepthSpec, z_m: float) -> float:
    """Fraction of a uniform grey wall (no texture of its own) that reads depth."""
    rgb = np.full((120, 160, 3), 128, np.uint8)
    z = np.full((120, 160), z_m, np.float32)
    s = replace(spec, dropout=0.0, registration_error_px=0.0)
    outs = [simulate_depth(z, s, FX_COLOUR, np.random.default_rng([SEED, k]), True, rgb=rgb) for k in range(5)]
    return float(np.mean([o > 0 for o in outs]))


def _load(path: str):
    spec = importlib.util.spec_from_file_location("baseline_d435_depth", path)
    if spec is None or spec.loader is None:
        raise SystemExit(f"bench_depth: --baseline {path}: not a Python file")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up while the class is made
    spec.loader.exec_module(mod)
    return mod


def cpu_ms(fn, n: int) -> float:
    fn(0)  # warm up
    t = time.process_time()
    for i in range(n):
        fn(i)
    return (time.process_time() - t) / n * 1e3


def timing(baseline: str | None, n: int) -> list[tuple[str, float]]:
    """CPU ms of one 640x480 frame: a box before a wall, textured colour, pooled noise."""
    H, W = 480, 640
    z = np.full((H, W), 2.0, np.float32)
    z[120:360, 250:420] = 1.0
    rgb = np.random.default_rng(SEED).integers(0, 256, (H, W, 3), dtype=np.uint8)
    pool = NoisePool.standard_normal([SEED, 1], 3 * H * W)
    spec = DepthSpec()
    trial = DepthTrial.draw(spec, (H, W), np.random.default_rng(SEED))
    rows = []
    if baseline:
        old = _load(baseline)
        # the baseline's own settings and inputs where it has them (the colour for the texture
        # effects, the per-trial draws), so that two versions of today's model time the same work;
        # an early version without a minimum range of its own gets the datasheet's
        old_spec = old.DepthSpec() if hasattr(old, "DepthSpec") else replace(spec, min_m=0.28)
        params = inspect.signature(old.simulate_depth).parameters
        extra = {"rgb": rgb} if "rgb" in params else {}
        if "trial" in params and hasattr(old, "DepthTrial"):
            extra["trial"] = old.DepthTrial.draw(old_spec, (H, W), np.random.default_rng(SEED))
        rows.append(
            (
                f"baseline ({baseline})",
                cpu_ms(
                    lambda k: old.simulate_depth(
                        z, old_spec, FX_COLOUR, np.random.default_rng(k), True, pool, **extra
                    ),
                    n,
                ),
            )
        )
    rows.append(
        (
            "this version, every effect",
            cpu_ms(
                lambda k: simulate_depth(
                    z, spec, FX_COLOUR, np.random.default_rng(k), True, pool, rgb=rgb, trial=trial
                ),
                n,
            ),
        )
    )
    plain = replace(spec, texture=False, flying_pixels=0.0, window_px=1, fixed_pattern=0.0)
    rows.append(
        (
            "this version, texture/flying/window off",
            cpu_ms(lambda k: simulate_depth(z, plain, FX_COLOUR, np.random.default_rng(k), True, pool), n),
        )
    )
    return rows


def figure(path: str, k: int) -> str:
    """Frame ``k`` of the default trial, colour beside depth (turbo, 0.2-4 m; black: no depth), as JPEG."""
    import cv2

    import sim.gl  # noqa: F401  (chooses MUJOCO_GL before mujoco is imported)
    from sim.scenario import load_scenario
    from sim.simulator import Simulation

    with Simulation(load_scenario("default")) as s:
        frame, _ = s.frame(k)
    d = frame.depth_m
    level = np.clip((d - 0.2) / (4.0 - 0.2), 0.0, 1.0)
    depth_bgr = cv2.applyColorMap((255 * (1.0 - level)).astype(np.uint8), cv2.COLORMAP_TURBO)
    depth_bgr[d == 0] = 0
    pair = np.concatenate([cv2.cvtColor(frame.rgb, cv2.COLOR_RGB2BGR), depth_bgr], axis=1)
    for text, x in ((f"colour, default trial frame {k}", 8), ("aligned depth (black: 0, no depth)", 648)):
        cv2.putText(pair, text, (x, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2, cv2.LINE_AA)
    cv2.imwrite(path, pair, [cv2.IMWRITE_JPEG_QUALITY, 80])
    return f"wrote {path}: frame {k}, {100 * float((d == 0).mean()):.1f}% of pixels without depth"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", help="another sim/sensors/d435_depth.py to time side by side")
    ap.add_argument("--frames", type=int, default=40, help="frames timed per model (default 40)")
    ap.add_argument("--figure", metavar="JPG", help="write the default trial's frame --frame, colour beside depth")
    ap.add_argument(
        "--frame", type=int, default=500, help="the frame of --figure (500: a heater and a crate before far walls)"
    )
    args = ap.parse_args(argv)
    if args.figure:
        print(figure(args.figure, args.frame))
        return 0
    spec = DepthSpec()
    print("| Figure | Simulated | Published or formula | Difference |")
    print("|---|---|---|---|")
    for z in (0.5, 1.0, 2.0, 4.0):
        formula = depth_sigma_m(
            z, sigma_d_px=spec.sigma_d_px, fx_depth_px=spec.fx_depth_px, baseline_m=spec.baseline_m
        )
        temporal, spatial, r = plane_stats(spec, z)
        print(
            f"| sigma_z at {z:g} m, temporal (per pixel) | {temporal * 1e3:.2f} mm | {formula * 1e3:.2f} mm "
            f"(z^2 0.08 / (f B)) | {_pct(temporal, formula)} |"
        )
        print(
            f"| sigma_z at {z:g} m, spatial (plane fit) | {spatial * 1e3:.2f} mm "
            f"({spatial / temporal:.2f} x temporal) "
            f"| {formula * 1e3:.2f} mm, and at least the temporal | {_pct(spatial, formula)} |"
        )
        if z == 1.0:
            print(f"| neighbour correlation at 1 m (lag 1 px) | {r:.2f} | strong (window matching) | - |")
    fB = spec.fx_depth_px * spec.baseline_m
    side, width = shadow_band(spec)
    expected = FX_COLOUR * (spec.baseline_m + spec.colour_offset_m) * (1.0 / 1.0 - 1.0 / 2.0)
    print(
        f"| shadow of a box at 1 m on a wall at 2 m | {side}, {width} px | left, "
        f"{expected:.1f} px (fx (B + b)(1/z_n - 1/z_f)) | {_pct(width, expected)} |"
    )
    mz = min_range(spec)
    print(f"| minimum range at 640x480 | {mz:.3f} m | {fB / 126:.3f} m (f B / 126) | {_pct(mz, fB / 126)} |")
    mz1280 = min_range(replace(spec, fx_depth_px=FX_1280_PX))
    print(
        f"| minimum range at 1280x720 (f = {FX_1280_PX:.0f} px) | {mz1280:.3f} m | "
        f"{DATASHEET_MIN_Z_1280_M:.2f} m (datasheet) | {_pct(mz1280, DATASHEET_MIN_Z_1280_M)} |"
    )
    fills = ", ".join(f"{z:g} m {plain_wall_fill(spec, z):.0%}" for z in (1, 3, 4, 5, 6, 8))
    print(f"| fill of a plain wall (projector only) | {fills} | falls beyond the projector's range | - |")
    rng = np.random.default_rng(SEED)
    off = np.array([DepthTrial.draw(replace(spec, fixed_pattern=0.0), (2, 2), rng).offset_px for _ in range(2000)])
    rms = float(np.sqrt((off**2).sum(axis=1).mean()))
    print(f"| depth-to-colour registration error (RMS over 2000 trials) | {rms:.2f} px | about 1 px | - |")
    print()
    cpu = platform.processor() or platform.machine()
    print(f"CPU ms per 640x480 frame ({cpu}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}):")
    for name, ms in timing(args.baseline, args.frames):
        print(f"  {name}: {ms:.1f} ms")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
