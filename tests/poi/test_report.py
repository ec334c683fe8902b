"""poi.report: the exact POI file layout, append-and-flush, atomic finalize with normal file modes."""

from __future__ import annotations

import os
import stat
from datetime import datetime

import numpy as np
import pytest

from poi.core.poi_file import read_poi_file
from poi.core.types import TrackSnapshot
from poi.report import PoiWriter, ReportError, ReportHeader

HEADER = ReportHeader(team="CUR", country="England", mission="Prelim1", start=datetime(2022, 7, 8, 9, 19, 11))
HEADER_BYTES = b"pois\n1.2\nCUR\nEngland\n2022-07-08\n09:19:11\nPrelim1\nid,time,text,x,y,z,robot,mode,type\n"


def snap(report_id, type_, text, xyz, first_seen_s, track_id=None) -> TrackSnapshot:
    return TrackSnapshot(
        track_id=report_id if track_id is None else track_id,
        report_id=report_id,
        type=type_,
        text=text,
        position_map=np.array(xyz, dtype=float),
        covariance=np.eye(3),
        first_seen_s=first_seen_s,
        support=3.0,
        n_detections=3,
        confirmed=report_id is not None,
    )


def test_exact_bytes_after_appends(tmp_path):
    p = tmp_path / "pois.csv"
    w = PoiWriter(p, HEADER, robot="Arbie", mode="T")
    assert p.read_bytes() == HEADER_BYTES  # header on open
    w.append(snap(0, "qr", "Chart M", [0.548, -0.392, 1.2414], 3.0))
    w.append(snap(1, "hazmat", "infectious-substance", [-0.0004, 0.4776, 1.289], 18.9))
    w.append(snap(2, "fire-extinguisher", "", [-4.603, -0.41, -0.015], 144.0))
    w.append(snap(3, "qr", 'Chart "N", 2', [1, 2, 3], 145.0), time_hms="09:30:00")
    w.close()
    assert p.read_bytes() == HEADER_BYTES + (
        b"0,09:19:14,Chart M,0.548,-0.392,1.241,Arbie,T,qr\n"
        # -0.0004 rounds to 0.000, written without a minus sign; time is start + 18.9 s
        b"1,09:19:29,infectious-substance,0.000,0.478,1.289,Arbie,T,hazmat\n"
        b"2,09:21:35,,-4.603,-0.410,-0.015,Arbie,T,fire-extinguisher\n"
        # a comma or quote in a QR text: CSV quoting, quotes doubled; an explicit time
        b'3,09:30:00,"Chart ""N"", 2",1.000,2.000,3.000,Arbie,T,qr\n'
    )


def test_killed_run_leaves_a_readable_file(tmp_path):
    p = tmp_path / "pois.csv"
    w = PoiWriter(p, HEADER, robot="Arbie", mode="A")
    w.append(snap(0, "door", "", [1, 2, 0.5], 1.0))
    w.append(snap(1, "qr", "a,b", [3, 4, 1.2], 2.0))
    # no finalize, no close: what is on disk now is what a killed run leaves
    data = p.read_bytes()
    assert data.endswith(b'1,09:19:13,"a,b",3.000,4.000,1.200,Arbie,A,qr\n')
    f = read_poi_file(p)
    assert f.problems == []
    assert [(r.id, r.type, r.text, r.x) for r in f.rows] == [
        (0, "door", "", 1.0),
        (1, "qr", "a,b", 3.0),
    ]
    w.close()


def test_a_withdrawn_object_leaves_the_streamed_file_at_once(tmp_path):
    # tracker step 6 takes a confirmed placard back: a run killed after that must not report it
    p = tmp_path / "pois.csv"
    w = PoiWriter(p, HEADER, robot="Arbie", mode="A")
    w.append(snap(0, "door", "", [1, 2, 0.5], 1.0, track_id=10))
    w.append(snap(1, "hazmat", "corrosive", [3, 4, 1.2], 2.0, track_id=11))
    w.append(snap(2, "valve", "", [5, 6, 1.0], 3.0, track_id=12))
    assert w.withdraw(11)
    door = b"0,09:19:12,,1.000,2.000,0.500,Arbie,A,door\n"
    valve = b"2,09:19:14,,5.000,6.000,1.000,Arbie,A,valve\n"
    assert p.read_bytes() == HEADER_BYTES + door + valve  # no finalize: what a killed run leaves
    assert not w.withdraw(11) and not w.withdraw(99)  # never streamed (or gone): nothing written
    assert p.read_bytes() == HEADER_BYTES + door + valve
    w.append(snap(3, "qr", "M", [0, 0, 1], 4.0, track_id=13))  # streaming goes on after the rewrite
    assert p.read_bytes() == HEADER_BYTES + door + valve + b"3,09:19:15,M,0.000,0.000,1.000,Arbie,A,qr\n"
    assert [r.id for r in read_poi_file(p).rows] == [0, 2, 3]
    assert sorted(x.name for x in tmp_path.iterdir()) == ["pois.csv"]  # no temp file left
    w.finalize([])
    with pytest.raises(ReportError, match="already finalized"):
        w.withdraw(10)


def test_finalize_rewrites_atomically(tmp_path):
    p = tmp_path / "pois.csv"
    w = PoiWriter(p, HEADER, robot="Arbie", mode="A")
    w.append(snap(0, "door", "", [1, 2, 0.5], 1.0))
    w.append(snap(1, "valve", "", [3, 4, 1.0], 2.0))
    # final positions moved; given out of order, written by report id
    w.finalize([snap(1, "valve", "", [3.5, 4, 1.0], 2.0), snap(0, "door", "", [1.25, 2, 0.5], 1.0)])
    assert p.read_bytes() == HEADER_BYTES + (
        b"0,09:19:12,,1.250,2.000,0.500,Arbie,A,door\n1,09:19:13,,3.500,4.000,1.000,Arbie,A,valve\n"
    )
    assert sorted(x.name for x in tmp_path.iterdir()) == ["pois.csv"]  # no temp file left
    with pytest.raises(ReportError, match="already finalized"):
        w.append(snap(2, "door", "", [0, 0, 0], 3.0))


def test_bad_rows_refused(tmp_path):
    w = PoiWriter(tmp_path / "pois.csv", HEADER)
    with pytest.raises(ReportError, match="no report id"):
        w.append(snap(None, "door", "", [0, 0, 0], 0.0, track_id=7))
    with pytest.raises(ReportError, match="canonical type"):
        w.append(snap(0, "QRCode", "", [0, 0, 0], 0.0))
    with pytest.raises(ReportError, match="mode"):
        PoiWriter(tmp_path / "x.csv", HEADER, mode="X")
    w.close()


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o027, 0o640)])
def test_files_get_the_mode_of_any_new_file(tmp_path, umask, mode):
    # 0666 less the umask, on open and after the atomic finalize (mkstemp would leave 0600)
    old = os.umask(umask)
    try:
        p = tmp_path / "pois.csv"
        w = PoiWriter(p, HEADER)
        assert stat.S_IMODE(p.stat().st_mode) == mode
        w.finalize([snap(0, "door", "", [1, 2, 0.5], 1.0)])
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == mode
