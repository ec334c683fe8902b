"""TrialOutputs: a failed write is recorded, the others go on, and the end is one line naming the file;
each file is written whole or not at all, and a full disk is named as such."""

import errno
import os

import pytest

from eval.trial.outputs import TrialOutputError, TrialOutputs


def _full(path):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_failures_are_kept_and_named_after_the_other_writes(tmp_path):
    outs = TrialOutputs(tmp_path)
    assert outs.write("map.png", _full) is False
    assert outs.write("score.json", lambda p: p.write_text("{}\n")) is True
    assert outs.write("trial.mp4", _full) is False
    assert outs.write("pois.csv", lambda p: p.write_text("x\n")) is True
    assert (tmp_path / "score.json").read_text() == "{}\n"
    assert outs.names() == ["pois.csv", "score.json"]
    with pytest.raises(TrialOutputError) as info:
        outs.check()
    assert str(info.value) == (
        f"cannot write {tmp_path / 'map.png'}: no space left on device; "
        "nor trial.mp4; written: pois.csv score.json"
    )


def test_a_folder_output_names_its_failed_file_and_all_written_is_quiet(tmp_path):
    outs = TrialOutputs(tmp_path)
    outs.fail("live/", OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "live" / "insets.mp4")))
    with pytest.raises(TrialOutputError, match=r"cannot write .*live/insets\.mp4: no space left on device$"):
        outs.check()
    ok = TrialOutputs(tmp_path)
    ok.write("config.yaml", lambda p: p.write_text("a: 1\n"))
    ok.check()
    assert ok.names() == ["config.yaml"]


def _half_then_full(path):
    """A writer that gets half its bytes out before the disk fills (what left 0-byte files)."""
    with open(path, "w") as f:
        f.write('{"total": ')
        f.flush()
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_failed_write_leaves_no_file_and_no_older_one_that_would_look_like_its_output(tmp_path):
    (tmp_path / "cost.json").write_text('{"wall_s": 1}\n')  # an earlier run's
    outs = TrialOutputs(tmp_path)
    for name in ("score.json", "cost.json", "config.yaml", "map.png"):
        assert outs.write(name, _half_then_full) is False
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no 0-byte, half or stale file, no temporary
    assert outs.write("score.json", lambda p: p.write_text("{}\n")) is True
    assert sorted(p.name for p in tmp_path.iterdir()) == ["score.json"]


def test_the_writer_is_given_a_temporary_name_with_the_same_suffix(tmp_path):
    seen = []
    outs = TrialOutputs(tmp_path)
    outs.write(
        "map.png", lambda p: seen.append((p.suffix, p.exists(), (tmp_path / "map.png").exists())) or p.touch()
    )
    assert seen == [(".png", False, False)] and (tmp_path / "map.png").exists()
    # a write that makes its own file (the video, pois.csv) is left as it is
    assert outs.write("trial.mp4", lambda _: (tmp_path / "trial.mp4").write_bytes(b"x"), atomic=False)
    assert (tmp_path / "trial.mp4").read_bytes() == b"x"


def test_a_full_disk_is_named_even_when_the_video_failed_first_with_a_broken_pipe(tmp_path, monkeypatch):
    outs = TrialOutputs(tmp_path)
    outs.fail("trial.mp4", BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE)))
    outs.write("score.json", _full)
    with pytest.raises(TrialOutputError) as info:
        outs.check()
    assert str(info.value) == f"cannot write {tmp_path / 'score.json'}: no space left on device; nor trial.mp4"
    # the encoder died on a full disk and nothing else failed: the disk's free space names it
    only_video = TrialOutputs(tmp_path)
    only_video.fail("trial.mp4", BrokenPipeError(errno.EPIPE, os.strerror(errno.EPIPE)))
    monkeypatch.setattr("shutil.disk_usage", lambda p: shutil_usage(total=10, used=10, free=0))
    with pytest.raises(TrialOutputError, match=r"trial\.mp4: no space left on device$"):
        only_video.check()
    monkeypatch.setattr("shutil.disk_usage", lambda p: shutil_usage(total=10 << 30, used=0, free=10 << 30))
    with pytest.raises(TrialOutputError, match=r"trial\.mp4: Broken pipe$"):
        only_video.check()


def shutil_usage(**kw):
    import collections

    return collections.namedtuple("usage", "total used free")(**kw)
