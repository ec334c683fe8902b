"""Scenarios a trial runs on: a named or file scenario, or one generated from a seed, with --set applied."""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

from poi.core.loader import Source
from sim.scenario import (
    Scenario,
    apply_settings,
    load_scenario,
    scenario_from_data,
    with_noise,
)


def generated_scenario(seed: int, rows: int = 4, cols: int = 4, preset: str = "rrl") -> Scenario:
    """A scenario with a generated maze and generated objects (every type), from one seed.

    Checked as a scenario file is (a negative seed, a maze past 64 x 64: ScenarioError).
    """
    data = {
        "name": f"generated-{seed}",
        "seed": seed,
        "maze": {"generate": {"rows": rows, "cols": cols, "preset": preset}},
    }
    return scenario_from_data(data, Source("generated scenario"))


def generated_arena_scenario(seed: int) -> Scenario:
    """The shipped ``turtlebot-goal`` scenario (the TurtleBot goal arena) laid out from ``seed``."""
    sc = load_scenario("turtlebot-goal")
    return apply_settings(sc, [f"seed={seed}", f"name=turtlebot-goal-{seed}"])


class SettingError(ValueError):
    """A ``--set`` key that is neither a scenario key nor a pipeline section (one line)."""


class UnknownScenarioError(ValueError):
    """A scenario argument that is neither a file nor a shipped scenario's name (one line)."""


def shipped_scenarios() -> list[str]:
    """The shipped scenarios' names (``maze_assets/scenarios/*.yaml``), sorted."""
    from maze_assets import SCENARIOS_DIR

    return sorted(p.stem for p in SCENARIOS_DIR.glob("*.yaml"))


def check_scenario_name(arg: str) -> None:
    """Refuse a scenario argument that names no file and no shipped scenario, listing the shipped names."""
    p = Path(arg)
    if p.exists() or (not p.suffix and arg in shipped_scenarios()):
        return
    raise UnknownScenarioError(
        f"{arg}: no such scenario file or shipped scenario; shipped scenarios are "
        f"{', '.join(shipped_scenarios())}, or give a scenario file"
    )


def split_settings(sets: list[str]) -> tuple[list[str], list[str]]:
    """Split ``--set key=value`` items into scenario settings and pipeline settings.

    The first part of each key routes it: a scenario key (``sensors.fps``) or a pipeline
    section (``tracker.gate``); a key that is neither is refused naming both lists, so that
    a mistyped scenario key is not reported as an unknown pipeline section.
    """
    from poi.config import PipelineConfig

    sim_keys = {f.name for f in fields(Scenario) if f.repr}
    pipe_keys = {f.name for f in fields(PipelineConfig)}
    sim_sets, pipe_sets = [], []
    for item in sets:
        head = item.split("=", 1)[0].split(".")[0].strip()
        if head in sim_keys:
            sim_sets.append(item)
            continue
        if "=" in item and head not in pipe_keys:
            raise SettingError(
                f"--set {item}: unknown key {head!r}; expected a scenario key ({', '.join(sorted(sim_keys))}) "
                f"or a pipeline section ({', '.join(sorted(pipe_keys))})"
            )
        pipe_sets.append(item)
    return sim_sets, pipe_sets


def resolve_scenario(arg: str | None, seed: int | None, sets: list[str], noise: str | None) -> Scenario:
    """Scenario from a file/name (default: the built-in one) or generated from --seed, then --set/--noise."""
    if seed is not None and arg is None:
        sc = generated_scenario(seed)
    else:
        if arg is not None:
            check_scenario_name(arg)
        sc = load_scenario(arg or "default")
        if seed is not None:
            sc = apply_settings(sc, [f"seed={seed}"])
    return resolve_config_scenario(sc, sets, noise)


def resolve_config_scenario(sc: Scenario, sets: list[str], noise: str | None) -> Scenario:
    """``sc`` (a scenario as built, or a trial config's) with the scenario items of --set, then --noise."""
    sim_sets, _ = split_settings(sets)
    if sim_sets:
        sc = apply_settings(sc, sim_sets)
    if noise is not None:
        sc = with_noise(sc, noise == "on")
    return sc


LARGE_MAZE_CELLS = 400  # from 20 x 20 the set-up takes long enough to need saying (below)


def large_maze_note(sc: Scenario) -> str | None:
    """A note for a generated maze of ``LARGE_MAZE_CELLS`` cells or more: its world, the robot's
    tour of every cell and the T265's track over the whole tour are built before the first
    frame, silently. Measured on the 2-core development machine: 5 CPU-s at 16 x 16, 40 at
    32 x 32, growing faster than the cells."""
    gen = sc.maze.generate if sc.maze is not None else None
    if gen is None or gen.rows * gen.cols < LARGE_MAZE_CELLS:
        return None
    return (
        f"a {gen.rows} x {gen.cols} maze: its world and the robot's tour of all {gen.rows * gen.cols} cells are "
        "built before the first frame (about 40 CPU-s at 32 x 32, minutes at 64 x 64)"
    )
