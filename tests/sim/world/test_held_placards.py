"""Placards in crates, on ramps and on boards with a QR code and a Landolt-C card (issue 17,
item 2): moved by seed from their walls, drawn with their holders, seen whole from in front."""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from maze_assets.models import (
    BACKING_M,
    BOARD_THICKNESS_M,
    CRATE_WALL_M,
    RAMP_RUN_SIDES,
    RAMP_SLOPE_DEG,
    RAMP_WIDTH_SIDES,
    crate_inner_m,
    reference_point,
)
from maze_assets.objects import PlacedObject
from poi.core.geometry import make_transform, rot_y, rot_z
from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation
from sim.world.placement import PlacementError, hang_placard_boards, lay_placards_on_ramps, put_placards_in_crates

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


def _scenario(crates: int = 0, boards: int = 0, landolt: int = 0, ramps: int = 0):
    sc = with_noise(load_scenario("default"), False)
    sc = apply_settings(
        sc,
        [
            f"objects.generate.hazmat_in_crates={crates}",
            f"objects.generate.hazmat_on_boards={boards}",
            f"objects.generate.hazmat_on_ramps={ramps}",
        ],
    )
    gen = replace(sc.objects.generate, counts={**sc.objects.generate.counts, "landolt-c": landolt})
    return replace(sc, objects=replace(sc.objects, generate=gen))


@pytest.fixture(scope="module")
def sims():
    with (
        Simulation(_scenario(landolt=1)) as plain,
        Simulation(_scenario(crates=2, boards=1, landolt=1, ramps=1)) as held,
    ):
        yield plain, held


def _normal(o: PlacedObject) -> np.ndarray:
    return np.array([math.cos(o.yaw), math.sin(o.yaw)])


def _right(o: PlacedObject) -> np.ndarray:
    n = _normal(o)
    return np.array([-n[1], n[0]])  # the viewer's right (local +y)


def _look_at(sim, o: PlacedObject, distance_m: float = 1.0, height_m: float = 0.5):
    n = _normal(o)
    cam = o.position[:2] + distance_m * n
    yaw = math.atan2(-n[1], -n[0])
    pitch = math.atan2(height_m - o.position[2], distance_m)
    T = sim.T_map_world @ make_transform(rot_z(yaw) @ rot_y(pitch), [cam[0], cam[1], height_m])
    return sim.view(T, 0)


def test_crated_placards_sit_on_the_back_panel_at_the_floor_where_they_hung(sims):
    plain, sim = sims
    crated = [o for o in sim.objects if o.holder == "crate"]
    assert len(crated) == 2 and all(o.type == "hazmat" for o in crated)
    before = {o.id: o for o in plain.objects}
    for o in crated:
        b = before[o.id]
        assert b.holder is None and b.mount == "wall"
        inner, depth = crate_inner_m(o.size_m)
        assert depth == pytest.approx(o.size_m) and inner == pytest.approx(1.5 * o.size_m)
        # straight out of its old place by the crate's back panel, centred inside the crate
        d = o.position[:2] - b.position[:2]
        assert d @ _normal(o) == pytest.approx(CRATE_WALL_M) and d @ _right(o) == pytest.approx(0.0, abs=1e-12)
        assert o.position[2] == pytest.approx(CRATE_WALL_M + inner / 2)
        left, right, bottom, top = o.holder_m
        assert bottom == pytest.approx(-o.position[2])  # the crate stands on the floor
        assert right - left == pytest.approx(inner + 2 * CRATE_WALL_M) == pytest.approx(top - bottom)
        assert o.yaw == b.yaw and o.wall == b.wall and o.size_m == b.size_m


def test_a_ramp_placard_lies_mid_slope_face_up_its_ramp_against_the_wall(sims):
    plain, sim = sims
    (o,) = [o for o in sim.objects if o.holder == "ramp"]
    b = {p.id: p for p in plain.objects}[o.id]
    slope = math.radians(RAMP_SLOPE_DEG)
    run = RAMP_RUN_SIDES * o.size_m  # 0.5 m: under half the default maze's 1.15 m clear cells
    assert o.tilt == pytest.approx(math.pi / 2 - slope) and o.mount == "floor" and o.wall is None
    n = _normal(o)
    # the face: the slope's middle, half the run out from where it hung, lifted by the backing
    normal = np.array([*(math.sin(slope) * n), math.cos(slope)])
    on_slope = o.position - normal * (BACKING_M + 0.001)
    d = on_slope[:2] - b.position[:2]
    assert d @ n == pytest.approx(run / 2) and d @ _right(o) == pytest.approx(0.0, abs=1e-12)
    assert on_slope[2] == pytest.approx(run / 2 * math.tan(slope))
    left, right, bottom, top = o.holder_m
    assert right - left == pytest.approx(RAMP_WIDTH_SIDES * o.size_m)
    assert top == -bottom == pytest.approx(run / 2 / math.cos(slope))
    # the reference point is the image's centre, 3 mm out of the slope
    assert (reference_point(o) - o.position) @ normal == pytest.approx(0.003)
    # the wedge: its back on the wall face where the placard hung, its slope under the placard
    m = sim.world.model
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"holder_ramp_{o.id}_wedge")
    assert g >= 0 and sim.world.geom_object_id[g] == -1
    body = int(m.geom_bodyid[g])
    foot = sim.world.data.xpos[body]
    assert (foot[:2] - b.position[:2]) @ n == pytest.approx(0.0, abs=1e-9) and foot[2] == 0.0


