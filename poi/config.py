"""The pipeline's settings: one validated config, loaded from YAML, settable by dotted keys.

Every threshold the pipeline uses lives here; ``poi/configs/default.yaml`` carries
the defaults with a comment per key (it is the documentation). A user file may
give any subset of keys; the rest keep their defaults. Unknown keys and values of
the wrong type or range are refused with :class:`ConfigError` naming the dotted
key and what was expected.

>>> cfg = apply_overrides(load_config(), ["tracker.gate=4", "detector.conf=0.3"])
>>> cfg.tracker.gate, cfg.detector.conf
(4.0, 0.3)
>>> apply_overrides(cfg, ["tracker.gaet=4"])  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
poi.config.ConfigError: tracker.gaet: unknown key; expected one of Sigma0_diag, assignment, ...

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from poi.core.geometry import make_transform, quat_wxyz_to_matrix
from poi.core.loader import FieldError, LoadError, Source, build, load_yaml_file, number, safe_load, show
from poi.core.names import TYPES
from poi.core.sensor_noise import CENTER_SIGMA_A_PX, CENTER_SIGMA_B

DEFAULT_CONFIG_PATH = Path(__file__).resolve().parent / "configs" / "default.yaml"
DEFAULT_PROVIDER = "CPUExecutionProvider"  # onnxruntime's; poi.detectors.base.CPU_PROVIDER


class ConfigError(LoadError):
    """An unknown setting, or one of the wrong type or range; the message names its dotted key."""


def check_per_type(key: str, values: dict[str, float], in_range: Callable[[float], bool], expected: str) -> None:
    """A per-type table of a config section: every key a canonical type, every value
    ``in_range``; else a FieldError naming ``key.type`` and what was ``expected``."""
    for t, v in values.items():
        if t not in TYPES:
            raise FieldError(f"{key}.{t}", f"unknown type; expected one of {', '.join(TYPES)}")
        if not in_range(v):
            raise FieldError(f"{key}.{t}", f"expected {expected}, got {v!r}")


@dataclass(kw_only=True)
class TrackerConfig:
    """Tracking ([Avevor2022]_ section 2.4, [Bouda2025]_ section 2.2.5)."""

    gate: float = number(9.0, lo=0.0, lo_open=True)
    gates: dict[str, float] = field(default_factory=dict)
    # Per type, metres: the association's m^2 adds allowance^2 I to Sigma + R (poi.estimation.tracker)
    gate_allowance_m: dict[str, float] = field(
        default_factory=lambda: {
            "door": 0.28,
            "valve": 0.14,
            "fire-extinguisher": 0.11,
            "baby-doll": 0.17,
            "heat-source": 0.17,
            "hazmat": 0.017,
            "qr": 0.017,
            "exit-sign": 0.017,
            "fire-extinguisher-sign": 0.017,
        }
    )
    n_min: int = number(3, lo=1)
    t_max: float = number(5.0, lo=0.0, lo_open=True)
    assignment: Literal["greedy", "hungarian"] = "greedy"
    settle_sigma_m: float = number(0.3, lo=0.0, lo_open=True)
    miss_penalty: float = number(0.5, lo=0.0)
    drop_support: float = 0.0
    fusion: Literal["mean", "confusion"] = "mean"
    sigma_eps_m: float = number(0.05, lo=0.0)
    shared_errors: bool = True
    shared_change: float = number(0.02, lo=0.0)
    init: Literal["observation", "prior"] = "observation"
    mu0: tuple[float, float, float] = (0.0, 0.0, 1.0)
    Sigma0_diag: tuple[float, float, float] = number((100.0, 100.0, 4.0), lo=0.0, lo_open=True)
    # a track is not confirmed, or is withdrawn, beside a better-seen track of another type (poi.estimation.tracker
    # step 6)
    cross_type_radius_m: float = number(0.2, lo=0.0, hi=10.0, hi_open=True)
    # a QR track is not confirmed, or is withdrawn, near an earlier confirmed one of its text (step 7)
    same_text_radius_m: float = number(1.0, lo=0.0, hi=10.0, hi_open=True)
    qr_requires_text: bool = True  # a QR or Landolt-C track is confirmed only once it has text
    landolt_required_rings: tuple[int, ...] = (3,)  # ...and a Landolt-C one once these rings read

    def __post_init__(self) -> None:
        if any(isinstance(k, bool) or not isinstance(k, int) or k < 1 for k in self.landolt_required_rings):
            raise FieldError(
                "landolt_required_rings",
                f"expected ring numbers >= 1 (1 = the outermost), got {list(self.landolt_required_rings)!r}",
            )
        check_per_type("gates", self.gates, lambda g: g > 0, "a value > 0")
        check_per_type("gate_allowance_m", self.gate_allowance_m, lambda a: 0.0 <= a < 10.0, "metres in [0, 10)")


@dataclass(kw_only=True)
class DetectorConfig:
    """The spec for ``poi.detectors.build_detector`` (see :meth:`PipelineConfig.detector_spec`)."""

    name: str = "onnx"
    model: str | None = None
    conf: float = number(0.4, lo=0.0, hi=1.0)
    nms_iou: float = number(0.45, lo=0.0, hi=1.0)
    imgsz: int | None = number(None, lo=1)
    letterbox: Literal["square", "rect"] = "square"
    providers: list[str] = field(default_factory=lambda: [DEFAULT_PROVIDER])
    label_model: str | None = None
    # Per object type, the confidence threshold in place of conf (an ONNX detector's).
    type_conf: dict[str, float] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check_per_type("type_conf", self.type_conf, lambda c: 0.0 <= c <= 1.0, "a score in [0, 1]")
        if not self.providers:
            raise FieldError(
                "providers", f"expected at least one onnxruntime execution provider, e.g. {DEFAULT_PROVIDER}"
            )


@dataclass(kw_only=True)
class CenterSigmaConfig:
    """Default centre-error model ([Avevor2022]_ 2.1.4): sigma_u = a + b w, sigma_v = a + b h (px)."""

    a_px: float = number(CENTER_SIGMA_A_PX, lo=0.0)
    b: float = number(CENTER_SIGMA_B, lo=0.0)


SHAPES = ("flat", "turned-square", "body", "leaf")  # poi.estimation.shapes registers one class each
FLAT_SHAPES = ("flat", "turned-square")


@dataclass(kw_only=True)
class TypeShapeConfig:
    """One type's row of ``localize.types``: the shape that localises it and its numbers
    (poi.estimation.shapes: flat, a flat sign; turned-square, a diamond placard hung at any
    in-plane turn; body, a solid 3-D item; leaf, a 3-D item whose hidden part goes on along its
    depth plane, a door's leaf or a doll lying on the floor)."""

    # The geometry that localises the type (poi.estimation.shapes): flat, turned-square, body or leaf.
    shape: Literal["flat", "turned-square", "body", "leaf"] = "body"
    # A flat shape's width over its height (poi.estimation.box_cuts.hidden_lengths_px).
    aspect: float | None = number(None, lo=0.0, lo_open=True)
    # A 3-D shape's width (m) its box spans in full view, at its centre's depth; null: not known
    # (poi.estimation.box_cuts.hidden_solid_px).
    box_width_m: float | None = number(None, lo=0.0, hi=10.0, lo_open=True, hi_open=True)
    # The same of its height.
    box_height_m: float | None = number(None, lo=0.0, hi=10.0, lo_open=True, hi_open=True)
    # From the surface the depth hits to the reference point (m), along the camera ray;
    # negative: before it (poi.estimation.projection.surface_to_center).
    surface_to_center_m: float = number(0.0, lo=-1.0, hi=1.0, lo_open=True, hi_open=True)
    # The reference point's spread (m) across the camera ray
    # (poi.estimation.localize.extent_covariance).
    extent_sigma_m: float = number(0.0, lo=0.0, hi=1.0, hi_open=True)
    # Its spread (m) along the camera ray; null: as across.
    extent_ray_sigma_m: float | None = number(None, lo=0.0, hi=1.0, hi_open=True)

    def __post_init__(self) -> None:
        flat = self.shape in FLAT_SHAPES
        if flat and self.aspect is None:
            raise FieldError("aspect", f"a {self.shape} shape needs its width / height ratio")
        if not flat and self.aspect is not None:
            raise FieldError(
                "aspect", f"a {self.shape} shape has no aspect (a {' or '.join(FLAT_SHAPES)} one has)"
            )
        for key in ("box_width_m", "box_height_m"):
            if flat and getattr(self, key) is not None:
                raise FieldError(key, f"a {self.shape} shape: its cut is judged by its aspect, not a size")
        if self.shape == "leaf" and self.box_width_m is None and self.box_height_m is None:
            raise FieldError("shape", "a leaf needs box_width_m or box_height_m (its cut goes on along its plane)")


def _row(shape: str, **numbers: float) -> TypeShapeConfig:
    return TypeShapeConfig(shape=shape, **numbers)  # type: ignore[arg-type]


def default_type_shapes() -> dict[str, TypeShapeConfig]:
    """``localize.types`` as poi/configs/default.yaml gives it (its comments say whence each number)."""
    return {
        "hazmat": _row("turned-square", aspect=1.0),
        "qr": _row("flat", aspect=1.0),
        "fire-extinguisher-sign": _row("flat", aspect=1.0),
        "exit-sign": _row("flat", aspect=2.0),
        "door": _row(
            "leaf",
            box_width_m=0.793,
            box_height_m=1.362,
            surface_to_center_m=0.064,
            extent_sigma_m=0.032,
            extent_ray_sigma_m=0.038,
        ),
        "baby-doll": _row(
            "leaf",
            box_width_m=0.37,
            box_height_m=0.165,
            surface_to_center_m=0.059,
            extent_sigma_m=0.008,
            extent_ray_sigma_m=0.031,
        ),
        "valve": _row(
            "body",
            box_width_m=0.256,
            box_height_m=0.256,
            surface_to_center_m=-0.056,
            extent_sigma_m=0.011,
            extent_ray_sigma_m=0.047,
        ),
        "fire-extinguisher": _row(
            "body",
            box_width_m=0.164,
            box_height_m=0.524,
            surface_to_center_m=0.065,
            extent_sigma_m=0.011,
            extent_ray_sigma_m=0.001,
        ),
        "heat-source": _row(
            "body",
            box_width_m=0.328,
            box_height_m=0.357,
            surface_to_center_m=0.102,
            extent_sigma_m=0.008,
            extent_ray_sigma_m=0.037,
        ),
        "pillar-blue": _row("body", surface_to_center_m=0.025),
        "pillar-red": _row("body", surface_to_center_m=0.025),
        "pillar-green": _row("body", surface_to_center_m=0.025),
        "ball": _row("body", surface_to_center_m=0.105),
    }


@dataclass(kw_only=True)
class LocalizeConfig:
    """Depth reading and deprojection ([Avevor2022]_ section 2.2, [Bouda2025]_ section 2.1.3)."""

    mode: Literal["t265", "slam"] = "slam"
    depth_scale: float = number(1.0, lo=0.0, lo_open=True)
    inner_fraction: float = number(0.5, lo=0.0, hi=1.0, lo_open=True)
    # A box whose inner part holds valid depth in fewer than this fraction of its pixels gives
    # no observation: past a near edge an item lies in the edge's stereo shadow, and the few
    # valid pixels are the occluder's (poi.estimation.localize.box_depth).
    min_depth_fill: float = number(0.4, lo=0.0, hi=1.0)
    # A box whose inner valid depths lie more than depth_split_m from their median in more
    # than max_depth_split of its pixels holds two surfaces (an occluder before the item, a
    # wall behind it) and gives no observation; 1 turns the check off (box_depth).
    depth_split_m: float = number(0.3, lo=0.0, lo_open=True)
    max_depth_split: float = number(0.25, lo=0.0, hi=1.0)
    sigma_d_px: float = number(0.08, lo=0.0)
    baseline_m: float = number(0.05, lo=0.0, lo_open=True)
    fx_depth_px: float = number(384.2, lo=0.0, lo_open=True)
    min_depth_m: float = number(0.28, lo=0.0)
    max_depth_m: float = number(10.0, lo=0.0, lo_open=True)
    center_sigma_px: CenterSigmaConfig = field(default_factory=CenterSigmaConfig)
    mount_sigma_deg: float = number(0.5, lo=0.0, hi=10.0)
    mount_sigma_m: float = number(0.005, lo=0.0, hi=0.5)
    # RMS length (px) of the depth image's registration error against the colour image, the
    # same all run long (poi.estimation.localize.registration_depth_variance).
    registration_sigma_px: float = number(1.0, lo=0.0, hi=20.0)
    # Side (px) of the window over which the depth camera's errors correlate (the stereo
    # matching window): the depth plane's slope variances are scaled by its square.
    depth_window_px: float = number(7.0, lo=1.0)
    # Per type, its shape (poi.estimation.shapes) and that shape's numbers: one row a type
    # (TypeShapeConfig). A type without a row is a body of no known size, its depth's surface
    # its reference point.
    types: dict[str, TypeShapeConfig] = field(default_factory=default_type_shapes)
    # A flat item is measured on the depth plane (centre, truncation) only when the plane's
    # tilt is known to this standard deviation (of its tangent) or better.
    flat_max_slope_sigma: float = number(0.2, lo=0.0)
    # A flat item whose tilt is not known that well is judged cut only when no tilt within
    # this many standard errors of the whole box's depth plane explains its shortfall.
    flat_tilt_sigmas: float = number(2.0, lo=0.0)
    # A box side within this many pixels of the image's edge touches it (the item may go on).
    border_px: float = number(8.0, lo=0.0)
    # A flat item's box touches the border also when its side lies within this many of its
    # centre sigmas beyond border_px (a cut box's edge jitters inward with the box).
    flat_border_sigmas: float = number(2.5, lo=0.0)
    # The same for a 3-D body's box (a body shape with a box size; a leaf keeps border_px).
    body_border_sigmas: float = number(2.5, lo=0.0)
    # A 3-D item's box is cut on an axis also where a surface more than this much (m) nearer
    # borders it there (poi.estimation.box_cuts.occluded_sides), and a flat item's only where
    # such a surface or the image border does; 0 turns the check off.
    occluder_margin_m: float = number(0.15, lo=0.0)
    # The hidden length's own error, as a fraction of it, beyond what the box's shape error
    # gives (the plane's tilt, a slanted sign's perspective); half of it adds to the centre's.
    hidden_length_sigma: float = number(0.25, lo=0.0)
    # A box counts as cut on an axis when it is shorter than the aspect says by more than this
    # fraction (the detector's box sizes jitter: the oracle's by 5% a side, 7% in the ratio).
    truncation_tolerance: float = number(0.05, lo=0.0, hi=1.0, hi_open=True)

    def __post_init__(self) -> None:
        for t in self.types:
            if t not in TYPES:
                raise FieldError(f"types.{t}", f"unknown type; expected one of {', '.join(TYPES)}")
        if self.max_depth_m <= self.min_depth_m:
            raise FieldError(
                "max_depth_m", f"expected a value > min_depth_m ({self.min_depth_m:g}), got {self.max_depth_m!r}"
            )


@dataclass(kw_only=True)
class SlamConfig:
    """UKF-SLAM drift correction ([Bouda2025]_ 2.2.1-2.2.5), used when ``localize.mode`` is slam."""

    alpha: float = number(1.0, lo=0.0, lo_open=True)
    beta: float = number(2.0, lo=0.0)
    kappa: float | None = 0.0
    sigma_xy_m: float = number(0.0005, lo=0.0)
    sigma_xy_per_m: float = number(0.005, lo=0.0)
    sigma_theta_rad: float = number(0.0003, lo=0.0)
    sigma_theta_per_rad: float = number(0.002, lo=0.0)
    sigma_theta_per_m: float = number(0.002, lo=0.0)
    scale_sigma: float = number(0.1, lo=0.0)
    scale_sigma_per_m: float = number(0.001, lo=0.0)
    drift_sigma: float = number(0.02, lo=0.0)
    drift_sigma_per_sqrt_m: float = number(0.002, lo=0.0)
    heading_drift_sigma: float = number(0.003, lo=0.0)
    heading_drift_sigma_per_sqrt_m: float = number(0.0003, lo=0.0)
    sigma_eps_m: float = number(0.002, lo=0.0)
    height_drift_sigma_per_m: float = number(0.002, lo=0.0)
    tilt_sigma_deg: float = number(0.3, lo=0.0, hi=90.0)
    max_speed_m_s: float = number(1.5, lo=0.0, lo_open=True)
    relocalisation_speed_sigma_m_s: float = number(0.05, lo=0.0)
    relocalisation_turn_sigma_rad_s: float = number(0.25, lo=0.0)
    odometry_latency_s: float = number(0.01, lo=0.0, hi=1.0)
    start_sigma_m: float = number(0.005, lo=0.0, lo_open=True)
    start_sigma_rad: float = number(0.0005, lo=0.0, lo_open=True)
    associate_m: float = number(0.5, lo=0.0, lo_open=True)
    # Huber's weight on a landmark update whose NIS (2 dof) exceeds robust_nis: its innovation
    # covariance is scaled by sqrt(NIS / robust_nis) (poi.estimation.slam.huber_scale); 0: off.
    robust_nis: float = number(9.21, lo=0.0)
    n_min: int = number(4, lo=0)
    t_max_s: float = number(3.0, lo=0.0, lo_open=True)
    shared_errors: bool = True
    view_decorrelation_deg: float = number(10.0, lo=0.0, lo_open=True)
    max_range_m: float = number(4.0, lo=0.0, lo_open=True)
    landmark_types: list[str] = field(
        default_factory=lambda: [
            "exit-sign",
            "fire-extinguisher-sign",
            "hazmat",
            "qr",
            "valve",
            "door",
            "pillar-blue",
            "pillar-red",
            "pillar-green",
        ]
    )

    def __post_init__(self) -> None:
        for i, t in enumerate(self.landmark_types):
            if t not in TYPES:
                raise FieldError(f"landmark_types[{i}]", f"unknown type {t!r}; expected one of {', '.join(TYPES)}")


@dataclass(kw_only=True)
class VisibilityConfig:
    """When a track counts as in view for the negative update (docs/FACTS.md "Tracking")."""

    margin_px: float = number(20.0, lo=0.0)
    max_range_m: float = number(4.0, lo=0.0, lo_open=True)
    occlusion_tolerance_m: float = number(0.3, lo=0.0)


@dataclass(kw_only=True)
class TransformConfig:
    """A rigid transform: translation (m) and unit quaternion in (w, x, y, z) order."""

    translation_m: tuple[float, float, float] = (0.0, 0.0, 0.045)
    quaternion_wxyz: tuple[float, float, float, float] = (0.5, -0.5, 0.5, -0.5)

    def __post_init__(self) -> None:
        n = float(np.linalg.norm(self.quaternion_wxyz))
        if abs(n - 1.0) > 1e-3:
            raise FieldError("quaternion_wxyz", f"expected a unit quaternion, got norm {n:.6f}")

    def matrix(self) -> np.ndarray:
        """The 4x4 homogeneous matrix."""
        return make_transform(quat_wxyz_to_matrix(self.quaternion_wxyz), self.translation_m)


@dataclass(kw_only=True)
class MountConfig:
    """The D435 colour optical frame in the T265 frame: p_tracker = Q0 p_c + t0 ([Avevor2022]_ 2.3.1)."""

    T_tracker_camera: TransformConfig = field(default_factory=TransformConfig)


@dataclass(kw_only=True)
class ThermalConfig:
    """The thermal camera's heat sources (poi.detectors.thermal) and what they vouch for.

    ``confirm_colour_boxes``: a heat-source box of another detector (a colour network's)
    counts only where a thermal detection of the same frame overlaps it
    (:func:`poi.heat_sources.vouched_for`); off with ``enabled``."""

    enabled: bool = True
    confirm_colour_boxes: bool = True


@dataclass(kw_only=True)
class QrConfig:
    """QR text reading (poi.detectors.qr).

    ``settled_votes``: a QR detection whose observation falls inside the gate of a
    QR track whose text has been read this many times, and whose box holds that track's
    projected centre, is not decoded again (its position still updates the track: an
    empty text pairs with any QR track); a box beside it is another code and is decoded. 0
    decodes every QR detection. Detections without an observation (no valid
    depth) are not decoded on frames with a pose and depth, since they cannot
    feed a track.
    """

    enabled: bool = True
    settled_votes: int = number(3, lo=0)
    # the colour camera's exposure cap (the robot's auto-exposure setting): where a frame does not
    # give its own exposure, a slew's blur is undone at exposures from this down to a quarter of it
    # (poi.core.motion_blur.EXPOSURE_LADDER)
    max_exposure_ms: float = number(10.0, lo=0.0, lo_open=True)


@dataclass(kw_only=True)
class FiducialConfig:
    """Mapping fiducials from depth (poi.estimation.fiducials): off unless a run asks for them
    (``poibench run`` does under a preset that judges the QR mapping bonus by fiducials).
    Heights are above the floor, in the map frame."""

    enabled: bool = False
    every_n_frames: int = number(4, lo=1)
    stride_px: int = number(4, lo=1, hi=64)
    max_range_m: float = number(3.0, lo=0.2)
    cell_m: float = number(0.02, lo=0.005, hi=0.1)
    low_m: tuple[float, float] = (0.08, 0.42)
    high_m: tuple[float, float] = (0.6, 1.1)
    min_hits: int = number(3, lo=1)
    min_cells: int = number(15, lo=3)
    top_m: float = number(0.12, lo=0.0)
    min_top_fraction: float = number(0.3, lo=0.0, hi=1.0)
    radius_m: tuple[float, float] = (0.12, 0.18)
    max_rms_m: float = number(0.03, lo=0.0)

    def __post_init__(self) -> None:
        for name in ("low_m", "high_m", "radius_m"):
            a, b = getattr(self, name)
            if not 0 <= a < b:
                raise FieldError(f"fiducials.{name}", f"expected [low, high] with 0 <= low < high, got [{a}, {b}]")


@dataclass(kw_only=True)
class ReportConfig:
    """Header and row values of the POI file (docs/RULES.md "The POI file")."""

    team: str = "poibench"
    country: str = "Simland"
    mission: str = "mission"
    robot: str = "poibench"
    mode: Literal["T", "A"] = "A"
    poi_version: Literal["1.2", "1.3"] = "1.2"


@dataclass(kw_only=True)
class PipelineConfig:
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    localize: LocalizeConfig = field(default_factory=LocalizeConfig)
    visibility: VisibilityConfig = field(default_factory=VisibilityConfig)
    mount: MountConfig = field(default_factory=MountConfig)
    slam: SlamConfig = field(default_factory=SlamConfig)
    qr: QrConfig = field(default_factory=QrConfig)
    fiducials: FiducialConfig = field(default_factory=FiducialConfig)
    thermal: ThermalConfig = field(default_factory=ThermalConfig)
    report: ReportConfig = field(default_factory=ReportConfig)
    calibration: str | None = None

    def detector_spec(self) -> dict[str, Any]:
        """The detector spec: name, model, conf, nms_iou, imgsz, letterbox, providers, label_model,
        type_conf (unset and default ones left out, so a detector without them still builds), options."""
        d = self.detector
        spec: dict[str, Any] = {"name": d.name, "conf": d.conf, "nms_iou": d.nms_iou}
        if d.model is not None:
            spec["model"] = d.model
        if d.imgsz is not None:
            spec["imgsz"] = d.imgsz
        if d.letterbox != "square":
            spec["letterbox"] = d.letterbox
        if d.providers != [DEFAULT_PROVIDER]:
            spec["providers"] = list(d.providers)
        if d.label_model is not None:
            spec["label_model"] = d.label_model
        if d.type_conf:
            spec["type_conf"] = dict(d.type_conf)
        spec.update(d.options)
        return spec


# ---------------------------------------------------------------------------------------------
# Building and checking


def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def config_from_dict(data: dict | None, source: str | Source = "<dict>") -> PipelineConfig:
    """Build a :class:`PipelineConfig` from a mapping (missing keys keep their defaults).

    ``source`` names the mapping in errors (a :class:`poi.core.loader.Source` adds its lines).
    """
    src = source if isinstance(source, Source) else Source(source)
    return build(PipelineConfig, data, src, error=ConfigError)


def load_config(path: str | Path | None = None) -> PipelineConfig:
    """Load a pipeline config from YAML (default: ``poi/configs/default.yaml``), bounded by poi.core.loader."""
    p = Path(path) if path is not None else DEFAULT_CONFIG_PATH
    data, src = load_yaml_file(p, what="config", error=ConfigError)
    return config_from_dict(data, src)


def _to_plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value):
        return {f.name: _to_plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, tuple):
        return [_to_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_plain(v) for k, v in value.items()}
    return value


