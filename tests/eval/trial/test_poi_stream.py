"""eval.trial.observers.PoiStream: pois.csv follows the pipeline's confirmations and withdrawals frame by frame."""

from __future__ import annotations

from types import SimpleNamespace

from eval.trial.observers import PoiStream
from poi.core.poi_file import read_poi_file
from poi.report import PoiWriter
from tests.poi.test_report import HEADER, snap


def tick(confirmed=(), withdrawn=()):
    return SimpleNamespace(res=SimpleNamespace(newly_confirmed=list(confirmed), withdrawn=list(withdrawn)))


def test_the_streamed_file_drops_a_withdrawn_report_in_the_frame_it_is_withdrawn(tmp_path):
    p = tmp_path / "pois.csv"
    stream = PoiStream(PoiWriter(p, HEADER))
    stream.on_frame(tick([snap(0, "hazmat", "corrosive", [1, 0, 1], 1.0, track_id=4)]))
    stream.on_frame(tick([snap(1, "landolt-c", "3", [1, 0.1, 1], 2.0, track_id=5)], withdrawn=[4]))
    rows = read_poi_file(p).rows  # the file a run killed now leaves
    assert [(r.id, r.type) for r in rows] == [(1, "landolt-c")]


def test_a_failed_write_stops_streaming_without_ending_the_run(tmp_path):
    p = tmp_path / "pois.csv"
    writer = PoiWriter(p, HEADER)
    stream = PoiStream(writer)
    stream.on_frame(tick([snap(0, "door", "", [1, 0, 0], 1.0, track_id=4)]))

    def full_disk(track_id):
        raise OSError(28, "No space left on device")

    writer.withdraw = full_disk
    stream.on_frame(tick(withdrawn=[4]))
    assert not stream.streaming
    stream.on_frame(tick([snap(1, "valve", "", [2, 0, 1], 2.0, track_id=6)]))  # no longer written
    assert [r.id for r in read_poi_file(p).rows] == [0]
    writer.close()
