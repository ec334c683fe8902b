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

from collections.abc import Callable

import numpy as np

from poi.config import PipelineConfig
from poi.core.types import Detection, Frame, Observation
from poi.estimation.box_depth import BoxDepth, LocalizeError, read_box_depth
from poi.estimation.covariance import (
    Calibration,
    camera_covariance,
    center_sigmas_px,
    deprojection_jacobian,
    map_covariance,
    mount_covariance,
)
from poi.estimation.shapes import Measured, shape_of


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


def camera_covariances(
    m: Measured, depth: BoxDepth, point: Callable[[float, float, float], np.ndarray], registration_sigma_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """(Sigma_c, Sigma_reg): the camera-frame covariance of a measured centre ([Avevor2022]_
    2.2.2-2.2.3) and the depth registration's part of it.

    Sigma_c = J2 J1 Sigma_1 J1^T J2^T + J2 diag(h_u, h_v, 0) J2^T + Sigma_reg, with
    Sigma_1 = diag(sigma_u^2, sigma_v^2, sigma_d^2 + var(g_u) sigma_u^2 + var(g_v) sigma_v^2)
    (a slope known to var(g) adds var(g) var(du) to g du's variance, whose g^2 var(du) J1 carries),
    J1 the box's depth gradient (:class:`poi.estimation.box_depth.BoxDepth`), J2 the Jacobian of
    ``point`` (deprojection and centre offset) at (u, v, d), h the hidden-length variances that
    skip J1 (``Measured.hidden_var``), and Sigma_reg = J2 diag(0, 0, var_reg) J2^T
    (:func:`registration_depth_variance`).
    """
    var_d = m.var_depth + depth.var_g[0] * m.sigma_u**2 + depth.var_g[1] * m.sigma_v**2
    Sigma_1 = np.diag([m.sigma_u**2, m.sigma_v**2, var_d])
    J2 = deprojection_jacobian(point, m.u, m.v, m.d)
    Sigma_c = camera_covariance(depth.J1, J2, Sigma_1)
    if m.hidden_var != (0.0, 0.0):
        Sigma_c = Sigma_c + camera_covariance(np.eye(3), J2, np.diag([*m.hidden_var, 0.0]))
    var_reg = registration_depth_variance(depth.grad, depth.var_g, registration_sigma_px)
    Sigma_reg = camera_covariance(np.eye(3), J2, np.diag([0.0, 0.0, var_reg]))
    return Sigma_c + Sigma_reg, Sigma_reg


def place_in_map(
    detection: Detection,
    frame: Frame,
    cfg: PipelineConfig,
    T_tracker_camera: np.ndarray,
    m: Measured,
    Sigma_c: np.ndarray,
    Sigma_reg: np.ndarray,
    Sigma_ext: np.ndarray,
) -> Observation:
    """The observation in the map frame ([Avevor2022]_ 2.3): p_map = Q (Q0 p_c + t0) + t and
    R = Q Q0 (Sigma_c + Sigma_ext) Q0^T Q^T + sigma_eps^2 I + R_mount, of which Sigma_ext, Sigma_eps,
    R_mount and Sigma_reg recur from frame to frame (``Observation.R_shared``)."""
    lc = cfg.localize
    pose = np.asarray(frame.pose, dtype=float)
    Q, t_map = pose[:3, :3], pose[:3, 3]
    Q0, t0 = T_tracker_camera[:3, :3], T_tracker_camera[:3, 3]
    # p_map = Q (Q0 p_c + t0) + t
    p_map = Q @ (Q0 @ m.p_c + t0) + t_map
    # Sigma_eps: the pose error as delivered (t265 mode), or what the planar SLAM, which adds
    # its own pose covariance later, leaves (height, roll, pitch: slam mode)
    sigma_eps = cfg.slam.sigma_eps_m if lc.mode == "slam" else cfg.tracker.sigma_eps_m
    # the mount calibration's error (a range-dependent part of what Sigma_eps lumps together)
    R_mount = mount_covariance(Q @ Q0 @ m.p_c, np.deg2rad(lc.mount_sigma_deg), lc.mount_sigma_m)
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
        position_cam=m.p_c,
        Sigma_c=Sigma_c,
        depth_m=m.d,
        R_shared=R_shared,
        Sigma_extent_c=Sigma_ext,
        box_cut=m.box_cut,
    )


def localize(
    detection: Detection,
    frame: Frame,
    cfg: PipelineConfig,
    T_tracker_camera: np.ndarray,
    calibration: Calibration | None = None,
) -> Observation | None:
    """Place a detection in the map frame with its covariance R ([Avevor2022]_ 2.2-2.3).

    The box's depth: its inner block's median and plane (:func:`poi.estimation.box_depth.
    read_box_depth`, [Bouda2025]_ 2.1.3); its type's shape (``localize.types``,
    :mod:`poi.estimation.shapes`) measures the centre p_c, its depth and Sigma_1's terms from
    them, the box centre's sigmas ([Avevor2022]_ 2.1.4, :func:`poi.estimation.covariance.
    center_sigmas_px`) and where the box is cut; Sigma_c from J1 and J2
    (:func:`camera_covariances`); Sigma_ext the reference point's spread
    (:func:`extent_covariance`); then p_map and R, and R's shared part (:func:`place_in_map`).

    None when the frame has no pose or no depth, the box has too little valid depth or two
    surfaces (:func:`poi.estimation.box_depth.box_depth`), or its shape gives no observation (a
    depth outside [``localize.min_depth_m``, ``localize.max_depth_m``], a flat item's box at the
    image border on both axes).
    """
    if frame.pose is None or frame.depth_m is None:
        return None
    intr, lc = frame.intrinsics, cfg.localize
    if frame.depth_m.shape != (intr.height, intr.width):
        raise LocalizeError(
            f"frame {frame.index}: depth image {frame.depth_m.shape[1]}x{frame.depth_m.shape[0]} does not match "
            f"the colour intrinsics {intr.width}x{intr.height} (depth must be aligned to colour)"
        )
    shape = shape_of(detection.type, lc)
    depth = read_box_depth(frame.depth_m, detection.box_xyxy, lc, shape.plane_depth)
    if depth is None:
        return None
    w, h = detection.size_wh
    cs = lc.center_sigma_px
    sigmas = center_sigmas_px(detection.class_name, w, h, a_px=cs.a_px, b=cs.b, calibration=calibration)
    m = shape.measure(detection, intr, frame.depth_m, depth, lc, sigmas)
    if m is None:
        return None
    Sigma_c, Sigma_reg = camera_covariances(m, depth, shape.point(intr), lc.registration_sigma_px)
    Sigma_ext = extent_covariance(m.p_c, *shape.extent_sigmas())
    return place_in_map(detection, frame, cfg, T_tracker_camera, m, Sigma_c, Sigma_reg, Sigma_ext)
