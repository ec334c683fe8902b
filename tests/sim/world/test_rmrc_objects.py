"""The RMRC labyrinth's objects (maze_assets/scenarios/rmrc.yaml): mapping fiducials placed in
pairs facing each other across a corridor cell, and A4 QR sheets with codes of 5, 3 and 2 mm
modules (sim/world/placement.py), their geometry (maze_assets/models.py) and the scenario's checks."""

from __future__ import annotations

import numpy as np
import pytest

from maze_assets.models import (
    FIDUCIAL_DIAMETER_M,
    FIDUCIAL_LENGTH_M,
    LANDOLT_CABINET_M,
    half_cylinder_mesh,
    qr_side_m,
)
from maze_assets.objects import fiducial_diameter_m
from maze_assets.qr import draw_qr
from sim.scenario import ScenarioError, apply_settings, load_scenario
from sim.world.maze import find_maze, load_maze
from sim.world.placement import A4_M, PlacementError, place_objects


@pytest.fixture(scope="module")
def rmrc_objects():
    sc = load_scenario("rmrc")
    return sc, place_objects(sc.objects, load_maze(find_maze(sc.maze.file)), np.random.default_rng(sc.seed))


def test_six_fiducials_in_three_facing_pairs(rmrc_objects) -> None:
    sc, objs = rmrc_objects
    fids = [o for o in objs if o.type == "fiducial"]
    assert len(fids) == 6
    clear = 1.2 - 0.05  # the default maze's cell less a wall thickness
    for a, b in zip(fids[::2], fids[1::2], strict=True):
        assert a.size_m == b.size_m and FIDUCIAL_DIAMETER_M[0] <= a.size_m <= FIDUCIAL_DIAMETER_M[1]
        assert fiducial_diameter_m(a.text) == pytest.approx(a.size_m, abs=5e-4)
        # facing each other: opposite yaws, across the cell along the first one's normal
        n = np.array([np.cos(a.yaw), np.sin(a.yaw)])
        assert np.cos(b.yaw - a.yaw) == pytest.approx(-1.0)
        assert b.position[:2] - a.position[:2] == pytest.approx(n * clear, abs=1e-9)
        assert a.position[2] == b.position[2] == FIDUCIAL_LENGTH_M / 2  # standing on the floor
    # the same seed, the same arena
    again = place_objects(sc.objects, load_maze(find_maze(sc.maze.file)), np.random.default_rng(sc.seed))
    assert [(o.type, o.text, tuple(o.position)) for o in again] == [
        (o.type, o.text, tuple(o.position)) for o in objs
    ]


def test_qr_sheets_hold_codes_down_to_2_mm_modules_on_one_a4_page(rmrc_objects) -> None:
    sc, objs = rmrc_objects
    sheet = [o for o in objs if o.type == "qr" and o.module_m is not None]
    assert len(sheet) == 3 * 3
    for k in range(3):
        page = sheet[3 * k : 3 * k + 3]
        name = page[0].text.rsplit(" ", 1)[0]
        assert [o.text for o in page] == [f"{name} 5mm", f"{name} 3mm", f"{name} 2mm"]
        assert [o.module_m for o in page] == [0.005, 0.003, 0.002]
        # a 21-module code drawn at 8 px a module in a 256 px texture: 32 modules a side
        assert [o.size_m for o in page] == pytest.approx([0.16, 0.096, 0.064])
        assert qr_side_m(page[2].text, 0.002) == pytest.approx(0.064)
        left, right, bottom, top = page[0].page_m
        assert (right - left, top - bottom) == pytest.approx(A4_M)
        assert all(o.page_m is None for o in page[1:]) and len({o.wall for o in page}) == 1
        # every code lies inside the page, in its plane
        n = np.array([np.cos(page[0].yaw), np.sin(page[0].yaw)])
        r = np.array([-n[1], n[0]])  # the page's local +y (the viewer's right)
        for o in page:
            d = o.position - page[0].position
            assert float(d[:2] @ n) == pytest.approx(0.0, abs=1e-12)
            u, v = float(d[:2] @ r), float(d[2])
            assert left <= u - o.size_m / 2 and u + o.size_m / 2 <= right + 1e-12
            assert bottom <= v - o.size_m / 2 and v + o.size_m / 2 <= top + 1e-12
    # the 2 mm code is real: it decodes from its own texture
    import cv2

    assert cv2.QRCodeDetector().detectAndDecode(draw_qr(sheet[2].text, 256))[0] == sheet[2].text


