"""Replacing a file whole or not at all: the one place poibench's atomic writes are made.

:func:`atomic_path` hands the writer a temporary name in the target's folder and renames it
over the target (``os.replace``) once the writer is done, so a reader, a resumed run or a
crash sees the old file or the whole new one, never a part; a failure removes the temporary
file and leaves the old one as it was.

>>> import tempfile
>>> target = Path(tempfile.mkdtemp()) / "a.txt"
>>> with atomic_path(target) as tmp:
...     _ = tmp.write_text("whole\\n")
>>> target.read_text(), [p.name for p in target.parent.iterdir()]
('whole\\n', ['a.txt'])
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path: str | Path, *, temp_name: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` for the block to write; on success it is synced
    to disk (``fsync``) and renamed over ``path``.

    Guarantees: ``path`` is always either its old file (or absent, if there was none) or the
    whole new one; when the block (or the sync or the rename) raises, anything at all, the
    temporary file is removed, ``path`` is untouched and the exception goes on.

    The block creates the file itself (``open``, ``Path.write_text``, a library's ``save``), so
    it gets the mode of any new file, 0666 less the umask (``tempfile.mkstemp`` would make it
    0600, and the rename would keep that). ``temp_name``: the temporary file's name in the
    folder; by default ``.NAME.RANDOM.tmp``, hidden and unique, so that writers of the same
    target never share one.
    """
    path = Path(path)
    tmp = path.with_name(temp_name or f".{path.name}.{secrets.token_hex(8)}.tmp")
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
