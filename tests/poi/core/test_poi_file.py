"""The POI file reader accepts what real teams write; the writer writes the exact layout."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from poi.core.poi_file import (
    PoiFileError,
    PoiHeader,
    PoiRow,
    format_poi_text,
    parse_poi_text,
    read_poi_file,
    write_poi_file,
    write_text_atomic,
)

# [Avevor2022] Figure 1 ("An example of one such file in CSV format"), written as the CSV it shows.
SEED_EXAMPLE = """pois
1.2
CUR
England
2022-07-08
09:19:11
Prelim1
id,time,text,x,y,z,robot,mode,type
0,09:19:14,Chart M,0.548,-0.392,1.241,Arbie,T,QRCode
1,09:19:18,Chart N,0.058,0.447,1.247,Arbie,T,QRCode
2,09:19:29,infectious-substance,-0.007,0.478,1.289,Arbie,T,Hazmat
3,09:20:10,Chart H,-1.565,1.183,1.248,Arbie,T,QRCode
4,09:20:12,Chart C,-0.649,0.853,1.248,Arbie,T,QRCode
5,09:20:20,explosive,-0.711,0.902,1.267,Arbie,T,Hazmat
6,09:20:27,Chart G,-2.479,1.763,1.293,Arbie,T,QRCode
7,09:20:30,Chart J,-3.401,2.254,1.293,Arbie,T,QRCode
8,09:20:33,flammable-solid,-3.504,2.335,1.322,Arbie,T,Hazmat
9,09:20:37,Chart K,-4.313,1.309,1.279,Arbie,T,QRCode
10,09:20:41,Chart O,-4.585,-0.435,1.264,Arbie,T,QRCode
11,09:20:45,Chart B,-3.675,-0.845,1.254,Arbie,T,QRCode
12,09:20:46,explosive,-3.599,-0.899,1.277,Arbie,T,Hazmat
13,09:20:52,Chart E,-2.884,-1.24,1.233,Arbie,T,QRCode
14,09:20:56,Chart F,-2.313,-1.514,1.235,Arbie,T,QRCode
15,09:21:00,Chart L,-1.521,-1.893,1.232,Arbie,T,QRCode
16,09:21:03,Chart I,-0.238,-1.922,1.277,Arbie,T,QRCode
17,09:21:12,spontaneously-combustible,-0.214,-1.823,1.297,Arbie,T,Hazmat
18,09:21:35,,-4.603,-0.41,-0.015,Arbie,T,fire extinguisher
19,09:22:48,inhalation-hazard,-4.588,-0.274,1.175,Arbie,T,Hazmat
"""

SMALL = """pois
1.2
CUR
England
2022-07-08
09:19:11
Prelim1
id,time,text,x,y,z,robot,mode,type
0,09:19:14,Chart M,0.548,-0.392,1.241,Arbie,T,QRCode
2,09:19:29,infectious-substance,-0.007,0.478,1.289,Arbie,T,Hazmat
18,09:21:35,,-4.603,-0.41,-0.015,Arbie,T,fire extinguisher
"""


def _key(f) -> tuple:
    rows = [(r.id, r.time, r.text, r.x, r.y, r.z, r.robot, r.mode, r.type) for r in f.rows]
    return (f.header, rows)


def test_seed_example_reads_without_problems(tmp_path: Path) -> None:
    path = tmp_path / "seed.csv"
    path.write_text(SEED_EXAMPLE)
    f = read_poi_file(path)
    assert f.problems == [] and f.warnings == []
    assert f.header == PoiHeader(
        version="1.2",
        team="CUR",
        country="England",
        date="2022-07-08",
        start_time="09:19:11",
        mission="Prelim1",
    )
    assert [r.id for r in f.rows] == list(range(20))
    assert [r.line for r in f.rows] == list(range(9, 29))  # header 7 + pois + columns = 8
    types = [r.type for r in f.rows]
    assert types.count("qr") == 13 and types.count("hazmat") == 6
    assert types[18] == "fire-extinguisher"
    r18 = f.rows[18]
    assert (r18.text, r18.x, r18.y, r18.z, r18.robot, r18.mode) == (
        "",
        -4.603,
        -0.41,
        -0.015,
        "Arbie",
        "T",
    )
    assert f.rows[0].text == "Chart M" and f.rows[17].text == "spontaneously-combustible"


def _quoted(text: str) -> str:
    lines = text.split("\n")
    return "\n".join(f'"{v}"' if 0 < i < 7 or i == 0 else v for i, v in enumerate(lines))


@pytest.mark.parametrize(
    "variant",
    [
        pytest.param(lambda t: t, id="bare"),
        pytest.param(_quoted, id="quoted-header"),
        pytest.param(lambda t: t.replace("Prelim1\n", "Prelim1\n\n"), id="blank-line"),
        pytest.param(lambda t: t.replace("\n", "\r\n"), id="crlf"),
        pytest.param(lambda t: "\ufeff" + t, id="bom"),
        pytest.param(lambda t: t.replace(",", " ,  ").replace("\n", "  \n"), id="extra-spaces"),
        pytest.param(
            lambda t: "\ufeff" + _quoted(t).replace('Prelim1"\n', 'Prelim1"\r\n\r\n').replace("\n", "\r\n"),
            id="bom-quoted-blank-crlf",
        ),
        pytest.param(
            lambda t: "\n".join(line + ",,,,,,,," if i < 7 else line for i, line in enumerate(t.split("\n"))),
            id="spreadsheet-padding",
        ),
    ],
)
def test_header_forms_read_the_same(tmp_path: Path, variant) -> None:
    expected = parse_poi_text(SMALL)
    path = tmp_path / "v.csv"
    path.write_bytes(variant(SMALL).encode("utf-8"))
    f = read_poi_file(path)
    assert f.problems == [] and f.warnings == []
    assert _key(f) == _key(expected)


def test_type_and_label_aliases() -> None:
    rows = [
        "1,10:00:00,Chart A,0,0,0,R,T,QR Code",
        "2,10:00:00,Chart B,0,0,0,R,T,qr_code",
        "3,10:00:00,,0,0,0,R,T,Victim",
        "4,10:00:00,,0,0,0,R,A,EXTINGUISHER",
        "5,10:00:00,,0,0,0,R,A,thermal",
        "6,10:00:00,Toxic,0,0,0,R,T,hazmat",
        "7,10:00:00,Flammable Liquid,0,0,0,R,T,HAZMAT",
        "8,10:00:00,explosives,0,0,0,R,T,Hazmat",
        "9,10:00:00,,0,0,0,R,t,Fire_Extinguisher_Sign",
    ]
    f = parse_poi_text(SMALL.split("0,09:19:14")[0] + "\n".join(rows) + "\n")
    assert f.problems == [] and f.warnings == []
    assert [(r.type, r.text) for r in f.rows] == [
        ("qr", "Chart A"),
        ("qr", "Chart B"),
        ("baby-doll", ""),
        ("fire-extinguisher", ""),
        ("heat-source", ""),
        ("hazmat", "inhalation-hazard"),
        ("hazmat", "flammable-gas"),
        ("hazmat", "explosive"),
        ("fire-extinguisher-sign", ""),
    ]
    assert f.rows[-1].mode == "T"


def test_qr_text_kept_exactly_and_unknown_label_kept_raw() -> None:
    head = SMALL.split("0,09:19:14")[0]
    body = '1,10:00:00,  Chart  m ,0,0,0,R,T,qr\n2,10:00:00,"Chart, M",1,1,1,R,T,qr\n'
    body += "3,10:00:00,Banana Peel,2,2,2,R,T,hazmat\n"
    f = parse_poi_text(head + body)
    assert f.problems == []
    assert f.rows[0].text == "Chart  m"  # surrounding spaces stripped, inside and case kept
    assert f.rows[1].text == "Chart, M"
    assert f.rows[2].text == "Banana Peel"
    assert len(f.warnings) == 1 and f.warnings[0].line == 11
    assert "unknown hazmat label 'Banana Peel'" in f.warnings[0].message


def test_broken_rows_are_problems_with_line_numbers() -> None:
    head = SMALL.split("0,09:19:14")[0]  # 8 lines: rows start on line 9
    body = "\n".join(
        [
            "0,10:00:00,Chart A,0,0,0,R,T,qr",  # 9 good
            "1,10:00:00,Chart, B,0,0,0,R,T,qr",  # 10 unquoted comma: 10 cells
            "2,10:00:00,,abc,0,0,R,T,door",  # 11 x not a number
            "3,10:00:00,,0,nan,0,R,T,door",  # 12 NaN
            "4,10:00:00,,0,0,0,R,T,spaceship",  # 13 unknown type
            "five,10:00:00,,0,0,0,R,T,valve",  # 14 id not an integer
            "",  # 15 blank: skipped
            "6,10:00:00,,0,0",  # 16 too few cells, type unreadable
            "7,10:00:00,,1,2,3,R,T,door",  # 17 good
        ]
    )
    f = parse_poi_text(head + body + "\n")
    assert [r.line for r in f.rows] == [9, 17]
    got = [(p.line, p.type) for p in f.problems]
    assert got == [(10, "qr"), (11, "door"), (12, "door"), (13, None), (14, "valve"), (16, None)]
    msgs = {p.line: p.message for p in f.problems}
    assert "expected 9 columns" in msgs[10] and "got 10" in msgs[10]
    assert "x 'abc' is not a finite number" in msgs[11]
    assert "y 'nan' is not a finite number" in msgs[12]
    assert "unknown type 'spaceship'" in msgs[13]
    assert "id 'five' is not an integer" in msgs[14]
    assert "got 5" in msgs[16]
    assert f.problems[0].id == "1"


def test_unknown_columns_are_kept_aside_with_a_warning_and_the_file_scores(tmp_path: Path) -> None:
    # issue 60 edge 2: a team's extra column refused the whole file
    from eval.scoring.rules import load_rules
    from eval.scoring.scorer import score

    head = SMALL.split("id,time")[0]  # 7 header lines: the column line is line 8
    body = (
        "id,time,text,confidence,x,y,z,robot,mode,type,notes\n"
        "0,09:19:14,Chart M,0.93,0.548,-0.392,1.241,Arbie,T,QRCode,seen twice\n"
        "1,09:19:29,infectious-substance,0.71,-0.007,0.478,1.289,Arbie,T,Hazmat\n"  # notes left out
        "2,09:19:30,,0.5,0,0,0,Arbie,T\n"  # a format column (type) left out: still a problem
    )
    path = tmp_path / "team.csv"
    path.write_text(head + body)
    f = read_poi_file(path)
    assert [(r.id, r.type, r.text, r.x) for r in f.rows] == [
        (0, "qr", "Chart M", 0.548),
        (1, "hazmat", "infectious-substance", -0.007),
    ]
    assert f.rows[0].extra == {"confidence": "0.93", "notes": "seen twice"}
    assert f.rows[1].extra == {"confidence": "0.71", "notes": ""}
    assert [p.line for p in f.problems] == [11]
    warned = [w.message for w in f.warnings if "not a POI column" in w.message]
    assert len(warned) == 2 and all(m.startswith(f"{path}: column '") for m in warned)
    assert "'confidence'" in warned[0] and "'notes'" in warned[1]
    assert {w.line for w in f.warnings if "not a POI column" in w.message} == {8}
    truth = parse_poi_text(SMALL.replace(",T,", ",GT,"))
    assert score(f, truth, load_rules("ex3")).total > 0
    # a column of the format named twice is still refused
    with pytest.raises(PoiFileError, match=r"line 8: column 'x' is repeated"):
        parse_poi_text(head + "id,time,text,x,y,z,robot,mode,type,x\n", source="twice.csv")


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("", "it is empty"),
        ("id,time,text,x,y,z,robot,mode,type\n", "line 1 is 'id,time"),
        ("poi\n1.2\n", "expected 'pois'"),
        ("pois\n1.2\nteam\n", "no column line"),
        ("pois\n1.2\n0,10:00:00,,0,0,0,R,T,door\n", "line 3: expected a header value"),
        ("pois\n1.2\nid,time,text,x,y,robot,mode,type\n", "column line lacks z"),
    ],
)
def test_unreadable_files_raise_one_line_errors(tmp_path: Path, content: str, match: str) -> None:
    path = tmp_path / "f.csv"
    path.write_text(content)
    with pytest.raises(PoiFileError, match=match) as info:
        read_poi_file(path)
    assert str(info.value).startswith(f"{path}: ")
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(PoiFileError, match=r"missing\.csv: no such file"):
        read_poi_file(tmp_path / "missing.csv")


def test_latin1_file_reads_with_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "l1.csv"
    path.write_bytes(SMALL.replace("England", "Österreich").encode("latin-1"))
    f = read_poi_file(path)
    assert f.header.country == "Österreich"
    assert [w.message for w in f.warnings] == ["not UTF-8; read as Latin-1"]


def test_header_oddities_are_warnings_not_errors() -> None:
    text = SMALL.replace("1.2\n", "1.1\n", 1).replace("2022-07-08", "08.07.2022")
    f = parse_poi_text(text.replace("Prelim1\n", ""))
    assert len(f.rows) == 3 and f.problems == []
    messages = " | ".join(w.message for w in f.warnings)
    assert "header has 5 values" in messages
    assert "version '1.1'" in messages


def test_writer_exact_layout_and_round_trip(tmp_path: Path) -> None:
    header = PoiHeader(team="poibench", country="sim", date="2000-01-01", start_time="00:00:00", mission="m1")
    rows = [
        PoiRow(
            line=0,
            id=0,
            time="00:00:01",
            text="Chart, M",
            x=0.5484,
            y=-0.3925,
            z=1.0,
            robot="sim",
            mode="GT",
            type="qr",
        ),
        PoiRow(
            line=0,
            id=1,
            time="00:00:02",
            text="",
            x=-4.6031,
            y=-0.0004,
            z=2.0,
            robot="sim",
            mode="GT",
            type="fire-extinguisher",
        ),
    ]
    path = tmp_path / "truth.csv"
    write_poi_file(path, header, rows)
    raw = path.read_bytes()
    assert b"\r" not in raw
    assert raw.decode() == (
        "pois\n1.2\npoibench\nsim\n2000-01-01\n00:00:00\nm1\n"
        "id,time,text,x,y,z,robot,mode,type\n"
        '0,00:00:01,"Chart, M",0.548,-0.393,1.000,sim,GT,qr\n'
        "1,00:00:02,,-4.603,0.000,2.000,sim,GT,fire-extinguisher\n"
    )
    f = read_poi_file(path)
    assert f.problems == [] and f.warnings == []
    assert f.header == header
    assert [(r.line, r.text, r.x, r.mode) for r in f.rows] == [
        (9, "Chart, M", 0.548, "GT"),
        (10, "", -4.603, "GT"),
    ]
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind
    assert format_poi_text(header, rows) == raw.decode()


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_get_the_mode_of_any_new_file(tmp_path: Path, umask: int, mode: int) -> None:
    # 0666 less the umask (mkstemp's temporary file would make every one 0600), also when
    # it replaces a file of another mode
    header = PoiHeader(team="t", country="c", date="2000-01-01", start_time="00:00:00", mission="m")
    old = tmp_path / "old.csv"
    old.write_text("x")
    old.chmod(0o600 if mode != 0o600 else 0o644)
    previous = os.umask(umask)
    try:
        write_poi_file(tmp_path / "truth.csv", header, [])
        write_poi_file(old, header, [])
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "truth.csv").stat().st_mode) == mode
    assert stat.S_IMODE(old.stat().st_mode) == mode


def test_failed_atomic_write_keeps_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "pois.csv"
    path.write_text("old\n")
    with pytest.raises(UnicodeEncodeError):
        write_text_atomic(path, "new \ud800")  # a lone surrogate cannot be written as UTF-8
    assert path.read_text() == "old\n"
    assert list(tmp_path.iterdir()) == [path]  # the temporary file is gone


def test_empty_header_value_keeps_its_place() -> None:
    header = PoiHeader(team="", country="CZ", date="2025-05-01", start_time="", mission="m")
    text = format_poi_text(header, [])
    assert text.startswith("pois\n1.2\n\nCZ\n2025-05-01\n\nm\n")
    f = parse_poi_text(text.replace("m\nid,", "m\n\nid,"))  # and a blank line after the header
    assert f.header == header and f.warnings == []


def test_quoted_cells_with_spaces_around_them() -> None:
    head = '  "pois"  \n"1.2"\n "CUR" \nEngland\n2022-07-08\n09:19:11\nPrelim1\n'
    body = ' "id" , "time","text","x","y","z","robot","mode","type"\n'
    body += '0 , 09:19:14 ,  "Chart, M" , 0.5 ,1,2 , R ,T , QRCode \n'
    f = parse_poi_text(head + body)
    assert f.problems == [] and f.warnings == [] and f.header.team == "CUR"
    r = f.rows[0]
    assert (r.line, r.text, r.x, r.y, r.z, r.robot, r.type) == (9, "Chart, M", 0.5, 1, 2, "R", "qr")
