"""A flat item on a depth plane: its size, centre and normal from the rays of its box's sides
([Avevor2022]_ 2.2.1: the deprojection; here applied to the box's sides, not its centre alone).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from poi.core.types import Intrinsics
from poi.estimation.projection import BOX_CORNER_TO_CENTER_PX, deproject_pixel_to_point, project_point_to_pixel

# flat_item: a ray within this cosine of the depth plane (87 degrees off its normal) sees
# it edge-on, and the plane says nothing of the item's size
EDGE_ON_COS = 0.05
# in-plane turns of a square sampled over its quarter turn (flat_item with turned=True), and
# the Newton steps that fit each one's centre to its box
TURN_SAMPLES = 9
TURN_NEWTON_STEPS = 3


@dataclass(kw_only=True)
class FlatItem:
    """A flat item framed by a box, measured on its depth plane (:func:`flat_item`): its
    width and height (m), the camera-frame point of its centre, and its plane's unit normal,
    pointing away from the camera."""

    width_m: float
    height_m: float
    center: np.ndarray
    normal: np.ndarray
    # the centre's spread over an unknown in-plane turn (px, along u and v; 0 unless turned)
    turn_sigma_px: tuple[float, float] = (0.0, 0.0)


def flat_item(
    intr: Intrinsics,
    u: float,
    v: float,
    d: float,
    grad: tuple[float, float],
    box_xyxy,
    diamond: bool = False,
    turned: bool = False,
) -> FlatItem | None:
    """The size and centre of the flat item (a sign) a box frames, on the depth plane; None
    when the plane is seen edge-on.

    The plane passes through the box centre's point p(u, v, d) with the depth gradient ``grad``
    (:func:`box_depth_plane`); the rays of the box's sides meet it in lines. A wall sign (the
    plane turned about the image's vertical) lies between the lines of the box's two vertical
    sides: its width is their distance, its centre line halfway. Perspective makes its near edge
    larger in the image, and off the camera's height also higher or lower, so the box centre is
    not the image of the sign's centre. Heights along the sides, X . e (e the sides' direction
    on the plane), are 0 at the camera's height: a rectangle's top edge reaches the box's top
    row at its near side when it lies above the camera (seen nearer, it reaches higher), else at
    its far side, and its bottom edge alike; the centre is halfway between the two on the centre
    line. A diamond (a hazmat placard) touches its box's top and bottom rows at its own centre
    column. A floor sign: the same with rows and columns swapped. Corner convention: column x1
    is pixel coordinate x1 - 0.5.

    A diamond hung at an unknown in-plane turn (``turned``: a placard hung at any angle) is a
    square whose corners may touch the box's ends anywhere (docs/CONSISTENCY.md "A placard hung
    at any angle"). For each of ``TURN_SAMPLES`` turns over a quarter turn, the square whose
    across extent is the box sides' distance on the plane has its centre height fitted (Newton)
    so that its corners' images span the box's ends about their middle; the centre is the mean
    over the turns, and ``turn_sigma_px`` their spread imaged at the centre (the turn uniform).

    >>> k = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=320.0, ppy=240.0)
    >>> f = flat_item(k, 319.5, 239.5, 2.0, (0.0, 0.0), (270, 215, 370, 265))
    >>> round(f.width_m, 6), round(f.height_m, 6), f.center.round(6).tolist()
    (0.4, 0.2, [-0.002, -0.002, 2.0])
    """
    x1, y1, x2, y2 = (float(c) - BOX_CORNER_TO_CENTER_PX for c in box_xyxy)
    gu, gv = grad
    P0 = deproject_pixel_to_point(intr, u, v, d)
    n = np.cross(
        deproject_pixel_to_point(intr, u + 1.0, v, d + gu) - P0,
        deproject_pixel_to_point(intr, u, v + 1.0, d + gv) - P0,
    )
    if not np.any(n):
        return None
    n = n / np.linalg.norm(n)
    n = -n if float(n @ P0) < 0.0 else n  # away from the camera

    def on_plane(a: float, b: float) -> np.ndarray | None:
        r = deproject_pixel_to_point(intr, a, b, 1.0)
        nr = float(n @ r)
        if abs(nr) < EDGE_ON_COS * float(np.linalg.norm(r)):
            return None
        t = float(n @ P0) / nr
        return t * r if t > 0.0 else None

    wall = abs(n[0]) >= abs(n[1])

    def at(side: float, end: float) -> np.ndarray | None:
        # the plane point on box side ``side`` (a column for a wall, a row for a floor) at ``end``
        return on_plane(side, end) if wall else on_plane(end, side)

    (sa, sb), (e0, e1) = ((x1, x2), (y1, y2)) if wall else ((y1, y2), (x1, x2))
    a0, a1, b0, b1 = at(sa, e0), at(sa, e1), at(sb, e0), at(sb, e1)
    if a0 is None or a1 is None or b0 is None or b1 is None:
        return None
    la, lb = float(np.linalg.norm(a1 - a0)), float(np.linalg.norm(b1 - b0))
    if la <= 0.0 or lb <= 0.0:
        return None
    e = (a1 - a0) / la + (b1 - b0) / lb  # along the sides, from end e0 to end e1
    e = e / float(np.linalg.norm(e))
    gap = b0 - a0
    gap = gap - (gap @ e) * e  # from side a's line to side b's, across
    across = float(np.linalg.norm(gap))
    mid = 0.5 * (a0 + a1) + 0.5 * gap  # on the item's centre line
    if diamond:
        # the corners touching ends e0 and e1 lie on the centre line
        uv = project_point_to_pixel(intr, mid)
        c = float(uv[0] if wall else uv[1])
        T, B = at(c, e0), at(c, e1)
        if T is None or B is None:
            return None
        lo, hi = float(T @ e), float(B @ e)
    else:
        lo, hi = _rectangle_ends(a0, a1, b0, b1, e)
    along = max(hi - lo, 0.0)
    height = 0.5 * (lo + hi)  # the centre's, along e
    turn_sigma_px = (0.0, 0.0)
    if diamond and turned:
        g = gap / across if across > 0.0 else gap
        height, turn_sigma_px = _turned_centre(intr, mid, e, g, 0.5 * across, (e0, e1), height, wall)
    center = mid + (height - float(mid @ e)) * e
    w_m, h_m = (across, along) if wall else (along, across)
    return FlatItem(width_m=w_m, height_m=h_m, center=center, normal=n, turn_sigma_px=turn_sigma_px)


def _rectangle_ends(
    a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray, e: np.ndarray
) -> tuple[float, float]:
    """A rectangle's ends' heights along ``e`` (X . e, 0 at the camera's height) between the
    plane points a0, a1 (side a at ends e0, e1) and b0, b1 (side b): its edge at end e0 meets
    the box there at its near side when it lies before the camera's height (seen from nearer,
    it reaches further out), else at its far side; end e1 alike."""
    near_a = float(np.linalg.norm(a0 + a1)) <= float(np.linalg.norm(b0 + b1))
    (n0, n1), (f0, f1) = ((a0, a1), (b0, b1)) if near_a else ((b0, b1), (a0, a1))
    lo = float(n0 @ e) if float(n0 @ e) <= 0.0 else float(f0 @ e)
    hi = float(n1 @ e) if float(n1 @ e) >= 0.0 else float(f1 @ e)
    return lo, hi


def _turned_centre(
    intr: Intrinsics,
    mid: np.ndarray,
    e: np.ndarray,
    g: np.ndarray,
    half_across: float,
    ends: tuple[float, float],
    start: float,
    wall: bool,
) -> tuple[float, tuple[float, float]]:
    """A turned square's centre height along ``e``, the mean over its turns
    (:func:`_turned_square_heights`), and that mean's spread over them imaged at the centre (px,
    along u and v: half the image of +-1 standard deviation of the heights)."""
    heights = _turned_square_heights(intr, mid, e, g, half_across, ends, start, wall)
    height = float(heights.mean())
    spread = float(heights.std())
    span = [project_point_to_pixel(intr, mid + (height + k * spread - float(mid @ e)) * e) for k in (-1.0, 1.0)]
    d_px = 0.5 * np.abs(span[1] - span[0])
    return height, (float(d_px[0]), float(d_px[1]))


def _turned_square_heights(
    intr: Intrinsics,
    mid: np.ndarray,
    e: np.ndarray,
    g: np.ndarray,
    half_across: float,
    ends: tuple[float, float],
    start: float,
    wall: bool,
) -> np.ndarray:
    """The centre heights (along ``e``) of squares turned by each of ``TURN_SAMPLES`` angles
    over a quarter turn whose images fit a box (:func:`flat_item`).

    The squares lie on the plane with their centre on the centre line (through ``mid``, along
    the unit ``e``), ``g`` the unit direction across it. A square turned by theta has corners
    at angles phi = theta + k pi / 2 about its centre, r (cos phi g + sin phi e) away, and its
    across extent r max(|cos theta|, |sin theta|) is ``half_across`` (the box sides' lines).
    Each centre height h solves F(h) = (min + max) / 2 - (e0 + e1) / 2 = 0 over the corners'
    image coordinates along the box's ends (rows for a wall sign, columns for a floor one),
    by Newton's method from ``start`` with a 1 mm difference quotient.
    """
    theta = (np.arange(TURN_SAMPLES) + 0.5) * (0.5 * np.pi / TURN_SAMPLES)
    r = half_across / np.maximum(np.abs(np.cos(theta)), np.abs(np.sin(theta)))
    phi = theta[:, None] + 0.5 * np.pi * np.arange(4)[None, :]  # (turns, corners)
    across = r[:, None] * np.cos(phi)
    rise = r[:, None] * np.sin(phi)
    base = mid - float(mid @ e) * e  # the centre line's point at height 0
    axis = 1 if wall else 0
    target = 0.5 * (ends[0] + ends[1])

    def middle(h: np.ndarray) -> np.ndarray:
        pts = base + across[..., None] * g + (h[:, None] + rise)[..., None] * e  # (turns, 4, 3)
        coord = project_point_to_pixel(intr, pts.reshape(-1, 3).T)[axis].reshape(pts.shape[:2])
        return 0.5 * (coord.min(axis=1) + coord.max(axis=1)) - target

    h = np.full(TURN_SAMPLES, float(start))
    step = 1e-3
    for _ in range(TURN_NEWTON_STEPS):
        f = middle(h)
        slope = (middle(h + step) - f) / step
        h = h - np.divide(f, slope, out=np.zeros_like(f), where=np.abs(slope) > 0.0)
    return h
