"""T265 drift as a percentage of distance driven, Monte Carlo over seeds (sim/sensors/t265.py).

The robot drives a 7.5 m x 5 m rectangle (25 m a lap) at 0.5 m/s, turning on the spot
at 90 degrees a second at the corners, and the position error of the reported pose at
the end of 25 m (one lap) and 200 m (eight laps) is taken as a percentage of the distance.
Intel quotes drift below 1% of the distance on a loop ([IntelT265SLAM]); the lap ends
where it started, as in that figure. Rows: the default model in good light and texture
(drift multiplier 1) with relocalisation off (the tracker's odometry alone) and on, and
in a dim room (80 lux, well-textured walls: multiplier 2.68 with the default ``conditions``).

Run: ``python bench/bench_t265.py`` (``--seeds N``, default 100).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from poi.core.geometry import make_transform, rot_z
from sim.sensors.base import PoseFunction
from sim.sensors.t265 import T265Spec, TrackingConditions, pose_interpolator, simulate_t265
from sim.sensors.tracking_conditions import drift_multiplier
from sim.world.world import LIGHT_LEVEL_LUX

LAP_SIDES_M = (7.5, 5.0)
SPEED_MPS = 0.5
TURN_RATE_RAD_S = np.pi / 2
FPS = 10.0


def lap_route(laps: int) -> tuple[PoseFunction, float, float]:
    """The true pose along ``laps`` laps of the rectangle, the duration and the distance."""
    t, poses, yaw, p = [0.0], [make_transform(np.eye(3), [0.0, 0.0, 0.5])], 0.0, np.array([0.0, 0.0, 0.5])
    for _ in range(laps):
        for side in (*LAP_SIDES_M, *LAP_SIDES_M):
            p = p + side * np.array([np.cos(yaw), np.sin(yaw), 0.0])
            t.append(t[-1] + side / SPEED_MPS)
            poses.append(make_transform(rot_z(yaw), p))
            yaw += np.pi / 2
            t.append(t[-1] + (np.pi / 2) / TURN_RATE_RAD_S)
            poses.append(make_transform(rot_z(yaw), p))
    return pose_interpolator(np.array(t), poses), t[-1], laps * 2 * sum(LAP_SIDES_M)


def drift_percent(spec: T265Spec, laps: int, seeds: int, multiplier: float) -> np.ndarray:
    route, duration, distance = lap_route(laps)
    cache: dict[tuple[int, float], np.ndarray] = {}

    def truth(t: np.ndarray) -> np.ndarray:  # every seed samples the same times: compute once
        key = (len(t), float(t[0]))
        if key not in cache:
            cache[key] = route(t)
        return cache[key]

    t_s = np.arange(0.0, duration + 1e-9, 1.0 / FPS)
    cond = TrackingConditions(t_s=np.array([0.0, duration]), multiplier=np.full(2, multiplier))
    out = []
    for seed in range(seeds):
        track = simulate_t265(truth, t_s, spec, np.random.default_rng(seed), True, cond)
        out.append(100.0 * track.error_m[-1] / distance)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    args = ap.parse_args()
    spec = T265Spec()
    dim = float(drift_multiplier(np.array([LIGHT_LEVEL_LUX["dim"]]), np.array([1.0]), spec.conditions)[0])
    rows = [
        ("good light, relocalisation off", replace(spec, relocalise=replace(spec.relocalise, enabled=False)), 1.0),
        ("good light, relocalisation on", spec, 1.0),
        (
            "dim room, relocalisation off",
            replace(spec, relocalise=replace(spec.relocalise, enabled=False)),
            dim,
        ),
    ]
    print(f"T265 drift, % of distance at the end of the lap, {args.seeds} seeds (mean / 95th percentile)")
    cpu = time.process_time()
    for name, s, m in rows:
        cells = []
        for laps in (1, 8):
            d = drift_percent(s, laps, args.seeds, m)
            cells.append(f"{25 * laps} m: {d.mean():.2f} / {np.percentile(d, 95):.2f}")
        print(f"  {name:32s} " + "   ".join(cells))
    print(f"CPU {time.process_time() - cpu:.1f} s")


if __name__ == "__main__":
    main()
