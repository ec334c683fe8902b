"""A trial's world in motion: the maze, its objects, the robot's route and the sensor frames.

``Simulation(scenario)`` builds everything from the scenario and its seed;
``frames()`` yields ``(Frame, FrameTruth)`` pairs: the ``Frame`` is all the
pipeline may see, the ``FrameTruth`` (true poses, visible objects with their
boxes, visible fraction and true camera-frame position) is kept apart for
scoring, the oracle detector and datasets.

Randomness: the scenario seed makes one ``np.random.Generator`` for building the
world (maze, placement, lighting, T265 drift) and, for sensor noise, one
generator per frame from ``SeedSequence([seed, 1, k])``, so frame k is the
same whichever frames are rendered.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import mujoco  # noqa: E402
import numpy as np

import sim.gl  # noqa: F401
from poi.geometry import (  # noqa: E402
    R_BODY_OPTICAL,
    invert_transform,
    make_transform,
    rot_x,
    rot_y,
    rot_z,
    transform_points,
)
from poi.types import Frame, Intrinsics  # noqa: E402
from sim.camera import T_RIG_OPTICAL  # noqa: E402
from sim.maze import (  # noqa: E402
    PRESETS,  # noqa: E402
    find_maze,
    load_maze,
)
from sim.maze_gen import generate_maze  # noqa: E402
from sim.objects import PlacedObject  # noqa: E402
from sim.placement import place_objects  # noqa: E402
from sim.route import Route, load_route_csv, rig_pose, route_from_tour  # noqa: E402
from sim.scenario import MountSpec, Scenario  # noqa: E402
from sim.sensors.d435_depth import simulate_depth  # noqa: E402
from sim.sensors.t265 import PoseTrack, simulate_t265  # noqa: E402
from sim.sensors.thermal import thermal_image  # noqa: E402
from sim.tour import plan_tour  # noqa: E402
from sim.world import CAMERA_NAME, World, build_world  # noqa: E402

SENSOR_STREAM = 1
COLOR_NOISE_POOL = 6


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


@dataclass(kw_only=True)
class FrameTruth:
    index: int
    timestamp_s: float
    T_map_camera: np.ndarray  # true optical frame pose
    T_map_tracker: np.ndarray  # true tracker pose
    visible: list[VisibleObject]
    object_mask: np.ndarray | None = None  # (H, W) object id per pixel, -1 elsewhere


def mount_transforms(m: MountSpec) -> tuple[np.ndarray, np.ndarray]:
    """(nominal, true) T_tracker_optical: p_tracker = Q0 p_c + t0."""

    def rpy(r):
        a = np.deg2rad(r)
        return rot_z(a[2]) @ rot_y(a[1]) @ rot_x(a[0])

    nominal = make_transform(rpy(m.rpy_deg) @ R_BODY_OPTICAL, m.t_m)
    error = make_transform(rpy(m.error_rpy_deg), m.error_t_m)
    return nominal, error @ nominal


def default_mast_height_m(cell_size_m: float) -> float:
    return 0.5 if cell_size_m >= 0.6 else 0.2


class Simulation:
    def __init__(self, scenario: Scenario) -> None:
        self.scenario = sc = scenario
        rng = np.random.default_rng(sc.seed)
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
        self.objects = place_objects(sc, self.maze, rng)
        d = sc.sensors.d435
        self.intrinsics = Intrinsics(width=d.width, height=d.height, fx=d.fx, fy=d.fy, ppx=d.ppx, ppy=d.ppy)
        th = sc.sensors.thermal
        self.thermal_intrinsics = self.intrinsics.scaled(th.width, th.height)
        self.world: World = build_world(self.maze, self.objects, self.intrinsics, sc.lighting, rng)

        sx, sy = self.maze.cell_center(*self.maze.start_cell)
        self.T_world_map = make_transform(rot_z(self.maze.start_heading_rad), [sx, sy, 0.0])
        self.T_map_world = invert_transform(self.T_world_map)
        if sc.robot.route == "tour":
            cells = plan_tour(self.maze, self.maze.start_cell)
            self.route: Route = route_from_tour(self.maze, cells, sc.robot, self.maze.start_heading_rad)
        else:
            self.route = load_route_csv(sc.resolve(sc.robot.route), self.T_world_map)
        self.mast_height_m = (
            sc.robot.mast_height_m
            if sc.robot.mast_height_m is not None
            else default_mast_height_m(self.maze.settings.cell_size_m)
        )
        duration = self.route.duration_s
        if sc.robot.max_duration_s is not None:
            duration = min(duration, sc.robot.max_duration_s)
        self.times_s = np.arange(0.0, duration + 1e-9, 1.0 / sc.sensors.fps)
        self.T_tracker_optical_nominal, self.T_tracker_optical_true = mount_transforms(sc.sensors.mount)
        T_rig_tracker = T_RIG_OPTICAL @ invert_transform(self.T_tracker_optical_true)
        self._T_map_rig = [
            self.T_map_world @ rig_pose(self.route, t, self.mast_height_m, np.deg2rad(sc.robot.tilt_deg))
            for t in self.times_s
        ]
        self.T_map_tracker_true = [T @ T_rig_tracker for T in self._T_map_rig]
        self.pose_track: PoseTrack = simulate_t265(
            self.T_map_tracker_true, self.times_s, sc.sensors.t265, rng, sc.sensors.noise
        )
        self._temp_of_geom = self._geom_temperatures()
        self._renderer: mujoco.Renderer | None = None
        self._color_pool: np.ndarray | None = None

    # ------------------------------------------------------------------ truth
    def truth_objects(self) -> list[TruthObject]:
        return [
            TruthObject(
                id=o.id,
                type=o.type,
                text=o.text,
                position_map=transform_points(self.T_map_world, o.position),
                placed=o,
            )
            for o in self.objects
        ]

    def walls_in_map(self) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """Wall pieces (that stand in the world) as map-frame 2D segments, for map plots."""
        doors = {o.wall for o in self.objects if o.type == "door"}
        out = []
        for seg in self.maze.wall_segments():
            if seg.name in doors:
                continue
            a = transform_points(self.T_map_world, np.array([seg.x0, seg.y0, 0.0]))
            b = transform_points(self.T_map_world, np.array([seg.x1, seg.y1, 0.0]))
            out.append(((float(a[0]), float(a[1])), (float(b[0]), float(b[1]))))
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

    # ---------------------------------------------------------------- render
    def _geom_temperatures(self) -> np.ndarray:
        ambient = self.scenario.sensors.thermal.ambient_c
        temp = np.full(self.world.model.ngeom, ambient, dtype=np.float32)
        by_id = {o.id: o for o in self.objects}
        for g, oid in enumerate(self.world.geom_object_id):
            if oid >= 0 and by_id[int(oid)].temperature_c is not None:
                temp[g] = by_id[int(oid)].temperature_c
        return temp

    def _renderer_ready(self) -> mujoco.Renderer:
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.world.model, self.intrinsics.height, self.intrinsics.width)
        return self._renderer

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self) -> Simulation:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _set_camera(self, k: int) -> np.ndarray:
        T_world_rig = self.T_world_map @ self._T_map_rig[k]
        m, d = self.world.model, self.world.data
        d.mocap_pos[self.world.rig_mocap_id] = T_world_rig[:3, 3]
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, T_world_rig[:3, :3].ravel())
        d.mocap_quat[self.world.rig_mocap_id] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)
        return self._T_map_rig[k] @ T_RIG_OPTICAL

    def render_raw(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
        """(rgb, true z-depth, geom-id segmentation or None, T_map_optical) for frame k."""
        r = self._renderer_ready()
        T_map_optical = self._set_camera(k)
        d = self.world.data
        r.update_scene(d, CAMERA_NAME)
        rgb = r.render().copy()
        r.enable_depth_rendering()
        r.update_scene(d, CAMERA_NAME)
        depth = r.render().copy()
        r.disable_depth_rendering()
        seg = None
        sens = self.scenario.sensors
        if sens.truth_boxes or (sens.thermal.enabled):
            r.enable_segmentation_rendering()
            r.update_scene(d, CAMERA_NAME)
            s = r.render()
            r.disable_segmentation_rendering()
            seg = np.where(s[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), s[..., 0], -1).astype(np.int32)
        return rgb, depth, seg, T_map_optical

    def _color_noise(self, rng: np.random.Generator, shape) -> np.ndarray:
        if self._color_pool is None:
            pool_rng = np.random.default_rng([self.scenario.seed, SENSOR_STREAM, 10**9])
            sigma = self.scenario.sensors.d435.color_noise_sigma
            self._color_pool = np.round(
                pool_rng.standard_normal((COLOR_NOISE_POOL, *shape), dtype=np.float32) * sigma
            ).astype(np.int16)
        i = int(rng.integers(COLOR_NOISE_POOL))
        shift = int(rng.integers(shape[0]))
        return np.roll(self._color_pool[i], shift, axis=0)

    def frame(self, k: int) -> tuple[Frame, FrameTruth]:
        sc = self.scenario
        sens = sc.sensors
        noise = sens.noise
        rng = np.random.default_rng([sc.seed, SENSOR_STREAM, k])
        rgb, z_true, seg, T_map_optical = self.render_raw(k)
        if noise and sens.d435.color_noise_sigma > 0:
            rgb = np.clip(rgb.astype(np.int16) + self._color_noise(rng, rgb.shape), 0, 255).astype(np.uint8)
        depth = None
        if sens.d435.enabled:
            depth = simulate_depth(z_true, sens.d435.depth, self.intrinsics.fx, rng, noise)
        thermal = None
        if sens.thermal.enabled and seg is not None:
            geom_img = np.where(seg >= 0, seg, -1)
            thermal = thermal_image(geom_img, self._temp_of_geom, sens.thermal, rng, noise)
        frame = Frame(
            index=k,
            timestamp_s=float(self.times_s[k]),
            rgb=rgb,
            intrinsics=self.intrinsics,
            depth_m=depth,
            pose=self.pose_track.poses[k],
            pose_confidence=self.pose_track.confidence[k],
            thermal_c=thermal,
            thermal_intrinsics=self.thermal_intrinsics if thermal is not None else None,
        )
        truth = FrameTruth(
            index=k,
            timestamp_s=float(self.times_s[k]),
            T_map_camera=T_map_optical,
            T_map_tracker=self.T_map_tracker_true[k],
            visible=[],
        )
        if seg is not None and sens.truth_boxes:
            truth.object_mask, truth.visible = self._visible_objects(seg, T_map_optical)
        return frame, truth

    def frames(self, start: int = 0, stop: int | None = None, step: int = 1) -> Iterator[tuple[Frame, FrameTruth]]:
        stop = self.n_frames if stop is None else min(stop, self.n_frames)
        for k in range(start, stop, step):
            yield self.frame(k)

    # ------------------------------------------------------- visible objects
    def _visible_objects(self, seg: np.ndarray, T_map_optical: np.ndarray):
        owner = self.world.geom_object_id
        lut = np.append(owner, -1)
        objmap = lut[seg]  # seg == -1 indexes the appended -1
        ys, xs = np.nonzero(objmap >= 0)
        out: list[VisibleObject] = []
        if len(xs) == 0:
            return objmap, out
        ids = objmap[ys, xs]
        T_optical_map = invert_transform(T_map_optical)
        by_id = {o.id: o for o in self.objects}
        for oid in np.unique(ids):
            sel = ids == oid
            px, py = xs[sel], ys[sel]
            o = by_id[int(oid)]
            p_cam = transform_points(T_optical_map, transform_points(self.T_map_world, o.position))
            n = int(sel.sum())
            full = self._unoccluded_pixels(int(oid))
            out.append(
                VisibleObject(
                    id=o.id,
                    type=o.type,
                    text=o.text,
                    box_xyxy=(
                        float(px.min()),
                        float(py.min()),
                        float(px.max() + 1),
                        float(py.max() + 1),
                    ),
                    pixels=n,
                    visible_fraction=float(min(1.0, n / full)) if full > 0 else 0.0,
                    position_cam=p_cam,
                )
            )
        return objmap, out

    def _unoccluded_pixels(self, oid: int) -> int:
        """Pixels the object would cover with nothing in front and no image border.

        The union of each of its geoms' projected bounding boxes (convex hulls),
        rasterised; counts pixels off the image too, so the visible fraction
        includes truncation. An estimate for round shapes (their boxes are a little
        larger than their silhouettes).
        """
        m, d = self.world.model, self.world.data
        intr = self.intrinsics
        cam_pos = d.cam_xpos[0]
        cam_mat = d.cam_xmat[0].reshape(3, 3)
        # MuJoCo camera frame -> optical frame: flip y and z
        R_oc = cam_mat @ np.diag([1.0, -1.0, -1.0])
        geoms = np.nonzero(self.world.geom_object_id == oid)[0]
        polys = []
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        for g in geoms:
            aabb = m.geom_aabb[g]
            corners_local = aabb[:3] + signs * aabb[3:]
            corners_w = corners_local @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
            pc = (corners_w - cam_pos) @ R_oc
            z = np.maximum(pc[:, 2], 0.05)
            uv = np.stack([intr.fx * pc[:, 0] / z + intr.ppx, intr.fy * pc[:, 1] / z + intr.ppy], axis=1)
            polys.append(uv)
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
