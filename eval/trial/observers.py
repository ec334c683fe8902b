"""The observers a trial or a replay attaches to its episode (:mod:`eval.trial.episode`).

* :class:`PoiStream`: each object appended to ``pois.csv`` as it is confirmed;
* :class:`VideoObserver`: the annotated view into ``trial.mp4``;
* :class:`LiveObserver`: the live view and its record (``live/``);
* :class:`FunnelObserver`: the funnel's per-frame counts (:mod:`eval.trial.funnel_recorder`);
* :class:`PoseError`: the planar error of the pose the pipeline mapped with;
* :class:`SkipCounter`, :class:`RobotPath`: frames skipped, the camera's path on the floor;
* :class:`FrameHook`, :class:`InterruptCheck`: a caller's per-frame hook, a Ctrl-C between frames.

A write that fails (a full disk) is recorded in the run's
:class:`eval.trial.outputs.TrialOutputs` and the episode goes on without that output.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

import numpy as np

from eval.trial.episode import Observer, Tick
from poi.core.geometry import planar_pose, wrap_angle


class PoiStream(Observer):
    """``pois.csv`` takes each object as it is confirmed (``poi.report.PoiWriter.append``) and
    loses each the tracker withdraws (``PoiWriter.withdraw``); after a failed write streaming
    stops and the end rewrites the file whole."""

    def __init__(self, writer) -> None:
        self.writer = writer
        self.streaming = True

    def on_frame(self, tick: Tick) -> None:
        if not self.streaming:
            return
        try:
            for track_id in tick.res.withdrawn:
                self.writer.withdraw(track_id)
            for snap in tick.res.newly_confirmed:
                self.writer.append(snap)
        except OSError:  # streaming stops; the end rewrites the file whole
            self.streaming = False


class VideoObserver(Observer):
    """The annotated camera view, a frame each, into ``trial.mp4`` (an
    :class:`eval.live.video.H264Writer`); a failed write ends the video, not the run."""

    NAME = "trial.mp4"

    def __init__(self, video, outputs) -> None:
        self.video = video
        self.outputs = outputs

    def on_frame(self, tick: Tick) -> None:
        if self.video is None:
            return
        try:
            self.video.write(tick.view)
        except OSError as e:  # the run goes on without its video
            self.outputs.fail(self.NAME, e)
            with contextlib.suppress(OSError):
                self.video.close()
            self.video = None

    def close(self) -> None:
        if self.video is not None:
            video = self.video
            self.outputs.write(self.NAME, lambda _: video.close(), atomic=False)


class LiveObserver(Observer):
    """The live view (:class:`eval.live.record.LiveRecorder`): its record ``live/`` is an
    output of the run when ``record`` is set."""

    def __init__(self, live, outputs, *, record: bool) -> None:
        self.live = live
        self.outputs = outputs
        self.record = record

    def on_frame(self, tick: Tick) -> None:
        self.live.on_frame(tick.frame, tick.res, tick.pipe, tick.view)

    def close(self) -> None:
        if self.record:
            self.outputs.write("live/", lambda _: self.live.close(), atomic=False)
        else:
            self.live.close()


class FunnelObserver(Observer):
    """The funnel's per-frame counts: the objects each frame shows (``Step.views``, by the
    source) against what the pipeline made of them (:class:`eval.trial.funnel_recorder.FunnelRecorder`)."""

    def __init__(self, recorder) -> None:
        self.recorder = recorder

    def on_frame(self, tick: Tick) -> None:
        self.recorder.on_frame(tick.step.views, tick.step.blur_px, tick.frame, tick.res)


def planar_pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """Distance on the floor (m) and absolute heading difference (degrees) of two poses."""
    est, true = planar_pose(T_est), planar_pose(T_true)
    return float(np.linalg.norm(est[:2] - true[:2])), abs(float(np.degrees(wrap_angle(est[2] - true[2]))))


def pose_error_summary(errors: list[tuple[float, float]]) -> dict[str, float]:
    """Median, 90th percentile, max and last of the per-frame planar position error (m) of the
    pose the pipeline mapped with against the true tracker pose, and the median heading error
    (degrees); frames with a pose only."""
    if not errors:
        return {"frames": 0}
    e = np.asarray([d for d, _ in errors])
    yaw = np.asarray([a for _, a in errors])
    return {
        "frames": int(e.size),
        "median_m": round(float(np.median(e)), 4),
        "p90_m": round(float(np.percentile(e, 90)), 4),
        "max_m": round(float(e.max()), 4),
        "final_m": round(float(e[-1]), 4),
        "heading_median_deg": round(float(np.median(yaw)), 3),
    }


class PoseError(Observer):
    """The planar error of the pose the pipeline mapped with (``res.pose_map``) against the
    step's true tracker pose, each frame with a pose (:func:`pose_error_summary`)."""

    def __init__(self) -> None:
        self.errors: list[tuple[float, float]] = []

    def on_frame(self, tick: Tick) -> None:
        if tick.res.pose_map is not None:
            self.errors.append(planar_pose_error(tick.res.pose_map, tick.step.T_map_tracker_true))

    def summary(self) -> dict[str, float]:
        return pose_error_summary(self.errors)


class SkipCounter(Observer):
    """The frames the pipeline skipped (``res.skipped_reason``: no pose, no depth, pose not
    finite), in all and by reason."""

    def __init__(self) -> None:
        self.skipped = 0
        self.by_reason: dict[str, int] = {}

    def on_frame(self, tick: Tick) -> None:
        reason = tick.res.skipped_reason
        if reason:
            self.skipped += 1
            self.by_reason[reason] = self.by_reason.get(reason, 0) + 1

    def note(self, n_frames: int) -> str | None:
        """One line for a run's notes when frames were skipped, e.g. "5 of 5 frames skipped
        (nothing localised or tracked on them): pose not finite 5"; None when none were."""
        if not self.skipped:
            return None
        reasons = ", ".join(f"{r} {c}" for r, c in sorted(self.by_reason.items()))
        return f"{self.skipped} of {n_frames} frames skipped (nothing localised or tracked on them): {reasons}"


class RobotPath(Observer):
    """The camera's path on the map's floor, (x, y) a frame with a pose (``map.png``)."""

    def __init__(self) -> None:
        self.path: list[list[float]] = []

    def on_frame(self, tick: Tick) -> None:
        if tick.res.pose_map is not None:
            T = tick.res.pose_map @ tick.pipe.T_tracker_camera
            self.path.append([float(T[0, 3]), float(T[1, 3])])

    def array(self) -> np.ndarray:
        return np.asarray(self.path).reshape(-1, 2)


class FrameHook(Observer):
    """A caller's ``on_frame(frame, truth, res, pipe)`` (``eval.ros.writer.TrialLogger``)."""

    def __init__(self, hook: Callable) -> None:
        self.hook = hook

    def on_frame(self, tick: Tick) -> None:
        self.hook(tick.frame, tick.step.truth, tick.res, tick.pipe)


class InterruptCheck(Observer):
    """A Ctrl-C ends the episode here, between two frames (:class:`eval.trial.interrupt.DeferredInterrupt`);
    attach it last."""

    def __init__(self, interrupt) -> None:
        self.interrupt = interrupt

    def on_frame(self, tick: Tick) -> None:
        self.interrupt.check()
