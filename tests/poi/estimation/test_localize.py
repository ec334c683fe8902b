"""poi.estimation.localize (box depth, (de)projection, localize) and poi.estimation.visibility (in_view)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from poi.config import ConfigError, apply_overrides, load_config
from poi.core.geometry import R_BODY_OPTICAL, make_transform, rot_z
from poi.core.sensor_noise import depth_sigma_m
from poi.core.types import Detection, Frame, Intrinsics
from poi.detectors.base import make_detection
from poi.estimation.box_cuts import box_at_border, hidden_lengths_px, hidden_solid_px, occluded_sides
from poi.estimation.box_depth import (
    LocalizeError,
    box_depth,
    box_depth_plane,
    median_variance_fraction,
    read_box_depth,
)
from poi.estimation.covariance import depth_jacobian
from poi.estimation.localize import localize
from poi.estimation.projection import deproject_pixel_to_point, project_point_to_pixel
from poi.estimation.shapes.plane_item import flat_item
from poi.estimation.visibility import in_view
from sim.sensors.d435_depth import window_noise

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


def test_the_depth_registration_error_of_a_sloping_box_is_a_shared_error():
    """A wall whose depth grows 4 mm a pixel to the right, seen through a depth image that sits
    up to a pixel off the colour image (1 px RMS): the box's depth is off by g du, du ~ N(0,
    1/2), so its variance grows by (g^2 + var(g_u) + var(g_v)) / 2 along dp/dd = p_c / d, all of
    it in R's shared part, and none without the registration error."""
    cfg = apply_overrides(load_config(), ["localize.mount_sigma_deg=0", "localize.mount_sigma_m=0"])
    f = frame()
    u = np.arange(K.width, dtype=np.float32) + 0.5
    f.depth_m[:] = 2.0 + 0.004 * (u - 370.0)  # 2.0 m at the box centre
    d = det((360.0, 230.0, 380.0, 250.0), class_name="qr")
    on = localize(d, f, apply_overrides(cfg, ["localize.registration_sigma_px=1"]), np.eye(4))
    off = localize(d, f, apply_overrides(cfg, ["localize.registration_sigma_px=0"]), np.eye(4))
    assert on.position_cam.tolist() == pytest.approx(off.position_cam.tolist(), abs=1e-12)
    # the slopes' variance: sigma_z^2 window^2 / sum(du^2) (10 x 10 inner box, sum 825)
    var_g = depth_sigma_m(on.depth_m, sigma_d_px=0.08, fx_depth_px=384.2, baseline_m=0.05) ** 2 * 49.0 / 825.0
    var_reg = 0.5 * (0.004**2 + 2.0 * var_g)
    ray = on.position_cam / on.depth_m
    assert on.Sigma_c - off.Sigma_c == pytest.approx(var_reg * np.outer(ray, ray), rel=1e-6, abs=1e-15)
    added = on.R - off.R
    assert added == pytest.approx(on.R_shared - off.R_shared, abs=1e-15)
    assert np.trace(added) == pytest.approx(var_reg * ray @ ray, rel=1e-6)


