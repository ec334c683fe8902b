"""Build the MuJoCo model of a scenario: floor, walls, lights, objects and the camera rig.

Walls are boxes named ``wall_{row}_{col}_{side}`` (the maze's wall pieces), the goal
arena's obstacles boxes named ``obstacle_{k}``;
objects are bodies named ``poi_{id}_{type}`` built by ``maze_assets.models``;
the camera rig is a mocap body ``camera_rig`` whose child camera ``d435``
reproduces the D435 colour intrinsics (``sim.camera``). Rendering only: no
geom collides, the robot is kinematic.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco  # noqa: E402
import numpy as np

import sim.gl  # noqa: F401  (must precede the mujoco import)
from maze_assets.clutter import build_clutter, build_milk_crates, place_clutter, place_milk_crates  # noqa: E402
from maze_assets.hazmat import placard_style, reprint  # noqa: E402
from maze_assets.mjcf import SceneAssets, fmt  # noqa: E402
from maze_assets.models import (  # noqa: E402
    build_holder,
    build_object,
    build_page,
    door_frame_extent_m,
    frames_item,
    placard_key,
)
from maze_assets.objects import PlacedObject  # noqa: E402
from maze_assets.surfaces import (  # noqa: E402
    DATASET_FLOOR_KINDS,
    DATASET_FLOOR_PX,
    FLOOR_KINDS,
    SHEET_M,
    WALL_KINDS,
    draw_dataset_floor,
    draw_floor_kind,
    draw_hall_wall,
    draw_wall,
)
from poi.core.types import Intrinsics  # noqa: E402
from sim.camera import mujoco_camera_attrs  # noqa: E402

if TYPE_CHECKING:
    from sim.world.arena import Obstacle

CAMERA_NAME = "d435"
RIG_BODY = "camera_rig"
TEXTURE_PX = 256
CURVE_SLICES, CURVE_STACKS = 12, 8  # tessellation of round geoms (MuJoCo's default: 28, 16)


@dataclass(kw_only=True)
class World:
    model: mujoco.MjModel
    data: mujoco.MjData
    xml: str
    assets: dict[str, bytes]
    rig_mocap_id: int
    geom_object_id: np.ndarray  # (ngeom,) object id of each geom, -1 for walls/floor
    # (ngeom,) the object id a box around the object takes each geom in with (truth boxes,
    # segmentation): geom_object_id but -1 for a flat item's backing (maze_assets.models.frames_item)
    geom_box_object_id: np.ndarray


@dataclass(frozen=True, kw_only=True)
class SceneLooks:
    """What a training scene (poibench dataset, eval/detector/dataset.py) looks like beyond a
    trial's: none of it is ever set in a trial, whose world is built as before.

    ``floor``: one of ``maze_assets.surfaces.DATASET_FLOOR_KINDS`` in place of the arena's
    floor (the tile glazed: a specular material). Per placard with its own print, from
    ``SeedSequence([seed, id, 58])``: saturation kept drawn from ``print_saturation`` and
    ink black from ``print_black`` (``maze_assets.hazmat.reprint``), and on ``glossy_share``
    of them glossy paper (specular 0.7-1, shininess 0.3-0.9: lamps mirror in it as glare).
    ``offsamples``: MSAA samples of the offscreen buffer (a trial: 0). ``milk_crates``: open
    plastic crates standing near placards (``maze_assets.clutter.place_milk_crates``; unlabelled).
    """

    seed: int
    floor: str | None = None
    print_saturation: tuple[float, float] | None = None
    print_black: tuple[float, float] | None = None
    glossy_share: float = 0.0
    offsamples: int = 0
    milk_crates: int = 0

    def __post_init__(self) -> None:
        if self.floor is not None and self.floor not in DATASET_FLOOR_KINDS:
            raise ValueError(f"floor: expected one of {', '.join(DATASET_FLOOR_KINDS)}, got {self.floor!r}")
        if self.offsamples < 0:
            raise ValueError(f"offsamples must be >= 0, got {self.offsamples}")


GLOSSY_TILE = {"specular": 0.6, "shininess": 0.8}  # glazed tile: lamps leave highlights on it


def _reprint_placards(assets: SceneAssets, objects: list[PlacedObject], looks: SceneLooks) -> None:
    """Each placard's own print reprinted and its paper made glossy per ``looks`` (in place)."""
    done = set()
    for o in objects:
        if o.type != "hazmat" or o.look_seed is None or placard_key(o) in done:
            continue
        key = placard_key(o)
        done.add(key)
        rng = np.random.default_rng(np.random.SeedSequence([looks.seed, o.id, 58]))
        sat = float(rng.uniform(*looks.print_saturation)) if looks.print_saturation else 1.0
        black = float(rng.uniform(*looks.print_black)) if looks.print_black else None
        glossy = rng.random() < looks.glossy_share
        fname = f"objtex_{key}.png"
        if fname in assets.files and (sat != 1.0 or black is not None):
            import cv2

            rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(assets.files[fname], np.uint8), 1), cv2.COLOR_BGR2RGB)
            ink = placard_style(o.text, o.look_seed).look.ink_black
            out = reprint(rgb, sat, ink if black is None else black, ink)
            assets.files[fname] = cv2.imencode(".png", cv2.cvtColor(out, cv2.COLOR_RGB2BGR))[1].tobytes()
        if glossy:
            for el in assets.asset.iter("material"):
                if el.get("name") == f"objmat_{key}":
                    el.set("specular", fmt(rng.uniform(0.7, 1.0)))
                    el.set("shininess", fmt(rng.uniform(0.3, 0.9)))


