"""Render cost against geom count: CPU milliseconds of one colour + depth render (sim.render)
of a scene with N small geoms in view, for boxes and for capsules, and a straight line fitted
to each (ms = a + b N).

The geoms are 2 cm, on a grid 3 m in front of a 640x480 camera, so the pixels they fill stay
few and the slope is the cost of a geom itself: MuJoCo's per-geom work and the vertices
Mesa's llvmpipe transforms (a box is 12 triangles; a capsule, sphere or cylinder is
tessellated by ``visual/quality`` numslices x numstacks: MuJoCo's 28 x 16 and the worlds'
``sim.world.world.CURVE_SLICES`` x ``CURVE_STACKS``). CPU is the
process's (the calling thread plus llvmpipe's rasteriser threads), ``time.process_time``.
The default trial's world's geoms by type are printed beside, to read the fit against.

Run: ``python bench/bench_render_geoms.py [--repeats 30]``.
"""

from __future__ import annotations

import argparse
import os
import time

import mujoco
import numpy as np

from sim.render import SceneRenderer
from sim.world.world import CURVE_SLICES, CURVE_STACKS

W, H = 640, 480
COUNTS = (0, 100, 200, 400, 800)


def scene_xml(n: int, kind: str, slices: tuple[int, int] = (28, 16)) -> str:
    """A floor, a light, a camera and ``n`` small geoms of ``kind`` on a grid facing it, round
    geoms tessellated ``slices`` (numslices, numstacks)."""
    side = max(1, int(np.ceil(np.sqrt(n))))
    geoms = []
    for i in range(n):
        r, c = divmod(i, side)
        x = -1.0 + 2.0 * (c + 0.5) / side
        z = 0.2 + 1.5 * (r + 0.5) / side
        size = "0.01 0.01 0.01" if kind == "box" else "0.008 0.01"
        geoms.append(f'<geom type="{kind}" size="{size}" pos="{x:.4f} 3 {z:.4f}" rgba="0.8 0.3 0.2 1"/>')
    return f"""<mujoco>
  <visual><global offwidth="{W}" offheight="{H}"/>
    <quality offsamples="0" numslices="{slices[0]}" numstacks="{slices[1]}"/></visual>
  <worldbody>
    <light pos="0 0 3" dir="0 0.3 -1" castshadow="false"/>
    <geom type="plane" size="5 5 0.1" rgba="0.5 0.5 0.5 1"/>
    <camera name="cam" pos="0 0 1" xyaxes="1 0 0 0 0 1" fovy="58"/>
    {"".join(geoms)}
  </worldbody>
</mujoco>"""


def render_ms(n: int, kind: str, repeats: int, slices: tuple[int, int] = (28, 16)) -> float:
    """Mean process CPU milliseconds of one colour + depth render of the ``n``-geom scene."""
    model = mujoco.MjModel.from_xml_string(scene_xml(n, kind, slices))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with SceneRenderer(model, W, H, "cam") as r:
        r.update(data)
        for _ in range(3):
            r.color_depth()
        t0 = time.process_time()
        for _ in range(repeats):
            r.update(data)
            r.color_depth()
        return 1000.0 * (time.process_time() - t0) / repeats


def default_world_geoms() -> dict[str, int]:
    from sim.scenario import load_scenario
    from sim.simulator import Simulation

    with Simulation(load_scenario("default")) as sim:
        types = sim.world.model.geom_type
        name = {int(t): mujoco.mjtGeom(int(t)).name.removeprefix("mjGEOM_").lower() for t in set(types)}
        return {name[t]: int(np.sum(types == t)) for t in name}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=30, help="renders timed per scene (default 30)")
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    ours = (CURVE_SLICES, CURVE_STACKS)
    for kind, slices in (("box", ours), ("capsule", (28, 16)), ("capsule", ours)):
        ms = [render_ms(n, kind, args.repeats, slices) for n in COUNTS]
        b, a = np.polyfit(COUNTS, ms, 1)
        points = ", ".join(f"{n}: {m:.1f}" for n, m in zip(COUNTS, ms, strict=True))
        what = kind if kind == "box" else f"{kind} {slices[0]}x{slices[1]}"
        print(f"{what:14s} ms by geom count {{{points}}}; fit {a:.2f} ms + {1000 * b:.1f} us a geom")
    geoms = default_world_geoms()
    print(f"the default world: {sum(geoms.values())} geoms, {geoms}")
    load1 = os.getloadavg()[0]
    print(f"load average {load0:.1f} at the start, {load1:.1f} at the end; {W}x{H}, CPU of the process")


if __name__ == "__main__":
    main()
