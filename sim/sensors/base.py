"""What the simulator's sensors share: two kinds, by when they measure.

A frame sensor (:class:`FrameSensor`: the D435's colour and depth streams, the thermal camera)
turns one frame's renders (a :class:`Shot`) into one image, the :class:`~poi.core.types.Frame`
field it fills. The simulator holds its frame sensors as a list and runs them in that order on
the frame's one generator (``SeedSequence([seed, 1, k])``), so each draws from it in a fixed
order: colour, then depth, then thermal.

A pose sensor (:class:`PoseSensor`: the T265, the base's wheel odometry) reports the whole
trial's poses at once, from the tracker's true motion (:class:`TrackerMotion`), as a
:class:`PoseTrack`; a trial has one, ``sensors.pose_source``.

Each sensor's settings (a keyword-only dataclass, ``*Spec``) sit beside its model in its own
module; :mod:`sim.scenario` composes them into ``sensors``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

MAX_IMAGE_PX = 4096  # a camera image's width and height (the D435 colour imager tops out at 1920 x 1080)

PoseFunction = Callable[[np.ndarray], np.ndarray]  # times (n,) -> true poses (n, 4, 4)


@dataclass(kw_only=True, frozen=True)
class Exposure:
    """Exposure time (ms) and analog gain (>= 1) of one frame."""

    exposure_ms: float
    gain: float

    @property
    def product_ms(self) -> float:
        return self.exposure_ms * self.gain


@dataclass(kw_only=True)
class Shot:
    """What frame k's sensors read: its renders and the colour camera's settings for it.

    ``geom_ids`` waits for the segmentation render (geom ids per pixel of the colour camera's
    view, (H, W), -1 where no geom is drawn; None when no segmentation is rendered), which the
    GL thread finishes while the colour and depth models run.
    """

    t_s: float  # the frame's time (0 for a view from an arbitrary pose)
    rgb: np.ndarray  # (H, W, 3) uint8 colour render, encoded with ``gamma``
    gamma: float  # the colour camera's display gamma, which decodes ``rgb`` to linear light
    z_m: np.ndarray  # (H, W) float32 true z-depth
    T_world_optical: np.ndarray  # the colour camera's optical frame in the world
    exposure: Exposure  # the frame's exposure and gain (auto-exposure's, or fixed)
    motion_px: tuple[float, float]  # (du, dv) the image centre moves during the exposure
    geom_ids: Callable[[], np.ndarray | None]


class FrameSensor(Protocol):
    """A camera: one image of each frame, from that frame's renders."""

    frame_field: str  # the Frame field its image fills ("rgb", "depth_m", "thermal_c")

    def measure(self, shot: Shot, rng: np.random.Generator) -> np.ndarray:
        """The delivered image of ``shot``; random draws from ``rng``, the frame's generator."""
        ...


@dataclass(kw_only=True)
class PoseTrack:
    """Reported poses (None during dropouts) and confidences, one per frame."""

    poses: list[np.ndarray | None]
    confidence: list[str]
    error_m: np.ndarray  # |p_meas - p_true| per frame (NaN in dropouts), for reports
    relocalisations_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # loop-closure times
    # per frame: the pose jumped (a loop closure or a false relocalisation) since the last frame
    # that had a pose, as librealsense's pose-relocalisation notification tells a pipeline
    relocalised: list[bool]


@dataclass(kw_only=True)
class TrackerMotion:
    """The tracker frame's true motion through a trial: its poses (T_map_tracker) at the frame
    times ``times_s``, and ``poses_at`` any times (the T265 samples at 200 Hz)."""

    times_s: np.ndarray
    poses: list[np.ndarray]
    poses_at: PoseFunction


class PoseSensor(Protocol):
    """A pose source: the whole trial's reported poses, from the tracker's true motion."""

    def track(self, motion: TrackerMotion, rng: np.random.Generator) -> PoseTrack:
        """One pose (or None) and confidence per frame time; random draws from ``rng``."""
        ...
