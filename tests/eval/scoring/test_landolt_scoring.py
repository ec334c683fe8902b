"""Landolt-C targets under the RMRC presets (docs/RULES.md "Landolt-C"): rmrc2026 scores the 3rd
ring's gap direction, rmrc2026-finals the 3rd and 4th; a report scores when it lies within
``landolt_radius_m`` (0.5 m) of its target and gives those rings right. Every score is
hand-computed in the comments.

The arena: target 20 at (1, 0, 0.5) reading "1:E 2:N 3:NE 4:S 5:W", target 21 at (5, 0, 0.5)
reading "1:W 2:W 3:S 4:N 5:E", an oxidizer placard 2 at (3, 0, 0.8). Every report is autonomous
(mode A): x4 when the run has no false report.
"""

from __future__ import annotations

import pytest

from eval.scoring.rules import RulesError, load_rules, rules_from_dict
from eval.scoring.scorer import score
from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text, parse_poi_text

RMRC2026 = load_rules("rmrc2026")
FINALS = load_rules("rmrc2026-finals")
HEADER = PoiHeader(team="t", country="-", date="2026-07-18", start_time="10:00:00", mission="m")


def _row(id_: int, type_: str, x: float, y: float, z: float, text: str, mode: str = "A") -> PoiRow:
    return PoiRow(line=0, id=id_, time="10:00:00", text=text, x=x, y=y, z=z, robot="r", mode=mode, type=type_)


def _file(rows: list[PoiRow]):
    return parse_poi_text(format_poi_text(HEADER, rows), source="f.csv")


TRUTH = _file(
    [
        _row(20, "landolt-c", 1.0, 0.0, 0.5, "1:E 2:N 3:NE 4:S 5:W", "GT"),
        _row(21, "landolt-c", 5.0, 0.0, 0.5, "1:W 2:W 3:S 4:N 5:E", "GT"),
        _row(2, "hazmat", 3.0, 0.0, 0.8, "oxidizer", "GT"),
    ]
)
PLACARD = _row(9, "hazmat", 3.0, 0.1, 0.8, "oxidizer")


def test_right_3rd_ring_scores_and_is_multiplied_when_nothing_is_false() -> None:
    # target 20 read to ring 3 (ring 4 missing: rmrc2026 does not ask for it), 0.1 m off: 1 x4;
    # the placard 1 x4; target 21 missed. Max: two targets and a placard, each 1 x4 = 12.
    rep = _file([_row(0, "landolt-c", 1.1, 0.0, 0.5, "1:E 2:N 3:NE"), PLACARD])
    res = score(rep, TRUTH, RMRC2026)
    lc, hz = res.reports
    assert (lc.status, lc.points, lc.object_id) == ("identified", 4, 20)
    assert lc.distance_m == pytest.approx(0.1)
    assert (hz.status, hz.points) == ("identified", 4)
    assert res.total == 8 and res.max_total == 12
    t = res.per_type["landolt-c"]
    from eval.scoring.report import format_tables

    text_lines = [line for line in format_tables(res).splitlines() if line.startswith("text of a")]
    assert text_lines == ["text of a landolt-c: each ring's gap direction, ring:direction, ring 1 the outermost"]
    assert (t.objects, t.found, t.missed, t.points) == (2, 1, 1, 4)


def test_wrong_orientation_is_a_false_report_and_costs_the_multiplier() -> None:
    # target 21's 3rd ring is S; the report says N (its other rings right): false, 0 points, and
    # the run now has a false report, so nothing is multiplied: target 20 1 + placard 1 = 2.
    rep = _file(
        [
            _row(0, "landolt-c", 1.0, 0.0, 0.5, "1:E 2:N 3:NE 4:S"),
            _row(1, "landolt-c", 5.0, 0.0, 0.5, "1:W 2:W 3:N 4:N"),
            PLACARD,
        ]
    )
    res = score(rep, TRUTH, RMRC2026)
    right, wrong, hz = res.reports
    assert (right.status, right.points) == ("identified", 1)
    assert (wrong.status, wrong.points) == ("false", 0)
    assert wrong.reason.startswith("wrong orientation: no landolt-c target has '3:N'")
    assert "nearest object: 21" in wrong.reason
    assert res.total == 2 and res.autonomy["applied"] is False


