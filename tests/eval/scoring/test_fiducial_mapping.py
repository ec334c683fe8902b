"""The QR mapping bonus by fiducials (docs/RULES.md "QR mapping by fiducials"): rmrc2025 and
rmrc2026 give a QR code its +4 when its distances on the map to the two fiducials closest to it
in real life are right within 0.30 m; the old radius rule stays as ``qr_mapping: radius``; the
finals preset scores only the 2 mm codes. Every score is hand-computed in the comments.

The arena: fiducials 10 and 11 at (-2, 0) and (2, 0), a second pair 12 and 13 at (8, 0) and
(8, 1.2); QR code "Chart A" at (0, 0, 0.5), 2 m from each of 10 and 11; an oxidizer placard at
(4, 0, 0.8).
"""

from __future__ import annotations

import math

import pytest

from eval.scoring.report import format_tables, to_json_dict
from eval.scoring.rules import RulesError, load_rules, rules_from_dict
from eval.scoring.scorer import score
from poi.core.poi_file import PoiHeader, PoiRow, format_poi_text, parse_poi_text

RMRC2025 = load_rules("rmrc2025")
HEADER = PoiHeader(team="t", country="-", date="2025-07-18", start_time="10:00:00", mission="m")


def _row(id_: int, type_: str, x: float, y: float, z: float = 0.0, text: str = "", mode: str = "A") -> PoiRow:
    return PoiRow(line=0, id=id_, time="10:00:00", text=text, x=x, y=y, z=z, robot="r", mode=mode, type=type_)


def _file(rows: list[PoiRow]):
    return parse_poi_text(format_poi_text(HEADER, rows), source="f.csv")


def truth(extra: list[PoiRow] = ()):
    return _file(
        [
            _row(1, "qr", 0.0, 0.0, 0.5, "Chart A", "GT"),
            _row(2, "hazmat", 4.0, 0.0, 0.8, "oxidizer", "GT"),
            _row(10, "fiducial", -2.0, 0.0, 0.25, "300 mm", "GT"),
            _row(11, "fiducial", 2.0, 0.0, 0.25, "300 mm", "GT"),
            _row(12, "fiducial", 8.0, 0.0, 0.25, "260 mm", "GT"),
            _row(13, "fiducial", 8.0, 1.2, 0.25, "260 mm", "GT"),
            *extra,
        ]
    )


def radius_rules():
    """rmrc2025 with the old radius rule: within 0.30 m of the true position."""
    d = RMRC2025.to_dict()
    for k in ("source", "qr_mapping", "fiducial_tolerance_m", "fiducial_match_radius_m"):
        d.pop(k)
    return rules_from_dict(d, source="radius")


def test_qr_off_by_0_4_m_with_right_fiducial_distances_is_mapped_under_rmrc2025_not_under_radius() -> None:
    # The QR code reported at (0, 0.4): 0.40 m from where it is. Its distances to the two closest
    # fiducials (10 and 11, true positions: the report has none) are sqrt(2^2 + 0.4^2) = 2.0396 m
    # against 2 m in real life: off by 0.04 m each, within 0.30 m.
    rep = _file([_row(0, "qr", 0.0, 0.4, 0.5, "Chart A"), _row(1, "hazmat", 4.1, 0.0, 0.8, "oxidizer")])
    res = score(rep, truth(), RMRC2025)
    qr, hz = res.reports
    assert qr.distance_m == pytest.approx(0.4)
    assert (qr.status, qr.points) == ("located", 5)  # 1 + the mapping bonus 4; never x4
    assert qr.reason == (
        "mapped: distance errors to fiducials 10 (true position) 0.04 m and 11 (true position) 0.04 m, limit 0.3 m"
    )
    assert (hz.status, hz.points) == ("identified", 4)  # 1 x4: autonomous, no false report
    assert res.total == 9  # 5 + 4
    assert res.max_total == 9  # 5 (QR located) + 4 (the placard, autonomous)
    block = res.qr_mapping
    assert block["fiducials_truth"] == 4 and block["fiducials_reported"] == 0
    assert block["fiducials_from_truth"] == 2 and block["qr_mapped"] == 1
    assert "their true positions were used" in block["reason"]
    assert to_json_dict(res)["qr_mapping"] == block
    assert any(line.startswith("QR mapping by fiducials: 1 of 1") for line in format_tables(res).splitlines())

    old = score(rep, truth(), radius_rules())  # 0.40 m > 0.30 m: identified only
    assert [(r.status, r.points) for r in old.reports] == [("identified", 1), ("identified", 4)]
    assert old.total == 5 and old.qr_mapping is None


