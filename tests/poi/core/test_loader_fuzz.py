"""Every input loader either loads a mutated shipped file or raises the project's own error (issue 16).

Hypothesis draws 1-3 mutations ``(kind, seed)`` from ``bench/loader_fuzz.py``, the
same mutations ``bench/bench_fuzz_loaders.py`` runs 10,000 of per loader; here a
bounded, derandomized number per loader so CI stays fast and gives the same cases
every run. "Own error" is a ValueError subclass defined in the project, the errors
the CLI reports as ``poibench CMD: error: ...`` with exit status 2; anything else
escaping (KeyError, RecursionError, a built-in ValueError, yaml.YAMLError, ...) fails.
"""

from __future__ import annotations

import importlib.util
import sys
import time
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

_spec = importlib.util.spec_from_file_location(
    "loader_fuzz", Path(__file__).parents[3] / "bench" / "loader_fuzz.py"
)
lf = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("loader_fuzz", lf)
_spec.loader.exec_module(lf)

CAP_S = 5.0  # watchdog: a case still running after this fails as a hang instead of stalling CI
# Examples per loader, sized so the whole file runs in about 10 s on a busy 2-core machine
# (a calibration file takes ~50 ms to load, a maze ~0.2 ms).
EXAMPLES = {"calibration": 25, "config": 40, "config-set": 40, "poi": 45}
DEFAULT_EXAMPLES = 60

OPS = st.lists(st.tuples(st.sampled_from(lf.KINDS), st.integers(0, 2**32 - 1)), min_size=1, max_size=3)


def _load(name: str, path: Path) -> None:
    """Load ``path`` with loader ``name``; fail on anything but success or the project's own error."""
    try:
        with lf.watchdog(CAP_S):
            lf.LOADERS[name].call(path)
    except lf.CaseTimeout as exc:
        pytest.fail(f"{name}: {path.name}: {exc}")
    except Exception as exc:
        if not lf.is_own_error(exc):
            raise AssertionError(f"{name}: foreign {type(exc).__name__} from {lf.project_frame(exc)}") from exc


@pytest.mark.parametrize("name", list(lf.LOADERS))
def test_mutated_file_loads_or_raises_own_error(name: str, tmp_path: Path) -> None:
    seeds = lf.seed_files(name)
    path = tmp_path / f"case{lf.LOADERS[name].suffix}"
    path.write_bytes(seeds[0])
    lf.LOADERS[name].call(path)  # the shipped file loads (and imports are done before the deadline counts)

    @settings(
        max_examples=EXAMPLES.get(name, DEFAULT_EXAMPLES),
        # no wall-clock deadline: on a shared machine a case's wall time measures the load; a hang
        # fails through the watchdog (CAP_S), and the per-case cost is bench/bench_fuzz_loaders.py's
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )
    @given(pick=st.integers(0, len(seeds) - 1), ops=OPS)
    def check(pick: int, ops: list[tuple[str, int]]) -> None:
        data, done = lf.mutate(seeds[pick], ops, lf.all_donors())
        path.write_bytes(data)
        try:
            _load(name, path)
        except AssertionError as exc:
            raise AssertionError(f"{exc}; mutations: {'; '.join(done)}") from exc.__cause__

    check()


@pytest.mark.parametrize("name", [n for n, loader in lf.LOADERS.items() if loader.yaml])
def test_alias_bomb_refused_in_under_a_second(name: str, tmp_path: Path) -> None:
    """The 350-byte billion-laughs file (9**9 strings if expanded) is refused, fast, by every YAML loader."""
    path = tmp_path / f"bomb{lf.LOADERS[name].suffix}"
    path.write_bytes(lf.alias_bomb(name))
    t = time.process_time()
    try:
        with lf.watchdog(CAP_S):
            lf.LOADERS[name].call(path)
    except lf.CaseTimeout as exc:
        pytest.fail(f"{name}: alias bomb {exc}")
    except Exception as exc:
        assert lf.is_own_error(exc), f"{name}: foreign {type(exc).__name__} from {lf.project_frame(exc)}"
    else:
        pytest.fail(f"{name}: the alias bomb loaded")
    assert time.process_time() - t < 1.0


@pytest.mark.parametrize("value", ["!!int ''", "!!int +", "!!float", "!!bool x", "!!timestamp x"])
@pytest.mark.parametrize("name", [n for n, loader in lf.LOADERS.items() if loader.yaml])
def test_explicitly_tagged_odd_scalar_is_own_error(name: str, value: str, tmp_path: Path) -> None:
    """Found by the bench: PyYAML's scalar constructors fail on these with IndexError, KeyError or
    AttributeError, which escaped every YAML loader."""
    seed = lf.seed_files(name)[0]
    if name.endswith("-set"):
        data = seed.split(b"=", 1)[0] + b"=" + value.encode() + b"\n"
    else:
        data = seed + b"zz_tagged: " + value.encode() + b"\n"
    path = tmp_path / f"tagged{lf.LOADERS[name].suffix}"
    path.write_bytes(data)
    with pytest.raises(ValueError, match=r":\d+: .*cannot read|--set") as info:
        lf.LOADERS[name].call(path)
    assert lf.is_own_error(info.value), repr(info.value)
