"""sim/memory.py: freed image buffers stay in the process (glibc's malloc thresholds)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

from sim.memory import keep_freed_memory

GLIBC = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"

# A frame's worth of images allocated, written and freed, 20 times; prints the page faults of
# the last 15 (the first 5 grow the heap). Sizes as the depth model's: (646, 486) noise, (480,
# 640) float32 and bool masks, a (480, 640, 3) float32 colour signal.
FRAMES = """
import resource, sys
import numpy as np
if sys.argv[1] == "keep":
    from sim.memory import keep_freed_memory
    assert keep_freed_memory()
def frame():
    a = [np.ones((486, 646), np.float32) for _ in range(3)] + [np.ones((480, 640), np.float32) for _ in range(6)]
    a += [np.ones((480, 640), bool) for _ in range(4)] + [np.ones((480, 640, 3), np.float32)]
    del a[::2]
    a.append(np.ones((480, 640), np.float32))
    return sum(float(x[0, 0].sum()) for x in a)
for _ in range(5):
    frame()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(15):
    frame()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", FRAMES, mode], capture_output=True, text=True, check=True)
    return int(out.stdout)


@pytest.mark.skipif(not GLIBC, reason="mallopt(3) is glibc's")
def test_frames_of_freed_images_fault_no_pages_in_once_kept():
    assert keep_freed_memory() and keep_freed_memory()  # set once, idempotent
    kept, default = _faults("keep"), _faults("default")
    # 15 frames of about 5 000 pages: with glibc's defaults most of them fault in again each
    # frame; kept, next to none do (a few for the interpreter's own allocations)
    assert kept < 300 and default > 20 * kept + 5000, (kept, default)