# Illuminance of each lighting preset where its lamps light a surface fully, for the colour
# camera's exposure (sim/sensors/d435_color.py): a white surface the robot's lamp lights is
# at this level (lux_of_decoded_one). Judgements (docs/FACTS.md "D435 colour camera"): a brightly lit
# hall, a room lit by the robot's own lamp, a hall with a few spot lamps.
LIGHT_LEVEL_LUX: dict[str, float] = {"bright": 1000.0, "dim": 80.0, "uneven": 300.0}
# The render's (display-encoded) level of a white surface facing the robot's own lamp in each
# preset: the headlight's ambient plus diffuse (_lights); bright's sun takes it to 1.
LAMP_WHITE_LEVEL: dict[str, float] = {"bright": 1.0, "dim": 0.45, "uneven": 0.37}


def lux_of_decoded_one(lighting: str, lux: float, gamma: float) -> float:
    """The illuminance a decoded render value of 1 stands for, so that a white surface the
    robot's lamp lights (render level ``LAMP_WHITE_LEVEL``) is at ``lux``.

    The dim presets render their lit whites below 1; taking ``lux`` for a decoded 1 would
    count their darkness twice (a dim white at 80 lux read as 0.45 ** 2.2 * 80 = 14 lux).
    """
    return lux / LAMP_WHITE_LEVEL[lighting] ** gamma


# Shadow maps (``shadows``): MuJoCo renders one depth map of this size per shadow-casting light and
# frame, 4096 unless told. At 1024 a texel spans about 6 mm of a 6 m maze (a shadow's edge shows
# steps that size); 2048 cost 7% more wall time a frame than 1024 with bright's sun (README "Mazes":
# the cost of shadows measured per preset).
SHADOW_MAP_PX = 1024


def _lights(
    world: ET.Element,
    visual: ET.Element,
    lighting: str,
    maze,
    rng: np.random.Generator,
    light_height_m: float | None = None,
    shadows: bool = False,
) -> None:
    """Headlight and lights of a preset; ``light_height_m`` puts the spot lamps of ``uneven``
    at that height (default: 1.8 wall heights, under a maze's ceiling). With ``shadows`` the
    sun of ``bright`` and the spot lamps of ``uneven`` cast shadows (walls darken the floor
    and corners beside them, a crate's inside is shaded); the robot's own lamp, MuJoCo's
    headlight, casts none (it sits at the camera, where its shadows hide behind what casts
    them)."""
    w, h = maze.size_m
    cast = "true" if shadows else "false"
    if shadows:
        visual.find("quality").set("shadowsize", str(SHADOW_MAP_PX))
    top = maze.settings.wall_height_m * 2.5 + 1.0
    head = ET.SubElement(visual, "headlight")
    if lighting == "bright":
        head.set("ambient", "0.35 0.35 0.35")
        head.set("diffuse", "0.45 0.45 0.45")
        head.set("specular", "0.05 0.05 0.05")
        ET.SubElement(
            world,
            "light",
            name="sun",
            directional="true",
            castshadow=cast,
            pos=fmt([w / 2, h / 2, top]),
            dir="0.2 0.3 -1",
            diffuse="0.5 0.5 0.5",
        )
    elif lighting == "dim":
        head.set("ambient", "0.10 0.10 0.10")
        head.set("diffuse", "0.35 0.35 0.33")  # the robot's own lamp
        head.set("specular", "0.02 0.02 0.02")
    elif lighting == "uneven":
        head.set("ambient", "0.12 0.12 0.12")
        head.set("diffuse", "0.25 0.25 0.25")
        head.set("specular", "0.02 0.02 0.02")
        n = max(2, int(round(maze.rows * maze.cols / 4)))
        for i in range(n):
            x, y = rng.uniform(0, w), rng.uniform(0, h)
            g = rng.uniform(0.5, 1.0)
            ET.SubElement(
                world,
                "light",
                name=f"spot_{i}",
                castshadow=cast,
                pos=fmt([x, y, maze.settings.wall_height_m * 1.8 if light_height_m is None else light_height_m]),
                dir="0 0 -1",
                cutoff="60",
                exponent="2",
                attenuation="1 0.3 0.3",
                diffuse=fmt([g, g * 0.95, g * 0.85]),
            )
    else:
        raise ValueError(f"lighting: expected bright, dim or uneven, got {lighting!r}")


