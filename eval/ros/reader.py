"""A robot's recording as the pipeline's frames: ROS 1 bags (the RealSense Viewer's layout too)
and rosbag2 folders in sqlite3 or MCAP storage, read with ``rosbags`` [rosbags]_.

:func:`open_recording` finds the streams (:mod:`eval.ros.topics`): the realsense-ros topics, the
RealSense Viewer's ``/device_0/sensor_*`` layout, or the names the caller gives. Each colour image
is one :class:`poi.core.types.Frame`:

* intrinsics from the colour stream's ``CameraInfo``;
* depth paired by header stamp (the nearest within half a colour frame period), aligned to colour
  (:func:`eval.ros.align.align_depth_to_color`) when the recording holds it unaligned, with the
  extrinsics it holds (the Viewer's ``tf/0`` of each stream, else the TF tree between the two
  optical frames);
* the pose from the odometry topic (nearest stamp within half a colour frame period; none: the
  frame has no pose, as in a tracker dropout) and its twist's angular velocity (the tracker's gyro,
  which the QR reader deblurs a slew by), the camera mount then from the TF tree between the
  odometry's child frame and the colour frame; or, without odometry, the TF tree from ``map``
  (or ``odom``) to the colour frame; with neither, the camera's first pose is the map frame for
  every frame, and :attr:`Recording.notes` says so.

A log its writer never closed (a run killed mid-trial: a rosbag2 MCAP folder without
``metadata.yaml`` and summary, a ROS 1 bag without its index) is read as far as it was written
(:mod:`eval.ros.unclosed`), and the notes say so.

Every problem with the file is one line naming it and the topic: a missing topic, an unknown
encoding, a truncated file, no camera info (:class:`RecordingError`).

References
----------
Full entries in docs/SOURCES.md.

.. [rosbags] Ternaris, "rosbags: pure Python library to read, modify, convert and write rosbag
   files", Apache-2.0.
"""

from __future__ import annotations

import bisect
import contextlib
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from eval.ros.align import align_depth_to_color
from eval.ros.compression import COMPRESSED_SUFFIX, DEPTH_SUFFIX
from eval.ros.messages import (
    MessageError,
    colour_of,
    depth_of,
    intrinsics_of,
    matrix_of,
    stamp_ns,
    thermal_of,
)
from eval.ros.topics import UNALIGNED_DEPTH, FrameNames, Topics, viewer_streams
from poi.core.geometry import R_BODY_OPTICAL, invert_transform, make_transform
from poi.core.types import Frame, Intrinsics

if TYPE_CHECKING:
    from eval.ros.unclosed import _Unclosed

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
ODOMETRY = "nav_msgs/msg/Odometry"
DEFAULT_PAIR_TOLERANCE_NS = 50_000_000  # a lone colour frame: depth and pose within 50 ms of it


class RecordingError(ValueError):
    """A recording poibench cannot read; the one-line message names the file and the topic."""


@dataclass
class TfTree:
    """The transforms of ``/tf_static`` (fixed) and ``/tf`` (stamped), child -> (parent, T_parent_child)."""

    static: dict[str, tuple[str, np.ndarray]] = field(default_factory=dict)
    dynamic: dict[str, list[tuple[int, str, np.ndarray]]] = field(default_factory=dict)

    def add(self, msg, is_static: bool) -> None:
        for tf in msg.transforms:
            T = matrix_of(tf.transform.translation, tf.transform.rotation)
            parent, child = tf.header.frame_id.lstrip("/"), tf.child_frame_id.lstrip("/")
            if is_static:
                self.static[child] = (parent, T)
            else:
                self.dynamic.setdefault(child, []).append((stamp_ns(tf.header.stamp), parent, T))

    def sort(self) -> None:
        for v in self.dynamic.values():
            v.sort(key=lambda e: e[0])

    def _edge(self, child: str, t_ns: int | None, tol_ns: int) -> tuple[str, np.ndarray] | None:
        if child in self.static:
            return self.static[child]
        seq = self.dynamic.get(child)
        if not seq or t_ns is None:
            return None
        k = bisect.bisect_left([e[0] for e in seq], t_ns)
        best = min((seq[j] for j in (k - 1, k) if 0 <= j < len(seq)), key=lambda e: abs(e[0] - t_ns))
        return (best[1], best[2]) if abs(best[0] - t_ns) <= tol_ns else None

    def chain(self, frame: str, t_ns: int | None = None, tol_ns: int = 0) -> dict[str, np.ndarray]:
        """Every ancestor of ``frame`` with T_ancestor_frame (``frame`` itself: identity)."""
        out = {frame: np.eye(4)}
        T, f = np.eye(4), frame
        for _ in range(64):  # a tree is never this deep; a loop in a broken file stops here
            e = self._edge(f, t_ns, tol_ns)
            if e is None:
                break
            f, T = e[0], e[1] @ T
            out[f] = T
        return out

    def between(self, parent: str, child: str, t_ns: int | None = None, tol_ns: int = 0) -> np.ndarray | None:
        """T_parent_child through their nearest common ancestor, or None when they are not connected."""
        a, b = self.chain(parent, t_ns, tol_ns), self.chain(child, t_ns, tol_ns)
        common = next((f for f in b if f in a), None)
        return None if common is None else invert_transform(a[common]) @ b[common]

    def frames(self) -> set[str]:
        names = set(self.static) | set(self.dynamic)
        names |= {p for p, _ in self.static.values()} | {e[1] for v in self.dynamic.values() for e in v}
        return names


