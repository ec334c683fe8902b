"""Suites, sweeps (cross product, resume after a kill, failing trials, Ray = local) and regress."""

import json
import os
import signal
import subprocess
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from eval.cli.main import main
from eval.experiments.suites import SuiteError, load_suite, shipped_suites
from eval.experiments.sweep import (
    RowWriter,
    SweepError,
    SweepSpec,
    aggregate,
    drop_torn_tail,
    make_tasks,
    parse_grid,
    read_rows,
    run_sweep,
    write_in_task_order,
)
from poi.core.poi_file import read_poi_file

TINY = str(Path(__file__).parent / "data" / "tiny_suite.yaml")
RESULT_COLS = ["trial", "scenario", "seed", "score", "max_score", "fraction", "false_reports", "misses"]


def test_shipped_suites_load_and_build():
    assert shipped_suites() == ["rmrc", "rrl", "rrl-hard", "smoke", "tune"]
    rrl = load_suite("rrl")
    assert len(rrl.scenarios) == 10 and len(load_suite("smoke").scenarios) == 2
    hard = load_suite("rrl-hard")
    sc = hard.build(hard.scenarios[0])
    assert sc.lighting == "dim" and sc.sensors.t265.drift_fraction == 0.03
    assert sc.objects.generate.counts["hazmat"] == 10 and sc.name == "hard-01"
    # the tuning suite: seeds no scored suite uses; its last three built as rrl-hard's mazes are
    tune = load_suite("tune")
    scored = {x.seed for name in ("rrl", "rrl-hard", "rmrc", "smoke") for x in load_suite(name).scenarios}
    assert len(tune.scenarios) == 9 and not {x.seed for x in tune.scenarios} & scored
    t7 = tune.build(tune.scenarios[6])
    assert t7.lighting == "dim" and t7.sensors.t265.drift_fraction == 0.03
    assert t7.objects.generate.counts == sc.objects.generate.counts


def test_suite_files_are_checked(tmp_path):
    bad = tmp_path / "s.yaml"
    bad.write_text("poibench_suite: 1\nname: x\nversion: 1\nscenarios:\n  - {name: a, seed: 1}\n")
    with pytest.raises(SuiteError, match=r"scenarios\[0\]: give exactly one of"):
        load_suite(bad)
    with pytest.raises(SuiteError, match="no such suite"):
        load_suite("nope")
    # a setting of the file is named as the file's, not as a --set, with the keys it could be
    bad.write_text(
        "poibench_suite: 1\nname: x\nversion: 1\nsettings: [robot.max_duration_ss=3]\nscenarios:\n"
        "  - {name: a, scenario: default, seed: 1}\n"
    )
    suite = load_suite(bad)
    with pytest.raises(
        SuiteError, match=r"scenario a: the suite's settings robot.max_duration_ss: unknown scenario key "
    ):
        suite.build(suite.scenarios[0])
    with pytest.raises(SuiteError, match=r"expected one of kind, route, speed_mps, "):
        suite.build(suite.scenarios[0])


def test_cross_product_of_settings_and_scenarios(tmp_path):
    grid = parse_grid(["tracker.gate=4,9,16", "lighting=bright,dim"])
    tasks = make_tasks(load_suite(TINY), SweepSpec(suite=TINY, grid=grid), tmp_path)
    assert len(tasks) == 3 * 2 * 2
    combos = {(t.settings["tracker.gate"], t.settings["lighting"], t.scenario_name) for t in tasks}
    assert len(combos) == 12 and len({t.trial for t in tasks}) == 12
    # scenario settings go into the scenario, pipeline ones stay settings of the run
    dim = next(t for t in tasks if t.settings["lighting"] == "dim")
    assert "lighting: dim" in dim.scenario_yaml
    with pytest.raises(SweepError, match="given twice"):
        parse_grid(["a=1", "a=2"])
    with pytest.raises(SweepError, match=r"^--set tracker.gate: empty value in '4,,9'$"):
        parse_grid(["tracker.gate=4,,9"])
    with pytest.raises(SweepError, match="--set"):
        make_tasks(load_suite(TINY), SweepSpec(suite=TINY, grid=parse_grid(["tracker.nope=1"])), tmp_path)


