"""Scenario files: defaults, validation with line numbers, settings, placement rules."""

import numpy as np
import pytest

from poi.core.names import RESCUE_TYPES
from sim.scenario import ScenarioError, apply_settings, load_scenario, parse_scenario
from sim.world.maze import find_maze, load_maze
from sim.world.placement import PlacementError, place_objects


def test_shipped_default_scenario_loads():
    sc = load_scenario("default")
    assert sc.name == "default" and sc.maze.file == "default"


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "seed: 1\nsensors:\n  fps: fast\n",
            "x.yaml:3: sensors.fps: expected a number, got 'fast'",
        ),
        ("seed: 1\nrobot:\n  speeed_mps: 1\n", "x.yaml:3: robot.speeed_mps: unknown key"),
        ("lighting: dark\n", "x.yaml:1: lighting: expected one of 'bright', 'dim', 'uneven'"),
        ("maze: {file: a, generate: {rows: 2}}\n", "x.yaml:1: maze: give exactly one of"),
        (
            "objects:\n  explicit:\n    - {type: dragon, position: [0, 0, 0]}\n",
            "x.yaml:3: objects.explicit[0]: unknown type",
        ),
        ("seed: [1\n", "x.yaml:2:1: not valid YAML"),
        ("poibench_scenario: 7\n", "unsupported version 7"),
        (
            "objects:\n  generate:\n    labels: [poison, not-a-label]\n",
            "x.yaml:2: objects.generate: labels: unknown hazmat label 'not-a-label'; expected one of explosive,",
        ),
    ],
)
def test_malformed_scenarios_give_one_line_errors_with_line_numbers(text, message):
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "x.yaml")
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_apply_settings_validates():
    sc = apply_settings(load_scenario("default"), ["robot.speed_mps=0.5"])
    assert sc.robot.speed_mps == 0.5
    with pytest.raises(ScenarioError, match=r"key 'wings'; expected one of kind, .*\(under robot\)"):
        apply_settings(sc, ["robot.wings=2"])
    with pytest.raises(ScenarioError, match="expected a number"):
        apply_settings(sc, ["robot.speed_mps=fast"])


def test_generated_placement_has_every_type_and_keeps_spacing():
    sc = load_scenario("default")
    maze = load_maze(find_maze("default"))
    objs = place_objects(sc.objects, maze, np.random.default_rng(3))
    assert {o.type for o in objs} == set(RESCUE_TYPES)
    assert sum(o.type == "hazmat" for o in objs) >= 2 and sum(o.type == "qr" for o in objs) >= 2
    pos = np.array([o.position for o in objs])
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(len(objs)) * 99
    assert d.min() >= sc.objects.generate.min_spacing_m - 1e-9
    for o in objs:
        if o.mount == "wall":
            assert 0.2 <= o.position[2] <= 1.5
    # different seeds, different placements; same seed, same placement
    again = place_objects(sc.objects, maze, np.random.default_rng(3))
    assert [tuple(o.position) for o in again] == [tuple(o.position) for o in objs]
    other = place_objects(sc.objects, maze, np.random.default_rng(4))
    assert [tuple(o.position) for o in other] != [tuple(o.position) for o in objs]


def test_explicit_placement_on_a_wall_face():
    sc = parse_scenario(
        "maze: {file: rrl_small}\nobjects:\n  generate: null\n  explicit:\n"
        "    - {type: hazmat, text: oxidizer, at: {cell: [0, 0], side: n, height_m: 1.0}}\n"
    )
    maze = load_maze(find_maze("rrl_small"))
    (o,) = place_objects(sc.objects, maze, np.random.default_rng(0))
    cx, cy = maze.cell_center(0, 0)
    half = maze.settings.cell_size_m / 2 - maze.settings.wall_thickness_m / 2
    assert np.allclose(o.position, [cx, cy + half, 1.0])
    assert np.isclose(o.yaw, -np.pi / 2)  # faces south, into the cell


def test_too_many_objects_is_a_clear_error():
    sc = parse_scenario("maze: {file: rrl_small}\nobjects:\n  generate: {counts: {hazmat: 60}}\n")
    said = r"^objects.generate: could not place a .* \(lower counts or min_spacing_m"
    with pytest.raises(PlacementError, match=said):
        place_objects(sc.objects, load_maze(find_maze("rrl_small")), np.random.default_rng(0))
