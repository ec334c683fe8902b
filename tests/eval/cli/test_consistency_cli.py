"""`poibench consistency`: the table, consistency.json and consistency.png; bad input is one line."""

import json

import pytest

from eval.cli.main import main


@pytest.mark.slow
def test_consistency_writes_the_table_json_and_plot(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["consistency", "--frames", "10", "--runs", "1", "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert table.splitlines()[0].split()[:4] == ["quantity", "N", "N_eff", "d"]
    doc = json.loads((out / "consistency.json").read_text())
    assert doc["frames"] == 10 and doc["runs"] == ["default:7"]
    rows = {r["quantity"]: r for r in doc["rows"]}
    # one pose a frame from frame 1: frame 0 keeps the odometry (the T265 latency; slam_localizer)
    assert rows["SLAM pose"]["n"] == 9 and rows["SLAM pose"]["d"] == 3
    assert (rows["SLAM pose position"]["d"], rows["SLAM pose heading"]["d"]) == (2, 1)
    assert rows["SLAM pose position"]["n"] == rows["SLAM pose heading"]["n"] == 9
    assert any(q.startswith("R cam ") for q in rows) and any(q.startswith("R map ") for q in rows)
    for r in rows.values():
        lo, hi = r["interval_99"]
        assert r["inside"] == (lo <= r["mean_nees"] <= hi)
    assert (out / "consistency.png").stat().st_size > 10_000


@pytest.mark.slow
def test_frames_all_runs_each_scenario_to_its_end(tmp_path):
    out = tmp_path / "c"
    # the default maze cut to 1.2 s: 13 frames at 10 frames a second
    args = [
        "consistency",
        "--frames",
        "all",
        "--runs",
        "1",
        "--set",
        "robot.max_duration_s=1.2",
        "--out",
        str(out),
    ]
    assert main(args) == 0
    doc = json.loads((out / "consistency.json").read_text())
    assert doc["frames"] == 13 and doc["frames_per_run"] == "all"


def test_consistency_refuses_bad_arguments_in_one_line(tmp_path, capsys):
    assert main(["consistency", "--frames", "0", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "poibench consistency: error: --frames: expected a positive number of frames, got 0"
    with pytest.raises(SystemExit):
        main(["consistency", "--frames", "most", "--out", str(tmp_path / "c")])
    assert "--frames: expected a number of frames or 'all', got 'most'" in capsys.readouterr().err
    assert main(["consistency", "default", "--suite", "rrl-hard", "--out", str(tmp_path / "c")]) == 2
    assert "SCENARIO or --suite" in capsys.readouterr().err


@pytest.mark.slow
def test_fit_extents_prints_settings_the_pipeline_takes(tmp_path, capsys):
    from poi.config import apply_overrides, load_config

    out = tmp_path / "c"
    sweep = ["--set", "robot.pan.mode=sweep"]  # the earlier tour: a 3-D object in its first 4 frames
    assert main(["consistency", "--frames", "4", "--runs", "1", "--fit-extents", *sweep, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    # the default maze's first frames see its valve (frame 0 is not observed: its pose is stale)
    assert "offset change (m)" in text and "\nvalve " in text
    doc = json.loads((out / "consistency.json").read_text())
    fits = {f["type"]: f for f in doc["extent_fit"]["fits"]}
    assert fits["valve"]["n"] >= 3 and fits["valve"]["objects"] == 1
    sets = doc["extent_fit"]["settings"]
    valve = [s.split("=")[0] for s in sets if s.startswith("localize.types.valve.")]
    assert valve == [
        f"localize.types.valve.{k}" for k in ("surface_to_center_m", "extent_ray_sigma_m", "extent_sigma_m")
    ]
    cfg = apply_overrides(load_config(), sets)  # the printed settings load as they are
    assert cfg.localize.types["valve"].extent_sigma_m == round(fits["valve"]["sigma_lat_m"], 3)
    # its three boxes here are all cut (localize's box_cut: the image border or a nearer
    # surface), so no full-view size is fitted and the printed one is the pipeline's
    assert fits["valve"]["box_height_m"] is None
    assert cfg.localize.types["valve"].box_height_m == load_config().localize.types["valve"].box_height_m
    before = load_config().localize.types["valve"].surface_to_center_m
    assert cfg.localize.types["valve"].surface_to_center_m == round(before + fits["valve"]["offset_change_m"], 3)
    # no 3-D type in the pipeline's settings: nothing to fit, said in one line
    none = ["localize.types={qr: {shape: flat, aspect: 1.0}}"]
    args = ["consistency", "--frames", "1", "--runs", "1", "--fit-extents", "--out", str(tmp_path / "d")]
    assert main(args + [a for s in none for a in ("--set", s)]) == 2
    assert capsys.readouterr().err.strip().endswith("--fit-extents: no observation of a 3-D type in these runs")


def test_suite_runs_past_the_suite_size_take_its_scenarios_again_with_fresh_seeds():
    from eval.cli.consistency import suite_runs
    from eval.experiments.consistency import ConsistencyError
    from eval.experiments.suites import load_suite

    suite = load_suite("rrl-hard")
    n = len(suite.scenarios)
    runs = suite_runs(["rrl-hard"], n + 2, 401, [])
    assert [sc.seed for sc in runs] == list(range(401, 401 + n + 2))
    assert all(sc.sensors.noise for sc in runs)
    with pytest.raises(
        ConsistencyError, match=rf"--runs {n + 2}: suite 'rrl-hard' has {n} scenarios; give --seed"
    ):
        suite_runs(["rrl-hard"], n + 2, None, [])
    own = [suite.build(e).seed for e in suite.scenarios[:2]]
    assert [sc.seed for sc in suite_runs(["rrl-hard"], 2, None, [])] == own