def config_to_dict(cfg: PipelineConfig) -> dict:
    """Plain nested dict (lists, no tuples) for writing ``config.yaml``; loads back the same."""
    return _to_plain(cfg)


def flatten_config(data: dict, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(dotted key, value) for each leaf of a nested settings dict (lists are leaves).

    >>> list(flatten_config({"tracker": {"gate": 9.0, "gates": {}}, "calibration": None}))
    [('tracker.gate', 9.0), ('tracker.gates', {}), ('calibration', None)]
    """
    for k, v in data.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and v:
            yield from flatten_config(v, key + ".")
        else:
            yield key, v


@dataclass(frozen=True)
class _Rows:
    """A mapping whose values are settings rows (``localize.types``): any key, each a ``row``."""

    row: type


def _below(cls: Any, part: str, here: str, nxt: str) -> Any:
    """The settings class below key ``part`` of ``cls`` (None: an open mapping, any key and
    value); ``nxt`` the key to be set below it, for the error on a single setting."""
    if isinstance(cls, _Rows):
        return cls.row
    tp = _hints(cls)[part]
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return tp
    if typing.get_origin(tp) is dict:
        row = typing.get_args(tp)[1]
        return _Rows(row) if isinstance(row, type) and dataclasses.is_dataclass(row) else None
    raise ConfigError(f"{here}: is a single setting, it has no key {nxt!r}")


def apply_overrides(cfg: PipelineConfig, items: Iterable[str]) -> PipelineConfig:
    """A new config with ``KEY=VALUE`` items applied; values are parsed as YAML and validated.

    ``tracker.gates.door=4`` sets an entry of an open mapping, ``localize.types.door.
    box_width_m=0.8`` a number of a type's row; any other unknown key is refused.
    """
    data = config_to_dict(cfg)
    for item in items:
        if "=" not in item:
            raise ConfigError(f"{item!r}: expected KEY=VALUE, e.g. tracker.gate=4")
        key, text = item.split("=", 1)
        key = key.strip()
        value = safe_load(text, f"--set {key}", error=ConfigError) if text.strip() else None
        parts = key.split(".")
        node: Any = data
        cls: Any = PipelineConfig
        for depth, part in enumerate(parts):
            here = ".".join(parts[: depth + 1])
            last = depth == len(parts) - 1
            if cls is None and not last:  # inside an open mapping (gates, options): any key
                raise ConfigError(f"{here}: cannot set a key below {here}")
            if cls is not None and not isinstance(cls, _Rows):
                names = {f.name for f in dataclasses.fields(cls)}
                if part not in names:
                    raise ConfigError(f"{here}: unknown key; expected one of {', '.join(sorted(names))}")
            if last:
                node[part] = value
                break
            cls = _below(cls, part, here, parts[depth + 1])
            if node.get(part) is None:
                node[part] = {}
            node = node[part]
            if not isinstance(node, dict):  # an earlier item set it to a non-mapping
                raise ConfigError(f"{here}: expected a mapping to set {parts[depth + 1]!r} in, got {show(node)}")
    return config_from_dict(data, "--set")


def mount_matrix(cfg: PipelineConfig) -> np.ndarray:
    """The nominal mount as a 4x4 matrix (Q0, t0 of [Avevor2022]_ section 2.3.1)."""
    return cfg.mount.T_tracker_camera.matrix()
