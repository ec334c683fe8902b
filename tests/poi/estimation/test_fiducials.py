"""The fiducial mapper (poi.estimation.fiducials) on depth images ray-cast by hand: a wall at
x = 1 m with a half-pipe of radius 0.15 m centred on it at y = 0, seen from two places."""

from __future__ import annotations

import numpy as np
import pytest

from poi.config import FiducialConfig
from poi.core.types import Frame, Intrinsics
from poi.estimation.fiducials import FiducialMapper

K = Intrinsics(width=160, height=120, fx=110.0, fy=110.0, ppx=79.5, ppy=59.5)
R_PIPE, WALL_X, H_CAM = 0.15, 1.0, 0.3


def _depth(cam_xy: tuple[float, float], top_m: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The z-depth image of a camera at (x, y, 0.3) looking along +x (optical z = map x, optical
    x = map -y, optical y = map -z), with the pipe ``top_m`` tall, and its T_map_camera."""
    v, u = np.mgrid[0 : K.height, 0 : K.width].astype(float)
    d = np.stack([(u - K.ppx) / K.fx, (v - K.ppy) / K.fy, np.ones_like(u)], axis=-1)  # optical rays, z = 1
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # optical -> map
    D = d @ R.T  # (H, W, 3) map directions with x component 1
    o = np.array([cam_xy[0], cam_xy[1], H_CAM])
    t = np.full(u.shape, np.inf)
    t_wall = (WALL_X - o[0]) / D[..., 0]  # the wall plane
    t = np.where((t_wall > 0) & (o[2] + t_wall * D[..., 2] <= 1.2), t_wall, t)
    t_floor = np.where(D[..., 2] < 0, -o[2] / np.minimum(D[..., 2], -1e-12), np.inf)
    t = np.minimum(t, t_floor)
    # the pipe: (x - 1)^2 + y^2 = r^2, x <= 1, 0 <= z <= top_m; nearest root
    a = D[..., 0] ** 2 + D[..., 1] ** 2
    b = 2 * ((o[0] - WALL_X) * D[..., 0] + o[1] * D[..., 1])
    c = (o[0] - WALL_X) ** 2 + o[1] ** 2 - R_PIPE**2
    disc = b * b - 4 * a * c
    t_pipe = np.where(disc >= 0, (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a), np.inf)
    z = o[2] + t_pipe * D[..., 2]
    x = o[0] + t_pipe * D[..., 0]
    t_pipe = np.where((t_pipe > 0) & (z >= 0) & (z <= top_m) & (x <= WALL_X), t_pipe, np.inf)
    t = np.minimum(t, t_pipe)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, o
    return np.where(np.isfinite(t), t, 0.0).astype(np.float32), T  # z-depth = t (ray z = 1)


def test_a_half_pipe_on_a_wall_is_found_at_its_axis() -> None:
    m = FiducialMapper(FiducialConfig(enabled=True, every_n_frames=1, stride_px=1, min_hits=1))
    for k, xy in enumerate([(0.0, -0.4), (0.0, 0.4), (0.2, 0.0)]):
        depth, T = _depth(xy)
        m.add(Frame(index=k, timestamp_s=float(k), rgb=np.zeros((K.height, K.width, 3), np.uint8),
                    intrinsics=K, depth_m=depth, pose=T), T)  # fmt: skip
    (fit,) = m.fits()
    assert (fit.x, fit.y) == pytest.approx((WALL_X, 0.0), abs=0.03)  # 2 cm cells
    assert fit.radius_m == pytest.approx(R_PIPE, abs=0.03) and fit.first_seen_s == 0.0
    (snap,) = m.landmarks(start_id=7)
    assert (snap.report_id, snap.type, snap.confirmed) == (7, "fiducial", True)
    assert snap.position_map[2] == 0.25


def test_a_bare_wall_has_no_fiducial() -> None:
    m = FiducialMapper(FiducialConfig(enabled=True, every_n_frames=1, stride_px=1, min_hits=1))
    global R_PIPE
    saved, R_PIPE = R_PIPE, 1e-6
    try:
        depth, T = _depth((0.0, 0.0))
    finally:
        R_PIPE = saved
    m.add(Frame(index=0, timestamp_s=0.0, rgb=np.zeros((K.height, K.width, 3), np.uint8), intrinsics=K,
                depth_m=depth, pose=T), T)  # fmt: skip
    assert m.fits() == []


def test_the_pipeline_reports_fiducials_only_when_asked() -> None:
    from poi.config import apply_overrides, load_config
    from poi.pipeline import Pipeline

    base = load_config()
    # the camera is the tracker here: an identity mount
    sets = [
        "mount.T_tracker_camera.translation_m=[0, 0, 0]",
        "mount.T_tracker_camera.quaternion_wxyz=[1, 0, 0, 0]",
    ]
    sets += ["fiducials.every_n_frames=1", "fiducials.stride_px=1", "fiducials.min_hits=1"]
    off = Pipeline(apply_overrides(base, sets), [])
    on = Pipeline(apply_overrides(base, [*sets, "fiducials.enabled=true"]), [])
    for k, xy in enumerate([(0.0, -0.4), (0.0, 0.4), (0.2, 0.0)]):
        depth, T = _depth(xy)
        frame = Frame(index=k, timestamp_s=float(k), rgb=np.zeros((K.height, K.width, 3), np.uint8), intrinsics=K,
                      depth_m=depth, pose=T)  # fmt: skip
        off.process(frame)
        res = on.process(frame)
        assert "fiducials" in res.timing_ms
    assert off.landmarks() == []
    (snap,) = on.landmarks()
    assert snap.report_id == 0 and snap.position_map[:2] == pytest.approx([WALL_X, 0.0], abs=0.03)


def test_something_round_but_low_is_not_a_fiducial() -> None:
    # the same half-pipe cut to 0.2 m: nothing of it reaches the top of the low band (0.30-0.42 m)
    m = FiducialMapper(FiducialConfig(enabled=True, every_n_frames=1, stride_px=1, min_hits=1))
    for k, xy in enumerate([(0.0, -0.4), (0.0, 0.4), (0.2, 0.0)]):
        depth, T = _depth(xy, top_m=0.2)
        m.add(Frame(index=k, timestamp_s=float(k), rgb=np.zeros((K.height, K.width, 3), np.uint8),
                    intrinsics=K, depth_m=depth, pose=T), T)  # fmt: skip
    assert m.fits() == []
