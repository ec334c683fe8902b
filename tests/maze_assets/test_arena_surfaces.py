"""Arena walls, floors, the hall and the distractors: deterministic, seamed, clear of POIs."""

from __future__ import annotations

import numpy as np
import pytest

from maze_assets.clutter import ITEM_SPACING_M, POI_CLEARANCE_M, build_clutter, place_clutter
from maze_assets.mjcf import SceneAssets
from maze_assets.objects import PlacedObject
from maze_assets.surfaces import (
    FLOOR_KINDS,
    WALL_KINDS,
    SurfaceSizeError,
    draw_floor_kind,
    draw_hall_wall,
    draw_wall,
)
from sim.world.maze import find_maze, load_maze


@pytest.mark.parametrize("kind", WALL_KINDS)
def test_wall_kind_is_deterministic_and_has_a_dark_sheet_joint(kind):
    a = draw_wall(kind, 128, np.random.default_rng(4))
    assert np.array_equal(a, draw_wall(kind, 128, np.random.default_rng(4)))
    lum = a.astype(float).mean(axis=2)
    # the joint along the left edge is darker than the sheet 5-20 px in (0.45 of it, marks aside)
    assert np.median(lum[:, 0]) < 0.7 * np.median(lum[:, 5:20])


@pytest.mark.parametrize("kind", FLOOR_KINDS)
def test_floor_kinds_draw(kind):
    img = draw_floor_kind(kind, 64, np.random.default_rng(1))
    assert img.shape == (64, 64, 3) and img.dtype == np.uint8


def test_unknown_kinds_name_the_choices():
    with pytest.raises(SurfaceSizeError, match="osb, plywood, painted"):
        draw_wall("marble", 64, np.random.default_rng(0))
    with pytest.raises(SurfaceSizeError, match="plywood, osb, painted"):
        draw_floor_kind("carpet", 64, np.random.default_rng(0))


def test_hall_wall_has_bright_windows_above_blockwork():
    img = draw_hall_wall(96, np.random.default_rng(2)).astype(float).mean(axis=2)
    windows, blocks = img[5:28], img[40:]
    assert windows.max() > 180 and np.median(blocks) > 150


def test_clutter_stays_clear_of_pois_and_of_each_other():
    maze = load_maze(find_maze("default"))
    pois = [PlacedObject(id=i, type="qr", text="x", position=[1.2 * i + 0.6, 0.7, 1.0]) for i in range(4)]
    items = place_clutter(maze, pois, np.random.default_rng(3), per_cell=0.5)
    assert len(items) > 5
    xy = np.array([i.xy for i in items])
    for p in pois:
        assert np.min(np.linalg.norm(xy - p.position[:2], axis=1)) >= POI_CLEARANCE_M
    d = np.linalg.norm(xy[:, None] - xy[None], axis=2) + np.eye(len(xy)) * 9
    assert d.min() >= ITEM_SPACING_M
    again = place_clutter(maze, pois, np.random.default_rng(3), per_cell=0.5)
    assert again == items
    geoms = build_clutter(items, SceneAssets())
    assert geoms and all(g.get("name").startswith("clutter_") for g in geoms)
    assert all(g.get("contype") == "0" for g in geoms)
    with pytest.raises(ValueError, match="per cell"):
        place_clutter(maze, pois, np.random.default_rng(3), per_cell=-1)