def test_a_board_holds_placard_qr_and_card_in_a_row_on_one_face(sims):
    plain, sim = sims
    on_board = [o for o in sim.objects if o.holder == "board"]
    assert sorted(o.type for o in on_board) == ["hazmat", "landolt-c", "qr"]
    placard = next(o for o in on_board if o.type == "hazmat")
    assert all(o.holder_m is None for o in on_board if o is not placard)
    n, right = _normal(placard), _right(placard)
    before = {o.id: o for o in plain.objects}
    assert placard.wall == before[placard.id].wall  # the board hangs on the placard's own face
    left, rgt, bottom, top = placard.holder_m
    spans = {o.id: o.size_m * (math.sqrt(2) if o.type == "hazmat" else 1.0) for o in on_board}
    us = []
    for o in on_board:
        assert o.yaw == pytest.approx(placard.yaw) and o.wall == placard.wall
        d = o.position - placard.position
        assert d[:2] @ n == pytest.approx(0.0, abs=1e-12) and d[2] == pytest.approx(0.0)
        u = float(d[:2] @ right)
        # inside the board, with its margin, and on it by the board's thickness
        assert left + spans[o.id] / 2 <= u + 1e-9 and u + spans[o.id] / 2 <= rgt + 1e-9
        assert spans[o.id] / 2 <= top + 1e-9 and -spans[o.id] / 2 >= bottom - 1e-9
        us.append((u, o))
    us.sort(key=lambda t: t[0])
    assert [o.type for _, o in us] == ["hazmat", "qr", "landolt-c"]  # left to right
    for (u0, a), (u1, b) in zip(us[:-1], us[1:], strict=True):
        assert u1 - u0 >= (spans[a.id] + spans[b.id]) / 2  # no two overlap
    face_out = placard.position[:2] @ n
    wall_face = before[placard.id].position[:2] @ n
    assert face_out - wall_face == pytest.approx(BOARD_THICKNESS_M)


def test_the_rest_stay_where_they_were(sims):
    plain, sim = sims
    for a, b in zip(plain.objects, sim.objects, strict=True):
        if b.holder is None:
            assert np.array_equal(a.position, b.position) and a.yaw == b.yaw, b.id


def test_holders_are_drawn_once_and_owned_by_no_object(sims):
    _, sim = sims
    m = sim.world.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(m.ngeom)]
    crates = {n.split("_")[2] for n in names if n.startswith("holder_crate_")}
    boards = [g for g, n in enumerate(names) if n.startswith("holder_board_")]
    assert crates == {str(o.id) for o in sim.objects if o.holder == "crate"}
    assert len(boards) == 1  # one panel for the group; the Landolt-C card draws none
    held = [g for g, n in enumerate(names) if n.startswith("holder_")]
    assert all(sim.world.geom_object_id[g] == -1 for g in held)


def test_held_placards_are_seen_whole_from_in_front(sims):
    _, sim = sims
    for o in sim.objects:
        if o.holder in ("crate", "board", "ramp"):
            _, truth = _look_at(sim, o)
            seen = {v.id: v.visible_fraction for v in truth.visible}
            assert seen.get(o.id, 0.0) > 0.9, (o.id, o.holder)


def test_the_crate_walls_hide_the_placard_from_the_side(sims):
    """Seen along the wall from the crate's side, the side panel hides it (a real crate does)."""
    _, sim = sims
    o = next(o for o in sim.objects if o.holder == "crate")
    n, right = _normal(o), _right(o)
    cam = o.position[:2] + 0.1 * n + 1.0 * right
    look = o.position[:2] - cam
    T = sim.T_map_world @ make_transform(rot_z(math.atan2(look[1], look[0])), [cam[0], cam[1], o.position[2]])
    _, truth = sim.view(T, 0)
    assert o.id not in {v.id for v in truth.visible if v.visible_fraction > 0.05}


def test_bad_counts_are_one_line_errors(sims):
    _, sim = sims
    with pytest.raises(PlacementError, match="hazmat_in_crates must be >= 0, got -1"):
        put_placards_in_crates(list(sim.objects), -1, 0, sim.maze)
    with pytest.raises(PlacementError, match="hazmat_on_boards must be >= 0, got -2"):
        hang_placard_boards(list(sim.objects), -2, 0, sim.maze)
    with pytest.raises(PlacementError, match="hazmat_on_ramps must be >= 0, got -3"):
        lay_placards_on_ramps(list(sim.objects), -3, 0, sim.maze)
    with pytest.raises(ValueError, match="hazmat_in_crates"):
        Simulation(_scenario(crates=-1))
    with pytest.raises(ValueError, match=r"holder 'crate' is not for this type; expected one of \['board'\]"):
        PlacedObject(id=0, type="qr", holder="crate")
    with pytest.raises(ValueError, match="holder_m"):
        PlacedObject(id=0, type="hazmat", holder="board", holder_m=(0.1, 0.2, -0.1, 0.1))


def test_same_seed_same_placement():
    with Simulation(_scenario(crates=2, boards=1, landolt=1, ramps=1)) as again:
        a = [(o.id, o.holder, o.position.tolist(), o.holder_m) for o in again.objects]
    with Simulation(_scenario(crates=2, boards=1, landolt=1, ramps=1)) as twice:
        b = [(o.id, o.holder, o.position.tolist(), o.holder_m) for o in twice.objects]
    assert a == b
