"""`poibench run rmrc`: the RMRC labyrinth under its own rules (rmrc2026) asks the pipeline for
the mapping fiducials, which it finds from depth and writes as 'fiducial' rows; the score says
how the QR mapping bonus was judged."""

from __future__ import annotations

import json
import math

import pytest
import yaml

from eval.cli.main import main
from poi.core.poi_file import read_poi_file

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


def test_rmrc_trial_reports_the_fiducials_it_passes(tmp_path, capsys) -> None:
    out = tmp_path / "t"
    args = ["run", "rmrc", "--out", str(out), "--detector", "oracle", "--max-frames", "90", "--quiet"]
    args += ["--set", "robot.pan.mode=sweep"]  # the earlier tour, whose first 9 s pass the pair
    assert main([*args, "--no-video", "--no-live-record"]) == 0
    assert yaml.safe_load((out / "config.yaml").read_text())["pipeline"]["fiducials"]["enabled"] is True
    truth = [r for r in read_poi_file(out / "truth.csv").rows if r.type == "fiducial"]
    found = [r for r in read_poi_file(out / "pois.csv").rows if r.type == "fiducial"]
    assert len(truth) == 6 and found
    # the first 9 s pass the pair across the first corridor: every fiducial found is within
    # 0.12 m of a true one (the pipe's axis), and the two of that pair are found
    near = [min(math.dist((f.x, f.y), (t.x, t.y)) for t in truth) for f in found]
    assert max(near) < 0.12 and len(found) >= 2
    doc = json.loads((out / "score.json").read_text())
    assert doc["qr_mapping"]["fiducials_reported"] == len(found)
    assert doc["qr_mapping"]["fiducials_paired"] == len(found)
    assert "QR mapping by fiducials" in capsys.readouterr().out


def test_the_fiducials_are_not_called_unreportable(tmp_path, capsys) -> None:
    """The shipped detector boxes no fiducials, but the fiducial mapper finds them from depth: a run
    of the rmrc scenario does not note them among the types the detector cannot report."""
    out = tmp_path / "t"
    argv = ["run", "rmrc", "--out", str(out), "--max-frames", "2", "--quiet", "--no-video", "--no-live-record"]
    assert main(argv) == 0
    printed = capsys.readouterr()
    assert "cannot report this scenario's" not in printed.out + printed.err