def test_missing_3rd_ring_is_false() -> None:
    # rings 1 and 2 read, ring 3 not: the report cannot be judged, so it is false (0 points).
    rep = _file([_row(0, "landolt-c", 5.0, 0.0, 0.5, "1:W 2:W")])
    (r,) = score(rep, TRUTH, RMRC2026).reports
    assert (r.status, r.points) == ("false", 0)
    assert r.reason == "Landolt-C text '1:W 2:W' does not give the gap direction of ring(s) 3"


def test_wrong_place_is_false_beyond_the_radius_and_scores_within_it() -> None:
    # "3:S" is target 21's; reported 0.6 m from it (> 0.5 m): too far, false. At 0.45 m: paired, 1 x4.
    far = score(_file([_row(0, "landolt-c", 5.6, 0.0, 0.5, "3:S")]), TRUTH, RMRC2026).reports[0]
    assert (far.status, far.points) == ("false", 0)
    assert far.reason == "too far: nearest landolt-c '3:S' (object 21) is 0.60 m away, limit 0.5 m"
    near = score(_file([_row(0, "landolt-c", 5.0, 0.45, 0.5, "3:S")]), TRUTH, RMRC2026).reports[0]
    assert (near.status, near.points, near.object_id) == ("identified", 4, 21)


def test_finals_need_the_3rd_and_4th_rings() -> None:
    # target 20: rings 3 and 4 right (NE, S): 1 x4. Target 21: ring 3 right (S), ring 4 wrong (W
    # for N): false under the finals, so no multiplier there: 1 + 0 = 1. Under rmrc2026 the same
    # file scores both (ring 3 only), 4 + 4 = 8.
    rep = _file(
        [
            _row(0, "landolt-c", 1.0, 0.0, 0.5, "3:NE 4:S"),
            _row(1, "landolt-c", 5.0, 0.0, 0.5, "1:W 3:S 4:W"),
        ]
    )
    fin = score(rep, TRUTH, FINALS)
    assert [(r.status, r.points) for r in fin.reports] == [("identified", 1), ("false", 0)]
    assert fin.reports[1].reason.startswith("wrong orientation: no landolt-c target has '3:S 4:W'")
    assert fin.total == 1
    assert score(rep, TRUTH, RMRC2026).total == 8
    only3 = score(_file([_row(0, "landolt-c", 1.0, 0.0, 0.5, "1:E 2:N 3:NE")]), TRUTH, FINALS).reports[0]
    assert only3.status == "false" and "ring(s) 3, 4" in only3.reason


def _with(**changes):
    d = RMRC2026.to_dict()
    d.pop("source")
    d.update(changes)
    return d


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"landolt_rings": [3, 9]}, "field 'landolt_rings': expected a list of distinct ring numbers from 1 to 5"),
        ({"landolt_rings": []}, "field 'landolt_rings': expected"),
        ({"landolt_radius_m": 0}, "field 'landolt_radius_m': expected a distance in metres > 0"),
        ({"landolt_radius_m": None}, "field 'landolt_radius_m': expected a distance"),
    ],
)
def test_bad_landolt_fields_are_refused_in_one_line(changes, message) -> None:
    with pytest.raises(RulesError, match=message) as e:
        rules_from_dict(_with(**changes), source="r.yaml")
    assert "\n" not in str(e.value)


def test_landolt_fields_go_with_a_landolt_type() -> None:
    d = _with()
    del d["landolt_rings"]
    with pytest.raises(RulesError, match="field 'landolt_rings' is missing"):
        rules_from_dict(d, source="r.yaml")
    d = _with()
    del d["types"]["landolt-c"]
    with pytest.raises(RulesError, match="field 'landolt_rings': is set but types has no landolt-c"):
        rules_from_dict(d, source="r.yaml")
    d = _with()
    d["types"]["landolt-c"] = {**d["types"]["landolt-c"], "identity_uses_text": False}
    with pytest.raises(RulesError, match="types.landolt-c.identity_uses_text"):
        rules_from_dict(d, source="r.yaml")
    assert rules_from_dict(_with(), source="r.yaml") == RMRC2026  # to_dict round-trips
