"""Records passed between the pipeline's stages.

Conventions (docs/DESIGN.md "Frames and conventions"):

* Camera optical frame: x right, y down, z forward (RealSense / OpenCV).
* Map frame: origin on the floor under the robot's start pose, x forward,
  y left, z up, metres.
* ``Frame.pose`` is ``T_map_tracker``: the tracking camera's (T265's) pose in
  the map frame as a 4x4 homogeneous matrix, i.e. ``p_map = Q @ p_tracker + t``
  with ``Q = pose[:3, :3]``, ``t = pose[:3, 3]`` ([Avevor2022]_ section 2.3.1).
* The camera mount is ``T_tracker_camera``: ``p_tracker = Q0 @ p_c + t0``.
* Images: RGB uint8 (H, W, 3); depth float32 metres (H, W), 0 = invalid;
  thermal float32 degrees Celsius (h, w).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, kw_only=True)
class Intrinsics:
    """Pinhole intrinsics with the fields of RealSense's ``rs2_intrinsics``.

    ``model`` is ``"none"`` (no distortion) or ``"brown_conrady"``; ``coeffs`` are
    the five distortion coefficients (k1, k2, p1, p2, k3).

    >>> k = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    >>> float(k.matrix()[0, 2])
    314.3
    """

    width: int
    height: int
    fx: float
    fy: float
    ppx: float
    ppy: float
    model: str = "none"
    coeffs: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"intrinsics: width and height must be positive, got {self.width}x{self.height}")
        if not (self.fx > 0 and self.fy > 0):
            raise ValueError(f"intrinsics: fx and fy must be positive, got fx={self.fx}, fy={self.fy}")
        if self.model not in ("none", "brown_conrady"):
            raise ValueError(f"intrinsics: model must be 'none' or 'brown_conrady', got {self.model!r}")
        if len(self.coeffs) != 5:
            raise ValueError(f"intrinsics: coeffs must have 5 values, got {len(self.coeffs)}")

    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K."""
        return np.array([[self.fx, 0.0, self.ppx], [0.0, self.fy, self.ppy], [0.0, 0.0, 1.0]])

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same optics resampled to another resolution (pixel-centre convention)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            width=width,
            height=height,
            fx=self.fx * sx,
            fy=self.fy * sy,
            ppx=(self.ppx + 0.5) * sx - 0.5,
            ppy=(self.ppy + 0.5) * sy - 0.5,
            model=self.model,
            coeffs=self.coeffs,
        )

    def to_dict(self) -> dict:
        return {
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "ppx": self.ppx,
            "ppy": self.ppy,
            "model": self.model,
            "coeffs": list(self.coeffs),
        }


@dataclass(kw_only=True)
class Frame:
    """What the robot's sensors deliver at one instant; all the pipeline may see.

    ``pose`` is None when the tracking camera gave no pose for this frame
    (dropout); the pipeline then skips localisation for the frame.
    ``pose_relocalised`` is True when the tracking camera relocalised (its pose jumped)
    since the last frame with a pose, as librealsense's pose-relocalisation notification
    tells; False where the source cannot tell (a recording without notifications).
    """

    index: int
    timestamp_s: float
    rgb: np.ndarray
    intrinsics: Intrinsics
    depth_m: np.ndarray | None = None
    pose: np.ndarray | None = None
    pose_confidence: str = "high"
    pose_relocalised: bool = False
    thermal_c: np.ndarray | None = None
    thermal_intrinsics: Intrinsics | None = None
    # what the camera's motion blur is made of (poi.core.motion_blur): the colour image's exposure
    # time, centred on ``timestamp_s`` (librealsense's ACTUAL_EXPOSURE metadata; its sensor
    # timestamp is the middle of the exposure), and the tracking camera's angular velocity over it
    # (rad/s, in the tracker's own axes, as its gyroscope gives it); None where the source does
    # not give them
    exposure_s: float | None = None
    angular_velocity: np.ndarray | None = None


@dataclass(kw_only=True)
class Detection:
    """One object found in one image.

    ``box_xyxy`` is (x1, y1, x2, y2) in colour-image pixels. ``class_name`` is a
    name in :data:`poi.core.names.CLASSES`; ``type`` and ``text`` are its identity
    (``text`` is the hazmat label, the decoded QR string, or ""). ``class_probs``
    is a distribution over :data:`poi.core.names.CLASSES` ([Avevor2022]_ section 2.1.5) or
    None when the detector gives only a top class.
    """

    class_name: str
    type: str
    text: str
    box_xyxy: tuple[float, float, float, float]
    confidence: float
    source: str = "detector"
    class_probs: np.ndarray | None = None
    track_id: int | None = None

    @property
    def center_uv(self) -> tuple[float, float]:
        x1, y1, x2, y2 = self.box_xyxy
        return (0.5 * (x1 + x2), 0.5 * (y1 + y2))

    @property
    def size_wh(self) -> tuple[float, float]:
        x1, y1, x2, y2 = self.box_xyxy
        return (x2 - x1, y2 - y1)


@dataclass(kw_only=True)
class Observation:
    """A detection placed in the map frame with its covariance R ([Avevor2022]_ 2.3.2)."""

    detection: Detection
    timestamp_s: float
    position_map: np.ndarray  # (3,)
    R: np.ndarray  # (3, 3) covariance in the map frame, m^2
    position_cam: np.ndarray  # (3,) in the camera optical frame
    Sigma_c: np.ndarray  # (3, 3) covariance in the camera frame ([Avevor2022] 2.2.2), registration included
    depth_m: float
    # (3, 3) the part of R whose error repeats over an object's successive observations (the
    # pose's, Sigma_eps, the mount's, the depth registration's, the odometry's height and tilt,
    # the object's extent);
    # None: all of R is fresh each frame
    R_shared: np.ndarray | None = None
    # (3, 3) spread of a 3-D object's reference point about position_cam (camera frame; R holds
    # Sigma_c + this, rotated); None: none (poi.estimation.localize.extent_covariance)
    Sigma_extent_c: np.ndarray | None = None
    # its box cut across its width / height (by the image border, or for a 3-D item by a
    # nearer surface): the box frames part of the item only (poi.estimation.localize)
    box_cut: tuple[bool, bool] = (False, False)


@dataclass(kw_only=True)
class TrackSnapshot:
    """The state of one tracked object as a report writer or a viewer needs it."""

    track_id: int
    report_id: int | None
    type: str
    text: str
    position_map: np.ndarray
    covariance: np.ndarray
    first_seen_s: float
    support: float
    n_detections: int
    confirmed: bool
    class_probs: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
