"""How far the simulated D435 colour stream resolves a concentric Landolt-C target's rings.

A MuJoCo scene holds ``--targets`` default targets (poi/core/landolt.py, docs/FACTS.md
"Landolt-C"; gap directions drawn from ``--seed``), each a textured card
(maze_assets/landolt.py) on a grey wall. The scenario's D435 colour camera
(sim/camera.py intrinsics, ``--scenario``'s settings, 640x480 by default) looks at each
card from every ``--distances`` (metres, to the card's plane), from ``--poses`` random
poses per target and distance: the camera moved sideways and up/down by up to 0.3 of
the half field of view at that distance and turned by up to 8 degrees, so the target
is off-centre and seen a little obliquely. The render is lit by the robot's lamp at
the scenario's lighting preset and goes through the scenario's colour model
(sim/sensors/d435_color.py: auto-exposure settled, shot and read noise, defocus,
vignetting, white balance, JPEG). The reader (poi/detectors/landolt.py) gets the frame
and the card's projected box (standing in for a detector's box) and reads every ring
from pixels.

For each distance and ring the table gives the gap's size in pixels on the image
(gap mm x fx / distance) and the share of readings that are right, wrong (a direction,
not the true one) and None (unreadable). Run:
``MUJOCO_GL=egl python bench/bench_landolt.py [--targets 24 --poses 4 --seed 0] [--set key=value ...]``.
"""

from __future__ import annotations

import argparse
import math
import time
import xml.etree.ElementTree as ET

import numpy as np

from maze_assets.landolt import card_side_mm, draw_landolt
from maze_assets.mjcf import SceneAssets, fmt
from poi.core.landolt import LandoltSpec, random_orientations
from poi.core.types import Intrinsics
from poi.detectors.landolt import read_landolt
from sim.camera import d435_intrinsics, mujoco_camera_attrs
from sim.render import SceneRenderer
from sim.scenario import Scenario, apply_settings, load_scenario
from sim.sensors.d435_color import ColourCamera, meter, steady_state_exposure
from sim.world.world import LAMP_WHITE_LEVEL, LIGHT_LEVEL_LUX, lux_of_decoded_one

TEXTURE_PX = 512  # the card's texture: ring 5's 0.33 mm gap is 2.6 texels
TARGET_SPACING_M = 3.0  # cards side by side along y, far enough apart that one fills a crop
WALL_GREY = 0.55
MAX_YAW_DEG = 8.0
MAX_SHIFT_FRAC = 0.3  # of the half field of view at the distance


def build_scene(
    spec: LandoltSpec, orientations: list[tuple[int, ...]], intr: Intrinsics, lamp_level: float
) -> tuple[str, dict]:
    """MJCF of the cards (facing +x at y = i x TARGET_SPACING_M, z = 0) and a camera rig."""
    assets = SceneAssets()
    side_m = card_side_mm(spec) / 1000.0
    h = side_m / 2.0
    V = [(0.0, -h, h), (0.0, h, h), (0.0, h, -h), (0.0, -h, -h)]  # top-left, top-right, ... seen from +x
    assets.mesh("card", V, [(0, 3, 2), (0, 2, 1)], [(0, 0), (1, 0), (1, 1), (0, 1)])
    assets.asset.find("mesh[@name='card']").set("inertia", "shell")  # a flat mesh has no volume
    root = ET.Element("mujoco", model="landolt_bench")
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", offwidth=str(intr.width), offheight=str(intr.height))
    ET.SubElement(vis, "map", znear="0.002", zfar="50")
    ET.SubElement(vis, "quality", shadowsize="0")
    # the robot's lamp: a white card facing it renders at lamp_level (sim/world/world.py LAMP_WHITE_LEVEL)
    ET.SubElement(vis, "headlight", ambient=fmt([lamp_level * 0.45] * 3), diffuse=fmt([lamp_level * 0.55] * 3))
    ET.SubElement(root, "statistic", extent="1", center="0 0 0")
    root.append(assets.asset)
    world = ET.SubElement(root, "worldbody")
    n = len(orientations)
    ET.SubElement(
        world,
        "geom",
        name="wall",
        type="box",
        pos=fmt([-0.01, (n - 1) * TARGET_SPACING_M / 2, 0]),
        size=fmt([0.005, n * TARGET_SPACING_M / 2 + 3, 3]),
        rgba=fmt([WALL_GREY, WALL_GREY, WALL_GREY, 1]),
        contype="0",
        conaffinity="0",
    )
    for i, o in enumerate(orientations):
        assets.texture(f"landolt_{i}", draw_landolt(spec, o, TEXTURE_PX))
        assets.material(f"m_landolt_{i}", texture=f"landolt_{i}", specular=0.0, shininess=0.0)
        ET.SubElement(
            world,
            "geom",
            name=f"card_{i}",
            type="mesh",
            mesh="card",
            material=f"m_landolt_{i}",
            pos=fmt([0.0, i * TARGET_SPACING_M, 0.0]),
            contype="0",
            conaffinity="0",
        )
    rig = ET.SubElement(world, "body", name="rig", mocap="true", pos="1 0 0")
    ET.SubElement(rig, "camera", name="d435", **mujoco_camera_attrs(intr))
    return ET.tostring(root, encoding="unicode"), assets.files


