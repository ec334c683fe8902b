"""The common sensor interface (sim/sensors/base.py): each frame sensor's ``measure`` is its model
run on the shot with the frame's generator, each pose sensor's ``track`` its model on the true
motion; nothing is added on the way, so the simulator's frames stay what the models give."""

import numpy as np

from poi.core.geometry import make_transform
from poi.core.types import Intrinsics
from sim.sensors.base import Exposure, FrameSensor, PoseSensor, Shot, TrackerMotion
from sim.sensors.d435_color import ColourCamera, ColourSensor, ColourSpec
from sim.sensors.d435_depth import DepthSensor, DepthSpec, DepthTrial, simulate_depth
from sim.sensors.noise_pool import NoisePool
from sim.sensors.t265 import T265, T265Spec, pose_interpolator, simulate_t265
from sim.sensors.thermal import (
    ThermalSensor,
    ThermalSpec,
    ThermalView,
    make_thermal_scene,
    sample_grid,
    thermal_image,
)
from sim.sensors.wheel_odometry import WheelOdometry, WheelOdometrySpec, simulate_wheel_odometry

H, W = 48, 64
K = Intrinsics(width=W, height=H, fx=60.0, fy=60.0, ppx=31.5, ppy=23.5)
# optical (x right, y down, z forward) to world (x forward, y left, z up), camera 0.5 m up
T_WORLD_OPTICAL = make_transform(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]), [0, 0, 0.5])


def _shot(geoms: np.ndarray | None = None) -> Shot:
    rng = np.random.default_rng(3)
    return Shot(
        t_s=1.5,
        rgb=rng.integers(0, 256, (H, W, 3), dtype=np.uint8),
        gamma=2.2,
        z_m=rng.uniform(0.5, 4.0, (H, W)).astype(np.float32),
        T_world_optical=T_WORLD_OPTICAL,
        exposure=Exposure(exposure_ms=4.0, gain=2.0),
        motion_px=(3.0, 1.0),
        geom_ids=lambda: geoms,
    )


def test_each_frame_sensor_is_its_model_on_the_shot():
    shot = _shot(np.zeros((H, W), np.int32))
    pool = NoisePool.standard_normal([1, 2, 3], 3 * H * W * 3)
    camera = ColourCamera(ColourSpec(), W, H, K.fx, K.fy, K.ppx, K.ppy)
    trial = DepthTrial.draw(DepthSpec(), (H, W), np.random.default_rng(4))
    scene = make_thermal_scene(
        ThermalSpec(width=16, height=12), np.random.default_rng(5), np.zeros(2), np.zeros(1, bool)
    )
    sensors: list[FrameSensor] = [
        ColourSensor(camera=camera, lux=500.0, pool=pool, effects=True),
        DepthSensor(spec=DepthSpec(), fx_color_px=K.fx, noise=True, pool=pool, trial=trial),
        ThermalSensor(
            spec=ThermalSpec(width=16, height=12),
            noise=True,
            intrinsics=K,
            temp_of_geom=np.array([np.nan]),
            scene=scene,
        ),
    ]
    rng = np.random.default_rng(7)
    got = {s.frame_field: s.measure(shot, rng) for s in sensors}

    rng = np.random.default_rng(7)  # the same draws, in the same order
    rgb = camera.render(shot.rgb, shot.exposure, 500.0, rng=rng, pool=pool, motion_px=shot.motion_px, effects=True)
    depth = simulate_depth(shot.z_m, DepthSpec(), K.fx, rng, True, pool, rgb=shot.rgb, gamma=2.2, trial=trial)
    # the thermal camera's 16 x 12 pixels integrate 2 x 2 samples each of the 64 x 48 renders
    view = ThermalView.from_depth(shot.z_m, K, T_WORLD_OPTICAL, 32, 24)
    geoms = sample_grid(np.zeros((H, W), np.int32), 32, 24)
    thermal = thermal_image(
        geoms, np.array([np.nan]), ThermalSpec(width=16, height=12), rng, True, scene=scene, view=view, t_s=1.5
    )
    assert list(got) == ["rgb", "depth_m", "thermal_c"]
    assert np.array_equal(got["rgb"], rgb) and np.array_equal(got["depth_m"], depth)
    assert np.array_equal(got["thermal_c"], thermal)


def test_each_pose_sensor_is_its_model_on_the_true_motion():
    t_s = np.arange(0.0, 5.0, 0.1)
    poses = [make_transform(np.eye(3), [0.3 * t, 0.0, 0.0]) for t in t_s]
    motion = TrackerMotion(times_s=t_s, poses=poses, poses_at=pose_interpolator(t_s, poses))
    for sensor, direct in (
        (
            T265(spec=T265Spec(), noise=True),
            lambda rng: simulate_t265(motion.poses_at, t_s, T265Spec(), rng, True),
        ),
        (
            WheelOdometry(spec=WheelOdometrySpec(), noise=True),
            lambda rng: simulate_wheel_odometry(poses, t_s, WheelOdometrySpec(), rng, True),
        ),
    ):
        ps: PoseSensor = sensor
        a, b = ps.track(motion, np.random.default_rng(2)), direct(np.random.default_rng(2))
        assert np.array_equal(np.array(a.poses), np.array(b.poses)) and a.confidence == b.confidence