def test_a_sweep_over_detector_model_is_refused_before_any_trial(tmp_path):
    # issue 60 edge 1: every row had the shipped detector's score under the team's model's name
    grid = parse_grid(["detector.model=a.onnx,b.onnx"])
    with pytest.raises(SweepError, match=r"^--set: detector.model=a.onnx: .*--detector FILE.onnx"):
        make_tasks(load_suite(TINY), SweepSpec(suite=TINY, grid=grid), tmp_path)
    with pytest.raises(SweepError, match="--detector FILE.onnx"):
        run_sweep(SweepSpec(suite=TINY, grid=grid), tmp_path / "s")
    assert not (tmp_path / "s" / "trials.csv").exists()


def test_workers_below_one_are_refused(tmp_path, capsys):
    # issue 60 edge 12: --workers 0 was accepted
    for cmd in (["suite", "run", TINY], ["sweep", "--suite", TINY, "--out", str(tmp_path / "w")]):
        with pytest.raises(SystemExit) as info:
            main([*cmd, "--workers", "0"])
        assert info.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.endswith("error: argument --workers: expected a whole number of at least 1, got 0")
    with pytest.raises(SweepError, match="--workers must be at least 1, got 0"):
        run_sweep(SweepSpec(suite=TINY, workers=0), tmp_path / "s")
    assert not (tmp_path / "s").exists()


@pytest.mark.slow
def test_a_failing_trial_is_a_row_and_the_sweep_goes_on(tmp_path, monkeypatch):
    import eval.trial.run

    real = eval.trial.run.run_trial

    def flaky(sc, *a, **k):
        if sc.name == "tiny-2":
            raise RuntimeError("simulated crash\nwith a second line")
        return real(sc, *a, **k)

    monkeypatch.setattr(eval.trial.run, "run_trial", flaky)
    df, agg = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"])), tmp_path / "s")
    assert len(df) == 2
    row = df.set_index("scenario").loc["tiny-2"]
    assert row["error"] == "RuntimeError: simulated crash"
    assert df.set_index("scenario").loc["tiny-1", "error"] == ""
    assert agg.loc[0, "trials"] == 2 and agg.loc[0, "failed"] == 1
    # the command fails with it, as suite run does (a CI job sees it)
    argv = ["sweep", "--suite", TINY, "--set", "tracker.gate=9", "--no-cache", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "m")]) == 1
    # --resume runs the failed one again (now working) and keeps the finished row
    monkeypatch.setattr(eval.trial.run, "run_trial", real)
    df2, _ = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"]), resume=True), tmp_path / "s")
    assert (df2["error"] == "").all() and len(df2) == 2
    # the rerun was appended; the run's end leaves one row a trial, the rerun's, in task order
    rows = pd.read_csv(tmp_path / "s" / "trials.csv", keep_default_na=False)
    assert list(rows["scenario"]) == ["tiny-1", "tiny-2"] and (rows["error"] == "").all()


def test_a_map_error_preset_is_refused_before_any_trial(tmp_path):
    with pytest.raises(SweepError, match="turtlebot scores a map error"):
        run_sweep(SweepSpec(suite=TINY, rules="turtlebot"), tmp_path / "s")
    assert not (tmp_path / "s").exists()


