"""The pipeline's POI report: confirmed tracks streamed into the competition POI file.

The format (docs/RULES.md, "The POI file", version 1.2, or 1.3 with ``version="1.3"``:
records, layout, the atomic writer) is :mod:`poi.core.poi_file`'s; this module turns tracks into its rows and
streams them. The header is written on open and each confirmed object is appended
and flushed to disk (fsync) at once, so a killed run leaves a valid file of what it
had; an object the tracker withdraws (its step 6: a read target settled its place) is taken
out of the file at once (:meth:`PoiWriter.withdraw`, an atomic rewrite of the rows streamed so
far), so a killed run's file never holds a report the pipeline took back;
:meth:`PoiWriter.finalize` rewrites the file with the final positions atomically
(:func:`poi.core.poi_file.write_text_atomic`).

>>> from datetime import datetime
>>> time_hms(datetime(2022, 7, 8, 9, 19, 11), 3.7)
'09:19:14'
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import TextIO

from poi.core.names import TYPES
from poi.core.poi_file import (
    MODES,
    POI_VERSION,
    POI_VERSIONS,
    PoiHeader,
    PoiRow,
    format_header_text,
    format_poi_text,
    format_row_text,
    write_text_atomic,
)
from poi.core.types import TrackSnapshot


class ReportError(ValueError):
    """A value that cannot be written into the POI file."""


@dataclass(frozen=True, kw_only=True)
class ReportHeader:
    """Header values; ``start`` is the mission's start (date and time lines, and the row times);
    ``version`` the POI file version written (1.2 or 1.3, docs/RULES.md "Version 1.3")."""

    team: str
    country: str
    mission: str
    start: datetime
    version: str = POI_VERSION

    def poi_header(self) -> PoiHeader:
        """The file's header record: the date and time lines are the start's."""
        return PoiHeader(
            version=self.version,
            team=self.team,
            country=self.country,
            date=self.start.strftime("%Y-%m-%d"),
            start_time=self.start.strftime("%H:%M:%S"),
            mission=self.mission,
        )


def time_hms(start: datetime, t_s: float) -> str:
    """Wall-clock HH:MM:SS of mission time ``t_s`` seconds (truncated to whole seconds)."""
    return (start + timedelta(seconds=float(t_s))).strftime("%H:%M:%S")


class PoiWriter:
    """Writes a POI file incrementally; see the module docstring."""

    def __init__(
        self, path: str | Path, header: ReportHeader, *, robot: str = "poibench", mode: str = "A"
    ) -> None:
        if header.version not in POI_VERSIONS:
            raise ReportError(f"POI version: expected one of {', '.join(POI_VERSIONS)}, got {header.version!r}")
        if mode not in MODES:
            raise ReportError(f"mode: expected {', '.join(MODES[:-1])} or {MODES[-1]}, got {mode!r}")
        self.path = Path(path)
        self.header = header
        self.robot = robot
        self.mode = mode
        self._fh: TextIO | None = open(self.path, "w", encoding="utf-8", newline="")  # noqa: SIM115 (kept open)
        self._streamed: dict[int, PoiRow] = {}  # track id -> its row as appended, in the file's order
        self._write(format_header_text(header.poi_header()))

    def _write(self, text: str) -> None:
        if self._fh is None:
            raise ReportError(f"{self.path}: already finalized")
        self._fh.write(text)
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def _row(self, track: TrackSnapshot, time: str | None) -> PoiRow:
        """The file's row of a confirmed track; its time defaults to start + first_seen_s."""
        if track.report_id is None:
            raise ReportError(f"track {track.track_id}: has no report id (not confirmed)")
        if track.type not in TYPES:
            raise ReportError(f"type {track.type!r}: expected a canonical type, one of {', '.join(TYPES)}")
        x, y, z = (float(c) for c in track.position_map)
        return PoiRow(
            line=0,
            id=int(track.report_id),
            time=time if time is not None else time_hms(self.header.start, track.first_seen_s),
            text=track.text,
            x=x,
            y=y,
            z=z,
            robot=self.robot,
            mode=self.mode,
            type=track.type,
        )

    def append(self, track: TrackSnapshot, time_hms: str | None = None) -> None:
        """Append one confirmed object, flushed to disk; time defaults to start + first_seen_s."""
        if self._fh is None:
            raise ReportError(f"{self.path}: already finalized")
        row = self._row(track, time_hms)
        self._write(format_row_text(row, self.header.version) + "\n")
        self._streamed[track.track_id] = row

    def withdraw(self, track_id: int) -> bool:
        """Take track ``track_id``'s streamed row out of the file: the rows appended so far, less
        it, rewritten atomically and the file reopened for appending. False (nothing written) when
        it was never appended."""
        if self._fh is None:
            raise ReportError(f"{self.path}: already finalized")
        if self._streamed.pop(track_id, None) is None:
            return False
        self.close()
        write_text_atomic(self.path, format_poi_text(self.header.poi_header(), list(self._streamed.values())))
        self._fh = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115 (kept open)
        return True

    def text(self, tracks: Iterable[TrackSnapshot]) -> str:
        """The file :meth:`finalize` would write for these objects (by report id)."""
        ordered = sorted((t for t in tracks), key=lambda t: t.report_id if t.report_id is not None else -1)
        return format_poi_text(self.header.poi_header(), [self._row(t, None) for t in ordered])

    def finalize(self, tracks: Iterable[TrackSnapshot]) -> None:
        """Rewrite the whole file with these objects (by report id), atomically."""
        text = self.text(tracks)
        self.close()
        write_text_atomic(self.path, text)

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> PoiWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
