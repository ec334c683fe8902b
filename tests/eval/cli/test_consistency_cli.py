"""`poibench consistency`: the table, consistency.json and consistency.png; bad input is one line."""

import json

from eval.cli.main import main


def test_consistency_writes_the_table_json_and_plot(tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["consistency", "--frames", "10", "--runs", "1", "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert table.splitlines()[0].split()[:3] == ["quantity", "N", "d"]
    doc = json.loads((out / "consistency.json").read_text())
    assert doc["frames"] == 10 and doc["runs"] == ["default:7"]
    rows = {r["quantity"]: r for r in doc["rows"]}
    assert rows["SLAM pose"]["n"] == 10 and rows["SLAM pose"]["d"] == 3
    assert any(q.startswith("R cam ") for q in rows) and any(q.startswith("R map ") for q in rows)
    for r in rows.values():
        lo, hi = r["interval_99"]
        assert r["inside"] == (lo <= r["mean_nees"] <= hi)
    assert (out / "consistency.png").stat().st_size > 10_000


def test_consistency_refuses_bad_arguments_in_one_line(tmp_path, capsys):
    assert main(["consistency", "--frames", "0", "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "poibench consistency: error: --frames: expected a positive number of frames, got 0"
    assert main(["consistency", "default", "--suite", "rrl-hard", "--out", str(tmp_path / "c")]) == 2
    assert "SCENARIO or --suite" in capsys.readouterr().err
