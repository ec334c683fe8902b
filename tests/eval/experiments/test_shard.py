"""Sharded runs (``--shard I/N``) and ``poibench suite merge``: the shards joined are the run."""

import csv
import io
import json
from pathlib import Path

import pytest
import yaml

from eval.cli.main import main
from eval.experiments.merge import MergeError, merge_shards
from eval.experiments.shard import Shard, ShardError, parse_shard
from eval.experiments.sweep import RowWriter, row_fields

TINY = str(Path(__file__).parent / "data" / "tiny_suite.yaml")
# what a run measures of itself: the one difference between two runs of the same trials
TIMING = ("wall_s", "cpu_s", "cpu_s_per_sim_s")


def _table(path: Path) -> tuple[list[str], list[list[str]]]:
    """(header, rows) of a CSV file, every cell the text written."""
    rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"), newline="")))
    return rows[0], rows[1:]


def _untimed(path: Path, timing: tuple[str, ...] = TIMING) -> list[list[str]]:
    """A table's rows with the timing columns blanked, the header first."""
    header, rows = _table(path)
    cut = [i for i, c in enumerate(header) if c in timing]
    return [header] + [[("" if i in cut else v) for i, v in enumerate(r)] for r in rows]


def _lines_by_trial(path: Path) -> dict[str, bytes]:
    """Each row of a trials file as the bytes written, by trial id."""
    lines = path.read_bytes().splitlines(keepends=True)[1:]
    return {line.split(b",", 1)[0].decode(): line for line in lines}


def test_shard_parsing_and_selection():
    s = parse_shard("1/3")
    assert s == Shard(index=1, count=3) and str(s) == "1/3"
    assert s.select(list("abcdefg")) == ["b", "e"]
    # every trial is in exactly one shard
    shards = [Shard(index=i, count=3) for i in range(3)]
    assert sorted(x for sh in shards for x in sh.select(list(range(10)))) == list(range(10))
    for bad in ("3/3", "-1/3", "1/0", "1", "a/b", "1/3/4"):
        with pytest.raises(ShardError, match=rf"^--shard {bad}: expected I/N"):
            parse_shard(bad)


def test_bad_shards_are_refused_before_any_trial(tmp_path, capsys):
    for argv in (
        ["suite", "run", TINY, "--shard", "2/2", "--out", str(tmp_path / "a")],
        ["sweep", "--suite", TINY, "--shard", "x", "--out", str(tmp_path / "b")],
    ):
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2
        assert "error: argument --shard: expected I/N" in capsys.readouterr().err
    assert main(["suite", "run", TINY, "--shard", "0/2"]) == 2
    assert "--shard 0/2: needs --out" in capsys.readouterr().err
    base = str(tmp_path / "base.json")
    argv = ["regress", "--suite", TINY, "--baseline", base, "--shard", "0/2", "--out", str(tmp_path / "r")]
    assert main([*argv, "--update"]) == 2
    assert "a verdict or baseline needs every scenario" in capsys.readouterr().err
    assert not (tmp_path / "a").exists() and not (tmp_path / "r").exists()


# --------------------------------------------------------------- merge refusals, on made-up shards


SWEEP = {"suite": "tiny", "grid": [], "detector": "default", "rules": "ex3"}
IDS = ["t0", "t1", "t2", "t3", "t4"]


