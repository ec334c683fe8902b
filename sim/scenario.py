"""The scenario file: one YAML document that describes a trial.

A scenario names the maze (a file or generator settings), the objects (explicit
or generated), the lighting, the robot's route, the sensors' settings and the
seed. Everything random in a trial is drawn from ``np.random.default_rng(seed)``
made once at the top and passed down (docs/DESIGN.md "Randomness").

Each section's settings class sits beside the model that reads it: a sensor's in its module
under ``sim/sensors/``, the maze generator's, the arena's and the objects' under ``sim/world/``,
the robot's in ``sim/motion/route.py``. This module composes them into :class:`Scenario` and
reads, checks and edits scenario files (every error one line, :class:`ScenarioError`).

Instead of a maze and its objects, a scenario can lay out the TurtleBot goal arena
of [Bouda2025]_ section 1 (an open floor with a goal of two blue pillars, a ball before
it, obstacles and other pillars; ``sim.world.arena``)::

    arena: {generate: {ball_axis_offset_m: 0.15, ball_goal_distance_m: [0.5, 1.5]}}
    robot: {kind: turtlebot, route: arena}
    sensors: {pose_source: wheels}
    rules: turtlebot

Example (``poibench scenario new --seed 3`` prints a complete one)::

    poibench_scenario: 1
    name: my-trial
    seed: 3
    maze: {generate: {rows: 4, cols: 4, preset: rrl}}
    objects: {generate: {counts: {hazmat: 4, qr: 4}}}
    lighting: dim
    robot: {speed_mps: 0.3}
    sensors: {fps: 10, t265: {drift_fraction: 0.03}}

References
----------
Full entries in docs/SOURCES.md.

.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
.. [RMRC2025] RoboCup Rescue Rapidly Manufactured Robot Challenge rulebook, 2025.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import yaml

from poi.core.loader import LoadError, Source, build, load_yaml, load_yaml_file, number, safe_load, to_plain
from sim.motion.route import RobotSpec
from sim.sensors.d435 import D435Spec
from sim.sensors.t265 import T265Spec
from sim.sensors.thermal import ThermalSpec
from sim.sensors.wheel_odometry import WheelOdometrySpec
from sim.world.arena import ArenaGenerate
from sim.world.maze_gen import MazeGenerate
from sim.world.placement import ObjectsSpec

SCENARIO_VERSION = 1


class ScenarioError(LoadError):
    """A scenario file that cannot be used; the message is one line."""


@dataclass(kw_only=True)
class MazeSpec:
    """Either ``file`` (a path, or the name of a shipped maze) or ``generate``."""

    file: str | None = None
    generate: MazeGenerate | None = None

    def __post_init__(self) -> None:
        if (self.file is None) == (self.generate is None):
            raise ValueError("give exactly one of 'file' or 'generate'")


@dataclass(kw_only=True)
class ArenaSpec:
    """An arena generated from the scenario seed (the only kind so far)."""

    generate: ArenaGenerate = field(default_factory=ArenaGenerate)


@dataclass(kw_only=True)
class MountSpec:
    """D435 colour optical frame in the T265 frame (x fwd, y left, z up): p_tracker = Q0 p_c + t0.

    ``rpy_deg`` is roll-pitch-yaw applied on top of the optical-to-body rotation.
    ``error_*`` perturbs the true mount the simulator uses; the pipeline is given
    the nominal one, so a calibration error can be simulated. With
    ``sensors.pose_source: wheels`` the tracker frame is the robot base (on the floor,
    under the camera) and the nominal mount follows from the camera's height and tilt:
    ``t_m`` and ``rpy_deg`` (the D435-to-T265 mounting) do not apply, ``error_*`` does.
    """

    t_m: tuple[float, float, float] = (0.0, 0.0, 0.045)
    rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    error_t_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    error_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(kw_only=True)
class SensorsSpec:
    noise: bool = True  # master switch: off gives a clean run (no depth, colour, pose noise)
    fps: float = 10.0
    d435: D435Spec = field(default_factory=D435Spec)
    t265: T265Spec = field(default_factory=T265Spec)
    # what Frame.pose comes from: the T265 (tracker frame: the T265), or the base's wheel
    # odometry (tracker frame: the base; docs/FACTS.md "Wheel odometry")
    pose_source: Literal["t265", "wheels"] = "t265"
    wheel_odometry: WheelOdometrySpec = field(default_factory=WheelOdometrySpec)
    thermal: ThermalSpec = field(default_factory=ThermalSpec)
    mount: MountSpec = field(default_factory=MountSpec)
    truth_boxes: bool = True  # per-frame ground-truth boxes (a segmentation render)

    def __post_init__(self) -> None:
        if self.fps <= 0:
            raise ValueError(f"fps must be positive, got {self.fps}")


@dataclass(kw_only=True)
class Scenario:
    """A trial: a maze with its objects (default: the shipped ``default`` maze and the
    default object counts), or an ``arena`` that lays out floor, objects and start itself.

    ``rules`` names the scoring preset the scenario is meant for; ``poibench run`` uses it
    when no ``--rules`` is given (none: ex3).
    """

    poibench_scenario: int = SCENARIO_VERSION
    name: str = "scenario"
    seed: int = number(0, lo=0)
    maze: MazeSpec | None = None
    objects: ObjectsSpec | None = None
    arena: ArenaSpec | None = None
    lighting: Literal["bright", "dim", "uneven"] = "bright"
    # the preset's lamps cast shadows (sim/world/world.py _lights): off in trials for its cost (a
    # shadow map a lamp a frame; README "Mazes"), on for half of poibench dataset's scenarios
    shadows: bool = False
    # distractors (crates, buckets, pipes, cables, boxes, debris; maze_assets/clutter.py) per
    # maze cell, against the walls; never objects of interest, never reported
    clutter_per_cell: float = number(0.3, lo=0.0, hi=2.0)
    robot: RobotSpec = field(default_factory=RobotSpec)
    sensors: SensorsSpec = field(default_factory=SensorsSpec)
    rules: str | None = None
    source_dir: str | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.poibench_scenario != SCENARIO_VERSION:
            raise ValueError(
                f"poibench_scenario: unsupported version {self.poibench_scenario}; expected {SCENARIO_VERSION}"
            )
        if self.arena is None:
            if self.maze is None:
                self.maze = MazeSpec(file="default")
            if self.objects is None:
                self.objects = ObjectsSpec()
            if self.robot.route == "arena":
                raise ValueError(
                    "robot.route: 'arena' drives the goal arena; a maze scenario has none (use 'tour')"
                )
        else:
            if self.maze is not None or self.objects is not None:
                raise ValueError(
                    "arena: an arena lays out its own floor and objects; give no 'maze' or 'objects' with it"
                )
            if self.robot.route == "tour":
                raise ValueError("robot.route: 'tour' visits maze cells; in an arena use 'arena' or a CSV file")
        if self.sensors.pose_source == "wheels" and self.robot.kind != "turtlebot":
            raise ValueError(
                "sensors.pose_source: 'wheels' needs robot.kind 'turtlebot' (odometry of a base the camera "
                "is fixed to; the mast robot's camera pans)"
            )
        if self.rules is not None and not self.rules.strip():
            raise ValueError("rules: expected a preset name or a rules file, got an empty string")

    def to_dict(self) -> dict:
        d = to_plain(self)
        d.pop("source_dir", None)
        return d

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)

    def resolve(self, path: str) -> Path | str:
        """A path in the scenario, relative to the scenario file's folder."""
        p = Path(path)
        if not p.is_absolute() and self.source_dir:
            cand = Path(self.source_dir) / p
            if cand.exists():
                return cand
        return Path(path) if p.exists() else path


