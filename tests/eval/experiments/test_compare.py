"""Intervals within [0, 1], numeric axes in numeric order, suite run's table, and ``suite compare``."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from eval.cli.main import main
from eval.cli.sweep import SUITE_RUN_FORMATS, mean_line
from eval.experiments.compare import CompareError, compare_runs, format_compare
from eval.experiments.sweep import (
    BOOTSTRAP_SEED,
    aggregate,
    mean_interval,
    row_fields,
    sweep_figure,
)
from eval.experiments.table import format_table
from eval.scoring.funnel import CAUSES, STAGES

TINY = str(Path(__file__).parent / "data" / "tiny_suite.yaml")


def _agg_rows(fractions: list[float], setting: list[str] | None = None) -> pd.DataFrame:
    n = len(fractions)
    return pd.DataFrame(
        {
            "set.a": setting or ["1"] * n,
            "fraction": fractions,
            "error": [""] * n,
            "score": [1.0] * n,
            "false_reports": [0] * n,
            "misses": [0] * n,
            "loc_err_median_m": [0.1] * n,
            "pose_err_median_m": [0.1] * n,
            "wall_s": [1.0] * n,
            "cpu_s": [1.0] * n,
            "cpu_s_per_sim_s": [0.1] * n,
        }
    )


def test_the_interval_of_two_mazes_stays_within_0_and_1():
    # the sweep printed [-1.06, 2.54] for these two fractions (a t interval on 1 degree of freedom)
    agg = aggregate(_agg_rows([0.6, 0.88]), ["a"]).iloc[0]
    assert agg["fraction_mean"] == pytest.approx(0.74)
    assert 0.0 <= agg["fraction_ci95_low"] <= agg["fraction_mean"] <= agg["fraction_ci95_high"] <= 1.0
    # with two mazes every draw's mean is 0.6, 0.74 or 0.88, each end at least 1/4 likely: the ends are the values
    assert (agg["fraction_ci95_low"], agg["fraction_ci95_high"]) == (0.6, 0.88)


@pytest.mark.parametrize("n", [2, 3, 5, 10, 40])
def test_bootstrap_intervals_of_fractions_stay_within_0_and_1(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        f = rng.choice([0.0, 1.0, rng.uniform()], size=n)  # fractions at the ends too
        lo, hi = mean_interval(f, rng=np.random.default_rng(BOOTSTRAP_SEED))
        assert 0.0 <= lo <= f.mean() + 1e-12 and f.mean() - 1e-12 <= hi <= 1.0


def test_bootstrap_interval_covers_its_level_on_many_mazes():
    # 40 mazes, fractions uniform on [0, 1]: the mean's sd is sqrt(1/12/40) = 0.0456, so a 95% interval
    # is about +-1.96 * 0.0456 = +-0.089 about the mean; 10000 draws fix each end to about 0.002
    f = np.random.default_rng(5).uniform(size=40)
    lo, hi = mean_interval(f, rng=np.random.default_rng(BOOTSTRAP_SEED))
    sd = f.std(ddof=0) / np.sqrt(len(f))
    assert hi - lo == pytest.approx(2 * 1.96 * sd, rel=0.1)
    assert mean_interval([0.5], rng=np.random.default_rng(0)) == pytest.approx((np.nan, np.nan), nan_ok=True)
    with pytest.raises(ValueError, match="level"):
        mean_interval([0.1, 0.2], rng=np.random.default_rng(0), level=95)


def test_a_heatmap_orders_a_numeric_axis_by_number():
    rows = [(a, b) for a in ("16", "4", "9") for b in ("dim", "bright")]
    df = _agg_rows([0.5] * len(rows) * 2, [a for a, _ in rows] * 2)
    df["set.b"] = [b for _, b in rows] * 2
    name, fig = sweep_figure(aggregate(df, ["a", "b"]), ["a", "b"])
    ax = fig.axes[0]
    assert name == "heatmap.png"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["4", "9", "16"]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["dim", "bright"]  # categories: as given
    name, fig = sweep_figure(aggregate(df, ["a"]), ["a"])
    assert name == "score.png" and [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["4", "9", "16"]


def test_suite_run_table_formats_each_column_once_and_drops_empty_ones():
    df = pd.DataFrame(
        {
            "scenario": ["a", "b"],
            "seed": [1, 2],
            "score": [45.0, 12.5],
            "max_score": [50.0, 50.0],
            "fraction": [0.9, 0.25],
            "cpu_s_per_sim_s": [0.0097, 1.23456],
            "boxes_per_frame": [float("nan"), float("nan")],
            "error": ["", ""],
        }
    )
    text = format_table(df, SUITE_RUN_FORMATS)
    lines = text.splitlines()
    assert lines[0].split() == ["scenario", "seed", "score", "max_score", "fraction", "cpu_s_per_sim_s"]
    assert lines[1].split() == ["a", "1", "45", "50", "0.900", "0.010"]
    assert lines[2].split() == ["b", "2", "12.5", "50", "0.250", "1.235"]
    line = mean_line(df, 2)
    assert (
        line
        == "mean score fraction 0.575 (95% interval [0.250, 0.900], bootstrap over the mazes) over 2 of 2 trials"
    )


# ----------------------------------------------------------------------------- compare


def _run_folder(
    root: Path,
    name: str,
    fractions: dict[str, float],
    lost: dict[str, dict[str, float]],
    *,
    suite: str = "tiny",
    version: int = 1,
    rules: str = "ex3",
    detector: str = "default",
    seeds: dict[str, int] | None = None,
    error: dict[str, str] | None = None,
) -> Path:
    """A finished suite run's folder as ``suite run --out`` writes it (the files compare reads)."""
    out = root / name
    out.mkdir()
    ident = {"suite": suite, "grid": [], "detector": detector, "rules": rules}
    (out / "sweep.yaml").write_text(
        yaml.safe_dump({"poibench_sweep": 1, "sweep": ident, "suite_version": version})
    )
    with open(out / "trials.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=row_fields([]))
        w.writeheader()
        for i, (maze, frac) in enumerate(fractions.items()):
            w.writerow(
                {
                    "trial": f"t{i}",
                    "suite": suite,
                    "suite_version": version,
                    "scenario": maze,
                    "seed": (seeds or {}).get(maze, 10 + i),
                    "score": 60 * frac,
                    "max_score": 60,
                    "fraction": frac,
                    "wall_s": 1.0,
                    "error": (error or {}).get(maze, ""),
                    "complete": 1,
                }
            )
    funnel = [
        {"type": t, "objects": 3, **{s: 0 for s in STAGES}, **{c: by_cause.get(c, 0) for c in CAUSES}}
        for t, by_cause in lost.items()
    ]
    pd.DataFrame(funnel).to_csv(out / "funnel.csv", index=False)
    return out


MAZES = ("m1", "m2", "m3")


def _three_runs(tmp_path: Path) -> list[Path]:
    return [
        _run_folder(
            tmp_path,
            "yolo-a",
            dict(zip(MAZES, [0.5, 0.7, 0.9], strict=True)),
            {"hazmat": {"not boxed": 3, "false: background": 1}, "qr": {"not read": 2}},
        ),
        _run_folder(
            tmp_path,
            "yolo-b",
            dict(zip(MAZES, [0.4, 0.7, 0.6], strict=True)),
            {"hazmat": {"not boxed": 8}, "qr": {"not read": 4, "misplaced": 1}},
        ),
        _run_folder(
            tmp_path,
            "yolo-c",
            dict(zip(MAZES, [0.6, 0.8, 1.0], strict=True)),
            {"hazmat": {"wrong type": 2}},
            detector="oracle",
        ),
    ]


def test_compare_ranks_runs_with_paired_differences_and_points_lost(tmp_path):
    table = compare_runs(_three_runs(tmp_path)).set_index("run")
    # means by hand: c (0.6 + 0.8 + 1.0) / 3 = 0.8, a 0.7, b (0.4 + 0.7 + 0.6) / 3 = 0.5667
    assert list(table.index) == ["yolo-c", "yolo-a", "yolo-b"]
    assert list(table["rank"]) == [1, 2, 3]
    assert table["fraction_mean"].tolist() == pytest.approx([0.8, 0.7, 0.5667], abs=1e-4)
    # three mazes: a draw of one maze three times has probability 1/27 = 3.7% > 2.5%, so the ends
    # of a 95% percentile interval are the smallest and largest value (10000 draws: 3.7% +- 0.2%)
    assert (table.loc["yolo-a", "fraction_ci95_low"], table.loc["yolo-a", "fraction_ci95_high"]) == (0.5, 0.9)
    # paired differences to c: a is 0.1 below on every maze, so its interval is that one value
    assert table.loc["yolo-a", "diff_to_first"] == pytest.approx(-0.1)
    assert (table.loc["yolo-a", "diff_ci95_low"], table.loc["yolo-a", "diff_ci95_high"]) == pytest.approx(
        (-0.1, -0.1)
    )
    # b: -0.2, -0.1, -0.4, mean -0.2333, interval [-0.4, -0.1]
    assert table.loc["yolo-b", "diff_to_first"] == pytest.approx(-0.2333, abs=1e-4)
    assert (table.loc["yolo-b", "diff_ci95_low"], table.loc["yolo-b", "diff_ci95_high"]) == pytest.approx(
        (-0.4, -0.1)
    )
    assert pd.isna(table.loc["yolo-c", "diff_to_first"])
    # points lost per type: funnel.csv's causes summed
    assert table.loc["yolo-a", "lost.hazmat"] == 4 and table.loc["yolo-a", "lost.qr"] == 2
    assert table.loc["yolo-b", "lost.qr"] == 5 and table.loc["yolo-c", "lost.qr"] == 0
    assert table["lost"].tolist() == [2, 6, 13]
    text = format_compare(table.reset_index())
    assert text.splitlines()[3].split()[:2] == ["1", "yolo-c"] and "[-0.400, -0.100]" in text
    assert "points lost per type" in text


def test_suite_compare_cli_prints_the_ranking_and_writes_compare_csv(tmp_path, capsys):
    runs = _three_runs(tmp_path)
    out = tmp_path / "cmp" / "compare.csv"
    assert main(["suite", "compare", *map(str, runs), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    ranking = printed.splitlines()[3:6]  # two lines of what it is, the column names, then the runs
    assert [line.split()[1] for line in ranking] == ["yolo-c", "yolo-a", "yolo-b"]
    assert pd.read_csv(out)["run"].tolist() == ["yolo-c", "yolo-a", "yolo-b"]


@pytest.mark.parametrize(
    "other, message",
    [
        ({"suite": "smoke"}, "yolo-a is a run of suite tiny v1, .*other of smoke v1: compare runs of one suite"),
        ({"version": 2}, "of tiny v2: compare runs of one suite"),
        ({"rules": "rmrc2025"}, "by rmrc2025: compare runs under one rules"),
        ({"fractions": {"m1": 0.5, "m2": 0.5}}, "other has no trial of maze m3: not the same mazes"),
        ({"seeds": {"m1": 99}}, "ran maze m1 with seeds 10 and 99: not the same mazes"),
        ({"error": {"m2": "boom"}}, r"other: maze m2 failed \(boom\)"),
    ],
)
def test_compare_refuses_runs_of_other_suites_or_mazes_with_one_line(tmp_path, capsys, other, message):
    a = _run_folder(tmp_path, "yolo-a", dict.fromkeys(MAZES, 0.5), {})
    fractions = other.pop("fractions", dict.fromkeys(MAZES, 0.6))
    b = _run_folder(tmp_path, "other", fractions, {}, **other)
    with pytest.raises(CompareError, match=message):
        compare_runs([a, b])
    assert main(["suite", "compare", str(a), str(b), "--out", str(tmp_path / "c.csv")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "poibench suite compare: error:" in err


def test_compare_refuses_a_folder_that_is_not_a_run(tmp_path):
    a = _run_folder(tmp_path, "yolo-a", dict.fromkeys(MAZES, 0.5), {})
    (tmp_path / "empty").mkdir()
    with pytest.raises(CompareError, match="give the --out folder of a finished poibench suite run"):
        compare_runs([a, tmp_path / "empty"])
    with pytest.raises(CompareError, match="two runs or more"):
        compare_runs([a])
    with pytest.raises(CompareError, match="yolo-a: given twice; compare different runs"):
        compare_runs([a, a])


def test_compare_refuses_to_write_its_table_over_a_runs_own_file(tmp_path, capsys):
    runs = _three_runs(tmp_path)
    before = (runs[0] / "trials.csv").read_bytes()
    assert main(["suite", "compare", *map(str, runs), "--out", str(runs[0] / "trials.csv")]) == 2
    err = capsys.readouterr().err
    assert f"--out {runs[0] / 'trials.csv'}: it is (or is in) a compared run {runs[0]}; give another name" in err
    assert (runs[0] / "trials.csv").read_bytes() == before


@pytest.mark.slow
def test_suite_run_then_compare_end_to_end(tmp_path, capsys):
    """Two real runs of the tiny suite (the default and the oracle detector), then compare."""
    a, b = tmp_path / "default", tmp_path / "oracle"
    assert main(["suite", "run", TINY, "--out", str(a), "--quiet", "--no-cache"]) == 0
    printed = capsys.readouterr().out
    assert "error" not in printed.splitlines()[1]  # no trial failed: no error column
    assert "mean score fraction" in printed and "95% interval [" in printed
    # an ONNX detector's setting cannot take effect on the oracle: refused before any trial
    bad = ["--detector", "oracle", "--set", "detector.conf=0.55"]
    assert main(["suite", "run", TINY, "--out", str(tmp_path / "bad"), "--quiet", "--no-cache", *bad]) == 2
    assert "detector.conf: the oracle detector takes none of these" in capsys.readouterr().err
    assert not (tmp_path / "bad" / "trials.csv").exists()
    oracle = ["--detector", "oracle", "--set", "tracker.gate=9.0"]  # a setting every trial takes
    assert main(["suite", "run", TINY, "--out", str(b), "--quiet", "--no-cache", *oracle]) == 0
    capsys.readouterr()
    assert (pd.read_csv(b / "trials.csv")["set.tracker.gate"] == 9.0).all()
    assert main(["suite", "compare", str(a), str(b), "--out", str(tmp_path / "compare.csv")]) == 0
    table = pd.read_csv(tmp_path / "compare.csv")
    folders = {"default": a, "oracle tracker.gate=9.0": b}  # a run is named with its settings
    assert sorted(table["run"]) == sorted(folders) and (table["mazes"] == 2).all()
    assert table["fraction_mean"].is_monotonic_decreasing
    # a percentile interval of the mean lies within the mazes' own fractions (which false
    # reports can take below 0)
    for _, row in table.iterrows():
        trials = pd.read_csv(folders[row["run"]] / "trials.csv")
        assert trials["fraction"].min() - 1e-4 <= row["fraction_ci95_low"] <= row["fraction_ci95_high"]
        assert row["fraction_ci95_high"] <= trials["fraction"].max() + 1e-4  # compare.csv: 4 decimals


def test_suite_run_refuses_a_setting_without_a_value_or_given_twice(capsys):
    assert main(["suite", "run", TINY, "--set", "detector.conf"]) == 2
    assert "--set 'detector.conf': expected key=value" in capsys.readouterr().err
    assert main(["suite", "run", TINY, "--set", "detector.conf=0.5", "--set", "detector.conf=0.6"]) == 2
    assert "--set detector.conf: given twice" in capsys.readouterr().err
