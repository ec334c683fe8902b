"""A trial's world in motion: the maze, its objects, the robot's route and the sensor frames.

``Simulation(scenario)`` builds everything from the scenario and its seed;
``frames()`` yields ``(Frame, FrameTruth)`` pairs: the ``Frame`` is all the
pipeline may see, the ``FrameTruth`` (true poses, visible objects with their
boxes, visible fraction and true camera-frame position) is kept apart for
scoring, the oracle detector and datasets.

Randomness: the scenario seed makes one ``np.random.Generator`` for building the
world (maze and placement, or the goal arena's layout; lighting; T265 drift or wheel
odometry errors) and, for sensor noise, one generator per frame from
``SeedSequence([seed, 1, k])``, so frame k is the same whichever frames are rendered;
the thermal camera's fixed patterns and air gradient come from ``SeedSequence([seed, 3])``.

Tracker frame: ``Frame.pose`` is the pose of the tracker frame, the T265 (mounted
relative to the camera by ``sensors.mount``) or, with ``sensors.pose_source: wheels``,
the robot base (on the floor under the camera, x forward), whose odometry the pipeline
then gets. ``T_tracker_optical_nominal`` is the camera mount the pipeline is told.

Threads: the OpenGL context lives on one worker thread per simulation, where
every frame is made; ``frames()`` keeps a couple of frames in flight there
while the caller runs the pipeline on the previous one (MuJoCo's renderer and
numpy release the GIL, so the two overlap on two cores).
"""

from __future__ import annotations

import itertools
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import TypeVar

import cv2
import mujoco
import numpy as np

import sim.gl  # noqa: F401  (sim/__init__ has chosen the GL backend already)
from maze_assets.models import FLAT_TYPES, body_rotation, reference_point
from maze_assets.objects import PlacedObject
from poi.core.geometry import (
    R_BODY_OPTICAL,
    invert_transform,
    make_transform,
    rot_x,
    rot_y,
    rot_z,
    transform_points,
)
from poi.core.motion_blur import image_motion_px
from poi.core.types import Frame, Intrinsics
from sim.camera import T_RIG_OPTICAL
from sim.memory import keep_freed_memory
from sim.motion.arena_route import arena_route
from sim.motion.route import TURTLEBOT_CAMERA_HEIGHT_M, Route, load_route_csv, rig_pose, route_from_tour
from sim.motion.tour import plan_tour
from sim.render import SceneRenderer
from sim.scenario import MountSpec, Scenario
from sim.sensors.base import Exposure, FrameSensor, PoseSensor, PoseTrack, Shot, TrackerMotion
from sim.sensors.d435_color import (
    ColourCamera,
    ColourSensor,
    ColourSpec,
    ae_history_frames,
    lagged_exposure,
    meter,
    steady_state_exposure,
)
from sim.sensors.d435_depth import DepthSensor, DepthTrial
from sim.sensors.noise_pool import NoisePool
from sim.sensors.t265 import T265, TrackingConditions
from sim.sensors.thermal import ThermalScene, ThermalSensor, make_thermal_scene
from sim.sensors.tracking_conditions import drift_multiplier, scene_lux, texture_contrast
from sim.sensors.wheel_odometry import WheelOdometry
from sim.world.arena import ArenaLayout, generate_arena
from sim.world.maze import (
    PRESETS,
    find_maze,
    load_maze,
)
from sim.world.maze_gen import generate_maze
from sim.world.placement import (
    assign_placard_looks,
    hang_placard_boards,
    hang_placards_on_doors,
    lay_placards_on_floor,
    lay_placards_on_ramps,
    place_objects,
    put_placards_in_crates,
)
from sim.world.world import (
    CAMERA_NAME,
    LIGHT_LEVEL_LUX,
    SceneLooks,
    World,
    build_world,
    door_gap_m,
    lux_of_decoded_one,
)

SENSOR_STREAM = 1
THERMAL_STREAM = 3  # the thermal camera's per-run draws: gradient direction, fixed patterns
ARENA_LIGHT_HEIGHT_M = 2.5  # the goal arena's lamps hang from a room's ceiling, not over low walls
PREFETCH_FRAMES = 2  # frames rendered ahead by Simulation.frames()
AE_CACHE_FRAMES = 16  # auto-exposure meters kept for the frames that follow
NOISE_POOL_FRAMES = 3  # frames' worth of pre-drawn noise per pool (sim.sensors.noise_pool)


_R = TypeVar("_R")


@dataclass(kw_only=True)
class TruthObject:
    """A POI as the ground truth file lists it: position in the map frame."""

    id: int
    type: str
    text: str
    position_map: np.ndarray
    placed: PlacedObject


@dataclass(kw_only=True)
class VisibleObject:
    id: int
    type: str
    text: str
    box_xyxy: tuple[float, float, float, float]
    pixels: int
    visible_fraction: float
    position_cam: np.ndarray  # true position in the camera optical frame
    # angle between a flat item's face normal and the ray from it to the camera (0: seen face-on);
    # NaN for a 3-D object, which has no one face
    view_angle_deg: float = float("nan")


@dataclass(kw_only=True)
class VisiblePage:
    """What shows of a QR chart's A4 page (its sheet and the codes printed on it): a detector
    may box the whole page as one code, a box that no code's truth box pairs with."""

    codes: tuple[int, ...]  # object ids of the codes printed on the page
    box_xyxy: tuple[float, float, float, float]
    pixels: int