def yaw_quat(yaw: float) -> np.ndarray:
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def project(points_w: np.ndarray, cam_pos: np.ndarray, cam_mat: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(N, 2) pixels of world points; MuJoCo's camera looks along -z with y up."""
    pc = (points_w - cam_pos) @ cam_mat  # (N, 3) in the camera frame
    z = -pc[:, 2]
    return np.stack([intr.ppx + intr.fx * pc[:, 0] / z, intr.ppy - intr.fy * pc[:, 1] / z], axis=1)


def measure(sc: Scenario, distances: list[float], n_targets: int, poses: int, seed: int) -> np.ndarray:
    """Counts (len(distances), n_rings, 3): readings right, wrong and None per distance and ring."""
    import mujoco  # after sim (importing sim chooses MUJOCO_GL before mujoco is loaded)

    d = sc.sensors.d435
    intr = d435_intrinsics(d.width, d.height, d.fx, d.fy, d.ppx, d.ppy)
    col = d.colour
    lux = lux_of_decoded_one(
        sc.lighting, col.lux if col.lux is not None else LIGHT_LEVEL_LUX[sc.lighting], col.gamma
    )
    camera = ColourCamera(col, intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy)
    rng = np.random.default_rng(seed)
    spec = LandoltSpec()
    truth = [random_orientations(spec.n_rings, rng) for _ in range(n_targets)]
    xml, files = build_scene(spec, truth, intr, LAMP_WHITE_LEVEL[sc.lighting])
    model = mujoco.MjModel.from_xml_string(xml, files)
    data = mujoco.MjData(model)
    cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "d435")
    half = card_side_mm(spec) / 2000.0
    corners = np.array([[0, -half, half], [0, half, half], [0, half, -half], [0, -half, -half]], float)
    half_fov = math.atan(intr.width / 2 / intr.fx), math.atan(intr.height / 2 / intr.fy)
    counts = np.zeros((len(distances), spec.n_rings, 3), int)  # right, wrong, None
    with SceneRenderer(model, intr.width, intr.height, "d435") as r:
        for i_d, dist in enumerate(distances):
            for i_t, o in enumerate(truth):
                for _ in range(poses):
                    dy = rng.uniform(-1, 1) * MAX_SHIFT_FRAC * dist * math.tan(half_fov[0])
                    dz = rng.uniform(-1, 1) * MAX_SHIFT_FRAC * dist * math.tan(half_fov[1])
                    yaw = math.radians(rng.uniform(-MAX_YAW_DEG, MAX_YAW_DEG))
                    data.mocap_pos[0] = [dist, i_t * TARGET_SPACING_M + dy, dz]
                    data.mocap_quat[0] = yaw_quat(math.pi + yaw)  # rig x forward: towards -x
                    mujoco.mj_forward(model, data)
                    r.update(data)
                    rgb, _depth = r.color_depth()
                    exposure = steady_state_exposure(meter(rgb, col.gamma), col, lux)
                    frame = camera.render(rgb, exposure, lux, rng=rng, pool=None)
                    cw = corners + np.array([0.0, i_t * TARGET_SPACING_M, 0.0])
                    uv = project(cw, data.cam_xpos[cam_id], data.cam_xmat[cam_id].reshape(3, 3), intr)
                    reading = read_landolt(frame, (*uv.min(axis=0), *uv.max(axis=0)))
                    for k in range(spec.n_rings):
                        got = None if reading is None else reading.rings[k].orientation_deg
                        counts[i_d, k, 2 if got is None else (0 if got == o[k] else 1)] += 1
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--set", action="append", default=[], help="a scenario setting key=value")
    ap.add_argument(
        "--distances", type=float, nargs="+", default=[0.3, 0.4, 0.5, 0.6, 0.75, 0.9, 1.0, 1.25, 1.5, 2.0]
    )
    ap.add_argument("--targets", type=int, default=24)
    ap.add_argument("--poses", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    if args.targets < 1 or args.poses < 1 or any(d <= 0 for d in args.distances):
        ap.error("--targets and --poses must be at least 1 and every distance positive")
    sc = apply_settings(load_scenario(args.scenario), args.set)
    d = sc.sensors.d435
    t0 = time.perf_counter()
    counts = measure(sc, args.distances, args.targets, args.poses, args.seed)
    elapsed = time.perf_counter() - t0
    n = args.targets * args.poses
    spec = LandoltSpec()
    gaps = spec.gaps_mm()
    print(
        f"scenario {args.scenario!r} {' '.join(args.set)} ({d.width}x{d.height}, fx {d.fx} px, lighting "
        f"{sc.lighting}): {args.targets} targets x {args.poses} poses = {n} readings per distance and ring, "
        f"seed {args.seed}; {elapsed:.0f} s"
    )
    print()
    print("readings right % / wrong % (the rest None), and the gap's width on the image")
    print()
    print("| distance | " + " | ".join(f"ring {k + 1} ({g:.2f} mm gap)" for k, g in enumerate(gaps)) + " |")
    print("|---:|" + "---:|" * spec.n_rings)
    for i_d, dist in enumerate(args.distances):
        cells = []
        for k in range(spec.n_rings):
            right, wrong, _none = (100.0 * c / n for c in counts[i_d, k])
            cells.append(f"{right:.0f} / {wrong:.0f} ({gaps[k] * d.fx / (dist * 1000):.1f} px)")
        print(f"| {dist:g} m | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
