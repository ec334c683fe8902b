"""What the live view shows, frame by frame, and its record for replay.

:class:`LiveRecorder` turns each trial frame into a message (time, the pose
the robot believes, the current detections by name with their track and
report ids, the confirmed objects as the POI file has them with their 2D
covariance, the running score against the ground truth) and the images (the
annotated camera view, thermal and depth insets). It hands both to a live
server when there is one and records them in the trial folder so that
``poibench view DIR`` replays the trial: ``live/init.json`` (walls, bounds,
path, colours), ``live/frames.jsonl`` (one message a frame) and
``live/insets.mp4`` (thermal | depth, 320x120); the camera frames are those of
``trial.mp4``.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import cv2
import numpy as np

from eval.scoring.map_plot import ARENA_RGB, style_of
from poi.annotate import DEFAULT_COLOR_RGB, TYPE_COLORS_RGB
from poi.core.geometry import planar_pose
from poi.core.names import display_name

INSET_W, INSET_H = 160, 120
THERMAL_RANGE_C = (15.0, 80.0)
DEPTH_RANGE_M = (0.0, 6.0)
# the map's markers are map.png's (eval.scoring.map_plot.style_of): the competition's shapes in the
# one table of type colours (poi.annotate.TYPE_COLORS_RGB), the goal arena's objects in their paint


def _hex(rgb) -> str:
    return "#{:02x}{:02x}{:02x}".format(*(int(c) for c in rgb))


def thermal_inset(thermal_c: np.ndarray | None) -> np.ndarray:
    """(INSET_H, INSET_W, 3) RGB false-colour thermal image, black when there is none."""
    if thermal_c is None:
        return np.zeros((INSET_H, INSET_W, 3), np.uint8)
    lo, hi = THERMAL_RANGE_C
    t = np.clip((np.asarray(thermal_c, np.float32) - lo) / (hi - lo), 0, 1)
    img = cv2.applyColorMap((t * 255).astype(np.uint8), cv2.COLORMAP_INFERNO)
    return cv2.cvtColor(cv2.resize(img, (INSET_W, INSET_H), interpolation=cv2.INTER_AREA), cv2.COLOR_BGR2RGB)


def depth_inset(depth_m: np.ndarray | None) -> np.ndarray:
    """(INSET_H, INSET_W, 3) RGB false-colour depth, invalid (0) pixels black."""
    if depth_m is None:
        return np.zeros((INSET_H, INSET_W, 3), np.uint8)
    small = cv2.resize(np.asarray(depth_m, np.float32), (INSET_W, INSET_H), interpolation=cv2.INTER_NEAREST)
    lo, hi = DEPTH_RANGE_M
    t = np.clip((small - lo) / (hi - lo), 0, 1)
    img = cv2.cvtColor(cv2.applyColorMap((t * 255).astype(np.uint8), cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    img[small <= 0] = 0
    return img


def pose_2d(T: np.ndarray | None) -> list[float] | None:
    """[x, y, yaw] of a map-frame pose (yaw of its x axis), or None."""
    if T is None or not np.all(np.isfinite(T)):
        return None
    x, y, yaw = planar_pose(T)
    return [round(float(x), 3), round(float(y), 3), round(float(yaw), 4)]


def confirmed_rows(snaps) -> list[dict]:
    """The confirmed objects as the POI file lists them, with their 2D covariance (m^2)."""
    rows = []
    for s in sorted(snaps, key=lambda s: s.report_id if s.report_id is not None else -1):
        if s.report_id is None:
            continue
        c = np.asarray(s.covariance, float)[:2, :2]
        rows.append(
            {
                "id": s.report_id,
                "t": round(float(s.first_seen_s), 2),
                "type": s.type,
                "text": s.text,
                "name": display_name(s.type, s.text),
                "x": round(float(s.position_map[0]), 3),
                "y": round(float(s.position_map[1]), 3),
                "z": round(float(s.position_map[2]), 3),
                "cov": [
                    [round(float(c[0, 0]), 6), round(float(c[0, 1]), 6)],
                    [round(float(c[1, 0]), 6), round(float(c[1, 1]), 6)],
                ],
            }
        )
    return rows


RESCORE_EVERY = 10  # frames between rescores of moved reports (one a second at 10 Hz)


class LiveRecorder:
    """Frame messages and images for the live server, recorded for replay."""

    def __init__(
        self,
        out_dir: Path,
        sim,
        *,
        title: str,
        score_fn=None,
        server=None,
        record: bool = True,
        n_frames: int | None = None,
    ) -> None:
        """``n_frames``: the frames the run will show (a trial's ``--max-frames``), else all of ``sim``'s."""
        self.out = Path(out_dir)
        self.server = server
        # () -> the running score of the confirmed objects so far (eval.scoring.report.live_summary), or None
        self.score_fn = score_fn
        self._score: dict | None = None
        self._scored_rows: list | None = None  # the confirmed rows the score was last computed for
        walls = [[round(a[0], 3), round(a[1], 3), round(b[0], 3), round(b[1], 3)] for a, b in sim.walls_in_map()]
        xs = [v for w in walls for v in (w[0], w[2])] or [0.0]
        ys = [v for w in walls for v in (w[1], w[3])] or [0.0]
        types = sorted(set(TYPE_COLORS_RGB) | set(ARENA_RGB))
        self.init = {
            "type": "init",
            "title": title,
            "n_frames": int(sim.n_frames if n_frames is None else n_frames),
            "walls": walls,
            "bounds": [min(xs) - 0.5, min(ys) - 0.5, max(xs) + 0.5, max(ys) + 0.5],
            "marker_colors": {t: _hex(style_of(t)[1]) for t in types},
            "marker_shapes": {t: style_of(t)[0] for t in types},
            "box_colors": {t: _hex(TYPE_COLORS_RGB.get(t, DEFAULT_COLOR_RGB)) for t in types},
            "path": [],
        }
        self._frames = None
        self._insets = None
        self.error: OSError | None = None  # the first write of the record that failed
        if record:
            live = self.out / "live"
            live.mkdir(parents=True, exist_ok=True)
            # written now and again at the end (with the path): a run stopped before its end leaves a
            # record poibench view replays (eval.live.server.ReplaySource rebuilds the path)
            (live / "init.json").write_text(json.dumps(self.init), encoding="utf-8")
            self._frames = open(live / "frames.jsonl", "w", encoding="utf-8")  # noqa: SIM115 (closed in close())
            from eval.live.video import H264Writer

            self._insets = H264Writer(
                live / "insets.mp4", 2 * INSET_W, INSET_H, float(sim.scenario.sensors.fps), crf=23
            )
        if server is not None:
            server.set_init(self.init)

    def on_frame(self, frame, res, pipe, camera_rgb: np.ndarray | None) -> None:
        pose = pose_2d(frame.pose)
        if pose is not None:
            self.init["path"].append(pose[:2])
        confirmed = pipe.confirmed()
        rows = confirmed_rows(confirmed)
        # rescored when a report appears or goes, and when one has moved or been renamed at most
        # once every RESCORE_EVERY frames and on the last (a report's estimate crossing the located
        # radius changes the score as much as a new one; scoring every frame slows a live trial)
        k = int(frame.index)
        due = k % RESCORE_EVERY == 0 or k >= self.init["n_frames"] - 1
        count_changed = self._scored_rows is None or len(rows) != len(self._scored_rows)
        if rows != self._scored_rows and (count_changed or due) and self.score_fn is not None:
            self._scored_rows = rows
            self._score = self.score_fn()
        by_track = {s.track_id: s for s in confirmed}
        msg = {
            "type": "frame",
            "k": int(frame.index),
            "t": round(float(frame.timestamp_s), 2),
            "pose": pose,
            "path_len": len(self.init["path"]),
            "detections": [
                {
                    "name": display_name(d.type, d.text),
                    "type": d.type,
                    "conf": round(float(d.confidence), 3),
                    "track": d.track_id,
                    "report": by_track[d.track_id].report_id if d.track_id in by_track else None,
                }
                for d in res.detections
            ],
            "confirmed": rows,
            "score": self._score,
            "skipped": res.skipped_reason,
        }
        insets = np.hstack([thermal_inset(frame.thermal_c), depth_inset(frame.depth_m)])
        if self._frames is not None:
            target = "frames.jsonl"
            try:
                self._frames.write(json.dumps(msg, separators=(",", ":")) + "\n")
                self._frames.flush()
                target = "insets.mp4"
                self._insets.write(insets)
            except OSError as e:  # a full disk: the record ends, the live view goes on
                self._fail(e, target)
        if self.server is not None:
            self.server.publish(msg, camera_rgb, insets)

    def _fail(self, e: OSError, name: str) -> None:
        """Keep the first failed write (with its file) for :meth:`close` and end the record."""
        if self.error is None:
            reason = e.strerror or (str(e).splitlines() or [type(e).__name__])[0]
            self.error = OSError(e.errno, reason, str(self.out / "live" / name))
        for f in (self._frames, self._insets):
            if f is not None:
                with contextlib.suppress(OSError):
                    f.close()
        self._frames = self._insets = None

    def close(self) -> None:
        """End the record (``live/init.json`` last) and tell the server the trial is done.

        Raises the OSError of the first write of the record that failed, naming its file.
        """
        target = "frames.jsonl"
        try:
            if self._frames is not None:
                self._frames.close()
                target = "insets.mp4"
                self._insets.close()
                target = "init.json"
                (self.out / "live" / "init.json").write_text(json.dumps(self.init), encoding="utf-8")
                self._frames = None
        except OSError as e:
            self._fail(e, target)
        finally:
            if self.server is not None:
                self.server.finish()
        if self.error is not None:
            raise self.error
