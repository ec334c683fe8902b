"""ROS messages to and from poibench's arrays, for ROS 1 and ROS 2 alike.

Messages are the ``rosbags`` typestore's dataclasses [rosbags]_. :func:`build` makes one from
the fields given and fills every other field with its zero value, so one call works in both
dialects (ROS 1 has ``Header.seq`` and ``CameraInfo.K``; ROS 2 has ``CameraInfo.k`` and more
``Marker`` fields). Images follow ``sensor_msgs/Image``'s encodings: colour ``rgb8`` (``bgr8``,
``rgba8``, ``bgra8`` read too), depth ``16UC1``/``mono16`` millimetres or ``32FC1`` metres, thermal
``32FC1`` degrees Celsius. Colour and depth are read from ``sensor_msgs/CompressedImage`` too
(:mod:`eval.ros.compression`: PNG or JPEG colour, compressedDepth or 16-bit PNG depth).

References
----------
Full entries in docs/SOURCES.md.

.. [rosbags] Ternaris, "rosbags: pure Python library to read, modify, convert and write rosbag
   files", Apache-2.0.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from eval.ros.compression import CodecError, Encoded, decode_colour, decode_depth
from poi.core.depth_units import from_z16
from poi.core.geometry import make_transform, matrix_to_quat_wxyz, quat_wxyz_to_matrix
from poi.core.types import Intrinsics

# rosbags' node kinds in ``Typestore.fielddefs`` (rosbags.typesys.base.Nodetype)
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4
_NUMPY = {
    "bool": np.bool_,
    "byte": np.uint8,
    "char": np.uint8,
    "int8": np.int8,
    "uint8": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}
# bytes a pixel and channels of each image encoding read here; depth 16UC1 and mono16 are millimetres
COLOUR_ENCODINGS = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4}
DEPTH_ENCODINGS = ("16UC1", "mono16", "32FC1")


# tf2_msgs/TFMessage as ROS 1 defines it (tf2_msgs/msg/TFMessage.msg); rosbags' ROS 1 store lacks it
TF_MESSAGE_DEFINITION = "geometry_msgs/TransformStamped[] transforms\n"


def typestore(ros1: bool):
    """rosbags' message types of ROS 1 Noetic or ROS 2 Humble, ``tf2_msgs/TFMessage`` included."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in ts.types:
        ts.register(get_types_from_msg(TF_MESSAGE_DEFINITION, "tf2_msgs/msg/TFMessage"))
    return ts


class MessageError(ValueError):
    """A message poibench cannot use (an unknown encoding, a size that does not fit); one line."""


def _zero(ts, node) -> Any:
    kind, arg = node
    if kind == _BASE:
        name = arg[0]
        if name == "string":
            return ""
        return False if name == "bool" else (0.0 if name.startswith("float") else 0)
    if kind == _NAME:
        return build(ts, arg)
    sub, length = arg
    if sub[0] == _BASE and sub[1][0] in _NUMPY:
        return np.zeros(length if kind == _ARRAY else 0, dtype=_NUMPY[sub[1][0]])
    return [_zero(ts, sub) for _ in range(length if kind == _ARRAY else 0)]


def build(ts, msgtype: str, **given: Any):
    """A ``msgtype`` message of typestore ``ts``: the fields ``given``, every other one zero.
    A field this dialect lacks (``seq`` in ROS 2) is dropped."""
    _, fields = ts.fielddefs[msgtype]
    values = {}
    for name, node in fields:
        values[name] = given[name] if name in given else _zero(ts, node)
    return ts.types[msgtype](**values)


def has_field(ts, msgtype: str, name: str) -> bool:
    return any(f == name for f, _ in ts.fielddefs[msgtype][1])


