"""Small rigid-transform helpers, and the IoU of image boxes. Quaternions only at the edges, in
(w, x, y, z) order.

>>> T = make_transform(rot_z(np.pi / 2), [1.0, 0.0, 0.0])
>>> np.round(transform_points(T, np.array([[1.0, 0.0, 0.0]])), 6).tolist()
[[1.0, 1.0, 0.0]]
>>> np.allclose(quat_wxyz_to_matrix(matrix_to_quat_wxyz(rot_z(0.3))), rot_z(0.3))
True
"""

from __future__ import annotations

import numpy as np


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap_angle(a):
    """Angle(s) wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def planar_pose(T: np.ndarray) -> np.ndarray:
    """(x, y, yaw) of a 4x4 pose: its position on the floor and the heading of its x axis."""
    return np.array([T[0, 3], T[1, 3], np.arctan2(T[1, 0], T[0, 0])], dtype=float)


def make_transform(R: np.ndarray, t) -> np.ndarray:
    """4x4 homogeneous matrix from rotation R (3x3) and translation t (3,)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=float)
    return T


def invert_transform(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform: (R, t) -> (R^T, -R^T t)."""
    R, t = T[:3, :3], T[:3, 3]
    return make_transform(R.T, -R.T @ t)


def transform_points(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Apply T to points p of shape (N, 3) (or (3,))."""
    p = np.asarray(p, dtype=float)
    return p @ T[:3, :3].T + T[:3, 3]


def quat_wxyz_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion given as (w, x, y, z)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat_wxyz(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w >= 0, of a rotation matrix (Shepperd's method)."""
    m = np.asarray(R, dtype=float)
    tr = np.trace(m)
    if tr > 0:
        s = 2.0 * np.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


# Camera optical frame (x right, y down, z forward) expressed in a body frame with
# x forward, y left, z up: optical z = body x, optical x = -body y, optical y = -body z.
R_BODY_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(len(a), len(b)) intersection over union of xyxy boxes.

    >>> iou_matrix(np.array([[0, 0, 2, 2]]), np.array([[1, 0, 3, 2], [5, 5, 6, 6]])).round(4).tolist()
    [[0.3333, 0.0]]
    """
    a = np.asarray(a, float).reshape(-1, 4)
    b = np.asarray(b, float).reshape(-1, 4)
    ix = np.clip(np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0]), 0, None)
    iy = np.clip(np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1]), 0, None)
    inter = ix * iy
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.where(union > 0, inter / np.where(union > 0, union, 1.0), 0.0)


def greedy_pairs(overlap: np.ndarray, min_overlap: float) -> list[tuple[int, int]]:
    """One-to-one (row, column) pairs of ``overlap`` (n, m) at ``min_overlap`` or more, taken
    greedily, largest overlap first, ties by row then column; sorted by row.

    >>> greedy_pairs(np.array([[0.9, 0.6], [0.95, 0.1]]), 0.5)
    [(0, 1), (1, 0)]
    """
    overlap = np.asarray(overlap, dtype=float)
    if overlap.size == 0:
        return []
    cand = np.argwhere(overlap >= min_overlap)  # row-major: ties stay by row, then column
    order = np.argsort(-overlap[cand[:, 0], cand[:, 1]], kind="stable")
    used_r: set[int] = set()
    used_c: set[int] = set()
    pairs = []
    for r, c in cand[order]:
        if int(r) in used_r or int(c) in used_c:
            continue
        used_r.add(int(r))
        used_c.add(int(c))
        pairs.append((int(r), int(c)))
    return sorted(pairs)
