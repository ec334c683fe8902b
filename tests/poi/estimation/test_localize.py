"""poi.estimation.localize (box depth, (de)projection, localize) and poi.estimation.visibility (in_view)."""

from __future__ import annotations

import numpy as np
import pytest

from poi.config import ConfigError, apply_overrides, load_config
from poi.core.geometry import R_BODY_OPTICAL, make_transform, rot_z
from poi.core.types import Detection, Frame, Intrinsics
from poi.detectors.base import make_detection
from poi.estimation.localize import (
    LocalizeError,
    box_depth,
    deproject_pixel_to_point,
    localize,
    project_point_to_pixel,
)
from poi.estimation.visibility import in_view

K = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=319.5, ppy=239.5)
K_BC = Intrinsics(
    width=640,
    height=480,
    fx=612.4,
    fy=610.6,
    ppx=314.3,
    ppy=237.8,
    model="brown_conrady",
    coeffs=(0.1, -0.05, 0.001, -0.002, 0.01),
)


def det(box, class_name="door", conf=0.9, text=None) -> Detection:
    return make_detection(class_name, box, conf, source="test", class_probs=None, text=text)


def frame(depth=2.0, pose=None, index=0, t=0.0) -> Frame:
    d = None if depth is None else np.full((K.height, K.width), depth, np.float32)
    return Frame(
        index=index,
        timestamp_s=t,
        rgb=np.zeros((K.height, K.width, 3), np.uint8),
        intrinsics=K,
        depth_m=d,
        pose=np.eye(4) if pose is None else pose,
    )


def test_box_depth_uses_the_inner_fraction():
    d = np.full((10, 10), 5.0)  # background
    d[2:8, 2:8] = 2.0  # object: the inner 6x6
    # inner 50% of box (0, 0, 10, 10): pixel centres in [2.5, 7.5] -> columns/rows 2..7
    assert box_depth(d, (0, 0, 10, 10), 0.5) == 2.0
    # the whole box: 64 background pixels beat 36 object pixels
    assert box_depth(d, (0, 0, 10, 10), 1.0) == 5.0


def test_box_depth_ignores_invalid_and_returns_none_without_valid():
    d = np.zeros((10, 10))
    d[4:6, 4:6] = [[1.0, 2.0], [np.nan, 4.0]]
    assert box_depth(d, (0, 0, 10, 10), 0.5) == 2.0  # median of 1, 2, 4
    assert box_depth(np.zeros((10, 10)), (0, 0, 10, 10), 0.5) is None
    assert box_depth(np.full((10, 10), np.nan), (0, 0, 10, 10), 0.5) is None
    # a box smaller than one pixel still reads the pixel holding its centre
    assert box_depth(d, (5.2, 5.2, 5.4, 5.4), 0.5) == 4.0  # d[5, 5]
    assert box_depth(d, (5.2, 4.2, 5.4, 4.4), 0.5) == 2.0  # d[4, 5]
    # a box outside the image reads nothing
    assert box_depth(d, (20, 20, 30, 30), 0.5) is None
    with pytest.raises(LocalizeError, match="inner_fraction"):
        box_depth(d, (0, 0, 10, 10), 0.0)


@pytest.mark.parametrize(("u", "v", "d"), [(0.0, 0.0, 1.0), (639.0, 479.0, 3.5), (319.5, 239.5, 2.0)])
def test_deproject_model_none_is_the_pinhole_formula(u, v, d):
    p = deproject_pixel_to_point(K, u, v, d)
    assert p.tolist() == pytest.approx([(u - K.ppx) / K.fx * d, (v - K.ppy) / K.fy * d, d], abs=1e-15)
    assert project_point_to_pixel(K, p).tolist() == pytest.approx([u, v], abs=1e-9)


def test_brown_conrady_round_trip():
    # librealsense's ten fixed-point iterations invert the forward model to far below
    # a pixel for mild distortion (|x|, |y| < 0.5); 1e-4 px is float noise at this scale
    for u, v in [(314.3, 237.8), (100.0, 50.0), (600.0, 400.0), (20.0, 460.0)]:
        p = deproject_pixel_to_point(K_BC, u, v, 2.0)
        assert p[2] == 2.0
        assert project_point_to_pixel(K_BC, p).tolist() == pytest.approx([u, v], abs=1e-4)
    # distortion moves off-centre points: not the pinhole answer
    p = deproject_pixel_to_point(K_BC, 600.0, 400.0, 2.0)
    pin = [(600.0 - K_BC.ppx) / K_BC.fx * 2.0, (400.0 - K_BC.ppy) / K_BC.fy * 2.0]
    assert abs(p[0] - pin[0]) > 1e-3


