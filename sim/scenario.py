"""The scenario file: one YAML document that describes a trial.

A scenario names the maze (a file or generator settings), the objects (explicit
or generated), the lighting, the robot's route, the sensors' settings and the
seed. Everything random in a trial is drawn from ``np.random.default_rng(seed)``
made once at the top and passed down (STYLE.md "Randomness").

Example (``poibench scenario new --seed 3`` prints a complete one)::

    poibench_scenario: 1
    name: my-trial
    seed: 3
    maze: {generate: {rows: 4, cols: 4, preset: rrl}}
    objects: {generate: {counts: {hazmat: 4, qr: 4}}}
    lighting: dim
    robot: {speed_mps: 0.3}
    sensors: {fps: 10, t265: {drift_fraction: 0.03}}
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import yaml

from poi.names import TYPES
from sim.schema import SchemaError, Source, build, convert, load_yaml, load_yaml_file, to_plain

SCENARIO_VERSION = 1


class ScenarioError(SchemaError):
    """A scenario file that cannot be used; the message is one line."""


@dataclass(kw_only=True)
class MazeGenerate:
    rows: int = 4
    cols: int = 4
    loop_fraction: float = 0.15
    preset: Literal["rrl", "rmrc"] = "rrl"

    def __post_init__(self) -> None:
        if self.rows < 1 or self.cols < 1:
            raise ValueError(f"maze size must be at least 1x1, got {self.rows}x{self.cols}")
        if not 0.0 <= self.loop_fraction <= 1.0:
            raise ValueError(f"loop_fraction must be in [0, 1], got {self.loop_fraction}")


@dataclass(kw_only=True)
class MazeSpec:
    """Either ``file`` (a path, or the name of a shipped maze) or ``generate``."""

    file: str | None = None
    generate: MazeGenerate | None = None

    def __post_init__(self) -> None:
        if (self.file is None) == (self.generate is None):
            raise ValueError("give exactly one of 'file' or 'generate'")


@dataclass(kw_only=True)
class WallSpot:
    """A spot on a wall face: the face of cell (row, col) on ``side`` (n/e/s/w)."""

    cell: tuple[int, int]
    side: Literal["n", "e", "s", "w"]
    height_m: float = 1.0
    offset_m: float = 0.0  # along the wall from the face centre, positive = left when facing the wall


@dataclass(kw_only=True)
class ObjectSpec:
    """An explicitly placed object: either ``at`` a wall spot or at ``position``."""

    type: str
    text: str = ""
    at: WallSpot | None = None
    position: tuple[float, float, float] | None = None  # world frame, metres
    yaw_deg: float = 0.0
    mount: Literal["wall", "floor", "opening"] | None = None
    size_m: float | None = None
    temperature_c: float | None = None

    def __post_init__(self) -> None:
        if self.type not in TYPES:
            raise ValueError(f"unknown type {self.type!r}; expected one of {', '.join(TYPES)}")
        if (self.at is None) == (self.position is None):
            raise ValueError("give exactly one of 'at' (a wall spot) or 'position'")


DEFAULT_COUNTS: dict[str, int] = {
    "hazmat": 5,
    "qr": 4,
    "door": 1,
    "valve": 1,
    "baby-doll": 1,
    "fire-extinguisher": 1,
    "exit-sign": 1,
    "fire-extinguisher-sign": 1,
    "heat-source": 1,
}


@dataclass(kw_only=True)
class ObjectsGenerate:
    """Random placement: how many of each type, and the spacing rules."""

    counts: dict[str, int] = field(default_factory=lambda: dict(DEFAULT_COUNTS))
    min_spacing_m: float = 0.6
    wall_height_m: tuple[float, float] = (0.2, 1.5)
    labels: list[str] | None = None  # hazmat labels to draw from (default: all 16)
    qr_texts: list[str] | None = None  # QR contents to use in order (default: "Chart A", ...)

    def __post_init__(self) -> None:
        for t, n in self.counts.items():
            if t not in TYPES:
                raise ValueError(f"counts: unknown type {t!r}; expected one of {', '.join(TYPES)}")
            if n < 0:
                raise ValueError(f"counts.{t}: must be >= 0, got {n}")
        lo, hi = self.wall_height_m
        if not 0.0 <= lo <= hi:
            raise ValueError(f"wall_height_m: expected [low, high] with 0 <= low <= high, got {lo}, {hi}")


@dataclass(kw_only=True)
class ObjectsSpec:
    generate: ObjectsGenerate | None = field(default_factory=ObjectsGenerate)
    explicit: list[ObjectSpec] = field(default_factory=list)


@dataclass(kw_only=True)
class PanSpec:
    amplitude_deg: float = 80.0
    period_s: float = 5.0


@dataclass(kw_only=True)
class RobotSpec:
    """The robot base and its camera mast (kinematic: it follows the route exactly)."""

    route: str = "tour"  # "tour" (visit every cell) or a CSV file of timed poses: t,x,y,yaw[,pan]
    speed_mps: float = 0.3
    yaw_rate_dps: float = 60.0
    mast_height_m: float | None = None  # default: 0.5 m for RRL cells, 0.2 m for RMRC
    tilt_deg: float = 0.0  # positive looks up
    pan: PanSpec = field(default_factory=PanSpec)
    max_duration_s: float | None = None

    def __post_init__(self) -> None:
        if self.speed_mps <= 0 or self.yaw_rate_dps <= 0:
            raise ValueError("speed_mps and yaw_rate_dps must be positive")


@dataclass(kw_only=True)
class DepthSpec:
    noise: bool = True
    sigma_d_px: float = 0.08  # subpixel disparity noise (FACTS.md)
    baseline_m: float = 0.05
    fx_depth_px: float = 384.2  # depth imager focal length at 640x480 (FACTS.md)
    subpixel: float = 1.0 / 32.0
    min_m: float = 0.28
    max_m: float = 10.0
    edge_holes: bool = True
    dropout: float = 0.002  # fraction of pixels randomly invalid (low texture, specular)

    def __post_init__(self) -> None:
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        for name in ("sigma_d_px", "baseline_m", "fx_depth_px", "subpixel", "max_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.min_m < self.max_m:
            raise ValueError(f"need 0 <= min_m < max_m, got min_m={self.min_m}, max_m={self.max_m}")


@dataclass(kw_only=True)
class D435Spec:
    enabled: bool = True
    width: int = 640
    height: int = 480
    fx: float = 612.4
    fy: float = 610.6
    ppx: float = 314.3
    ppy: float = 237.8
    color_noise_sigma: float = 2.0  # per-pixel Gaussian noise, 8-bit levels
    depth: DepthSpec = field(default_factory=DepthSpec)


@dataclass(kw_only=True)
class JumpSpec:
    rate_per_min: float = 0.0
    sigma_m: float = 0.2


@dataclass(kw_only=True)
class DropoutSpec:
    rate_per_min: float = 0.0
    duration_s: tuple[float, float] = (3.0, 7.0)


@dataclass(kw_only=True)
class T265Spec:
    enabled: bool = True
    drift_fraction: float = 0.01  # position error grows ~1% of distance travelled
    yaw_drift_deg_per_m: float = 0.1
    scale_error: float = 0.0  # -0.2 means distances reported 20% short
    jumps: JumpSpec = field(default_factory=JumpSpec)
    dropouts: DropoutSpec = field(default_factory=DropoutSpec)


@dataclass(kw_only=True)
class ThermalSpec:
    enabled: bool = True
    width: int = 160
    height: int = 120
    ambient_c: float = 20.0
    netd_k: float = 0.08
    blur_px: float = 0.8

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"thermal size must be at least 1x1, got {self.width}x{self.height}")
        if self.netd_k < 0 or self.blur_px < 0:
            raise ValueError("netd_k and blur_px must be >= 0")


@dataclass(kw_only=True)
class MountSpec:
    """D435 colour optical frame in the T265 frame (x fwd, y left, z up): p_tracker = Q0 p_c + t0.

    ``rpy_deg`` is roll-pitch-yaw applied on top of the optical-to-body rotation.
    ``error_*`` perturbs the true mount the simulator uses; the pipeline is given
    the nominal one, so a calibration error can be simulated.
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
    thermal: ThermalSpec = field(default_factory=ThermalSpec)
    mount: MountSpec = field(default_factory=MountSpec)
    truth_boxes: bool = True  # per-frame ground-truth boxes (a segmentation render)

    def __post_init__(self) -> None:
        if self.fps <= 0:
            raise ValueError(f"fps must be positive, got {self.fps}")


