"""Words and figures as the commands print them: "1 false report", "3 misses", "+4.2 (+1.0 to +7.5)"."""

from __future__ import annotations


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and the noun in the number it takes.

    >>> counted(1, "false report"), counted(3, "miss", "misses"), counted(0, "frame")
    ('1 false report', '3 misses', '0 frames')
    """
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


def signed_interval(value: float, lo: float, hi: float) -> str:
    """A signed figure with its interval, to one decimal (points of a gap).

    >>> signed_interval(-24.53, -31.2, -17.4)
    '-24.5 (-31.2 to -17.4)'
    """
    return f"{value:+.1f} ({lo:+.1f} to {hi:+.1f})"
