"""A trial as a ROS log: a rosbag2 folder in MCAP storage (CDR, with the ``metadata.yaml``
``ros2 bag play`` reads) or a ROS 1 ``.bag``, written with ``rosbags`` [rosbags]_.

Per frame, at the frame's stamp (the mission start plus the frame time):

* colour ``sensor_msgs/Image`` ``rgb8`` and its ``CameraInfo``;
* depth aligned to colour, ``16UC1`` millimetres, and its ``CameraInfo`` (the colour optics);
* with ``images="png"`` (or ``"jpeg"``), colour and depth as ``sensor_msgs/CompressedImage``
  instead, on the topics image_transport gives them (:mod:`eval.ros.compression`): colour PNG
  (or JPEG) on ``<colour topic>/compressed``, depth a lossless 16-bit PNG on
  ``<depth topic>/compressedDepth``;
* thermal ``32FC1`` degrees Celsius and its ``CameraInfo`` when the trial has a thermal camera;
* the tracker's pose as ``nav_msgs/Odometry`` (none for a frame without a pose, a dropout), its
  twist the tracker's angular velocity (its gyro, in the tracker's axes, the child frame's);
* ``/tf``: ``odom -> base`` and ``base -> mast`` from the same pose;
* the pipeline's localised detections and its confirmed objects as
  ``visualization_msgs/MarkerArray`` (spheres with a text label each, map frame).

Once, at the start: ``/tf_static`` (``map -> odom``, the camera mount ``mast -> colour``,
``colour -> depth`` and ``colour -> thermal``, identity: both are registered to colour) and the
ground truth as a ``MarkerArray``; in a ROS 1 bag both connections are latched. Topic and frame
names are :class:`eval.ros.topics.Topics` and :class:`eval.ros.topics.FrameNames`.

Serialising and writing run on a thread of their own behind a bounded queue (as the video
writer's encoder runs in its own process), so the trial waits only when the writer falls
:data:`QUEUE_FRAMES` frames behind. :attr:`LogWriter.cpu_ms_per_frame` is the writer thread's
CPU time per frame.

References
----------
Full entries in docs/SOURCES.md.

.. [rosbags] Ternaris, "rosbags: pure Python library to read, modify, convert and write rosbag
   files", Apache-2.0.
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from eval.ros.compression import (
    COLOUR_CODECS,
    COMPRESSED_SUFFIX,
    DEPTH_SUFFIX,
    encode_colour,
    encode_depth,
)
from eval.ros.messages import (
    build,
    camera_info_msg,
    compressed_image_msg,
    header,
    image_msg,
    pose_msg,
    transform_msg,
    twist_msg,
    typestore,
)
from eval.ros.topics import FrameNames, Topics
from poi.core.depth_units import to_z16
from poi.core.geometry import invert_transform, make_transform, planar_pose, rot_z
from poi.core.names import display_name
from poi.core.types import Frame

FORMATS = ("mcap", "bag")
IMAGE_MODES = ("raw", *COLOUR_CODECS)  # images as sensor_msgs/Image, or compressed with colour PNG or JPEG
QUEUE_FRAMES = 8  # frames the writer may fall behind before the trial waits for it
MARKER_DIAMETER_M = 0.15
TEXT_HEIGHT_M = 0.12
# marker colours (RGBA, 0..1): ground truth green, detections yellow, confirmed objects blue
TRUTH_RGBA = (0.1, 0.8, 0.2, 0.8)
DETECTION_RGBA = (1.0, 0.85, 0.1, 0.9)
CONFIRMED_RGBA = (0.15, 0.35, 1.0, 0.9)


class LogError(ValueError):
    """A log that cannot be written (an unknown format); one line."""


def log_path(out_dir: Path, fmt: str) -> Path:
    """Where a trial's log goes: ``trial_mcap/`` (a rosbag2 folder) or ``trial.bag``."""
    if fmt not in FORMATS:
        raise LogError(f"--log {fmt}: unknown log format; expected one of {', '.join(FORMATS)}")
    return out_dir / ("trial_mcap" if fmt == "mcap" else "trial.bag")


@dataclass(kw_only=True)
class _Item:
    t_ns: int
    frame: Frame
    observations: list  # (type, text, position_map)
    confirmed: list  # (report_id, type, text, position_map)


@dataclass
class _Stats:
    frames: int = 0
    cpu_s: float = 0.0
    wait_s: float = 0.0  # time the trial spent waiting for a queue slot
    caller_cpu_s: float = 0.0  # CPU time the trial's thread spent handing frames over
    error: BaseException | None = None
    counts: dict[str, int] = field(default_factory=dict)