def _fake_shard(
    folder: Path, index: int, count: int, *, ids=IDS, sweep=SWEEP, rows: list[str] | None = None
) -> Path:
    """A shard's folder as ``--shard index/count`` leaves it: sweep.yaml and trials.csv (its rows,
    default all of its trials)."""
    folder.mkdir(parents=True)
    doc = {"poibench_sweep": 1, "sweep": sweep, "suite_version": 1, "trials": len(ids)}
    doc["shard"] = {"index": index, "count": count, "trial_ids": list(ids)}
    (folder / "sweep.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    w = RowWriter(folder / "trials.csv", row_fields([]))
    for t in rows if rows is not None else Shard(index=index, count=count).select(ids):
        t, error = t if isinstance(t, tuple) else (t, "")  # (trial, error): a failed run of it
        k = ids.index(t)
        w.write(
            {"trial": t, "suite": "tiny", "suite_version": 1, "scenario": f"s{k}", "seed": k, "score": k}
            | {"max_score": 10, "fraction": k / 10, "error": error, "wall_s": 1.5, "complete": 1}
        )
    w.close()
    return folder


def test_merge_orders_rows_as_one_run_and_keeps_each_rows_bytes(tmp_path):
    a, b = _fake_shard(tmp_path / "a", 0, 2), _fake_shard(tmp_path / "b", 1, 2)
    df, agg = merge_shards([b, a], tmp_path / "m")  # any order of folders
    assert list(df["trial"]) == IDS and agg.loc[0, "trials"] == 5
    merged = (tmp_path / "m" / "trials.csv").read_bytes().splitlines(keepends=True)
    given = _lines_by_trial(a / "trials.csv") | _lines_by_trial(b / "trials.csv")
    assert merged[1:] == [given[t] for t in IDS]
    assert merged[0] == (a / "trials.csv").read_bytes().splitlines(keepends=True)[0]
    assert "shard" not in yaml.safe_load((tmp_path / "m" / "sweep.yaml").read_text())


def test_a_resumed_shard_gives_its_rerun_row(tmp_path):
    """A shard resumed after a failed trial holds the failure and the rerun; the merge takes the
    rerun, as read_rows does for a single run."""
    a = _fake_shard(tmp_path / "a", 0, 2)
    b = _fake_shard(tmp_path / "b", 1, 2, rows=[("t1", "RuntimeError: crash"), "t3", "t1"])
    df, _ = merge_shards([a, b], tmp_path / "m")
    assert list(df["trial"]) == IDS and (df["error"] == "").all()
    assert len((tmp_path / "m" / "trials.csv").read_bytes().splitlines()) == 1 + len(IDS)


@pytest.mark.parametrize(
    "shards, message",
    [
        ([(0, 2, {}), (1, 3, {})], r"not shards of one run \(their shard count N differ\)"),
        ([(0, 2, {}), (1, 2, {"sweep": {**SWEEP, "rules": "rmrc2025"}})], r"their sweep \(suite, --set"),
        ([(0, 2, {}), (1, 2, {"ids": ["x", *IDS[1:]]})], "their trial ids differ"),
        ([(0, 2, {}), (0, 2, {})], r"^shard 0/2 given twice: .*/s0 and .*/s1$"),
        ([(0, 3, {}), (2, 3, {})], r"^shard 1/3 missing \(2 of 3 shards given\)"),
        ([(0, 2, {}), (1, 2, {"rows": ["t1"]})], r"shard 1/2 did not finish \(1 of 2 trials recorded\)"),
        ([(0, 2, {"rows": ["t0", "t1"]})], "trial t1 is not one of shard 0/2's"),
    ],
)
def test_merge_refuses_shards_that_do_not_make_one_run(tmp_path, shards, message):
    folders = [_fake_shard(tmp_path / f"s{k}", i, n, **kw) for k, (i, n, kw) in enumerate(shards)]
    with pytest.raises(MergeError, match=message):
        merge_shards(folders, tmp_path / "m")
    assert not (tmp_path / "m").exists()


def test_merge_refuses_a_folder_that_is_no_shard_and_a_used_out(tmp_path, capsys):
    a, b = _fake_shard(tmp_path / "a", 0, 2), _fake_shard(tmp_path / "b", 1, 2)
    (tmp_path / "single").mkdir()
    (tmp_path / "single" / "sweep.yaml").write_text(yaml.safe_dump({"poibench_sweep": 1, "sweep": SWEEP}))
    assert main(["suite", "merge", str(a), str(tmp_path / "single"), "--out", str(tmp_path / "m")]) == 2
    assert "single/sweep.yaml: not a shard (no 'shard')" in capsys.readouterr().err
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "x").write_text("")
    assert main(["suite", "merge", str(a), str(b), "--out", str(tmp_path / "used")]) == 2
    assert "--out " + str(tmp_path / "used") + ": not empty" in capsys.readouterr().err
    (b / "trials.csv").unlink()
    assert main(["suite", "merge", str(a), str(b), "--out", str(tmp_path / "m")]) == 2
    assert "shard 1/2 did not finish (no trials.csv)" in capsys.readouterr().err