def test_localize_places_the_box_centre_in_the_map():
    # R of the sensors alone, the box centre's point (no object offset), a mount known exactly
    sensors_only = [
        "localize.types.door.extent_sigma_m=0",
        "localize.types.door.extent_ray_sigma_m=0",
        "localize.types.door.surface_to_center_m=0",
        "localize.mount_sigma_deg=0",
        "localize.mount_sigma_m=0",
    ]
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
    # flat depth: the depth plane has no slope, so J1 adds nothing; z_c's variance is the
    # median's (poi.estimation.box_depth.median_depth_variance), g^2 of one pixel's sigma_z^2 for the
    # 10 x 10 px inner box (every pixel lies within sigma_z of the median) with
    # g = sum_k (10 - |k|) (1 - |k| / 7) / 100 = 0.54 (the mean of a
    # row of 10 pixels whose noise correlates over the 7 px window), plus the Z16 unit's
    # rounding (1 mm)^2 / 12; the plane's slope error times the centre's, var(g) sigma_u^2 +
    # var(g_v) sigma_v^2, var(g) = sigma_z^2 window^2 / sum(du^2): du = +-0.5 .. +-4.5,
    # sum(du^2) = 10 * 82.5 = 825, window 7 px; sigma_u = sigma_v = 1 + 0.03 * 20 px; and the
    # depth registration's offset (1 px RMS, N(0, 1/2) per axis) times the slopes' error,
    # (var(g_u) + var(g_v)) / 2 = var(g)
    sigma_z = 4.0 * 0.08 / (384.2 * 0.05)
    var_median = 0.54**2 * sigma_z**2 + 1e-6 / 12.0
    var_d = var_median + sigma_z**2 * (2 * 49.0 * 1.6**2 / 825.0 + 49.0 / 825.0)
    assert obs.Sigma_c[2, 2] == pytest.approx(var_d, rel=1e-9)
    # x_c variance: (d/fx)^2 sigma_u^2 + (u - ppx)^2/fx^2 var_d
    expect_xx = (2 / 500) ** 2 * 1.6**2 + (50 / 500) ** 2 * var_d
    assert obs.Sigma_c[0, 0] == pytest.approx(expect_xx, rel=1e-6)
    # map covariance: optical z (depth) -> tracker x -> map y after the 90 degree turn
    # plus Sigma_eps: slam.sigma_eps_m in slam mode (the default), tracker.sigma_eps_m in t265 mode
    assert obs.R[1, 1] == pytest.approx(var_d + 0.002**2, rel=1e-9)
    assert np.allclose(obs.R, obs.R.T)
    t265 = localize(d, frame(pose=pose), apply_overrides(cfg, ["localize.mode=t265"]), T_tc)
    assert t265.R[1, 1] == pytest.approx(var_d + 0.05**2, rel=1e-9)
    # Sigma_eps and the registration's part of z_c (map y) repeat from frame to frame: they are
    # the shared part
    var_reg = sigma_z**2 * 49.0 / 825.0
    along_z_c = np.array([0.1, 1.0, 0.0])  # dp/dd = p_c / d in the map frame
    assert obs.R_shared == pytest.approx(0.002**2 * np.eye(3) + var_reg * np.outer(along_z_c, along_z_c), rel=1e-9)
    # a mount known to 1 degree and 1 cm: q = (0.2, 2, 0) from the camera to the point in the
    # map, R gains s_r^2 (|q|^2 I - q q^T) + s_t^2 I: 4 s_r^2 + s_t^2 across the line of sight
    # (x), 0.04 s_r^2 + s_t^2 along it (y), 4.04 s_r^2 + s_t^2 vertically; shared as well
    mount = apply_overrides(
        load_config(), [*sensors_only[:4], "localize.mount_sigma_deg=1", "localize.mount_sigma_m=0.01"]
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
    no_valve_offset = apply_overrides(cfg, ["localize.types.valve.surface_to_center_m=0"])
    flat = localize(det((360.0, 230.0, 380.0, 250.0), class_name="valve"), frame(), no_valve_offset, T_tc)
    assert flat.position_cam.tolist() == pytest.approx([0.2, 0.0, 2.0], abs=1e-12)  # no offset
    # a negative offset: the depth read the wall behind a thin valve, its centre is nearer
    near = apply_overrides(cfg, ["localize.types.valve.surface_to_center_m=-0.05"])
    valve = localize(det((360.0, 230.0, 380.0, 250.0), class_name="valve"), frame(), near, T_tc)
    shrink = 1.0 - 0.05 / np.hypot(0.2, 2.0)
    assert valve.position_cam.tolist() == pytest.approx([0.2 * shrink, 0.0, 2.0 * shrink], abs=1e-12)
    # the offset is in J2: Sigma_c(ball) = G Sigma_c(flat) G^T, G = (1 + r/|p|) I - r p p^T / |p|^3
    p = np.array([0.2, 0.0, 2.0])
    n = np.linalg.norm(p)
    G = (1.0 + 0.105 / n) * np.eye(3) - 0.105 * np.outer(p, p) / n**3
    np.testing.assert_allclose(ball.Sigma_c, G @ flat.Sigma_c @ G.T, rtol=1e-6, atol=1e-12)
    assert not np.allclose(ball.Sigma_c, flat.Sigma_c, rtol=1e-3)
    with pytest.raises(ConfigError, match="localize.types.cube: unknown type"):
        apply_overrides(cfg, ["localize.types.cube={shape: body, surface_to_center_m: 0.1}"])
    with pytest.raises(ConfigError, match=r"localize.types.valve.surface_to_center_m: expected a value > -1"):
        apply_overrides(cfg, ["localize.types.valve.surface_to_center_m=-1.5"])


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


def test_an_item_in_a_near_edges_stereo_shadow_gives_no_observation():
    """A QR code at 5 m seen past a wall edge at 2.2 m: the D435 reads no depth on the
    code (the edge's shadow), so the inner box's few valid pixels are the wall's."""
    cfg = load_config()
    box = (300.0, 220.0, 340.0, 260.0)  # inner box: columns and rows 310..329, 400 pixels
    f = frame(depth=5.0)
    f.depth_m[:, :326] = 0.0  # the shadow covers the placard up to the edge ...
    f.depth_m[:, 326:] = 2.2  # ... the wall beyond it: 4 of the inner 20 columns are valid
    assert box_depth(f.depth_m, box, 0.5) == pytest.approx(2.2)  # what the median would say
    assert localize(det(box, "qr"), f, cfg, np.eye(4)) is None
    f.depth_m[:, 318:326] = 5.0  # 12 of 20 columns valid: 60% >= min_depth_fill ...
    one_surface = apply_overrides(cfg, ["localize.max_depth_split=1"])
    assert localize(det(box, "qr"), f, one_surface, np.eye(4)) is not None
    assert localize(det(box, "qr"), f, cfg, np.eye(4)) is None  # ... a third the wall's: two surfaces
    off = apply_overrides(cfg, ["localize.min_depth_fill=0"])
    f.depth_m[:, :326] = 0.0
    assert localize(det(box, "qr"), f, off, np.eye(4)).depth_m == pytest.approx(2.2)
    with pytest.raises(ConfigError, match="min_depth_fill"):
        apply_overrides(cfg, ["localize.min_depth_fill=1.5"])


def test_a_box_holding_two_surfaces_gives_no_observation():
    """An extinguisher 3.4 m away behind a bucket at 2.7 m (rrl-hard's first maze): the bucket
    fills 58% of the inner box, so its median reads the bucket, 0.7 m short; a split box gives
    no observation, and a box whose near part is within depth_split_m of the rest does."""
    cfg = load_config()
    box = (300.0, 200.0, 340.0, 280.0)  # inner box: columns 310..329, rows 220..259
    f = frame(depth=3.4)
    f.depth_m[220:260, 310:318] = 2.7  # 8 of the inner 20 columns: 40% of its pixels
    f.depth_m[220:232, 318:330] = 2.7  # and the bucket's top left: 58% in all
    assert box_depth(f.depth_m, box, 0.5) == pytest.approx(2.7)  # what the median would say
    assert localize(det(box, "fire-extinguisher"), f, cfg, np.eye(4)) is None
    off = apply_overrides(cfg, ["localize.max_depth_split=1"])
    assert localize(det(box, "fire-extinguisher"), f, off, np.eye(4)).depth_m == pytest.approx(2.7)
    f.depth_m[f.depth_m < 3.0] = 3.2  # the near part 0.2 m in front: one surface's relief
    assert localize(det(box, "fire-extinguisher"), f, cfg, np.eye(4)) is not None
    with pytest.raises(ConfigError, match="max_depth_split"):
        apply_overrides(cfg, ["localize.max_depth_split=1.5"])


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


def test_object_extent_widens_r_along_and_across_the_ray_only_for_3d_types():
    """Sigma_ext = sigma_ray^2 r r^T + sigma_lat^2 (I - r r^T) in the camera frame, rotated into
    R; a type with extent_sigma_m alone spreads as much along the ray as across it."""
    door_row = "localize.types.door.extent_sigma_m={0}", "localize.types.door.extent_ray_sigma_m={1}"
    base = apply_overrides(load_config(), [k.format(0, "null") for k in door_row])
    wide = apply_overrides(load_config(), [k.format(0.05, 0.2) for k in door_row])
    iso = apply_overrides(load_config(), [k.format(0.05, "null") for k in door_row])
    T_tc = make_transform(R_BODY_OPTICAL, [0.0, 0.0, 0.045])
    pose = make_transform(np.eye(3), [0.0, 0.0, 0.0])
    box = (360.0, 230.0, 380.0, 250.0)
    door = Detection(class_name="door", type="door", text="", box_xyxy=box, confidence=0.9)
    o0 = localize(door, frame(pose=pose), base, T_tc)
    o1 = localize(door, frame(pose=pose), wide, T_tc)
    r = o1.position_cam / np.linalg.norm(o1.position_cam)
    S_ext = 0.2**2 * np.outer(r, r) + 0.05**2 * (np.eye(3) - np.outer(r, r))
    np.testing.assert_allclose(o1.Sigma_extent_c, S_ext, atol=1e-15)
    np.testing.assert_allclose(o1.R - o0.R, R_BODY_OPTICAL @ S_ext @ R_BODY_OPTICAL.T, atol=1e-15)
    # along the ray: the variance in the direction r is sigma_ray^2, across it sigma_lat^2
    assert r @ o1.Sigma_extent_c @ r == pytest.approx(0.2**2)
    np.testing.assert_allclose(
        localize(door, frame(pose=pose), iso, T_tc).Sigma_extent_c, 0.05**2 * np.eye(3), atol=1e-15
    )
    hazmat = det(box, class_name="oxidizer")
    assert np.allclose(
        localize(hazmat, frame(pose=pose), wide, T_tc).R, localize(hazmat, frame(pose=pose), base, T_tc).R
    )
    with pytest.raises(ConfigError, match=r"localize.types.door.extent_ray_sigma_m: expected a value >= 0"):
        apply_overrides(base, ["localize.types.door.extent_ray_sigma_m=-0.1"])
    with pytest.raises(ConfigError, match="localize.types.door.aspect: a leaf shape has no aspect"):
        apply_overrides(base, ["localize.types.door.aspect=1"])


def _wall(z0: float, slope_m_per_px: float, noise_m: float, rng) -> np.ndarray:
    """A depth image of a wall whose depth grows by ``slope_m_per_px`` per column, with white
    per-pixel noise of ``noise_m``."""
    u = np.arange(K.width, dtype=float)[None, :] - K.ppx
    return (z0 + slope_m_per_px * u + noise_m * rng.standard_normal((K.height, K.width))).astype(np.float32)


def test_the_depth_plane_reads_a_slope_that_central_differences_lose_in_the_noise():
    """A wall at 1 m seen at 45 degrees slopes by z / fx = 2 mm a pixel; the D435's per-pixel
    noise there is 4 mm (poi.core.sensor_noise.depth_sigma_m), so two pixels either side give
    the slope +- 2.8 mm (worse than the slope itself), while the plane through the inner box of
    a 40 px box (400 pixels) gives it to about 0.05 mm."""
    rng = np.random.default_rng(3)
    slope, noise = 0.002, 0.004
    box = (300.0, 220.0, 340.0, 260.0)
    plane_err, central_err = [], []
    for _ in range(50):
        depth = _wall(1.0, slope, noise, rng)
        pl = box_depth_plane(depth, box, 0.5)
        plane_err.append(pl.g_u - slope)
        central_err.append(depth_jacobian(depth, 319.5, 239.5)[2, 0] - slope)
        assert abs(pl.g_v) < 5 * np.sqrt(pl.var_g_v)
    # least squares: sigma / sqrt(sum du^2) = 0.004 / sqrt(20 * 665) = 0.035 mm; 50 draws: rms within 30%
    assert np.sqrt(np.mean(np.square(plane_err))) == pytest.approx(noise / np.sqrt(20 * 665.0), rel=0.3)
    assert np.sqrt(np.mean(np.square(central_err))) > slope  # the slope is lost in the noise
    # the variance the plane reports: the residuals' (about the noise), times window^2, or the
    # noise given
    pl1 = box_depth_plane(depth, box, 0.5)
    pl7 = box_depth_plane(depth, box, 0.5, window_px=7.0)
    assert pl1.var_g_u == pytest.approx(noise**2 / (20 * 665.0), rel=0.3)
    assert pl7.var_g_u == pytest.approx(49.0 * pl1.var_g_u, rel=1e-9)
    assert box_depth_plane(depth, box, 0.5, noise_sigma_m=0.01).var_g_u == pytest.approx(1e-4 / (20 * 665.0))
    # too few pixels, or all in one row: no plane
    assert box_depth_plane(depth, (300.0, 220.0, 302.0, 222.0), 0.5) is None
    assert box_depth_plane(depth, (300.0, 239.6, 340.0, 240.4), 1.0) is None


def _window_wall(z0: float, slope_m_per_px: float, noise_m: float, rng, window_px: int = 7) -> np.ndarray:
    """:func:`_wall` with the simulator's depth noise: white noise averaged over the stereo
    matching window (:func:`sim.sensors.d435_depth.window_noise`), ``noise_m`` per pixel."""
    white = rng.standard_normal((K.height + window_px - 1, K.width + window_px - 1), np.float32)
    return _wall(z0, slope_m_per_px, 0.0, rng) + np.float32(noise_m) * window_noise(white, window_px)


@pytest.mark.parametrize("holes", [False, True])
def test_the_depth_planes_depth_at_the_box_centre_has_the_variance_it_reports(holes):
    """A 40 px box on a wall at 1 m sloping 2 mm a pixel (45 degrees), the D435's noise
    correlated over its 7 px window: over 400 draws the plane's depth at the box centre errs
    with the variance :meth:`DepthPlane.depth_variance_at` reports, within 20% (the estimate's
    own spread is 7%), also with the block's left 40% in holes (the valid pixels then centre
    off the box, and the slopes' error carries to it). It is a small part of one pixel's
    variance: about (7 / 20)^2 / fill of it."""
    rng = np.random.default_rng(21 if holes else 20)
    slope, noise = 0.002, 0.004
    box = (299.5, 219.5, 339.5, 259.5)  # centre (319, 239) in pixel coordinates
    u, v = 319.0, 239.0
    truth = 1.0 + slope * (u - K.ppx)
    errors, variances = [], []
    for _ in range(400):
        depth = _window_wall(1.0, slope, noise, rng)
        if holes:
            depth[:, :317] = 0.0  # 8 of the inner block's 20 columns read nothing
        pl = box_depth_plane(depth, box, 0.5, 7.0, noise, mean_variance=True)
        errors.append(pl.depth_at(u, v) - truth)
        variances.append(pl.depth_variance_at(u, v))
    assert np.mean(np.square(errors)) == pytest.approx(np.mean(variances), rel=0.2)
    assert np.mean(variances) < (0.3 if holes else 0.15) * noise**2
    with pytest.raises(LocalizeError, match="mean_variance"):
        box_depth_plane(depth, box, 0.5, 7.0, noise).depth_variance_at(u, v)


FACING_BOX = (289.5, 209.5, 349.5, 269.5)  # 60 x 60 px about the image centre


def _facing_wall_frame(z: float, rng) -> tuple[Frame, float]:
    """A frame of a wall facing the camera ``z`` metres away with the simulator's depth noise
    (:func:`_window_wall`), and that noise's sigma_z per pixel."""
    lc = load_config().localize
    s_z = depth_sigma_m(z, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    depth = _window_wall(z, 0.0, s_z, rng)
    return Frame(index=0, timestamp_s=0.0, rgb=None, intrinsics=K, depth_m=depth, pose=np.eye(4)), s_z


def test_a_signs_depth_has_its_planes_variance():
    """A qr code on a wall facing the camera 2 m away, a 60 px box: Sigma_c's variance along the
    ray is the plane mean's (about (7 / 30)^2 of one pixel's sigma_z^2 for the 30 x 30 px inner
    block, plus the Z16 rounding), far less than one pixel's."""
    f, s_z = _facing_wall_frame(2.0, np.random.default_rng(2))
    cfg = apply_overrides(load_config(), ["localize.registration_sigma_px=0"])
    obs = localize(det(FACING_BOX, class_name="qr"), f, cfg, np.eye(4))
    assert 0.03 * s_z**2 < float(obs.Sigma_c[2, 2]) < 0.1 * s_z**2


@pytest.mark.parametrize("surface", ["flat", "holes", "slope"])
def test_a_box_medians_variance_is_the_share_its_windows_leave(surface):
    """The median of a 20 x 20 px inner block of window-correlated noise (the simulator's, 7 px,
    unit variance) varies as :func:`median_variance_fraction` says: on a flat block, one with a
    third of its columns reading nothing, and one sloping by a twentieth of a sigma a pixel,
    where the pixels within a sigma of the median are fewer. Far less than one pixel's variance,
    and more than 400 independent pixels' would give. A block that slopes by half a sigma a
    pixel has a fifth of its pixels there: which of them the median reads is the surface's
    doing, not the noise's, and one pixel's variance stays. Small images keep the draws cheap."""
    rng = np.random.default_rng({"flat": 30, "holes": 31, "slope": 32}[surface])
    box = (10.0, 10.0, 50.0, 50.0)
    ramp = 0.05 * np.arange(60.0)[None, :] if surface == "slope" else 0.0
    medians, fractions = [], []
    for _ in range(1500):
        depth = 30.0 + ramp + window_noise(rng.standard_normal((66, 66), np.float32), 7).astype(float)
        if surface == "holes":
            depth[:, 20:27] = 0.0
        median = box_depth(depth, box, 0.5)
        medians.append(median - float(np.median(30.0 + np.broadcast_to(ramp, (60, 60))[20:40, 20:40])))
        fractions.append(median_variance_fraction(depth, box, 0.5, 7.0, 1.0, median))
    assert np.var(medians) == pytest.approx(np.mean(fractions), rel=0.15)
    assert 1.0 / 400 < np.mean(fractions) < {"flat": 0.12, "holes": 0.2, "slope": 0.15}[surface]
    steep = 30.0 + 0.5 * np.arange(60.0)[None, :] + window_noise(rng.standard_normal((66, 66), np.float32), 7)
    assert median_variance_fraction(steep, box, 0.5, 7.0, 1.0, box_depth(steep, box, 0.5)) == 1.0
    # one pixel's own: a single valid pixel; a noiseless flat block, noise that does not correlate
    one = np.zeros((60, 60))
    one[30, 30] = 2.0
    assert median_variance_fraction(one, box, 0.5, 7.0, 1.0, 2.0) == pytest.approx(1.0)
    assert median_variance_fraction(np.full((60, 60), 2.0), box, 0.5, 1.0, 1.0, 2.0) == pytest.approx(1 / 400)


def test_a_3d_items_depth_has_its_medians_variance():
    """A valve 3 m away, a 60 px box, its depth the median of its 30 x 30 px inner block: the
    depth's part of Sigma_c's variance along the ray is one pixel's sigma_z^2 times the window's
    share plus the Z16 rounding (poi.estimation.box_depth.median_depth_variance); the rest is
    the plane's slope times the centre's error, (g^2 + var(g)) sigma^2 on each axis."""
    f, _ = _facing_wall_frame(3.0, np.random.default_rng(3))
    depth, lc = f.depth_m, load_config().localize
    box = FACING_BOX
    base = [
        "localize.registration_sigma_px=0",
        "localize.types.valve.surface_to_center_m=0",
        "localize.types.valve.extent_sigma_m=0",
        "localize.types.valve.extent_ray_sigma_m=0",
    ]
    cfg = apply_overrides(load_config(), base)
    ray = float(localize(det(box, class_name="valve"), f, cfg, np.eye(4)).Sigma_c[2, 2])
    d = float(np.median(depth[225:255, 305:335]))
    s_d = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    share = median_variance_fraction(depth, box, 0.5, 7.0, s_d, d)
    bd = read_box_depth(depth, box, lc, False)
    s_c = 1.0 + 0.03 * 60.0  # the default centre sigma of a 60 px box
    slope = sum((float(g) ** 2 + var) * s_c**2 for g, var in zip(bd.grad, bd.var_g, strict=True))
    assert ray == pytest.approx(share * s_d**2 + 1e-6 / 12.0 + slope, rel=1e-3)
    assert ray < 0.3 * s_d**2
    assert 0.03 < share < 0.1


def _sign_nees(cfg, rng, n: int) -> list[float]:
    """Camera-frame NEES of n observations of a qr code on the 45-degree wall at 1 m (depth
    z = 1 + 0.002 (u - ppx)), boxed with the oracle's centre noise; the depth carries the
    D435's noise as a common offset (what the box's median keeps: on a slope of half a sigma a
    pixel, one pixel's variance, :func:`median_variance_fraction`) plus per-pixel white noise
    of the same size (what a slope estimate sees)."""
    lc = cfg.localize
    slope, w = 0.002, 40.0
    s_z = depth_sigma_m(1.0, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
    s_u = 1.0 + 0.03 * w  # the oracle's centre noise, px
    out = []
    for _ in range(n):
        depth = _wall(1.0 + s_z * rng.standard_normal(), slope, s_z, rng)
        u, v = rng.uniform(250.0, 390.0), rng.uniform(200.0, 280.0)  # the true centre, pixel coordinates
        cu, cv = np.array([u, v]) + 0.5 + s_u * rng.standard_normal(2)
        box = (cu - w / 2, cv - w / 2, cu + w / 2, cv + w / 2)
        f = Frame(index=0, timestamp_s=0.0, rgb=None, intrinsics=K, depth_m=depth, pose=np.eye(4))
        obs = localize(det(box, class_name="qr"), f, cfg, np.eye(4))
        e = obs.position_cam - deproject_pixel_to_point(K, u, v, 1.0 + slope * (u - K.ppx))
        out.append(float(e @ np.linalg.solve(obs.Sigma_c, e)))
    return out


def test_the_plane_slope_makes_a_sign_seen_at_an_angle_consistent():
    """With J1 from the depth plane the mean NEES of those observations lies in its chi-square
    99% interval (central differences of single pixels, [Avevor2022] 2.2.2, read the D435's
    per-pixel noise and turn Sigma_c, thin across the wall, a random way: docs/CONSISTENCY.md).
    Shape and truncation are off (the qr code a body), so only J1 counts."""
    n = 300
    lo, hi = chi2.ppf([0.005, 0.995], 3 * n) / n  # 99% interval of the mean of n chi2(3)
    # the boxes' depth is read where they are drawn: no registration error
    cfg = apply_overrides(load_config(), ["localize.types.qr={shape: body}", "localize.registration_sigma_px=0"])
    plane = _sign_nees(cfg, np.random.default_rng(5), n)
    assert lo <= np.mean(plane) <= hi


def _item_box(corners: np.ndarray) -> tuple[tuple[float, float, float, float], np.ndarray]:
    """The box (corner convention) framing camera-frame points, and their pixels."""
    uv = np.array([project_point_to_pixel(K, c) for c in corners])
    lo, hi = uv.min(axis=0) + 0.5, uv.max(axis=0) + 0.5
    return (lo[0], lo[1], hi[0], hi[1]), uv


def _plane_at(center: np.ndarray, normal: np.ndarray, u: float, v: float) -> float:
    """Depth z where the ray of pixel (u, v) meets the plane through ``center`` with ``normal``."""
    r = deproject_pixel_to_point(K, u, v, 1.0)
    return float(normal @ center / (normal @ r))


@pytest.mark.parametrize("height_m", [-0.25, 0.2])  # above the camera (y up is -y), below it
@pytest.mark.parametrize("diamond", [False, True])
def test_a_flat_item_seen_at_an_angle_is_measured_and_centred_on_its_plane(height_m, diamond):
    """A 0.3 x 0.15 m exit sign (or a 0.25 m hazmat diamond) on a wall turned 50 degrees, 1.2 m
    away: its box's centre ray misses the sign's centre by a centimetre or more (perspective:
    the near edge is larger and, off the camera's height, higher or lower); measured on the
    plane, the centre is within 2 mm and the sides within 2%."""
    yaw = np.deg2rad(50.0)
    normal = np.array([np.sin(yaw), 0.0, -np.cos(yaw)])  # facing the camera, turned about y
    along = np.array([np.cos(yaw), 0.0, np.sin(yaw)])  # the sign's width direction
    up = np.array([0.0, -1.0, 0.0])
    c = np.array([0.15, height_m, 1.2])
    if diamond:
        s = 0.25 / np.sqrt(2.0)  # half diagonal of a 0.25 m square turned 45 degrees
        corners = np.array([c + s * up, c + s * along, c - s * up, c - s * along])
        W = H = 2 * s
    else:
        W, H = 0.3, 0.15
        corners = np.array([c + sa * W / 2 * along + su * H / 2 * up for sa in (-1, 1) for su in (-1, 1)])
    box, _ = _item_box(corners)
    u, v = 0.5 * (box[0] + box[2]) - 0.5, 0.5 * (box[1] + box[3]) - 0.5
    d = _plane_at(c, normal, u, v)
    g = (
        0.5 * (_plane_at(c, normal, u + 1, v) - _plane_at(c, normal, u - 1, v)),
        0.5 * (_plane_at(c, normal, u, v + 1) - _plane_at(c, normal, u, v - 1)),
    )
    item = flat_item(K, u, v, d, g, box, diamond=diamond)
    assert np.linalg.norm(deproject_pixel_to_point(K, u, v, d) - c) > 0.008  # the box centre's ray
    assert np.linalg.norm(item.center - c) < 0.002
    assert item.width_m == pytest.approx(W, rel=0.02)
    assert item.height_m == pytest.approx(H, rel=0.02)
    # and cut by an occluder to its left 40%: the box says its width is cut by about that much
    x1 = box[0] + 0.4 * (box[2] - box[0])
    cut = (x1, box[1], box[2], box[3])
    uc = 0.5 * (cut[0] + cut[2]) - 0.5
    cut_item = flat_item(K, uc, v, _plane_at(c, normal, uc, v), g, cut, diamond=diamond)
    aspect = W / H
    hid_w, hid_h = hidden_lengths_px(
        (cut[2] - cut[0], cut[3] - cut[1]), (cut_item.width_m, cut_item.height_m), aspect, 0.05
    )
    assert hid_h == 0.0
    assert hid_w > 0.5 * 0.4 * (box[2] - box[0])  # perspective: a metre-wise 40% is fewer pixels on the far side


@pytest.mark.parametrize(("yaw_deg", "height_m", "z"), [(70.0, 0.25, 1.0), (45.0, -0.2, 0.7)])
def test_a_placard_hung_at_any_angle_is_centred_over_its_turns(yaw_deg, height_m, z):
    """A 0.25 m square placard on a wall turned ``yaw_deg`` from face-on, off the camera's
    height, hung at each of 18 in-plane turns: the diamond rule (which holds for a turn of 0)
    puts its centre up to 9-17 px off in the image; ``turned`` centres it as the mean over the
    turns, and the spread it reports covers the errors (mean squared error over spread^2
    between 0.7 and 1.3, no error beyond 2.5 spreads); the column is exact either way."""
    yaw = np.deg2rad(yaw_deg)
    normal = np.array([np.sin(yaw), 0.0, -np.cos(yaw)])
    along = np.array([np.cos(yaw), 0.0, np.sin(yaw)])
    up = np.array([0.0, -1.0, 0.0])
    c = np.array([0.0, height_m, z])
    true_uv = project_point_to_pixel(K, c)
    diamond_err, q = [], []
    for theta in np.deg2rad(np.arange(0.0, 90.0, 5.0)):  # 0: vertices up and across (a diamond)
        phi = theta + 0.5 * np.pi * np.arange(4)
        corners = c + 0.125 * np.sqrt(2.0) * (np.cos(phi)[:, None] * along + np.sin(phi)[:, None] * up)
        box, _ = _item_box(corners)
        u, v = 0.5 * (box[0] + box[2]) - 0.5, 0.5 * (box[1] + box[3]) - 0.5
        g = (
            0.5 * (_plane_at(c, normal, u + 1, v) - _plane_at(c, normal, u - 1, v)),
            0.5 * (_plane_at(c, normal, u, v + 1) - _plane_at(c, normal, u, v - 1)),
        )
        d = _plane_at(c, normal, u, v)
        diamond = flat_item(K, u, v, d, g, box, diamond=True)
        turned = flat_item(K, u, v, d, g, box, diamond=True, turned=True)
        diamond_err.append(project_point_to_pixel(K, diamond.center)[1] - true_uv[1])
        err = project_point_to_pixel(K, turned.center) - true_uv
        assert abs(err[0]) < 0.2
        assert turned.turn_sigma_px[0] < 0.2
        assert abs(err[1]) < 2.5 * turned.turn_sigma_px[1]
        q.append(err[1] ** 2 / turned.turn_sigma_px[1] ** 2)
    assert abs(diamond_err[0]) < 0.05  # the diamond rule is exact for a diamond
    assert max(np.abs(diamond_err)) > 8.0
    assert 0.7 < np.mean(q) < 1.3


def test_a_cut_sign_widens_its_centre_sigma_and_a_corner_gives_none():
    """A 100 x 100 px qr code face-on at 1 m and its right half alone, the left cut by an
    occluder 0.3 m nearer: the cut box's sigma_u grows by half the hidden 50 px. The same half
    box with nothing beside it is not cut (a sign on a wall is hidden only by something, though
    by its shape alone it is). On the border (within border_px) no tolerance is
    given; a box in a corner of the image gives no observation, a door's does."""
    cfg = load_config()
    T = np.eye(4)
    f = frame(depth=1.0)
    occluded = frame(depth=1.0)
    occluded.depth_m[:, :318] = 0.7  # a wall edge left of the half box
    full = localize(det((270.0, 190.0, 370.0, 290.0), class_name="qr"), f, cfg, T)
    half_box = det((320.0, 190.0, 370.0, 290.0), class_name="qr")
    half = localize(half_box, occluded, cfg, T)
    s_u = 1.0 + 0.03 * 50  # the centre model for a 50 px wide box
    var_x = (1.0 / 500) ** 2 * (s_u**2 + 25.0**2)  # plus (u - ppx) / fx sigma_d: u is 25 px off the axis
    assert half.Sigma_c[0, 0] == pytest.approx(var_x, rel=0.05)
    assert half.Sigma_c[1, 1] == pytest.approx(full.Sigma_c[1, 1], rel=0.05)  # v: not cut
    assert full.Sigma_c[0, 0] == pytest.approx((1.0 / 500) ** 2 * 4.0**2, rel=0.05)  # not cut either
    alone = localize(half_box, f, cfg, T)  # nothing beside it: whole
    assert alone.Sigma_c[0, 0] == pytest.approx((1.0 / 500) ** 2 * s_u**2, rel=0.05)
    # 97 px of 100 at the image's left edge: cut there (a border box gets no tolerance), in the
    # middle of the image: the 3% is within truncation_tolerance
    edge = localize(det((1.0, 190.0, 98.0, 290.0), class_name="qr"), f, cfg, T)
    mid = localize(det((271.0, 190.0, 368.0, 290.0), class_name="qr"), f, cfg, T)
    assert edge.Sigma_c[0, 0] > 1.05 * mid.Sigma_c[0, 0]
    assert box_at_border((1.0, 190.0, 98.0, 290.0), 640, 480, cfg.localize.border_px) == (True, False)
    corner = (0.0, 0.0, 90.0, 100.0)
    assert localize(det(corner, class_name="qr"), f, cfg, T) is None
    assert localize(det(corner, class_name="door"), f, cfg, T) is not None


def test_a_sign_cut_by_the_border_is_centred_on_the_whole_sign():
    """A 100 x 100 px qr code face-on at 1 m, its top 40 px above the image: its box is (270, 0,
    370, 60), its shape says 40 px are hidden, and the border says where. The centre is the
    whole code's, pixel row 9.5 (y = (9.5 - 239.5) / 500 m), not the visible part's 29.5; its
    sigma_v is the box model's 1 + 0.03 * 60 px plus half the full 100 px times the shape's
    error, hypot(2 * 4 / 100, 2 * 2.8 / 60), plus half of hidden_length_sigma (0.25) of the
    hidden 40 px. A diamond (hazmat) face-on is centred alike. Where the depth leaves the tilt
    open the hidden length is a bound only and the centre stays."""
    cfg = load_config()
    T, f = np.eye(4), frame(depth=1.0)
    box = (270.0, 0.0, 370.0, 60.0)
    whole = localize(det(box, class_name="qr"), f, cfg, T)
    assert whole.position_cam == pytest.approx([0.0, (9.5 - 239.5) / 500, 1.0], abs=1e-3)
    sigma_v = math.hypot(2.8, 0.5 * 100 * math.hypot(2 * 4.0 / 100, 2 * 2.8 / 60), 0.5 * 0.25 * 40)
    # Sigma_c's y variance: sigma_v^2 (z / fy)^2, plus the depth's share (y / z)^2 var_d
    dy = whole.Sigma_c[1, 1] - (whole.position_cam[1] / 1.0) ** 2 * whole.Sigma_c[2, 2]
    assert dy == pytest.approx((sigma_v / 500) ** 2, rel=0.05)
    assert whole.Sigma_c[0, 0] == pytest.approx((4.0 / 500) ** 2, rel=0.05)  # u: not cut
    placard = localize(det(box, class_name="oxidizer"), f, cfg, T)
    assert placard.position_cam == pytest.approx(whole.position_cam, abs=1e-3)
    # the same box at the bottom of the image moves down
    low = localize(det((270.0, 420.0, 370.0, 480.0), class_name="qr"), f, cfg, T)
    assert low.position_cam[1] == pytest.approx((469.5 - 239.5) / 500, abs=1e-3)
    # a 20 x 12 px box at 5 m: the inner block's few pixels leave its tilt open (slope sigma
    # above flat_max_slope_sigma), so the 8 px the face-on bound hides are an upper bound only
    # and the centre stays at the visible part's, row 5.5, widened by half of them
    far = localize(det((300.0, 0.0, 320.0, 12.0), class_name="qr"), frame(depth=5.0), cfg, T)
    assert far.position_cam[1] == pytest.approx((5.5 - 239.5) / 500 * 5.0, abs=1e-3)
    dy_far = far.Sigma_c[1, 1] - (far.position_cam[1] / 5.0) ** 2 * far.Sigma_c[2, 2]
    assert dy_far == pytest.approx((np.hypot(1.0 + 0.03 * 12, 4.0) * 5.0 / 500) ** 2, rel=0.05)
    with pytest.raises(ConfigError, match="localize.hidden_length_sigma"):
        apply_overrides(cfg, ["localize.hidden_length_sigma=-0.1"])


def test_a_flat_items_box_a_few_sigmas_inside_the_border_counts_as_touching_it():
    """A 200 px qr code box at 1 m on the image's bottom edge, its right side 20 px inside the
    right edge: within border_px (8) plus 2.5 of its centre sigmas (1 + 0.03 * 200 = 7 px), so
    it may be cut there too, and a box in a corner gives no observation. 40 px inside it is cut
    at the bottom only. A door's box keeps border_px (it is not rejected either way)."""
    cfg = load_config()
    T, f = np.eye(4), frame(depth=1.0)
    near = (420.0, 280.0, 620.0, 480.0)
    assert localize(det(near, class_name="qr"), f, cfg, T) is None
    assert localize(det(near, class_name="qr"), f, apply_overrides(cfg, ["localize.flat_border_sigmas=0"]), T)
    assert localize(det((400.0, 280.0, 600.0, 480.0), class_name="qr"), f, cfg, T) is not None
    assert localize(det(near, class_name="door"), f, cfg, T) is not None
    with pytest.raises(ConfigError, match="localize.flat_border_sigmas"):
        apply_overrides(cfg, ["localize.flat_border_sigmas=-1"])


def test_a_solid_item_cut_by_the_border_widens_its_centre_sigma_by_half_the_hidden_length():
    """An extinguisher's box at the bottom of the image, 180 px tall at 1 m: in full view
    box_height_m (0.523 m) spans f S / z = 246 px at its centre's depth, so 66 px are hidden
    and sigma_v grows by half of that; the same box inside the image, or a box taller than
    f S / z, is not widened; a 3-D type with no size is not either."""
    cfg = load_config()
    T = np.eye(4)
    f = frame(depth=1.0)
    box = (270.0, 300.0, 370.0, 480.0)  # touches the bottom edge
    cut = localize(det(box, class_name="fire-extinguisher"), f, cfg, T)
    no_size = apply_overrides(cfg, ["localize.types.fire-extinguisher.box_height_m=null"])
    uncut = localize(det(box, class_name="fire-extinguisher"), f, no_size, T)
    z = float(cut.position_cam[2])
    assert z == pytest.approx(1.0 + cfg.localize.types["fire-extinguisher"].surface_to_center_m, abs=0.01)
    hid = hidden_solid_px((100.0, 180.0), (0.159, 0.523), z, (500.0, 500.0), (False, True))
    assert hid[0] == 0.0 and hid[1] == pytest.approx(500.0 * 0.523 / z - 180.0)
    # Sigma_c's v block grows by (hid / 2)^2 times (dY / dv)^2, dY / dv about z / fy
    added = cut.Sigma_c[1, 1] - uncut.Sigma_c[1, 1]
    assert added == pytest.approx((0.5 * hid[1] * z / 500.0) ** 2, rel=0.05)
    assert cut.Sigma_c[0, 0] == pytest.approx(uncut.Sigma_c[0, 0], rel=1e-9)  # u: not at the border
    assert cut.box_cut == (False, True)
    inside = (270.0, 200.0, 370.0, 380.0)
    a = localize(det(inside, class_name="fire-extinguisher"), f, cfg, T)
    b = localize(det(inside, class_name="fire-extinguisher"), f, no_size, T)
    assert a.Sigma_c[1, 1] == pytest.approx(b.Sigma_c[1, 1], rel=1e-9)
    assert a.box_cut == (False, False)
    tall = (270.0, 200.0, 370.0, 480.0)  # 280 px: no shorter than the item
    a = localize(det(tall, class_name="fire-extinguisher"), f, cfg, T)
    b = localize(det(tall, class_name="fire-extinguisher"), f, no_size, T)
    assert a.Sigma_c[1, 1] == pytest.approx(b.Sigma_c[1, 1], rel=1e-9)


def test_a_bodys_box_a_few_sigmas_inside_the_border_counts_as_touching_it():
    """An extinguisher cut at its foot 1 m away, its 180 px box's bottom 12 px inside the image
    (a detector's box edge jitters inward with its size): within border_px (8) plus 2.5 of its
    centre sigmas (1 + 0.03 * 180 = 6.4 px), so it counts as cut at the bottom and sigma_v
    grows by half the hidden length; with body_border_sigmas = 0 it is whole. A door's box
    keeps border_px (its hidden length moves its depth along its plane)."""
    cfg = load_config()
    T, f = np.eye(4), frame(depth=1.0)
    box = (270.0, 288.0, 370.0, 468.0)
    cut = localize(det(box, class_name="fire-extinguisher"), f, cfg, T)
    off_cfg = apply_overrides(cfg, ["localize.body_border_sigmas=0"])
    off = localize(det(box, class_name="fire-extinguisher"), f, off_cfg, T)
    assert cut.box_cut == (False, True) and off.box_cut == (False, False)
    z = float(cut.position_cam[2])
    hid = 500.0 * cfg.localize.types["fire-extinguisher"].box_height_m / z - 180.0
    added = cut.Sigma_c[1, 1] - off.Sigma_c[1, 1]
    assert added == pytest.approx((0.5 * hid * z / 500.0) ** 2, rel=0.05)
    assert localize(det(box, class_name="door"), f, cfg, T).box_cut == (False, False)
    with pytest.raises(ConfigError, match="localize.body_border_sigmas"):
        apply_overrides(cfg, ["localize.body_border_sigmas=-1"])


def test_a_depth_plane_leaves_out_a_nearer_surface_in_its_block():
    """A qr code on a wall 4.2 m away whose 30 px box's left 4 columns lie on a wall edge at
    3.0 m: fitted through both surfaces, the plane slopes by centimetres a pixel; fitted to the
    depths within depth_split_m of the block's median, it is the wall's, flat."""
    depth = np.full((480, 640), 4.2, np.float32)
    depth[:, :414] = 3.0
    box = (410.0, 216.0, 440.0, 246.0)
    both = box_depth_plane(depth, box, 1.0)
    item = box_depth_plane(depth, box, 1.0, split_m=0.3)
    assert abs(both.g_u) > 0.01
    assert item.g_u == pytest.approx(0.0, abs=1e-9) and item.d0 == pytest.approx(4.2, abs=1e-6)


def test_a_solid_item_beside_a_nearer_surface_counts_as_cut_on_that_side():
    """A door at 2.5 m whose box holds the third of its leaf that a wall 1 m nearer leaves in
    view (the wall fills the image left of the box; a nearer surface below a box is the floor
    before it and cuts nothing, one above it does): box_width_m (0.771 m) spans 154 px there,
    the box 50, so sigma_u grows by half the 104 px hidden. The same box with the wall 5 cm
    nearer only (a door frame's recess), or with occluder_margin_m = 0, is not cut; a door in
    full view beside the wall is not widened either (its box is no shorter than the door)."""
    cfg = load_config()
    T = np.eye(4)
    f = frame(depth=2.5)
    box = (300.0, 100.0, 350.0, 390.0)
    f.depth_m[:, :300] = 1.5
    assert occluded_sides(f.depth_m, box, 2.5, 0.15) == (True, False)
    below, above = f.depth_m.copy(), f.depth_m.copy()
    below[395:, :], above[:95, :] = 1.5, 1.5
    assert occluded_sides(below, box, 2.5, 0.15) == (True, False)  # the floor before an item hides nothing
    assert occluded_sides(above, box, 2.5, 0.15) == (True, True)  # a beam before its top does
    cut = localize(det(box, class_name="door"), f, cfg, T)
    off = localize(det(box, class_name="door"), f, apply_overrides(cfg, ["localize.occluder_margin_m=0"]), T)
    z = float(cut.position_cam[2])
    hid = 500.0 * cfg.localize.types["door"].box_width_m / z - 50.0
    added = cut.Sigma_c[0, 0] - off.Sigma_c[0, 0]
    assert added == pytest.approx((0.5 * hid * z / 500.0) ** 2, rel=0.05)  # dX / du about z / fx
    assert cut.Sigma_c[1, 1] == pytest.approx(off.Sigma_c[1, 1], rel=1e-3)  # v: not cut
    assert cut.box_cut == (True, False) and off.box_cut == (False, False)
    f.depth_m[:, :300] = 2.45  # a recess, not an occluder
    recess = localize(det(box, class_name="door"), f, cfg, T)
    assert recess.Sigma_c[0, 0] == pytest.approx(off.Sigma_c[0, 0], rel=1e-9)
    assert recess.box_cut == (False, False)
    f.depth_m[:, :300] = 1.5
    full = (300.0, 100.0, 460.0, 390.0)  # 160 px: the whole leaf
    a = localize(det(full, class_name="door"), f, cfg, T)
    b = localize(det(full, class_name="door"), f, apply_overrides(cfg, ["localize.occluder_margin_m=0"]), T)
    assert a.Sigma_c[0, 0] == pytest.approx(b.Sigma_c[0, 0], rel=1e-9)
    with pytest.raises(ConfigError, match="localize.occluder_margin_m"):
        apply_overrides(cfg, ["localize.occluder_margin_m=-0.1"])


def test_a_cut_body_keeps_its_visible_parts_depth_and_a_cut_door_follows_its_plane():
    """Boxes at the bottom edge of an image whose depth slopes 2 mm a pixel down the image.
    An extinguisher (a body with relief, surface_to_center_m) cut there: its hidden part widens
    sigma_v but not the depth, which the slope of its visible part does not carry on to the
    hidden foot (the depth's added variance is under 2% of what the slope would give: close
    views cut at the foot came out at NEES 40-90 along the coupled axis). A door's leaf is the
    surface its depth reads: cut, its added variance follows the slope into the depth."""
    cfg = load_config()
    T = np.eye(4)
    f = frame(depth=1.0)
    rows = np.arange(K.height, dtype=np.float32)[:, None]
    f.depth_m[:] = 1.0 + 0.002 * (rows - 390.0)
    no_size = ["localize.types.fire-extinguisher.box_height_m=null", "localize.types.door.box_height_m=null"]
    box = (270.0, 300.0, 370.0, 480.0)
    cut = localize(det(box, class_name="fire-extinguisher"), f, cfg, T)
    uncut = localize(det(box, class_name="fire-extinguisher"), f, apply_overrides(cfg, no_size), T)
    z = float(cut.position_cam[2])
    hid = 500.0 * cfg.localize.types["fire-extinguisher"].box_height_m / z - 180.0
    assert hid > 50.0
    added = cut.Sigma_c - uncut.Sigma_c
    assert added[1, 1] == pytest.approx((0.5 * hid * z / 500.0) ** 2, rel=0.1)
    assert added[2, 2] < 0.02 * (0.002 * 0.5 * hid) ** 2
    door_box = (270.0, 120.0, 370.0, 480.0)
    door = localize(det(door_box, class_name="door"), f, cfg, T)
    door_uncut = localize(det(door_box, class_name="door"), f, apply_overrides(cfg, no_size), T)
    hid_door = 500.0 * cfg.localize.types["door"].box_height_m / float(door.position_cam[2]) - 360.0
    assert hid_door > 50.0
    assert door.Sigma_c[2, 2] - door_uncut.Sigma_c[2, 2] == pytest.approx((0.002 * 0.5 * hid_door) ** 2, rel=0.15)


def test_type_shapes_are_checked_at_load():
    """Each row of localize.types is checked at load, its error naming the key."""
    cfg = load_config()
    with pytest.raises(
        ConfigError, match=r"localize.types.qr.box_width_m: a flat shape: its cut is judged by its"
    ):
        apply_overrides(cfg, ["localize.types.qr.box_width_m=0.2"])
    with pytest.raises(ConfigError, match=r"localize.types.valve.box_height_m: expected a value > 0"):
        apply_overrides(cfg, ["localize.types.valve.box_height_m=-0.2"])
    with pytest.raises(ConfigError, match=r"localize.types.qr.shape: a leaf needs box_width_m or box_height_m"):
        apply_overrides(cfg, ["localize.types.qr={shape: leaf}"])
    with pytest.raises(ConfigError, match=r"localize.types.valve.aspect: a turned-square shape needs its width"):
        apply_overrides(cfg, ["localize.types.valve={shape: turned-square}"])
    with pytest.raises(ConfigError, match=r"localize.types.valve.shape: expected one of 'flat', 'turned-square'"):
        apply_overrides(cfg, ["localize.types.valve.shape=cube"])
    with pytest.raises(ConfigError, match=r"localize.types.valve.radius_m: unknown key"):
        apply_overrides(cfg, ["localize.types.valve.radius_m=0.1"])
    # a row given whole; a number of a row set alone
    valve = apply_overrides(cfg, ["localize.types.valve={shape: body, box_width_m: 0.3}"]).localize.types["valve"]
    assert (valve.box_width_m, valve.box_height_m, valve.surface_to_center_m) == (0.3, None, 0.0)
    assert apply_overrides(cfg, ["localize.types.door.box_width_m=0.8"]).localize.types["door"].box_width_m == 0.8


def test_the_depth_plane_takes_a_depth_image_that_only_slices_whole_pixels():
    """A replay's depth (eval.trial.perception_cache.TiledDepth) takes slices without a step;
    a large box's plane is fitted on a grid taken after slicing."""

    class NoStep:
        def __init__(self, a: np.ndarray) -> None:
            self.a, self.shape = a, a.shape

        def __getitem__(self, key):
            if any(isinstance(k, slice) and k.step not in (None, 1) for k in key):
                raise IndexError("slices with a step are not supported")
            return self.a[key]

    depth = _wall(1.0, 0.002, 0.0, np.random.default_rng(0))
    pl = box_depth_plane(NoStep(depth), (0.0, 0.0, 640.0, 480.0), 1.0)  # 307200 pixels: a grid
    assert pl.g_u == pytest.approx(0.002, rel=1e-4) and abs(pl.g_v) < 1e-6


def _tilted_wall_depth(tilt_deg: float, d0: float = 2.0) -> np.ndarray:
    """Depth (K) of a wall through (0, 0, d0) turned tilt_deg about the camera's vertical axis:
    z = d0 / (1 + tan(tilt) x) for the ray (x, y, 1)."""
    x = (np.arange(K.width) - K.ppx) / K.fx
    z = d0 / (1.0 + np.tan(np.deg2rad(tilt_deg)) * x)
    return np.tile(z.astype(np.float32), (K.height, 1))


def test_a_sign_seen_steeply_is_foreshortened_not_cut():
    """A 0.3 m qr code at 2 m on a wall turned 75 degrees: its box is about 20 x 80 px, too narrow
    for the inner box's plane to fix the tilt. Judged face-on (flat_tilt_sigmas huge: the
    shrink reaches 0) it looks cut to a quarter, though nothing beside it hides it; judged
    on the whole box's plane, at most 2 sigmas less tilted, it is whole and that axis is a few
    cm. The same box on a face-on wall is a cut sign, as before."""
    cfg = load_config()
    tilt = np.deg2rad(75.0)
    c = np.array([0.0, 0.0, 2.0])
    along = np.array([np.cos(tilt), 0.0, -np.sin(tilt)])  # on the wall, horizontal
    corners = [c + a * 0.15 * along + np.array([0.0, b * 0.15, 0.0]) for a in (-1, 1) for b in (-1, 1)]
    uv = np.array([project_point_to_pixel(K, p) for p in corners])
    box = (uv[:, 0].min() + 0.5, uv[:, 1].min() + 0.5, uv[:, 0].max() + 0.5, uv[:, 1].max() + 0.5)
    assert box[2] - box[0] < 0.3 * (box[3] - box[1])  # foreshortened to about a quarter
    f = frame()
    f.depth_m = _tilted_wall_depth(75.0)
    T = np.eye(4)
    steep = localize(det(box, class_name="qr"), f, cfg, T)
    face_on_rule = localize(
        det(box, class_name="qr"), f, apply_overrides(cfg, ["localize.flat_tilt_sigmas=1000000"]), T
    )
    widest = lambda o: float(np.sqrt(np.linalg.eigvalsh(o.Sigma_c)[-1]))  # noqa: E731
    assert widest(face_on_rule) < 0.05  # nothing beside it hides it
    assert widest(steep) < 0.05
    assert np.linalg.norm(steep.position_cam - c) < 0.03
    # a face-on wall with a nearer wall beside the box: the narrow box is the visible quarter of
    # a cut sign, sigma_u grows by half the rest
    wall = frame(depth=2.0)
    wall.depth_m[:, : int(box[0]) - 1] = 1.5
    cut = localize(det(box, class_name="qr"), wall, cfg, T)
    w, h = box[2] - box[0], box[3] - box[1]
    assert np.sqrt(cut.Sigma_c[0, 0]) * K.fx / 2.0 > 0.4 * (h - w)


def test_a_flat_items_depth_is_its_planes_at_the_box_centre_where_holes_lie_to_one_side():
    """A qr code on a wall turned 45 degrees at 1 m (depth rising 2 mm a pixel), its box 40 px
    at the image centre, the left 40% of its inner block holes (no depth: texture the stereo
    matcher cannot match). The median of the valid pixels is the depth 4 px right of the box
    centre, 8 mm too far; the depth plane through them reads the box centre's depth. A door, a
    3-D item, keeps the median."""
    slope = 0.002
    depth = _wall(1.0, slope, 0.0, np.random.default_rng(0))
    box = (300.0, 220.0, 340.0, 260.0)  # centre (u, v) = (ppx, ppy): depth 1 m there
    depth[230:250, 310:318] = 0.0  # the inner block is columns 310..329: its left 8 are holes
    f = frame()
    f.depth_m = depth
    cfg = load_config()
    on_plane = localize(det(box, class_name="qr"), f, cfg, np.eye(4))
    median = localize(det(box, class_name="door"), f, cfg, np.eye(4))
    assert on_plane.depth_m == pytest.approx(1.0, abs=1e-4)
    assert median.depth_m == pytest.approx(1.0 + 4 * slope, abs=1e-3)
