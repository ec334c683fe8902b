"""Images as ``sensor_msgs/CompressedImage``, the way ROS's image_transport plugins publish them
[ImageTransportPlugins]_: colour on ``<topic>/compressed`` (the ``compressed`` plugin: a PNG or
JPEG file, format ``"rgb8; png compressed bgr8"``), depth on ``<topic>/compressedDepth`` (the
``compressedDepth`` plugin: a 12-byte configuration header, then a 16-bit PNG of the ``16UC1``
millimetres; format ``"16UC1; compressedDepth png"``). PNG is lossless, so a decoded image is
the array encoded, pixel for pixel; JPEG is not.

As the plugin's own codec (``compressed_depth_image_transport/src/codec.cpp``) does, the
compression (``png``, or ``rvl``, which is not read here) is told by the format string; the
header's fields (format ``INV_DEPTH``, two quantisation parameters) matter only to the inverse
depth coding of ``32FC1`` images, which poibench neither writes nor reads.

Encoding and decoding are OpenCV's ``imencode`` and ``imdecode``, as the plugins' own.

References
----------
Full entries in docs/SOURCES.md.

.. [ImageTransportPlugins] ROS, "image_transport_plugins": compressed_image_transport and
   compressed_depth_image_transport (format strings, the compressedDepth ConfigHeader).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import cv2
import numpy as np

COLOUR_CODECS = ("png", "jpeg")
COMPRESSED_SUFFIX = "/compressed"  # image_transport's compressed plugin
DEPTH_SUFFIX = "/compressedDepth"  # image_transport's compressedDepth plugin
# compressedDepth's ConfigHeader: int32 format (the plugin writes INV_DEPTH, 0, for every image)
# and float32 depthParam[2] (the inverse depth quantisation of 32FC1 images; 0 for 16UC1)
DEPTH_HEADER = struct.Struct("<iff")
INV_DEPTH = 0
# How the PNGs are made, chosen on 60 frames of the default trial (python bench/bench_log.py;
# CPU ms a frame, 2 cores at load 10): zlib's Huffman coding alone after one fixed row filter.
# Sensor noise leaves deflate's string matching little to find: level 1 (zlib's default strategy,
# OpenCV's adaptive filters) gave colour 589 kB in 21.4 ms and depth 181 kB in 10.1 ms, level 6
# 573 kB in 40.9 ms and 155 kB in 47.5 ms; Huffman-only with the Average filter (colour) 523 kB
# in 7.9 ms, with Paeth (depth) 164 kB in 6.6 ms.
PNG_LEVEL = 1
JPEG_QUALITY = 90


def _png_params(row_filter: str) -> list[int]:
    """imencode's PNG parameters: level 1, Huffman coding only and ``row_filter`` (``AVG``,
    ``PAETH``) where this OpenCV offers the choice (``IMWRITE_PNG_FILTER``; an older one filters
    adaptively)."""
    params = [
        cv2.IMWRITE_PNG_COMPRESSION,
        PNG_LEVEL,
        cv2.IMWRITE_PNG_STRATEGY,
        cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY,
    ]
    if hasattr(cv2, "IMWRITE_PNG_FILTER"):
        params += [cv2.IMWRITE_PNG_FILTER, getattr(cv2, f"IMWRITE_PNG_FILTER_{row_filter}")]
    return params


COLOUR_PNG = _png_params("AVG")
DEPTH_PNG = _png_params("PAETH")


class CodecError(ValueError):
    """A compressed image poibench cannot decode (one line naming the topic)."""


@dataclass(frozen=True, kw_only=True)
class Encoded:
    """One image's ``CompressedImage`` payload: the bytes and the format string."""

    data: bytes
    format: str


