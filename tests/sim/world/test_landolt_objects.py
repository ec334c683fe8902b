"""Landolt-C targets in the maze (docs/RULES.md "Landolt-C"): placed on walls, on boards and in a
sensor cabinet with seeded gap directions (sim/world/placement.py), drawn with their holders
(maze_assets/models.py), and the scenario's checks."""

from __future__ import annotations

import numpy as np
import pytest

from maze_assets.landolt import card_side_mm
from maze_assets.models import LANDOLT_BOARD_M, LANDOLT_CABINET_M
from poi.core.landolt import DEFAULT_N_RINGS, LandoltSpec, parse_orientation_text
from sim.scenario import ScenarioError, apply_settings, load_scenario
from sim.world.maze import find_maze, load_maze
from sim.world.placement import place_objects


@pytest.fixture(scope="module")
def rmrc():
    sc = load_scenario("rmrc")
    maze = load_maze(find_maze(sc.maze.file))
    return sc, maze, place_objects(sc.objects, maze, np.random.default_rng(sc.seed))


def test_targets_sit_in_a_cabinet_on_boards_and_on_walls(rmrc) -> None:
    sc, maze, objs = rmrc
    targets = [o for o in objs if o.type == "landolt-c"]
    # rmrc.yaml: five targets, one in a cabinet, two on boards, the rest on the wall; placed last
    assert [o.holder for o in targets] == ["cabinet", "board", "board", None, None]
    assert [o.id for o in targets] == list(range(len(objs) - 5, len(objs)))
    for o in targets:
        assert o.size_m == pytest.approx(card_side_mm(LandoltSpec()) / 1000)
        rings = parse_orientation_text(o.text)
        assert sorted(rings) == list(range(1, DEFAULT_N_RINGS + 1))
        assert 0.3 <= o.position[2] <= 0.8 and o.mount == "wall"
        # the card stands out from its wall face by its holder: the board's thickness, the cabinet's back
        face = next(
            f
            for f in maze.wall_faces()
            if f.wall == o.wall and np.cos(o.yaw - np.arctan2(*f.normal_xy[::-1])) > 0.99
        )
        n = np.asarray(face.normal_xy, float)
        out = float(np.dot(o.position[:2] - np.asarray(face.center_xy, float), n))
        want = {"board": LANDOLT_BOARD_M[2], "cabinet": LANDOLT_CABINET_M[3], None: 0.0}[o.holder]
        assert out == pytest.approx(want, abs=1e-9)
    # the targets' directions come from the seed: the same seed, the same texts; another, others
    again = place_objects(sc.objects, maze, np.random.default_rng(sc.seed))
    assert [o.text for o in again if o.type == "landolt-c"] == [o.text for o in targets]
    other = place_objects(sc.objects, maze, np.random.default_rng(sc.seed + 1))
    assert [o.text for o in other if o.type == "landolt-c"] != [o.text for o in targets]


def test_adding_targets_leaves_the_other_objects_where_they_were(rmrc) -> None:
    sc, maze, objs = rmrc
    without = apply_settings(sc, ["objects.generate.counts.landolt-c=0", "objects.generate.landolt=null"])
    before = place_objects(without.objects, maze, np.random.default_rng(sc.seed))
    assert [(o.type, o.text, tuple(o.position)) for o in before] == [
        (o.type, o.text, tuple(o.position)) for o in objs if o.type != "landolt-c"
    ]


def test_bad_landolt_settings_are_refused_in_one_line() -> None:
    sc = load_scenario("rmrc")
    with pytest.raises(
        ScenarioError, match="1 cabinets \\+ 2 boards need 3 targets, but counts.landolt-c is 2"
    ) as e:
        apply_settings(sc, ["objects.generate.counts.landolt-c=2"])
    assert "\n" not in str(e.value)
    with pytest.raises(ScenarioError, match="height_m: expected \\[low, high\\] with 0 < low <= high"):
        apply_settings(sc, ["objects.generate.landolt.height_m=[0.9, 0.3]"])
    spec = {"type": "landolt-c", "text": "1:E 2:N 3:up", "at": {"cell": [0, 0], "side": "n"}}
    with pytest.raises(ScenarioError, match="'3:up' is not RING:DIRECTION"):
        apply_settings(sc, [f"objects.explicit=[{spec}]".replace("'", '"')])
    spec["text"] = "1:E 2:N 3:NE"
    with pytest.raises(ScenarioError, match="gives rings 1 to 5 once each"):
        apply_settings(sc, [f"objects.explicit=[{spec}]".replace("'", '"')])