@dataclass(kw_only=True)
class ColourDepthRender:
    """One rasterisation of frame k's view."""

    rgb: np.ndarray  # (H, W, 3) uint8
    z_m: np.ndarray  # (H, W) float32 true z-depth; sky reads far beyond any sensor range
    T_map_optical: np.ndarray


@dataclass(kw_only=True)
class SegmentationRender:
    """One segmentation pass of frame k's view at the colour camera's size: its geom ids (the
    thermal camera's input) and, with truth boxes, the object ids they belong to."""

    geom_ids: np.ndarray | None  # (H, W) int32 geom id, -1 for none
    object_ids: np.ndarray | None  # (H, W) int32 object id, -1 for none; only with truth boxes


@dataclass(kw_only=True)
class FrameTruth:
    index: int
    timestamp_s: float
    T_map_camera: np.ndarray  # true optical frame pose
    T_map_tracker: np.ndarray  # true tracker pose
    visible: list[VisibleObject]
    object_mask: np.ndarray | None = None  # (H, W) object id per pixel, -1 elsewhere
    # pixels the image centre moved during the colour exposure (the motion blur's length); 0 without it
    blur_px: float = 0.0
    pages: list[VisiblePage] = field(default_factory=list)  # QR chart pages in view (with truth boxes)


def _regions(label_map: np.ndarray) -> list[tuple[int, tuple[float, float, float, float], int]]:
    """(label, box xyxy in pixels, pixel count) of every label >= 0 in ``label_map``, in label order."""
    ys, xs = np.nonzero(label_map >= 0)
    ids = label_map[ys, xs]
    out = []
    for label in np.unique(ids):
        sel = ids == label
        px, py = xs[sel], ys[sel]
        box = (float(px.min()), float(py.min()), float(px.max() + 1), float(py.max() + 1))
        out.append((int(label), box, int(sel.sum())))
    return out


def _rpy(deg) -> np.ndarray:
    """Rotation of roll, pitch, yaw (degrees): Rz(yaw) Ry(pitch) Rx(roll)."""
    a = np.deg2rad(deg)
    return rot_z(a[2]) @ rot_y(a[1]) @ rot_x(a[0])


def mount_transforms(m: MountSpec) -> tuple[np.ndarray, np.ndarray]:
    """(nominal, true) T_tracker_optical: p_tracker = Q0 p_c + t0."""
    nominal = make_transform(_rpy(m.rpy_deg) @ R_BODY_OPTICAL, m.t_m)
    error = make_transform(_rpy(m.error_rpy_deg), m.error_t_m)
    return nominal, error @ nominal


def base_mount_transforms(height_m: float, tilt_rad: float, m: MountSpec) -> tuple[np.ndarray, np.ndarray]:
    """(nominal, true) T_base_optical of a camera fixed ``height_m`` above the base, tilted
    up by ``tilt_rad``; the true one carries ``m``'s ``error_*`` (as :func:`mount_transforms`)."""
    # the rig above the base (sim.motion.route.rig_pose with no pan), then rig -> optical
    nominal = make_transform(rot_y(-tilt_rad) @ R_BODY_OPTICAL, [0.0, 0.0, height_m])
    error = make_transform(_rpy(m.error_rpy_deg), m.error_t_m)
    return nominal, error @ nominal


def default_mast_height_m(cell_size_m: float) -> float:
    return 0.5 if cell_size_m >= 0.6 else 0.2


