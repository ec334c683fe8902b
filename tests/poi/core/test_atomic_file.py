"""atomic_path: the target is its old file or the whole new one, and no temporary file is left behind."""

import errno
import os
import stat
from pathlib import Path

import pytest

from poi.core.atomic_file import atomic_path


def test_the_new_file_replaces_the_old_one_whole(tmp_path: Path) -> None:
    target = tmp_path / "score.json"
    target.write_text("old\n")
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".score.json.") and tmp.suffix == ".tmp"
        tmp.write_text("new\n")
        assert target.read_text() == "old\n"  # not yet: a reader still sees the old file
    assert target.read_text() == "new\n"
    assert list(tmp_path.iterdir()) == [target]


def test_a_failure_mid_write_keeps_the_old_file_and_leaves_no_temporary_one(tmp_path: Path) -> None:
    target = tmp_path / "model.onnx"
    target.write_bytes(b"old")
    with pytest.raises(OSError, match="No space left"), atomic_path(target) as tmp:
        tmp.write_bytes(b"half a ne")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert target.read_bytes() == b"old"
    assert list(tmp_path.iterdir()) == [target]


def test_a_failure_before_anything_was_written_leaves_no_file(tmp_path: Path) -> None:
    target = tmp_path / "a.csv"
    with pytest.raises(KeyboardInterrupt), atomic_path(target):
        raise KeyboardInterrupt  # any exception, not only OSError
    with pytest.raises(FileNotFoundError), atomic_path(target):
        pass  # a writer that made no file: nothing to rename, and no target appears
    assert list(tmp_path.iterdir()) == []


def test_a_given_temporary_name_is_used_and_gets_the_mode_of_any_new_file(tmp_path: Path) -> None:
    target = tmp_path / "map.png"
    target.write_bytes(b"old")
    target.chmod(0o600)
    previous = os.umask(0o022)
    try:
        with atomic_path(target, temp_name=".map.partial.png") as tmp:
            assert tmp == tmp_path / ".map.partial.png"
            tmp.write_bytes(b"new")
    finally:
        os.umask(previous)
    assert target.read_bytes() == b"new" and stat.S_IMODE(target.stat().st_mode) == 0o644
    assert list(tmp_path.iterdir()) == [target]
