"""Fills a trial's funnel frame by frame (:mod:`eval.scoring.funnel`).

Per frame, :meth:`FunnelRecorder.on_frame` takes the ground truth's views of the objects
(:class:`eval.scoring.funnel.ObjectView`, from the simulator's segmentation render or a
perception record), the camera's blur and the pipeline's :class:`poi.pipeline.FrameResult`,
and

1. counts each object in view (the oracle's own test, :func:`poi.core.in_view.boxable_view`), with its
   box size, distance, viewing angle and the blur;
2. pairs the frame's boxes with the objects' visible boxes one to one, greedily by IoU, at
   IoU >= ``BOX_IOU`` (the usual detection match, [Bolya2020]_), and counts per object the
   frames it was boxed, boxed as its type, localised (the box gave an observation; if not,
   why: a skipped frame, too little depth in the box, or the rest of localisation's tests),
   and read (the observation's identity is the object's);
3. counts each QR view at ``QR_MIN_MODULE_PX`` a module or more with a QR box on it and whether
   the reader reads it right (asking the reader, ``qr_reader``, where the pipeline did not), and
   those whole in the image and blurred by less than a module;
4. notes which object each track's observations lay on (the one each box overlaps most, from
   IoU ``BACKGROUND_IOU``: [Bolya2020]_'s background threshold), and when each track was confirmed.

:meth:`FunnelRecorder.funnel` hands that to :func:`eval.scoring.funnel.attribute` with the score.

References
----------
.. [Bolya2020] D. Bolya et al., "TIDE: A General Toolbox for Identifying Object Detection
   Errors", ECCV 2020 (docs/SOURCES.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from eval.scoring.funnel import (
    BACKGROUND_IOU,
    BOX_IOU,
    QR_MIN_MODULE_PX,
    QR_WHOLE_FRACTION,
    DetectorActivity,
    Funnel,
    ObjectTrace,
    ObjectView,
    TrackTrace,
    attribute,
)
from eval.scoring.map_error import MapErrorResult
from eval.scoring.rules import AnyRules, Rules
from eval.scoring.scorer import ScoreResult, identity_of
from poi.core.geometry import greedy_pairs, iou_matrix
from poi.core.types import Detection, Frame, TrackSnapshot
from poi.estimation.box_depth import box_depth

# sources of the helpers that run beside a trial's detector (heat, Landolt-C rings, QR finder):
# their boxes do not say whether the detector itself boxes anything
HELPER_SOURCES = frozenset({"thermal", "landolt", "qr"})


def box_overlaps(dets: Sequence[Detection], views: Sequence[ObjectView]) -> np.ndarray:
    """(detections, views) IoU of each detection's box with each view's box; for a point view (a
    recording's) 1 where the box holds its point, else 0.

    >>> v = [ObjectView(id=3, box_xyxy=(5, 5, 5, 5), visible_fraction=1.0, distance_m=1.0, point=True)]
    >>> d = [Detection(class_name="qr", type="qr", text="", box_xyxy=(1, 1, 10, 10), confidence=0.9)]
    >>> box_overlaps(d, v).tolist()
    [[1.0]]
    """
    boxes = np.array([d.box_xyxy for d in dets], dtype=float).reshape(-1, 4)  # (n, 4)
    iou = iou_matrix(boxes, np.array([v.box_xyxy for v in views], dtype=float).reshape(-1, 4))
    for j, v in enumerate(views):
        if v.point:  # a recording's view: the boxes that hold its point, each counted as a full overlap
            u, w = v.box_xyxy[0], v.box_xyxy[1]
            holds = (boxes[:, 0] <= u) & (u <= boxes[:, 2]) & (boxes[:, 1] <= w) & (w <= boxes[:, 3])
            iou[:, j] = holds.astype(float)
    return iou


def match_boxes(
    dets: Sequence[Detection], views: Sequence[ObjectView], iou_min: float = BOX_IOU
) -> dict[int, int]:
    """Detection index -> view index, one to one, greedily by IoU (highest first) at ``iou_min``
    (:func:`poi.core.geometry.greedy_pairs` on :func:`box_overlaps`).

    >>> v = [ObjectView(id=3, box_xyxy=(0, 0, 10, 10), visible_fraction=1.0, distance_m=1.0)]
    >>> d = [Detection(class_name="qr", type="qr", text="", box_xyxy=(1, 1, 10, 10), confidence=0.9)]
    >>> match_boxes(d, v)
    {0: 0}
    """
    return dict(greedy_pairs(box_overlaps(dets, views), iou_min))


def projected_views(
    positions: dict[int, np.ndarray], frame: Frame, T_tracker_camera: np.ndarray, visibility
) -> list[ObjectView]:
    """The point views (:attr:`ObjectView.point`) of the objects at map ``positions`` that a
    recording's ``frame`` shows by its own pose: the pipeline's in-view test
    (:func:`poi.estimation.visibility.in_view`, with the ``visibility`` settings) on each."""
    from poi.core.geometry import invert_transform, transform_points
    from poi.estimation.projection import project_point_to_pixel
    from poi.estimation.visibility import in_view

    if frame.pose is None:
        return []
    T_camera_map = invert_transform(np.asarray(frame.pose, dtype=float) @ T_tracker_camera)
    out = []
    for oid, p in positions.items():
        if not in_view(
            p,
            frame,
            T_tracker_camera,
            frame.intrinsics,
            visibility.margin_px,
            visibility.max_range_m,
            visibility.occlusion_tolerance_m,
        ):
            continue
        p_c = transform_points(T_camera_map, p)
        u, v = (float(x) for x in project_point_to_pixel(frame.intrinsics, p_c))
        out.append(
            ObjectView(
                id=oid,
                box_xyxy=(u, v, u, v),
                visible_fraction=1.0,
                distance_m=float(np.linalg.norm(p_c)),
                point=True,
            )
        )
    return out


class FunnelRecorder:
    """The funnel's per-frame counts for one trial (module docstring).

    ``objects``: (id, type, text, modules) of every ground-truth object, ``modules`` a QR
    code's modules across (quiet zone included; None for other types); ``cfg`` the trial's
    pipeline configuration (its localisation settings say why a box gave no observation);
    ``rules`` the scoring preset (what identity a read must give); ``by_pose``: the views are a
    recording's (:func:`point_views`), each object's point projected by the recording's own pose.
    """

    def __init__(
        self,
        objects: Iterable[tuple[int, str, str, int | None]],
        cfg,
        rules: AnyRules,
        qr_reader: Callable[[Frame, Detection], str] | None = None,
        by_pose: bool = False,
    ) -> None:
        self.traces = {
            oid: ObjectTrace(id=oid, type=t, text=text, modules=modules, by_pose=by_pose)
            for oid, t, text, modules in objects
        }
        self.tracks: dict[int, TrackTrace] = {}
        self.cfg = cfg
        self.rules = rules
        self.activity = DetectorActivity(conf=float(cfg.detector.conf))
        # (frame, QR box) -> the reader's text, for the QR views the pipeline did not ask it about
        self.qr_reader = qr_reader

    def _same_identity(self, det: Detection, o: ObjectTrace) -> bool:
        """Whether a box's type and text are the object's identity as the trial's rules give it
        (docs/RULES.md rule 1, :func:`eval.scoring.scorer.identity_of`: the text counts where the
        type's ``identity_uses_text`` says so); under a map-error preset, or for a type the rules do
        not score, the type alone."""
        if det.type != o.type:
            return False
        if not isinstance(self.rules, Rules) or o.type not in self.rules.types:
            return True
        mine = identity_of(o.type, o.text, self.rules)
        return mine is not None and identity_of(det.type, det.text, self.rules) == mine

    def _why_not_localised(self, det: Detection, frame: Frame, skipped: str | None) -> str:
        if skipped:
            return skipped
        lc = self.cfg.localize
        d = box_depth(
            frame.depth_m,
            det.box_xyxy,
            lc.inner_fraction,
            lc.min_depth_fill,
            split_m=lc.depth_split_m,
            max_split=lc.max_depth_split,
        )
        if d is None:
            return "depth fill"
        if not lc.min_depth_m <= d * lc.depth_scale <= lc.max_depth_m:
            return "depth range"
        return "border or pose"

    def on_frame(self, views: Sequence[ObjectView], blur_px: float | None, frame: Frame, res) -> None:
        """Count one frame: its truth ``views``, the camera's ``blur_px`` (None: not known) and the
        pipeline's result."""
        views = [v for v in views if v.id in self.traces]
        for v in views:
            if not v.in_view():
                continue
            o = self.traces[v.id]
            o.in_view_frames += 1
            if o.first_in_view is None:
                o.first_in_view = frame.index
            o.best_px = max(o.best_px, v.min_side_px)
            o.min_distance_m = min(o.min_distance_m, v.distance_m)
            if np.isfinite(v.angle_deg):
                o.min_angle_deg = v.angle_deg if np.isnan(o.min_angle_deg) else min(o.min_angle_deg, v.angle_deg)
            if blur_px is not None:
                o.blur_px.append(round(float(blur_px), 3))
        dets = res.detections
        self.activity.frames += 1
        self.activity.boxes += sum(d.source not in HELPER_SOURCES for d in dets)
        observed = set(res.observed)
        tried = set(res.qr_tried)
        overlap = box_overlaps(dets, views)  # (detections, views), once a frame
        on = dict(greedy_pairs(overlap, BOX_IOU))
        for k, j in on.items():
            det, v = dets[k], views[j]
            o = self.traces[v.id]
            o.boxed_frames += 1
            o.boxed_as[det.type] += 1
            if det.type != o.type:
                continue
            o.typed_frames += 1
            if o.type == "qr" and v.in_view() and o.modules and v.min_side_px / o.modules >= QR_MIN_MODULE_PX:
                self._count_qr_view(o, v, det, k in tried, frame)
            if k not in observed:
                o.not_localised[self._why_not_localised(det, frame, res.skipped_reason)] += 1
                continue
            o.localised_frames += 1
            o.read_as[det.text] += 1
            o.read_frames += self._same_identity(det, o)
            if det.track_id is not None:
                o.tracks[det.track_id] += 1
        near = self._nearest_views(overlap)
        for k in observed:
            tid = dets[k].track_id
            if tid is None:
                continue
            t = self.tracks.setdefault(tid, TrackTrace(track_id=tid))
            j = on.get(k, near.get(k))
            t.on[None if j is None else views[j].id] += 1
        for tid in res.withdrawn:  # withdrawn from the report (tracker step 6): confirmed no more
            if tid in self.tracks:
                self.tracks[tid].confirmed_frame = None
                self.tracks[tid].observations_at_confirmation = None
        for snap in res.newly_confirmed:
            t = self.tracks.setdefault(snap.track_id, TrackTrace(track_id=snap.track_id))
            t.confirmed_frame = res.frame_index
            t.observations_at_confirmation = snap.n_detections

    @staticmethod
    def _nearest_views(overlap: np.ndarray) -> dict[int, int]:
        """Detection index -> the view it overlaps most (``overlap``, :func:`box_overlaps`), where
        that IoU is at least ``BACKGROUND_IOU`` (a box below it on every object lies on the background)."""
        if overlap.size == 0:
            return {}
        best = np.argmax(overlap, axis=1)
        return {k: int(best[k]) for k in range(overlap.shape[0]) if overlap[k, best[k]] >= BACKGROUND_IOU}

    def _count_qr_view(self, o: ObjectTrace, v: ObjectView, det: Detection, tried: bool, frame: Frame) -> None:
        """One QR view at >= QR_MIN_MODULE_PX a module: did the reader read it right? Its text as the
        pipeline read it, or, where the pipeline did not ask (a settled track), the reader's answer."""
        text = det.text
        if not tried and not text:
            if self.qr_reader is None:
                return
            text = self.qr_reader(frame, det)
        right = text == o.text
        o.qr_views += 1
        o.qr_decoded += right
        if v.visible_fraction >= QR_WHOLE_FRACTION:
            o.qr_whole_views += 1
            o.qr_whole_decoded += right

    def funnel(
        self,
        confirmed: Sequence[TrackSnapshot],
        result: ScoreResult | MapErrorResult,
        detectors: Sequence = (),
    ) -> Funnel:
        """The trial's funnel: the tracks reported (``confirmed``, the pipeline's snapshots at
        the end) and the score; ``detectors`` give their ``highest_score`` where they keep one."""
        for snap in confirmed:
            if snap.report_id is not None and snap.track_id in self.tracks:
                self.tracks[snap.track_id].report_id = snap.report_id
        scores = [getattr(d, "highest_score", None) for d in detectors]
        scores = [s for s in scores if s is not None]
        if scores:
            self.activity.highest_score = round(float(max(scores)), 4)
        ids = {oid: oid for oid in self.traces}
        return attribute(list(self.traces.values()), self.tracks, result, ids, self.activity)


def funnel_objects(rows) -> list[tuple[int, str, str, int | None]]:
    """(id, type, text, modules across) of each truth row; modules for a QR code only (its
    quiet zone included, maze_assets.qr), None where the text cannot be drawn."""
    from maze_assets.qr import QUIET_MODULES, QrTextureError, qr_modules

    out = []
    for r in rows:
        modules = None
        if r.type == "qr" and r.text:
            try:
                modules = int(qr_modules(r.text).shape[0]) + 2 * QUIET_MODULES
            except (QrTextureError, ValueError):
                modules = None
        out.append((int(r.id), str(r.type), str(r.text), modules))
    return out


def write_funnel_csv(path: Path, funnel: Funnel) -> None:
    """``funnel.csv``: one row an object, one a charged false report (eval.scoring.funnel.CSV_COLUMNS)."""
    import csv

    from eval.scoring.funnel import CSV_COLUMNS, funnel_rows

    with open(path, "w", encoding="utf-8", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(CSV_COLUMNS), lineterminator="\n")
        w.writeheader()
        w.writerows(funnel_rows(funnel))
