"""The ``--out`` check every command makes before its start-up: can the output folder be written?
And the lock a trial-writing command holds on it while it runs.

A folder that is a file, lies under a file, or cannot be written in used to fail with
the raw errno text after the simulator, the models or the scenes had been loaded; this
refuses it at once with one line that names the path and what is wrong.

Two runs into the same ``--out`` used to both exit 0 and leave a mixed folder (one run's
``map.png``, the other's ``score.json``, ``live/frames.jsonl`` interleaved): a command that
sets ``locks_out`` holds :func:`hold_output_folder` while it runs, and a second one is refused.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

LOCK_NAME = ".poibench.lock"  # in the output folder: "PID START" of the run that holds it


class OutputPathError(ValueError):
    """An output path that cannot be written (one line naming the path)."""


def check_output_folder(path: str | Path, option: str = "--out") -> None:
    """Raise :class:`OutputPathError` unless ``path`` is a folder, or can be made one, that
    this process can write in; nothing is created.

    The test is a real one: an unnamed temporary file is opened in the folder (or, for a
    folder still to be made, in its nearest existing parent), so permissions, ACLs and
    read-only file systems all count, as they do for the command itself.
    """
    if not str(path).strip():
        raise OutputPathError(f"{option}: an empty path (an unset shell variable?); give a folder")
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputPathError(f"{option} {p}: is a file, not a folder")
    # the folder itself, or the nearest parent that exists (the file system root always does)
    where = p if p.exists() else next(a for a in p.absolute().parents if a.exists())
    if not where.is_dir():
        raise OutputPathError(f"{option} {p}: cannot make it, {where} is a file")
    try:
        with tempfile.TemporaryFile(dir=where):
            pass
    except OSError as e:
        reason = e.strerror or type(e).__name__
        what = "cannot write in it" if where == p else f"cannot make it in {where}"
        raise OutputPathError(f"{option} {p}: {what} ({reason})") from None


def check_output_file(path: str | Path, option: str = "--out") -> None:
    """:func:`check_output_folder` for an output file: it must not be a folder, and its folder
    must be writable or makeable."""
    if not str(path).strip():
        raise OutputPathError(f"{option}: an empty path (an unset shell variable?); give a file name")
    p = Path(path)
    if p.is_dir():
        raise OutputPathError(f"{option} {p}: is a folder; give a file name")
    check_output_folder(p.parent, option=f"{option} {p}: its folder")


class OutputFolderBusyError(OutputPathError):
    """An output folder another live run is writing in (one line naming the folder and the pid)."""


_held: set[Path] = set()  # the lock files this process holds


def _start_time(pid: int) -> str:
    """The process's start time in clock ticks since boot (Linux), so that a pid reused by
    another process since the lock was written is not taken for its holder; "" elsewhere."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat.rsplit(")", 1)[-1].split()[19]  # field 22 of proc(5), counted after "(comm)"


def _holder(lock: Path) -> int | None:
    """The pid of the live process that holds ``lock``; None when it is stale (its process has
    ended, or the file is unreadable or garbled) or is this process's own leftover."""
    try:
        pid_text, _, start = lock.read_text(encoding="utf-8").strip().partition(" ")
        pid = int(pid_text)
    except (OSError, ValueError):
        return None
    if pid <= 0 or (pid == os.getpid() and lock not in _held):
        return None
    try:
        os.kill(pid, 0)  # signal 0: only asks whether the process exists
    except ProcessLookupError:
        return None
    except PermissionError:  # it exists, under another user
        pass
    if start and _start_time(pid) not in ("", start):
        return None  # the pid now belongs to another process
    return pid


@contextlib.contextmanager
def hold_output_folder(path: str | Path, option: str = "--out") -> Iterator[Path]:
    """Hold ``path`` (made if need be) for this process while the block runs.

    Raises :class:`OutputFolderBusyError` when another live process holds it. A lock left by a
    process that has ended (killed, crashed) is taken over. The lock file is made whole, then
    linked into place (``os.link`` fails when the name exists), so another run never reads a
    half-written one; on a file system without hard links the folder is not locked.
    """
    folder = Path(path)
    made = not folder.exists()  # made here: removed again if the run leaves nothing in it
    folder.mkdir(parents=True, exist_ok=True)
    lock = folder / LOCK_NAME
    me = os.getpid()
    mine = folder / f"{LOCK_NAME}.{me}"
    mine.write_text(f"{me} {_start_time(me)}\n", encoding="utf-8")
    held = False
    try:
        try:
            os.link(mine, lock)
            held = True
        except FileExistsError:
            holder = _holder(lock)
            if holder is not None:
                raise OutputFolderBusyError(
                    f"{option} {folder}: another poibench run (pid {holder}) is writing in it; "
                    f"wait for it to end or choose another {option}"
                ) from None
            os.replace(mine, lock)  # a stale lock: take it over
            held = True
        except OSError:  # no hard links here: run unlocked, as before
            pass
    finally:
        with contextlib.suppress(OSError):
            mine.unlink()
    if held:
        _held.add(lock)
    try:
        yield folder
    finally:
        if held:
            _held.discard(lock)
            with contextlib.suppress(OSError, ValueError):
                if int(lock.read_text(encoding="utf-8").split()[0]) == me:
                    lock.unlink()
        if made:
            with contextlib.suppress(OSError):  # not empty: the run's outputs stay
                folder.rmdir()