# ------------------------------------------------------------------------- real trials, merged


@pytest.mark.slow
def test_two_shards_of_a_suite_run_merge_into_the_rows_of_one_run(tmp_path, capsys):
    """The tiny suite (two 2x2 mazes, 4 s each) run whole, then as shards 0/2 and 1/2 and merged:
    the same trials.csv, row for row and byte for byte but for the timing columns; the same
    sweep.yaml, funnel and summaries; and regress judges the merged run as it judges a whole one."""
    common = ["--quiet", "--no-cache"]
    assert main(["suite", "run", TINY, "--out", str(tmp_path / "one"), *common]) == 0
    for i in (0, 1):
        assert main(["suite", "run", TINY, "--shard", f"{i}/2", "--out", str(tmp_path / f"s{i}"), *common]) == 0
    capsys.readouterr()
    assert main(["suite", "merge", str(tmp_path / "s1"), str(tmp_path / "s0"), "--out", str(tmp_path / "m")]) == 0
    assert "mean score fraction" in capsys.readouterr().out
    one, merged = tmp_path / "one", tmp_path / "m"
    assert len(_table(one / "trials.csv")[1]) == 2
    assert _untimed(merged / "trials.csv") == _untimed(one / "trials.csv")
    for name in ("sweep.yaml", "funnel.jsonl", "funnel.csv", "points.png"):
        assert (merged / name).read_bytes() == (one / name).read_bytes(), name
    timing_means = ("wall_s_mean", "cpu_s_mean", "cpu_s_per_sim_s_mean")
    assert _untimed(merged / "aggregate.csv", timing_means) == _untimed(one / "aggregate.csv", timing_means)
    for tid in _lines_by_trial(one / "trials.csv"):
        assert (merged / "trials" / tid / "pois.csv").read_bytes() == (
            one / "trials" / tid / "pois.csv"
        ).read_bytes()
    # a regress run sharded the same way: its verdict from the merged folder
    base = tmp_path / "base.json"
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--update", "--merged", str(merged)]) == 0
    fractions = {r[3]: float(r[7]) for r in _table(one / "trials.csv")[1]}
    assert json.loads(base.read_text())["scenarios"] == fractions
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--merged", str(merged)]) == 0
    assert "PASS mean score fraction" in capsys.readouterr().out
    assert main(["regress", "--suite", TINY, "--baseline", str(base), "--merged", str(tmp_path / "s0")]) == 2
    assert "a shard, not a merged run" in capsys.readouterr().err


@pytest.mark.slow
def test_three_shards_of_a_sweep_merge_into_its_rows_in_its_order(tmp_path):
    """A sweep of 2 settings x 2 mazes in 3 shards (shard 0 holds trials 0 and 3): merged, the
    rows are the whole sweep's in its order; replayed from one perception cache, as sweeps run."""
    common = ["--suite", TINY, "--set", "tracker.gate=4,9", "--quiet", "--cache", str(tmp_path / "cache")]
    assert main(["sweep", *common, "--out", str(tmp_path / "one")]) == 0
    for i in (2, 0, 1):
        assert main(["sweep", *common, "--shard", f"{i}/3", "--out", str(tmp_path / f"s{i}")]) == 0
    assert len(_table(tmp_path / "s0" / "trials.csv")[1]) == 2
    shards = [str(tmp_path / f"s{i}") for i in range(3)]
    assert main(["suite", "merge", *shards, "--out", str(tmp_path / "m")]) == 0
    one, merged = tmp_path / "one", tmp_path / "m"
    assert _untimed(merged / "trials.csv") == _untimed(one / "trials.csv")
    assert [r[5] for r in _table(merged / "trials.csv")[1]] == ["4", "4", "9", "9"]  # set.tracker.gate
    assert (merged / "funnel.csv").read_bytes() == (one / "funnel.csv").read_bytes()
    assert (merged / "points.png").read_bytes() == (one / "points.png").read_bytes()
    assert (merged / "score.png").exists()