@dataclass(kw_only=True)
class Recording:
    """What :func:`open_recording` found; :meth:`frames` reads the frames."""

    path: Path
    layout: str  # "realsense-ros", "viewer" (RealSense Viewer) or "custom" (names given)
    color_topic: str
    depth_topic: str
    color_k: Intrinsics
    depth_k: Intrinsics
    aligned: bool
    T_color_depth: np.ndarray
    depth_unit_m: float
    pose_source: str  # "odometry TOPIC", "tf FRAME", or "none"
    T_tracker_camera: np.ndarray | None  # the mount the recording holds (None: the config's)
    n_frames: int
    period_ns: int  # the colour stream's frame period (median stamp difference)
    start: datetime  # the first colour frame's stamp, UTC
    notes: list[str] = field(default_factory=list)
    thermal_topic: str | None = None
    thermal_k: Intrinsics | None = None
    # colour stamps and, per colour frame, the depth / thermal stamp paired with it and the pose
    _color_stamps: list[int] = field(default_factory=list, repr=False)
    _depth_of: list[int | None] = field(default_factory=list, repr=False)
    _thermal_of: list[int | None] = field(default_factory=list, repr=False)
    _poses: list[np.ndarray | None] = field(default_factory=list, repr=False)
    # per colour frame, the odometry's angular velocity with its pose (the tracker's gyro; None without)
    _rates: list[np.ndarray | None] = field(default_factory=list, repr=False)
    # a log its writer never closed: the reader that found its connections and last stamp (one scan
    # of the file), kept so that reading the frames does not scan it again
    _unclosed: _Unclosed | None = field(default=None, repr=False)

    @property
    def fps(self) -> float:
        return 1e9 / self.period_ns

    def frames(self) -> Iterator[Frame]:
        """The frames in colour-stamp order (each colour image once)."""
        want = {self.color_topic, self.depth_topic} | ({self.thermal_topic} if self.thermal_topic else set())
        depth_wanted = {s for s in self._depth_of if s is not None}
        thermal_wanted = {s for s in self._thermal_of if s is not None}
        order = {s: i for i, s in enumerate(self._color_stamps)}
        colours: dict[int, np.ndarray] = {}
        depths: dict[int, np.ndarray] = {}
        thermals: dict[int, np.ndarray] = {}
        last_depth = {d: j for j, d in enumerate(self._depth_of) if d is not None}
        last_thermal = {d: j for j, d in enumerate(self._thermal_of) if d is not None}
        k = 0
        t0 = self._color_stamps[0] if self._color_stamps else 0
        with _open(self.path) if self._unclosed is None else contextlib.nullcontext(self._unclosed) as reader:
            conns = [c for c in reader.connections if c.topic in want]
            for conn, _, raw in _messages(reader, conns, self.path):
                msg = _deserialize(reader, raw, conn, self.path)
                s = stamp_ns(msg.header.stamp)
                if conn.topic == self.color_topic and s in order:
                    colours[s] = _decode(colour_of, msg, conn.topic, self.path)
                elif conn.topic == self.depth_topic and s in depth_wanted:
                    depths[s] = _decode(depth_of, msg, conn.topic, self.path, self.depth_unit_m)
                elif conn.topic == self.thermal_topic and s in thermal_wanted:
                    thermals[s] = _decode(thermal_of, msg, conn.topic, self.path)
                # hand out every frame whose parts have all arrived, in colour order
                while k < len(self._color_stamps):
                    cs, ds, ts_ = self._color_stamps[k], self._depth_of[k], self._thermal_of[k]
                    if cs not in colours or (ds is not None and ds not in depths):
                        break
                    if ts_ is not None and ts_ not in thermals:
                        break
                    yield self._frame(k, t0, colours.pop(cs), depths.get(ds), thermals.get(ts_))
                    if last_depth.get(ds) == k:  # no later colour frame pairs with this depth image
                        depths.pop(ds, None)
                    if last_thermal.get(ts_) == k:
                        thermals.pop(ts_, None)
                    k += 1
        if k < len(self._color_stamps):
            raise RecordingError(
                f"{self.path}: truncated: {len(self._color_stamps) - k} frames of {self.color_topic} "
                "could not be read"
            )

    def _frame(self, k: int, t0: int, rgb: np.ndarray, depth: np.ndarray | None, thermal) -> Frame:
        if depth is not None and not self.aligned:
            depth = align_depth_to_color(depth, self.depth_k, self.color_k, self.T_color_depth)
        if rgb.shape[:2] != (self.color_k.height, self.color_k.width):
            raise RecordingError(
                f"{self.path}: {self.color_topic} frame {k} is {rgb.shape[1]}x{rgb.shape[0]}, its camera info "
                f"{self.color_k.width}x{self.color_k.height}"
            )
        return Frame(
            index=k,
            timestamp_s=(self._color_stamps[k] - t0) / 1e9,
            rgb=rgb,
            intrinsics=self.color_k,
            depth_m=depth,
            pose=self._poses[k],
            angular_velocity=self._rates[k] if self._rates else None,
            thermal_c=thermal,
            thermal_intrinsics=self.thermal_k if thermal is not None else None,
        )