WALL_MATERIALS = 3  # wall sheet looks per scenario, each wall piece takes one
WALL_KIND_SHARES = (0.5, 0.3, 0.2)  # osb, plywood, painted
FLOOR_KIND_SHARES = (0.5, 0.3, 0.2)  # plywood, osb, painted
HALL_MARGIN_M = (3.0, 8.0)  # the hall's walls stand this far beyond the arena
HALL_HEIGHT_M = (6.0, 9.0)


def _hall(world: ET.Element, assets: SceneAssets, maze, rng: np.random.Generator) -> None:
    """The hall an arena stands in, seen above and beyond its walls: blockwork walls with a
    band of windows, a ceiling with rows of lamps and roof trusses (geoms named ``hall_*``).

    Lamps are emissive panels, not light sources: the scene's light comes from its preset.
    """
    w, h = maze.size_m
    m = float(rng.uniform(*HALL_MARGIN_M))
    top = float(rng.uniform(*HALL_HEIGHT_M))
    x0, y0, x1, y1 = -m, -m, w + m, h + m
    assets.texture("tex_hall", draw_hall_wall(TEXTURE_PX, rng), kind="cube")
    assets.material("hall_wall", texture="tex_hall")
    ceiling = tuple(float(v) for v in rng.uniform(0.35, 0.6, 3).round(2)) + (1.0,)
    ET.SubElement(assets.asset, "material", name="hall_ceiling", rgba=fmt(ceiling))
    ET.SubElement(assets.asset, "material", name="hall_lamp", rgba="1 1 0.96 1", emission="1")
    ET.SubElement(assets.asset, "material", name="hall_steel", rgba="0.3 0.32 0.35 1")
    common = {"contype": "0", "conaffinity": "0", "group": "1"}
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    half = [(x1 - x0) / 2, (y1 - y0) / 2]
    for name, pos, size in (
        ("hall_wall_s", [cx, y0, top / 2], [half[0], 0.1, top / 2]),
        ("hall_wall_n", [cx, y1, top / 2], [half[0], 0.1, top / 2]),
        ("hall_wall_w", [x0, cy, top / 2], [0.1, half[1], top / 2]),
        ("hall_wall_e", [x1, cy, top / 2], [0.1, half[1], top / 2]),
    ):
        ET.SubElement(
            world, "geom", name=name, type="box", material="hall_wall", pos=fmt(pos), size=fmt(size), **common
        )
    ET.SubElement(
        world,
        "geom",
        name="hall_ceiling",
        type="box",
        material="hall_ceiling",
        pos=fmt([cx, cy, top + 0.1]),
        size=fmt([half[0], half[1], 0.1]),
        **common,
    )
    span = float(rng.uniform(4.0, 7.0))  # trusses and lamp rows across the hall's width
    for k, x in enumerate(np.arange(x0 + span / 2, x1, span)):
        ET.SubElement(
            world,
            "geom",
            name=f"hall_truss_{k}",
            type="box",
            material="hall_steel",
            pos=fmt([x, cy, top - 0.4]),
            size=fmt([0.08, half[1], 0.25]),
            **common,
        )
        for j, y in enumerate(np.arange(y0 + span / 2, y1, span)):
            ET.SubElement(
                world,
                "geom",
                name=f"hall_lamp_{k}_{j}",
                type="box",
                material="hall_lamp",
                pos=fmt([x + span / 2, y, top - 0.05]),
                size=fmt([0.6, 0.15, 0.03]),
                **common,
            )


def door_gap_m(length_m: float, door: PlacedObject, wall_height_m: float) -> tuple[float, float, float]:
    """(a, b, top): a door's frame spans [a, b] along its wall piece (centred) and rises to ``top``."""
    fw, fh = door_frame_extent_m(door.size_m, wall_height_m)
    return (length_m - fw) / 2, (length_m + fw) / 2, fh


