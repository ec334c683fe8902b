"""Topic and frame names of the logs poibench writes and reads.

The defaults follow realsense-ros [RealsenseRos]_ (``realsense2_camera``, camera name ``camera``;
the T265 under the name ``t265`` as its D400-plus-T265 launch file has it): colour on
``/camera/color/image_raw``, depth aligned to colour on
``/camera/aligned_depth_to_color/image_raw``, each with its ``camera_info``, the T265's odometry on
``/t265/odom/sample``. Every name can be changed (``--topic color=/front/rgb`` on the command
line, :func:`parse_overrides`).

A RealSense Viewer recording (librealsense's own bag layout [IntelRosbag]_) keeps each stream
under ``/device_0/sensor_S/<Stream>_I/``: ``image/data`` (the frames), ``info/camera_info`` (its
intrinsics) and ``tf/0`` (the extrinsics from the device's reference stream to it). :func:`viewer_streams`
finds them.

References
----------
Full entries in docs/SOURCES.md.

.. [RealsenseRos] Intel RealSense, "realsense-ros: ROS wrapper for Intel RealSense cameras"
   (realsense2_camera), topic names of its launch files.
.. [IntelRosbag] Intel RealSense, librealsense "ROS bag" recording format (src/media/ros).
.. [ImageTransport] ROS, "image_transport" (``camera_common``: ``getCameraInfoTopic``).
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass


class TopicError(ValueError):
    """A topic name override that names no topic; one line."""


@dataclass(frozen=True, kw_only=True)
class Topics:
    """Where each stream is, in a log poibench writes or a recording it reads."""

    color: str = "/camera/color/image_raw"
    color_info: str = "/camera/color/camera_info"
    depth: str = "/camera/aligned_depth_to_color/image_raw"
    depth_info: str = "/camera/aligned_depth_to_color/camera_info"
    odom: str = "/t265/odom/sample"
    thermal: str = "/thermal/image_raw"
    thermal_info: str = "/thermal/camera_info"
    tf: str = "/tf"
    tf_static: str = "/tf_static"
    truth: str = "/poibench/truth"
    detections: str = "/poibench/detections"
    confirmed: str = "/poibench/confirmed"


# realsense-ros's depth topics before alignment, looked for when the aligned ones are absent
UNALIGNED_DEPTH = ("/camera/depth/image_rect_raw", "/camera/depth/camera_info")


@dataclass(frozen=True, kw_only=True)
class FrameNames:
    """TF frame names: the map, odometry and robot frames, and each camera's optical frame.

    The tree written: ``map -> odom`` (identity), ``odom -> base`` (the tracked pose on the
    floor: x, y, yaw), ``base -> mast`` (the rest of the tracker's pose: its height, pitch and roll;
    the tracker sits on the mast), ``mast -> color`` (the camera mount), ``color -> depth``
    (identity: depth is aligned to colour) and ``color -> thermal``.
    """

    map: str = "map"
    odom: str = "odom"
    base: str = "base_link"
    mast: str = "t265_pose_frame"
    color: str = "camera_color_optical_frame"
    depth: str = "camera_aligned_depth_to_color_frame"
    thermal: str = "thermal_optical_frame"


# each image stream and the stream of its camera's intrinsics
IMAGE_INFO = {"color": "color_info", "depth": "depth_info", "thermal": "thermal_info"}


def camera_info_topic(image_topic: str) -> str:
    """The ``camera_info`` topic beside an image topic: the image's namespace plus ``camera_info``,
    where image_transport's camera publisher puts it ([ImageTransport]_, ``getCameraInfoTopic``) and
    realsense-ros has it ([RealsenseRos]_); for a transport's topic (``.../image_raw/compressed``,
    ``.../compressedDepth``), beside its base topic.

    >>> camera_info_topic("/cam/color/image_raw"), camera_info_topic("/cam/depth/image_raw/compressedDepth")
    ('/cam/color/camera_info', '/cam/depth/camera_info')
    """
    from eval.ros.compression import COMPRESSED_SUFFIX, DEPTH_SUFFIX

    for suffix in (COMPRESSED_SUFFIX, DEPTH_SUFFIX):
        if image_topic.endswith(suffix):
            image_topic = image_topic[: -len(suffix)]
    return image_topic.rsplit("/", 1)[0] + "/camera_info"


def parse_overrides(items: list[str], base: Topics | None = None, flag: str = "--topic") -> Topics:
    """``Topics`` with ``NAME=/topic`` overrides applied, e.g. ``["color=/front/rgb"]``; errors name
    ``flag``, the option the items came from. An image stream named without its camera info
    (``color`` without ``color_info``) has the info beside it (:func:`camera_info_topic`).

    >>> t = parse_overrides(["color=/cam/color/image_raw"])
    >>> t.color, t.color_info, t.depth_info
    ('/cam/color/image_raw', '/cam/color/camera_info', '/camera/aligned_depth_to_color/camera_info')
    >>> parse_overrides(["colour=/x"])
    Traceback (most recent call last):
    ...
    eval.ros.topics.TopicError: --topic colour=/x: unknown stream 'colour'; expected one of color, ...
    """
    topics = base or Topics()
    names = [f.name for f in dataclasses.fields(Topics)]
    changes = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not value.startswith("/") or value.endswith("/"):
            raise TopicError(f"{flag} {item}: expected NAME=/topic/name, e.g. color=/camera/color/image_raw")
        if name not in names:
            raise TopicError(f"{flag} {item}: unknown stream {name!r}; expected one of {', '.join(names)}")
        changes[name] = value
    named = set(changes)
    for image, info in IMAGE_INFO.items():
        if image in named and info not in named:
            changes[info] = camera_info_topic(changes[image])
    out = dataclasses.replace(topics, **changes)
    first_of: dict[str, str] = {}  # topic -> the first stream on it
    for name in names:
        topic = getattr(out, name)
        first = first_of.setdefault(topic, name)
        if first != name and {first, name} & set(changes):
            derived = [n for n in (first, name) if n in changes and n not in named]
            hint = (
                f" ({', '.join(derived)}: beside its image topic unless named, {flag} {derived[0]}=/...)"
                if derived
                else ""
            )
            raise TopicError(f"{flag}: {first} and {name} would both be {topic}{hint}")
    return out


_VIEWER = re.compile(r"^/device_(\d+)/sensor_(\d+)/(\w+?)_(\d+)/image/data$")


@dataclass(frozen=True, kw_only=True)
class ViewerStream:
    """One stream of a RealSense Viewer recording: its image, camera info and extrinsics topics."""

    kind: str  # "Color", "Depth", "Infrared", ...
    image: str
    info: str
    extrinsics: str


def viewer_streams(topics: list[str]) -> dict[str, ViewerStream]:
    """The Viewer-layout streams among ``topics`` by kind (the first of each kind).

    >>> s = viewer_streams(["/device_0/sensor_1/Color_0/image/data"])
    >>> s["Color"].info, s["Color"].extrinsics
    ('/device_0/sensor_1/Color_0/info/camera_info', '/device_0/sensor_1/Color_0/tf/0')
    """
    found: dict[str, ViewerStream] = {}
    for t in sorted(topics):
        m = _VIEWER.match(t)
        if m is None or m.group(3) in found:
            continue
        stem = t[: -len("/image/data")]
        found[m.group(3)] = ViewerStream(
            kind=m.group(3), image=t, info=f"{stem}/info/camera_info", extrinsics=f"{stem}/tf/0"
        )
    return found