def _unclosed_mcap(path: Path) -> Path | None:
    """The MCAP file of a rosbag2 folder its writer never closed (no metadata.yaml), or None."""
    if not path.is_dir() or (path / "metadata.yaml").is_file():
        return None
    stored = sorted(path.glob("*.mcap"))
    return stored[0] if len(stored) == 1 else None


def _never_closed(path: Path) -> Path | None:
    """What to read of a log its writer never closed: the MCAP file of a rosbag2 folder without
    metadata.yaml, or a ROS 1 bag without its index (the bag itself); None for any other path."""
    from eval.ros.unclosed import bag_is_unclosed

    stored = _unclosed_mcap(path)
    if stored is not None:
        return stored
    return path if path.is_file() and bag_is_unclosed(path) else None


def _unclosed(path: Path):
    """A reader of :mod:`eval.ros.unclosed` for a log its writer never closed, or None."""
    import importlib.util

    from eval.ros.unclosed import UnclosedBag, UnclosedMcap

    stored = _never_closed(path)
    if stored is None:
        return None
    if stored == path:
        return UnclosedBag(path)
    if importlib.util.find_spec("mcap") is None:
        raise RecordingError(
            f"{path}: a recording never closed (no metadata.yaml); reading it needs the mcap library: "
            "pip install 'poibench[ros]' (or pip install mcap)"
        )
    return UnclosedMcap(stored)