class LogWriter:
    """A trial's frames in, a ROS log out (see the module docstring).

    ``truth`` is a list of (id, type, text, (x, y, z)) in the map frame; ``T_tracker_camera`` the
    camera mount the pipeline was given; ``start_ns`` the stamp of time 0 (nanoseconds since the
    epoch).
    """

    def __init__(
        self,
        path: Path,
        fmt: str,
        *,
        start_ns: int,
        T_tracker_camera: np.ndarray,
        truth: list[tuple[int, str, str, tuple[float, float, float]]],
        topics: Topics | None = None,
        names: FrameNames | None = None,
        images: str = "raw",
    ) -> None:
        if fmt not in FORMATS:
            raise LogError(f"--log {fmt}: unknown log format; expected one of {', '.join(FORMATS)}")
        if images not in IMAGE_MODES:
            raise LogError(f"--log-images {images}: expected one of {', '.join(IMAGE_MODES)}")
        self.path = Path(path)
        self.fmt = fmt
        self.images = images
        self.topics = topics or Topics()
        self.names = names or FrameNames()
        self.start_ns = int(start_ns)
        self.T_tracker_camera = np.asarray(T_tracker_camera, float)
        self.truth = list(truth)
        self.ts = typestore(ros1=fmt == "bag")
        self._serialize = self.ts.serialize_ros1 if fmt == "bag" else self.ts.serialize_cdr
        self._queue: queue.Queue = queue.Queue(maxsize=QUEUE_FRAMES)
        self.stats = _Stats()
        self._writer = None
        self._conns: dict[str, object] = {}
        self._started = False
        self._thread = threading.Thread(target=self._run, name="ros-log-writer", daemon=True)
        self._open()
        self._thread.start()

    # --- the trial's side ------------------------------------------------------------------------

    def write(self, frame: Frame, observations, confirmed) -> None:
        """Queue one frame with the pipeline's localised observations and confirmed snapshots."""
        if self.stats.error is not None:
            raise self._failure()
        c0 = time.thread_time()
        item = _Item(
            t_ns=self.start_ns + round(frame.timestamp_s * 1e9),
            frame=frame,
            observations=[
                (o.detection.type, o.detection.text, np.asarray(o.position_map, float)) for o in observations
            ],
            confirmed=[
                (s.report_id, s.type, s.text, np.asarray(s.position_map, float))
                for s in confirmed
                if s.report_id is not None
            ],
        )
        t0 = time.perf_counter()
        self._queue.put(item)
        self.stats.wait_s += time.perf_counter() - t0
        self.stats.caller_cpu_s += time.thread_time() - c0

    def close(self) -> None:
        """Write what is queued, end the log (metadata.yaml for rosbag2) and raise a write that failed."""
        self._queue.put(None)
        self._thread.join()
        if self._writer is not None:
            try:
                self._writer.close()
            except OSError as e:
                self.stats.error = self.stats.error or e
            self._writer = None
        if self.stats.error is not None:
            raise self._failure()

    @property
    def cpu_ms_per_frame(self) -> float:
        """CPU time of the writer thread per frame (serialising and writing), ms."""
        return 1e3 * self.stats.cpu_s / self.stats.frames if self.stats.frames else float("nan")

    @property
    def caller_ms_per_frame(self) -> tuple[float, float]:
        """(CPU, wall) ms per frame the trial's own thread spent in :meth:`write`, waiting included."""
        n = max(self.stats.frames, 1)
        return 1e3 * self.stats.caller_cpu_s / n, 1e3 * self.stats.wait_s / n

    def _failure(self) -> OSError:
        e = self.stats.error
        if isinstance(e, OSError):
            return e
        return OSError(f"cannot write {self.path}: {e}")

    # --- the writer thread ---------------------------------------------------------------------------

    def _open(self) -> None:
        if self.fmt == "bag":
            from rosbags.rosbag1 import Writer

            self._writer = Writer(self.path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()

    def _conn(self, topic: str, msgtype: str, latched: bool = False):
        c = self._conns.get(topic)
        if c is None:
            kw = {}
            if latched and self.fmt == "bag":
                kw["latching"] = 1
            elif latched:
                kw["offered_qos_profiles"] = [_transient_local_qos()]
            c = self._writer.add_connection(topic, msgtype, typestore=self.ts, **kw)
            self._conns[topic] = c
        return c

    def _put(self, topic: str, msgtype: str, t_ns: int, msg, latched: bool = False) -> None:
        self._writer.write(self._conn(topic, msgtype, latched), t_ns, self._serialize(msg, msgtype))
        self.stats.counts[topic] = self.stats.counts.get(topic, 0) + 1

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self.stats.error is not None:
                continue  # drain: the trial learns of the failure on its next write
            c0 = time.thread_time()
            try:
                if not self._started:
                    self._write_static(item)
                    self._started = True
                self._write_frame(item)
            except Exception as e:  # a full disk; reported by write() and close()
                self.stats.error = e
            self.stats.cpu_s += time.thread_time() - c0
            self.stats.frames += 1

    def _tf(self, t_ns: int, parent: str, child: str, T: np.ndarray):
        return build(
            self.ts,
            "geometry_msgs/msg/TransformStamped",
            header=header(self.ts, t_ns, parent),
            child_frame_id=child,
            transform=transform_msg(self.ts, T),
        )

    def _write_static(self, first: _Item) -> None:
        n, t = self.names, first.t_ns
        static = [
            self._tf(t, n.map, n.odom, np.eye(4)),
            self._tf(t, n.mast, n.color, self.T_tracker_camera),
            self._tf(t, n.color, n.depth, np.eye(4)),
            self._tf(t, n.color, n.thermal, np.eye(4)),
        ]
        self._put(self.topics.tf_static, "tf2_msgs/msg/TFMessage", t, self._tf_message(static), latched=True)
        markers = [
            self._marker(t, "truth", k, typ, text, pos, TRUTH_RGBA)
            for k, (_, typ, text, pos) in enumerate(self.truth)
        ]
        self._put(self.topics.truth, "visualization_msgs/msg/MarkerArray", t, self._markers(markers), latched=True)

    def _tf_message(self, transforms: list):
        return build(self.ts, "tf2_msgs/msg/TFMessage", transforms=transforms)

    def _write_frame(self, item: _Item) -> None:
        f, t, n, T = item.frame, item.t_ns, self.names, self.topics
        k = f.intrinsics
        if self.images == "raw":
            self._put(T.color, "sensor_msgs/msg/Image", t, image_msg(self.ts, t, n.color, f.rgb, "rgb8"))
        else:
            msg = compressed_image_msg(self.ts, t, n.color, encode_colour(f.rgb, self.images))
            self._put(T.color + COMPRESSED_SUFFIX, "sensor_msgs/msg/CompressedImage", t, msg)
        self._put(T.color_info, "sensor_msgs/msg/CameraInfo", t, camera_info_msg(self.ts, t, n.color, k))
        if f.depth_m is not None:
            mm = to_z16(f.depth_m)
            if self.images == "raw":
                self._put(T.depth, "sensor_msgs/msg/Image", t, image_msg(self.ts, t, n.depth, mm, "16UC1"))
            else:
                msg = compressed_image_msg(self.ts, t, n.depth, encode_depth(mm))
                self._put(T.depth + DEPTH_SUFFIX, "sensor_msgs/msg/CompressedImage", t, msg)
            self._put(T.depth_info, "sensor_msgs/msg/CameraInfo", t, camera_info_msg(self.ts, t, n.depth, k))
        if f.thermal_c is not None and f.thermal_intrinsics is not None:
            th = np.asarray(f.thermal_c, np.float32)
            self._put(T.thermal, "sensor_msgs/msg/Image", t, image_msg(self.ts, t, n.thermal, th, "32FC1"))
            self._put(
                T.thermal_info,
                "sensor_msgs/msg/CameraInfo",
                t,
                camera_info_msg(self.ts, t, n.thermal, f.thermal_intrinsics),
            )
        if f.pose is not None and np.all(np.isfinite(f.pose)):
            odom = build(
                self.ts,
                "nav_msgs/msg/Odometry",
                header=header(self.ts, t, n.odom),
                child_frame_id=n.mast,
                pose=build(self.ts, "geometry_msgs/msg/PoseWithCovariance", pose=pose_msg(self.ts, f.pose)),
                twist=twist_msg(self.ts, f.angular_velocity),
            )
            self._put(T.odom, "nav_msgs/msg/Odometry", t, odom)
            x, y, yaw = planar_pose(f.pose)
            T_odom_base = make_transform(rot_z(yaw), [x, y, 0.0])
            T_base_mast = invert_transform(T_odom_base) @ f.pose
            tfs = [self._tf(t, n.odom, n.base, T_odom_base), self._tf(t, n.base, n.mast, T_base_mast)]
            self._put(T.tf, "tf2_msgs/msg/TFMessage", t, self._tf_message(tfs))
        dets = [self._marker(t, "detections", j, *o, DETECTION_RGBA) for j, o in enumerate(item.observations)]
        self._put(T.detections, "visualization_msgs/msg/MarkerArray", t, self._markers(dets, clear=t))
        conf = [
            self._marker(t, "confirmed", rid, typ, text, pos, CONFIRMED_RGBA)
            for rid, typ, text, pos in item.confirmed
        ]
        self._put(T.confirmed, "visualization_msgs/msg/MarkerArray", t, self._markers(conf, clear=t))

    def _marker(self, t_ns: int, ns: str, mid: int, typ: str, text: str, pos, rgba) -> list:
        """A sphere at ``pos`` and its text label above it (ids 2 mid and 2 mid + 1)."""
        ts = self.ts
        colour = build(ts, "std_msgs/msg/ColorRGBA", r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
        p = np.asarray(pos, float)
        common = {"header": header(ts, t_ns, self.names.map), "ns": ns, "color": colour, "action": 0}
        sphere = build(
            ts,
            "visualization_msgs/msg/Marker",
            id=2 * int(mid),
            type=2,  # SPHERE
            pose=pose_msg(ts, make_transform(np.eye(3), p)),
            scale=build(
                ts, "geometry_msgs/msg/Vector3", x=MARKER_DIAMETER_M, y=MARKER_DIAMETER_M, z=MARKER_DIAMETER_M
            ),
            **common,
        )
        label = build(
            ts,
            "visualization_msgs/msg/Marker",
            id=2 * int(mid) + 1,
            type=9,  # TEXT_VIEW_FACING
            pose=pose_msg(ts, make_transform(np.eye(3), p + [0.0, 0.0, MARKER_DIAMETER_M])),
            scale=build(ts, "geometry_msgs/msg/Vector3", z=TEXT_HEIGHT_M),
            text=display_name(typ, text),
            **common,
        )
        return [sphere, label]

    def _markers(self, pairs: list[list], clear: int | None = None):
        """A MarkerArray of the markers; with ``clear`` (a stamp) a DELETEALL first, so each message
        replaces the last."""
        markers = [m for pair in pairs for m in pair]
        if clear is not None:
            wipe = build(
                self.ts,
                "visualization_msgs/msg/Marker",
                header=header(self.ts, clear, self.names.map),
                action=3,  # DELETEALL
            )
            markers = [wipe, *markers]
        return build(self.ts, "visualization_msgs/msg/MarkerArray", markers=markers)


def _transient_local_qos():
    """The QoS ``/tf_static`` is published with (reliable, transient local, keep last 1), so a
    node that subscribes after the start of ``ros2 bag play`` still gets it."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    zero = QosTime(sec=0, nsec=0)
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=1,
        reliability=QosReliability.RELIABLE,
        durability=QosDurability.TRANSIENT_LOCAL,
        deadline=zero,
        lifespan=zero,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=zero,
        avoid_ros_namespace_conventions=False,
    )


class TrialLogger:
    """``run_trial``'s ``on_frame`` hook that logs the trial: the log opens on the first frame (the
    mount is then the pipeline's and ``truth.csv`` is written) and :meth:`close` ends it."""

    def __init__(
        self,
        out_dir: Path,
        fmt: str,
        start_ns: int,
        topics: Topics | None = None,
        names: FrameNames | None = None,
        images: str = "raw",
    ) -> None:
        if images not in IMAGE_MODES:
            raise LogError(f"--log-images {images}: expected one of {', '.join(IMAGE_MODES)}")
        self.out = Path(out_dir)
        self.path = log_path(self.out, fmt)
        self.fmt, self.start_ns, self.topics, self.names, self.images = fmt, start_ns, topics, names, images
        self.writer: LogWriter | None = None

    def __call__(self, frame, truth, res, pipe) -> None:
        if self.writer is None:
            from poi.core.poi_file import read_poi_file

            rows = read_poi_file(self.out / "truth.csv").rows
            if self.path.exists():
                import shutil

                shutil.rmtree(self.path) if self.path.is_dir() else self.path.unlink()
            self.writer = LogWriter(
                self.path,
                self.fmt,
                start_ns=self.start_ns,
                T_tracker_camera=pipe.T_tracker_camera,
                truth=[(r.id, r.type, r.text, (r.x, r.y, r.z)) for r in rows],
                topics=self.topics,
                names=self.names,
                images=self.images,
            )
        c0 = time.thread_time()
        confirmed = pipe.confirmed()
        self.writer.stats.caller_cpu_s += time.thread_time() - c0
        self.writer.write(frame, res.observations, confirmed)

    def close(self) -> LogWriter | None:
        if self.writer is not None:
            self.writer.close()
        return self.writer