def test_a_shifted_map_is_judged_against_its_own_fiducials() -> None:
    # The whole map is shifted by (0.5, 0.5): the QR code at (0.5, 0.5), 0.71 m from the truth,
    # and fiducials 10 and 11 at (-1.5, 0.5) and (2.5, 0.5). On the map the code is 2 m from
    # each: the distances are right (error 0), so it is mapped.
    shifted = [
        _row(0, "qr", 0.5, 0.5, 0.5, "Chart A"),
        _row(1, "fiducial", -1.5, 0.5, 0.25),
        _row(2, "fiducial", 2.5, 0.5, 0.25),
    ]
    res = score(_file(shifted), truth(), RMRC2025)
    qr, f1, f2 = res.reports
    assert (qr.status, qr.points) == ("located", 5)
    assert qr.reason.startswith(
        "mapped: distance errors to fiducials 10 (reported) 0.00 m and 11 (reported) 0.00 m"
    )
    assert f1.status == f2.status == "ignored" and "QR mapping test" in f1.reason
    assert res.false_reports == 0
    assert res.qr_mapping["fiducials_paired"] == 2 and "fiducials_from_truth" not in res.qr_mapping
    # Without its fiducials the same code is judged against the true ones: its distance to 10 is
    # sqrt(2.5^2 + 0.5^2) = 2.5495 m against 2 m (error 0.55 m > 0.30 m): not mapped, 1 point.
    alone = score(_file(shifted[:1]), truth(), RMRC2025)
    (qr,) = alone.reports
    assert (qr.status, qr.points) == ("identified", 1)
    assert qr.reason.startswith("not mapped: distance errors to fiducials 10 (true position) 0.55 m")


def test_the_two_closest_fiducials_in_real_life_are_used_and_each_must_pass() -> None:
    # Reported at (0.4, 0): 2.4 m from 10 (error 0.40 m) and 1.6 m from 11 (error 0.40 m): not mapped.
    res = score(_file([_row(0, "qr", 0.4, 0.0, 0.5, "Chart A")]), truth(), RMRC2025)
    assert (res.reports[0].status, res.reports[0].points) == ("identified", 1)
    # A second code at (7.7, 0.6): its closest fiducials are 12 (0.6708 m) and 13 (0.6708 m), not 11.
    # Reported at (7.7, 0.9): 0.9487 m from 12 (error 0.28 m) and 0.4243 m from 13 (error 0.25 m): mapped.
    extra = [_row(3, "qr", 7.7, 0.6, 0.5, "Chart B", "GT")]
    res = score(_file([_row(0, "qr", 7.7, 0.9, 0.5, "Chart B")]), truth(extra), RMRC2025)
    (qr,) = res.reports
    assert (qr.status, qr.points) == ("located", 5)
    assert "fiducials 12 (true position) 0.28 m and 13 (true position) 0.25 m" in qr.reason
    assert math.isclose(
        math.dist((7.7, 0.9), (8.0, 0.0)) - math.dist((7.7, 0.6), (8.0, 0.0)), 0.2779, abs_tol=1e-4
    )


def test_fewer_than_two_fiducials_falls_back_to_the_radius_rule() -> None:
    t = _file([_row(1, "qr", 0.0, 0.0, 0.5, "Chart A", "GT"), _row(10, "fiducial", -2.0, 0.0, 0.25, "", "GT")])
    res = score(_file([_row(0, "qr", 0.0, 0.25, 0.5, "Chart A")]), t, RMRC2025)  # 0.25 m <= 0.30 m
    assert (res.reports[0].status, res.reports[0].points) == ("located", 5)
    assert "fewer than two: the radius rule decided" in res.qr_mapping["reason"]


def test_finals_score_only_the_2_mm_code() -> None:
    finals = load_rules("rmrc2026-finals")
    t = truth(
        [_row(3, "qr", 0.0, 0.1, 0.5, "Chart F 2mm", "GT"), _row(4, "qr", 0.0, -0.1, 0.6, "Chart F 5mm", "GT")]
    )
    rep = _file([_row(0, "qr", 0.0, 0.1, 0.5, "Chart F 2mm"), _row(1, "qr", 0.0, -0.1, 0.6, "Chart F 5mm")])
    res = score(rep, t, finals)
    two, five = res.reports
    assert (two.status, two.points) == ("located", 5)  # on the spot: distance errors 0
    assert five.status == "ignored" and "qr_text_filter" in five.reason
    # Only "Chart F 2mm" and the placard are scored objects: 5 + 1 x4; "Chart A" and the 5 mm are ignored.
    assert res.per_type["qr"].objects == 1 and res.max_total == 9
    assert res.total == 5 and res.false_reports == 0  # the placard is missed


