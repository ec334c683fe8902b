"""Words for counts in what the commands print: "1 false report", "3 misses"."""

from __future__ import annotations


def counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and the noun in the number it takes.

    >>> counted(1, "false report"), counted(3, "miss", "misses"), counted(0, "frame")
    ('1 false report', '3 misses', '0 frames')
    """
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"
