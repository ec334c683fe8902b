"""Argument types the commands share: each refuses a value out of range at parsing, so the
command ends with one line, ``poibench <command>: error: argument --port: ...``, and exit
status 2, before anything starts (argparse's own handling of ``ArgumentTypeError``).

>>> port("8080"), positive_int("3")
(8080, 3)
>>> port("99999")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: expected a port from 0 to 65535 (0: a free one), got 99999
"""

from __future__ import annotations

import argparse

from eval.scoring.rules import PRESETS

MAX_PORT = 65535
RULES_HELP = f"a scoring preset ({', '.join(PRESETS)}) or a rules YAML file"


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def port(text: str) -> int:
    """A TCP port to serve on: 0 (a free one) to 65535."""
    value = _int(text)
    if not 0 <= value <= MAX_PORT:
        raise argparse.ArgumentTypeError(f"expected a port from 0 to {MAX_PORT} (0: a free one), got {value}")
    return value


def non_negative_int(text: str) -> int:
    """A count that may be 0 (0: none)."""
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 0, got {value}")
    return value


def positive_int(text: str) -> int:
    """A count of at least 1 (frames, workers, trials)."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 1, got {value}")
    return value


def unit_interval(text: str) -> float:
    """A score or probability from 0 to 1 (an operating confidence)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 1, got {text!r}") from None
    if not 0.0 <= value <= 1.0:  # NaN too
        raise argparse.ArgumentTypeError(f"expected a number from 0 to 1, got {text}")
    return value


def shard(text: str):
    """``I/N``: shard I of N, 0-based (eval.experiments.shard)."""
    from eval.experiments.shard import ShardError, parse_shard

    try:
        return parse_shard(text)
    except ShardError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix(f"--shard {text}: ")) from None