def test_against_pyrealsense2_if_installed():
    rs = pytest.importorskip("pyrealsense2")
    for k, model in [(K, rs.distortion.none), (K_BC, rs.distortion.brown_conrady)]:
        ri = rs.intrinsics()
        ri.width, ri.height, ri.fx, ri.fy, ri.ppx, ri.ppy = (
            k.width,
            k.height,
            k.fx,
            k.fy,
            k.ppx,
            k.ppy,
        )
        ri.model, ri.coeffs = model, list(k.coeffs)
        for u, v in [(100.0, 50.0), (600.0, 400.0)]:
            ours = deproject_pixel_to_point(k, u, v, 2.0)
            theirs = rs.rs2_deproject_pixel_to_point(ri, [u, v], 2.0)
            assert ours.tolist() == pytest.approx(theirs, abs=1e-5)  # float32 in librealsense


def test_localize_places_the_box_centre_in_the_map():
    # R of the sensors alone: no extent, a mount known exactly
    sensors_only = ["localize.extent_sigma_m={}", "localize.mount_sigma_deg=0", "localize.mount_sigma_m=0"]
    cfg = apply_overrides(load_config(), sensors_only)
    # box centre cx = 370 (corner convention) is pixel u = 369.5 = ppx + 50, v = ppy
    d = det((360.0, 230.0, 380.0, 250.0))
    # camera optical frame in the tracker frame: the nominal mount, 45 mm up
    T_tc = make_transform(R_BODY_OPTICAL, [0.0, 0.0, 0.045])
    # tracker at (1, 2, 0) turned 90 degrees left
    pose = make_transform(rot_z(np.pi / 2), [1.0, 2.0, 0.0])
    obs = localize(d, frame(pose=pose), cfg, T_tc)
    # p_c = (50/500 * 2, 0, 2) = (0.2, 0, 2); Q0 p_c + t0 = (2, -0.2, 0.045)
    # Q (2, -0.2, 0.045) + t = (0.2, 2, 0.045) + (1, 2, 0) = (1.2, 4.0, 0.045)
    assert obs.position_cam.tolist() == pytest.approx([0.2, 0.0, 2.0], abs=1e-12)
    assert obs.position_map.tolist() == pytest.approx([1.2, 4.0, 0.045], abs=1e-12)
    assert obs.depth_m == 2.0
    # flat depth: J1 has no gradient, so z_c's variance is the depth noise alone
    sigma_z = 4.0 * 0.08 / (384.2 * 0.05)
    assert obs.Sigma_c[2, 2] == pytest.approx(sigma_z**2, rel=1e-9)
    # x_c variance: (d/fx)^2 sigma_u^2 + (u - ppx)^2/fx^2 sigma_d^2, sigma_u = 1 + 0.03 * 20 px
    expect_xx = (2 / 500) ** 2 * 1.6**2 + (50 / 500) ** 2 * sigma_z**2
    assert obs.Sigma_c[0, 0] == pytest.approx(expect_xx, rel=1e-6)
    # map covariance: optical z (depth) -> tracker x -> map y after the 90 degree turn
    # plus Sigma_eps: slam.sigma_eps_m in slam mode (the default), tracker.sigma_eps_m in t265 mode
    assert obs.R[1, 1] == pytest.approx(sigma_z**2 + 0.012**2, rel=1e-9)
    assert np.allclose(obs.R, obs.R.T)
    t265 = localize(d, frame(pose=pose), apply_overrides(cfg, ["localize.mode=t265"]), T_tc)
    assert t265.R[1, 1] == pytest.approx(sigma_z**2 + 0.05**2, rel=1e-9)
    # Sigma_eps repeats from frame to frame: it is the shared part
    assert obs.R_shared == pytest.approx(0.012**2 * np.eye(3), rel=1e-12)
    # a mount known to 1 degree and 1 cm: q = (0.2, 2, 0) from the camera to the point in the
    # map, R gains s_r^2 (|q|^2 I - q q^T) + s_t^2 I: 4 s_r^2 + s_t^2 across the line of sight
    # (x), 0.04 s_r^2 + s_t^2 along it (y), 4.04 s_r^2 + s_t^2 vertically; shared as well
    mount = apply_overrides(
        load_config(), [sensors_only[0], "localize.mount_sigma_deg=1", "localize.mount_sigma_m=0.01"]
    )
    obs_m = localize(d, frame(pose=pose), mount, T_tc)
    s_r2, s_t2 = np.deg2rad(1.0) ** 2, 1e-4
    added = np.diag([4.0 * s_r2, 0.04 * s_r2, 4.04 * s_r2]) + s_t2 * np.eye(3)
    added[0, 1] = added[1, 0] = -0.4 * s_r2
    np.testing.assert_allclose(obs_m.R - obs.R, added, rtol=0, atol=1e-12)
    np.testing.assert_allclose(obs_m.R_shared - obs.R_shared, added, rtol=0, atol=1e-12)


