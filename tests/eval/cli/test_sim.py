"""`poibench scenario new` and `poibench render`; route files; lighting presets."""

import json

import cv2
import numpy as np
import pytest

from eval.cli.main import main
from poi.core.poi_file import read_poi_file
from sim.scenario import apply_settings, load_scenario, parse_scenario
from sim.simulator import Simulation

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


def test_scenario_new_prints_a_loadable_scenario(tmp_path, capsys):
    assert main(["scenario", "new", "--seed", "5"]) == 0
    text = capsys.readouterr().out
    sc = parse_scenario(text, "<stdout>")
    assert sc.seed == 5 and sc.maze.generate is not None
    out = tmp_path / "s.yaml"
    assert main(["scenario", "new", "--seed", "5", "-o", str(out)]) == 0
    assert out.read_text() == text
    assert f"wrote {out}: poibench run {out} runs it" in capsys.readouterr().err  # what to do next
    # an existing file is not overwritten, a path under a file is one line
    assert main(["scenario", "new", "--seed", "6", "-o", str(out)]) == 2
    assert f"error: -o {out}: exists; choose another name or remove it first" in capsys.readouterr().err
    assert out.read_text() == text
    assert main(["scenario", "new", "--seed", "6", "-o", str(out / "x.yaml")]) == 2
    assert f"-o {out / 'x.yaml'}: its folder {out}: is a file, not a folder" in capsys.readouterr().err


def test_render_writes_frames_depth_overlays_and_truth(tmp_path):
    out = tmp_path / "r"
    assert main(["render", "--frames", "3", "--out", str(out), "--set", "maze.file=rrl_small"]) == 0
    assert len(list((out / "color").glob("*.png"))) == 3
    depth = cv2.imread(str(next((out / "depth").glob("*.png"))), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (480, 640)
    assert 200 < np.median(depth[depth > 0]) < 10000  # millimetres inside a 3.6 m maze
    lines = (out / "frames.jsonl").read_text().splitlines()
    assert len(lines) == 3 and "objects" in json.loads(lines[0])
    # each object's visible pixel count: what the in-view test (poi.core.in_view.boxable_view) needs
    objects = [o for line in lines for o in json.loads(line)["objects"]]
    assert objects and all(isinstance(o["pixels"], int) and o["pixels"] > 0 for o in objects)
    truth = read_poi_file(out / "truth.csv")
    assert truth.problems == [] and all(r.mode == "GT" for r in truth.rows)


def test_route_replayed_from_a_file_of_timed_poses(tmp_path):
    route = tmp_path / "route.csv"
    route.write_text("t_s,x_m,y_m,yaw_deg\n0,0,0,0\n4,1.2,0,0\n5,1.2,0,90\n")
    sc = apply_settings(load_scenario("default"), [f"robot.route={route}", "sensors.noise=false"])
    with Simulation(sc) as sim:
        assert sim.duration_s == pytest.approx(5.0)
        path = sim.robot_path_map()
        assert np.allclose(path[0], [0, 0]) and np.allclose(path[-1], [1.2, 0], atol=1e-9)
        # the map frame's x is the start heading: the tracker moved 1.2 m forward
        assert sim.T_map_tracker_true[40][0, 3] - sim.T_map_tracker_true[0][0, 3] == pytest.approx(1.2)


def test_bad_route_file_names_the_line(tmp_path):
    route = tmp_path / "route.csv"
    route.write_text("t_s,x_m,y_m,yaw_deg\n0,0,0,0\n0,1,0,0\n")
    sc = apply_settings(load_scenario("default"), [f"robot.route={route}"])
    with pytest.raises(ValueError, match=r"route.csv:3: time 0.0 does not increase"):
        Simulation(sc)


@pytest.mark.parametrize("lighting", ["bright", "dim", "uneven"])
def test_lighting_presets_render_and_dim_is_darker(lighting):
    sc = apply_settings(load_scenario("default"), [f"lighting={lighting}", "maze.file=rrl_small"])
    with Simulation(sc) as sim:
        frame, _ = sim.frame(0)
    mean = float(frame.rgb.mean())
    assert 5 < mean < 250
    if lighting == "dim":
        with Simulation(apply_settings(sc, ["lighting=bright"])) as sim:
            bright, _ = sim.frame(0)
        assert mean < 0.8 * float(bright.rgb.mean())
