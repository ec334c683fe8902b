"""Progress bars, made in this one place: shown on a terminal, never written into a log file.

Every command's bar goes to stderr and is off when stderr is no terminal (a CI log, a
redirect, a pipe), whatever ``--quiet`` says; ``--quiet`` turns it off on a terminal too.
A trial used to write about 950 bar updates into a CI log without ``--quiet``.

>>> import io
>>> log = io.StringIO()  # a log file: no terminal
>>> sum(progress_bar(range(3), desc="trial", file=log)), log.getvalue()
(3, '')
"""

from __future__ import annotations

import sys
from collections.abc import Iterable


def progress_bar(iterable: Iterable | None = None, *, quiet: bool = False, file=None, **kwargs):
    """A ``tqdm`` bar over ``iterable`` (or one updated by hand: ``total=``, ``bar.update``) on
    ``file`` (default: stderr as it is at the call), shown only when ``file`` is a terminal and
    ``quiet`` is false. ``kwargs`` go to ``tqdm`` (``total``, ``desc``, ``unit``)."""
    from tqdm import tqdm

    # disable=None: tqdm's own "off unless file.isatty()"
    return tqdm(iterable, disable=True if quiet else None, file=sys.stderr if file is None else file, **kwargs)
