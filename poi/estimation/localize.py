"""From a detection box to a map position with its covariance ([Avevor2022]_ 2.2-2.3, [Bouda2025]_ 2.1.3).

A box's depth and plane: :mod:`poi.estimation.box_depth`; where a box is cut:
:mod:`poi.estimation.box_cuts`; pixels and points: :mod:`poi.estimation.projection` (the
pixel conventions are stated there).

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
from dataclasses import dataclass

import numpy as np

from poi.config import PipelineConfig
from poi.core.depth_units import DEPTH_UNIT_M
from poi.core.sensor_noise import depth_sigma_m
from poi.core.types import Detection, Frame, Intrinsics, Observation
from poi.estimation.box_cuts import border_sides, box_at_border, hidden_lengths_px, hidden_solid_px, occluded_sides
from poi.estimation.box_depth import (
    LocalizeError,
    box_depth,
    box_depth_plane,
    median_variance_fraction,
    plane_slope_sigma,
)
from poi.estimation.covariance import (
    Calibration,
    camera_covariance,
    center_sigmas_px,
    deprojection_jacobian,
    depth_jacobian,
    map_covariance,
    mount_covariance,
)
from poi.estimation.projection import (
    BOX_CORNER_TO_CENTER_PX,
    deproject_pixel_to_point,
    project_point_to_pixel,
    surface_to_center,
)

# flat_item: a ray within this cosine of the depth plane (87 degrees off its normal) sees
# it edge-on, and the plane says nothing of the item's size
EDGE_ON_COS = 0.05
# in-plane turns of a square sampled over its quarter turn (flat_item with turned=True), and
# the Newton steps that fit each one's centre to its box
TURN_SAMPLES = 9
TURN_NEWTON_STEPS = 3
# planar_face_center: an upright face's unit normal has at most this component along the
# camera's vertical (the sine of 30 degrees: the camera's own pitch and a ramp's, with margin)
PLANAR_MAX_NORMAL_UP = 0.5


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

    The plane passes through the box centre's point p(u, v, d) with the depth gradient
    ``grad`` (:func:`box_depth_plane`); the rays of the box's sides meet it in lines. A wall
    sign (the plane turned about the image's vertical) lies between the lines of the box's
    two vertical sides: its width is their distance, its centre line halfway. Perspective makes
    its near edge larger in the image, and off the camera's height also higher or lower, so the
    box centre is not the image of the sign's centre (1-2 cm off at 0.5-1 m and 45 degrees).
    Heights along the sides, X . e (e the sides' direction on the plane), are 0 at the
    camera's height: a rectangle's top edge reaches the box's top row at its near side when it
    lies above the camera (seen nearer, it reaches higher), else at its far side, and its bottom
    edge alike; the centre is halfway between the two on the centre line. A diamond (a hazmat
    placard) touches its box's top and bottom rows at its own centre column. A floor sign: the
    same with rows and columns swapped. Corner convention: column x1 is pixel coordinate
    x1 - 0.5.

    A diamond hung at an unknown in-plane turn (``turned``: a placard hung at any angle) is a
    square whose corners may touch the box's ends anywhere: seen at an angle and off the
    camera's height, the diamond rule's centre was 5-12 px off (a placard 1 m away, 70 degrees
    off face-on, turned 15-45 degrees), against a centre sigma of 6-7 px. For each of
    ``TURN_SAMPLES`` turns over a quarter turn, the square whose across extent is the box
    sides' distance on the plane has its centre height fitted (Newton) so that its corners'
    images span the box's ends about their middle; the centre is the mean over the turns, and
    ``turn_sigma_px`` their spread imaged at the centre (the turn taken as uniform).

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
    C = [at(sa, e0), at(sa, e1), at(sb, e0), at(sb, e1)]
    if any(c is None for c in C):
        return None
    a0, a1, b0, b1 = C
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
        # X @ e is a point's height along the sides, 0 at the camera's: a rectangle's edge at
        # end e0 meets the box there at its near side when it lies before the camera's height
        # (seen from nearer, it reaches further out), else at its far side; end e1 alike
        near_a = float(np.linalg.norm(a0 + a1)) <= float(np.linalg.norm(b0 + b1))
        (n0, n1), (f0, f1) = ((a0, a1), (b0, b1)) if near_a else ((b0, b1), (a0, a1))
        lo = float(n0 @ e) if float(n0 @ e) <= 0.0 else float(f0 @ e)
        hi = float(n1 @ e) if float(n1 @ e) >= 0.0 else float(f1 @ e)
    along = max(hi - lo, 0.0)
    height = 0.5 * (lo + hi)  # the centre's, along e
    turn_sigma_px = (0.0, 0.0)
    if diamond and turned:
        g = gap / across if across > 0.0 else gap
        heights = _turned_square_heights(intr, mid, e, g, 0.5 * across, (e0, e1), height, wall)
        height = float(heights.mean())
        spread = float(heights.std())
        span = [
            project_point_to_pixel(intr, mid + (height + k * spread - float(mid @ e)) * e) for k in (-1.0, 1.0)
        ]
        d_px = 0.5 * np.abs(span[1] - span[0])
        turn_sigma_px = (float(d_px[0]), float(d_px[1]))
    center = mid + (height - float(mid @ e)) * e
    w_m, h_m = (across, along) if wall else (along, across)
    return FlatItem(width_m=w_m, height_m=h_m, center=center, normal=n, turn_sigma_px=turn_sigma_px)


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


@dataclass(kw_only=True)
class FlatMeasure:
    """A flat item measured from its box (:func:`measure_flat_item`): its centre on the depth
    plane (camera frame; None where the plane's tilt is not known well enough), the pixels its
    box leaves out across u and v, the move of the box centre (px) that puts it at the
    centre of the whole item where the image border cut it (0 elsewhere), and the centre's
    spread over an unknown in-plane turn (px along u and v: :func:`flat_item`)."""

    centre: np.ndarray | None
    hidden_w: float
    hidden_h: float
    shift_u: float = 0.0
    shift_v: float = 0.0
    turn_sigma_px: tuple[float, float] = (0.0, 0.0)


def least_tilted_gradient(
    grad: tuple[float, float], var_g: tuple[float, float], n_sigmas: float
) -> tuple[float, float]:
    """The depth gradient (m / px) of the most face-on plane a measured one allows: each
    axis's slope moved toward 0 by ``n_sigmas`` of its standard errors, not past 0. A plane
    seen face-on makes an item look widest, so a box judged on this plane is called cut only
    when no tilt within ``n_sigmas`` explains its shortfall.

    >>> [round(g, 6) for g in least_tilted_gradient((0.01, -0.001), (1e-6, 1e-6), 2.0)]
    [0.008, -0.0]
    """
    out = []
    for g, var in zip(grad, var_g, strict=True):
        shrink = n_sigmas * math.sqrt(max(var, 0.0))
        out.append(math.copysign(max(abs(g) - shrink, 0.0), g))
    return out[0], out[1]


def measure_flat_item(
    detection: Detection,
    intr: Intrinsics,
    u: float,
    v: float,
    d: float,
    grad: tuple[float, float],
    var_g: tuple[float, float],
    lc,
    depth_m: np.ndarray | None = None,
    *,
    at_border: tuple[bool, bool],
    cause: tuple[bool, bool] = (True, True),
    toward: tuple[int, int] = (0, 0),
) -> FlatMeasure:
    """A flat item of ``lc.aspect`` measured from its box (:class:`FlatMeasure`): its centre
    measured on the depth plane (:func:`flat_item`) when the plane's tilt is known to
    ``lc.flat_max_slope_sigma`` (of its tangent: the slope's standard error times f / d), else
    None, and the pixels its box leaves out across u and v (:func:`hidden_lengths_px`).

    The image border hides the part beyond it: where a box is cut on an axis by the border on
    side ``toward`` (-1 left / top, +1 right / bottom, 0 none: :func:`border_sides`), the
    plane's tilt is known and ``lc.flat_border_shift`` is on, the box is taken to go on past
    that border by the hidden length, and the centre is the extended box's (shift_u / shift_v,
    the move of the box centre in pixels). With the tilt not known the hidden length is a bound
    only, and the centre stays. Left at the visible part's centre and widened by half the
    hidden length both ways, placards cut at the top or bottom of the image came out 2.6 cm
    short of the border side on average (35 views, vertical NEES 2.0, docs/CONSISTENCY.md).

    The shape is judged on the plane when its tilt is known; a plane tilted by its error theta
    lengthens a side by 1 / cos(theta) - 1, about theta^2 / 2, so the tolerance then grows by
    slope_sigma^2 (two sigmas' worth). Else (a far or narrow box's few noisy pixels do not fix
    the tilt) it is judged on the most face-on plane the depth allows
    (:func:`least_tilted_gradient`, ``lc.flat_tilt_sigmas``), fitted to the whole box in
    ``depth_m`` (a wider base than the inner box; the wall around a placard is in its plane),
    or to the inner box when that fit fails: the widest the item can look, so the hidden length
    is an upper bound at that many sigmas. Judging such a box face-on, as this did before,
    took a sign seen at 75 degrees (15 x 65 px) for one cut to a quarter: its sigma_u grew by
    25 px and R's widest axis to 0.2-0.4 m against errors of 2-3 cm (README, "Covariance
    consistency"). A box touching the image border on an axis (``at_border``, u and v:
    :func:`box_at_border`) counts as cut there whenever it is short of the shape at all (no
    tolerance on that axis). An axis without a ``cause`` (``localize.flat_cut_needs_cause``:
    neither the image border nor a nearer surface borders the box there, :func:`localize`)
    is not cut, whatever the shape: a sign on a wall is hidden only by something. Judged by
    shape alone, 40% of the signs' views with more than 90% of the sign in sight were called
    cut (box jitter, a tilt that noise leaves open), and their R's widest axis came out 1.5-3
    times too wide beyond 3 m (docs/CONSISTENCY.md).
    """
    t = detection.type
    diamond = t in lc.diamond_types
    slope_sigma = plane_slope_sigma(var_g, intr, d)
    fitted = slope_sigma <= lc.flat_max_slope_sigma
    # the turn model only where the centre is kept (a tilt not known gives no centre)
    turned = fitted and t in lc.turned_types
    item = flat_item(intr, u, v, d, grad, detection.box_xyxy, diamond, turned)
    if fitted:
        shape = item
    else:
        wide = None
        if depth_m is not None:
            sigma_px = depth_sigma_m(
                d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m
            )
            wide = box_depth_plane(
                depth_m, detection.box_xyxy, 1.0, lc.depth_window_px, sigma_px, split_m=lc.depth_split_m
            )
        if wide is not None:
            grad, var_g = (wide.g_u, wide.g_v), (wide.var_g_u, wide.var_g_v)
        least = least_tilted_gradient(grad, var_g, lc.flat_tilt_sigmas)
        shape = flat_item(intr, u, v, d, least, detection.box_xyxy, diamond)
    w, h = detection.size_wh
    hid_w = hid_h = 0.0
    if shape is not None:
        size_m = (shape.width_m, shape.height_m)
        tol = lc.truncation_tolerance + (slope_sigma**2 if fitted else 0.0)
        hid_w, hid_h = hidden_lengths_px((w, h), size_m, lc.aspect[t], tol)
        at_u, at_v = at_border
        if at_u or at_v:
            bw, bh = hidden_lengths_px((w, h), size_m, lc.aspect[t], 0.0)
            hid_w = max(hid_w, bw) if at_u else hid_w
            hid_h = max(hid_h, bh) if at_v else hid_h
        hid_w, hid_h = (hid_w if cause[0] else 0.0), (hid_h if cause[1] else 0.0)
    # the hidden part's side is known at the border, and its length where the tilt is (else the
    # face-on bound above is an upper bound only)
    shift = lc.flat_border_shift and fitted
    shift_u = 0.5 * hid_w * toward[0] if shift else 0.0
    shift_v = 0.5 * hid_h * toward[1] if shift else 0.0
    if shift_u or shift_v:
        # the whole item's box: the cut one gone on past the border by the hidden length
        x1, y1, x2, y2 = (float(c) for c in detection.box_xyxy)
        whole = (
            x1 + min(2.0 * shift_u, 0.0),
            y1 + min(2.0 * shift_v, 0.0),
            x2 + max(2.0 * shift_u, 0.0),
            y2 + max(2.0 * shift_v, 0.0),
        )
        item = flat_item(intr, u, v, d, grad, whole, diamond, turned)
    centre = item.center if item is not None and fitted else None
    turn = item.turn_sigma_px if centre is not None else (0.0, 0.0)
    return FlatMeasure(
        centre=centre, hidden_w=hid_w, hidden_h=hid_h, shift_u=shift_u, shift_v=shift_v, turn_sigma_px=turn
    )


def planar_face_center(
    depth_m: np.ndarray, box_xyxy, intr: Intrinsics, u: float, v: float, lc, sigma_px: float
) -> FlatItem | None:
    """The flat face (a door's leaf) a box frames, measured as a flat item (:func:`flat_item`)
    on the face's plane, fitted in inverse depth (:func:`box_depth_plane`); None where that
    plane cannot be fitted, its tilt is not known to ``lc.flat_max_slope_sigma`` or it is seen
    edge-on. Seen at an angle, the face's near half fills more of the box, and the ray through
    the box's centre meets the face nearer than its middle: doors 1.2 m away and 70-80
    degrees off face-on came out 10-15 cm near. ``surface_to_center_m`` then lies behind the
    face across it (``FlatItem.normal``), not along the ray, which for a face seen edge-on runs
    along the face (docs/CONSISTENCY.md "A door seen at an angle: centred on its leaf").

    A door's face is upright: a plane whose normal leans more than ``PLANAR_MAX_NORMAL_UP``
    (the sine of 30 degrees) toward the camera's vertical is the floor, a ceiling or a box that
    frames no door (a false detection), and gives None. Without that check a box on the floor
    was measured as a sign lying there, and its point moved 2.5 cm along the floor's normal,
    into the floor (docs/CONSISTENCY.md "A door seen at an angle: centred on its leaf").
    """
    plane = box_depth_plane(
        depth_m, box_xyxy, lc.inner_fraction, lc.depth_window_px, sigma_px, split_m=lc.depth_split_m, inverse=True
    )
    if plane is None:
        return None
    s = lc.depth_scale
    d = plane.depth_at(u, v) * s
    if plane_slope_sigma((s**2 * plane.var_g_u, s**2 * plane.var_g_v), intr, d) > lc.flat_max_slope_sigma:
        return None
    face = flat_item(intr, u, v, d, (s * plane.g_u, s * plane.g_v), box_xyxy)
    if face is None or abs(float(face.normal[1])) > PLANAR_MAX_NORMAL_UP:
        return None
    return face


def registration_depth_variance(grad: tuple[float, float], var_g: tuple[float, float], sigma_px: float) -> float:
    """Variance of a box's depth from the depth image's registration error against the colour
    image: the depth is read (du, dv) pixels off the colour box, each N(0, s^2 / 2) with s =
    ``sigma_px`` (``localize.registration_sigma_px``, the offset's RMS length), so it is off by
    g_u du + g_v dv for the box's depth slopes ``grad`` (J1's last row), with variance (g_u^2 +
    var_g_u + g_v^2 + var_g_v) s^2 / 2 (a slope known to var_g, as for the centre's error in
    :func:`localize`).

    A D435 maps depth into the colour image through its factory extrinsics; an error of about
    0.1 degree there moves every pixel about 1 px (docs/FACTS.md "D435 depth"). The offset is
    the same all run long, so a sloping box's depth is off the same way in every view: it is
    a shared error (docs/CONSISTENCY.md "The depth registration").

    >>> registration_depth_variance((0.004, 0.0), (0.0, 0.0), 1.0)
    8e-06
    """
    s2 = 0.5 * sigma_px**2
    return float(s2 * (grad[0] ** 2 + var_g[0] + grad[1] ** 2 + var_g[1]))


def extent_covariance(p_c: np.ndarray, sigma_lat_m: float, sigma_ray_m: float) -> np.ndarray:
    """Sigma_ext = sigma_ray^2 r r^T + sigma_lat^2 (I - r r^T), r = p_c / |p_c|: an object's
    reference point spreads about the observation by ``sigma_ray_m`` along the camera ray (how
    deep behind the surface seen it lies depends on the side seen) and ``sigma_lat_m`` across it.

    >>> np.diag(extent_covariance(np.array([0.0, 0.0, 2.0]), 0.1, 0.3)).round(6).tolist()
    [0.01, 0.01, 0.09]
    """
    r = p_c / float(np.linalg.norm(p_c))
    rr = np.outer(r, r)
    return sigma_ray_m**2 * rr + sigma_lat_m**2 * (np.eye(3) - rr)


def localize(
    detection: Detection,
    frame: Frame,
    cfg: PipelineConfig,
    T_tracker_camera: np.ndarray,
    calibration: Calibration | None = None,
) -> Observation | None:
    """Place a detection in the map frame with its covariance R ([Avevor2022]_ 2.2-2.3).

    p_map = Q (Q0 p_c + t0) + t with (Q, t) = ``frame.pose`` (T_map_tracker) and (Q0, t0)
    = ``T_tracker_camera``; R = Q Q0 (Sigma_c + Sigma_ext) Q0^T Q^T + sigma_eps^2 I + R_mount,
    where

    * Sigma_c = J2 J1 Sigma_1 J1^T J2^T is the detection and depth model: J1 holds the depth
      gradient of the box (``localize.depth_gradient``: by default the plane through its
      inner depths, :func:`box_depth_plane`), J2 the Jacobian of the deprojection and, for
      a type with ``surface_to_center_m``, of its centre offset (:func:`surface_to_center`);
      Sigma_1's centre variances grow by (hidden / 2)^2 on an axis along which a flat item of
      known ``localize.aspect`` is cut (:func:`hidden_lengths_px`), or along which the box of
      a 3-D item of known ``localize.box_width_m`` / ``box_height_m`` is cut by the image
      border or a nearer surface (:func:`hidden_solid_px`, :func:`occluded_sides`); for a
      3-D type not in ``localize.hidden_on_plane`` that growth skips J1 (the hidden part's
      depth does not follow the visible part's slope). A flat item cut by the image border on
      one side (``localize.flat_border_shift``) is instead centred on the whole item, its box
      gone on past that border by the hidden length (:func:`measure_flat_item`), and its
      centre variance there grows by the square of half that length's error: the full length
      times the shape's relative error, hypot(2 sigma_u / w, 2 sigma_v / h) (a box side's
      length errs by both its edges' errors, each sqrt(2) times the centre's sigma), and half
      the rest of that length's error, ``localize.hidden_length_sigma`` of it. A diamond hung at
      an unknown in-plane turn (``localize.turned_types``) is centred as the mean over the
      turns of a square, and its centre variances grow by that centre's spread over them
      (:func:`flat_item`). A type in ``localize.planar_center`` (a door) is centred on the
      middle of its face (:func:`planar_face_center`);
    * Sigma_ext (:func:`extent_covariance`, ``Observation.Sigma_extent_c``) is the spread of
      a 3-D object's reference point about the observation, ``extent_ray_sigma_m`` along the
      camera ray and ``extent_sigma_m`` across it;
    * sigma_eps is ``slam.sigma_eps_m`` in slam mode, ``tracker.sigma_eps_m`` in t265 mode,
      and R_mount the mount calibration's error
      (:func:`poi.estimation.covariance.mount_covariance`).

    Sigma_c also holds Sigma_reg, the depth image's registration error against the colour image
    (:func:`registration_depth_variance`). Sigma_reg, Sigma_eps, R_mount and Sigma_ext repeat
    from frame to frame: they are the observation's shared part (``Observation.R_shared``,
    :mod:`poi.estimation.tracker`).

    The depth is the median of the box's inner block (:func:`box_depth`; its variance the share
    of one pixel's that the pixels deciding it leave, ``localize.median_depth_variance``:
    :func:`median_variance_fraction`), or for a flat item
    (``localize.flat_depth``: plane) its depth plane's at the box centre
    (:meth:`DepthPlane.depth_at`): on a sloping sign the median is the depth where the block's
    valid pixels centre, off the box centre's where holes lie to one side.

    None when the frame has no pose or no depth, too little valid depth lies in the box
    (``localize.min_depth_fill``, :func:`box_depth`) or it holds two surfaces
    (``localize.max_depth_split``), the depth is out of range, or
    (``localize.flat_reject_corner``) the box of a flat item touches the image border on both
    axes (within ``localize.border_px`` plus ``localize.flat_border_sigmas`` of its centre
    sigmas: a cut box's edge jitters inward with it).
    """
    if frame.pose is None or frame.depth_m is None:
        return None
    intr = frame.intrinsics
    depth = frame.depth_m
    if depth.shape != (intr.height, intr.width):
        raise LocalizeError(
            f"frame {frame.index}: depth image {depth.shape[1]}x{depth.shape[0]} does not match "
            f"the colour intrinsics {intr.width}x{intr.height} (depth must be aligned to colour)"
        )
    lc = cfg.localize
    d_med = box_depth(
        depth,
        detection.box_xyxy,
        lc.inner_fraction,
        lc.min_depth_fill,
        split_m=lc.depth_split_m,
        max_split=lc.max_depth_split,
    )
    if d_med is None:
        return None
    cx, cy = detection.center_uv
    u, v = cx - BOX_CORNER_TO_CENTER_PX, cy - BOX_CORNER_TO_CENTER_PX
    w, h = detection.size_wh
    t = detection.type

    # J1: the depth gradient of the box, from its depth plane or central differences
    var_g = (0.0, 0.0)
    plane = None
    # a flat item read on its plane takes the plane's own depth variance (flat_depth_variance)
    mean_variance = lc.flat_depth == "plane" and lc.flat_depth_variance == "plane" and t in lc.aspect
    if lc.depth_gradient == "plane":
        J1 = np.eye(3)
        sigma_px = depth_sigma_m(
            d_med, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m
        )
        plane = box_depth_plane(
            depth,
            detection.box_xyxy,
            lc.inner_fraction,
            lc.depth_window_px,
            sigma_px,
            mean_variance,
            split_m=lc.depth_split_m,
        )
        if plane is not None:
            J1[2, :2] = lc.depth_scale * plane.g_u, lc.depth_scale * plane.g_v
            var_g = (lc.depth_scale**2 * plane.var_g_u, lc.depth_scale**2 * plane.var_g_v)
    else:
        J1 = depth_jacobian(depth, u, v, lc.depth_scale)
    # a flat item's depth at its box centre: its plane's there (the median of a sloping
    # surface is the depth where its valid pixels centre, off the box centre where holes lie)
    on_plane = lc.flat_depth == "plane" and t in lc.aspect and plane is not None
    d = (plane.depth_at(u, v) if on_plane else d_med) * lc.depth_scale
    if not lc.min_depth_m <= d <= lc.max_depth_m:
        return None
    to_center = lc.surface_to_center_m.get(t, 0.0)

    def point(a: float, b: float, c: float) -> np.ndarray:
        # a 3-D object: the depth is its front surface, the report names its centre
        return surface_to_center(deproject_pixel_to_point(intr, a, b, c), to_center)

    p_c = point(u, v, d)
    # Sigma_1 = diag(sigma_u^2, sigma_v^2, sigma_d^2)
    sigma_u, sigma_v = center_sigmas_px(
        detection.class_name,
        w,
        h,
        a_px=lc.center_sigma_px.a_px,
        b=lc.center_sigma_px.b,
        calibration=calibration,
    )
    hid_w = hid_h = 0.0  # pixels of the item its box leaves out, across u and v
    # a flat item's or a body's box edge may sit a few of its sigmas inside the image and still
    # be cut there (an extinguisher cut at its foot at 0.7-1 m, its box's bottom 11-17 px up);
    # a door's or a doll's may not: its hidden length moves its depth along its plane, and a
    # whole door called cut got a needle-thin R
    sized = t in lc.box_width_m or t in lc.box_height_m  # a 3-D type of known full-view size
    n_sigmas = 0.0
    if t in lc.aspect:
        n_sigmas = lc.flat_border_sigmas
    elif sized and t not in lc.hidden_on_plane:
        n_sigmas = lc.body_border_sigmas
    margin = (lc.border_px + n_sigmas * sigma_u, lc.border_px + n_sigmas * sigma_v)
    at = box_at_border(detection.box_xyxy, intr.width, intr.height, margin)
    if t in lc.aspect and lc.flat_reject_corner and all(at):
        # a flat item cut by two borders: its shape cannot say how much of it is hidden
        return None
    occluded = (False, False)  # a nearer surface borders the box across u, across v
    flat_cause = t in lc.aspect and lc.flat_cut_needs_cause
    if lc.occluder_margin_m > 0.0 and (flat_cause or sized):
        surface = d_med if plane is None else plane
        occluded = occluded_sides(depth, detection.box_xyxy, surface, lc.occluder_margin_m / lc.depth_scale)
    shifted = (False, False)  # the centre moved toward the border that cut it, across u, v
    turn_px = (0.0, 0.0)  # a square's centre spread over its unknown in-plane turn, across u, v
    if t in lc.aspect:
        cause = (at[0] or occluded[0], at[1] or occluded[1]) if flat_cause else (True, True)
        toward = border_sides(detection.box_xyxy, intr.width, intr.height, margin)
        flat = measure_flat_item(
            detection,
            intr,
            u,
            v,
            d,
            (J1[2, 0], J1[2, 1]),
            var_g,
            lc,
            depth,
            at_border=at,
            cause=cause,
            toward=toward,
        )
        hid_w, hid_h = flat.hidden_w, flat.hidden_h
        shifted = (flat.shift_u != 0.0, flat.shift_v != 0.0)
        if any(shifted):
            # the whole item's box centre, and its depth on the plane there
            u, v = u + flat.shift_u, v + flat.shift_v
            if on_plane:
                d = plane.depth_at(u, v) * lc.depth_scale
            p_c = point(u, v, d)
        if flat.centre is not None and lc.flat_center:
            p_c = flat.centre
            turn_px = flat.turn_sigma_px
    elif sized:
        if t in lc.planar_center and plane is not None:
            face = planar_face_center(depth, detection.box_xyxy, intr, u, v, lc, sigma_px)
            p_c = p_c if face is None else face.center + to_center * face.normal
        # a 3-D item cut by the image border or by a nearer surface: its hidden length from its
        # known size
        size_m = (lc.box_width_m.get(t, 0.0), lc.box_height_m.get(t, 0.0))
        at = (at[0] or occluded[0], at[1] or occluded[1])
        hid_w, hid_h = hidden_solid_px((w, h), size_m, float(p_c[2]), (intr.fx, intr.fy), at)
    # a cut box: its centre is off the item's by up to half the hidden length. Where the hidden
    # part goes on along the box's depth plane (a flat sign, a door's leaf, a lying doll:
    # localize.hidden_on_plane) its depth follows the centre through J1; a body whose visible
    # part's slope says nothing of the hidden part's (an extinguisher cut at its foot) keeps
    # its visible part's depth (hidden_var, through J2 only)
    hidden_var = (0.0, 0.0)
    if any(shifted):
        # moved to the whole item's centre: off by half the hidden length's error, the full
        # length times the shape's relative error. A side's length errs by both its edges'
        # errors, the centre by their mean: with the edges independent, a side's sigma is
        # twice the centre's; and by the rest of the hidden length's own error
        # (localize.hidden_length_sigma of it: the plane's tilt, a slanted sign's perspective)
        shape_sigma = math.hypot(2.0 * sigma_u / w, 2.0 * sigma_v / h)
        k = 0.5 * lc.hidden_length_sigma
        if shifted[0]:
            sigma_u = math.hypot(sigma_u, 0.5 * (w + hid_w) * shape_sigma, k * hid_w)
        if shifted[1]:
            sigma_v = math.hypot(sigma_v, 0.5 * (h + hid_h) * shape_sigma, k * hid_h)
        hid_w, hid_h = (0.0 if shifted[0] else hid_w), (0.0 if shifted[1] else hid_h)
    sigma_u, sigma_v = math.hypot(sigma_u, turn_px[0]), math.hypot(sigma_v, turn_px[1])
    if t in lc.aspect or t in lc.hidden_on_plane:
        sigma_u = math.hypot(sigma_u, 0.5 * hid_w)
        sigma_v = math.hypot(sigma_v, 0.5 * hid_h)
    else:
        hidden_var = ((0.5 * hid_w) ** 2, (0.5 * hid_h) ** 2)
    if on_plane and mean_variance:
        # the plane's depth at the box centre averages the noise of the block's windows
        # plus the Z16 unit's rounding, which a block facing the camera shares (1 mm^2 / 12)
        var_depth = lc.depth_scale**2 * (plane.depth_variance_at(u, v) + DEPTH_UNIT_M**2 / 12.0)
    else:
        sigma_d = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
        var_depth = sigma_d**2
        if not on_plane and lc.median_depth_variance == "window":
            # the median of the inner block averages its windows' noise, but keeps the Z16
            # unit's rounding (1 mm^2 / 12)
            sigma_raw = sigma_d / lc.depth_scale  # in the depth image's units, as its pixels
            fraction = median_variance_fraction(
                depth, detection.box_xyxy, lc.inner_fraction, lc.depth_window_px, sigma_raw, d_med
            )
            var_depth = fraction * var_depth + (lc.depth_scale * DEPTH_UNIT_M) ** 2 / 12.0
    # the slope's own error times the centre's: var(g du) = g^2 var(du) (in J1) + var(g) var(du)
    var_d = var_depth + var_g[0] * sigma_u**2 + var_g[1] * sigma_v**2
    Sigma_1 = np.diag([sigma_u**2, sigma_v**2, var_d])
    J2 = deprojection_jacobian(point, u, v, d)  # with the centre offset, for a 3-D object
    Sigma_c = camera_covariance(J1, J2, Sigma_1)
    if hidden_var != (0.0, 0.0):
        Sigma_c = Sigma_c + camera_covariance(np.eye(3), J2, np.diag([*hidden_var, 0.0]))
    # the depth image's registration error: its depth is read (du, dv) off the colour box,
    # the same offset all run long (a shared error), so the box's depth is off by g . (du, dv)
    var_reg = registration_depth_variance((J1[2, 0], J1[2, 1]), var_g, lc.registration_sigma_px)
    Sigma_reg = camera_covariance(np.eye(3), J2, np.diag([0.0, 0.0, var_reg]))
    Sigma_c = Sigma_c + Sigma_reg
    sigma_lat = lc.extent_sigma_m.get(t, 0.0)
    sigma_ray = lc.extent_ray_sigma_m.get(t, sigma_lat)
    Sigma_ext = extent_covariance(p_c, sigma_lat, sigma_ray)

    pose = np.asarray(frame.pose, dtype=float)
    Q, t_map = pose[:3, :3], pose[:3, 3]
    Q0, t0 = T_tracker_camera[:3, :3], T_tracker_camera[:3, 3]
    # p_map = Q (Q0 p_c + t0) + t
    p_map = Q @ (Q0 @ p_c + t0) + t_map
    # Sigma_eps: the pose error as delivered (t265 mode), or what the planar SLAM, which adds
    # its own pose covariance later, leaves (height, roll, pitch: slam mode)
    sigma_eps = cfg.slam.sigma_eps_m if lc.mode == "slam" else cfg.tracker.sigma_eps_m
    # the mount calibration's error (a range-dependent part of what Sigma_eps lumps together)
    R_mount = mount_covariance(Q @ Q0 @ p_c, np.deg2rad(lc.mount_sigma_deg), lc.mount_sigma_m)
    # Sigma_eps, the mount and the extent recur from frame to frame: the shared part the
    # tracker does not average away; the detection and depth noise does not
    R_shared = map_covariance(Sigma_ext, Q, Q0, sigma_eps) + R_mount
    R = map_covariance(Sigma_c, Q, Q0, 0.0) + R_shared
    R_shared = R_shared + map_covariance(Sigma_reg, Q, Q0, 0.0)  # in Sigma_c, and shared
    return Observation(
        detection=detection,
        timestamp_s=frame.timestamp_s,
        position_map=p_map,
        R=R,
        position_cam=p_c,
        Sigma_c=Sigma_c,
        depth_m=d,
        R_shared=R_shared,
        Sigma_extent_c=Sigma_ext,
        box_cut=(bool(at[0]), bool(at[1])),
    )
