"""A trial's output files: each written in turn, a failed one recorded and the others still written.

A full disk used to end a trial on the first failed write with an errno line that named no
file, losing ``score.json`` and ``map.png`` with it. :class:`TrialOutputs` runs each write,
keeps going past a failure, and :meth:`TrialOutputs.check` ends with one line naming the
file (or files) that could not be written.

Each file is written whole or not at all: to a temporary name beside it, then renamed over
it (:func:`poi.core.atomic_file.atomic_path`). A full disk used to leave 0-byte ``score.json``,
``config.yaml``, ``cost.json`` and ``map.png`` that looked like outputs; now a failed one is
absent, and an older file of that name (an earlier run's) is removed with it. A full disk is named as such,
"no space left on device", even where the first write to fail was the video's (its encoder
dies first, and the trial saw a broken pipe).
"""

from __future__ import annotations

import contextlib
import errno
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from poi.core.atomic_file import atomic_path

NO_SPACE = "no space left on device"
FULL_DISK_FREE_BYTES = 1 << 20  # less free than this after a failed write: the disk was full

# the order the closing "wrote DIR/: ..." line lists them in
OUTPUT_ORDER = (
    "pois.csv",
    "truth.csv",
    "score.json",
    "funnel.csv",
    "cost.json",
    "map.png",
    "trial.mp4",
    "config.yaml",
    "live/",
)


class TrialOutputError(ValueError):
    """An output of the trial could not be written (one line naming the file)."""


@dataclass
class TrialOutputs:
    """The outputs written to ``folder`` so far (names relative to it) and those that failed."""

    folder: Path
    written: list[str] = field(default_factory=list)
    failed: list[tuple[str, OSError]] = field(default_factory=list)

    def write(self, name: str, write: Callable[[Path], object], *, atomic: bool = True) -> bool:
        """Run ``write(path)`` for ``folder / name``; an OSError is recorded for :meth:`check`,
        not raised. True when it was written.

        ``atomic``: ``path`` is a temporary name in the same folder (same suffix, so a plotter
        that goes by it still does), renamed over ``folder / name`` once ``write`` returns; on a
        failure neither it nor an older ``folder / name`` is left. False for a ``write`` that
        makes its own file (the video, ``pois.csv``, ``live/``) and ignores ``path``.
        """
        final = self.folder / name
        try:
            if atomic:
                with atomic_path(final, temp_name=f".{final.stem}.partial{final.suffix}") as path:
                    write(path)
            else:
                write(final)
        except OSError as e:
            if atomic:
                with contextlib.suppress(OSError):
                    final.unlink()
            self.fail(name, e)
            return False
        if name not in self.written:
            self.written.append(name)
        return True

    def fail(self, name: str, error: OSError) -> None:
        """Record that ``name`` could not be written (the first error of each name is kept)."""
        if name in self.written:
            self.written.remove(name)
        if all(n != name for n, _ in self.failed):
            self.failed.append((name, error))

    def names(self) -> list[str]:
        """The written outputs, in :data:`OUTPUT_ORDER` (others after, as written)."""
        rank = {n: i for i, n in enumerate(OUTPUT_ORDER)}
        return sorted(self.written, key=lambda n: rank.get(n, len(rank)))

    def check(self) -> None:
        """Raise :class:`TrialOutputError` naming the first failed file, its reason, the other
        failed ones and what was written all the same; nothing when all were written."""
        if not self.failed:
            return
        full = [f for f in self.failed if f[1].errno == errno.ENOSPC]
        name, e = (full or self.failed)[0]
        others = [n for n, _ in self.failed if n != name]
        reason = e.strerror or (str(e).splitlines() or [type(e).__name__])[0]
        if full or self._disk_full():
            reason = NO_SPACE
        path = self.folder / name
        if name.endswith("/") and isinstance(e.filename, str) and e.filename:
            path = Path(e.filename)  # the file of that folder (live/) that failed
        msg = f"cannot write {path}: {reason}"
        if others:
            msg += f"; nor {', '.join(others)}"
        if self.written:
            msg += f"; written: {' '.join(self.names())}"
        raise TrialOutputError(msg)

    def _disk_full(self) -> bool:
        """Whether the output folder's disk has (almost) no space left."""
        try:
            return shutil.disk_usage(self.folder).free < FULL_DISK_FREE_BYTES
        except OSError:
            return False
