"""The autonomy multiplier (docs/RULES.md "Autonomy"): the mode column scored x4 under rmrc2025,
only in a run with no false or multiple detections, never for QR codes (the mapping bonus
replaces it); ex3 scores no autonomy. Every score hand-computed."""

from __future__ import annotations

import re

import pytest

from eval.scoring.report import format_tables, to_json_dict
from eval.scoring.rules import RulesError, load_rules, rules_from_dict
from eval.scoring.scorer import score
from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text, parse_poi_text

RMRC = load_rules("rmrc2025")
EX3 = load_rules("ex3")
HEADER = PoiHeader(team="t", country="c", date="2025-01-01", start_time="10:00:00", mission="m")


def row(id_: int, type_: str, x: float, text: str = "", mode: str = "A") -> PoiRow:
    return PoiRow(line=0, id=id_, time="10:00:01", text=text, x=x, y=0.0, z=0.0, robot="r", mode=mode, type=type_)


def poi(*rows: PoiRow):
    return parse_poi_text(format_poi_text(HEADER, list(rows)))


TRUTH = poi(
    row(1, "qr", 0.0, "A", "GT"), row(2, "hazmat", 5.0, "poison", "GT"), row(3, "hazmat", 10.0, "oxygen", "GT")
)


def test_autonomous_run_without_false_reports_is_multiplied() -> None:
    reports = poi(
        row(0, "qr", 0.1, "A"),  # located within 0.30 m: 1 + 4 = 5, not multiplied (mapping replaces autonomy)
        row(1, "hazmat", 5.0, "poison"),  # 1 x 4 = 4
        row(2, "hazmat", 12.0, "oxygen"),  # no distance limit: 1 x 4 = 4
    )
    res = score(reports, TRUTH, RMRC)
    assert [r.points for r in res.reports] == [5, 4, 4]
    assert [o.points for o in res.objects] == [5, 4, 4]
    assert [r.reason for r in res.reports] == ["", "autonomous: points x4", "autonomous: points x4"]
    assert (res.total, res.max_total) == (13, 5 + 4 + 4)
    assert res.per_type["hazmat"].points == 8
    assert res.autonomy == {
        "multiplier": 4,
        "applied": True,
        "autonomous_reports": 3,
        "multiplied_reports": 2,
        "reason": "2 autonomous reports (mode A) multiplied by 4",
    }
    assert to_json_dict(res)["autonomy"] == res.autonomy
    table = format_tables(res)
    assert "autonomy x4: 2 autonomous reports (mode A) multiplied by 4" in table
    # rmrc2025 gives placards no locate bonus: their 'located' reads '-', the QR code's (mapping) 1
    totals = {
        line.split()[0]: line.split() for line in table.splitlines()[table.splitlines().index("Totals per type") :]
    }
    assert totals["hazmat"][3] == "-" and totals["qr"][3] == "1" and totals["TOTAL"][3] == "1"


def test_mode_is_per_row() -> None:
    reports = poi(row(0, "qr", 0.1, "A"), row(1, "hazmat", 5.0, "poison"), row(2, "hazmat", 12.0, "oxygen", "T"))
    res = score(reports, TRUTH, RMRC)
    assert [r.points for r in res.reports] == [5, 4, 1]  # the teleoperated report is not multiplied
    assert res.total == 10 and res.autonomy["autonomous_reports"] == 2


def test_a_multiple_detection_costs_the_multiplier() -> None:
    reports = poi(
        row(0, "qr", 0.1, "A"),  # 5
        row(1, "hazmat", 5.0, "poison"),  # 1
        row(2, "hazmat", 5.5, "poison"),  # a second report of the one poison placard: false, 0
        row(3, "hazmat", 12.0, "oxygen"),  # 1
    )
    res = score(reports, TRUTH, RMRC)
    assert [r.points for r in res.reports] == [5, 1, 0, 1]
    assert res.total == 7 and res.max_total == 13 and res.false_reports == 1
    assert res.autonomy["applied"] is False and res.autonomy["multiplied_reports"] == 0
    assert res.autonomy["reason"] == (
        "not applied: the run has 1 false report, 1 of them multiple detections; the multiplier requires none"
    )


def test_a_false_report_costs_the_multiplier() -> None:
    reports = poi(row(0, "qr", 0.1, "A"), row(1, "hazmat", 5.0, "poison"), row(2, "qr", 3.0, "no such code"))
    res = score(reports, TRUTH, RMRC)
    assert [r.points for r in res.reports] == [5, 1, 0] and res.total == 6
    assert res.autonomy["reason"].startswith("not applied: the run has 1 false report, 0 of them multiple")


def test_without_the_two_conditions_every_autonomous_pair_is_multiplied() -> None:
    data = RMRC.to_dict()
    del data["source"]
    data["autonomy_requires_no_false_or_multiple"] = False
    data["qr_mapping_replaces_autonomy"] = False
    loose = rules_from_dict(data)
    reports = poi(row(0, "qr", 0.1, "A"), row(1, "hazmat", 5.0, "poison"), row(2, "qr", 3.0, "no such code"))
    res = score(reports, TRUTH, loose)
    assert [r.points for r in res.reports] == [20, 4, 0]  # the QR code too: 5 x 4
    assert (res.total, res.max_total) == (24, 20 + 4 + 4)


def test_ex3_scores_no_autonomy() -> None:
    truth = poi(row(1, "door", 0.0, mode="GT"))
    res = score(poi(row(0, "door", 0.5)), truth, EX3)
    assert res.total == 10 and res.autonomy is None
    doc = to_json_dict(res)
    assert "autonomy" not in doc and "autonomy_multiplier" not in doc["rules"]


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("autonomy_multiplier: 0.5", "14: field 'autonomy_multiplier': expected a number >= 1"),
        ("autonomy_multiplier: true", "14: field 'autonomy_multiplier': expected a number >= 1"),
        (
            "autonomy_requires_no_false_or_multiple: yes please",
            "14: field 'autonomy_requires_no_false_or_multiple': expected true or false, got 'yes please'",
        ),
        (
            "qr_mapping_replaces_autonomy: true",
            "14: field 'qr_mapping_replaces_autonomy': is true but autonomy_multiplier is not set",
        ),
    ],
)
def test_autonomy_fields_are_checked(tmp_path, line: str, message: str) -> None:
    path = tmp_path / "r.yaml"
    path.write_text(
        "name: r\nidentify_radius_m: 2.0\nfalse_report_penalty: type_points\nunscored_types: ignore\n"
        + "types:\n"
        + "  door: {points: 5, locate_radius_m: 1.0, located_points: 10, identity_uses_text: false}\n"
        + "\n" * 7  # the field on line 14
        + line
        + "\n"
    )
    with pytest.raises(RulesError, match="^" + re.escape(f"{path}:{message}")):
        load_rules(str(path))


def test_the_summary_counts_ignored_reports_and_objects_apart() -> None:
    """rmrc2025 does not score doors: a door report and a door object are both ignored, and the
    summary line says which is which."""
    truth = poi(*TRUTH.rows, row(4, "door", 20.0, "", "GT"))
    res = score(poi(row(0, "door", 20.0)), truth, RMRC)
    line = format_tables(res).splitlines()[1]
    assert line.endswith(", ignored: 1 report, 1 object (of types the rules do not score)")
