"""One episode: the one loop over frames, as the CARLA leaderboard's evaluator owns its loop.

An episode is a frame source, a stage that processes each frame (the pipeline,
:class:`poi.pipeline.Pipeline`) and observers. :func:`run_episode` pulls each
:class:`Step` from the source, runs the stage on its frame and shows every observer the
:class:`Tick` (the step, the stage's result, the stage), in the order given; at the end, or
when a frame raises (a Ctrl-C between frames), it closes every observer, in the same order.

What differs between a trial (:func:`eval.trial.run.run_trial`), a replay of a perception
record (:mod:`eval.trial.sources`), a replay of a robot's recording (:mod:`eval.ros.replay`),
a consistency run (:mod:`eval.experiments.consistency`) and the pipeline benchmark
(``bench/bench_pipeline.py``) is the source and the observers attached
(:mod:`eval.trial.observers`: the POI writer, the video, the live view, the pose error, the
funnel; the NEES collector; the stage timer), not a copy of the loop.
"""

from __future__ import annotations

import contextlib
import functools
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from eval.progress import progress_bar
from poi.core.types import Frame


@dataclass(kw_only=True)
class Step:
    """One frame as a source gives it, with what the source knows beside it.

    ``truth``: the simulator's truth of the frame (``sim.simulator.FrameTruth``; a simulation
    only); ``T_map_tracker_true``: the true tracker pose (the pose error); ``views``: the
    objects the frame shows (``eval.scoring.funnel.ObjectView``, the funnel), None where the
    source knows none; ``blur_px``: the colour camera's motion blur, None where unknown."""

    frame: Frame
    truth: Any = None
    T_map_tracker_true: np.ndarray | None = None
    views: list | None = None
    blur_px: float | None = None


class FrameSource(Protocol):
    """Frames in order, and how many there will be (the progress bar's total)."""

    n_frames: int

    def steps(self) -> Iterator[Step]: ...


class Stage(Protocol):
    """What processes each frame: the pipeline (``process(frame) -> PipelineResult``)."""

    def process(self, frame: Frame) -> Any: ...


@dataclass
class Tick:
    """One frame of an episode as observers see it: the step, the stage's result ``res``, the
    stage ``pipe`` (its confirmed objects, its mount) and the stage's time in milliseconds."""

    step: Step
    res: Any
    pipe: Any
    process_ms: float

    @property
    def frame(self) -> Frame:
        return self.step.frame

    @functools.cached_property
    def view(self) -> np.ndarray:
        """The annotated camera view (``poi.annotate``), drawn once for all who show it."""
        from poi.annotate import annotate

        f = self.step.frame
        return annotate(f.rgb, self.res.detections, self.pipe.confirmed(), f.timestamp_s)


class Observer:
    """Sees each frame of an episode (:meth:`on_frame`) and is closed at its end (:meth:`close`),
    also when the episode stops early. Both do nothing unless overridden."""

    def on_frame(self, tick: Tick) -> None:
        pass

    def close(self) -> None:
        pass


def run_episode(
    source: FrameSource,
    pipe: Stage,
    observers: Sequence[Observer] = (),
    *,
    progress: bool = False,
    desc: str = "trial",
) -> int:
    """Run ``pipe`` over every step of ``source``, each of ``observers`` seeing each frame in
    turn; returns the frames run. Every observer is closed at the end, in order, also when a
    frame raises (each close runs even when an earlier one raised; the first error propagates)."""
    n = 0
    with contextlib.ExitStack() as closing:
        for ob in reversed(observers):  # the stack closes last-in first: observers close in order
            closing.callback(ob.close)
        steps = progress_bar(source.steps(), total=source.n_frames, desc=desc, unit="frame", quiet=not progress)
        for step in steps:
            t = time.perf_counter()
            res = pipe.process(step.frame)
            tick = Tick(step, res, pipe, 1e3 * (time.perf_counter() - t))
            for ob in observers:
                ob.on_frame(tick)
            n += 1
    return n