def build_world_xml(
    maze,
    objects: list[PlacedObject],
    intr: Intrinsics,
    lighting: str,
    rng: np.random.Generator,
    *,
    obstacles: Sequence[Obstacle] = (),
    light_height_m: float | None = None,
    clutter_per_cell: float = 0.0,
    shadows: bool = False,
    looks: SceneLooks | None = None,
) -> tuple[str, dict[str, bytes]]:
    """The MJCF text and its in-memory assets (PNG textures).

    ``obstacles`` (the goal arena's cubes, not POIs) are plywood boxes named by their
    ``name``; ``light_height_m`` and ``shadows``: see :func:`_lights`; ``clutter_per_cell``:
    distractors (``clutter_*`` geoms) a maze cell on average; ``looks``: a training
    scene's (:class:`SceneLooks`), drawn from its own seed (this ``rng``'s draws stay as they are).
    """
    root = ET.Element("mujoco", model="poibench")
    ET.SubElement(root, "compiler", angle="radian")
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(max(intr.width, 640)), offheight=str(max(intr.height, 480)))
    # Round geoms (capsules, cylinders, spheres, ellipsoids) tessellated CURVE_SLICES x
    # CURVE_STACKS instead of MuJoCo's 28 x 16: a capsule then costs a fifth of the CPU to
    # render on llvmpipe (bench/bench_render_geoms.py: 39 against 182 us) and the default
    # frame's colour render about 17% less; a silhouette r pixels in radius moves by at most
    # r (1 - cos(pi / 12)), 3.4% of r (tests/sim/test_render.py; issue 18)
    offsamples = "0" if looks is None else str(looks.offsamples)
    ET.SubElement(
        visual, "quality", offsamples=offsamples, numslices=str(CURVE_SLICES), numstacks=str(CURVE_STACKS)
    )
    ET.SubElement(visual, "map", znear="0.005", zfar="60")
    assets = SceneAssets()
    root.append(assets.asset)
    # a dim grey hall above the walls instead of black
    ET.SubElement(
        assets.asset,
        "texture",
        name="tex_sky",
        type="skybox",
        builtin="gradient",
        rgb1="0.62 0.62 0.64",
        rgb2="0.32 0.32 0.34",
        width="32",
        height="32",
    )
    world = ET.SubElement(root, "worldbody")
    _lights(world, visual, lighting, maze, rng, light_height_m, shadows)

    w, h = maze.size_m
    s = maze.settings
    floor_kind = FLOOR_KINDS[int(rng.choice(len(FLOOR_KINDS), p=FLOOR_KIND_SHARES))]
    floor_rgb = draw_floor_kind(floor_kind, TEXTURE_PX, rng)  # drawn always: rng's later draws stay
    floor_kw = {"texrepeat": [max(1.0, w / 1.2), max(1.0, h / 1.2)], "texuniform": False}
    if looks is not None and looks.floor is not None:
        floor_rgb = draw_dataset_floor(looks.floor, DATASET_FLOOR_PX, np.random.default_rng([looks.seed, 581]))
        # repeats over the whole plane (w + 2 by h + 2 m), so one tile is SHEET_M whatever the
        # maze's size (the trial's w / 1.2 make a small maze's floor tiles metres wide)
        floor_kw = {"texrepeat": [(w + 2.0) / SHEET_M, (h + 2.0) / SHEET_M], "texuniform": False}
        if looks.floor == "tile":
            floor_kw.update(GLOSSY_TILE)
    assets.texture("tex_floor", floor_rgb)
    assets.material("floor", texture="tex_floor", **floor_kw)
    ET.SubElement(
        world,
        "geom",
        name="floor",
        type="plane",
        material="floor",
        pos=fmt([w / 2, h / 2, 0]),
        size=fmt([w / 2 + 1.0, h / 2 + 1.0, 0.1]),
        contype="0",
        conaffinity="0",
    )
    wall_materials = []
    for k in range(WALL_MATERIALS):
        kind = WALL_KINDS[int(rng.choice(len(WALL_KINDS), p=WALL_KIND_SHARES))]
        # a cube texture fits the image to each face of a wall piece: one sheet per piece (a
        # 2D texture is mapped by the box's local x and y and streaks down a vertical face)
        assets.texture(f"tex_wall_{k}", draw_wall(kind, TEXTURE_PX, rng), kind="cube")
        assets.material(f"wall_{k}", texture=f"tex_wall_{k}")
        wall_materials.append(f"wall_{k}")
    doors = {o.wall: o for o in objects if o.type == "door" and o.wall}
    for seg in maze.wall_segments():
        material = wall_materials[int(rng.integers(len(wall_materials)))]
        p0, p1 = np.array([seg.x0, seg.y0]), np.array([seg.x1, seg.y1])
        length = float(np.linalg.norm(p1 - p0))
        d = (p1 - p0) / length
        yaw = float(np.arctan2(d[1], d[0]))
        # (start, end) along the piece and (bottom, top) of each box; each piece is
        # extended by half a thickness at both ends so corners close
        t2 = seg.thickness / 2
        boxes = [(-t2, length + t2, 0.0, s.wall_height_m)]
        if seg.name in doors:
            # the door fills a frame in the middle; wall stays either side and above it
            a, b, fh = door_gap_m(length, doors[seg.name], s.wall_height_m)
            boxes = [(-t2, a, 0.0, s.wall_height_m), (b, length + t2, 0.0, s.wall_height_m)]
            if fh < s.wall_height_m - 1e-6:
                boxes.append((a, b, fh, s.wall_height_m))
        for i, (u0, u1, z0, z1) in enumerate(boxes):
            if u1 - u0 <= 1e-6:
                continue
            mid = p0 + d * (u0 + u1) / 2
            name = seg.name if len(boxes) == 1 else f"{seg.name}_{i}"
            ET.SubElement(
                world,
                "geom",
                name=name,
                type="box",
                material=material,
                pos=fmt([mid[0], mid[1], (z0 + z1) / 2]),
                euler=fmt([0, 0, yaw]),
                size=fmt([(u1 - u0) / 2, t2, (z1 - z0) / 2]),
                contype="0",
                conaffinity="0",
            )
    for ob in obstacles:
        ET.SubElement(
            world,
            "geom",
            name=ob.name,
            type="box",
            material=wall_materials[0],
            pos=fmt([ob.center_xy[0], ob.center_xy[1], ob.size_m / 2]),
            size=fmt([ob.size_m / 2] * 3),
            contype="0",
            conaffinity="0",
        )
    _hall(world, assets, maze, rng)
    for el in build_clutter(place_clutter(maze, objects, rng, clutter_per_cell), assets):
        world.append(el)
    for obj in objects:
        world.append(build_object(obj, assets, wall_height_m=s.wall_height_m, wall_thickness_m=s.wall_thickness_m))
        page = build_page(obj, assets)  # the A4 sheet of a QR page (sim/world/placement.py)
        if page is not None:
            world.append(page)
        holder = build_holder(obj, assets)  # a flat item's board, sensor cabinet, crate or ramp
        if holder is not None:
            world.append(holder)

    if looks is not None:
        _reprint_placards(assets, objects, looks)
        crates = place_milk_crates(maze, objects, np.random.default_rng([looks.seed, 583]), looks.milk_crates)
        for el in build_milk_crates(crates, assets):
            world.append(el)
    rig = ET.SubElement(world, "body", name=RIG_BODY, mocap="true", pos="0 0 1")
    ET.SubElement(rig, "camera", name=CAMERA_NAME, **mujoco_camera_attrs(intr))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode"), assets.files


