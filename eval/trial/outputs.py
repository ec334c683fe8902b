"""A trial's output files: each written in turn, a failed one recorded and the others still written.

A full disk used to end a trial on the first failed write with an errno line that named no
file, losing ``score.json`` and ``map.png`` with it. :class:`TrialOutputs` runs each write,
keeps going past a failure, and :meth:`TrialOutputs.check` ends with one line naming the
file (or files) that could not be written.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

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

    def write(self, name: str, write: Callable[[Path], object]) -> bool:
        """Run ``write(folder / name)``; an OSError is recorded for :meth:`check`, not raised.
        True when it was written."""
        try:
            write(self.folder / name)
        except OSError as e:
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
        name, e = self.failed[0]
        reason = e.strerror or (str(e).splitlines() or [type(e).__name__])[0]
        path = self.folder / name
        if name.endswith("/") and isinstance(e.filename, str) and e.filename:
            path = Path(e.filename)  # the file of that folder (live/) that failed
        msg = f"cannot write {path}: {reason}"
        if len(self.failed) > 1:
            msg += f"; nor {', '.join(n for n, _ in self.failed[1:])}"
        if self.written:
            msg += f"; written: {' '.join(self.names())}"
        raise TrialOutputError(msg)