def test_each_trial_is_scored_by_its_scenarios_own_rules_unless_rules_are_given(tmp_path):
    # as poibench run: the rmrc scenario names rmrc2026, a generated maze none (ex3)
    suite = tmp_path / "mixed.yaml"
    suite.write_text(
        "poibench_suite: 1\nname: mixed\nversion: 1\nscenarios:\n"
        "  - {name: lab, scenario: rmrc, seed: 1}\n"
        "  - {name: gen, generate: {rows: 2, cols: 2, preset: rrl}, seed: 2}\n"
    )
    tasks = make_tasks(load_suite(suite), SweepSpec(suite=str(suite)), tmp_path / "s")
    assert [(t.scenario_name, t.rules) for t in tasks] == [("lab", "rmrc2026"), ("gen", "ex3")]
    tasks = make_tasks(load_suite(suite), SweepSpec(suite=str(suite), rules="rmrc2025"), tmp_path / "s")
    assert [t.rules for t in tasks] == ["rmrc2025", "rmrc2025"]
    # a scenario whose own rules score a map error is refused by name, before any trial
    suite.write_text(suite.read_text().replace("scenario: rmrc", "scenario: turtlebot-goal"))
    with pytest.raises(SweepError, match="scenario lab's own rules turtlebot: .* map error"):
        run_sweep(SweepSpec(suite=str(suite)), tmp_path / "t")
    assert not (tmp_path / "t").exists()


def test_an_existing_sweep_needs_resume_with_the_same_settings(tmp_path):
    run_sweep(SweepSpec(suite=TINY), tmp_path)
    with pytest.raises(SweepError, match="--resume"):
        run_sweep(SweepSpec(suite=TINY), tmp_path)
    with pytest.raises(SweepError, match="other settings"):
        run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=4"]), resume=True), tmp_path)


def test_a_trial_folder_or_other_files_are_no_place_for_a_sweep(tmp_path):
    trial = tmp_path / "trial"
    trial.mkdir()
    (trial / "config.yaml").write_text("detector: oracle\n")
    with pytest.raises(SweepError, match=r"trial holds a trial \(poibench run\), not a suite run or sweep"):
        run_sweep(SweepSpec(suite=TINY, resume=True), trial)
    (trial / "config.yaml").rename(trial / "notes.txt")
    with pytest.raises(SweepError, match="holds other files"):
        run_sweep(SweepSpec(suite=TINY), trial)
    assert sorted(p.name for p in trial.iterdir()) == ["notes.txt"]


@pytest.mark.slow
def test_resume_after_a_kill_loses_nothing_and_matches_an_unbroken_run(tmp_path):
    args = ["--suite", TINY, "--set", "tracker.gate=4,9,16", "--quiet"]
    cmd = [sys.executable, "-m", "eval.cli.main", "sweep", *args, "--out", str(tmp_path / "k")]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    trials = tmp_path / "k" / "trials.csv"
    deadline = time.time() + 120
    while time.time() < deadline and len(read_rows(trials)) < 2:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    before = read_rows(trials)
    assert 2 <= len(before) < 6, "the sweep was killed midway"
    assert main(["sweep", *args, "--out", str(tmp_path / "k"), "--resume"]) == 0
    after = read_rows(trials)
    assert len(after) == 6
    # the rows written before the kill are still there, unchanged
    pd.testing.assert_frame_equal(
        after.set_index("trial").loc[before["trial"], RESULT_COLS[1:]], before.set_index("trial")[RESULT_COLS[1:]]
    )
    assert main(["sweep", *args, "--out", str(tmp_path / "u")]) == 0
    unbroken = read_rows(tmp_path / "u" / "trials.csv")
    key = ["trial"]
    pd.testing.assert_frame_equal(
        after[RESULT_COLS].sort_values(key).reset_index(drop=True),
        unbroken[RESULT_COLS].sort_values(key).reset_index(drop=True),
    )
    assert (tmp_path / "u" / "score.png").exists() and (tmp_path / "u" / "aggregate.csv").exists()


@pytest.mark.slow
def test_a_torn_last_line_is_dropped_on_resume_and_its_trial_runs_again(tmp_path, capsys):
    spec = SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"]))
    whole, _ = run_sweep(spec, tmp_path)
    trials = tmp_path / "trials.csv"
    text = trials.read_bytes()
    lines = text.splitlines(keepends=True)
    assert len(lines) == 3 and all(line.endswith(b"\r\n") for line in lines)
    cut = len(text) - len(lines[-1]) // 2  # the last row, cut mid-row as a crash would leave it
    trials.write_bytes(text[:cut])
    torn = lines[-1].split(b",")[0].decode()
    assert torn not in set(read_rows(trials)["trial"])
    df, _ = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"]), resume=True), tmp_path)
    assert "dropped a torn last line" in capsys.readouterr().err
    # the fragment is gone, the rerun row is a line of its own: the file reads strictly
    strict = pd.read_csv(trials, dtype={"trial": str})
    assert len(strict) == 2 and list(strict["trial"]) == list(whole["trial"])
    assert trials.read_bytes().startswith(text[: len(text) - len(lines[-1])])
    pd.testing.assert_frame_equal(df[RESULT_COLS], whole[RESULT_COLS])