def build_world(
    maze,
    objects: list[PlacedObject],
    intr: Intrinsics,
    lighting: str,
    rng: np.random.Generator,
    *,
    obstacles: Sequence[Obstacle] = (),
    light_height_m: float | None = None,
    clutter_per_cell: float = 0.0,
    shadows: bool = False,
    looks: SceneLooks | None = None,
) -> World:
    xml, files = build_world_xml(
        maze,
        objects,
        intr,
        lighting,
        rng,
        obstacles=obstacles,
        light_height_m=light_height_m,
        clutter_per_cell=clutter_per_cell,
        shadows=shadows,
        looks=looks,
    )
    model = mujoco.MjModel.from_xml_string(xml, files)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rig_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, RIG_BODY)
    owner = np.full(model.ngeom, -1, dtype=np.int64)
    by_body = {o.body_name: o.id for o in objects}
    for g in range(model.ngeom):
        # a geom belongs to the object whose body is its body or an ancestor of it
        b = int(model.geom_bodyid[g])
        while b > 0:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)
            if name in by_body:
                owner[g] = by_body[name]
                break
            b = int(model.body_parentid[b])
    framed = [frames_item(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or "") for g in range(model.ngeom)]
    return World(
        model=model,
        data=data,
        xml=xml,
        assets=files,
        rig_mocap_id=int(model.body_mocapid[rig_body]),
        geom_object_id=owner,
        geom_box_object_id=np.where(framed, owner, -1),
    )
