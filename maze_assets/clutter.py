"""Distractors: what lies about in a real arena and is not an object of interest.

Crates, buckets, pipes, cables, cardboard boxes and debris stand against the walls
(clear of every point of interest), so a detector meets the things that fooled it on
real photos and the pipeline must not report them. They are geoms named
``clutter_{k}_{part}``: no ``poi_`` body, so the ground truth and the segmentation's
object map leave them out (sim/world/world.py). Drawn from an explicit ``rng``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from maze_assets.mjcf import SceneAssets, fmt
from maze_assets.objects import PlacedObject

CLUTTER_KINDS = ("crate", "bucket", "pipe", "cable", "box", "debris")
CLUTTER_SHARES = (0.2, 0.2, 0.2, 0.15, 0.15, 0.1)
POI_CLEARANCE_M = 0.6  # no distractor this close (in plan) to a point of interest
ITEM_SPACING_M = 0.4
MIN_CELL_M = 0.9  # smaller cells (RMRC lanes) get no distractors
BUCKET_RGBA = ((0.95, 0.45, 0.1, 1), (0.92, 0.92, 0.9, 1), (0.12, 0.12, 0.13, 1), (0.15, 0.35, 0.75, 1))
PIPE_RGBA = ((0.55, 0.57, 0.6, 1), (0.9, 0.88, 0.85, 1), (0.95, 0.5, 0.15, 1), (0.15, 0.15, 0.16, 1))
CABLE_RGBA = ((0.08, 0.08, 0.08, 1), (0.95, 0.55, 0.1, 1), (0.9, 0.8, 0.1, 1), (0.2, 0.3, 0.8, 1))


@dataclass(frozen=True, kw_only=True)
class ClutterItem:
    """One distractor: its kind, where it stands (plan, metres), which way the wall runs."""

    kind: str
    xy: tuple[float, float]
    along: tuple[float, float]  # unit vector along the wall it leans on
    out: tuple[float, float]  # unit normal out of that wall
    seed: int


def place_clutter(
    maze, objects: list[PlacedObject], rng: np.random.Generator, per_cell: float
) -> list[ClutterItem]:
    """About ``per_cell`` distractors a maze cell, each against a wall face, clear of the POIs.

    None in mazes with cells under ``MIN_CELL_M``: a crate 0.2 m off the wall would fill an
    RMRC lane (0.3 m cells) that the robot has to drive.
    """
    if per_cell < 0:
        raise ValueError(f"clutter per cell must be >= 0, got {per_cell}")
    if maze.settings.cell_size_m < MIN_CELL_M:
        return []
    faces = list(maze.wall_faces())
    n = int(round(per_cell * maze.rows * maze.cols))
    poi_xy = np.array([o.position[:2] for o in objects]).reshape(-1, 2)
    items: list[ClutterItem] = []
    for _ in range(n):
        for _attempt in range(50):
            f = faces[int(rng.integers(len(faces)))]
            normal = np.asarray(f.normal_xy, float)
            along = np.array([-normal[1], normal[0]])
            off = float(rng.uniform(-0.35, 0.35)) * f.length_m
            xy = np.asarray(f.center_xy, float) + along * off + normal * float(rng.uniform(0.12, 0.22))
            if len(poi_xy) and np.min(np.linalg.norm(poi_xy - xy, axis=1)) < POI_CLEARANCE_M:
                continue
            if any(np.hypot(*(np.array(i.xy) - xy)) < ITEM_SPACING_M for i in items):
                continue
            kind = CLUTTER_KINDS[int(rng.choice(len(CLUTTER_KINDS), p=CLUTTER_SHARES))]
            items.append(
                ClutterItem(
                    kind=kind,
                    xy=(float(xy[0]), float(xy[1])),
                    along=(float(along[0]), float(along[1])),
                    out=(float(normal[0]), float(normal[1])),
                    seed=int(rng.integers(2**31)),
                )
            )
            break
    return items


def _material(assets: SceneAssets, name: str, rgba) -> str:
    full = f"cluttermat_{name}"
    if not assets.has(full):
        assets.material(full, rgba=tuple(float(v) for v in rgba))
    return full


def build_clutter(items: list[ClutterItem], assets: SceneAssets) -> list[ET.Element]:
    """The geoms of every item (plain shapes; no collision, as the arena's other geoms)."""
    out: list[ET.Element] = []
    for k, it in enumerate(items):
        rng = np.random.default_rng(it.seed)
        x, y = it.xy
        a, o = np.array(it.along), np.array(it.out)
        yaw = float(np.arctan2(a[1], a[0]))

        def geom(part: str, material: str, k: int = k, **attrs) -> None:
            attrs = {key: (fmt(v) if not isinstance(v, str) else v) for key, v in attrs.items()}
            out.append(
                ET.Element(
                    "geom", name=f"clutter_{k}_{part}", material=material, contype="0", conaffinity="0", **attrs
                )
            )

        if it.kind == "crate":
            w, d, h = rng.uniform(0.3, 0.5), rng.uniform(0.25, 0.4), rng.uniform(0.25, 0.45)
            wood = _material(assets, "crate", (0.62, 0.48, 0.3, 1))
            dark = _material(assets, "crate_slat", (0.45, 0.33, 0.2, 1))
            geom("body", wood, type="box", pos=[x, y, h / 2], euler=[0, 0, yaw], size=[w / 2, d / 2, h / 2])
            for j, z in enumerate((0.3 * h, 0.7 * h)):
                p = np.array([x, y]) + o * (d / 2 + 0.005)
                geom(
                    f"slat_{j}",
                    dark,
                    type="box",
                    pos=[p[0], p[1], z],
                    euler=[0, 0, yaw],
                    size=[w / 2, 0.006, 0.02],
                )
        elif it.kind == "bucket":
            r, h = rng.uniform(0.13, 0.16), rng.uniform(0.3, 0.38)
            i = int(rng.integers(len(BUCKET_RGBA)))
            mat = _material(assets, f"bucket_{i}", BUCKET_RGBA[i])
            geom("body", mat, type="cylinder", pos=[x, y, h / 2], size=[r, h / 2])
        elif it.kind == "pipe":
            r, length = rng.uniform(0.03, 0.055), rng.uniform(0.6, 1.2)
            i = int(rng.integers(len(PIPE_RGBA)))
            p0, p1 = np.array([x, y]) - a * length / 2, np.array([x, y]) + a * length / 2
            mat = _material(assets, f"pipe_{i}", PIPE_RGBA[i])
            geom("body", mat, type="capsule", fromto=[p0[0], p0[1], r, p1[0], p1[1], r], size=[r])
        elif it.kind == "cable":
            r = rng.uniform(0.006, 0.01)
            i = int(rng.integers(len(CABLE_RGBA)))
            mat = _material(assets, f"cable_{i}", CABLE_RGBA[i])
            pts = [np.array([x, y]) - a * 0.5]
            for _ in range(int(rng.integers(3, 6))):
                pts.append(pts[-1] + a * rng.uniform(0.2, 0.35) + o * rng.normal(0, 0.08))
            for j, (p0, p1) in enumerate(zip(pts[:-1], pts[1:], strict=True)):
                geom(f"seg_{j}", mat, type="capsule", fromto=[p0[0], p0[1], r, p1[0], p1[1], r], size=[r])
        elif it.kind == "box":
            w, d, h = rng.uniform(0.2, 0.45), rng.uniform(0.2, 0.35), rng.uniform(0.15, 0.4)
            mat = _material(assets, "cardboard", (0.6, 0.45, 0.3, 1))
            tape = _material(assets, "box_tape", (0.75, 0.6, 0.4, 1))
            geom("body", mat, type="box", pos=[x, y, h / 2], euler=[0, 0, yaw], size=[w / 2, d / 2, h / 2])
            geom("tape", tape, type="box", pos=[x, y, h + 0.001], euler=[0, 0, yaw], size=[w / 2, 0.025, 0.001])
        else:  # debris: bricks and chunks
            for j in range(int(rng.integers(3, 7))):
                p = np.array([x, y]) + a * rng.uniform(-0.3, 0.3) + o * rng.uniform(-0.08, 0.08)
                s = rng.uniform(0.04, 0.12, 3)
                grey = rng.uniform(0.35, 0.6)
                rgba = (grey, grey * 0.97, grey * 0.95, 1) if rng.random() < 0.6 else (0.6, 0.25, 0.18, 1)
                mat = _material(assets, f"debris_{k}_{j}", rgba)
                geom(
                    f"piece_{j}",
                    mat,
                    type="box",
                    pos=[p[0], p[1], s[2] / 2],
                    euler=[0, 0, rng.uniform(0, np.pi)],
                    size=s / 2,
                )
    return out


# --- milk crates beside placards (training scenes only) ----------------------------------------
# Real placard photos show placards among clutter, milk crates most of all (issue 58); poibench
# dataset stands open plastic crates near its placards (sim.world.world.SceneLooks.milk_crates), trials
# never. A crate is 33 x 33 x 28 cm, its sides an open grid of bars.
MILK_CRATE_M = (0.33, 0.33, 0.28)
MILK_CRATE_RGBA = (
    (0.8, 0.1, 0.08, 1),
    (0.1, 0.3, 0.75, 1),
    (0.1, 0.55, 0.25, 1),
    (0.95, 0.75, 0.1, 1),
    (0.1, 0.1, 0.11, 1),
    (0.6, 0.62, 0.64, 1),
    (0.92, 0.92, 0.9, 1),
)
MILK_CRATE_BAR_M = 0.012  # half-thickness of a bar of the grid
MILK_CRATE_NEAR_M = (0.25, 0.7)  # from the placard's foot


def place_milk_crates(
    maze, objects: list[PlacedObject], rng: np.random.Generator, count: int
) -> list[ClutterItem]:
    """``count`` crates each beside a placard (on the floor in front of or beside it), clear of
    the walls and of every object by 5 cm; none in mazes with cells under ``MIN_CELL_M``."""
    if count < 0:
        raise ValueError(f"milk crates must be >= 0, got {count}")
    placards = [o for o in objects if o.type == "hazmat"]
    if count == 0 or not placards or maze.settings.cell_size_m < MIN_CELL_M:
        return []
    half = MILK_CRATE_M[0] / 2 * np.sqrt(2.0)  # the crate's corner radius: any yaw
    segs = maze.wall_segments()
    w, h = maze.size_m
    items: list[ClutterItem] = []
    for _ in range(count):
        for _attempt in range(50):
            p = placards[int(rng.integers(len(placards)))]
            ang = float(p.yaw + rng.uniform(-1.2, 1.2))  # in front of it, or to a side
            xy = p.position[:2] + float(rng.uniform(*MILK_CRATE_NEAR_M)) * np.array([np.cos(ang), np.sin(ang)])
            if not (half < xy[0] < w - half and half < xy[1] < h - half):
                continue
            clear = True
            for sg in segs:
                a, b = np.array([sg.x0, sg.y0]), np.array([sg.x1, sg.y1])
                t = np.clip(np.dot(xy - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
                if np.linalg.norm(xy - (a + t * (b - a))) < sg.thickness / 2 + half + 0.02:
                    clear = False
                    break
            if not clear or any(np.hypot(*(o.position[:2] - xy)) < half + 0.05 + 0.5 * o.size_m for o in objects):
                continue
            if any(np.hypot(*(np.array(i.xy) - xy)) < 2 * half + 0.02 for i in items):
                continue
            yaw = float(rng.uniform(0, np.pi / 2))
            items.append(
                ClutterItem(
                    kind="milk-crate",
                    xy=(float(xy[0]), float(xy[1])),
                    along=(float(np.cos(yaw)), float(np.sin(yaw))),
                    out=(float(-np.sin(yaw)), float(np.cos(yaw))),
                    seed=int(rng.integers(2**31)),
                )
            )
            break
    return items


def build_milk_crates(items: list[ClutterItem], assets: SceneAssets) -> list[ET.Element]:
    """Geoms ``milkcrate_{k}_{part}``: a floor plate and four sides of rim, posts and grid bars."""
    out: list[ET.Element] = []
    W, _, H = MILK_CRATE_M
    t = MILK_CRATE_BAR_M
    for k, it in enumerate(items):
        rng = np.random.default_rng(it.seed)
        i = int(rng.integers(len(MILK_CRATE_RGBA)))
        mat = _material(assets, f"milk_crate_{i}", MILK_CRATE_RGBA[i])
        x, y = it.xy
        yaw = float(np.arctan2(it.along[1], it.along[0]))
        c, s_ = np.cos(yaw), np.sin(yaw)

        def box(part: str, local, size, k: int = k, x=x, y=y, c=c, s_=s_, yaw=yaw, mat=mat) -> None:
            px, py, pz = local
            pos = [x + c * px - s_ * py, y + s_ * px + c * py, pz]
            out.append(
                ET.Element(
                    "geom",
                    name=f"milkcrate_{k}_{part}",
                    type="box",
                    material=mat,
                    pos=fmt(pos),
                    euler=fmt([0, 0, yaw]),
                    size=fmt(size),
                    contype="0",
                    conaffinity="0",
                )
            )

        box("floor", (0, 0, t / 2), (W / 2, W / 2, t / 2))
        for side, (ux, uy) in enumerate(((1, 0), (0, 1), (-1, 0), (0, -1))):
            # a side facing (ux, uy): rim and foot bars along it, 3 grid bars across, 2 rails
            along = (abs(uy) * W / 2, abs(ux) * W / 2)
            cx, cy = ux * (W / 2 - t), uy * (W / 2 - t)
            for j, z in enumerate((H - 1.5 * t, 1.5 * t, H * 0.38, H * 0.68)):
                hz = 1.5 * t if j == 0 else t
                box(f"s{side}_rail{j}", (cx, cy, z), (max(along[0], t), max(along[1], t), hz))
            for j, f in enumerate((-1.0, -0.5, 0.0, 0.5, 1.0)):
                off = f * (W / 2 - t)
                px, py = (cx + abs(uy) * off, cy + abs(ux) * off)
                box(f"s{side}_post{j}", (px, py, H / 2), (t, t, H / 2))
    return out
