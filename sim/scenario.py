"""The scenario file: one YAML document that describes a trial.

A scenario names the maze (a file or generator settings), the objects (explicit
or generated), the lighting, the robot's route, the sensors' settings and the
seed. Everything random in a trial is drawn from ``np.random.default_rng(seed)``
made once at the top and passed down (docs/DESIGN.md "Randomness").

Instead of a maze and its objects, a scenario can lay out the TurtleBot goal arena
of [Bouda2025]_ section 1 (an open floor with a goal of two blue pillars, a ball before
it, obstacles and other pillars; ``sim.arena``)::

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

from poi.core.landolt import DEFAULT_N_RINGS, parse_orientation_text
from poi.core.loader import LoadError, number, safe_load
from poi.core.names import MAPPING_TYPES, RESCUE_TYPES, TARGET_TYPES, TYPES
from sim.maze import MAX_MAZE_SIDE
from sim.schema import SchemaError, Source, build, convert, load_yaml, load_yaml_file, to_plain

SCENARIO_VERSION = 1
MAX_IMAGE_PX = 4096  # a camera image's width and height (the D435 colour imager tops out at 1920 x 1080)


class ScenarioError(SchemaError):
    """A scenario file that cannot be used; the message is one line."""


@dataclass(kw_only=True)
class MazeGenerate:
    rows: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    cols: int = number(4, lo=1, hi=MAX_MAZE_SIDE)
    loop_fraction: float = 0.15
    preset: Literal["rrl", "rmrc"] = "rrl"

    def __post_init__(self) -> None:
        if not (1 <= self.rows <= MAX_MAZE_SIDE and 1 <= self.cols <= MAX_MAZE_SIDE):
            raise ValueError(
                f"maze size must be from 1x1 to {MAX_MAZE_SIDE}x{MAX_MAZE_SIDE}, got {self.rows}x{self.cols}"
            )
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
        if self.type == "landolt-c" and self.text:  # empty: the gap directions are drawn from the seed
            rings = parse_orientation_text(self.text)
            if sorted(rings) != list(range(1, DEFAULT_N_RINGS + 1)):
                raise ValueError(
                    f"text {self.text!r}: a landolt-c target's text gives rings 1 to {DEFAULT_N_RINGS} once each, "
                    'e.g. "1:E 2:N 3:NE 4:S 5:W"'
                )


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
class QrSheets:
    """A4 pages of QR codes ([RMRC2025]_, as issue 22 quotes it: "A4 pages of codes in several
    sizes, stapled at random locations and heights, matte"), placed by sim/placement.py.

    ``count`` pages, each on a random wall face with its centre at a height drawn from
    ``height_m``; every page carries one code per entry of ``module_mm`` (the side of one
    module, millimetres; the finals' code has 2 mm modules), all encoding the page's name and
    their module size ("Chart F 2mm").
    """

    count: int = number(0, lo=0, hi=100)
    module_mm: tuple[float, ...] = (5.0, 3.0, 2.0)
    height_m: tuple[float, float] = (0.25, 1.0)

    def __post_init__(self) -> None:
        if not self.module_mm or any(not 0.5 <= m <= 20 for m in self.module_mm):
            raise ValueError(
                f"module_mm: expected one or more module sizes in 0.5..20 mm, got {list(self.module_mm)}"
            )
        if len(set(self.module_mm)) != len(self.module_mm):
            raise ValueError(f"module_mm: expected each module size once, got {list(self.module_mm)}")
        lo, hi = self.height_m
        if not 0.0 <= lo <= hi:
            raise ValueError(f"height_m: expected [low, high] with 0 <= low <= high, got {lo}, {hi}")


@dataclass(kw_only=True)
class LandoltTargets:
    """Where the ``counts.landolt-c`` targets go (sim/placement.py ``place_landolt``): ``cabinets``
    of them at the back of a sensor cabinet, ``boards`` on a wooden board, the rest on the wall
    itself, each with its centre at a height drawn from ``height_m`` and its gap directions
    drawn from the seed ([RMRC2025]_ Sensor Cabinet and Linear Rail Inspect; docs/RULES.md
    "Landolt-C")."""

    cabinets: int = number(0, lo=0, hi=100)
    boards: int = number(0, lo=0, hi=100)
    height_m: tuple[float, float] = (0.3, 1.0)

    def __post_init__(self) -> None:
        lo, hi = self.height_m
        if not 0.0 < lo <= hi:
            raise ValueError(f"height_m: expected [low, high] with 0 < low <= high, got {lo}, {hi}")


GENERATED_TYPES: tuple[str, ...] = RESCUE_TYPES + MAPPING_TYPES + TARGET_TYPES


@dataclass(kw_only=True)
class ObjectsGenerate:
    """Random placement: how many of each type, and the spacing rules.

    ``counts.fiducial`` places RMRC mapping fiducials in pairs facing each other across a
    cell (so it must be even; sim/placement.py); ``qr_sheets`` adds pages of QR codes;
    ``counts.landolt-c`` places Landolt-C targets, ``landolt`` says how many sit in a sensor
    cabinet or on a board and at what heights.
    """

    counts: dict[str, int] = field(default_factory=lambda: dict(DEFAULT_COUNTS))
    min_spacing_m: float = 0.6
    wall_height_m: tuple[float, float] = (0.2, 1.5)
    labels: list[str] | None = None  # hazmat labels to draw from (default: all 16)
    qr_texts: list[str] | None = None  # QR contents to use in order (default: "Chart A", ...)
    # share of the placards laid face up on the floor in front of their wall (sim.placement.
    # lay_placards_on_floor); the dataset generator lays some there, trials keep them on walls
    hazmat_on_floor: float = number(0.0, lo=0.0, hi=1.0)
    # wall placards moved onto doors, one per door face (sim.placement.hang_placards_on_doors)
    hazmat_on_doors: int = number(0, lo=0, hi=100)
    # wall placards moved into open crates on the floor (sim.placement.put_placards_in_crates)
    hazmat_in_crates: int = number(0, lo=0, hi=100)
    # wall placards laid on wooden ramps against their walls (sim.placement.lay_placards_on_ramps)
    hazmat_on_ramps: int = number(0, lo=0, hi=100)
    # boards of a wall placard with a QR code and a Landolt-C card beside it
    # (sim.placement.hang_placard_boards)
    hazmat_on_boards: int = number(0, lo=0, hi=100)
    qr_sheets: QrSheets | None = None
    landolt: LandoltTargets | None = None  # where the landolt-c targets go (default: all on walls)

    def __post_init__(self) -> None:
        for t, n in self.counts.items():
            if t not in GENERATED_TYPES:
                where = " (the arena's types are laid out by 'arena')" if t in TYPES else ""
                raise ValueError(
                    f"counts: unknown type {t!r}{where}; expected one of {', '.join(GENERATED_TYPES)}"
                )
            if n < 0:
                raise ValueError(f"counts.{t}: must be >= 0, got {n}")
        if self.counts.get("fiducial", 0) % 2:
            raise ValueError(
                f"counts.fiducial: fiducials are mounted in pairs facing each other; expected an even number, "
                f"got {self.counts['fiducial']}"
            )
        lo, hi = self.wall_height_m
        if not 0.0 <= lo <= hi:
            raise ValueError(f"wall_height_m: expected [low, high] with 0 <= low <= high, got {lo}, {hi}")
        if self.landolt is not None:
            n = self.counts.get("landolt-c", 0)
            held = self.landolt.cabinets + self.landolt.boards
            if held > n:
                raise ValueError(
                    f"landolt: {self.landolt.cabinets} cabinets + {self.landolt.boards} boards need "
                    f"{held} targets, but counts.landolt-c is {n}"
                )


@dataclass(kw_only=True)
class ObjectsSpec:
    generate: ObjectsGenerate | None = field(default_factory=ObjectsGenerate)
    explicit: list[ObjectSpec] = field(default_factory=list)


ARENA_CELL_M = 0.5  # the arena's floor is a grid of these cells (its walls are pieces this long)


def _range(name: str, lo: float, hi: float, *, positive: bool = False) -> None:
    if not lo <= hi or lo < 0 or (positive and lo <= 0):
        bound = "0 < low" if positive else "0 <= low"
        raise ValueError(f"{name}: expected [low, high] with {bound} <= high, got [{lo}, {hi}]")


@dataclass(kw_only=True)
class ArenaGenerate:
    """The TurtleBot goal arena ([Bouda2025]_ section 1, tasks 2 and 3), laid out from the seed.

    An open floor ``size_m`` (x by y) inside low boundary walls; the goal, two blue
    pillars ``goal_width_m`` apart, ``behind_goal_m`` before the +x wall with its axis
    along x; the ball within ``ball_axis_offset_m`` (c) of the axis and
    ``ball_goal_distance_m`` (a..b) before the goal line; ``obstacles`` cubes of side
    ``obstacle_size_m`` between the ball and the goal line that always leave a corridor
    ``min_path_width_m`` wide from the ball to the goal; ``other_pillars`` red or green
    pillars behind the goal, every two pillars at least ``min_pillar_spacing_m`` apart;
    the robot starting ``robot_ball_distance_m`` (d..e) from the ball, facing roughly
    towards it. Defaults are task 3's figures; task 2's are ``ball_axis_offset_m: 0.15``,
    ``ball_goal_distance_m: [0.5, 1.5]``, ``obstacles: [0, 0]``. Counts and ranges are
    drawn uniformly.
    """

    size_m: tuple[float, float] = (6.0, 5.0)
    boundary_wall_height_m: float = 0.15  # below the camera (0.3 m) and the pillars: never hides one
    goal_width_m: tuple[float, float] = (0.7, 1.0)  # between the blue pillars' centres; "at least 700 mm"
    ball_axis_offset_m: float = 0.3  # c
    ball_goal_distance_m: tuple[float, float] = (0.5, 2.0)  # a..b
    obstacles: tuple[int, int] = (0, 2)  # "up to two obstacles before the line"
    obstacle_size_m: float = 0.3
    min_path_width_m: float = 0.6  # "a path at least 600 mm wide from the ball to the goal"
    other_pillars: tuple[int, int] = (2, 4)  # "any number of pillars behind the goal"
    min_pillar_spacing_m: float = 0.3
    robot_ball_distance_m: tuple[float, float] = (0.7, 2.5)  # d..e
    behind_goal_m: float = 1.5  # floor between the goal line and the +x wall

    def __post_init__(self) -> None:
        for i, v in enumerate(self.size_m):
            if v <= 0 or abs(v / ARENA_CELL_M - round(v / ARENA_CELL_M)) > 1e-9:
                raise ValueError(f"size_m[{i}]: expected a positive multiple of {ARENA_CELL_M} m, got {v}")
        for name in ("boundary_wall_height_m", "obstacle_size_m", "min_path_width_m", "behind_goal_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: expected a positive number, got {getattr(self, name)}")
        if self.ball_axis_offset_m < 0 or self.min_pillar_spacing_m < 0:
            raise ValueError("ball_axis_offset_m and min_pillar_spacing_m: expected numbers >= 0")
        _range("goal_width_m", *self.goal_width_m, positive=True)
        _range("ball_goal_distance_m", *self.ball_goal_distance_m, positive=True)
        _range("robot_ball_distance_m", *self.robot_ball_distance_m, positive=True)
        _range("obstacles", *self.obstacles)
        _range("other_pillars", *self.other_pillars)
        if self.goal_width_m[0] <= self.min_path_width_m:
            raise ValueError(
                f"goal_width_m: the goal ({self.goal_width_m[0]} m) must be wider than min_path_width_m "
                f"({self.min_path_width_m} m)"
            )
        if self.behind_goal_m >= self.size_m[0]:
            raise ValueError(
                f"behind_goal_m: {self.behind_goal_m} m leaves no field in a {self.size_m[0]} m floor"
            )


@dataclass(kw_only=True)
class ArenaSpec:
    """An arena generated from the scenario seed (the only kind so far)."""

    generate: ArenaGenerate = field(default_factory=ArenaGenerate)


@dataclass(kw_only=True)
class PanSpec:
    """How the mast robot's camera pans (docs/FACTS.md "How a rescue robot searches").

    ``mode: steps`` (the default) scans as a pan-tilt unit does: at each cell the tour enters
    for the first time the base stops, the camera slews at ``rate_dps`` through the pan angles
    ``steps_deg`` (degrees from the base's heading, positive left) in the order given, dwells
    ``dwell_s`` at each, slews back to 0 and the robot drives on looking ahead. Team Hector's
    sensor head scans in steps of 40 degrees out to 80 with a 1 s dwell ([HectorCameraControl]_);
    the defaults, -90 to 90 in 45-degree steps, put each side wall face on in the simulated D435's
    55-degree view with 10 degrees of overlap, and 0.5 s holds the camera still for five frames
    at 10 fps. 120 deg/s is within what a Dynamixel MX-28 (330 deg/s unloaded, [RobotisMX28]_)
    or a PTU-D46 ([PTU-D46]_) turns.

    At a step that faces a wall of the cell (0.6 m away in an RRL cell, where the D435's
    42-degree vertical view spans only 0.27-0.73 m of it from a 0.5 m mast) the head also dwells
    at each tilt of ``wall_tilts_deg`` (up positive) before levelling: at -25 and +25 degrees it
    sees the wall from its foot to 1.1 m, as a sensor head looks down and up a wall within reach.

    ``mode: sweep`` pans continuously, ``pan(t) = amplitude_deg sin(2 pi t / period_s)``, while the
    robot drives and turns without stopping (the default before issue 57).

    References
    ----------
    Full entries in docs/SOURCES.md.

    .. [HectorCameraControl] Team Hector Darmstadt, hector_camera_control (ROS), sensor head
       "look_around" patterns.
    .. [RobotisMX28] ROBOTIS, DYNAMIXEL MX-28 e-Manual, specifications.
    .. [PTU-D46] Directed Perception, PTU-D46 pan-tilt unit user's manual, v2.14.0, 2006.
    """

    mode: Literal["sweep", "steps"] = "steps"
    steps_deg: tuple[float, ...] = number((-90.0, -45.0, 0.0, 45.0, 90.0), lo=-180.0, hi=180.0)
    dwell_s: float = number(0.5, lo=0.0, hi=60.0)
    wall_tilts_deg: tuple[float, ...] = number((-25.0, 25.0), lo=-60.0, hi=60.0)
    rate_dps: float = number(120.0, lo=0.0, hi=1000.0, lo_open=True)
    amplitude_deg: float = number(80.0, lo=-180.0, hi=180.0)
    period_s: float = number(5.0, lo=0.0, lo_open=True)

    def __post_init__(self) -> None:
        if self.mode == "steps" and not self.steps_deg:
            raise ValueError("steps_deg: mode 'steps' needs at least one pan angle, e.g. [-90, -45, 0, 45, 90]")


TURTLEBOT_CAMERA_HEIGHT_M = 0.30  # the D435 on a TurtleBot's top plate


@dataclass(kw_only=True)
class RobotSpec:
    """The robot base and its camera (kinematic: it follows the route exactly).

    ``kind``: ``mast``, the rescue robot whose camera pans on a mast (``pan``); or
    ``turtlebot``, a differential-drive base with the camera fixed on its top plate,
    looking forward (``pan`` does not apply; ``mast_height_m`` is the camera's height,
    default ``TURTLEBOT_CAMERA_HEIGHT_M``). ``route``: ``tour`` (visit every maze
    cell), ``arena`` (the goal arena's look-around and approach, sim/arena_route.py) or
    a CSV file of timed poses ``t,x,y,yaw[,pan]``.
    """

    kind: Literal["mast", "turtlebot"] = "mast"
    route: str = "tour"
    speed_mps: float = 0.3
    yaw_rate_dps: float = 60.0
    mast_height_m: float | None = None  # default: 0.5 m for RRL cells, 0.2 m for RMRC; turtlebot 0.3 m
    tilt_deg: float = 0.0  # positive looks up
    pan: PanSpec = field(default_factory=PanSpec)
    max_duration_s: float | None = None

    def __post_init__(self) -> None:
        if self.speed_mps <= 0 or self.yaw_rate_dps <= 0:
            raise ValueError("speed_mps and yaw_rate_dps must be positive")


@dataclass(kw_only=True)
class DepthSpec:
    """The D435 depth stream's effects (sim/sensors/d435_depth.py; docs/FACTS.md "D435 depth").
    Each is a setting and can be switched off; ``sensors.noise: false`` switches off the random
    ones and the depth-dependent holes, leaving the range limits and the Z16 unit.

    Stereo: ``fx_depth_px`` (the depth imager's focal length in the resolution mode used:
    384.2 px at 640x480), ``baseline_m``; disparity noise ``sigma_d_px`` rounded to
    ``subpixel`` steps, spread over the stereo matcher's ``window_px`` x ``window_px`` window
    (1: independent pixels), plus a per-trial fixed pattern ``fixed_pattern`` times as large.
    Range: ``min_m`` (default: ``fx_depth_px * baseline_m / disparity_search_px``, the
    D4 matcher's 126-pixel search) and ``max_m``; closer than ``min_m`` a pixel reads 0
    (``below_min: zero``) or a wrong depth (``wrong``). Holes: the stereo shadow of near
    objects on their left (``edge_holes``) widened by the colour camera's offset
    ``colour_offset_m`` to the left of the depth reference (alignment disocclusion);
    ``dropout``, a random fraction. Texture (``texture``): the noise grows and the fill falls
    where the surface has less local contrast than ``texture_ref`` (linear luminance std over
    the window) counting the IR projector's dots (``projector_range_m``); below
    ``min_texture`` times that, holes. Pixels brighter than ``saturation`` (linear, 0..1;
    specular highlights, lamps) read 0. ``flying_pixels``: the chance that a pixel at a
    depth edge reads a depth between the two sides. ``registration_error_px``: RMS offset
    of the depth image against the colour image, drawn once per trial. Output: Z16 counts of
    ``depth_unit_m`` (1 mm), handed on in metres.
    """

    noise: bool = True
    sigma_d_px: float = number(0.08, lo=0.0, lo_open=True)  # subpixel disparity noise
    baseline_m: float = number(0.05, lo=0.0, lo_open=True)
    fx_depth_px: float = number(384.2, lo=0.0, lo_open=True)  # depth imager focal length at 640x480
    subpixel: float = number(1.0 / 32.0, lo=0.0, lo_open=True)
    min_m: float | None = number(None, lo=0.0)  # None: fx_depth_px * baseline_m / disparity_search_px
    disparity_search_px: float = number(126.0, lo=1.0)
    below_min: Literal["zero", "wrong"] = "zero"
    max_m: float = number(10.0, lo=0.0, lo_open=True)
    edge_holes: bool = True
    colour_offset_m: float = number(0.015, lo=0.0, hi=1.0)
    dropout: float = number(0.002, lo=0.0, hi=1.0, hi_open=True)  # fraction of pixels randomly invalid
    window_px: int = number(7, lo=1, hi=31)
    fixed_pattern: float = number(0.3, lo=0.0, hi=10.0)
    texture: bool = True
    texture_ref: float = number(0.02, lo=0.0, lo_open=True)
    projector_range_m: float = number(3.0, lo=0.0)
    min_texture: float = number(0.25, lo=0.0, hi=1.0)
    max_noise_gain: float = number(4.0, lo=1.0)
    saturation: float = number(0.98, lo=0.0, hi=1.0, lo_open=True)
    flying_pixels: float = number(0.5, lo=0.0, hi=1.0)
    registration_error_px: float = number(1.0, lo=0.0, hi=20.0)
    depth_unit_m: float = number(0.001, lo=0.0, hi=0.01, lo_open=True)

    def __post_init__(self) -> None:
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")
        for name in ("sigma_d_px", "baseline_m", "fx_depth_px", "subpixel", "max_m", "depth_unit_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.min_range_m < self.max_m:
            raise ValueError(f"need 0 <= min_m < max_m, got min_m={self.min_range_m}, max_m={self.max_m}")
        if self.max_m / self.depth_unit_m > 65535:
            raise ValueError(f"max_m {self.max_m} m does not fit Z16 counts of depth_unit_m {self.depth_unit_m} m")

    @property
    def min_range_m(self) -> float:
        """The minimum range: ``min_m``, or where the disparity reaches the matcher's search
        range, f B / d_max ([IntelTuning]: MinZ = focal length x baseline / 126)."""
        if self.min_m is not None:
            return self.min_m
        return self.fx_depth_px * self.baseline_m / self.disparity_search_px


@dataclass(kw_only=True)
class ColourSpec:
    """The D435 colour stream's camera effects (sim/sensors/d435_color.py; docs/FACTS.md
    "D435 colour camera"). Each is a setting and can be switched off; ``sensors.noise: false``
    switches off the random ones (noise) and the blurs, compression and white-balance error,
    leaving exposure and tone.

    Light: ``lux`` is the illuminance on a white surface the robot's lamp lights (default: the
    lighting preset's level, ``sim.world.LIGHT_LEVEL_LUX``; the render's shading sets the rest,
    ``sim.world.lux_of_decoded_one``); a white surface in full light gives
    ``sensitivity_e_per_lux_ms`` electrons per lux and millisecond of exposure at unit gain.
    Auto-exposure (``auto_exposure``) meters the mean linear level and sets exposure first
    (``min_exposure_ms`` .. ``max_exposure_ms``), then analog gain (1 .. ``max_gain``), so the
    mean lands at ``ae_target`` (encoded, 0..1), with a first-order lag ``ae_time_constant_s``;
    without it, ``exposure_ms`` and ``gain`` hold. Noise: shot noise (Poisson in electrons)
    plus ``read_noise_e``, relative to ``full_well_e``. Output: display gamma ``gamma``.
    Blurs: the camera's own motion during the exposure (``motion_blur``), ``defocus_sigma_px``
    (Gaussian). ``vignetting``: the fraction of the cos^4 falloff left after the lens'
    correction (0: none). ``wb_gains``: per-channel (R, G, B) white-balance error.
    ``jpeg_quality``: JPEG compression of the delivered image (0, the default: off, as the
    D435 sends its colour frames uncompressed over USB; a robot that sends them on as JPEG
    sets its quality).
    """

    auto_exposure: bool = True
    ae_target: float = number(0.6, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    ae_time_constant_s: float = number(0.15, lo=0.0)
    exposure_ms: float = number(10.0, lo=0.0, lo_open=True)
    gain: float = number(1.0, lo=1.0)
    min_exposure_ms: float = number(0.1, lo=0.0, lo_open=True)
    max_exposure_ms: float = number(10.0, lo=0.0, lo_open=True)
    max_gain: float = number(16.0, lo=1.0)
    lux: float | None = number(None, lo=0.0, lo_open=True)
    sensitivity_e_per_lux_ms: float = number(0.2, lo=0.0, lo_open=True)
    full_well_e: float = number(5000.0, lo=1.0)
    read_noise_e: float = number(3.0, lo=0.0)
    shot_noise: bool = True
    gamma: float = number(2.2, lo=1.0, hi=4.0)
    motion_blur: bool = True
    defocus_sigma_px: float = number(0.5, lo=0.0, hi=20.0)
    vignetting: float = number(0.4, lo=0.0, hi=1.0)
    wb_gains: tuple[float, float, float] = number((1.04, 1.0, 0.95), lo=0.0, lo_open=True)
    jpeg_quality: int = number(0, lo=0, hi=100)

    def __post_init__(self) -> None:
        if self.min_exposure_ms > self.max_exposure_ms:
            raise ValueError(
                f"min_exposure_ms ({self.min_exposure_ms}) must not exceed "
                f"max_exposure_ms ({self.max_exposure_ms})"
            )


@dataclass(kw_only=True)
class D435Spec:
    enabled: bool = True
    width: int = number(640, lo=1, hi=MAX_IMAGE_PX)
    height: int = number(480, lo=1, hi=MAX_IMAGE_PX)
    fx: float = number(612.4, lo=0.0, lo_open=True)
    fy: float = number(610.6, lo=0.0, lo_open=True)
    ppx: float = 314.3
    ppy: float = 237.8
    colour: ColourSpec = field(default_factory=ColourSpec)
    depth: DepthSpec = field(default_factory=DepthSpec)


@dataclass(kw_only=True)
class JumpSpec:
    """False relocalisations: Poisson jumps of N(0, sigma_m^2) in x and y, at ``rate_per_min``
    in good conditions (times the T265's drift multiplier where the scene is dim or bare)."""

    rate_per_min: float = number(0.0, lo=0.0)
    sigma_m: float = number(0.2, lo=0.0)


@dataclass(kw_only=True)
class DropoutSpec:
    rate_per_min: float = number(0.0, lo=0.0)
    duration_s: tuple[float, float] = number((3.0, 7.0), lo=0.0)

    def __post_init__(self) -> None:
        if self.duration_s[0] > self.duration_s[1]:
            raise ValueError(f"duration_s: expected (shortest, longest), got {list(self.duration_s)}")


@dataclass(kw_only=True)
class T265ConditionsSpec:
    """How the scene's light and texture where the robot is scale the T265's drift
    (sim/sensors/tracking_conditions.py; **poibench**'s model, docs/FACTS.md "T265 tracking camera").

    The drift rate (and the false-jump rate) is multiplied by
    1 + dim_gain * clip(1 - lux / good_lux, 0, 1) + bare_gain * clip(1 - contrast / good_contrast, 0, 1)
    with ``lux`` the light the robot's lamp and the scene's lamps give where it is and
    ``contrast`` the RMS contrast of the wall and floor textures around it.
    """

    good_lux: float = number(500.0, lo=0.0, lo_open=True)
    dim_gain: float = number(2.0, lo=0.0)
    good_contrast: float = number(0.12, lo=0.0, lo_open=True)
    bare_gain: float = number(2.0, lo=0.0)
    radius_m: float = number(1.5, lo=0.0, lo_open=True)  # walls this near the robot count


@dataclass(kw_only=True)
class RelocaliseSpec:
    """Loop closure: back at a place it mapped ``min_gap_m`` or more of travel ago (within
    ``radius_m``, heading within ``max_heading_deg``), the T265 recognises it with probability
    ``probability`` / multiplier per keyframe (one every ``keyframe_m``), and its pose jumps back
    toward the truth: ``strength`` of the error gained since that visit is removed.
    **poibench**'s model of librealsense's relocalisation with pose jumping on ([T265Issues])."""

    enabled: bool = True
    radius_m: float = number(0.5, lo=0.0, lo_open=True)
    min_gap_m: float = number(5.0, lo=0.0)
    max_heading_deg: float = number(60.0, lo=0.0, hi=180.0)
    probability: float = number(0.3, lo=0.0, hi=1.0)
    strength: float = number(1.0, lo=0.0, hi=1.0)
    keyframe_m: float = number(0.5, lo=0.0, lo_open=True)


@dataclass(kw_only=True)
class T265Spec:
    """The T265 pose model (sim/sensors/t265.py; docs/FACTS.md "T265 tracking camera").

    Per-axis drift, in distance travelled (times the conditions' multiplier): ``drift_fraction``
    (x and y: a random walk whose size grows by this fraction of the distance, its direction
    wandering), ``z_drift_fraction`` (z: a rate drawn once, N(0, this^2) metres per metre),
    ``yaw_drift_deg_per_m`` (yaw: a bias of this size, its sign drawn once), ``tilt_sigma_deg``
    and ``tilt_correlation_m`` (roll and pitch: bounded, a Gauss-Markov error of this standard
    deviation and correlation length; gravity keeps them observable). Poses come at
    ``rate_hz`` with white ``jitter_m`` / ``jitter_deg`` per sample; frame k gets the pose of
    time t_k - ``latency_s`` (SE(3)-interpolated between samples), or that pose extrapolated
    to t_k at the last samples' velocity with ``latency_extrapolate``.
    """

    enabled: bool = True
    drift_fraction: float = number(0.007, lo=0.0)
    z_drift_fraction: float = number(0.002, lo=0.0)
    yaw_drift_deg_per_m: float = number(0.08, lo=0.0)
    tilt_sigma_deg: float = number(0.3, lo=0.0)
    tilt_correlation_m: float = number(5.0, lo=0.0, lo_open=True)
    scale_error: float = number(0.0, lo=-1.0, lo_open=True)  # -0.2 means distances reported 20% short
    rate_hz: float = number(200.0, lo=1.0, hi=1000.0)
    latency_s: float = number(0.01, lo=0.0, hi=1.0)
    latency_extrapolate: bool = False
    jitter_m: float = number(0.0005, lo=0.0)
    jitter_deg: float = number(0.02, lo=0.0)
    conditions: T265ConditionsSpec = field(default_factory=T265ConditionsSpec)
    relocalise: RelocaliseSpec = field(default_factory=RelocaliseSpec)
    jumps: JumpSpec = field(default_factory=JumpSpec)
    dropouts: DropoutSpec = field(default_factory=DropoutSpec)


@dataclass(kw_only=True)
class WheelOdometrySpec:
    """Differential-drive wheel odometry (sim/sensors/wheel_odometry.py). Defaults: a
    TurtleBot 2 (Kobuki base, 0.23 m between the wheels) on a hard floor.

    Systematic errors (fixed for a run): ``wheel_radius_error`` (the radius the odometry
    assumes over the true one, minus 1: +0.05 reports every distance and turn 5% long),
    ``wheel_radius_mismatch`` (true right minus left wheel radius over their mean: a
    straight run curves), ``wheel_base_error`` (the wheel base the odometry assumes over
    the true one, minus 1: +0.02 reports turns 2% short). Random slip, a random walk in
    distance travelled: ``slip_m_per_sqrt_m`` (distance error sigma after 1 m driven),
    ``slip_rad_per_sqrt_rad`` (heading error sigma after 1 rad turned),
    ``slip_rad_per_sqrt_m`` (heading error sigma after 1 m driven).
    """

    wheel_base_m: float = 0.23
    wheel_radius_error: float = 0.01  # worn or soft tyres: about 1%
    wheel_radius_mismatch: float = 0.002  # UMBmark-size diameter ratio error: about 0.5 deg per metre
    wheel_base_error: float = 0.01  # the contact patches' spread: about 1%, 3.6 deg per full turn
    slip_m_per_sqrt_m: float = 0.01
    slip_rad_per_sqrt_rad: float = 0.02  # about 2.9 deg after a full turn in place
    slip_rad_per_sqrt_m: float = 0.005

    def __post_init__(self) -> None:
        if self.wheel_base_m <= 0:
            raise ValueError(f"wheel_base_m: expected a positive number, got {self.wheel_base_m}")
        for name in ("wheel_radius_error", "wheel_base_error"):
            if getattr(self, name) <= -1.0:
                raise ValueError(f"{name}: expected a relative error > -1, got {getattr(self, name)}")
        if not abs(self.wheel_radius_mismatch) < 2.0:
            raise ValueError(
                f"wheel_radius_mismatch: expected a number in (-2, 2), got {self.wheel_radius_mismatch}"
            )
        for name in ("slip_m_per_sqrt_m", "slip_rad_per_sqrt_rad", "slip_rad_per_sqrt_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name}: expected a number >= 0, got {getattr(self, name)}")


@dataclass(kw_only=True)
class ThermalSpec:
    """The thermal camera (sim/sensors/thermal.py; docs/FACTS.md "Thermal camera"; all
    **poibench**'s choices). The air: ``ambient_c`` at ``reference_height_m``, warming by
    ``vertical_gradient_c_per_m`` per metre up and changing by ``horizontal_gradient_c_per_m``
    per metre along a direction drawn from the seed. Lamp panels at ``lamp_c``; metal reads
    ``metal_emissivity`` of its own temperature and the rest from what it mirrors. Sensor:
    NETD ``netd_k`` (per pixel and frame), optical blur ``blur_px``, fixed-pattern noise
    ``fpn_sigma_k`` drifting by ``fpn_drift_k_per_min`` until the flat-field correction
    every ``ffc_interval_s``.
    """

    enabled: bool = True
    width: int = number(160, lo=1, hi=MAX_IMAGE_PX)
    height: int = number(120, lo=1, hi=MAX_IMAGE_PX)
    ambient_c: float = number(20.0, lo=-50.0, hi=60.0)
    netd_k: float = number(0.08, lo=0.0)
    blur_px: float = number(0.8, lo=0.0)
    reference_height_m: float = 0.5
    vertical_gradient_c_per_m: float = number(1.0, lo=-10.0, hi=10.0)
    horizontal_gradient_c_per_m: float = number(0.2, lo=-10.0, hi=10.0)
    lamp_c: float = number(40.0, lo=-50.0, hi=500.0)
    metal_emissivity: float = number(0.1, lo=0.0, hi=1.0)
    fpn_sigma_k: float = number(0.2, lo=0.0)
    fpn_drift_k_per_min: float = number(0.1, lo=0.0)
    ffc_interval_s: float = number(120.0, lo=0.0, lo_open=True)

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
    # the preset's lamps cast shadows (sim/world.py _lights): off in trials for its cost (a
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
    return scenario_from_data(data, src, source_dir=str(p.resolve().parent))


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
            value = safe_load(raw, f"--set {key}")
        except LoadError:
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
    return scenario_from_data(data, Source("--set"), source_dir=sc.source_dir)


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
    "convert",
]
