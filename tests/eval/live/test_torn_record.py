"""``poibench view`` of a torn record replays the frames before the torn line with one warning,
and a replay page's seek message is validated (``{"seek": 1e400}`` was an OverflowError)."""

import json

import pytest

from eval.live.server import LiveError, ReplaySource, seek_index


def _frame(k: int) -> str:
    return json.dumps({"type": "frame", "k": k, "t": k / 10, "pose": None, "detections": [], "confirmed": []})


def _record(folder, lines: list[str]):
    live = folder / "live"
    live.mkdir(parents=True)
    (live / "init.json").write_text(json.dumps({"type": "init", "n_frames": 5, "walls": [], "path": []}))
    (live / "frames.jsonl").write_text("".join(line + "\n" for line in lines))
    return folder


def test_a_torn_line_ends_the_replay_there_with_one_warning(tmp_path):
    # a killed run's last line, cut mid-message; and two runs' lines interleaved
    torn = _record(tmp_path / "a", [_frame(0), _frame(1), _frame(2)[:17]])
    src = ReplaySource(torn)
    assert [m["k"] for m in src.frames] == [0, 1]
    assert src.init["n_frames"] == 2
    assert "line 3" in src.warning and "replaying the 2 frames before it" in src.warning
    assert "\n" not in src.warning
    src.close()
    mixed = _record(tmp_path / "b", [_frame(0), _frame(1)[:9] + _frame(0), _frame(2)])
    assert [m["k"] for m in ReplaySource(mixed).frames] == [0]
    whole = ReplaySource(_record(tmp_path / "c", [_frame(0), _frame(1)]))
    assert whole.warning is None and len(whole.frames) == 2


def test_a_record_stopped_before_its_end_replays_with_its_path_rebuilt(tmp_path):
    # what a run leaves when stopped at frame 2: init.json as written at its start (no path yet)
    poses = [[0.0, 0.0, 0.1], None, [0.5, 0.2, 0.3]]
    lines = []
    for k, pose in enumerate(poses):
        path_len = sum(p is not None for p in poses[: k + 1])
        lines.append(json.dumps({"type": "frame", "k": k, "t": k / 10, "pose": pose, "path_len": path_len}))
    src = ReplaySource(_record(tmp_path / "a", lines))
    assert src.init["path"] == [[0.0, 0.0], [0.5, 0.2]]
    assert (
        src.warning == f"{tmp_path / 'a'}: the trial stopped at frame 2 before its end: replaying what it recorded"
    )
    src.close()
    # a finished record's path is its own, and no warning
    init = json.loads((tmp_path / "a" / "live" / "init.json").read_text()) | {"path": [[0.0, 0.0], [0.5, 0.2]]}
    (tmp_path / "a" / "live" / "init.json").write_text(json.dumps(init))
    whole = ReplaySource(tmp_path / "a")
    assert whole.warning is None and whole.init["path"] == [[0.0, 0.0], [0.5, 0.2]]
    whole.close()


def test_view_prints_the_warning_and_a_record_with_no_whole_frame_is_one_line(tmp_path, capsys, monkeypatch):
    from eval.cli.main import main

    with pytest.raises(LiveError, match="no whole frame message"):
        ReplaySource(_record(tmp_path / "empty", [_frame(0)[:5]]))
    assert main(["view", str(tmp_path / "empty")]) == 2
    assert "no whole frame message" in capsys.readouterr().err

    class Server:  # the view's server, not started: the test needs only what view prints first
        def __init__(self, port, replay):
            raise KeyboardInterrupt

    monkeypatch.setattr("eval.live.server.LiveServer", Server)
    assert main(["view", str(_record(tmp_path / "torn", [_frame(0), "{"]))]) == 130
    err = capsys.readouterr().err
    assert err.startswith("warning: ") and "line 2 is not a whole frame message" in err


@pytest.mark.parametrize(
    ("data", "k"),
    [
        ('{"seek": 3}', 3),
        ('{"seek": 2.7}', 2),
        ('{"seek": 1e400}', None),  # inf: was OverflowError from int()
        ('{"seek": -1e400}', None),
        ('{"seek": NaN}', None),
        ('{"seek": 1' + "0" * 400 + "}", 9),  # a 401-digit integer: the last frame
        ('{"seek": -5}', 0),
        ('{"seek": true}', None),
        ('{"seek": "4"}', None),
        ('{"seek": null}', None),
        ("[4]", None),
        ("not json", None),
        ("{}", 0),
    ],
)
def test_seek_messages_are_validated(data, k):
    assert seek_index(data, 10) == k
