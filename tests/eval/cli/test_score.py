"""``poibench score``: tables or JSON on stdout, exit 0 when scored, 2 on unreadable input."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest
import yaml

from eval.cli.score import register, run
from eval.scoring.rules import RULES_DIR
from poi.core.poi_file import PoiHeader, PoiRow, read_poi_file, write_poi_file

HEADER = PoiHeader(team="t", country="c", date="2025-01-01", start_time="10:00:00", mission="m")


def _row(id_: int, type_: str, x: float, text: str = "", mode: str = "T") -> PoiRow:
    return PoiRow(
        line=0,
        id=id_,
        time="10:00:01",
        text=text,
        x=x,
        y=0.0,
        z=0.0,
        robot="r",
        mode=mode,
        type=type_,
    )


@pytest.fixture
def files(tmp_path: Path) -> tuple[Path, Path]:
    truth = tmp_path / "truth.csv"
    write_poi_file(
        truth,
        HEADER,
        [
            _row(1, "door", 0.0, mode="GT"),
            _row(2, "qr", 5.0, "Chart M", "GT"),
            _row(3, "valve", 10.0, mode="GT"),
        ],
    )
    report = tmp_path / "report.csv"
    # door located (+10), qr 1.5 m off (+1), a false valve far away (-3); valve 3 missed.
    write_poi_file(
        report,
        HEADER,
        [_row(0, "door", 0.2), _row(1, "qr", 6.5, "Chart M"), _row(2, "valve", 20.0)],
    )
    with report.open("a") as fh:
        fh.write("3,10:00:09,,oops,0,0,r,T,door\n")  # line 12: unreadable, -5
    return report, truth


def _main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="poibench")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    args = parser.parse_args(argv)
    assert args.func is run
    return run(args)


def test_json_output(files, capsys) -> None:
    report, truth = files
    assert _main(["score", str(report), "--truth", str(truth), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["total"] == 10 + 1 - 3 - 5
    assert data["max_total"] == 10 + 2 + 6
    assert (data["false_reports"], data["misses"], data["located"]) == (2, 1, 1)
    assert [r["points"] for r in data["reports"]] == [10, 1, -3, -5]
    assert data["reports"][3]["line"] == 12 and "unreadable" in data["reports"][3]["reason"]
    assert [o["status"] for o in data["objects"]] == ["located", "identified", "missed"]
    assert data["per_type"]["door"]["points"] == 5
    assert data["rules"]["name"] == "ex3"
    assert [(p["line"], p["severity"]) for p in data["problems"]] == [(12, "error")]


def test_a_report_and_truth_swapped_are_refused_and_a_report_of_truth_rows_named(files, capsys) -> None:
    report, truth = files
    assert _main(["score", str(report), "--truth", str(truth)]) == 0
    assert "note:" not in capsys.readouterr().err
    assert _main(["score", str(truth), "--truth", str(report)]) == 2
    line = read_poi_file(report).rows[0].line
    assert capsys.readouterr().err.splitlines() == [
        f"poibench score: error: {report}: line {line}: mode 'T'; expected GT (a truth.csv, not a report: "
        "swapped with the report?)"
    ]
    assert _main(["score", str(truth), "--truth", str(truth)]) == 0  # a report of truth rows: scored, named
    notes = capsys.readouterr().err.splitlines()
    assert notes == [f"note: {truth}: 3 of 3 report rows are of mode GT, the truth's"]


def test_tables_output(files, capsys) -> None:
    report, truth = files
    assert _main(["score", str(report), "--truth", str(truth)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Score 3 of 18 (rules ex3")
    from eval.scoring.report import OBJECTS_TITLE, REPORTS_TITLE

    for section in (REPORTS_TITLE, OBJECTS_TITLE, "Totals per type", "Problems"):
        assert f"\n{section}\n" in out
    lines = out.splitlines()
    total_line = next(line for line in lines if line.startswith("TOTAL"))
    # points objects missed max: found is objects - missed, not a column of its own
    assert total_line.split()[-4:] == ["3", "3", "1", "18"]
    totals_header = lines[lines.index("Totals per type") + 1].split()
    assert totals_header[-4:] == ["points", "objects", "missed", "max"]
    header = lines[lines.index(REPORTS_TITLE) + 1]
    assert header.split()[:3] == ["line", "id", "type"]
    # Aligned: every row of the reports table starts its 'points' column at the same place.
    rows = lines[lines.index(REPORTS_TITLE) + 1 : lines.index(REPORTS_TITLE) + 7]
    end = header.index("points") + len("points")
    assert all(r[end - 2 : end].strip().lstrip("-").isdigit() for r in rows[2:])


def test_rmrc2025_and_rules_file(files, tmp_path: Path, capsys) -> None:
    report, truth = files
    argv = ["score", str(report), "--truth", str(truth), "--json"]
    assert _main([*argv, "--rules", "rmrc2025"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["total"] == 1 and data["max_total"] == 5 and data["false_reports"] == 0
    rules = yaml.safe_load((RULES_DIR / "ex3.yaml").read_text())
    rules["types"]["door"]["located_points"] = 20
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(rules))
    assert _main(["score", str(report), "--truth", str(truth), "--rules", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["total"] == 20 + 1 - 3 - 5


@pytest.mark.parametrize("which", ["report", "truth", "rules"])
def test_unreadable_input_exits_2_with_one_line(files, tmp_path: Path, capsys, which) -> None:
    report, truth = files
    bad = tmp_path / "bad.txt"
    bad.write_text("hello\n")
    argv = ["score", str(report), "--truth", str(truth)]
    if which == "report":
        argv[1] = str(bad)
    elif which == "truth":
        argv[3] = str(tmp_path / "missing.csv")
    else:
        argv += ["--rules", str(bad)]
    assert _main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err.splitlines()
    assert len(err) == 1 and err[0].startswith("poibench score: error: "), captured.err
