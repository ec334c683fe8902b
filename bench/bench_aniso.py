"""CPU cost of anisotropic texture filtering (sim/render.py): one colour + depth render of the
default trial's frames without it, with it on the decal textures (the default) and on all.

MuJoCo filters its textures trilinearly; ``SceneRenderer`` sets each texture's
``GL_TEXTURE_MAX_ANISOTROPY_EXT`` to the driver's maximum (16 on Mesa's llvmpipe), which takes
up to that many trilinear samples per pixel where a texture is seen at a grazing angle (the
floor, the walls along a corridor). This bench renders ``--frames`` frames spread over the
default trial with three renderers of the same world, alternating them frame by frame so
that machine load falls on all alike, ``--repeats`` times each, and
prints the mean process CPU milliseconds (the calling thread plus llvmpipe's rasteriser
threads, ``time.process_time``) of each and the load average.

Run: ``MUJOCO_GL=egl python bench/bench_aniso.py [--frames 12 --repeats 5] [--scenario default]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from sim.render import SceneRenderer
from sim.scenario import load_scenario
from sim.simulator import Simulation
from sim.world.world import CAMERA_NAME


def render_cpu_ms(scenario: str, n_frames: int, repeats: int) -> dict[bool | str, float]:
    """Mean process CPU ms of one colour + depth render without (False) anisotropic filtering,
    with it on the decals (True, the default) and on every texture ("all"), over ``n_frames``
    frames spread evenly over the trial."""
    with Simulation(load_scenario(scenario)) as sim:
        ks = np.linspace(0, sim.n_frames - 1, n_frames).round().astype(int)
        intr = sim.intrinsics

        def job() -> dict[bool | str, float]:
            m = sim.world.model
            renderers = {
                a: SceneRenderer(m, intr.width, intr.height, CAMERA_NAME, anisotropic=a)
                for a in (False, True, "all")
            }
            cpu = dict.fromkeys(renderers, 0.0)
            try:
                for k in ks:
                    sim._set_camera(int(k))
                    for a, r in renderers.items():
                        r.update(sim.world.data)
                        r.color_depth()  # one untimed render of the frame first
                        t0 = time.process_time()
                        for _ in range(repeats):
                            r.color_depth()
                        cpu[a] += time.process_time() - t0
            finally:
                for r in renderers.values():
                    r.close()
            return {a: 1000.0 * c / (len(ks) * repeats) for a, c in cpu.items()}

        return sim.on_gl_thread(job)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    if args.frames < 1 or args.repeats < 1:
        ap.error("--frames and --repeats must be at least 1")
    load0 = os.getloadavg()[0]
    ms = render_cpu_ms(args.scenario, args.frames, args.repeats)
    load1 = os.getloadavg()[0]
    print(
        f"{args.scenario!r}, {args.frames} frames x {args.repeats} renders: colour + depth "
        f"{ms[False]:.1f} CPU ms without anisotropic filtering, {ms[True]:.1f} with it on the decals "
        f"({100 * (ms[True] / ms[False] - 1):+.0f} %, the default), {ms['all']:.1f} on every texture "
        f"({100 * (ms['all'] / ms[False] - 1):+.0f} %); load average {load0:.1f} at the start, "
        f"{load1:.1f} at the end"
    )


if __name__ == "__main__":
    main()
