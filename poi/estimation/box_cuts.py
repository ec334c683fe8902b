"""Where a box is cut: by the image border, by a nearer surface beside it, and how many pixels of
the item it leaves out ([Avevor2022]_ 2.1.4: a box's centre error; here, its part beyond sight).

A flat item's box says by its own shape how much of it is hidden (:func:`hidden_lengths_px`); a
3-D item's by its known full-view size (:func:`hidden_solid_px`). The image border
(:func:`box_at_border`, :func:`border_sides`) and a nearer surface (:func:`occluded_sides`) say
which axis is cut.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

import math

import numpy as np

from poi.estimation.box_depth import DepthPlane

# where occluded_sides reads beside a box: from 2 px outside its edge (a box's edge jitters by a
# pixel or two) to 10 px (past an occluder's edge pixels, which the depth camera blurs)
OCCLUDER_STRIP_PX = (2, 10)


def hidden_lengths_px(
    size_wh: tuple[float, float], size_m: tuple[float, float], aspect: float, tolerance: float
) -> tuple[float, float]:
    """How many pixels of a flat item of width / height ``aspect`` a w x h box leaves out,
    (across u, across v); at most one is non-zero.

    ``size_m`` is the box's (width, height) measured on the item's plane
    (:func:`flat_item`). q = (W / H) / aspect is 1 for the whole item (a cut box is
    only ever shorter than the item); q < 1 - ``tolerance`` says its width was cut (by the
    image border or an occluder in front) and about w / q - w pixels are hidden;
    1 / q < 1 - ``tolerance`` says the same of its height. The box then holds the visible part,
    and its centre is off the item's by up to half the hidden length, on a side the box does
    not say (:func:`localize` widens sigma_u or sigma_v by that half).

    >>> hidden_lengths_px((50.0, 100.0), (0.1, 0.2), 1.0, 0.1)
    (50.0, 0.0)
    >>> hidden_lengths_px((95.0, 100.0), (0.19, 0.2), 1.0, 0.1)
    (0.0, 0.0)
    """
    w, h = size_wh
    W, H = size_m
    if w <= 0.0 or h <= 0.0 or W <= 0.0 or H <= 0.0 or aspect <= 0.0:
        return 0.0, 0.0
    q = W / H / aspect
    if q < 1.0 - tolerance:
        return w / q - w, 0.0
    if 1.0 / q < 1.0 - tolerance:
        return 0.0, h * q - h
    return 0.0, 0.0


def hidden_solid_px(
    size_wh: tuple[float, float],
    size_m: tuple[float, float],
    depth_m: float,
    focal_px: tuple[float, float],
    at_border: tuple[bool, bool],
) -> tuple[float, float]:
    """How many pixels of a 3-D item a box cut by the image border leaves out, (across u,
    across v): f S / z - w on an axis where the box touches the border (``at_border``, from
    :func:`box_at_border`), S the width or height the type's uncut box spans (``size_m``,
    a row's ``box_width_m`` / ``box_height_m`` in ``localize.types``; 0: not known), z the depth of its centre and
    f the focal length (a length S at depth z spans f S / z pixels);
    0 on an axis the box does not touch, or where it is no shorter than f S / z.

    A flat item's box says by its own shape how much of it is cut (:func:`hidden_lengths_px`);
    a 3-D item's shape changes with the side seen, so only the border says that it is cut, and
    its known size how much. The box holds the visible part, its centre off the item's by up
    to half the hidden length, toward the image's inside (:func:`localize`).

    >>> hidden_solid_px((90.0, 240.0), (0.16, 0.52), 1.0, (615.0, 615.0), (False, True))
    (0.0, 79.8)
    >>> hidden_solid_px((90.0, 240.0), (0.16, 0.52), 1.0, (615.0, 615.0), (True, False))
    (8.4, 0.0)
    """
    out = []
    for n_px, s_m, f_px, cut in zip(size_wh, size_m, focal_px, at_border, strict=True):
        full = f_px * s_m / depth_m if cut and s_m > 0.0 and depth_m > 0.0 else 0.0
        out.append(round(max(full - n_px, 0.0), 9))
    return out[0], out[1]


def box_at_border(box_xyxy, width: int, height: int, border_px: float | tuple[float, float]) -> tuple[bool, bool]:
    """Whether a box (corner convention) comes within ``border_px`` of the image's left or right
    edge, and of its top or bottom edge; ``border_px`` may be one margin or one per axis (u, v).

    >>> box_at_border((0.0, 100.0, 50.0, 200.0), 640, 480, 2.0), box_at_border((3, 3, 637, 477), 640, 480, 2.0)
    ((True, False), (False, False))
    >>> box_at_border((3, 3, 637, 477), 640, 480, (2.0, 4.0))
    (False, True)
    """
    (left, right), (top, bottom) = _border_contacts(box_xyxy, width, height, border_px)
    return left or right, top or bottom


def _border_contacts(
    box_xyxy, width: int, height: int, border_px: float | tuple[float, float]
) -> tuple[tuple[bool, bool], tuple[bool, bool]]:
    """Whether a box (corner convention) comes within ``border_px`` (one margin, or one per
    axis) of the image's (left, right) and (top, bottom) edges."""
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    bu, bv = border_px if isinstance(border_px, tuple) else (border_px, border_px)
    return (x1 <= bu, x2 >= width - bu), (y1 <= bv, y2 >= height - bv)


