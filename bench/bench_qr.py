"""Which QR decoder reads the rendered maze codes, by pixels per module, viewing angle and blur.

A MuJoCo scene holds ``--codes`` QR cards as the maze has them (maze_assets/qr.py textures
of ``maze_assets.models.TEXTURE_PX`` pixels, ``--side-m`` metres a side, "Chart X" texts:
version 1, 21 modules and a quiet zone, 32 modules across the card) on a grey wall. The
scenario's D435 colour camera looks at each card's centre from ``--distances`` metres at
``--angles`` degrees off the card's normal (turned about the vertical, as a code on a side
wall is seen along a corridor), each pose jittered by up to 3 degrees of yaw. The render
(sim/render.py, anisotropic filtering on unless ``--no-aniso``) goes through the scenario's
colour model (sim/sensors/d435_color.py: exposure, noise, defocus, vignetting) with a
horizontal motion blur of each ``--blur-px`` (a pan smears the image sideways). The card's
projected box stands in for a detector's box (as the oracle gives it).

Each decoder gets the same box: ``cv-aruco`` and ``cv-classic`` (OpenCV's
``QRCodeDetectorAruco`` and ``QRCodeDetector`` on the crop at its own size), ``cv-reader``
(poi/detectors/qr.py as it was before zxing-cpp: both OpenCV decoders on an upscaled crop,
with and without a white border), ``zxing`` (zxing-cpp's ``read_barcodes`` on the crop as it
is), ``reader`` (poi/detectors/qr.py ``decode_qr`` as it is now: zxing-cpp on the crop,
upscaled, stretched square when narrow, and sharpened) and ``reader+gyro`` (the same given the
camera's motion, poi.core.motion_blur.CameraMotion, as a trial's pipeline gets it: a box it does
not read otherwise is deblurred by the line the motion draws). On the cards the motion is the
pan that makes each ``--blur-px`` over the exposure; on ``--trial`` the frame's gyro over the
ladder of exposures below ``qr.max_exposure_ms`` (the default colour camera runs auto-exposure,
which reports no exposure). Printed: reads (right text) per
bin of pixels per module (the box's shorter side / 29 modules, the code's quiet zone
included, as the funnel counts them), of angle and of blur, and each decoder's CPU
milliseconds per call (process time, so other jobs on the machine do not count).

``--trial`` measures the same on the scenario's own trial instead: every QR view the oracle
boxes (at least 35 % visible, box at least 12 px), its truth box, the angle off the code's
normal and the frame's motion blur (``--views FILE`` keeps the views to decode again). Run:
``MUJOCO_GL=egl python bench/bench_qr.py [--codes 4 --seed 0] [--no-aniso] [--set key=value ...]``
or ``MUJOCO_GL=egl python bench/bench_qr.py --trial [--step 2] [--views views.pkl] [--set ...]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import pickle
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from maze_assets.mjcf import SceneAssets, fmt
from maze_assets.models import TEXTURE_PX
from maze_assets.qr import QUIET_MODULES, draw_qr, qr_modules
from poi.core.in_view import boxable_view
from poi.core.motion_blur import CameraMotion, camera_motion
from poi.core.types import Intrinsics
from sim.camera import d435_intrinsics, mujoco_camera_attrs
from sim.render import SceneRenderer
from sim.scenario import Scenario, apply_settings, load_scenario
from sim.sensors.d435_color import ColourCamera, meter, steady_state_exposure
from sim.world.world import LAMP_WHITE_LEVEL, LIGHT_LEVEL_LUX, lux_of_decoded_one

CARD_SPACING_M = 4.0  # cards side by side along y, far enough apart that one fills a crop
WALL_GREY = 0.55
MAX_YAW_JITTER_DEG = 3.0
MARGIN_FRAC = 0.15  # crop margin, as poi/detectors/qr.py


def build_scene(texts: list[str], side_m: float, intr: Intrinsics, lamp_level: float) -> tuple[str, dict]:
    """MJCF of the QR cards (facing +x at y = i x CARD_SPACING_M, z = 0) and a camera rig."""
    assets = SceneAssets()
    h = side_m / 2.0
    V = [(0.0, -h, h), (0.0, h, h), (0.0, h, -h), (0.0, -h, -h)]  # top-left, top-right, ... seen from +x
    assets.mesh("card", V, [(0, 3, 2), (0, 2, 1)], [(0, 0), (1, 0), (1, 1), (0, 1)])
    assets.asset.find("mesh[@name='card']").set("inertia", "shell")
    root = ET.Element("mujoco", model="qr_bench")
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", offwidth=str(intr.width), offheight=str(intr.height))
    ET.SubElement(vis, "map", znear="0.002", zfar="50")
    ET.SubElement(vis, "quality", shadowsize="0")
    ET.SubElement(vis, "headlight", ambient=fmt([lamp_level * 0.45] * 3), diffuse=fmt([lamp_level * 0.55] * 3))
    ET.SubElement(root, "statistic", extent="1", center="0 0 0")
    root.append(assets.asset)
    world = ET.SubElement(root, "worldbody")
    n = len(texts)
    ET.SubElement(
        world,
        "geom",
        name="wall",
        type="box",
        pos=fmt([-0.01, (n - 1) * CARD_SPACING_M / 2, 0]),
        size=fmt([0.005, n * CARD_SPACING_M / 2 + 3, 3]),
        rgba=fmt([WALL_GREY, WALL_GREY, WALL_GREY, 1]),
        contype="0",
        conaffinity="0",
    )
    for i, text in enumerate(texts):
        assets.texture(f"qr_{i}", draw_qr(text, TEXTURE_PX))
        assets.material(f"m_qr_{i}", texture=f"qr_{i}", specular=0.0, shininess=0.0)
        ET.SubElement(
            world,
            "geom",
            name=f"card_{i}",
            type="mesh",
            mesh="card",
            material=f"m_qr_{i}",
            pos=fmt([0.0, i * CARD_SPACING_M, 0.0]),
            contype="0",
            conaffinity="0",
        )
    rig = ET.SubElement(world, "body", name="rig", mocap="true", pos="1 0 0")
    ET.SubElement(rig, "camera", name="d435", **mujoco_camera_attrs(intr))
    return ET.tostring(root, encoding="unicode"), assets.files


def project(points_w: np.ndarray, cam_pos: np.ndarray, cam_mat: np.ndarray, intr: Intrinsics) -> np.ndarray:
    """(N, 2) pixels of world points; MuJoCo's camera looks along -z with y up."""
    pc = (points_w - cam_pos) @ cam_mat  # (N, 3) in the camera frame
    z = -pc[:, 2]
    return np.stack([intr.ppx + intr.fx * pc[:, 0] / z, intr.ppy - intr.fy * pc[:, 1] / z], axis=1)


