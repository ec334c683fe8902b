"""Tables as the commands print them: one format a column, empty columns left out.

``poibench suite run`` printed pandas' own rendering: 0.900000 beside 0.0097 and an
``error`` column with nothing in it. :func:`format_table` gives every value of a column the
same format (decimals chosen by the column's unit), prints a missing value as ``-`` and
leaves out a column that has no value in any row.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

MISSING = "-"


def _missing(v: object) -> bool:
    return v is None or (isinstance(v, str) and v.strip() == "") or (isinstance(v, float) and math.isnan(v))


def format_value(v: object, spec: str) -> str:
    """One value in a column's format: ``s`` text, ``d`` a whole number, ``g`` or ``.Nf`` a number.

    >>> format_value(0.9, ".3f"), format_value(0.0097, ".3f"), format_value(3.0, "d"), format_value(12.5, "g")
    ('0.900', '0.010', '3', '12.5')
    >>> format_value(float("nan"), ".3f"), format_value("", "s")
    ('-', '-')
    """
    if _missing(v):
        return MISSING
    if spec == "s":
        return str(v)
    if spec == "d":
        return str(int(round(float(v))))
    return format(float(v), spec)


def format_table(df, formats: Mapping[str, str], headers: Mapping[str, str] | None = None) -> str:
    """The columns of ``df`` named in ``formats`` (in its order; a format spec each, as
    :func:`format_value` takes), under ``headers`` (default: the column names); a column
    missing from ``df`` or with no value in any row is left out. Numbers right-aligned, text
    left-aligned.

    >>> import pandas as pd
    >>> df = pd.DataFrame({"maze": ["a", "b"], "fraction": [0.9, 0.25], "error": ["", ""]})
    >>> print(format_table(df, {"maze": "s", "fraction": ".3f", "error": "s"}))
    maze  fraction
    a        0.900
    b        0.250
    """
    headers = headers or {}
    cols = [c for c in formats if c in df and not all(_missing(v) for v in df[c].tolist())]
    body = [[format_value(v, formats[c]) for v in df[c].tolist()] for c in cols]  # per column
    names = [headers.get(c, c) for c in cols]
    widths = [max([len(n), *(len(v) for v in vals)]) for n, vals in zip(names, body, strict=True)]
    right = [formats[c] != "s" for c in cols]

    def line(cells: list[str]) -> str:
        return "  ".join(
            c.rjust(w) if r else c.ljust(w) for c, w, r in zip(cells, widths, right, strict=True)
        ).rstrip()

    rows = [line(names)] + [line([vals[i] for vals in body]) for i in range(len(df))]
    return "\n".join(rows)


def interval_text(lo: float, hi: float, spec: str = ".3f") -> str:
    """``[lo, hi]`` in ``spec``, or ``-`` when there is no interval (one value).

    >>> interval_text(0.25, 0.5), interval_text(float("nan"), float("nan"))
    ('[0.250, 0.500]', '-')
    """
    if _missing(lo) or _missing(hi):
        return MISSING
    return f"[{format(lo, spec)}, {format(hi, spec)}]"
