"""Z16 depth, as librealsense gives it: uint16 counts of a depth unit (1 mm by default).

A D400 camera sends depth as ``RS2_FORMAT_Z16``: one uint16 per pixel, 0 for no depth,
in units of the sensor's depth scale (``rs2::depth_sensor::get_depth_scale()``, 0.001 m
unless the advanced mode changes it) ([IntelProjection]_; docs/FACTS.md "D435 depth").
The simulator rounds its depth to the unit with :func:`to_z16` and hands the pipeline
metres (:func:`from_z16`), and every file or message boundary (``poibench render``'s PNGs,
ROS ``16UC1`` images) converts with the same two functions.

>>> to_z16(np.array([0.0, 1.2344, 1.2346, 70.0])).tolist()
[0, 1234, 1235, 65535]
>>> from_z16(np.array([0, 1234], np.uint16)).tolist() == [0.0, np.float32(1.234)]
True

References
----------
Full entries in docs/SOURCES.md.

.. [IntelProjection] Intel RealSense, "Projection in RealSense SDK 2.0".
"""

from __future__ import annotations

import numpy as np

DEPTH_UNIT_M = 0.001  # librealsense's default depth scale for D400 cameras
Z16_MAX = 65535


def to_z16(depth_m: np.ndarray, depth_unit_m: float = DEPTH_UNIT_M) -> np.ndarray:
    """uint16 counts of ``depth_unit_m`` (rounded to nearest; 0 stays 0; saturates at 65535 units)."""
    if not depth_unit_m > 0:
        raise ValueError(f"depth_unit_m must be positive, got {depth_unit_m}")
    z = np.asarray(depth_m)
    if z.dtype != np.float32:  # float32 holds every count to 2^24 exactly, and is quicker
        z = z.astype(np.float64)
    counts = z * z.dtype.type(1.0 / depth_unit_m)
    np.rint(counts, out=counts)
    np.clip(counts, 0, Z16_MAX, out=counts)
    return counts.astype(np.uint16)


def from_z16(counts: np.ndarray, depth_unit_m: float = DEPTH_UNIT_M) -> np.ndarray:
    """float32 metres of uint16 ``counts`` of ``depth_unit_m`` (0 stays 0, no depth)."""
    if not depth_unit_m > 0:
        raise ValueError(f"depth_unit_m must be positive, got {depth_unit_m}")
    # dividing by counts per metre (1000 for 1 mm, exact in float32) rounds correctly: the
    # nearest float32 to counts * unit, as float64 arithmetic would give, at float32 cost
    z = np.asarray(counts).astype(np.float32)
    z /= np.float32(1.0 / depth_unit_m)
    return z