def px_per_module(box: tuple[float, float, float, float], text: str) -> float:
    """The box's shorter side over the code's modules across, quiet zone included (21 + 8 for
    a version-1 code): the funnel's measure (eval/trial/funnel_recorder.py)."""
    return min(box[2] - box[0], box[3] - box[1]) / (qr_modules(text).shape[0] + 2 * QUIET_MODULES)


def crop_box(gray: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """The box grown by MARGIN_FRAC of its longer side, clipped to the image (a view)."""
    x1, y1, x2, y2 = box
    m = MARGIN_FRAC * max(x2 - x1, y2 - y1)
    h, w = gray.shape
    c1, r1 = max(int(math.floor(x1 - m)), 0), max(int(math.floor(y1 - m)), 0)
    c2, r2 = min(int(math.ceil(x2 + m)), w), min(int(math.ceil(y2 + m)), h)
    return gray[r1:r2, c1:c2]


Decoder = Callable[[np.ndarray, np.ndarray, tuple, "CameraMotion | None"], str]


def decoders() -> dict[str, Decoder]:
    """Name -> f(gray image, crop, box, camera motion) giving the decoded text ('' when none)."""
    import zxingcpp

    from poi.detectors import qr

    aruco, classic = cv2.QRCodeDetectorAruco(), cv2.QRCodeDetector()

    def cv(det):
        def f(_gray, crop, _box, _motion=None):
            try:
                return det.detectAndDecode(crop)[0] or ""
            except cv2.error:
                return ""

        return f

    def zx(_gray, crop, _box, _motion):
        found = zxingcpp.read_barcodes(crop, formats=zxingcpp.BarcodeFormat.QRCode)
        return found[0].text if found else ""

    def cv_reader(_gray, crop, box, _motion):
        # poi/detectors/qr.py before zxing-cpp (commit d2c3cd5): the crop scaled so a module of a
        # 33-module code is 3 px (at most 8x), then twice that, each as it is and with a white
        # border, through both OpenCV decoders
        s0 = float(np.clip(3.0 * 33 / max(min(box[2] - box[0], box[3] - box[1]), 1.0), 1.0, 8.0))
        for s in dict.fromkeys((s0, min(2.0 * s0, 8.0))):
            img = crop if s == 1.0 else cv2.resize(crop, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
            b = int(np.ceil(4 * min(img.shape) / 33))
            for cand in (img, cv2.copyMakeBorder(img, b, b, b, b, cv2.BORDER_CONSTANT, value=255)):
                for det in (aruco, classic):
                    text = cv(det)(None, cand, None, None)
                    if text:
                        return text
        return ""

    def reader(gray, _crop, box, _motion):
        return qr.decode_qr(gray, box) or ""

    def reader_gyro(gray, _crop, box, motion):
        return qr.decode_qr(gray, box, motion=motion) or ""

    return {
        "cv-aruco": cv(aruco),
        "cv-classic": cv(classic),
        "cv-reader": cv_reader,
        "zxing": zx,
        "reader": reader,
        "reader+gyro": reader_gyro,
    }


def pan_motion(blur_px: float, exposure_s: float, intr: Intrinsics) -> CameraMotion:
    """The pan (a turn about the optical y axis) that moves the principal point ``blur_px``
    along u in ``exposure_s``: omega = 2 atan(blur / (2 fx)) / exposure."""
    w = 2.0 * math.atan(blur_px / (2.0 * intr.fx)) / exposure_s
    return CameraMotion(omega_optical=np.array([0.0, w, 0.0]), exposures_s=(exposure_s,), intrinsics=intr)


def measure(
    sc: Scenario,
    distances: list[float],
    angles_deg: list[float],
    blurs_px: list[float],
    n_codes: int,
    side_m: float,
    seed: int,
    anisotropic: bool = True,
    decs: dict[str, Decoder] | None = None,
) -> tuple[list[dict], dict[str, float]]:
    """One row per view (distance, angle, blur, px per module, box, and each decoder's read 0/1),
    and each decoder's CPU seconds in all; ``decs`` defaults to :func:`decoders`."""
    import mujoco  # after sim (importing sim chooses MUJOCO_GL before mujoco is loaded)

    d = sc.sensors.d435
    intr = d435_intrinsics(d.width, d.height, d.fx, d.fy, d.ppx, d.ppy)
    col = d.colour
    lux = lux_of_decoded_one(
        sc.lighting, col.lux if col.lux is not None else LIGHT_LEVEL_LUX[sc.lighting], col.gamma
    )
    camera = ColourCamera(col, intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy)
    rng = np.random.default_rng(seed)
    letters = rng.permutation(26)[:n_codes]
    texts = [f"Chart {chr(ord('A') + int(i))}" for i in letters]
    xml, files = build_scene(texts, side_m, intr, LAMP_WHITE_LEVEL[sc.lighting])
    model = mujoco.MjModel.from_xml_string(xml, files)
    data = mujoco.MjData(model)
    cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, "d435")
    h = side_m / 2
    corners = np.array([[0, -h, h], [0, h, h], [0, h, -h], [0, -h, -h]], float)
    decs = decoders() if decs is None else decs
    cpu = dict.fromkeys(decs, 0.0)
    rows = []
    with SceneRenderer(model, intr.width, intr.height, "d435", anisotropic=anisotropic) as r:
        for dist in distances:
            for ang in angles_deg:
                for i, text in enumerate(texts):
                    a = math.radians(ang + rng.uniform(-1, 1) * MAX_YAW_JITTER_DEG)
                    centre = np.array([0.0, i * CARD_SPACING_M, 0.0])
                    data.mocap_pos[0] = centre + dist * np.array([math.cos(a), math.sin(a), 0.0])
                    yaw = a + math.pi  # rig x forward, towards the card
                    data.mocap_quat[0] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
                    mujoco.mj_forward(model, data)
                    r.update(data)
                    rgb, _depth = r.color_depth()
                    exposure = steady_state_exposure(meter(rgb, col.gamma), col, lux)
                    uv = project(
                        corners + centre, data.cam_xpos[cam_id], data.cam_xmat[cam_id].reshape(3, 3), intr
                    )
                    box = (*uv.min(axis=0), *uv.max(axis=0))
                    for blur in blurs_px:
                        frame = camera.render(rgb, exposure, lux, rng=rng, pool=None, motion_px=(blur, 0.0))
                        motion = pan_motion(blur, exposure.exposure_ms / 1000.0, intr)
                        gray = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY)
                        crop = np.ascontiguousarray(crop_box(gray, box))
                        row = {
                            "dist": dist,
                            "angle": ang,
                            "blur": blur,
                            "px_per_module": px_per_module(box, text),
                            "box_w": box[2] - box[0],
                            "box_h": box[3] - box[1],
                        }
                        for name, f in decs.items():
                            t0 = time.process_time()
                            got = f(gray, crop, box, motion)
                            cpu[name] += time.process_time() - t0
                            row[name] = int(got == text)
                        rows.append(row)
    return rows, cpu