class Simulation:
    def __init__(self, scenario: Scenario, *, looks: SceneLooks | None = None) -> None:
        """``looks``: a training scene's (sim.world.world.SceneLooks; poibench dataset), never a trial's."""
        # every frame allocates and frees the same few dozen images: keep them in the process
        # instead of faulting their pages in anew each frame (sim/memory.py)
        keep_freed_memory()
        self.scenario = sc = scenario
        rng = np.random.default_rng(sc.seed)
        self.arena: ArenaLayout | None = None
        if sc.arena is not None:
            self.arena = generate_arena(sc.arena.generate, rng, name=f"arena-{sc.seed}")
            self.maze = self.arena.floor
            self.objects = self.arena.objects
            start_xy, start_yaw = self.arena.start_xy, self.arena.start_yaw_rad
        else:
            if sc.maze.file is not None:
                self.maze = load_maze(find_maze(sc.resolve(sc.maze.file)))
            else:
                g = sc.maze.generate
                self.maze = generate_maze(
                    g.rows,
                    g.cols,
                    rng,
                    loop_fraction=g.loop_fraction,
                    settings=PRESETS[g.preset],
                    name=f"generated-{sc.seed}",
                )
            self.objects = place_objects(sc.objects, self.maze, rng)
            if sc.objects.generate is not None:
                generated = self.objects[len(sc.objects.explicit) :]
                gen = sc.objects.generate
                lay_placards_on_floor(generated, gen.hazmat_on_floor, sc.seed, self.maze)
                hang_placards_on_doors(generated, gen.hazmat_on_doors, sc.seed, self.maze)
                put_placards_in_crates(generated, gen.hazmat_in_crates, sc.seed, self.maze)
                lay_placards_on_ramps(generated, gen.hazmat_on_ramps, sc.seed, self.maze)
                hang_placard_boards(generated, gen.hazmat_on_boards, sc.seed, self.maze)
            start_xy, start_yaw = self.maze.cell_center(*self.maze.start_cell), self.maze.start_heading_rad
        assign_placard_looks(self.objects, sc.seed)
        d = sc.sensors.d435
        self.intrinsics = Intrinsics(width=d.width, height=d.height, fx=d.fx, fy=d.fy, ppx=d.ppx, ppy=d.ppy)
        th = sc.sensors.thermal
        self.thermal_intrinsics = self.intrinsics.scaled(th.width, th.height)
        self.world: World = build_world(
            self.maze,
            self.objects,
            self.intrinsics,
            sc.lighting,
            rng,
            obstacles=self.arena.obstacles if self.arena is not None else (),
            light_height_m=ARENA_LIGHT_HEIGHT_M if self.arena is not None else None,
            clutter_per_cell=sc.clutter_per_cell,
            shadows=sc.shadows,
            looks=looks,
        )

        self.T_world_map = make_transform(rot_z(start_yaw), [float(start_xy[0]), float(start_xy[1]), 0.0])
        self.T_map_world = invert_transform(self.T_world_map)
        if sc.robot.route == "tour":
            cells = plan_tour(self.maze, self.maze.start_cell)
            self.route: Route = route_from_tour(self.maze, cells, sc.robot, self.maze.start_heading_rad)
        elif sc.robot.route == "arena":
            self.route = arena_route(self.arena, sc.robot)
        else:
            self.route = load_route_csv(sc.resolve(sc.robot.route), self.T_world_map)
        turtlebot = sc.robot.kind == "turtlebot"
        if turtlebot:  # the camera is fixed to the base: no pan, whatever the route file says
            self.route = replace(self.route, pan_rad=None, pan_amplitude_rad=0.0)
        if sc.robot.mast_height_m is not None:
            self.mast_height_m = sc.robot.mast_height_m
        elif turtlebot:
            self.mast_height_m = TURTLEBOT_CAMERA_HEIGHT_M
        else:
            self.mast_height_m = default_mast_height_m(self.maze.settings.cell_size_m)
        duration = self.route.duration_s
        if sc.robot.max_duration_s is not None:
            duration = min(duration, sc.robot.max_duration_s)
        self.times_s = np.arange(0.0, duration + 1e-9, 1.0 / sc.sensors.fps)
        tilt = np.deg2rad(sc.robot.tilt_deg)
        self._tilt_rad = tilt
        wheels = sc.sensors.pose_source == "wheels"
        if wheels:  # the tracker frame is the base, the camera fixed above it
            mounts = base_mount_transforms(self.mast_height_m, tilt, sc.sensors.mount)
        else:
            mounts = mount_transforms(sc.sensors.mount)
        self.T_tracker_optical_nominal, self.T_tracker_optical_true = mounts
        T_rig_tracker = T_RIG_OPTICAL @ invert_transform(self.T_tracker_optical_true)
        self._T_rig_tracker = T_rig_tracker
        self._T_map_rig = [
            self.T_map_world @ rig_pose(self.route, t, self.mast_height_m, tilt) for t in self.times_s
        ]
        self.T_map_tracker_true = [T @ T_rig_tracker for T in self._T_map_rig]
        self.tracking_conditions: TrackingConditions | None = None  # the T265's only
        if wheels:
            self.pose_sensor: PoseSensor = WheelOdometry(spec=sc.sensors.wheel_odometry, noise=sc.sensors.noise)
        else:
            self.tracking_conditions = self._tracking_conditions()
            self.pose_sensor = T265(
                spec=sc.sensors.t265, noise=sc.sensors.noise, conditions=self.tracking_conditions
            )
        motion = TrackerMotion(times_s=self.times_s, poses=self.T_map_tracker_true, poses_at=self._tracker_poses)
        self.pose_track: PoseTrack = self.pose_sensor.track(motion, rng)
        self._temp_of_geom = self._geom_temperatures()
        self._thermal_scene = self._make_thermal_scene() if sc.sensors.thermal.enabled else None
        self.colour_lux = self._decoded_one_lux(sc.sensors.d435.colour)
        self._meters: dict[int, float] = {}  # frame index -> auto-exposure meter of its render
        # FrameTruth.visible and .object_mask come from the full-size segmentation render's object
        # ids (the visible objects' boxes about 1 ms of CPU a frame); off, the render is still made
        # for the thermal camera's geom ids when that camera is on
        self.truth_boxes: bool = sc.sensors.truth_boxes
        # each geom's object (-1: none), with a -1 appended that background's geom id -1 picks
        self._object_of_geom = np.append(self.world.geom_box_object_id, -1).astype(np.int32)
        self._page_of_geom, self._page_codes = self._qr_pages()
        self._tilt_rad = tilt
        self._renderer: SceneRenderer | None = None
        self._gl_thread: ThreadPoolExecutor | None = ThreadPoolExecutor(1, thread_name_prefix="poibench-gl")
        self._pools: tuple[NoisePool | None, NoisePool | None] = (
            self._noise_pools() if sc.sensors.noise else (None, None)
        )
        # the colour stream (its auto-exposure and motion blur are the simulator's: they read other
        # frames' renders and the route), then the other frame sensors in their drawing order
        self.colour: ColourSensor = self._colour_sensor(sc.sensors.d435.colour, self._pools[0])
        self.sensors: list[FrameSensor] = self._frame_sensors()
        self._object_corners_world = self._object_geom_corners()
        # objects never move: each one's reference point (world frame), once
        self._reference_world = {o.id: reference_point(o) for o in self.objects}
        self._face_normal_world = {o.id: body_rotation(o).apply([1.0, 0.0, 0.0]) for o in self.objects}
        self._model_thread: ThreadPoolExecutor | None = ThreadPoolExecutor(
            1, thread_name_prefix="poibench-sensors"
        )

    # ------------------------------------------------------------------ truth
    def truth_objects(self) -> list[TruthObject]:
        return [
            TruthObject(
                id=o.id,
                type=o.type,
                text=o.text,
                position_map=transform_points(self.T_map_world, self._reference_world[o.id]),
                placed=o,
            )
            for o in self.objects
        ]

    def walls_in_map(self) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """Wall pieces as map-frame 2D segments, for map plots; a door's piece is drawn as
        the wall either side of its frame; the goal arena's obstacles by their outlines."""
        doors = {o.wall: o for o in self.objects if o.type == "door" and o.wall}
        out = []
        for seg in self.maze.wall_segments():
            p0, p1 = np.array([seg.x0, seg.y0, 0.0]), np.array([seg.x1, seg.y1, 0.0])
            spans = [(p0, p1)]
            if seg.name in doors:
                length = float(np.linalg.norm(p1 - p0))
                a, b, _ = door_gap_m(length, doors[seg.name], self.maze.settings.wall_height_m)
                d = (p1 - p0) / length
                spans = [(p0, p0 + d * a), (p0 + d * b, p1)]
            for q0, q1 in spans:
                if np.linalg.norm(q1 - q0) <= 1e-6:
                    continue
                a2 = transform_points(self.T_map_world, q0)
                b2 = transform_points(self.T_map_world, q1)
                out.append(((float(a2[0]), float(a2[1])), (float(b2[0]), float(b2[1]))))
        for ob in self.arena.obstacles if self.arena is not None else ():
            c = np.c_[ob.corners(), np.zeros(4)]  # (4, 3) on the floor
            m = transform_points(self.T_map_world, c)
            for i in range(4):
                a2, b2 = m[i], m[(i + 1) % 4]
                out.append(((float(a2[0]), float(a2[1])), (float(b2[0]), float(b2[1]))))
        return out

    def robot_path_map(self) -> np.ndarray:
        """(N, 2) true base positions at the frame times, in the map frame."""
        pts = []
        for t in self.times_s:
            x, y, _ = self.route.base_pose(float(t))
            pts.append(transform_points(self.T_map_world, np.array([x, y, 0.0]))[:2])
        return np.array(pts)

    @property
    def n_frames(self) -> int:
        return len(self.times_s)

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1]) if len(self.times_s) else 0.0

    # ------------------------------------------------------------------- T265
    def _tracker_poses(self, t: np.ndarray) -> np.ndarray:
        """True T_map_tracker at times ``t`` (n,): :func:`sim.motion.route.rig_pose` for many times at once."""
        t = np.asarray(t, dtype=float)
        r = self.route
        x, y, yaw = (np.interp(t, r.t_s, v) for v in (r.x_m, r.y_m, r.yaw_rad))
        pan = r.pans(t)
        tilt = self._tilt_rad + (np.zeros(len(t)) if r.tilt_rad is None else np.interp(t, r.t_s, r.tilt_rad))
        n = len(t)
        T_world_base = np.zeros((n, 4, 4))
        c, sn = np.cos(yaw), np.sin(yaw)
        T_world_base[:, 0, 0], T_world_base[:, 0, 1], T_world_base[:, 1, 0], T_world_base[:, 1, 1] = c, -sn, sn, c
        T_world_base[:, 2, 2] = T_world_base[:, 3, 3] = 1.0
        T_world_base[:, 0, 3], T_world_base[:, 1, 3] = x, y
        cp, sp = np.cos(pan), np.sin(pan)
        Rz_pan = np.zeros((n, 3, 3))
        Rz_pan[:, 0, 0], Rz_pan[:, 0, 1], Rz_pan[:, 1, 0], Rz_pan[:, 1, 1], Rz_pan[:, 2, 2] = cp, -sp, sp, cp, 1.0
        T_base_rig = np.zeros((n, 4, 4))
        ct, st = np.cos(-tilt), np.sin(-tilt)  # rot_y(-tilt) for each time
        Ry = np.zeros((n, 3, 3))
        Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = ct, st, 1.0, -st, ct
        T_base_rig[:, :3, :3] = Rz_pan @ Ry
        T_base_rig[:, 2, 3] = self.mast_height_m
        T_base_rig[:, 3, 3] = 1.0
        return self.T_map_world @ T_world_base @ T_base_rig @ self._T_rig_tracker

    def _tracking_conditions(self) -> TrackingConditions:
        """The T265's drift multiplier at the frame times, from the light and the wall and
        floor textures where the tracker is (sim/sensors/tracking_conditions.py)."""
        spec = self.scenario.sensors.t265.conditions
        p_world = np.array([(self.T_world_map @ T)[:3, 3] for T in self.T_map_tracker_true])
        m, d = self.world.model, self.world.data
        lux = scene_lux(m, d, self.scenario.lighting, p_world)
        contrast = texture_contrast(m, d, self.world.geom_object_id, p_world, spec.radius_m)
        return TrackingConditions(t_s=self.times_s, multiplier=drift_multiplier(lux, contrast, spec))

    # ---------------------------------------------------------------- render
    def _geom_material_names(self) -> list[str]:
        m = self.world.model
        return [
            (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_MATERIAL, int(mid)) or "") if mid >= 0 else ""
            for mid in m.geom_matid
        ]

    def _geom_temperatures(self) -> np.ndarray:
        """Each geom's own temperature (its object's, or a lamp panel's), NaN for "the air's
        where it is" (sim/sensors/thermal.py)."""
        temp = np.full(self.world.model.ngeom, np.nan)
        by_id = {o.id: o for o in self.objects}
        for g, (oid, mat) in enumerate(zip(self.world.geom_object_id, self._geom_material_names(), strict=True)):
            if oid >= 0 and by_id[int(oid)].temperature_c is not None:
                temp[g] = by_id[int(oid)].temperature_c
            elif mat == "hall_lamp":
                temp[g] = self.scenario.sensors.thermal.lamp_c
        return temp

    def _make_thermal_scene(self) -> ThermalScene:
        """The thermal model's per-run scene: metal geoms (steel materials of things with no
        temperature of their own), a static copy of the scene for reflected rays, and the
        gradient direction and fixed patterns from the seed's thermal stream."""
        m = self.world.model
        metal = np.array(
            [
                "steel" in name and not np.isfinite(t)
                for name, t in zip(self._geom_material_names(), self._temp_of_geom, strict=True)
            ]
        )
        data = mujoco.MjData(m)
        mujoco.mj_kinematics(m, data)
        w, h = self.maze.size_m
        rng = np.random.default_rng([self.scenario.seed, THERMAL_STREAM])
        return make_thermal_scene(self.scenario.sensors.thermal, rng, np.array([w / 2, h / 2]), metal, m, data)

    def _renderer_ready(self) -> SceneRenderer:
        if self._renderer is None:
            self._renderer = SceneRenderer(
                self.world.model, self.intrinsics.width, self.intrinsics.height, CAMERA_NAME
            )
        return self._renderer

    def on_gl_thread(self, fn: Callable[..., _R], *args) -> _R:
        """Run ``fn(*args)`` on the thread that owns the OpenGL context and wait for it.

        An OpenGL context is current on one thread only, so every render and every
        change to ``world.data`` happens on this simulation's own worker thread.
        """
        if self._gl_thread is None:
            raise RuntimeError("the simulation is closed")
        return self._gl_thread.submit(fn, *args).result()

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def close(self) -> None:
        if self._model_thread is not None:
            self._model_thread.shutdown(wait=True, cancel_futures=True)
            self._model_thread = None
        if self._gl_thread is not None:
            try:
                self._gl_thread.submit(self._close_renderer).result()
            finally:
                self._gl_thread.shutdown(wait=True, cancel_futures=True)
                self._gl_thread = None

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _set_camera(self, k: int | np.ndarray) -> np.ndarray:
        """Move the rig to frame k's pose (or to a given T_map_rig); returns T_map_optical."""
        T_map_rig = self._T_map_rig[k] if isinstance(k, (int, np.integer)) else np.asarray(k, float)
        T_world_rig = self.T_world_map @ T_map_rig
        m, d = self.world.model, self.world.data
        d.mocap_pos[self.world.rig_mocap_id] = T_world_rig[:3, 3]
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, T_world_rig[:3, :3].ravel())
        d.mocap_quat[self.world.rig_mocap_id] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        return T_map_rig @ T_RIG_OPTICAL

    def _render_colour_depth(self, k: int | np.ndarray) -> ColourDepthRender:
        """Colour and true z-depth of frame k from one rasterisation (GL thread)."""
        r = self._renderer_ready()
        T_map_optical = self._set_camera(k)
        r.update(self.world.data)
        rgb, depth = r.color_depth()
        return ColourDepthRender(rgb=rgb, z_m=depth, T_map_optical=T_map_optical)

    def _render_segmentation(self, k: int | np.ndarray) -> SegmentationRender:
        """One segmentation pass at full size when ground-truth boxes or the thermal camera are
        on (GL thread): geom ids, and object ids looked up from them for the truth boxes."""
        sens = self.scenario.sensors
        if not self.truth_boxes and not sens.thermal.enabled:
            return SegmentationRender(geom_ids=None, object_ids=None)
        r = self._renderer_ready()
        self._set_camera(k)
        r.update(self.world.data)
        geoms = r.geom_segmentation()
        objects = self._object_of_geom.take(geoms) if self.truth_boxes else None  # index -1: the -1 appended
        return SegmentationRender(geom_ids=geoms, object_ids=objects)

    def _submit_renders(self, k: int | np.ndarray) -> tuple[Future, Future]:
        """Queue the two render jobs of frame k (or of a rig pose T_map_rig) on the GL thread; the
        colour one comes back first, so the sensor models of colour and depth run while the
        segmentation renders."""
        if self._gl_thread is None:
            raise RuntimeError("the simulation is closed")
        return (
            self._gl_thread.submit(self._render_colour_depth, k),
            self._gl_thread.submit(self._render_segmentation, k),
        )

    def _noise_pools(self) -> tuple[NoisePool, NoisePool]:
        """(colour, depth) pools of pre-drawn noise from the scenario seed."""
        H, W = self.intrinsics.height, self.intrinsics.width
        seed = self.scenario.seed
        colour = NoisePool.standard_normal([seed, SENSOR_STREAM, 10**9], NOISE_POOL_FRAMES * H * W * 3)
        depth = NoisePool.standard_normal([seed, SENSOR_STREAM, 10**9 + 1], NOISE_POOL_FRAMES * H * W)
        return colour, depth

    def _frame_sensors(self) -> list[FrameSensor]:
        """The frame sensors, in the order they draw from a frame's generator: colour, then
        depth (with its per-trial draws from the seed), then thermal; those switched off left out."""
        sc = self.scenario
        d, noise = sc.sensors.d435, sc.sensors.noise
        sensors: list[FrameSensor] = [self.colour]
        if d.enabled:
            trial_rng = np.random.default_rng([sc.seed, SENSOR_STREAM, 10**9 + 2])
            trial = DepthTrial.draw(d.depth, (d.height, d.width), trial_rng)
            depth = DepthSensor(
                spec=d.depth, fx_color_px=self.intrinsics.fx, noise=noise, pool=self._pools[1], trial=trial
            )
            sensors.append(depth)
        if self._thermal_scene is not None:
            sensors.append(
                ThermalSensor(
                    spec=sc.sensors.thermal,
                    noise=noise,
                    intrinsics=self.intrinsics,
                    temp_of_geom=self._temp_of_geom,
                    scene=self._thermal_scene,
                )
            )
        return sensors

    def frame(self, k: int) -> tuple[Frame, FrameTruth]:
        """Frame k and its ground truth: rendered on the GL thread, sensor models on this one."""
        if not 0 <= k < self.n_frames:
            raise IndexError(f"frame {k} out of range 0..{self.n_frames - 1}")
        return self._sensor_frame(k, *self._submit_renders(k))

    def view(
        self,
        T_map_rig: np.ndarray,
        k: int,
        *,
        colour: ColourSpec | None = None,
        motion_px: tuple[float, float] | None = None,
    ) -> tuple[Frame, FrameTruth]:
        """A frame from an arbitrary rig pose (datasets), with frame k's sensor noise draws.

        The frame's pose is the true tracker pose (no T265 model: there is no
        trajectory), its timestamp 0. The colour camera's auto-exposure is settled (no
        history) and there is no motion blur unless ``motion_px`` gives the image's motion
        during the exposure; ``colour`` replaces the scenario's colour settings.
        """
        T_map_rig = np.asarray(T_map_rig, dtype=float)
        if T_map_rig.shape != (4, 4) or not np.all(np.isfinite(T_map_rig)):
            raise ValueError("view: T_map_rig must be a finite 4x4 transform")
        return self._sensor_frame(
            k, *self._submit_renders(T_map_rig), T_map_rig=T_map_rig, colour=colour, motion_px=motion_px
        )

    # ------------------------------------------------------------ colour camera
    def _colour_sensor(self, colour: ColourSpec, pool: NoisePool | None) -> ColourSensor:
        """The colour stream with ``colour``'s settings, under the scene's illuminance for them."""
        i = self.intrinsics
        camera = ColourCamera(colour, i.width, i.height, i.fx, i.fy, i.ppx, i.ppy)
        return ColourSensor(
            camera=camera, lux=self._decoded_one_lux(colour), pool=pool, effects=self.scenario.sensors.noise
        )

    def _decoded_one_lux(self, colour: ColourSpec) -> float:
        """The illuminance a decoded render value of 1 stands for with ``colour``: its ``lux``
        (default: the lighting preset's level) scaled by the preset's shading
        (:func:`sim.world.world.lux_of_decoded_one`)."""
        lighting = self.scenario.lighting
        lux = colour.lux if colour.lux is not None else LIGHT_LEVEL_LUX[lighting]
        return lux_of_decoded_one(lighting, lux, colour.gamma)

    def _steady_exposure(self, rgb: np.ndarray, spec: ColourSpec, lux: float) -> Exposure:
        if not spec.auto_exposure:
            return Exposure(exposure_ms=spec.exposure_ms, gain=spec.gain)
        return steady_state_exposure(meter(rgb, spec.gamma), spec, lux)

    def _meter(self, j: int, rgb: np.ndarray | None = None) -> float:
        """Frame j's auto-exposure meter (cached; rendered on the GL thread when not given)."""
        m = self._meters.get(j)
        if m is None:
            if rgb is None:
                rgb = self.on_gl_thread(self._render_colour_depth, j).rgb
            m = meter(rgb, self.scenario.sensors.d435.colour.gamma)
            self._meters[j] = m
            if len(self._meters) > 4 * AE_CACHE_FRAMES:
                for old in sorted(self._meters)[:-AE_CACHE_FRAMES]:
                    self._meters.pop(old, None)
        return m

    def exposure(self, k: int, rgb: np.ndarray | None = None) -> Exposure:
        """Frame k's exposure and gain: fixed, or the auto-exposure's lagged response to the
        meters of frames k, k - 1, ... (sim/sensors/d435_color.py); the same whichever frames
        were rendered before."""
        spec = self.scenario.sensors.d435.colour
        if not spec.auto_exposure:
            return Exposure(exposure_ms=spec.exposure_ms, gain=spec.gain)
        dt = 1.0 / self.scenario.sensors.fps
        n = ae_history_frames(spec.ae_time_constant_s, dt)
        steady = [
            steady_state_exposure(self._meter(j, rgb if j == k else None), spec, self.colour_lux)
            for j in range(k, max(k - n, -1), -1)
        ]
        return lagged_exposure(steady, spec, dt)

    def _rig_at(self, t_s: float) -> np.ndarray:
        """The rig's true pose in the world at time ``t_s`` of the route (mast and tilt included)."""
        return rig_pose(self.route, t_s, self.mast_height_m, self._tilt_rad)

    def motion_px(self, k: int, exposure_ms: float, z_m: np.ndarray) -> tuple[float, float]:
        """(du, dv) pixels the image centre moves during frame k's exposure (centred on the
        frame time), from the true rig poses and the median depth at the image centre."""
        t, half = float(self.times_s[k]), exposure_ms / 2000.0

        def pose(tt: float) -> np.ndarray:  # T_map_optical at time tt
            return self.T_map_world @ self._rig_at(tt) @ T_RIG_OPTICAL

        H, W = z_m.shape
        c = z_m[H // 2 - 8 : H // 2 + 8, W // 2 - 8 : W // 2 + 8]
        depth = float(np.clip(np.median(c), 0.1, 50.0))
        i = self.intrinsics
        return image_motion_px(pose(t - half), pose(t + half), i.fx, i.fy, i.ppx, i.ppy, depth)

    def tracker_angular_velocity(self, k: int, exposure_ms: float) -> np.ndarray:
        """The tracking camera's mean angular velocity (rad/s, its own axes) over frame k's
        exposure, as its gyroscope gives it: the rotation vector of R(t - e/2)^T R(t + e/2) over e.
        Exact: a MEMS gyro's noise, a fraction of a degree a second, is left out (about a
        thousandth of a scan's 120 deg/s slew; docs/FACTS.md "QR codes")."""
        t, half = float(self.times_s[k]), exposure_ms / 2000.0

        def rotation(tt: float) -> np.ndarray:  # R_world_tracker at time tt
            return (self._rig_at(tt) @ self._T_rig_tracker)[:3, :3]

        rvec, _ = cv2.Rodrigues(rotation(t - half).T @ rotation(t + half))
        return rvec.reshape(3) / (2.0 * half)

    def _sensor_frame(
        self,
        k: int,
        colour_depth: Future,
        segmentation: Future,
        T_map_rig: np.ndarray | None = None,
        colour: ColourSpec | None = None,
        motion_px: tuple[float, float] | None = None,
    ) -> tuple[Frame, FrameTruth]:
        """The sensor models and ground truth of frame k (or of a view from ``T_map_rig``, with
        frame k's noise) from its render jobs; ``colour`` replaces the scenario's colour camera
        settings and ``motion_px`` gives a view's motion blur (datasets).

        Reads nothing that rendering other frames changes, so it may run on any
        thread while the GL thread renders ahead.
        """
        sc = self.scenario
        rng = np.random.default_rng([sc.seed, SENSOR_STREAM, k])
        raw = colour_depth.result()
        T_map_optical = raw.T_map_optical
        camera = self.colour if colour is None else self._colour_sensor(colour, self._pools[0])
        sensors = [camera if s is self.colour else s for s in self.sensors]
        spec = camera.camera.spec
        exposure = (
            self.exposure(k, raw.rgb) if T_map_rig is None else self._steady_exposure(raw.rgb, spec, camera.lux)
        )
        motion = (0.0, 0.0) if motion_px is None else motion_px
        if T_map_rig is None and spec.motion_blur:
            motion = self.motion_px(k, exposure.exposure_ms, raw.z_m)
        shot = Shot(
            t_s=float(self.times_s[k]) if T_map_rig is None else 0.0,
            rgb=raw.rgb,
            gamma=spec.gamma,
            z_m=raw.z_m,
            T_world_optical=self.T_world_map @ T_map_optical,
            exposure=exposure,
            motion_px=motion,
            geom_ids=lambda: segmentation.result().geom_ids,
        )
        # each in turn, so each draws from rng in the same order every frame (sim.sensors.base)
        images = {s.frame_field: s.measure(shot, rng) for s in sensors}
        seg = segmentation.result()
        if T_map_rig is None:
            t_s, pose, confidence = float(self.times_s[k]), self.pose_track.poses[k], self.pose_track.confidence[k]
            relocalised = bool(self.pose_track.relocalised[k])
            T_map_tracker = self.T_map_tracker_true[k]
        else:
            T_map_tracker = T_map_rig @ self._T_rig_tracker
            t_s, pose, confidence, relocalised = 0.0, T_map_tracker, "high", False
        frame = Frame(
            index=k,
            timestamp_s=t_s,
            intrinsics=self.intrinsics,
            pose=pose,
            pose_confidence=confidence,
            pose_relocalised=relocalised,
            **images,
            thermal_intrinsics=self.thermal_intrinsics if "thermal_c" in images else None,
            # the exposure as the D435's colour metadata gives it: under auto-exposure it does not
            # (librealsense #2549, #5035; docs/FACTS.md); a view (datasets) has no tour to turn
            # along: its blur, if any, is drawn, not measured
            exposure_s=exposure.exposure_ms / 1000.0 if T_map_rig is None and not spec.auto_exposure else None,
            angular_velocity=self.tracker_angular_velocity(k, exposure.exposure_ms) if T_map_rig is None else None,
        )
        truth = FrameTruth(
            index=k,
            timestamp_s=t_s,
            T_map_camera=T_map_optical,
            T_map_tracker=T_map_tracker,
            visible=[],
            blur_px=float(np.hypot(*motion)),
        )
        if seg.object_ids is not None:
            truth.object_mask = seg.object_ids
            truth.visible = self._visible_objects(seg.object_ids, T_map_optical)
            if self._page_codes:
                truth.pages = self._visible_pages(seg.geom_ids)
        return frame, truth

    def frames(
        self, start: int = 0, stop: int | None = None, step: int = 1, prefetch: int = PREFETCH_FRAMES
    ) -> Iterator[tuple[Frame, FrameTruth]]:
        """Frames start, start + step, ... before ``stop``, the same as ``frame(k)`` gives.

        A two-stage pipeline keeps up to ``prefetch`` frames in flight: the GL
        thread renders frame k + 1 while a second thread runs the sensor models of
        frame k and the caller works on frame k - 1.
        """
        if self._gl_thread is None or self._model_thread is None:
            raise RuntimeError("the simulation is closed")
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        ks = iter(range(start, stop, step))
        pending: deque[Future] = deque()

        def submit(k: int) -> None:
            pending.append(self._model_thread.submit(self._sensor_frame, k, *self._submit_renders(k)))

        try:
            for k in itertools.islice(ks, max(prefetch, 0) + 1):
                submit(k)
            while pending:
                result = pending.popleft().result()
                for k in itertools.islice(ks, 1):
                    submit(k)
                yield result
        finally:
            for f in pending:
                f.cancel()

    # ------------------------------------------------------- visible objects
    def _qr_pages(self) -> tuple[np.ndarray, list[tuple[int, ...]]]:
        """Each geom's QR chart page (-1: none; a -1 appended for background's geom id -1) and
        each page's codes. A page is the sheet geom of the code that carries ``page_m`` and the
        geoms of every code whose text names the same chart (sim.world.placement.place_qr_sheets:
        "<chart> <module>mm")."""
        geom_object = self.world.geom_object_id
        page_of_geom = np.full(len(geom_object) + 1, -1, dtype=np.int32)
        pages: list[tuple[int, ...]] = []
        for o in self.objects:
            if o.page_m is None:
                continue
            chart = o.text.rsplit(" ", 1)[0]
            codes = tuple(c.id for c in self.objects if c.type == "qr" and c.text.rsplit(" ", 1)[0] == chart)
            sheet = mujoco.mj_name2id(self.world.model, mujoco.mjtObj.mjOBJ_GEOM, f"qr_page_{o.id}_sheet")
            page_of_geom[np.flatnonzero(np.isin(geom_object, codes))] = len(pages)
            page_of_geom[sheet] = len(pages)
            pages.append(codes)
        return page_of_geom, pages

    def _visible_pages(self, geom_ids: np.ndarray) -> list[VisiblePage]:
        """Box and pixel count of every QR chart page with a pixel in ``geom_ids``."""
        return [
            VisiblePage(codes=self._page_codes[p], box_xyxy=box, pixels=n)
            for p, box, n in _regions(self._page_of_geom.take(geom_ids))
        ]

    def _visible_objects(self, objmap: np.ndarray, T_map_optical: np.ndarray) -> list[VisibleObject]:
        """Box, pixel count and visible fraction of every object with a pixel in ``objmap``."""
        out: list[VisibleObject] = []
        regions = _regions(objmap)
        if not regions:
            return out
        T_optical_map = invert_transform(T_map_optical)
        T_optical_world = T_optical_map @ self.T_map_world
        by_id = {o.id: o for o in self.objects}
        for oid, box, n in regions:
            o = by_id[oid]
            p_world = self._reference_world[o.id]
            p_cam = transform_points(T_optical_map, transform_points(self.T_map_world, p_world))
            full = self._unoccluded_pixels(oid, T_optical_world)
            angle = float("nan")
            if o.type in FLAT_TYPES:
                # cos = n . (camera - p) / |camera - p|, in the optical frame, where the camera is at 0
                n_cam = T_optical_world[:3, :3] @ self._face_normal_world[o.id]
                r = float(np.linalg.norm(p_cam))
                cos = float(np.clip(-n_cam @ p_cam / r, -1.0, 1.0)) if r > 0 else 1.0
                angle = float(np.degrees(np.arccos(cos)))
            out.append(
                VisibleObject(
                    id=o.id,
                    type=o.type,
                    text=o.text,
                    box_xyxy=box,
                    pixels=n,
                    visible_fraction=float(min(1.0, n / full)) if full > 0 else 0.0,
                    position_cam=p_cam,
                    view_angle_deg=angle,
                )
            )
        return out

    def _object_geom_corners(self) -> dict[int, list[np.ndarray]]:
        """World-frame points whose convex hull holds each object geom; objects never move.

        A mesh gives its vertices (its bounding box can be twice its area: a placard cut
        along its diamond fills half the square around it), any other geom the 8 corners of
        its bounding box.
        """
        m, d = self.world.model, self.world.data
        mujoco.mj_kinematics(m, d)
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        out: dict[int, list[np.ndarray]] = {}
        for g, oid in enumerate(self.world.geom_box_object_id):
            if oid < 0:
                continue
            if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
                mesh = int(m.geom_dataid[g])
                adr, num = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
                corners_local = m.mesh_vert[adr : adr + num].astype(float)
            else:
                aabb = m.geom_aabb[g]
                corners_local = aabb[:3] + signs * aabb[3:]
            out.setdefault(int(oid), []).append(corners_local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g])
        return out

    def _unoccluded_pixels(self, oid: int, T_optical_world: np.ndarray) -> int:
        """Pixels the object would cover with nothing in front and no image border.

        The union of each of its geoms' projected hulls (mesh vertices or bounding-box
        corners, :meth:`_object_geom_corners`), rasterised; counts pixels off the image
        too, so the visible fraction includes truncation. An estimate for round shapes
        (their boxes are a little larger than their silhouettes).
        """
        intr = self.intrinsics
        polys = []
        for corners_w in self._object_corners_world.get(oid, []):
            pc = transform_points(T_optical_world, corners_w)
            z = np.maximum(pc[:, 2], 0.05)
            uv = np.stack([intr.fx * pc[:, 0] / z + intr.ppx, intr.fy * pc[:, 1] / z + intr.ppy], axis=1)
            polys.append(uv)
        if not polys:
            return 0
        allpts = np.concatenate(polys)
        lo = np.floor(allpts.min(axis=0)).astype(int)
        hi = np.ceil(allpts.max(axis=0)).astype(int)
        size = hi - lo + 1
        if size[0] * size[1] > 16 * intr.width * intr.height:
            return intr.width * intr.height * 16  # right in front of the camera: effectively huge
        canvas = np.zeros((size[1], size[0]), dtype=np.uint8)
        for uv in polys:
            hull = cv2.convexHull(np.round(uv - lo).astype(np.int32))
            cv2.fillConvexPoly(canvas, hull, 1)
        return int(canvas.sum())
