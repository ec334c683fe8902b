"""The scenario's ground truth as a POI file (mode ``GT``), in the map frame."""

from __future__ import annotations

from pathlib import Path

from poi.core.poi_file import PoiFile, PoiHeader, PoiRow, read_poi_file, write_poi_file

GT_ROBOT = "sim"
GT_DATE = "2000-01-01"
GT_START = "00:00:00"


def truth_rows(sim) -> list[PoiRow]:
    """One row per object of a ``sim.simulator.Simulation``, ids as placed."""
    rows = []
    for o in sim.truth_objects():
        x, y, z = (float(v) for v in o.position_map)
        rows.append(
            PoiRow(
                line=0,
                id=o.id,
                time=GT_START,
                text=o.text,
                x=x,
                y=y,
                z=z,
                robot=GT_ROBOT,
                mode="GT",
                type=o.type,
            )
        )
    return rows


def write_truth_csv(path: str | Path, rows: list[PoiRow], mission: str) -> None:
    """Write ``truth.csv``; the date and time are fixed so the file depends only on the scenario."""
    header = PoiHeader(team="poibench", country="sim", date=GT_DATE, start_time=GT_START, mission=mission)
    write_poi_file(path, header, rows)


class TruthFileError(ValueError):
    """A file given as ground truth that is not one (one line naming the file and line)."""


def read_truth_file(path: str | Path) -> PoiFile:
    """A ground-truth POI file (``truth.csv``, or one written by hand for a real arena): every row
    of mode ``GT`` and at least one. A report given in its place (rows of mode A or T, a trial's
    ``pois.csv``) or an empty file would score anything as nothing, so it is refused."""
    truth = read_poi_file(path)
    other = next((r for r in truth.rows if r.mode != "GT"), None)
    if other is not None:
        raise TruthFileError(
            f"{path}: line {other.line}: mode {other.mode!r}; expected GT (a truth.csv, not a report: "
            "swapped with the report?)"
        )
    if not truth.rows:
        raise TruthFileError(f"{path}: no objects; expected the ground truth (a truth.csv)")
    return truth