def encode_colour(rgb: np.ndarray, codec: str) -> Encoded:
    """An RGB uint8 (H, W, 3) image as a PNG or JPEG file (image_transport's ``compressed``).

    >>> e = encode_colour(np.zeros((2, 3, 3), np.uint8), "png")
    >>> e.format, e.data[:4]
    ('rgb8; png compressed bgr8', b'\\x89PNG')
    """
    if codec not in COLOUR_CODECS:
        raise CodecError(f"colour codec {codec!r}: expected one of {', '.join(COLOUR_CODECS)}")
    bgr = np.ascontiguousarray(rgb[..., ::-1])  # (H, W, 3): OpenCV writes from BGR
    if codec == "png":
        ok, buf = cv2.imencode(".png", bgr, COLOUR_PNG)
    else:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise CodecError(f"OpenCV could not encode a {rgb.shape} image as {codec}")
    return Encoded(data=buf.tobytes(), format=f"rgb8; {codec} compressed bgr8")


def encode_depth(z16: np.ndarray) -> Encoded:
    """A ``16UC1`` (H, W) uint16 image as compressedDepth's header and a 16-bit PNG (lossless).

    >>> z = np.array([[0, 1], [65535, 1234]], np.uint16)
    >>> e = encode_depth(z)
    >>> e.format, bool((decode_depth(e.data, e.format, "/d") == z).all())
    ('16UC1; compressedDepth png', True)
    """
    if z16.dtype != np.uint16 or z16.ndim != 2:
        raise CodecError(f"depth to compress: expected a (H, W) uint16 image, got {z16.dtype} {z16.shape}")
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(z16), DEPTH_PNG)
    if not ok:
        raise CodecError(f"OpenCV could not encode a {z16.shape} depth image as PNG")
    head = DEPTH_HEADER.pack(INV_DEPTH, 0.0, 0.0)
    return Encoded(data=head + buf.tobytes(), format="16UC1; compressedDepth png")


def _decode(data: bytes, topic: str, what: str) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise CodecError(f"{topic}: a {what} that OpenCV cannot decode ({len(data)} bytes)")
    return img


def decode_colour(data: bytes, fmt: str, topic: str) -> np.ndarray:
    """RGB uint8 (H, W, 3) of a colour ``CompressedImage`` (PNG or JPEG; grey read as grey RGB)."""
    if "compressedDepth" in fmt:
        raise CodecError(f"{topic}: a compressedDepth image ({fmt!r}) where colour was expected")
    img = _decode(bytes(data), topic, f"compressed colour image ({fmt!r})")
    if img.dtype != np.uint8:
        raise CodecError(f"{topic}: a {img.dtype} compressed image ({fmt!r}); expected 8-bit colour")
    if img.ndim == 2:
        return np.repeat(img[..., None], 3, axis=2)
    if img.shape[2] == 4:
        img = img[..., :3]  # BGRA -> BGR
    return np.ascontiguousarray(img[..., ::-1])  # (H, W, 3): imdecode gives BGR


def decode_depth(data: bytes, fmt: str, topic: str) -> np.ndarray:
    """The ``16UC1`` (H, W) uint16 of a depth ``CompressedImage``: compressedDepth (``"16UC1;
    compressedDepth png"``, or ``"16UC1; compressedDepth"`` of older plugins: its 12-byte header, then
    a PNG) or a 16-bit PNG as the ``compressed`` plugin writes it."""
    raw = bytes(data)
    if "compressedDepth" in fmt:
        encoding, _, compression = (p.strip() for p in fmt.partition(";"))
        if encoding not in ("16UC1", "mono16"):
            raise CodecError(f"{topic}: compressedDepth of {encoding!r} ({fmt!r}); only 16UC1 depth is read")
        if compression not in ("compressedDepth", "compressedDepth png"):
            raise CodecError(f"{topic}: compressedDepth {fmt!r}; only its PNG compression is read, not RVL")
        if len(raw) <= DEPTH_HEADER.size:
            raise CodecError(f"{topic}: a compressedDepth image of {len(raw)} bytes, no more than its header")
        raw = raw[DEPTH_HEADER.size :]
    img = _decode(raw, topic, f"compressed depth image ({fmt!r})")
    if img.dtype != np.uint16 or img.ndim != 2:
        raise CodecError(f"{topic}: compressed depth of {img.dtype} {img.shape}; expected one 16-bit channel")
    return img
