"""Placards laid face up on the floor: chosen by seed, in front of their wall, rendered face up."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from maze_assets.models import BACKING_M
from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation
from sim.world.placement import FLOOR_PLACARD_OUT_M, PlacementError, lay_placards_on_floor


def _scenario(share: float):
    sc = with_noise(load_scenario("default"), False)
    return apply_settings(sc, [f"objects.generate.hazmat_on_floor={share}"])


@pytest.fixture(scope="module")
def pair():
    with Simulation(_scenario(0.0)) as wall, Simulation(_scenario(1.0)) as floor:
        yield wall, floor


@pytest.mark.slow
def test_placards_move_from_the_wall_to_the_floor_in_front_of_it(pair):
    wall, floor = pair
    moved = 0
    for before, after in zip(wall.objects, floor.objects, strict=True):
        if after.type != "hazmat" or after.mount == "wall":
            # everything else is where it was: the floor draw takes its own random stream
            assert np.array_equal(before.position, after.position), after.id
            continue
        moved += 1
        assert after.mount == "floor" and after.tilt == pytest.approx(np.pi / 2)
        assert after.position[2] == pytest.approx(BACKING_M + 0.001)
        normal = np.array([np.cos(before.yaw), np.sin(before.yaw)])
        gap = (after.position[:2] - before.position[:2]) @ normal - 0.5 * after.size_m
        assert FLOOR_PLACARD_OUT_M[0] <= gap <= FLOOR_PLACARD_OUT_M[1]  # default maze: RRL scale
        # straight out from the wall, at the same place along it
        along = np.array([-normal[1], normal[0]])
        assert (after.position[:2] - before.position[:2]) @ along == pytest.approx(0.0, abs=1e-9)
    assert moved >= 3  # of 5: one may stay on its wall for want of room


@pytest.mark.slow
def test_a_floor_placard_faces_up_and_the_camera_above_sees_it(pair):
    _, floor = pair
    m, d = floor.world.model, floor.world.data
    mujoco.mj_kinematics(m, d)
    o = next(o for o in floor.objects if o.mount == "floor" and o.type == "hazmat")
    face = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{o.body_name}_face")
    normal = d.geom_xmat[face].reshape(3, 3)[:, 0]  # the face's +x
    assert np.allclose(normal, [0.0, 0.0, 1.0], atol=1e-9)
    # a camera 0.8 m above it, looking straight down (optical z = world -z)
    p = floor.T_map_world @ np.array([*o.position, 1.0])
    T = np.eye(4)
    T[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]  # rig x (forward) down
    T[:3, 3] = p[:3] + [0.0, 0.0, 0.8]
    _, truth = floor.view(T, 0)
    seen = {v.id: v for v in truth.visible}
    assert o.id in seen and seen[o.id].visible_fraction > 0.9


def test_share_is_checked():
    with pytest.raises(PlacementError, match=r"hazmat_on_floor must be in \[0, 1\], got 1.5"):
        lay_placards_on_floor([], 1.5, 0, None)
    with pytest.raises(ValueError, match="hazmat_on_floor"):
        _scenario(-0.1)