def test_hector_style_1_3_file_scores_under_rmrc2026() -> None:
    # Hector's 2025 writer: header pois, 1.3, team, country, date, time, mission <counter>; rows
    # id, HH:MM:SS, x, y, z, robot, A|T; no type column, so rows pair by location with the
    # scored objects (no distance limit under rmrc2026).
    hector = parse_poi_text(
        "pois\n1.3\nHector\nGermany\n2025-07-18\n10:15:00\nmission 2\n"
        + "0,10:15:20,0.000,0.400,0.500,hector,A\n"  # the QR code, 0.4 m off, distances right: 5
        + "1,10:15:40,4.200,0.000,0.800,hector,A\n",  # the placard, 0.2 m: 1 x4 = 4
        source="hector.csv",
    )
    res = score(hector, truth(), load_rules("rmrc2026"))
    assert not res.types_checked
    assert [(r.type, r.status, r.points, r.object_id) for r in res.reports] == [
        ("qr", "located", 5, 1),
        ("hazmat", "identified", 4, 2),
    ]
    assert res.total == 9 and res.autonomy["applied"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"qr_mapping": "nearest"}, "field 'qr_mapping': expected one of radius, fiducials"),
        ({"fiducial_tolerance_m": -1}, "field 'fiducial_tolerance_m': expected a distance in metres > 0"),
        ({"qr_mapping": "radius"}, "field 'fiducial_tolerance_m': is set but qr_mapping is not 'fiducials'"),
        ({"qr_text_filter": "(2mm"}, "field 'qr_text_filter': not a regular expression"),
    ],
)
def test_bad_mapping_fields_are_refused_with_the_field_named(change: dict, message: str) -> None:
    d = {**RMRC2025.to_dict(), **change}
    d.pop("source")
    with pytest.raises(RulesError, match=message.replace("(", r"\(")):
        rules_from_dict(d, source="r.yaml")


def test_the_map_draws_fiducials_as_half_discs_against_their_wall(tmp_path) -> None:
    import cv2

    from eval.scoring.map_plot import FIDUCIAL_REPORT_RGB, FIDUCIAL_RGB, MapFiducial, draw_map, score_layers

    rep = _file([_row(0, "qr", 0.0, 0.4, 0.5, "Chart A"), _row(1, "fiducial", 2.05, 0.0, 0.25)])
    layers = score_layers(score(rep, truth(), RMRC2025))
    assert layers["fiducials"][:2] == [
        MapFiducial(x=-2.0, y=0.0, diameter_m=0.3),
        MapFiducial(x=2.0, y=0.0, diameter_m=0.3),
    ]
    assert layers["fiducials"][-1] == MapFiducial(x=2.05, y=0.0, reported=True)
    assert [r.type for r in layers["reports"]] == ["qr"]  # a fiducial report is drawn as a fiducial
    walls = [((-3.0, -0.025), (9.0, -0.025))]  # all fiducials stand on its north face, facing +y

    def pixels(path, rgb) -> int:
        img = cv2.imread(str(path))[:, :, ::-1]
        return int((img == rgb).all(axis=2).sum())

    with_f = draw_map(tmp_path / "f.png", walls=walls, robot_path=[[0, 0.6]], **layers)
    layers.pop("fiducials")
    without = draw_map(tmp_path / "n.png", walls=walls, robot_path=[[0, 0.6]], **layers)
    assert pixels(without, FIDUCIAL_RGB) == 0
    # 910 px of axes over 14 m: 65 px a metre; a 0.3 m half-disc covers pi 9.75^2 / 2 = 149 px less its
    # black edge; four truth fiducials, one half under the reported one: more than one half-disc, less
    # than four whole ones (the legend's swatches add a few pixels of each grey)
    assert 149 < pixels(with_f, FIDUCIAL_RGB) < 4 * 149
    assert pixels(without, FIDUCIAL_REPORT_RGB) == 0 < pixels(with_f, FIDUCIAL_REPORT_RGB)
