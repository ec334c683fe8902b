"""Benchmark suites: named, versioned sets of scenarios (``eval/suites/*.yaml``).

A suite file::

    poibench_suite: 1
    name: smoke
    version: 1                      # bumped whenever its scenarios change
    description: ...
    settings: [robot.max_duration_s=40]   # scenario settings for every scenario
    scenarios:
      - {name: smoke-1, generate: {rows: 3, cols: 3, preset: rrl}, seed: 101}
      - {name: smoke-2, scenario: default, seed: 102, settings: [lighting=dim]}

Each scenario is either generated (``generate``: a maze of rows x cols with
every object type, as ``poibench scenario new``) or a scenario file or shipped
name (``scenario``), with its ``seed`` and the suite's then its own settings
applied. Shipped suites: smoke, rrl, rrl-hard, rmrc; ``--suite FILE`` takes a
user's own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from poi.core.loader import FieldError, LoadError, build, load_yaml_file, number
from sim.world.maze import MAX_MAZE_SIDE

SUITES_DIR = Path(__file__).parent / "suites"
SUITE_VERSION = 1


class SuiteError(LoadError):
    """A suite file is missing or malformed (one line naming the file, line and field)."""


def _check_settings(settings: list[str]) -> None:
    for i, item in enumerate(settings):
        if "=" not in item:
            raise FieldError(f"settings[{i}]", f"expected a key=value string, got {item!r}")


@dataclass(kw_only=True)
class SuiteGenerate:
    """A generated maze with every object type, as ``poibench scenario new``."""

    rows: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    cols: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    preset: Literal["rrl", "rmrc"] = "rrl"


@dataclass(kw_only=True)
class SuiteScenario:
    name: str
    seed: int = number(lo=0)
    generate: SuiteGenerate | None = None
    scenario: str | None = None
    settings: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        if (self.generate is None) == (self.scenario is None):
            raise ValueError("give exactly one of 'generate' or 'scenario'")
        _check_settings(self.settings)


@dataclass(kw_only=True)
class _SuiteFile:
    """The suite file's schema (module docstring)."""

    poibench_suite: int
    name: str
    version: int
    description: str = ""
    settings: list[str] = field(default_factory=list)
    scenarios: list[SuiteScenario]

    def __post_init__(self) -> None:
        if self.poibench_suite != SUITE_VERSION:
            raise FieldError("poibench_suite", f"expected {SUITE_VERSION}, got {self.poibench_suite!r}")
        _check_settings(self.settings)
        if not self.scenarios:
            raise FieldError("scenarios", "expected a non-empty list")
        names: set[str] = set()
        for i, entry in enumerate(self.scenarios):
            if entry.name in names:
                raise FieldError(f"scenarios[{i}].name", f"expected a unique name, got {entry.name!r} again")
            names.add(entry.name)


@dataclass(kw_only=True)
class Suite:
    name: str
    version: int
    description: str
    settings: list[str]
    scenarios: list[SuiteScenario]
    source: str

    def build(self, entry: SuiteScenario):
        """The Scenario of one entry: generated or loaded, seed set, suite then entry settings."""
        from eval.trial.scenarios import generated_scenario
        from sim.scenario import ScenarioError, apply_settings, load_scenario

        try:
            if entry.generate is not None:
                g = entry.generate
                sc = generated_scenario(entry.seed, g.rows, g.cols, g.preset)
            else:
                sc = apply_settings(load_scenario(entry.scenario), [f"seed={entry.seed}"])
            sc = apply_settings(sc, [f"name={entry.name}"])
            sc = apply_settings(sc, self.settings, what="the suite's settings")
            sc = apply_settings(sc, entry.settings, what="its settings")
        except ScenarioError as e:
            raise SuiteError(f"{self.source}: scenario {entry.name}: {e}") from None
        return sc


def shipped_suites() -> list[str]:
    return sorted(p.stem for p in SUITES_DIR.glob("*.yaml"))


def load_suite(name_or_path: str | Path) -> Suite:
    """A shipped suite by name or a suite file by path, validated (errors: :class:`SuiteError`)."""
    p = Path(name_or_path)
    if not p.is_file():
        shipped = SUITES_DIR / f"{name_or_path}.yaml"
        if not shipped.is_file():
            raise SuiteError(
                f"{name_or_path}: no such suite; shipped suites are {', '.join(shipped_suites())}, or give a file"
            )
        p = shipped
    data, src = load_yaml_file(p, error=SuiteError)
    doc = build(_SuiteFile, data, src, error=SuiteError)
    return Suite(
        name=doc.name,
        version=doc.version,
        description=doc.description,
        settings=doc.settings,
        scenarios=doc.scenarios,
        source=str(p),
    )
