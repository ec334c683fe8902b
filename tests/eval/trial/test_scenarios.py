"""``--set`` routing: scenario keys to the scenario, pipeline sections to the pipeline, anything else refused."""

import pytest

from eval.cli.main import main
from eval.trial.scenarios import SettingError, split_settings
from sim.scenario import ScenarioError, apply_settings, load_scenario


def test_settings_are_split_by_their_first_key():
    sim, pipe = split_settings(["sensors.fps=15", "tracker.gate=4", "seed=3", "detector.options.names=n.txt"])
    assert sim == ["sensors.fps=15", "seed=3"]
    assert pipe == ["tracker.gate=4", "detector.options.names=n.txt"]


def test_a_mistyped_scenario_key_lists_both_kinds_of_key():
    with pytest.raises(SettingError) as info:
        split_settings(["tracker.gate=4", "sensor.fps=15"])
    msg = str(info.value)
    assert "sensor.fps=15" in msg and "\n" not in msg
    assert "scenario key (" in msg and "sensors" in msg and "robot" in msg
    assert "pipeline section (" in msg and "tracker" in msg and "detector" in msg


@pytest.mark.slow
def test_run_refuses_it_as_one_line_before_simulating(tmp_path, capsys):
    out = tmp_path / "t"
    assert main(["run", "--out", str(out), "--set", "sensor.fps=15", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error: --set sensor.fps=15") and "sensors" in err and "tracker" in err
    assert not out.exists()


@pytest.mark.slow
def test_an_unknown_scenario_name_lists_the_shipped_ones_and_the_suite_it_looks_like(tmp_path, capsys):
    # issue 60 edge 6: "rrl-1: cannot read: No such file or directory", no names
    out = tmp_path / "t"
    assert main(["run", "nowhere", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error: nowhere: no such scenario file or shipped scenario; ")
    assert "shipped scenarios are default, rmrc, turtlebot-goal" in err and "\n" not in err
    assert "suite" not in err
    assert main(["run", "rrl-1", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "shipped scenarios are default" in err and err.endswith("runs with poibench suite run rrl")
    assert not out.exists()


@pytest.mark.slow
def test_an_unknown_scenario_key_lists_the_keys_valid_at_its_level(tmp_path, capsys):
    # issue 60 edge 6: "--set sensors.fsp: unknown setting", no keys (the pipeline's --set lists them)
    out = tmp_path / "t"
    assert main(["run", "--out", str(out), "--set", "sensors.fsp=15", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("poibench run: error: --set sensors.fsp: unknown scenario key 'fsp'; expected one of ")
    assert "fps" in err and "d435" in err and "(under sensors)" in err and "\n" not in err
    with pytest.raises(ScenarioError, match=r"unknown scenario key 'gamma'; .*width.*\(under sensors\.d435\)"):
        apply_settings(load_scenario("default"), ["sensors.d435.gamma=2"])
    assert apply_settings(load_scenario("default"), ["sensors.fps=15"]).sensors.fps == 15
    assert not out.exists()


def test_a_key_under_a_section_left_unset_is_checked_by_the_sections_own_keys():
    """A section the scenario leaves unset (the TurtleBot arena's maze, a maze file's generator) has no
    keys in the data to list: its settings class names them, or says why the section cannot be set."""
    with pytest.raises(ScenarioError, match=r"generate\.foo: unknown key; expected one of rows, cols"):
        apply_settings(load_scenario("default"), ["maze.file=null", "maze.generate.foo=1"])
    sets = ["maze.file=null", "maze.generate.rows=3", "maze.generate.cols=5"]
    generated = apply_settings(load_scenario("default"), sets)
    assert (generated.maze.generate.rows, generated.maze.generate.cols, generated.maze.file) == (3, 5, None)
    with pytest.raises(ScenarioError, match=r"maze: .*file.*generate|file or generate"):
        apply_settings(load_scenario("default"), ["maze.generate.rows=3"])  # a file and a generator
    with pytest.raises(ScenarioError, match=r"arena|maze") as info:
        apply_settings(load_scenario("turtlebot-goal"), ["maze.generate.rows=3"])
    assert "\n" not in str(info.value)
    with pytest.raises(ScenarioError, match=r"--set lighting\.x: lighting is a value, not a section with 'x'"):
        apply_settings(load_scenario("default"), ["lighting.x=1"])


def test_a_large_generated_maze_says_its_set_up_takes_long():
    from eval.trial.scenarios import large_maze_note

    big = apply_settings(
        load_scenario("default"), ["maze.file=null", "maze.generate.rows=20", "maze.generate.cols=20"]
    )
    assert large_maze_note(big).startswith("a 20 x 20 maze: its world and the robot's tour of all 400 cells")
    small = apply_settings(big, ["maze.generate.cols=19"])
    assert large_maze_note(small) is None and large_maze_note(load_scenario("default")) is None
    assert large_maze_note(load_scenario("turtlebot-goal")) is None