def parse_scenario(text: str, name: str = "<scenario>", source_dir: str | None = None) -> Scenario:
    """A scenario from YAML text (``name`` names it in errors, which are all :class:`ScenarioError`)."""
    data, src = load_yaml(text, name, error=ScenarioError)
    return scenario_from_data(data, src, source_dir=source_dir)


def scenario_from_data(data: object, src: Source, path: str = "", source_dir: str | None = None) -> Scenario:
    """A scenario from parsed YAML data (at dotted ``path`` of the document ``src`` describes)."""
    sc = build(Scenario, data, src, path, error=ScenarioError)
    sc.source_dir = source_dir
    return sc


def load_scenario(path: str | Path) -> Scenario:
    """Load a scenario file; a bare name (``default``) resolves to a shipped scenario."""
    from maze_assets import SCENARIOS_DIR

    p = Path(path)
    if not p.exists() and not p.suffix:
        shipped = SCENARIOS_DIR / f"{path}.yaml"
        if shipped.exists():
            p = shipped
    data, src = load_yaml_file(p, error=ScenarioError)
    if data is None or data == {}:  # an empty or truncated file would run as the built-in defaults
        raise ScenarioError(
            f"{p}: an empty scenario file; a scenario file starts with poibench_scenario: {SCENARIO_VERSION} "
            "(poibench scenario new -o FILE writes one)"
        )
    return scenario_from_data(data, src, source_dir=str(p.resolve().parent))


def apply_settings(sc: Scenario, assignments: list[str], what: str = "--set") -> Scenario:
    """Apply dotted ``key=value`` settings (values parsed as YAML) to a copy of a scenario;
    ``what`` names where they came from in an error (``--set``, a suite file's ``settings:``).

    >>> sc = apply_settings(Scenario(), ["sensors.t265.drift_fraction=0.03", "lighting=dim"])
    >>> sc.sensors.t265.drift_fraction, sc.lighting
    (0.03, 'dim')
    """

    def unknown(key: str, part: str, node, path: list[str]) -> ScenarioError:
        where = f"under {'.'.join(path)}" if path else "at the top"
        if not isinstance(node, dict):
            return ScenarioError(f"{what} {key}: {'.'.join(path)} is a value, not a section with {part!r} in it")
        known = ", ".join(node)
        return ScenarioError(f"{what} {key}: unknown scenario key {part!r}; expected one of {known} ({where})")

    data = sc.to_dict()
    opened: list[dict] = []  # sections left unset that these settings fill: any key goes, the loader checks
    for item in assignments:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ScenarioError(f"{what} {item!r}: expected key=value")
        try:
            value = safe_load(raw, f"{what} {key}")
        except LoadError:
            value = raw
        node = data
        parts = key.split(".")
        for depth, part in enumerate(parts):
            if not isinstance(node, dict) or (part not in node and not any(node is o for o in opened)):
                raise unknown(key, part, node, parts[:depth])
            if depth == len(parts) - 1:
                node[part] = value
            elif node.get(part) is None:
                # a section left unset (the arena of a maze scenario, the generator of a maze file):
                # the loader below names the keys it takes, or why it cannot be set here
                node[part] = {}
                node = node[part]
                opened.append(node)
            else:
                node = node[part]
    return scenario_from_data(data, Source(what), source_dir=sc.source_dir)


def with_noise(sc: Scenario, on: bool) -> Scenario:
    """A copy with the master noise switch set."""
    return replace(sc, sensors=replace(sc.sensors, noise=on))


__all__ = [
    "Scenario",
    "ScenarioError",
    "load_scenario",
    "parse_scenario",
    "scenario_from_data",
    "apply_settings",
    "with_noise",
]
