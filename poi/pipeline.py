"""The perception pipeline: detect -> localise -> (SLAM) -> read QR text -> in-view check -> track.

Per frame (:meth:`Pipeline.process`):

1. every detector's ``detect(frame)``; their detections are concatenated; a Landolt-C
   detection without text (a detector that gives boxes only) has its rings read from the
   frame's pixels (poi.detectors.landolt.attach_landolt_text); with the thermal camera on
   (``thermal.enabled``, ``thermal.confirm_colour_boxes``), a heat-source box of another
   detector that no thermal detection overlaps is dropped (poi.heat_sources);
2. a frame without a pose or a depth image stops here (``skipped_reason``): its
   detections get their QR text for display but nothing is localised or tracked;
3. each detection is localised ([Avevor2022]_ 2.2-2.3); one without valid depth gives no
   observation; with ``localize.mode: slam`` the UKF-SLAM (poi.estimation.slam_localizer) then
   corrects the frame's pose from the static landmarks seen, and the observations and
   the rest of the frame's steps use the corrected pose;
4. QR text is attached by ``poi.detectors.qr.attach_qr_text(rgb, detections, motion)`` when
   ``qr.enabled`` and that function exists (``motion``: the camera's turn during the exposure,
   :func:`poi.core.motion_blur.camera_motion`, where the frame gives it) (else QR detections keep the text the
   detector gave, usually none, and a note says so once), to the QR observations
   that have no text yet and do not show a code whose text is settled (``qr.settled_votes``
   reads of a track in whose gate the observation falls and whose centre projects into its box);
5. tracks whose centre is in view (poi.estimation.visibility) are passed to the tracker for the
   negative update, and the tracker steps ([Avevor2022]_ 2.4); each paired update's
   innovation, S and NIS come back in ``FrameResult.innovations``;
6. with ``fiducials.enabled``, the frame's depth feeds the fiducial mapper
   (poi.estimation.fiducials), whose fiducials :meth:`Pipeline.landmarks` gives at the end.

Detections get the id of the track they fed (``Detection.track_id``) for display.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import dataclasses
import importlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from poi.config import PipelineConfig, mount_matrix
from poi.core.motion_blur import camera_motion
from poi.core.types import Detection, Frame, Observation, TrackSnapshot
from poi.detectors.landolt import attach_landolt_text
from poi.estimation.covariance import Calibration, load_calibration
from poi.estimation.fiducials import FiducialMapper
from poi.estimation.localize import localize
from poi.estimation.slam_localizer import SlamLocalizer
from poi.estimation.tracker import Innovation, Tracker
from poi.estimation.visibility import in_view, pixel_of_map_point
from poi.heat_sources import frame_has_thermal_view, vouched_for

QR_MODULE = "poi.detectors.qr"
QR_FUNCTION = "attach_qr_text"


@dataclass(kw_only=True)
class FrameResult:
    frame_index: int
    timestamp_s: float
    detections: list[Detection]
    observations: list[Observation]
    newly_confirmed: list[TrackSnapshot]
    withdrawn: list[int] = field(default_factory=list)  # ids of confirmed tracks unconfirmed (tracker step 6)
    skipped_reason: str | None = None
    timing_ms: dict[str, float] = field(default_factory=dict)
    pose_map: np.ndarray | None = None  # the pose the frame was mapped with (corrected in slam mode)
    # the index in ``detections`` of each observation's detection, and of each QR detection the
    # reader was given this frame (a funnel tells a code not read from one never tried)
    observed: list[int] = field(default_factory=list)
    qr_tried: list[int] = field(default_factory=list)
    # the tracker's paired updates: each one's innovation, S and NIS (poi.estimation.tracker.Innovation;
    # its obs_index indexes ``observations``)
    innovations: list[Innovation] = field(default_factory=list)


def _find_qr_reader() -> tuple[Callable | None, str | None]:
    try:
        mod = importlib.import_module(QR_MODULE)
    except ImportError as e:
        return (
            None,
            f"QR text reading unavailable ({QR_MODULE} cannot be imported: {e}); "
            "QR text stays as the detector gave it",
        )
    fn = getattr(mod, QR_FUNCTION, None)
    if fn is None:
        return (
            None,
            f"QR text reading unavailable ({QR_MODULE} has no {QR_FUNCTION}); "
            "QR text stays as the detector gave it",
        )
    return fn, None


def find_qr_reader() -> Callable | None:
    """The QR reader the pipeline uses (``attach_qr_text``), None when it cannot be imported."""
    return _find_qr_reader()[0]


def skip_reason(frame: Frame) -> str | None:
    """Why a frame cannot be localised ("no pose", "no depth", "pose not finite"), else None."""
    if frame.pose is None:
        return "no pose"
    if frame.depth_m is None:
        return "no depth"
    if not np.all(np.isfinite(frame.pose)):
        return "pose not finite"
    return None


def qr_camera_motion(frame: Frame, cfg: PipelineConfig, T_tracker_camera: np.ndarray):
    """The camera's motion during ``frame``'s exposure as the QR reader takes it
    (:func:`poi.core.motion_blur.camera_motion`: the mount ``T_tracker_camera``, that is
    ``mount_matrix(cfg)``, and ``qr.max_exposure_ms`` where the frame gives no exposure)."""
    return camera_motion(frame, T_tracker_camera, cfg.qr.max_exposure_ms / 1000.0)


class Pipeline:
    """Frames in, tracked objects out; ``detectors`` have ``detect(frame) -> list[Detection]``.

    ``qr_reader`` (``reader(rgb, detections, motion) -> detections``, as ``attach_qr_text``) replaces
    the QR module's reader when ``qr.enabled``: a replay (eval.trial.perception_cache) gives
    the texts read when its frames were recorded.
    """

    def __init__(
        self,
        cfg: PipelineConfig,
        detectors: Sequence,
        calibration: Calibration | None = None,
        qr_reader: Callable | None = None,
    ) -> None:
        self.cfg = cfg
        self.detectors = list(detectors)
        if calibration is None and cfg.calibration is not None:
            calibration = load_calibration(cfg.calibration)
        self.calibration = calibration
        self.T_tracker_camera = mount_matrix(cfg)
        self.tracker = Tracker(cfg.tracker, calibration)
        self.slam = SlamLocalizer(cfg.slam) if cfg.localize.mode == "slam" else None
        self.notes: list[str] = []
        self.fiducials = FiducialMapper(cfg.fiducials) if cfg.fiducials.enabled else None
        self._thermal_vouches = cfg.thermal.enabled and cfg.thermal.confirm_colour_boxes
        self._qr_reader: Callable | None = None
        if cfg.qr.enabled and qr_reader is not None:
            self._qr_reader = qr_reader
        elif cfg.qr.enabled:
            self._qr_reader, note = _find_qr_reader()
            if note:
                self.notes.append(note)

    def _tracks_in_view(self, frame: Frame) -> set[int]:
        v = self.cfg.visibility
        return {
            tr.track_id
            for tr in self.tracker.tracks.values()
            if in_view(
                tr.mu,
                frame,
                self.T_tracker_camera,
                frame.intrinsics,
                v.margin_px,
                v.max_range_m,
                v.occlusion_tolerance_m,
            )
        }

    def _settled_qr(self, obs: Observation, frame: Frame) -> bool:
        """Whether ``obs`` shows a QR code whose text is settled: it falls in the gate of a QR
        track whose text has ``qr.settled_votes`` reads, and that track's centre projects into
        ``obs``'s box in ``frame``. A box in the gate that the centre misses is another code
        (codes of different sizes sit side by side on one chart, closer than a gate): it is
        read, and a text of its own keeps it off the settled track."""
        need = self.cfg.qr.settled_votes
        if need <= 0:
            return False
        settled = [
            tr
            for tr in self.tracker.tracks.values()
            if tr.type == "qr" and max(tr.text_votes.values(), default=0) >= need
        ]
        if not settled:
            return False
        x1, y1, x2, y2 = obs.detection.box_xyxy
        for tr, m2 in zip(settled, self.tracker.distances([obs], settled)[0], strict=True):
            if not np.isfinite(m2):
                continue
            seen = pixel_of_map_point(tr.mu, frame, self.T_tracker_camera, frame.intrinsics)
            if seen is not None and x1 <= seen[0] <= x2 and y1 <= seen[1] <= y2:
                return True
        return False

    def _read_qr(
        self, reader: Callable, frame: Frame, detections: list[Detection], todo: list[int]
    ) -> list[Detection]:
        """Decode with ``reader`` the text of detections ``todo`` (qr ones without text) in a copy
        of ``detections``, with the camera's motion where ``frame`` gives it."""
        if not todo:
            return detections
        motion = qr_camera_motion(frame, self.cfg, self.T_tracker_camera)
        read = list(reader(frame.rgb, [detections[k] for k in todo], motion))
        if len(read) != len(todo):
            raise RuntimeError(f"{QR_MODULE}.{QR_FUNCTION} returned {len(read)} detections for {len(todo)}")
        out = list(detections)
        for k, det in zip(todo, read, strict=True):
            out[k] = det
        return out

    @staticmethod
    def _unread_qr(detections: list[Detection]) -> list[int]:
        """Indices of qr detections without text (a detector may have read some already)."""
        return [k for k, d in enumerate(detections) if d.type == "qr" and not d.text]

    def process(self, frame: Frame) -> FrameResult:
        timing: dict[str, float] = {}
        t0 = time.perf_counter()
        detections: list[Detection] = []
        for det in self.detectors:
            detections.extend(det.detect(frame))
        if frame.rgb.size and any(d.type == "landolt-c" and not d.text for d in detections):
            detections = attach_landolt_text(frame.rgb, detections)
        if self._thermal_vouches and frame_has_thermal_view(frame):
            detections = vouched_for(detections)
        t1 = time.perf_counter()
        timing["detect"] = 1e3 * (t1 - t0)
        reason = skip_reason(frame)
        pose = frame.pose
        if reason is not None or pose is None:
            return self._skipped(frame, detections, reason or "no pose", timing, t1)

        observations: list[Observation] = []
        det_of_obs: list[int] = []
        for k, det in enumerate(detections):
            obs = localize(det, frame, self.cfg, self.T_tracker_camera, self.calibration)
            if obs is not None:
                observations.append(obs)
                det_of_obs.append(k)
        t2 = time.perf_counter()
        timing["localize"] = 1e3 * (t2 - t1)
        if self.slam is not None:
            corrected = self.slam.step(pose, observations, frame.timestamp_s, frame.pose_relocalised)
            # a stale pose (frame 0 with a latency): R does not hold its error, the
            # observations are dropped (poi.estimation.slam_localizer, step 1)
            observations = corrected.observations
            if corrected.stale:
                observations, det_of_obs = [], []
            frame = dataclasses.replace(frame, pose=corrected.pose)
            t_slam = time.perf_counter()
            timing["slam"] = 1e3 * (t_slam - t2)
            t2 = t_slam

        todo: list[int] = []
        if self._qr_reader is not None:
            unread = set(self._unread_qr(detections))
            todo = [
                i for i, k in enumerate(det_of_obs) if k in unread and not self._settled_qr(observations[i], frame)
            ]
            read = self._read_qr(self._qr_reader, frame, detections, [det_of_obs[i] for i in todo])
            for i in todo:
                observations[i] = dataclasses.replace(observations[i], detection=read[det_of_obs[i]])
            detections = read
        t3 = time.perf_counter()
        timing["qr"] = 1e3 * (t3 - t2)

        visible = self._tracks_in_view(frame)
        step = self.tracker.step(observations, frame.timestamp_s, visible)
        for i, tid in step.pairs + step.new_tracks + step.duplicates:
            detections[det_of_obs[i]].track_id = tid
        t4 = time.perf_counter()
        timing["track"] = 1e3 * (t4 - t3)
        if self.fiducials is not None:
            self.fiducials.add(frame, frame.pose @ self.T_tracker_camera)
            timing["fiducials"] = 1e3 * (time.perf_counter() - t4)
        return FrameResult(
            frame_index=frame.index,
            timestamp_s=frame.timestamp_s,
            detections=detections,
            observations=observations,
            newly_confirmed=step.newly_confirmed,
            withdrawn=step.withdrawn,
            skipped_reason=None,
            timing_ms=timing,
            pose_map=np.asarray(frame.pose, dtype=float),
            observed=list(det_of_obs),
            qr_tried=[det_of_obs[i] for i in todo],
            innovations=step.innovations,
        )

    def _skipped(
        self, frame: Frame, detections: list[Detection], reason: str, timing: dict[str, float], t1: float
    ) -> FrameResult:
        """The result of a frame that cannot be localised (:func:`skip_reason`): its QR codes are
        read all the same, nothing is tracked."""
        qr_tried = self._unread_qr(detections) if self._qr_reader is not None else []
        if self._qr_reader is not None:
            detections = self._read_qr(self._qr_reader, frame, detections, qr_tried)
        timing["qr"] = 1e3 * (time.perf_counter() - t1)
        return FrameResult(
            frame_index=frame.index,
            timestamp_s=frame.timestamp_s,
            detections=detections,
            observations=[],
            newly_confirmed=[],
            skipped_reason=reason,
            timing_ms=timing,
            qr_tried=qr_tried,
        )

    def confirmed(self) -> list[TrackSnapshot]:
        """Snapshots of the confirmed tracks, by report id."""
        return self.tracker.snapshots(confirmed_only=True)

    def landmarks(self) -> list[TrackSnapshot]:
        """The mapping fiducials found (step 6), as confirmed snapshots numbered after the
        confirmed tracks' report ids; none unless ``fiducials.enabled``."""
        if self.fiducials is None:
            return []
        ids = [t.report_id for t in self.confirmed() if t.report_id is not None]
        return self.fiducials.landmarks(start_id=max(ids, default=-1) + 1)

    def tracks(self) -> list[TrackSnapshot]:
        """Snapshots of every live track, tentative ones included."""
        return self.tracker.snapshots()