def _not_a_recording(path: Path) -> str | None:
    """Why ``path`` cannot be a recording poibench reads, said plainly, or None: a folder without
    rosbag2's metadata.yaml and without the one MCAP file of an unclosed recording, or a file that
    does not start as a ROS 1 bag does."""
    if path.is_dir():
        if (path / "metadata.yaml").is_file() or _unclosed_mcap(path):
            return None
        stored = sorted(p.name for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
        if stored:
            return (
                f"{path}: a rosbag2 folder without metadata.yaml beside {', '.join(stored)} (the recording was "
                "never closed: a run stopped before its end?); ros2 bag reindex rebuilds it"
            )
        return f"{path}: not a recording (no rosbag2 metadata.yaml, no .mcap or .db3 in the folder)"
    from eval.ros.unclosed import ROS1_MAGIC

    with open(path, "rb") as f:
        head = f.read(len(ROS1_MAGIC))
    if path.suffix == ".bag" and head != ROS1_MAGIC:
        return f"{path}: not a ROS 1 bag (it does not start with {ROS1_MAGIC.decode()})"
    return None


def _open(path: Path):
    """A reader of the recording at ``path``: rosbags' for a closed recording, :mod:`eval.ros.unclosed`'s
    for a log its writer never closed."""
    from rosbags.highlevel import AnyReader

    problem = _not_a_recording(path)
    if problem:
        raise RecordingError(problem)
    try:
        reader = _unclosed(path)
        if reader is None:
            reader = AnyReader([path])
            reader.open()
    except RecordingError:
        raise
    except Exception as e:  # rosbags raises its own errors, and struct/KeyError on a damaged file
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise RecordingError(f"{path}: cannot read the recording (truncated or not a bag?): {reason}") from None

    class _Closing:
        def __enter__(self):
            return reader

        def __exit__(self, *exc):
            reader.close()
            return False

    return _Closing()


def _messages(reader, conns, path: Path):
    try:
        yield from reader.messages(connections=conns)
    except RecordingError:
        raise
    except Exception as e:
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise RecordingError(f"{path}: truncated or damaged: {reason}") from None


def _deserialize(reader, raw, conn, path: Path):
    try:
        return reader.deserialize(raw, conn.msgtype)
    except Exception as e:
        reason = (str(e).splitlines() or [type(e).__name__])[0]
        raise RecordingError(
            f"{path}: {conn.topic}: a {conn.msgtype} message that cannot be decoded: {reason}"
        ) from None


def _decode(fn, msg, topic: str, path: Path, *args):
    try:
        return fn(msg, topic, *args)
    except MessageError as e:
        raise RecordingError(f"{path}: {e}") from None


def _nearest(stamps: list[int], s: int, tol_ns: int) -> int | None:
    """Index of the stamp nearest ``s`` within ``tol_ns``, or None."""
    k = bisect.bisect_left(stamps, s)
    best = min((j for j in (k - 1, k) if 0 <= j < len(stamps)), key=lambda j: abs(stamps[j] - s), default=None)
    return best if best is not None and abs(stamps[best] - s) <= tol_ns else None


def open_recording(
    path: str | Path, topics: Topics | None = None, given: set[str] = frozenset(), names: FrameNames | None = None
) -> Recording:
    """Find the streams of the recording at ``path`` (a ``.bag`` file or a rosbag2 folder) and
    index its frames. ``given`` names the :class:`Topics` fields the user set (they are used
    as they are; the others fall back to the layout found)."""
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such file or folder")
    try:
        return _index(path, topics or Topics(), given, names or FrameNames())
    except RecordingError as e:
        if "never closed" in str(e) or _never_closed(path) is None:
            raise
        # what is missing may be what the writer had not flushed when it stopped
        raise RecordingError(f"{e} (a recording never closed or cut short: read as far as it goes)") from None


def _index(path: Path, topics: Topics, given: set[str], names: FrameNames) -> Recording:
    """:func:`open_recording` of an existing ``path``."""
    notes: list[str] = []
    with _open(path) as reader:
        unclosed = reader if hasattr(reader, "note") else None
        if unclosed is not None:
            notes.append(unclosed.note())
        by_topic = {}
        for c in reader.connections:
            by_topic.setdefault(c.topic, c)
        available = sorted(by_topic)
        viewer = viewer_streams(available)
        depth_unit_m = 0.001
        viewer_ext: dict[str, str] = {}
        if "color" not in given and topics.color not in by_topic and "Color" in viewer:
            layout = "viewer"
            c, d = viewer["Color"], viewer.get("Depth")
            color, color_info = c.image, c.info
            depth, depth_info = (d.image, d.info) if d else (topics.depth, topics.depth_info)
            aligned = False
            viewer_ext = {"color": c.extrinsics, "depth": d.extrinsics if d else ""}
            unit_topic = next((t for t in available if t.endswith("/option/Depth Units/value")), None)
            fps_topic = c.image[: -len("/image/data")] + "/info"
        else:
            layout = "custom" if given & {"color", "depth"} else "realsense-ros"
            color, color_info = topics.color, topics.color_info
            depth, depth_info = topics.depth, topics.depth_info
            aligned = True
            # image_transport's compressed topics (poibench run --log-images png) when the raw ones are absent
            color = _compressed_topic(color, by_topic, (COMPRESSED_SUFFIX,))
            depth = _compressed_topic(depth, by_topic, (DEPTH_SUFFIX, COMPRESSED_SUFFIX))
            if "depth" not in given and depth not in by_topic and UNALIGNED_DEPTH[0] in by_topic:
                depth, depth_info = UNALIGNED_DEPTH
                aligned = False
            elif "aligned_depth" not in depth and "depth" in given:
                aligned = False  # a depth topic given by name: aligned only if its info says so (below)
            unit_topic = fps_topic = None
        for stream, role, topic, kinds in (
            ("color", "colour image", color, (IMAGE, COMPRESSED_IMAGE)),
            ("color_info", "colour camera info", color_info, (CAMERA_INFO,)),
            ("depth", "depth image", depth, (IMAGE, COMPRESSED_IMAGE)),
            ("depth_info", "depth camera info", depth_info, (CAMERA_INFO,)),
        ):
            if topic not in by_topic:
                what = "no camera info" if kinds == (CAMERA_INFO,) else "missing topic"
                image = stream.removesuffix("_info")
                if image != stream and image in given and stream not in given:  # put beside the named image
                    what += f" beside --topic {image}"
                raise RecordingError(
                    f"{path}: {what}: no {role} on {topic} (--topic to name another; topics: "
                    f"{_topic_list(available)})"
                )
            if by_topic[topic].msgtype not in kinds:
                raise RecordingError(
                    f"{path}: {topic} holds {by_topic[topic].msgtype}, not the {role} ({' or '.join(kinds)})"
                )
        for role in ("odom", "thermal", "thermal_info", "tf", "tf_static"):  # named by --topic: must be there
            if role in given and getattr(topics, role) not in by_topic:
                raise RecordingError(
                    f"{path}: --topic {role}={getattr(topics, role)}: no such topic in the recording (topics: "
                    f"{_topic_list(available)})"
                )
        odom = topics.odom if topics.odom in by_topic else None
        if odom is not None and by_topic[odom].msgtype != ODOMETRY:
            raise RecordingError(f"{path}: {odom} holds {by_topic[odom].msgtype}, not {ODOMETRY}")
        thermal = topics.thermal if topics.thermal in by_topic else None
        if thermal is not None and topics.thermal_info not in by_topic:
            raise RecordingError(f"{path}: no camera info: no thermal camera info on {topics.thermal_info}")

        # pass 1: everything but the image pixels
        infos: dict[str, Intrinsics] = {}
        info_topics = {color_info, depth_info} | ({topics.thermal_info} if thermal else set())
        stamps: dict[str, list[int]] = {color: [], depth: []}
        if thermal:
            stamps[thermal] = []
        frame_ids: dict[str, str] = {}
        odom_stamps: list[int] = []
        odom_poses: list[np.ndarray] = []
        odom_rates: list[np.ndarray] = []  # the twist's angular velocity (rad/s, the child frame's axes)
        odom_child = None
        tree = TfTree()
        ext: dict[str, np.ndarray] = {}
        color_fps = 0.0
        small = info_topics | {t for t in (odom, topics.tf, topics.tf_static, unit_topic, fps_topic) if t}
        small |= {t for t in viewer_ext.values() if t}
        conns = [by_topic[t] for t in sorted(small | set(stamps)) if t in by_topic]
        for conn, _, raw in _messages(reader, conns, path):
            t = conn.topic
            if t in stamps:  # an image: only its header is needed here
                head = _raw_header(raw, reader.is2)
                if head is None:
                    msg = _deserialize(reader, raw, conn, path)
                    head = (stamp_ns(msg.header.stamp), msg.header.frame_id)
                stamps[t].append(head[0])
                frame_ids.setdefault(t, head[1].lstrip("/"))
                continue
            msg = _deserialize(reader, raw, conn, path)
            if t in info_topics and t not in infos:
                infos[t] = _decode(intrinsics_of, msg, t, path)
            elif t == odom:
                p = msg.pose.pose
                odom_stamps.append(stamp_ns(msg.header.stamp))
                odom_poses.append(_matrix(p.position, p.orientation, t, path))
                w = msg.twist.twist.angular
                odom_rates.append(np.array([w.x, w.y, w.z], float))
                odom_child = odom_child or msg.child_frame_id.lstrip("/")
            elif t in (topics.tf, topics.tf_static):
                try:
                    tree.add(msg, t == topics.tf_static)
                except MessageError as e:
                    raise RecordingError(f"{path}: {t}: {e}") from None
            elif t == unit_topic:
                depth_unit_m = float(msg.data)
            elif t == fps_topic:
                color_fps = float(getattr(msg, "fps", 0.0))
            else:
                for role, et in viewer_ext.items():
                    if t == et:
                        ext[role] = _matrix(msg.translation, msg.rotation, t, path)
    tree.sort()
    for t in info_topics:
        if t not in infos:
            raise RecordingError(f"{path}: no camera info: {t} holds no message")
    if not stamps[color]:
        raise RecordingError(f"{path}: missing topic: {color} holds no image")
    color_k, depth_k = infos[color_info], infos[depth_info]
    if aligned and (depth_k.width, depth_k.height) != (color_k.width, color_k.height):
        aligned = False
    T_color_depth = np.eye(4)
    if not aligned:
        if layout == "viewer":
            if "color" not in ext or "depth" not in ext:
                raise RecordingError(
                    f"{path}: no extrinsics to align depth to colour "
                    f"({viewer_ext['color']}, {viewer_ext['depth']})"
                )
            # tf/0 is the extrinsics from the device's reference stream (depth) to the stream:
            # p_stream = T p_ref (on the D435 fixture colour edges then fall on depth edges; with the
            # inverse they are off by the 14 mm baseline, about 6 px at 1.5 m)
            T_color_depth = ext["color"] @ invert_transform(ext["depth"])
        else:
            T = tree.between(frame_ids.get(color, ""), frame_ids.get(depth, ""))
            if T is None:
                raise RecordingError(
                    f"{path}: depth on {depth} is not aligned to colour and no TF connects its frame "
                    f"{frame_ids.get(depth)!r} to the colour frame {frame_ids.get(color)!r}"
                )
            T_color_depth = T
        notes.append(f"depth on {depth} aligned to colour with the recording's extrinsics")

    color_stamps = sorted(set(stamps[color]))
    if len(color_stamps) > 1:
        period = int(np.median(np.diff(color_stamps)))
    else:  # one frame: the stream's declared rate (the Viewer's StreamInfo), else 10 Hz
        period = int(1e9 / color_fps) if color_fps else 2 * DEFAULT_PAIR_TOLERANCE_NS
    # depth and thermal: the nearest image within a colour period (streams need not be synchronised);
    # the pose: within half a period, so a tracker dropout leaves its frame without a pose
    tol = period // 2
    dstamps = sorted(set(stamps[depth]))
    depth_of = [None if (j := _nearest(dstamps, s, period)) is None else dstamps[j] for s in color_stamps]
    missing_depth = sum(d is None for d in depth_of)
    if missing_depth:
        notes.append(
            f"{missing_depth} of {len(color_stamps)} colour frames have no depth within {period / 1e6:.0f} ms"
        )
    thermal_of: list[int | None] = [None] * len(color_stamps)
    thermal_k = None
    if thermal:
        tstamps = sorted(set(stamps[thermal]))
        thermal_of = [None if (j := _nearest(tstamps, s, period)) is None else tstamps[j] for s in color_stamps]
        thermal_k = infos[topics.thermal_info]

    color_frame = frame_ids.get(color, "")
    mount = None
    rates: list[np.ndarray | None] = [None] * len(color_stamps)
    if odom is not None and odom_stamps:
        order = np.argsort(odom_stamps, kind="stable")
        os_ = [odom_stamps[i] for i in order]
        op = [odom_poses[i] for i in order]
        orates = [odom_rates[i] for i in order]
        nearest = [_nearest(os_, s, tol) for s in color_stamps]
        poses = [None if j is None else op[j] for j in nearest]
        rates = [None if j is None else orates[j] for j in nearest]
        pose_source = f"odometry {odom}"
        mount = tree.between(odom_child or "", color_frame) if odom_child and color_frame else None
        if mount is None:
            notes.append(
                f"no TF from the odometry's frame {odom_child!r} to the colour frame {color_frame!r}: the camera "
                "mount is the pipeline config's (mount.T_tracker_camera)"
            )
        no_pose = sum(p is None for p in poses)
        if no_pose:
            notes.append(f"{no_pose} of {len(poses)} frames have no odometry within {tol / 1e6:.0f} ms (no pose)")
    else:
        root = next((f for f in (names.map, names.odom) if f in tree.frames()), None)
        poses = []
        if root is not None and color_frame:
            poses = [tree.between(root, color_frame, s, tol) for s in color_stamps]
        if poses and any(p is not None for p in poses):
            pose_source = f"tf {root}"
            mount = np.eye(4)  # the pose is the colour camera's own
        else:
            pose_source = "none"
            mount = np.eye(4)
            # the map frame is the camera's first pose, level: x forward (optical z), z up (optical -y)
            T_map_camera = make_transform(R_BODY_OPTICAL, [0.0, 0.0, 0.0])
            poses = [T_map_camera] * len(color_stamps)
            notes.append(
                f"no odometry ({topics.odom}) and no TF to the colour frame: the camera's first pose is the map "
                "frame (x forward, z up), the same for every frame"
            )
    start = datetime.fromtimestamp(color_stamps[0] / 1e9, tz=timezone.utc).replace(tzinfo=None)
    return Recording(
        path=path,
        layout=layout,
        color_topic=color,
        depth_topic=depth,
        color_k=color_k,
        depth_k=depth_k,
        aligned=aligned,
        T_color_depth=T_color_depth,
        depth_unit_m=depth_unit_m,
        pose_source=pose_source,
        T_tracker_camera=mount,
        n_frames=len(color_stamps),
        period_ns=period,
        start=start,
        notes=notes,
        thermal_topic=thermal,
        thermal_k=thermal_k,
        _color_stamps=color_stamps,
        _depth_of=depth_of,
        _thermal_of=thermal_of,
        _poses=poses,
        _rates=rates,
        _unclosed=unclosed,
    )


def _compressed_topic(topic: str, by_topic: dict, suffixes: tuple[str, ...]) -> str:
    """``topic`` when the recording has it, else its first image_transport compressed topic
    (``topic`` + a suffix) that it has, else ``topic`` (reported missing by the caller).

    >>> _compressed_topic("/c", {"/c/compressed": None}, ("/compressed",))
    '/c/compressed'
    """
    if topic in by_topic:
        return topic
    return next((topic + s for s in suffixes if topic + s in by_topic), topic)


def _raw_header(raw, ros2: bool) -> tuple[int, str] | None:
    """(stamp ns, frame_id) of a serialised message that starts with a ``std_msgs/Header``, read from its
    first bytes: ROS 2 CDR little-endian (4-byte encapsulation, int32 sec, uint32 nanosec, uint32 length
    with the terminating NUL, the characters) or ROS 1 (uint32 seq, uint32 secs, uint32 nsecs, uint32
    length, the characters). None for anything else (a big-endian CDR), which is then deserialised whole.

    >>> _raw_header(bytes([0, 1, 0, 0]) + struct.pack("<iII", 2, 5, 2) + b"c" + bytes(1), ros2=True)
    (2000000005, 'c')
    """
    b = memoryview(raw)
    try:
        if ros2:
            if bytes(b[:2]) != b"\x00\x01":
                return None
            sec, nsec, n = struct.unpack_from("<iII", b, 4)
            name = bytes(b[16 : 16 + max(n - 1, 0)])
        else:
            _, sec, nsec, n = struct.unpack_from("<IIII", b, 0)
            name = bytes(b[16 : 16 + n])
        return sec * 1_000_000_000 + nsec, name.decode("utf-8")
    except (struct.error, UnicodeDecodeError):
        return None


def _matrix(translation, rotation, topic: str, path: Path) -> np.ndarray:
    try:
        return matrix_of(translation, rotation)
    except MessageError as e:
        raise RecordingError(f"{path}: {topic}: {e}") from None


def _topic_list(topics: list[str], limit: int = 8) -> str:
    shown = ", ".join(topics[:limit])
    return shown + (f" and {len(topics) - limit} more" if len(topics) > limit else "") if topics else "none"