@pytest.mark.slow
def test_rows_and_aggregate_give_each_trials_cpu_seconds(tmp_path):
    df, agg = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"])), tmp_path)
    assert (df["cpu_s"] > 0).all() and (df["cpu_s_per_sim_s"] > 0).all()
    # the tiny suite drives 4 s (the last frame's time is at most one frame short of it)
    sim_s = df["cpu_s"] / df["cpu_s_per_sim_s"]
    assert ((sim_s > 3.8) & (sim_s < 4.01)).all(), sim_s
    assert agg.loc[0, "cpu_s_mean"] == pytest.approx(df["cpu_s"].mean(), abs=0.01)
    assert agg.loc[0, "cpu_s_per_sim_s_mean"] == pytest.approx(df["cpu_s_per_sim_s"].mean(), abs=1e-4)
    # each row's funnel charges its lost points (max - score), and funnel.csv sums them per type
    assert (df["funnel_check"] == "ok").all()
    assert np.allclose(df["funnel_lost"], df["max_score"] - df["score"])
    assert df["boxes_per_frame"].notna().all()
    funnel = pd.read_csv(tmp_path / "funnel.csv")
    causes = [c for c in funnel.columns if c.startswith(("not ", "false: ", "reported", "misplaced", "taken"))]
    causes += ["autonomy withheld"]
    assert funnel[causes].to_numpy().sum() == pytest.approx((df["max_score"] - df["score"]).sum())
    assert funnel["objects"].sum() == len(df) * len(
        read_poi_file(tmp_path / "trials" / df["trial"][0] / "truth.csv").rows
    )
    # a trials.csv of other columns (an older poibench) is refused, not appended to
    header = (tmp_path / "trials.csv").read_text().splitlines()[0]
    (tmp_path / "trials.csv").write_text(header.replace(",cpu_s,cpu_s_per_sim_s", "") + "\n")
    with pytest.raises(
        SweepError, match=r"holds the rows of another run \(its columns \(none\), this run's cpu_s, "
    ):
        run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.gate=9"]), resume=True), tmp_path)


def test_a_finished_run_leaves_one_row_a_trial_in_task_order(tmp_path):
    """Rows appended in the order workers finished, one trial run twice (a resume's rerun after
    a failure): the rewrite keeps each trial's last row, in the order the run's tasks were made,
    every value as written, and leaves out a trial without a row."""
    path = tmp_path / "trials.csv"
    fields = ["trial", "scenario", "score", "error", "complete"]
    w = RowWriter(path, fields)
    for row in [("c", "m3", "7.50", "", "1"), ("a", "m1", "", "RuntimeError: x", "1"), ("b", "m2", "4", "", "1")]:
        w.write(dict(zip(fields, row, strict=True)))
    w.write(dict(zip(fields, ("a", "m1", "5.0", "", "1"), strict=True)))
    w.close()
    write_in_task_order(path, ["a", "b", "c", "d"])
    assert path.read_text(encoding="utf-8").splitlines() == [
        "trial,scenario,score,error,complete",
        "a,m1,5.0,,1",
        "b,m2,4,,1",
        "c,m3,7.50,,1",
    ]


