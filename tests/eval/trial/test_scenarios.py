"""``--set`` routing: scenario keys to the scenario, pipeline sections to the pipeline, anything else refused."""

import pytest

from eval.cli.main import main
from eval.trial.scenarios import SettingError, apply_scenario_settings, split_settings
from sim.scenario import load_scenario


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
    with pytest.raises(SettingError, match=r"unknown scenario key 'gamma'; .*width.*\(under sensors\.d435\)"):
        apply_scenario_settings(load_scenario("default"), ["sensors.d435.gamma=2"])
    assert apply_scenario_settings(load_scenario("default"), ["sensors.fps=15"]).sensors.fps == 15
    assert not out.exists()
