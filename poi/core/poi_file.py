"""The competition POI file (versions 1.2 and 1.3): its records, a tolerant reader and an exact writer.

Implements docs/RULES.md "The POI file". The header is one value a line (``pois``,
``1.2``, team, country, date, start time, mission), then the column line
``id,time,text,x,y,z,robot,mode,type`` and one row per reported object.

Version 1.3 (docs/RULES.md "Version 1.3", Hector's 2025 writer as issue 22 describes it)
has the same header with ``1.3`` (its mission line is ``mission <counter>``) and rows
``id,time,x,y,z,robot,mode`` with no column line and no type; poibench also reads a
type column and a text column after them (``...,mode,type,text``, the text cell optional),
or a column line naming any of ``id,time,x,y,z,robot,mode,type,text`` (all but ``type``
and ``text`` required). A file without a type column has ``typed`` False and its rows
``type`` None: the scorer pairs them by location only.

What the reader accepts, because real teams write it:

- header values quoted or bare, with or without blank lines (or spreadsheet
  padding such as ``pois,,,,``) before the column line;
- CRLF or LF line ends, a UTF-8 byte order mark, spaces around any value;
  a file that is not UTF-8 is read as Latin-1, with a warning;
- the columns in any order (named by the column line), trailing empty cells;
- columns the format does not have (``confidence``, ``notes``): their cells are kept
  aside in each row's ``extra``, not scored, with a warning naming the column and file;
- type and hazmat label spellings with the aliases of :mod:`poi.core.names`.

Choices the rules leave open, made here:

- Every cell is stripped of surrounding spaces. For ``qr`` rows the text is
  otherwise kept exactly (case, inner spaces, punctuation): a CSV cannot tell
  padding from a code's leading or trailing space, and codes do not use them.
- A ``hazmat`` row's text is normalised to the canonical label; an unknown label
  keeps its raw text (a warning), and the scorer pairs it with nothing.
- Other types keep their text as written; the scorer ignores it.
- A row that cannot be read (wrong column count, an id that is not an integer, a
  coordinate that is not a finite number, an unknown type) becomes a
  :class:`Problem` with its line number and reason, and the scorer counts it as a
  false report. Its ``type`` is the canonical type when the type cell could be
  read (for a row with the wrong column count, the last cell when the type
  column is last), so the penalty is that type's points; when the type cannot be
  read, the penalty is 0 but the problem is still listed.
- Quoted values with embedded line breaks are not supported (each physical line
  is one record), so every problem's line number is the line an editor shows.

A file that cannot be read at all (missing, empty, first line not ``pois``, no
column line) raises :class:`PoiFileError` with a one-line ``FILE: reason`` message.

What the writer writes (docs/RULES.md "What the writer writes"): bare values, LF line ends,
coordinates with 3 decimals (never ``-0.000``), the canonical type name; a value
holding a comma, a quote or edge spaces is quoted (a quote doubled), and line breaks
inside a value become spaces (the format has one record a line). A whole file is
written atomically (:func:`write_text_atomic`); the pipeline's streaming writer
(:class:`poi.report.PoiWriter`) appends rows formatted here.

>>> text = "pois\\n1.2\\nCUR\\nEngland\\n2022-07-08\\n09:19:11\\nPrelim1\\n"
>>> text += "id,time,text,x,y,z,robot,mode,type\\n"
>>> text += "0,09:19:14,Chart M,0.548,-0.392,1.241,Arbie,T,QRCode\\n"
>>> f = parse_poi_text(text, source="example.csv")
>>> f.header.team, f.rows[0].type, f.rows[0].text, f.rows[0].line, f.problems
('CUR', 'qr', 'Chart M', 9, [])
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from poi.core.atomic_file import atomic_path
from poi.core.names import HAZMAT_LABELS, TYPES, canonical_label, canonical_type

POI_MAGIC = "pois"
POI_VERSION = "1.2"
POI_VERSIONS: tuple[str, ...] = ("1.2", "1.3")
COLUMNS: tuple[str, ...] = ("id", "time", "text", "x", "y", "z", "robot", "mode", "type")
# Version 1.3's rows: Hector's seven columns, then poibench's optional type and text.
COLUMNS_13: tuple[str, ...] = ("id", "time", "x", "y", "z", "robot", "mode")
COLUMNS_13_TYPED: tuple[str, ...] = (*COLUMNS_13, "type", "text")
HEADER_FIELDS: tuple[str, ...] = ("version", "team", "country", "date", "start_time", "mission")
MODES: tuple[str, ...] = ("T", "A", "GT")
COORD_DECIMALS = 3

_DATE_RE = re.compile(r"^\d{4}-\d{2}-\d{2}$")
_TIME_RE = re.compile(r"^\d{1,2}:\d{2}:\d{2}$")


class PoiFileError(ValueError):
    """A POI file that cannot be read at all; the message is ``FILE: reason``."""


@dataclass(kw_only=True)
class PoiHeader:
    """The seven header lines after ``pois``: version, team, country, date, time, mission."""

    version: str = POI_VERSION
    team: str = ""
    country: str = ""
    date: str = ""
    start_time: str = ""
    mission: str = ""


@dataclass(kw_only=True)
class PoiRow:
    """One reported (or ground-truth) object; ``type`` is canonical (None in a 1.3 file
    without a type column), ``line`` 1-based."""

    line: int
    id: int
    time: str
    text: str
    x: float
    y: float
    z: float
    robot: str
    mode: str
    type: str | None
    # cells of columns the format does not have (``confidence``, ``notes``), by column name: kept, not scored
    extra: dict[str, str] = field(default_factory=dict, compare=False, repr=False)


@dataclass(kw_only=True)
class Problem:
    """A line the reader could not use (or, in ``warnings``, something odd it accepted).

    ``type`` is the canonical type of an unreadable row when its type cell could be
    read (the scorer's penalty), else None; ``line`` 0 means the whole file.
    """

    line: int
    message: str
    type: str | None = None
    id: str = ""


@dataclass(kw_only=True)
class PoiFile:
    """A read POI file: rows that scored, problems (unreadable rows), warnings; ``typed``
    False for a version 1.3 file without a type column (its rows' ``type`` is None)."""

    header: PoiHeader
    rows: list[PoiRow]
    problems: list[Problem] = field(default_factory=list)
    warnings: list[Problem] = field(default_factory=list)
    source: str = ""
    typed: bool = True


def read_poi_file(path: str | Path) -> PoiFile:
    """Read a POI file (report or ground truth); see the module docstring for what it accepts."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError as exc:
        raise PoiFileError(f"{path}: no such file") from exc
    except OSError as exc:
        raise PoiFileError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    warnings: list[Problem] = []
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
        warnings.append(Problem(line=0, message="not UTF-8; read as Latin-1"))
    result = parse_poi_text(text, source=str(path))
    result.warnings[:0] = warnings
    return result


def parse_poi_text(text: str, *, source: str = "<text>") -> PoiFile:
    """Parse the text of a POI file; ``source`` names it in messages."""
    text = text.removeprefix("\ufeff")
    lines = text.splitlines()
    warnings: list[Problem] = []
    _check_magic(lines, source)
    values, column_index = _header_lines(lines, source)
    header = _make_header(values, warnings)
    column_cells = _cells(lines[column_index])
    if _is_column_line(column_cells):
        layout = _layout(column_cells, column_index + 1, source, header.version)
        for name in dict.fromkeys(n for n in layout if n not in COLUMNS):
            warnings.append(
                Problem(
                    line=column_index + 1,
                    message=f"{source}: column {name!r} is not a POI column ({','.join(COLUMNS)}): "
                    "its cells are kept aside, not scored",
                )
            )
    else:
        layout = _positional_layout_13(lines[column_index + 1 :])
    text_optional = layout == COLUMNS_13_TYPED and not _is_column_line(column_cells)
    col = {name: i for i, name in enumerate(layout)}
    problems: list[Problem] = []
    rows = _rows(lines, column_index, layout, col, text_optional, problems, warnings)
    return PoiFile(
        header=header, rows=rows, problems=problems, warnings=warnings, source=source, typed="type" in col
    )


def _check_magic(lines: list[str], source: str) -> None:
    """Line 1 must be "pois"; else a PoiFileError."""
    first = _header_value(lines[0]) if lines else ""
    if first is None or first.lower() != POI_MAGIC:
        shown = lines[0][:40] if lines else ""
        raise PoiFileError(
            f"{source}: not a POI file: line 1 is {shown!r}, expected {POI_MAGIC!r}"
            if lines
            else f"{source}: not a POI file: it is empty, expected {POI_MAGIC!r} on line 1"
        )


def _header_lines(lines: list[str], source: str) -> tuple[list[str], int]:
    """The header values after line 1 and the index of the column line (for Hector's 1.3, which
    has none, the line before the first row)."""
    values: list[str] = []
    column_index = -1
    for i in range(1, len(lines)):
        cells = _cells(lines[i])
        if _is_column_line(cells):
            column_index = i
            break
        value = _header_value(lines[i])
        if value is None and values and values[0] == "1.3":
            column_index = i - 1  # Hector's 1.3: the rows follow the header, no column line
            break
        if value is None:
            raise PoiFileError(
                f"{source}: line {i + 1}: expected a header value or the column line "
                f"{','.join(COLUMNS)}, got {lines[i][:60]!r}"
            )
        values.append(value)
    if column_index < 0 and values and values[0] == "1.3":
        column_index = len(lines) - 1  # a 1.3 header with no rows
    if column_index < 0:
        raise PoiFileError(f"{source}: no column line {','.join(COLUMNS)} after the header")
    # Blank lines before the column line are allowed; an empty value inside the header
    # keeps its place when the header has exactly its six lines after "pois".
    while values and values[-1] == "":
        values.pop()
    if len(values) != len(HEADER_FIELDS):
        values = [v for v in values if v != ""]
    return values, column_index


def _rows(
    lines: list[str],
    column_index: int,
    layout: tuple[str, ...],
    col: dict[str, int],
    text_optional: bool,
    problems: list[Problem],
    warnings: list[Problem],
) -> list[PoiRow]:
    """The rows after the column line; a row's problems and warnings appended to the lists."""
    rows: list[PoiRow] = []
    seen_ids: dict[int, int] = {}
    for i in range(column_index + 1, len(lines)):
        line_no = i + 1
        cells = _cells(lines[i])
        while cells and cells[-1] == "" and len(cells) > len(layout):
            cells.pop()
        if not any(cells):
            continue
        if text_optional and len(cells) == len(layout) - 1:
            cells.append("")  # a positional 1.3 row may leave out its text cell
        if len(cells) < len(layout) and all(name not in COLUMNS for name in layout[len(cells) :]):
            cells += [""] * (len(layout) - len(cells))  # trailing unknown columns left empty
        row = _parse_row(cells, layout, col, line_no, problems, warnings)
        if row is None:
            continue
        if row.id in seen_ids:
            warnings.append(Problem(line=line_no, message=f"id {row.id} also used on line {seen_ids[row.id]}"))
        else:
            seen_ids[row.id] = line_no
        rows.append(row)
    return rows


def _cells(line: str) -> list[str]:
    """CSV cells of one line, each stripped of surrounding spaces (quotes removed)."""
    try:
        cells = next(csv.reader([line], skipinitialspace=True), [])
    except csv.Error:
        cells = line.split(",")
    return [c.strip() for c in cells]


def _header_value(line: str) -> str | None:
    """The one value of a header line ('' if blank), or None if it holds several."""
    values = [c for c in _cells(line) if c != ""]
    if len(values) > 1:
        return None
    return values[0] if values else ""


def _is_column_line(cells: list[str]) -> bool:
    names = {c.lower() for c in cells if c}
    return {"id", "x", "y"} <= names


def _layout(cells: list[str], line_no: int, source: str, version: str) -> tuple[str, ...]:
    """The column names of a column line, in file order; 1.3 may leave out type and text.
    A column the format does not have is kept in the layout (its cells go to ``PoiRow.extra``);
    a format column named twice is refused."""
    names = [c.lower() for c in cells]
    while names and names[-1] == "":
        names.pop()
    seen: set[str] = set()
    for name in names:
        if name in seen and name in COLUMNS:
            raise PoiFileError(
                f"{source}: line {line_no}: column {name!r} is repeated; expected each of {','.join(COLUMNS)} once"
            )
        seen.add(name)
    required = COLUMNS_13 if version == "1.3" else COLUMNS
    missing = [c for c in required if c not in seen]
    if missing:
        raise PoiFileError(
            f"{source}: line {line_no}: column line lacks {', '.join(missing)}; expected {','.join(required)}"
        )
    return tuple(names)


def _positional_layout_13(lines: list[str]) -> tuple[str, ...]:
    """The columns of a 1.3 file without a column line, from its first row's cell count: 7,
    Hector's ``id,time,x,y,z,robot,mode``; more, with ``type`` and ``text`` (the text cell may be left out)."""
    for line in lines:
        cells = _cells(line)
        while len(cells) > len(COLUMNS_13) and cells[-1] == "":
            cells.pop()
        if any(cells):
            return COLUMNS_13 if len(cells) <= len(COLUMNS_13) else COLUMNS_13_TYPED
    return COLUMNS_13


def _make_header(values: list[str], warnings: list[Problem]) -> PoiHeader:
    n = len(HEADER_FIELDS)
    if len(values) != n:
        warnings.append(
            Problem(
                line=0,
                message=f"header has {len(values)} values after 'pois', expected {n} "
                "(version, team, country, date, start time, mission)",
            )
        )
    padded = (values + [""] * n)[:n]
    header = PoiHeader(**dict(zip(HEADER_FIELDS, padded, strict=True)))
    if header.version not in POI_VERSIONS:
        expected = " or ".join(repr(v) for v in POI_VERSIONS)
        warnings.append(Problem(line=2, message=f"version {header.version!r}, expected {expected}"))
    if header.date and not _DATE_RE.match(header.date):
        warnings.append(Problem(line=0, message=f"date {header.date!r} is not YYYY-MM-DD"))
    if header.start_time and not _TIME_RE.match(header.start_time):
        warnings.append(Problem(line=0, message=f"start time {header.start_time!r} is not HH:MM:SS"))
    return header


def _parse_row(
    cells: list[str],
    layout: tuple[str, ...],
    col: dict[str, int],
    line_no: int,
    problems: list[Problem],
    warnings: list[Problem],
) -> PoiRow | None:
    n = len(layout)
    typed = "type" in col
    if len(cells) != n:
        # The type cell's position is unsure; when the type column is last, use the last cell.
        type_guess = canonical_type(cells[-1]) if typed and col["type"] == n - 1 and cells else None
        problems.append(
            Problem(
                line=line_no,
                message=f"expected {n} columns ({','.join(layout)}), got {len(cells)}",
                type=type_guess,
                id=cells[col["id"]] if len(cells) > col["id"] else "",
            )
        )
        return None
    get = {name: cells[index] for name, index in col.items()}
    extra = {name: value for name, value in get.items() if name not in COLUMNS}
    get.setdefault("text", "")
    reasons: list[str] = []
    type_ = canonical_type(get["type"]) if typed and get["type"] else None
    if typed and type_ is None:
        reasons.append(f"unknown type {get['type']!r}; expected one of {', '.join(TYPES)} or an alias")
    try:
        id_ = int(get["id"])
    except ValueError:
        id_ = -1
        reasons.append(f"id {get['id']!r} is not an integer")
    xyz: list[float] = []
    for axis in ("x", "y", "z"):
        try:
            value = float(get[axis])
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            reasons.append(f"{axis} {get[axis]!r} is not a finite number")
        xyz.append(value)
    if reasons:
        problems.append(Problem(line=line_no, message="; ".join(reasons), type=type_, id=get["id"]))
        return None

    text = get["text"]
    if type_ == "hazmat":
        label = canonical_label(text) if text else None
        if label is None:
            warnings.append(
                Problem(
                    line=line_no,
                    message=f"unknown hazmat label {text!r}: kept as written, it matches no "
                    f"object; expected one of {', '.join(HAZMAT_LABELS)} or an alias",
                )
            )
        else:
            text = label
    elif type_ == "qr" and not text:
        warnings.append(Problem(line=line_no, message="QR code with empty text"))
    mode = get["mode"].upper()
    if mode not in MODES:
        warnings.append(Problem(line=line_no, message=f"mode {get['mode']!r}, expected {', '.join(MODES)}"))
    if get["time"] and not _TIME_RE.match(get["time"]):
        warnings.append(Problem(line=line_no, message=f"time {get['time']!r} is not HH:MM:SS"))
    return PoiRow(
        line=line_no,
        id=id_,
        time=get["time"],
        text=text,
        x=xyz[0],
        y=xyz[1],
        z=xyz[2],
        robot=get["robot"],
        mode=mode,
        type=type_,
        extra=extra,
    )


def csv_cell(value: str) -> str:
    """One CSV value of a POI file: quoted only when it holds a comma, a quote or edge spaces
    (line breaks become spaces).

    >>> csv_cell("Chart M"), csv_cell('Chart "N", 2'), csv_cell("two\\nlines")
    ('Chart M', '"Chart ""N"", 2"', 'two lines')
    """
    value = value.replace("\r\n", " ").replace("\r", " ").replace("\n", " ")
    if any(ch in value for ch in ',"') or value != value.strip():
        return '"' + value.replace('"', '""') + '"'
    return value


def format_coord(value: float) -> str:
    """A coordinate with three decimals, never \"-0.000\" (docs/RULES.md "What the writer writes").

    >>> format_coord(1.2414), format_coord(-0.0004)
    ('1.241', '0.000')
    """
    text = f"{value:.{COORD_DECIMALS}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text  # no "-0.000"


def format_header_text(header: PoiHeader) -> str:
    """``pois``, the six header values and, for version 1.2, the column line, each LF-terminated
    (1.3 has no column line: its rows follow the header, docs/RULES.md "Version 1.3")."""
    values = (POI_MAGIC, *(getattr(header, f) for f in HEADER_FIELDS))
    text = "".join(csv_cell(v) + "\n" for v in values)
    return text if header.version == "1.3" else text + ",".join(COLUMNS) + "\n"


def format_row_text(r: PoiRow, version: str = POI_VERSION) -> str:
    """One data row of ``version``'s layout, without the line end (``line`` is not written).
    Version 1.3 is written with its type and text columns: ``id,time,x,y,z,robot,mode,type,text``.

    >>> r = PoiRow(line=0, id=0, time="09:19:14", text="Chart M", x=0.548, y=-0.392,
    ...            z=1.2414, robot="Arbie", mode="T", type="qr")
    >>> format_row_text(r), format_row_text(r, "1.3")
    ('0,09:19:14,Chart M,0.548,-0.392,1.241,Arbie,T,qr', '0,09:19:14,0.548,-0.392,1.241,Arbie,T,qr,Chart M')
    """
    if version not in POI_VERSIONS:
        raise ValueError(f"POI version {version!r}: expected one of {', '.join(POI_VERSIONS)}")
    coords = [format_coord(v) for v in (r.x, r.y, r.z)]
    type_ = r.type or ""
    if version == "1.3":
        values = [str(r.id), r.time, *coords, r.robot, r.mode, type_, r.text]
    else:
        values = [str(r.id), r.time, r.text, *coords, r.robot, r.mode, type_]
    return ",".join(csv_cell(v) for v in values)


def format_poi_text(header: PoiHeader, rows: list[PoiRow]) -> str:
    """The exact layout of docs/RULES.md "What the writer writes": bare values, LF, coordinates with 3 decimals.

    >>> h = PoiHeader(team="T", country="C", date="2025-01-02", start_time="10:00:00", mission="M")
    >>> r = PoiRow(line=0, id=1, time="10:00:05", text="", x=1.23456, y=-0.0001, z=0.0,
    ...            robot="sim", mode="GT", type="door")
    >>> print(format_poi_text(h, [r]), end="")
    pois
    1.2
    T
    C
    2025-01-02
    10:00:00
    M
    id,time,text,x,y,z,robot,mode,type
    1,10:00:05,,1.235,0.000,0.000,sim,GT,door
    """
    return format_header_text(header) + "".join(format_row_text(r, header.version) + "\n" for r in rows)


def write_poi_file(path: str | Path, header: PoiHeader, rows: list[PoiRow]) -> None:
    """Write a POI file atomically (:func:`write_text_atomic`) in the exact layout."""
    write_text_atomic(path, format_poi_text(header, rows))


def write_text_atomic(path: str | Path, text: str) -> None:
    """Replace ``path`` with ``text`` (UTF-8, line ends as given) so that a reader sees the old
    file or the new one, never a part (:func:`poi.core.atomic_file.atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "x", encoding="utf-8", newline="") as fh:
        fh.write(text)