def trial_views(sc: Scenario, step: int = 1) -> list[dict]:
    """The QR views of a trial's frames (every ``step``-th) that the oracle boxes and the funnel
    counts in view (at least 35 % visible, box at least 12 px on its shorter side): each a grey
    crop round the truth box (half its longer side of margin, clipped to the frame), the box in
    the crop's pixels, the text, and the view's distance, angle off the code's normal, visible
    fraction, the frame's motion blur (px) and the camera's motion as the pipeline takes it."""
    from poi.config import PipelineConfig
    from sim.simulator import Simulation

    views = []
    max_exposure_s = PipelineConfig().qr.max_exposure_ms / 1000.0
    with Simulation(sc) as sim:
        sim.truth_boxes = True
        T = np.array(sim.T_tracker_optical_nominal)
        for frame, truth in sim.frames(step=step):
            motion = camera_motion(frame, T, max_exposure_s)
            gray = None
            for v in truth.visible:
                x1, y1, x2, y2 = v.box_xyxy
                shown = dict(visible_fraction=v.visible_fraction, pixels=v.pixels)
                # the views the oracle boxes and the funnel counts (poi.core.in_view)
                if v.type != "qr" or not boxable_view(v.type, **shown, min_side_px=min(x2 - x1, y2 - y1)):
                    continue
                if gray is None:
                    gray = cv2.cvtColor(frame.rgb, cv2.COLOR_RGB2GRAY)
                m = 0.5 * max(x2 - x1, y2 - y1)
                c1, r1 = max(int(x1 - m), 0), max(int(y1 - m), 0)
                c2, r2 = min(int(math.ceil(x2 + m)), gray.shape[1]), min(int(math.ceil(y2 + m)), gray.shape[0])
                views.append(
                    {
                        "gray": gray[r1:r2, c1:c2].copy(),
                        "box": (x1 - c1, y1 - r1, x2 - c1, y2 - r1),
                        "text": v.text,
                        "frame": truth.index,
                        "id": v.id,
                        "dist": float(np.linalg.norm(v.position_cam)),
                        "angle": v.view_angle_deg,
                        "visible": v.visible_fraction,
                        "blur": truth.blur_px,
                        "motion": motion,
                        "offset": (c1, r1),
                    }
                )
    return views


