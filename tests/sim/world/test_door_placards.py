"""Placards on doors: moved from walls by seed, centred on a door's upper panel, facing out."""

from __future__ import annotations

import math

import numpy as np
import pytest

from maze_assets.models import DOOR_PANELS, door_height_m
from poi.core.geometry import make_transform, rot_y, rot_z
from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation
from sim.world.placement import PlacementError, hang_placards_on_doors

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


def _scenario(n: int):
    sc = with_noise(load_scenario("default"), False)
    return apply_settings(sc, [f"objects.generate.hazmat_on_doors={n}"])


@pytest.fixture(scope="module")
def pair():
    with Simulation(_scenario(0)) as plain, Simulation(_scenario(2)) as doors:
        yield plain, doors


def test_two_placards_on_the_two_faces_of_the_door(pair):
    plain, sim = pair
    (door,) = [o for o in sim.objects if o.type == "door"]
    on_door = [o for o in sim.objects if o.type == "hazmat" and o.wall == door.wall]
    assert len(on_door) == 2
    ids = {o.id for o in on_door}
    for before, after in zip(plain.objects, sim.objects, strict=True):
        if after.id not in ids:
            assert np.array_equal(before.position, after.position), after.id  # the rest stay
    s = sim.maze.settings
    # default maze: 1.2 m walls, 50 mm thick: a 40 mm leaf, panels 6 mm proud, the sign 1 mm off
    assert door_height_m(s.wall_height_m) == pytest.approx(1.08) and s.wall_thickness_m == pytest.approx(0.05)
    centre_z = 0.5 * sum(DOOR_PANELS[1]) * 1.08
    sides = []
    for o in on_door:
        n = np.array([math.cos(o.yaw), math.sin(o.yaw)])
        offset = o.position[:2] - door.position[:2]
        assert offset @ n == pytest.approx(0.02 + 0.006 + 0.001)  # straight out of the panel
        assert np.linalg.norm(offset) == pytest.approx(0.027)
        assert o.position[2] == pytest.approx(centre_z)
        sides.append(float(n @ np.array([math.cos(door.yaw), math.sin(door.yaw)])))
    assert sorted(sides) == pytest.approx([-1.0, 1.0])  # one on each face


def test_a_door_placard_is_seen_whole_from_in_front(pair):
    _, sim = pair
    (door,) = [o for o in sim.objects if o.type == "door"]
    o = next(o for o in sim.objects if o.type == "hazmat" and o.wall == door.wall)
    n = np.array([math.cos(o.yaw), math.sin(o.yaw)])
    cam = o.position[:2] + 1.2 * n
    yaw = math.atan2(-n[1], -n[0])
    T = sim.T_map_world @ make_transform(rot_z(yaw) @ rot_y(math.radians(-10)), [cam[0], cam[1], 0.5])
    _, truth = sim.view(T, 0)
    seen = {v.id: v for v in truth.visible}
    assert o.id in seen and seen[o.id].visible_fraction > 0.9


def test_bad_counts_are_one_line_errors(pair):
    _, sim = pair
    objs = [o for o in sim.objects]
    with pytest.raises(
        PlacementError, match=r"hazmat_on_doors: 3 placards need 3 door faces, the maze has 2 \(1 doors\)"
    ):
        hang_placards_on_doors(objs, 3, 0, sim.maze)
    with pytest.raises(PlacementError, match="hazmat_on_doors must be >= 0, got -1"):
        hang_placards_on_doors(objs, -1, 0, sim.maze)
    with pytest.raises(ValueError, match="hazmat_on_doors"):
        Simulation(_scenario(-1))