def test_drop_torn_tail_keeps_whole_lines_only(tmp_path):
    f = tmp_path / "t.csv"
    for content, kept in [
        (b"", b""),
        (b"a,b\r\n", b"a,b\r\n"),
        (b"a,b\r\n1,2\r", b"a,b\r\n"),  # cut between the two bytes of the line end
        (b"a,b\r\n1,", b"a,b\r\n"),
        (b"a,", b""),  # a torn header: the next writer writes it again
    ]:
        f.write_bytes(content)
        assert drop_torn_tail(f) == len(content) - len(kept)
        assert f.read_bytes() == kept
    f.write_bytes(b"a,")
    w = RowWriter(f, ["a", "b"])
    w.write({"a": 1, "b": 2})
    w.close()
    assert f.read_bytes() == b"a,b\r\n1,2\r\n"


@pytest.mark.slow
def test_two_workers_give_the_rows_of_one(tmp_path):
    one, _ = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.n_min=2,3"])), tmp_path / "a")
    two, agg = run_sweep(SweepSpec(suite=TINY, grid=parse_grid(["tracker.n_min=2,3"]), workers=2), tmp_path / "b")
    cols = RESULT_COLS
    # the same rows in the same (task) order, so the same bootstrap intervals
    pd.testing.assert_frame_equal(one[cols].reset_index(drop=True), two[cols].reset_index(drop=True))
    assert list(agg["set.tracker.n_min"].astype(str)) == ["2", "3"]
    same = ["fraction_mean", "fraction_ci95_low", "fraction_ci95_high", "false_reports_mean"]
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "aggregate.csv")[same], agg[same])


@pytest.mark.slow
def test_ray_backend_gives_the_same_table(tmp_path):
    pytest.importorskip("ray")
    grid = parse_grid(["tracker.gate=4,9"])
    local, _ = run_sweep(SweepSpec(suite=TINY, grid=grid), tmp_path / "local")
    ray_rows, _ = run_sweep(SweepSpec(suite=TINY, grid=grid, backend="ray", workers=2), tmp_path / "ray")
    pd.testing.assert_frame_equal(
        local[RESULT_COLS].sort_values("trial").reset_index(drop=True),
        ray_rows[RESULT_COLS].sort_values("trial").reset_index(drop=True),
    )