def border_sides(box_xyxy, width: int, height: int, border_px: float | tuple[float, float]) -> tuple[int, int]:
    """Which image border a box (corner convention) comes within ``border_px`` of, across u and
    v: -1 the left (top), +1 the right (bottom), 0 neither or both (a box that spans the image
    says no side), as :func:`box_at_border` tests.

    >>> border_sides((0.0, 100.0, 50.0, 478.0), 640, 480, 4.0), border_sides((1, 3, 639, 477), 640, 480, 2.0)
    ((-1, 1), (0, 0))
    """
    (left, right), (top, bottom) = _border_contacts(box_xyxy, width, height, border_px)
    return int(right) - int(left), int(bottom) - int(top)


def occluded_sides(
    depth_m: np.ndarray,
    box_xyxy,
    surface: float | DepthPlane,
    margin_m: float,
    strip_px: tuple[int, int] = OCCLUDER_STRIP_PX,
) -> tuple[bool, bool]:
    """Whether a nearer surface borders a box on its left or right side, and on its top: the
    box then holds the part of the item that the occluder leaves visible. Not on its bottom:
    below an item on the floor lies the floor before it, which is nearer by its slope (0.2 m
    10 px below a heater 2 m from a camera 0.3 m up) and occludes nothing.

    On each side a strip ``strip_px`` = (from, to) pixels outside the box edge, along the
    middle half of the edge, is read; the side is occluded when at least half of the strip's
    valid depths lie more than ``margin_m`` nearer than the item's ``surface`` carried on to
    them: its depth plane (:func:`box_depth_plane`), or one depth for the whole box. A door
    seen past a corridor's corner is; a door seen at 70 degrees is not, though its near edge
    and the wall beside it are 0.3 m nearer than its centre. A strip outside the image or
    without valid depth says nothing. The strip starts a few pixels out so that a box a few
    pixels too small still reads past the item's own edge.

    >>> d = np.full((100, 100), 3.0, np.float32); d[:, :40] = 1.0  # a wall 2 m nearer on the left
    >>> occluded_sides(d, (40, 30, 70, 70), 3.0, 0.15)
    (True, False)
    >>> occluded_sides(d, (60, 30, 90, 70), 3.0, 0.15), occluded_sides(d, (40, 30, 70, 70), 1.1, 0.15)
    ((False, False), (False, False))
    >>> d = 1.0 + 0.02 * np.arange(100.0)[None, :].repeat(100, 0)  # a wall seen at a slant
    >>> slant = DepthPlane(d0=2.1, u0=55.0, v0=50.0, g_u=0.02, g_v=0.0, var_g_u=0.0, var_g_v=0.0)
    >>> occluded_sides(d, (40, 30, 70, 70), slant, 0.15), occluded_sides(d, (40, 30, 70, 70), 2.1, 0.15)
    ((False, False), (True, False))
    """
    h, w = depth_m.shape
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    a, b = strip_px
    r0, r1 = max(int(y1 + 0.25 * (y2 - y1)), 0), min(int(math.ceil(y2 - 0.25 * (y2 - y1))), h)
    c0, c1 = max(int(x1 + 0.25 * (x2 - x1)), 0), min(int(math.ceil(x2 - 0.25 * (x2 - x1))), w)
    u_end = int(math.ceil(x2))
    strips = (  # (rows, columns) of each strip: left, right, top
        ((r0, r1), (max(int(x1) - b, 0), max(int(x1) - a, 0))),
        ((r0, r1), (min(u_end + a, w), min(u_end + b, w))),
        ((max(int(y1) - b, 0), max(int(y1) - a, 0)), (c0, c1)),
    )

    def nearer(rows: tuple[int, int], cols: tuple[int, int]) -> bool:
        if rows[1] <= rows[0] or cols[1] <= cols[0]:
            return False
        z = np.asarray(depth_m[rows[0] : rows[1], cols[0] : cols[1]], dtype=float)
        if isinstance(surface, DepthPlane):
            vv, uu = np.mgrid[rows[0] : rows[1], cols[0] : cols[1]]
            item = surface.depth_at(uu, vv)
        else:
            item = np.full(z.shape, float(surface))
        ok = np.isfinite(z) & (z > 0.0)
        return bool(ok.any() and np.count_nonzero(z[ok] < item[ok] - margin_m) >= 0.5 * np.count_nonzero(ok))

    left, right, top = (nearer(rows, cols) for rows, cols in strips)
    return left or right, top
