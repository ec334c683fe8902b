"""A team's Python detector runs a scored trial from the command line, and its config.yaml reruns it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from eval.cli.main import main
from poi.core.poi_file import read_poi_file

DETECTORS = Path(__file__).resolve().parents[2] / "poi" / "detectors"  # red_detector.py
# no distractors: the toy detector takes any red blob (an orange bucket too) for an extinguisher
SCENE = [
    "--set",
    "maze.file=rrl_small",
    "--set",
    "objects.generate.counts={fire-extinguisher: 2, valve: 1}",
    "--set",
    "clutter_per_cell=0",
]
RED = "python:red_detector:RedBlobDetector"


@pytest.fixture
def team_module(monkeypatch):
    monkeypatch.syspath_prepend(str(DETECTORS))
    import red_detector

    return red_detector


@pytest.mark.slow
def test_a_python_detector_runs_a_scored_trial_and_its_config_reruns_it(tmp_path, team_module, capsys):
    weights = team_module.write_weights(tmp_path / "red.npz")
    out = tmp_path / "t"
    argv = ["run", "--detector", RED, "--set", f"detector.options.weights={weights}", "--set", "detector.conf=0.3"]
    assert main([*argv, "--max-frames", "60", "--no-video", "--quiet", "--out", str(out), *SCENE]) == 0
    err = capsys.readouterr().err
    note = f"note: {RED} takes its settings from detector.options only; detector.conf (the ONNX detector's)"
    assert note in err
    doc = json.loads((out / "score.json").read_text())
    assert doc["trial"]["detector"] == RED
    # its red blobs were tracked, reported and scored: an extinguisher found and placed, nothing false
    rows = read_poi_file(out / "pois.csv").rows
    assert [r.type for r in rows] == ["fire-extinguisher"]
    assert doc["total"] > 0 and doc["false_reports"] == 0
    again = tmp_path / "again"
    assert main(["run", "--config", str(out / "config.yaml"), "--out", str(again), "--quiet", "--no-video"]) == 0
    assert (again / "pois.csv").read_bytes() == (out / "pois.csv").read_bytes()
    assert (again / "score.json").read_bytes() == (out / "score.json").read_bytes()
    assert json.loads((again / "cost.json").read_text())["cpu_s"] > 0  # what it cost, which differs


@pytest.mark.parametrize(
    ("detector", "sets", "expected"),
    [
        (
            "python:red_detector:WrongOutput",
            ["--set", "detector.options.kind=class"],
            "poibench run: error: detector 'python:red_detector:WrongOutput' on frame 0: detection 0: "
            "class_name 'Toxic' is not in poi.core.names.CLASSES (did you mean 'inhalation-hazard'?)",
        ),
        (
            RED,
            ["--set", "detector.options.weight=w.npz"],
            f"poibench run: error: detector '{RED}': unknown option(s) weight; it takes weights, conf",
        ),
        (
            "python:red_detectr:RedBlobDetector",
            [],
            "poibench run: error: detector 'python:red_detectr:RedBlobDetector': cannot import module "
            "'red_detectr' (No module named 'red_detectr')",
        ),
        (
            "redblob",
            [],
            "poibench run: error: unknown detector 'redblob'; expected default | oracle | FILE.onnx | "
            "python:MODULE:CLASS | an installed detector's name (installed: ",
        ),
    ],
)
@pytest.mark.slow
def test_a_detector_mistake_is_one_line_and_exit_2(detector, sets, expected, tmp_path, team_module, capsys):
    argv = ["run", "--detector", detector, *sets, "--max-frames", "3", "--no-video", "--quiet", *SCENE]
    assert main([*argv, "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(expected)
    assert err.count("\n") == 1


def test_sweep_refuses_a_detector_that_does_not_import_before_any_trial(tmp_path, capsys):
    argv = ["sweep", "--suite", "smoke", "--set", "tracker.gate=4", "--detector", "python:no_such_team_mod:Det"]
    assert main([*argv, "--out", str(tmp_path / "sw"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "poibench sweep: error: detector 'python:no_such_team_mod:Det': cannot import module "
        "'no_such_team_mod' (No module named 'no_such_team_mod')\n"
    )
    assert not (tmp_path / "sw" / "trials.csv").exists()