def decode_views(views: list[dict], decs: dict[str, Decoder] | None = None) -> tuple[list[dict], dict[str, float]]:
    """Rows as :func:`measure` gives them for the views of :func:`trial_views` (the motion of a
    view's crop taken at its place in the frame)."""
    decs = decoders() if decs is None else decs
    cpu = dict.fromkeys(decs, 0.0)
    rows = []
    for v in views:
        gray, box = v["gray"], v["box"]
        crop = np.ascontiguousarray(crop_box(gray, box))
        row = {k: v[k] for k in ("frame", "id", "dist", "angle", "visible", "blur")}
        row.update(px_per_module=px_per_module(box, v["text"]), box_w=box[2] - box[0], box_h=box[3] - box[1])
        motion = v.get("motion")
        if motion is not None:  # the crop's pixels are the frame's shifted by its offset
            c1, r1 = v["offset"]
            k = motion.intrinsics
            motion = CameraMotion(
                omega_optical=motion.omega_optical,
                exposures_s=motion.exposures_s,
                intrinsics=dataclasses.replace(k, ppx=k.ppx - c1, ppy=k.ppy - r1),
            )
        for name, f in decs.items():
            t0 = time.process_time()
            got = f(gray, crop, box, motion)
            cpu[name] += time.process_time() - t0
            row[name] = int(got == v["text"])
        rows.append(row)
    return rows, cpu