def test_half_cylinder_mesh_is_closed_and_faces_out() -> None:
    V, F = half_cylinder_mesh(0.15, 0.5)
    tri = V[F]  # (m, 3, 3)
    volume = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6
    # 32 facets: the section is 32 triangles of area r^2 sin(pi/32) / 2 (positive: faces point out)
    assert volume == pytest.approx(16 * 0.15**2 * np.sin(np.pi / 32) * 0.5, rel=1e-12)
    assert volume == pytest.approx(np.pi * 0.15**2 / 2 * 0.5, rel=2e-3)  # the exact half-cylinder
    assert V[:, 0].min() == 0.0 and V[:, 0].max() == pytest.approx(0.15)


def test_bad_fiducial_and_sheet_settings_are_refused() -> None:
    sc = load_scenario("rmrc")
    with pytest.raises(ScenarioError, match="counts.fiducial: fiducials are mounted in pairs"):
        apply_settings(sc, ["objects.generate.counts.fiducial=5"])
    with pytest.raises(ScenarioError, match="module_mm"):
        apply_settings(sc, ["objects.generate.qr_sheets.module_mm=[5, 0.1]"])
    small = apply_settings(sc, ["maze.file=rmrc_lanes"])
    with pytest.raises(PlacementError, match="counts.fiducial: a pair of fiducials"):
        place_objects(small.objects, load_maze(find_maze("rmrc_lanes")), np.random.default_rng(0))


def test_the_world_draws_each_page_once_and_no_object_owns_it(rmrc_objects) -> None:
    """Also the Landolt-C targets' holders (tests/sim/test_landolt_objects.py has the rest): one
    world build for both, it is the slow part."""
    import mujoco

    from poi.core.types import Intrinsics
    from sim.world.world import build_world

    sc, objs = rmrc_objects
    intr = Intrinsics(width=64, height=48, fx=60.0, fy=60.0, ppx=32.0, ppy=24.0)
    world = build_world(load_maze(find_maze(sc.maze.file)), objs, intr, "bright", np.random.default_rng(0))
    m = world.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)]
    pages = [g for g, n in enumerate(names) if n and n.startswith("qr_page_")]
    assert len(pages) == 3 and all(world.geom_object_id[g] == -1 for g in pages)
    fid = [g for g, n in enumerate(names) if n and n.startswith("poi_") and n.endswith("_fiducial_body")]
    assert len(fid) == 6 and sorted(int(world.geom_object_id[g]) for g in fid) == list(range(6))
    # a page lies flat on its wall, A4 in size (the box's half extents: depth, width, height)
    assert sorted(m.geom_size[pages[0]][1:] * 2) == pytest.approx(sorted(A4_M))
    # Landolt-C: a cabinet (back, two sides, top, bottom) and two boards, owned by no object; the
    # cards are the objects
    cabinet = [g for g, n in enumerate(names) if n and n.startswith("holder_cabinet_")]
    boards = [g for g, n in enumerate(names) if n and n.startswith("holder_board_")]
    assert len(cabinet) == 5 and len(boards) == 2
    assert all(world.geom_object_id[g] == -1 for g in cabinet + boards)
    cards = [g for g, n in enumerate(names) if n and n.startswith("poi_") and "_landolt-c_" in n]
    assert {int(world.geom_object_id[g]) for g in cards} == {o.id for o in objs if o.type == "landolt-c"}
    back = next(g for g in cabinet if names[g].endswith("_back"))
    assert sorted(m.geom_size[back][1:] * 2) == pytest.approx(sorted(LANDOLT_CABINET_M[:2]))