def test_a_round_object_is_placed_at_its_centre_behind_the_surface_seen():
    """The depth hits a ball's front; its report names its centre, one radius further along
    the ray: for a ball of radius 0.105 m seen 2 m off the axis by 0.2 m (p_c = (0.2, 0, 2)),
    p = p_c (1 + 0.105 / |p_c|)."""
    cfg = load_config()
    T_tc = make_transform(R_BODY_OPTICAL, [0.0, 0.0, 0.045])
    ball = localize(det((360.0, 230.0, 380.0, 250.0), class_name="ball"), frame(), cfg, T_tc)
    scale = 1.0 + 0.105 / np.hypot(0.2, 2.0)
    assert ball.position_cam.tolist() == pytest.approx([0.2 * scale, 0.0, 2.0 * scale], abs=1e-12)
    flat = localize(det((360.0, 230.0, 380.0, 250.0), class_name="exit-sign"), frame(), cfg, T_tc)
    assert flat.position_cam.tolist() == pytest.approx([0.2, 0.0, 2.0], abs=1e-12)  # flat: no offset
    # the offset is in J2: Sigma_c(ball) = G Sigma_c(flat) G^T, G = (1 + r/|p|) I - r p p^T / |p|^3
    p = np.array([0.2, 0.0, 2.0])
    n = np.linalg.norm(p)
    G = (1.0 + 0.105 / n) * np.eye(3) - 0.105 * np.outer(p, p) / n**3
    np.testing.assert_allclose(ball.Sigma_c, G @ flat.Sigma_c @ G.T, rtol=1e-6, atol=1e-12)
    assert not np.allclose(ball.Sigma_c, flat.Sigma_c, rtol=1e-3)
    with pytest.raises(ConfigError, match="surface_to_center_m.cube: unknown type"):
        apply_overrides(cfg, ["localize.surface_to_center_m={cube: 0.1}"])


def test_localize_depth_scale_and_none_cases():
    cfg = apply_overrides(load_config(), ["localize.depth_scale=1.04"])
    T = np.eye(4)
    box = (300.0, 220.0, 340.0, 260.0)
    assert localize(det(box), frame(), cfg, T).depth_m == pytest.approx(2.08)
    assert localize(det(box), frame(depth=None), cfg, T) is None
    f = frame()
    f.pose = None
    assert localize(det(box), f, cfg, T) is None
    assert localize(det(box), frame(depth=0.0), cfg, T) is None  # all invalid
    assert localize(det(box), frame(depth=12.0), cfg, T) is None  # beyond max_depth_m
    assert localize(det(box), frame(depth=0.1), cfg, T) is None  # below min_depth_m
    bad = frame()
    bad.depth_m = np.ones((10, 10), np.float32)
    with pytest.raises(LocalizeError, match="does not match"):
        localize(det(box), bad, cfg, T)


def test_in_view():
    T = np.eye(4)  # camera = tracker, optical axes in the map: a plain pinhole at the origin
    f = frame(depth=5.0)
    kw = {"margin_px": 20, "max_range": 4.0}
    assert in_view(np.array([0.0, 0.0, 3.0]), f, T, K, **kw)
    assert not in_view(np.array([0.0, 0.0, -3.0]), f, T, K, **kw)  # behind the camera
    assert not in_view(np.array([0.0, 0.0, 4.5]), f, T, K, **kw)  # beyond max_range
    # u = ppx + 500 x / z must be <= 639 - 20 = 619: x = 1.85 at z = 3 gives u = 627.8
    assert not in_view(np.array([1.85, 0.0, 3.0]), f, T, K, **kw)
    assert in_view(np.array([1.75, 0.0, 3.0]), f, T, K, **kw)  # u = 611.2
    # occluded: a wall at 2 m in front of a track at 3 m
    assert not in_view(np.array([0.0, 0.0, 3.0]), frame(depth=2.0), T, K, **kw)
    # within the tolerance (the object's own surface) it is visible
    assert in_view(np.array([0.0, 0.0, 2.2]), frame(depth=2.0), T, K, **kw)
    # invalid depth says nothing about occlusion
    assert in_view(np.array([0.0, 0.0, 3.0]), frame(depth=0.0), T, K, **kw)
    f.pose = None
    assert not in_view(np.array([0.0, 0.0, 3.0]), f, T, K, **kw)


def test_object_extent_widens_r_by_its_variance_only_for_3d_types():
    base = apply_overrides(load_config(), ["localize.extent_sigma_m={}"])
    wide = apply_overrides(load_config(), ["localize.extent_sigma_m={door: 0.2}"])
    T_tc = make_transform(R_BODY_OPTICAL, [0.0, 0.0, 0.045])
    pose = make_transform(np.eye(3), [0.0, 0.0, 0.0])
    box = (360.0, 230.0, 380.0, 250.0)
    door = Detection(class_name="door", type="door", text="", box_xyxy=box, confidence=0.9)
    r0 = localize(door, frame(pose=pose), base, T_tc).R
    r1 = localize(door, frame(pose=pose), wide, T_tc).R
    assert np.allclose(r1 - r0, 0.2**2 * np.eye(3), atol=1e-15)
    hazmat = det(box, class_name="oxidizer")
    assert np.allclose(
        localize(hazmat, frame(pose=pose), wide, T_tc).R, localize(hazmat, frame(pose=pose), base, T_tc).R
    )
