"""One shard of a suite, sweep or regress run: every N-th trial, for independent batch jobs.

``--shard I/N`` (0-based, ``0 <= I < N``, as Slurm's ``SLURM_ARRAY_TASK_ID`` and Kubernetes'
``JOB_COMPLETION_INDEX`` count) keeps the trials whose index k in the run's fixed task order
(settings outer, scenarios inner: :func:`eval.experiments.sweep.make_tasks`) has
``k % N == I``. Each shard writes a folder of its own; ``poibench suite merge``
(:mod:`eval.experiments.merge`) joins them into the folder a single run writes.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")
_SHARD = re.compile(r"^\s*(\d+)\s*/\s*(\d+)\s*$")


class ShardError(ValueError):
    """A ``--shard`` that names no shard (one line)."""


@dataclass(frozen=True, kw_only=True)
class Shard:
    """Shard ``index`` of ``count`` (0-based): the trials k with ``k % count == index``."""

    index: int
    count: int

    def __post_init__(self) -> None:
        if self.count < 1 or not 0 <= self.index < self.count:
            raise ShardError(
                f"--shard {self.index}/{self.count}: expected I/N with N >= 1 and 0 <= I < N (0-based, as "
                "SLURM_ARRAY_TASK_ID and JOB_COMPLETION_INDEX count)"
            )

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"

    def takes(self, k: int) -> bool:
        """Whether trial index ``k`` (0-based, in the run's task order) is this shard's.

        >>> [k for k in range(7) if Shard(index=1, count=3).takes(k)]
        [1, 4]
        """
        return k % self.count == self.index

    def select(self, items: Sequence[T]) -> list[T]:
        """This shard's items of the run's full, ordered list."""
        return [x for k, x in enumerate(items) if self.takes(k)]

    def to_dict(self) -> dict[str, int]:
        return {"index": self.index, "count": self.count}


def parse_shard(text: str) -> Shard:
    """``I/N`` as a :class:`Shard`.

    >>> parse_shard("0/4")
    Shard(index=0, count=4)
    >>> parse_shard("4/4")  # doctest: +IGNORE_EXCEPTION_DETAIL
    Traceback (most recent call last):
    eval.experiments.shard.ShardError: --shard 4/4: expected I/N with N >= 1 and 0 <= I < N ...
    """
    m = _SHARD.match(text)
    if m is None:
        raise ShardError(f"--shard {text}: expected I/N, two whole numbers (0 <= I < N), e.g. 0/4")
    return Shard(index=int(m[1]), count=int(m[2]))