def test_aggregate_mean_and_bootstrap_interval():
    df = pd.DataFrame(
        {
            "set.a": ["1", "1", "1", "2"],
            "fraction": [0.5, 0.7, 0.9, 1.0],
            "error": ["", "", "", ""],
            "score": [1, 2, 3, 4],
            "false_reports": [0, 0, 0, 0],
            "misses": [1, 1, 1, 0],
            # a trial that located nothing has no location error: the mean is over the others,
            # and NaN (with no numpy warning) when none has one
            "loc_err_median_m": [0.1, float("nan"), 0.3, float("nan")],
            "pose_err_median_m": [0.2, 0.2, 0.2, 0.2],
            "wall_s": [1, 1, 1, 1],
            "cpu_s": [2.0, 4.0, 6.0, 1.0],
            "cpu_s_per_sim_s": [0.2, 0.4, 0.6, 0.1],
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        agg = aggregate(df, ["a"]).set_index("set.a")
    assert agg.loc["1", "loc_err_median_m"] == pytest.approx(0.2)
    assert pd.isna(agg.loc["2", "loc_err_median_m"])
    assert agg.loc["1", "cpu_s_mean"] == pytest.approx(4.0) and agg.loc["2", "cpu_s_mean"] == pytest.approx(1.0)
    assert agg.loc["1", "cpu_s_per_sim_s_mean"] == pytest.approx(0.4)
    # mean 0.7 of 0.5, 0.7, 0.9: a bootstrap draw of one value three times has probability 1/27 (3.7%,
    # above 2.5%), so the 95% percentile interval's ends are the smallest and largest value
    assert agg.loc["1", "fraction_mean"] == pytest.approx(0.7)
    assert (agg.loc["1", "fraction_ci95_low"], agg.loc["1", "fraction_ci95_high"]) == (0.5, 0.9)
    assert pd.isna(agg.loc["2", "fraction_ci95_low"])  # one trial: no interval


@pytest.mark.slow
def test_regress_passes_then_fails_against_a_raised_baseline(tmp_path, capsys):
    base = tmp_path / "baseline.json"
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--update", "--quiet"]) == 0
    doc = json.loads(base.read_text())
    assert doc["suite"] == "tiny" and set(doc["scenarios"]) == {"tiny-1", "tiny-2"}
    junit = tmp_path / "junit.xml"
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--junit", str(junit), "--quiet"]) == 0
    root = ET.parse(junit).getroot()
    assert root.find("testsuite").get("failures") == "0" and len(root.iter("testcase").__next__().attrib) >= 2
    doc["mean_fraction"] += 0.1
    doc["scenarios"]["tiny-1"] += 0.1
    base.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--junit", str(junit), "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "DROP tiny-1" in out and "FAIL mean score fraction" in out
    failures = [c.get("name") for c in ET.parse(junit).getroot().iter("testcase") if c.find("failure") is not None]
    assert failures == ["tiny-1", "mean"]


def _tiny_baseline(path: Path, **fields) -> Path:
    from eval.experiments.regress import BASELINE_VERSION

    suite = load_suite(TINY)
    doc = {"poibench_baseline": BASELINE_VERSION, "suite": suite.name, "suite_version": suite.version}
    doc |= {"detector": "default", "rules": None, "settings": [], "mean_fraction": 0.5, "scenarios": {}}
    path.write_text(json.dumps(doc | fields))
    return path


def test_regress_refuses_other_rules_and_an_unwritable_junit_before_any_trial(tmp_path, capsys, monkeypatch):
    import eval.cli.sweep as cli_sweep

    monkeypatch.setattr(cli_sweep, "_run", lambda *a: pytest.fail("a trial ran"))
    base = _tiny_baseline(tmp_path / "b.json", rules="rmrc2026")
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{base}: the baseline was scored with rules rmrc2026, this run with each scenario its own" in err
    base = _tiny_baseline(tmp_path / "b.json")
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--junit", "/proc/x.xml", "--quiet"]) == 2
    assert "error: --junit /proc/x.xml: its folder" in capsys.readouterr().err


def test_flags_that_cannot_take_effect_are_refused_before_any_trial(tmp_path, capsys):
    out = ["--out", str(tmp_path / "w"), "--quiet"]
    assert main(["sweep", "--suite", TINY, "--set", "tracker.gate=4,9", "--address", "1.2.3.4:10001", *out]) == 2
    assert (
        "error: --address 1.2.3.4:10001: a Ray cluster's address; it needs --backend ray"
        in capsys.readouterr().err
    )
    base = _tiny_baseline(tmp_path / "b.json")
    argv = ["regress", "--suite", TINY, "--baseline", str(base), "--merged", str(tmp_path), "--workers", "2"]
    assert main(argv) == 2
    assert "error: --workers with --merged" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()


def test_a_baseline_of_another_detector_or_settings_is_named_in_the_verdict(tmp_path):
    from eval.experiments.regress import check_baseline_run

    base = {"detector": "default", "rules": None, "settings": ["tracker.gate=4"]}
    path = tmp_path / "b.json"
    assert check_baseline_run(base, path, "default", None, ["tracker.gate=4"]) is None
    assert check_baseline_run(base, path, "oracle", None, []) == (
        "note: against a baseline of another pipeline: detector default -> oracle; --set tracker.gate=4 -> (none)"
    )


@pytest.mark.parametrize(
    "params, said",
    [
        (["tracker.gate=float:-5:2"], "--param tracker.gate: range end -5.0 is refused (tracker.gate: "),
        (["tracker.gatee=float:2:25"], "--param tracker.gatee: range end 2.0 is refused ("),
        (["localize.mode=choice:slam,foo"], "--param localize.mode: choice foo is refused ("),
        (["tracker.gate=float:2:25", "tracker.gate=float:3:4"], "--param tracker.gate: given twice"),
        (["tracker.n_min=int:1.5:6"], "--param tracker.n_min: int:LOW:HIGH needs whole numbers, got 1.5:6"),
    ],
)
def test_tune_refuses_a_parameter_trials_would_refuse_up_front(tmp_path, capsys, monkeypatch, params, said):
    import eval.experiments.tune as tune

    monkeypatch.setattr(tune, "run_local", lambda *a: pytest.fail("a trial ran"))
    out = tmp_path / "u"
    argv = ["tune", "--suite", TINY, *(a for p in params for a in ("--param", p)), "--trials", "1", "--quiet"]
    assert main([*argv, "--no-cache", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()  # nothing written: the same --out takes the corrected command


def test_regress_without_a_baseline_says_so(tmp_path, capsys):
    assert main(["regress", "--suite", TINY, "--baseline", str(tmp_path / "none.json"), "--quiet"]) == 2
    assert "no such baseline" in capsys.readouterr().err


def test_tune_finds_settings_writes_the_study_and_repeats_itself(tmp_path, capsys):
    pytest.importorskip("optuna")
    args = [
        "tune",
        "--suite",
        TINY,
        "--param",
        "tracker.gate=float:4:16",
        "--param",
        "tracker.n_min=int:2:4",
        "--trials",
        "3",
        "--seed",
        "5",
        "--quiet",
    ]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert "best mean score fraction" in capsys.readouterr().out
    import yaml

    best = yaml.safe_load((tmp_path / "a" / "best.yaml").read_text())
    study = pd.read_csv(tmp_path / "a" / "study.csv")
    assert len(study) == 3 and best["best_mean_fraction"] == pytest.approx(study["value"].max(), abs=1e-6)
    assert [s.split("=")[0] for s in best["settings"]] == ["tracker.gate", "tracker.n_min"]
    n_min = int(best["settings"][1].split("=")[1])
    assert 2 <= n_min <= 4 and best["pipeline"]["tracker"]["n_min"] == n_min
    assert len(read_rows(tmp_path / "a" / "trials.csv")) == 6  # 3 study trials x 2 scenarios
    assert (tmp_path / "a" / "history.png").exists()
    assert main([*args, "--out", str(tmp_path / "b")]) == 0  # same seed, same draws, same scores
    again = pd.read_csv(tmp_path / "b" / "study.csv")
    pd.testing.assert_frame_equal(study.drop(columns=["duration"]), again.drop(columns=["duration"]))


@pytest.mark.slow
def test_tune_on_the_ray_backend_scores_like_the_local_one(tmp_path):
    pytest.importorskip("optuna")
    pytest.importorskip("ray")
    args = [
        "tune",
        "--suite",
        TINY,
        "--param",
        "tracker.gate=float:4:16",
        "--trials",
        "2",
        "--seed",
        "3",
        "--quiet",
    ]
    assert main([*args, "--out", str(tmp_path / "local")]) == 0
    assert main([*args, "--out", str(tmp_path / "ray"), "--backend", "ray", "--workers", "2"]) == 0
    a = pd.read_csv(tmp_path / "local" / "study.csv").drop(columns=["duration"])
    b = pd.read_csv(tmp_path / "ray" / "study.csv").drop(columns=["duration"])
    pd.testing.assert_frame_equal(a, b)


POOL_OF_SLEEPERS = """
import sys, time
from eval.experiments.sweep import local_pool

pool = local_pool(2)
futures = [pool.submit(time.sleep, 120) for _ in range(2)]
time.sleep(0.5)
print(" ".join(str(p) for p in pool._processes), flush=True)
time.sleep(120)
"""


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by init) counts as gone
    stat = Path(f"/proc/{pid}/stat")
    return not (stat.exists() and stat.read_text().split(")")[-1].split()[0] == "Z")


@pytest.mark.slow
def test_a_killed_sweeps_pool_workers_end_with_it():
    """SIGKILL the process that holds a sweep's pool while its workers are busy for two
    minutes: the workers are gone within a few seconds, not left running their trials."""
    proc = subprocess.Popen([sys.executable, "-c", POOL_OF_SLEEPERS], stdout=subprocess.PIPE, text=True)
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not any(_alive(p) for p in workers)
    finally:
        proc.kill()