def table(rows: list[dict], key: str, edges: list[float], names: list[str]) -> list[str]:
    """Markdown lines: per bin of ``key`` (edges[i] <= v < edges[i + 1]) each decoder's reads / views."""
    out = [f"| {key} | views | " + " | ".join(names) + " |", "|---|---:|" + "---:|" * len(names)]
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = [r for r in rows if lo <= r[key] < hi]
        if not sel:
            continue
        cells = [f"{100.0 * sum(r[n] for r in sel) / len(sel):.0f} %" for n in names]
        out.append(f"| {lo:g}-{hi:g} | {len(sel)} | " + " | ".join(cells) + " |")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scenario", default="default")
    ap.add_argument("--set", action="append", default=[], help="a scenario setting key=value")
    ap.add_argument("--distances", type=float, nargs="+", default=[0.8, 1.2, 1.6, 2.0, 2.5, 3.0, 3.5])
    ap.add_argument("--angles", type=float, nargs="+", default=[0.0, 30.0, 50.0, 65.0, 75.0])
    ap.add_argument("--blur-px", type=float, nargs="+", default=[0.0, 3.0, 6.0])
    ap.add_argument("--codes", type=int, default=4)
    ap.add_argument("--side-m", type=float, default=0.20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-aniso", action="store_true", help="render without anisotropic filtering")
    ap.add_argument("--trial", action="store_true", help="the scenario's trial frames instead of the card scene")
    ap.add_argument("--step", type=int, default=1, help="with --trial, every step-th frame")
    ap.add_argument("--views", help="with --trial, a pickle of the views: read if it exists, else written")
    args = ap.parse_args()
    if args.codes < 1 or args.codes > 26 or any(d <= 0 for d in args.distances):
        ap.error("--codes must be 1..26 and every distance positive")
    sc = apply_settings(load_scenario(args.scenario), args.set)
    t0 = time.process_time()
    if args.trial:
        if args.views and Path(args.views).exists():
            views = pickle.loads(Path(args.views).read_bytes())
        else:
            views = trial_views(sc, args.step)
            if args.views:
                Path(args.views).write_bytes(pickle.dumps(views))
        rows, cpu = decode_views(views)
    else:
        rows, cpu = measure(
            sc, args.distances, args.angles, args.blur_px, args.codes, args.side_m, args.seed, not args.no_aniso
        )
    names = list(cpu)
    what = (
        "its trial's QR views"
        if args.trial
        else f"{args.codes} codes of {args.side_m} m, anisotropic {'off' if args.no_aniso else 'on'}, "
        f"seed {args.seed}"
    )
    print(
        f"scenario {args.scenario!r} {' '.join(args.set)} (lighting {sc.lighting}), {what}: {len(rows)} views, "
        f"{time.process_time() - t0:.0f} CPU s"
    )
    print()
    print("CPU ms per call: " + ", ".join(f"{n} {1000 * cpu[n] / len(rows):.1f}" for n in names))
    print()
    sharp = [r for r in rows if r["blur"] < 1.0]
    print("views with under 1 px of motion blur, by pixels per module:")
    print()
    print("\n".join(table(sharp, "px_per_module", [0, 1, 1.5, 2, 2.5, 3, 4, 6, 100], names)))
    print()
    print("views at >= 3 px a module, under 1 px of motion blur, by angle off the code's normal:")
    print()
    still = [r for r in rows if r["px_per_module"] >= 3.0]
    print("\n".join(table([r for r in still if r["blur"] < 1.0], "angle", [0, 20, 40, 55, 70, 90], names)))
    print()
    print("views at >= 3 px a module, under 55 degrees, by motion blur (px):")
    print()
    print("\n".join(table([r for r in still if r["angle"] < 55], "blur", [0, 1, 4, 7, 100], names)))
    print()
    if args.trial:
        print("views at >= 3 px a module by the visible fraction of the code:")
        print()
        print("\n".join(table(still, "visible", [0.35, 0.6, 0.9, 1.01], names)))
        print()
        whole = [r for r in rows if r["visible"] >= 0.9 and r["blur"] < 1.0]
        print("views at least 90 % visible with under 1 px of motion blur, by pixels per module:")
        print()
        print("\n".join(table(whole, "px_per_module", [0, 1, 1.5, 2, 2.5, 3, 100], names)))
        print()
    print("all views at >= 3 px a module (the issue's target):")
    print()
    print("\n".join(table(still, "px_per_module", [3, 100], names)))


if __name__ == "__main__":
    main()
