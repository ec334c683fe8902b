"""Object models: names, compilation, and what a camera sees of them (rendered with MuJoCo)."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest

from sim.world.placement import SIZE_AT_RRL_M

# isort: off
import sim.gl  # noqa: F401  (sets MUJOCO_GL before mujoco is imported)
import mujoco

# isort: on
from maze_assets.hazmat import ORANGE, RED, YELLOW
from maze_assets.mjcf import SceneAssets, fmt
from maze_assets.models import (
    ARENA_SIZE_M,
    BALL_RGBA,
    FLAT_TYPES,
    PILLAR_RGBA,
    QUAD_OFFSET_M,
    ModelError,
    build_object,
    door_height_m,
)
from maze_assets.objects import PlacedObject
from maze_assets.qr import draw_qr
from poi.core.names import TYPES

W, H = 640, 480
# the sizes placement gives each type at RRL scale (a fiducial is a real 300 mm pipe, a Landolt-C
# target's card a real 64 mm print)
SIZES = {**SIZE_AT_RRL_M, **ARENA_SIZE_M, "fiducial": 0.3, "landolt-c": 0.0637}
TEXTS = {"hazmat": "organic-peroxide", "qr": "Chart M", "landolt-c": "1:E 2:N 3:NE 4:S 5:W"}
SPACING_M = 4.0  # objects stand this far apart along y, so each camera sees only its own


def _object(i: int, type_: str, **kw) -> PlacedObject:
    """Object i faces -x (yaw = pi) towards a camera on the -x side; its centre at z = 1."""
    args = {"id": i, "type": type_, "text": TEXTS.get(type_, ""), "size_m": SIZES[type_]}
    args |= {"position": [0.0, SPACING_M * i, 1.0], "yaw": np.pi}
    args |= kw
    return PlacedObject(**args)


def _scene(objects: list[PlacedObject], cam_dist_m: float = 1.0):
    """A lit scene with one camera per object, cam_dist_m in front of it along -x."""
    assets = SceneAssets()
    root = ET.Element("mujoco")
    ET.SubElement(root, "compiler", angle="radian")
    vis = ET.SubElement(root, "visual")
    ET.SubElement(vis, "global", offwidth=str(W), offheight=str(H))
    ET.SubElement(vis, "headlight", ambient="0.5 0.5 0.5", diffuse="0.5 0.5 0.5", specular="0 0 0")
    root.append(assets.asset)
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "geom", name="floor", type="plane", size="50 50 0.1", rgba="0.5 0.5 0.5 1")
    for o in objects:
        world.append(build_object(o, assets))
        p = o.position
        # camera looking along +x: its x axis (image right) is -y, its y axis (image up) is z
        ET.SubElement(
            world,
            "camera",
            name=f"cam_{o.id}",
            pos=fmt([p[0] - cam_dist_m, p[1], p[2]]),
            xyaxes="0 -1 0 0 0 1",
            fovy="45",
        )
    xml = ET.tostring(root, encoding="unicode")
    model = mujoco.MjModel.from_xml_string(xml, assets.files)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data, assets


def _segmentation(model, data, cam: str) -> np.ndarray:
    r = mujoco.Renderer(model, H, W)
    r.enable_segmentation_rendering()
    r.update_scene(data, cam)
    seg = r.render()
    r.close()
    return seg


def _rgb(model, data, cam: str) -> np.ndarray:
    r = mujoco.Renderer(model, H, W)
    r.update_scene(data, cam)
    img = r.render()
    r.close()
    return img


@pytest.fixture(scope="module")
def all_types():
    objects = [_object(i, t) for i, t in enumerate(TYPES)]
    return objects, *_scene(objects, cam_dist_m=1.6)


def test_every_type_builds_with_named_non_colliding_geoms():
    assets = SceneAssets()
    for i, t in enumerate(TYPES):
        o = _object(i, t, yaw=0.3)
        body = build_object(o, assets, wall_height_m=1.2, wall_thickness_m=0.05)
        assert body.tag == "body" and body.get("name") == f"poi_{i}_{t}"
        assert body.get("euler") == fmt([0, 0, 0.3])
        assert body.get("pos") == fmt(o.position)
        geoms = list(body.iter("geom"))
        assert geoms, t
        names = [g.get("name") for g in geoms]
        assert len(set(names)) == len(names)
        for g in geoms:
            assert re.fullmatch(rf"poi_{i}_{re.escape(t)}_[a-z0-9_]+", g.get("name"))
            assert (g.get("contype"), g.get("conaffinity"), g.get("group")) == ("0", "0", "0")
            assert g.get("material", "").startswith("objmat_")


def test_compiles_and_steps_without_warnings(all_types, capfd, recwarn):
    _, model, data, _ = all_types
    for _ in range(3):
        mujoco.mj_step(model, data)
    assert all(w.number == 0 for w in data.warning)
    out, err = capfd.readouterr()
    assert "WARNING" not in (out + err).upper()
    assert len(recwarn) == 0


@pytest.mark.slow
def test_each_object_is_seen_by_its_camera(all_types):
    objects, model, data, _ = all_types
    for o in objects:
        seg = _segmentation(model, data, f"cam_{o.id}")
        geom_ids = seg[:, :, 0][seg[:, :, 1] == int(mujoco.mjtObj.mjOBJ_GEOM)]
        names = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) for g in geom_ids}
        own = [n for n in names if n and n.startswith(f"poi_{o.id}_{o.type}_")]
        assert own, o.type
        mask = np.isin(
            seg[:, :, 0],
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n) for n in own],
        ) & (seg[:, :, 1] == int(mujoco.mjtObj.mjOBJ_GEOM))
        # the smallest object (a 0.2 m sign at 1.6 m, fy = 240 / tan(22.5 deg) = 579 px)
        # covers (0.2 * 579 / 1.6)^2 = 5200 px; 1000 px means "clearly there"; a Landolt-C card,
        # a 64 mm print, covers (0.0637 * 579 / 1.6)^2 = 531 px
        assert mask.sum() > (400 if o.type == "landolt-c" else 1000), (o.type, int(mask.sum()))
        # the reference point is inside the object: the mask's centre is near the image
        # centre (within a quarter of the image: the doll and heater are off-centre by design)
        rows, cols = np.nonzero(mask)
        assert abs(cols.mean() - W / 2) < W / 4 and abs(rows.mean() - H / 2) < H / 4, o.type


def test_flat_items_share_textures_and_sit_in_front_of_the_wall():
    assets = SceneAssets()
    for i in range(3):
        build_object(_object(i, "hazmat", text="poison"), assets)
    build_object(_object(3, "hazmat", text="oxidizer"), assets)
    textures = [t.get("name") for t in assets.asset.iter("texture")]
    assert textures == ["objtex_hazmat_poison", "objtex_hazmat_oxidizer"]
    mesh = next(assets.asset.iter("mesh"))
    v = np.array(mesh.get("vertex").split(), float).reshape(-1, 3)
    assert np.allclose(v[:, 0], QUAD_OFFSET_M)
    assert np.allclose(np.ptp(v[:, 1]), 0.25) and np.allclose(np.ptp(v[:, 2]), 0.25)
    body = build_object(_object(4, "exit-sign"), assets)
    size = np.array(body.find("geom").get("size").split(), float)  # the backing box
    assert np.allclose(size[1:], [0.15, 0.075])  # 0.30 m wide, 0.15 m high


def _qr_first_corner_is_top_left(img: np.ndarray, text: str) -> bool:
    """Decode ``img``; True when the code's own top-left corner is the image's top-left.

    OpenCV 5 decodes mirrored codes too, so decoding alone does not prove orientation. The
    detector returns the corners in the code's order (top-left, top-right, bottom-right,
    bottom-left of the code itself, the first at the finder pattern there): an upright,
    unmirrored code has its first corner nearest the image's top-left; mirrored left to
    right, that corner is the image's top-right.
    """
    decoded, pts, _ = cv2.QRCodeDetector().detectAndDecode(img)
    assert decoded == text
    pts = pts.reshape(4, 2)
    return int(np.argmin(pts.sum(axis=1))) == 0


@pytest.mark.slow
def test_rendered_qr_decodes_and_is_not_mirrored():
    assert _qr_first_corner_is_top_left(draw_qr("Chart QZ", 256), "Chart QZ")
    o = _object(0, "qr", text="Chart QZ")
    model, data, _ = _scene([o], cam_dist_m=1.0)
    img = _rgb(model, data, "cam_0")
    assert _qr_first_corner_is_top_left(img, "Chart QZ")
    # the same check fails on the render mirrored left to right
    assert not _qr_first_corner_is_top_left(np.ascontiguousarray(img[:, ::-1]), "Chart QZ")


def _hue_close(px: np.ndarray, rgb, tol_deg: float = 12.0) -> bool:
    """Same hue (lighting scales brightness, not hue) and clearly saturated."""
    h1 = cv2.cvtColor(px.reshape(1, 1, 3).astype(np.uint8), cv2.COLOR_RGB2HSV_FULL)[0, 0]
    h2 = cv2.cvtColor(np.uint8([[rgb]]), cv2.COLOR_RGB2HSV_FULL)[0, 0]
    dh = abs(int(h1[0]) - int(h2[0])) * 360 / 256
    return min(dh, 360 - dh) < tol_deg and h1[1] > 120


@pytest.mark.parametrize(
    ("label", "top", "bottom"),
    [("organic-peroxide", RED, YELLOW), ("explosive", ORANGE, ORANGE)],
)
@pytest.mark.slow
def test_rendered_placard_is_upright(label, top, bottom):
    o = _object(0, "hazmat", text=label)
    model, data, _ = _scene([o], cam_dist_m=1.0)
    img = _rgb(model, data, "cam_0")
    seg = _segmentation(model, data, "cam_0")
    face = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "poi_0_hazmat_face")
    rows, cols = np.nonzero(seg[:, :, 0] == face)
    r0, r1, c = rows.min(), rows.max(), int(cols.mean())
    side = r1 - r0
    # 12 % of the side below the top corner lies inside the border, above the symbol
    assert _hue_close(img[r0 + int(0.12 * side), c], top), img[r0 + int(0.12 * side), c]
    # 35 % above the bottom corner: the lower field (beside the class number)
    px = img[r1 - int(0.35 * side), c - int(0.2 * side)]
    assert _hue_close(px, bottom), px
    if top != bottom:  # upside down would swap them
        assert not _hue_close(img[r0 + int(0.12 * side), c], bottom)


@pytest.mark.parametrize("roll", [np.pi, np.pi / 2])
@pytest.mark.slow
def test_rolled_placard_turns_about_its_face_normal(roll):
    # organic-peroxide: red top half, yellow bottom half. Turned by pi the red half is at
    # the bottom; turned by pi/2 counter-clockwise (as the viewer sees it) it is on the left.
    o = _object(0, "hazmat", text="organic-peroxide", roll=roll)
    model, data, _ = _scene([o], cam_dist_m=1.0)
    img = _rgb(model, data, "cam_0")
    seg = _segmentation(model, data, "cam_0")
    face = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "poi_0_hazmat_face")
    rows, cols = np.nonzero(seg[:, :, 0] == face)
    r0, r1, c0, c1 = rows.min(), rows.max(), cols.min(), cols.max()
    rc, cc = (r0 + r1) // 2, (c0 + c1) // 2
    if roll == np.pi:
        near_red, near_yellow = img[r1 - int(0.12 * (r1 - r0)), cc], img[r0 + int(0.12 * (r1 - r0)), cc]
    else:
        near_red, near_yellow = img[rc, c0 + int(0.12 * (c1 - c0))], img[rc, c1 - int(0.12 * (c1 - c0))]
    assert _hue_close(near_red, RED), near_red
    assert _hue_close(near_yellow, YELLOW), near_yellow


@pytest.mark.slow
def test_cut_placard_is_a_diamond_and_a_sheet_is_a_square():
    from maze_assets.hazmat import placard_style

    cut = next(k for k in range(100) if placard_style("poison", k).look.cut)
    sheet = next(k for k in range(100) if not placard_style("poison", k).look.cut)
    fill = {}
    for name, seed in (("cut", cut), ("sheet", sheet)):
        o = _object(0, "hazmat", text="poison", look_seed=seed)
        model, data, _ = _scene([o], cam_dist_m=1.0)
        seg = _segmentation(model, data, "cam_0")
        ids = {
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"poi_0_hazmat_{p}") for p in ("face", "backing")
        }
        mask = np.isin(seg[:, :, 0], list(ids))
        rows, cols = np.nonzero(mask)
        box = mask[rows.min() : rows.max() + 1, cols.min() : cols.max() + 1]
        fill[name] = box.mean()
    # a diamond fills half its bounding box, a square all of it (edge pixels aside)
    assert abs(fill["cut"] - 0.5) < 0.05, fill
    assert fill["sheet"] > 0.95, fill


@pytest.mark.slow
def test_rendered_exit_sign_arrow_points_right():
    o = _object(0, "exit-sign")
    model, data, _ = _scene([o], cam_dist_m=1.0)
    img = _rgb(model, data, "cam_0")
    seg = _segmentation(model, data, "cam_0")
    face = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "poi_0_exit-sign_face")
    rows, cols = np.nonzero(seg[:, :, 0] == face)
    c0, c1 = cols.min(), cols.max()
    white = img.astype(int).min(axis=2) > 200
    r0, r1, c0, c1 = rows.min(), rows.max(), cols.min(), cols.max()
    h, w = r1 - r0, c1 - c0
    # the arrow lies in x 0.70..0.93 of the width: head base at 0.82, 0.40 of the height
    # tall, tip at 0.93 on the mid line (maze_assets/signs.py); skip the 6 % border
    band = white[r0 + int(0.06 * h) : r1 - int(0.06 * h), c0 + int(0.68 * w) : c0 + int(0.95 * w)]
    counts = band.sum(axis=0)
    base = int(np.argmax(counts))
    assert counts[base] > 0.3 * h  # the head's base (a mirrored sign has a leg here)
    tip = int(np.flatnonzero(counts).max())
    assert tip > base + 0.05 * w  # the head narrows to the right: it points right
    tip_rows = np.flatnonzero(band[:, tip]) + int(0.06 * h)
    assert abs(tip_rows.mean() - h / 2) < 0.1 * h


def test_door_dimensions():
    assets = SceneAssets()
    body = build_object(_object(0, "door"), assets, wall_height_m=1.2, wall_thickness_m=0.05)
    leaf = next(g for g in body.iter("geom") if g.get("name") == "poi_0_door_leaf")
    size = np.array(leaf.get("size").split(), float)
    # leaf: 0.8 m wide and min(2.0, 0.9 * 1.2) = 1.08 m high (less a 3 mm gap each side)
    assert np.allclose(2 * size[1:], [0.8 - 0.006, 1.08 - 0.006])
    assert door_height_m(3.0) == 2.0
    with pytest.raises(ModelError):
        build_object(_object(1, "door"), assets, wall_height_m=0.0)


def test_bad_size_is_rejected():
    with pytest.raises(ModelError, match="size_m"):
        build_object(_object(0, "valve", size_m=0.0), SceneAssets())
    with pytest.raises(ValueError, match="laser"):
        build_object(_object(1, "hazmat", text="laser"), SceneAssets())


@pytest.mark.parametrize("light", [0.5, 0.15])  # bright and dim headlight
@pytest.mark.slow
def test_arena_pillars_and_ball_render_in_distinct_matte_hues(light):
    types = [*PILLAR_RGBA, "ball"]
    objects = [_object(i, t) for i, t in enumerate(types)]
    model, data, _ = _scene(objects, cam_dist_m=1.6)
    model.vis.headlight.ambient[:] = float(light)
    model.vis.headlight.diffuse[:] = float(light)
    hues = {}
    for o in objects:
        img = _rgb(model, data, f"cam_{o.id}")
        seg = _segmentation(model, data, f"cam_{o.id}")
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"poi_{o.id}_{o.type}_body")
        px = img[seg[:, :, 0] == body].astype(float)
        assert len(px) > 1000, (o.type, light)
        rgba = PILLAR_RGBA.get(o.type, BALL_RGBA)
        target = tuple(int(255 * c) for c in rgba[:3])
        assert _hue_close(np.median(px, axis=0), target, tol_deg=15.0), (o.type, np.median(px, axis=0))
        hsv = cv2.cvtColor(np.uint8([[np.median(px, axis=0)]]), cv2.COLOR_RGB2HSV_FULL)[0, 0]
        hues[o.type] = int(hsv[0]) * 360 / 256
        # matte: no specular highlight, the brightest pixel stays close to the median
        assert px.max(axis=0).max() < np.median(px, axis=0).max() + 60, o.type
    names = sorted(hues)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            d = abs(hues[a] - hues[b])
            assert min(d, 360 - d) > 40, (a, b, hues)


def test_flat_types_listed():
    assert set(FLAT_TYPES) <= set(TYPES)