def stamp(ts, t_ns: int):
    """``builtin_interfaces/Time`` of ``t_ns`` nanoseconds."""
    return ts.types["builtin_interfaces/msg/Time"](
        sec=int(t_ns // 1_000_000_000), nanosec=int(t_ns % 1_000_000_000)
    )


def stamp_ns(time_msg) -> int:
    return int(time_msg.sec) * 1_000_000_000 + int(time_msg.nanosec)


def header(ts, t_ns: int, frame_id: str):
    return build(ts, "std_msgs/msg/Header", stamp=stamp(ts, t_ns), frame_id=frame_id)


# --- images --------------------------------------------------------------------------------------


def image_msg(ts, t_ns: int, frame_id: str, array: np.ndarray, encoding: str):
    """``sensor_msgs/Image`` of an (H, W) or (H, W, C) array, little-endian, rows packed."""
    a = np.ascontiguousarray(array)
    h, w = a.shape[:2]
    return build(
        ts,
        "sensor_msgs/msg/Image",
        header=header(ts, t_ns, frame_id),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=a.strides[0],
        data=a.reshape(-1).view(np.uint8),
    )


def compressed_image_msg(ts, t_ns: int, frame_id: str, encoded: Encoded):
    """``sensor_msgs/CompressedImage`` of an encoded image (:mod:`eval.ros.compression`)."""
    return build(
        ts,
        "sensor_msgs/msg/CompressedImage",
        header=header(ts, t_ns, frame_id),
        format=encoded.format,
        data=np.frombuffer(encoded.data, np.uint8),
    )


def is_compressed(msg) -> bool:
    """Whether an image message is a ``sensor_msgs/CompressedImage`` (it has ``format``, no ``encoding``)."""
    return hasattr(msg, "format") and not hasattr(msg, "encoding")


def _decoded(fn, msg, topic: str) -> np.ndarray:
    try:
        return fn(np.asarray(msg.data, np.uint8).tobytes(), str(msg.format), topic)
    except CodecError as e:
        raise MessageError(str(e)) from None


def _pixels(msg, dtype, channels: int, topic: str) -> np.ndarray:
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    item = np.dtype(dtype).itemsize * channels
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * item or data.size < step * h:
        raise MessageError(
            f"{topic}: image of {w}x{h} {msg.encoding} holds {data.size} bytes, step {step}; expected at least "
            f"{w * item * h}"
        )
    rows = data[: step * h].reshape(h, step)[:, : w * item]
    out = np.ascontiguousarray(rows).view(np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<"))
    out = out.reshape(h, w, channels) if channels > 1 else out.reshape(h, w)
    return out.astype(dtype, copy=False)


def colour_of(msg, topic: str) -> np.ndarray:
    """RGB uint8 (H, W, 3) of a colour ``sensor_msgs/Image`` or ``CompressedImage``."""
    if is_compressed(msg):
        return _decoded(decode_colour, msg, topic)
    enc = msg.encoding
    if enc not in COLOUR_ENCODINGS:
        raise MessageError(
            f"{topic}: unknown colour encoding {enc!r}; expected one of {', '.join(COLOUR_ENCODINGS)}"
        )
    px = _pixels(msg, np.uint8, COLOUR_ENCODINGS[enc], topic)
    if enc.startswith("bgr"):
        px = px[..., 2::-1]
    return np.ascontiguousarray(px[..., :3])


def depth_of(msg, topic: str, depth_unit_m: float = 0.001) -> np.ndarray:
    """Depth in metres, float32 (H, W), 0 invalid, of a ``16UC1``/``mono16`` (units of
    ``depth_unit_m``, millimetres by default) or ``32FC1`` (metres; NaN read as 0) image, or of a
    ``CompressedImage`` of those 16-bit units."""
    if is_compressed(msg):
        return from_z16(_decoded(decode_depth, msg, topic), depth_unit_m)
    enc = msg.encoding
    if enc in ("16UC1", "mono16"):
        return from_z16(_pixels(msg, np.uint16, 1, topic), depth_unit_m)
    if enc == "32FC1":
        z = _pixels(msg, np.float32, 1, topic).copy()
        z[~np.isfinite(z)] = 0.0
        return z
    raise MessageError(f"{topic}: unknown depth encoding {enc!r}; expected one of {', '.join(DEPTH_ENCODINGS)}")


def thermal_of(msg, topic: str) -> np.ndarray:
    """Degrees Celsius, float32 (h, w), of a ``32FC1`` thermal image."""
    if msg.encoding != "32FC1":
        raise MessageError(f"{topic}: unknown thermal encoding {msg.encoding!r}; expected 32FC1 (degrees Celsius)")
    return _pixels(msg, np.float32, 1, topic).copy()


# --- camera info ---------------------------------------------------------------------------------


def _ci(msg, name: str) -> np.ndarray:
    return np.asarray(getattr(msg, name) if hasattr(msg, name) else getattr(msg, name.upper()), dtype=float)


def camera_info_msg(ts, t_ns: int, frame_id: str, k: Intrinsics):
    """``sensor_msgs/CameraInfo`` of intrinsics ``k`` (``plumb_bob`` with its five coefficients)."""
    K = k.matrix()
    P = np.hstack([K, np.zeros((3, 1))])
    up = has_field(ts, "sensor_msgs/msg/CameraInfo", "K")
    arrays = {
        "D": np.asarray(k.coeffs, dtype=np.float64),
        "K": K.reshape(-1),
        "R": np.eye(3).reshape(-1),
        "P": P.reshape(-1),
    }
    return build(
        ts,
        "sensor_msgs/msg/CameraInfo",
        header=header(ts, t_ns, frame_id),
        height=k.height,
        width=k.width,
        distortion_model="plumb_bob",
        **{(n if up else n.lower()): v for n, v in arrays.items()},
    )


def intrinsics_of(msg, topic: str) -> Intrinsics:
    """Intrinsics of a ``sensor_msgs/CameraInfo`` (K; D as Brown-Conrady ``plumb_bob``)."""
    K = _ci(msg, "k").reshape(3, 3)
    D = _ci(msg, "d")
    if not (K[0, 0] > 0 and K[1, 1] > 0) or msg.width <= 0 or msg.height <= 0:
        raise MessageError(
            f"{topic}: camera info without intrinsics (K {K.reshape(-1).tolist()}, {msg.width}x{msg.height})"
        )
    coeffs = tuple(float(v) for v in (list(D[:5]) + [0.0] * 5)[:5])
    model = "brown_conrady" if any(coeffs) else "none"
    return Intrinsics(
        width=int(msg.width),
        height=int(msg.height),
        fx=float(K[0, 0]),
        fy=float(K[1, 1]),
        ppx=float(K[0, 2]),
        ppy=float(K[1, 2]),
        model=model,
        coeffs=coeffs,
    )


# --- transforms ----------------------------------------------------------------------------------


def transform_msg(ts, T: np.ndarray):
    """``geometry_msgs/Transform`` of a 4x4 matrix."""
    w, x, y, z = matrix_to_quat_wxyz(T[:3, :3])
    return build(
        ts,
        "geometry_msgs/msg/Transform",
        translation=build(ts, "geometry_msgs/msg/Vector3", x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
        rotation=build(ts, "geometry_msgs/msg/Quaternion", x=float(x), y=float(y), z=float(z), w=float(w)),
    )


def pose_msg(ts, T: np.ndarray):
    """``geometry_msgs/Pose`` of a 4x4 matrix."""
    tf = transform_msg(ts, T)
    p = tf.translation
    return build(
        ts,
        "geometry_msgs/msg/Pose",
        position=build(ts, "geometry_msgs/msg/Point", x=p.x, y=p.y, z=p.z),
        orientation=tf.rotation,
    )


def twist_msg(ts, angular: np.ndarray | None):
    """``geometry_msgs/TwistWithCovariance`` of an angular velocity (rad/s; the odometry's child
    frame's axes, as nav_msgs/Odometry gives its twist); no linear velocity; zero without one."""
    w = np.zeros(3) if angular is None else np.asarray(angular, float)
    return build(
        ts,
        "geometry_msgs/msg/TwistWithCovariance",
        twist=build(
            ts,
            "geometry_msgs/msg/Twist",
            angular=build(ts, "geometry_msgs/msg/Vector3", x=float(w[0]), y=float(w[1]), z=float(w[2])),
        ),
    )


def matrix_of(translation, rotation) -> np.ndarray:
    """4x4 matrix of a translation (x, y, z) and a quaternion message (x, y, z, w fields)."""
    q = (rotation.w, rotation.x, rotation.y, rotation.z)
    if not np.isfinite(q).all() or np.linalg.norm(q) < 1e-9:
        raise MessageError(f"a rotation that is not a quaternion: (w, x, y, z) = {q}")
    return make_transform(quat_wxyz_to_matrix(q), [translation.x, translation.y, translation.z])