@dataclass(kw_only=True)
class Scenario:
    poibench_scenario: int = SCENARIO_VERSION
    name: str = "scenario"
    seed: int = 0
    maze: MazeSpec = field(default_factory=lambda: MazeSpec(file="default"))
    objects: ObjectsSpec = field(default_factory=ObjectsSpec)
    lighting: Literal["bright", "dim", "uneven"] = "bright"
    robot: RobotSpec = field(default_factory=RobotSpec)
    sensors: SensorsSpec = field(default_factory=SensorsSpec)
    source_dir: str | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.poibench_scenario != SCENARIO_VERSION:
            raise ValueError(
                f"poibench_scenario: unsupported version {self.poibench_scenario}; expected {SCENARIO_VERSION}"
            )

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


def _wrap(e: SchemaError) -> ScenarioError:
    return ScenarioError(str(e))


def parse_scenario(text: str, name: str = "<scenario>", source_dir: str | None = None) -> Scenario:
    try:
        data, src = load_yaml(text, name)
        sc = build(Scenario, data, src)
    except ScenarioError:
        raise
    except SchemaError as e:
        raise _wrap(e) from None
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
    try:
        data, src = load_yaml_file(p)
        sc = build(Scenario, data, src)
    except SchemaError as e:
        raise _wrap(e) from None
    sc.source_dir = str(p.resolve().parent)
    return sc


def apply_settings(sc: Scenario, assignments: list[str]) -> Scenario:
    """Apply dotted ``key=value`` settings (values parsed as YAML) to a copy of a scenario.

    >>> sc = apply_settings(Scenario(), ["sensors.t265.drift_fraction=0.03", "lighting=dim"])
    >>> sc.sensors.t265.drift_fraction, sc.lighting
    (0.03, 'dim')
    """
    data = sc.to_dict()
    for item in assignments:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            raise ScenarioError(f"--set {item!r}: expected key=value")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        node = data
        parts = key.split(".")
        for part in parts[:-1]:
            if not isinstance(node, dict) or part not in node:
                raise ScenarioError(f"--set {key}: unknown setting {part!r}")
            if node[part] is None:
                node[part] = {}
            node = node[part]
        if not isinstance(node, dict) or parts[-1] not in node:
            raise ScenarioError(f"--set {key}: unknown setting")
        node[parts[-1]] = value
    try:
        out = build(Scenario, data, Source("--set"))
    except SchemaError as e:
        raise _wrap(e) from None
    out.source_dir = sc.source_dir
    return out


def with_noise(sc: Scenario, on: bool) -> Scenario:
    """A copy with the master noise switch set."""
    return replace(sc, sensors=replace(sc.sensors, noise=on))


__all__ = [
    "Scenario",
    "ScenarioError",
    "load_scenario",
    "parse_scenario",
    "apply_settings",
    "with_noise",
    "convert",
]
