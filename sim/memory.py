"""Freed image buffers kept in the process for the next frame, not handed back to the kernel.

Each frame allocates a few dozen arrays of 0.3-3.7 MB (renders, the sensor models'
intermediates, the detector's input) and frees them before the next. glibc's malloc
serves a block above its mmap threshold (128 KiB at start) with a new ``mmap`` and unmaps
it on ``free``, and gives the top of a heap back once more than ``M_TRIM_THRESHOLD`` of it
is free ([GlibcMallopt]_); every page of a new mapping then faults on its first write.
On the 2-core machine the D435 depth model alone took 3432 page faults and 7-9 ms of
system CPU a frame that way (17-19 ms in all), and none with 10.0 ms in all once the
thresholds below keep the memory in the process; over the first 150 frames of a default
trial, the process's system CPU fell from 6.1 to 2.1 ms a frame (issue 62). glibc's own remedy, raising
the mmap threshold after such a free (and the trim threshold to twice it), did not stop
it: measured in one thread, the heap's top was still trimmed once a frame's arrays were
freed, and its pages faulted in again.

:func:`keep_freed_memory` sets ``M_MMAP_THRESHOLD`` to 32 MiB (glibc's largest on 64-bit
systems: every image here stays in the heaps) and ``M_TRIM_THRESHOLD`` to 1 GiB, once per
process, through ``mallopt(3)``. The process then keeps its peak heap (a trial's is a few
hundred MB) until it exits. Elsewhere than glibc it does nothing.

References
----------
Full entries in docs/SOURCES.md.

.. [GlibcMallopt] The GNU C Library, ``mallopt(3)`` (M_MMAP_THRESHOLD, M_TRIM_THRESHOLD) and
   "Memory Allocation Tunables" in its manual.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import platform

M_TRIM_THRESHOLD = -1  # glibc's malloc.h
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 32 * 2**20  # DEFAULT_MMAP_THRESHOLD_MAX on 64-bit: the largest mallopt takes
TRIM_THRESHOLD_BYTES = 2**30

_applied: bool | None = None


def keep_freed_memory() -> bool:
    """Set glibc's malloc to keep freed blocks up to 32 MiB in the process (module docstring);
    True when it is set (now or before), False where the C library is not glibc."""
    global _applied
    if _applied is not None:
        return _applied
    _applied = False
    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        name = ctypes.util.find_library("c")
        if name is not None:
            libc = ctypes.CDLL(name)
            ok_mmap = libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
            ok_trim = libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
            _applied = bool(ok_mmap and ok_trim)  # mallopt returns 1 on success
    return _applied
