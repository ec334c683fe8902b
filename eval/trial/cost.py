"""What a trial costs: wall seconds and CPU seconds, and both per simulated second.

Wall time is noisy on a shared machine; CPU time much less so, which is why a trial's
CPU seconds per simulated second is what a trial's ``cost.json``, ``poibench run`` and the
sweep table report beside the wall time.

``cpu_s`` counts the trial's own process, every thread of it (``time.process_time``:
the ONNX runtime's intra-op threads included), plus the child processes it reaped while
it ran (``os.times``): the ffmpeg encoders of ``trial.mp4`` and of the live record,
which exit when their file is closed. ``cpu_children_s`` is that children's share.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass


def _children_cpu_s() -> float:
    t = os.times()
    return t.children_user + t.children_system


@dataclass(frozen=True)
class TrialCost:
    """Seconds a trial took (wall and CPU) for ``sim_s`` simulated seconds."""

    wall_s: float
    cpu_s: float  # the process (all threads) plus its reaped children
    cpu_children_s: float
    sim_s: float

    @property
    def cpu_s_per_sim_s(self) -> float:
        return self.cpu_s / self.sim_s if self.sim_s > 0 else float("nan")

    @property
    def real_time_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else float("inf")

    def to_dict(self) -> dict[str, float | None]:
        """A trial's ``cost.json`` (rounded: seconds to the millisecond). A ratio that is not
        defined (a one-frame trial simulates 0 s) is null: JSON has no NaN or infinity.

        >>> TrialCost(wall_s=2.0, cpu_s=3.0, cpu_children_s=0.0, sim_s=0.0).to_dict()["cpu_s_per_sim_s"] is None
        True
        """
        return {
            "wall_s": round(self.wall_s, 3),
            "cpu_s": round(self.cpu_s, 3),
            "cpu_children_s": round(self.cpu_children_s, 3),
            "cpu_s_per_sim_s": _finite(self.cpu_s_per_sim_s, 4),
            "real_time_factor": _finite(self.real_time_factor, 3),
        }


def _finite(value: float, digits: int) -> float | None:
    """``value`` rounded, or None when it is NaN or infinite."""
    return round(value, digits) if math.isfinite(value) else None


@dataclass(frozen=True)
class CostClock:
    """Started when a trial starts; ``read`` gives what it has cost since."""

    wall0: float
    cpu0: float
    children0: float

    @classmethod
    def start(cls) -> CostClock:
        return cls(wall0=time.perf_counter(), cpu0=time.process_time(), children0=_children_cpu_s())

    def read(self, sim_s: float) -> TrialCost:
        children = _children_cpu_s() - self.children0
        return TrialCost(
            wall_s=time.perf_counter() - self.wall0,
            cpu_s=time.process_time() - self.cpu0 + children,
            cpu_children_s=children,
            sim_s=sim_s,
        )
