"""A low-resolution thermal camera registered to the colour camera.

Every geom has a surface temperature: its object's own (the heat source; dolls at body
temperature), a lamp's (``lamp_c``), or the air's where it stands. The air is not at one
temperature (**poibench**'s model, docs/FACTS.md "Thermal camera"): warm air rises, so
it warms by ``vertical_gradient_c_per_m`` per metre above ``reference_height_m``, and it
changes by ``horizontal_gradient_c_per_m`` per metre along a direction drawn from the
seed (a door, a heater at one end of the hall), zero at the arena's centre.

Metal reflects most of the infrared it receives: a pixel on a metal geom reads
e T_surface + (1 - e) T_reflected, with e = ``metal_emissivity`` and T_reflected the
temperature of what the mirror direction (the view ray reflected about the surface
normal, from the depth image) hits, by a ray cast in the scene (ambient if nothing).

The image is the segmentation render mapped through those temperatures, area-averaged
down to the thermal resolution (each thermal pixel integrates its footprint:
``THERMAL_SUPERSAMPLE`` x ``THERMAL_SUPERSAMPLE`` samples of the colour camera's full-size
segmentation, :func:`sample_grid`), blurred by the optics, with fixed-pattern noise and NETD
noise. Fixed-pattern noise, per pixel and fixed for a run: F0 (standard deviation
``fpn_sigma_k``) plus a second pattern F1 (unit standard deviation) that grows at
``fpn_drift_k_per_min`` and is reset by the camera's flat-field correction every
``ffc_interval_s``. Degrees Celsius, float32.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import mujoco
import numpy as np

from poi.core.loader import number
from poi.core.types import Intrinsics
from sim.sensors.base import MAX_IMAGE_PX, Shot

THERMAL_SUPERSAMPLE = 2  # each thermal pixel integrates THERMAL_SUPERSAMPLE^2 segmentation samples


def sample_grid(img: np.ndarray, width: int, height: int) -> np.ndarray:
    """``img`` (H, W, ...) sampled at a ``width`` x ``height`` grid over the same view: at each
    grid pixel's centre, the image's pixel under it, row floor((j + 1/2) H / height) and column
    floor((i + 1/2) W / width) (for H / height = 2 that is pixel 2j + 1, whose centre lies half
    an image pixel past the grid pixel's). One sampling for the geom ids and the depths, so
    each sample's depth is the depth of its geom.

    >>> sample_grid(np.arange(16).reshape(4, 4), 2, 2).tolist()
    [[5, 7], [13, 15]]
    """
    H, W = img.shape[:2]
    if H % height == 0 and W % width == 0:  # whole steps r: rows r j + r // 2, a strided view
        ry, rx = H // height, W // width
        return img[ry // 2 :: ry, rx // 2 :: rx]
    rows = ((np.arange(height) + 0.5) * (H / height)).astype(np.intp)
    cols = ((np.arange(width) + 0.5) * (W / width)).astype(np.intp)
    return img[rows[:, None], cols[None, :]]


@dataclass(kw_only=True)
class ThermalSpec:
    """The thermal camera (sim/sensors/thermal.py; docs/FACTS.md "Thermal camera"; all
    **poibench**'s choices). The air: ``ambient_c`` at ``reference_height_m``, warming by
    ``vertical_gradient_c_per_m`` per metre up and changing by ``horizontal_gradient_c_per_m``
    per metre along a direction drawn from the seed. Lamp panels at ``lamp_c``; metal reads
    ``metal_emissivity`` of its own temperature and the rest from what it mirrors. Sensor:
    NETD ``netd_k`` (per pixel and frame), optical blur ``blur_px``, fixed-pattern noise
    ``fpn_sigma_k`` drifting by ``fpn_drift_k_per_min`` until the flat-field correction
    every ``ffc_interval_s``.
    """

    enabled: bool = True
    width: int = number(160, lo=1, hi=MAX_IMAGE_PX)
    height: int = number(120, lo=1, hi=MAX_IMAGE_PX)
    ambient_c: float = number(20.0, lo=-50.0, hi=60.0)
    netd_k: float = number(0.08, lo=0.0)
    blur_px: float = number(0.8, lo=0.0)
    reference_height_m: float = 0.5
    vertical_gradient_c_per_m: float = number(1.0, lo=-10.0, hi=10.0)
    horizontal_gradient_c_per_m: float = number(0.2, lo=-10.0, hi=10.0)
    lamp_c: float = number(40.0, lo=-50.0, hi=500.0)
    metal_emissivity: float = number(0.1, lo=0.0, hi=1.0)
    fpn_sigma_k: float = number(0.2, lo=0.0)
    fpn_drift_k_per_min: float = number(0.1, lo=0.0)
    ffc_interval_s: float = number(120.0, lo=0.0, lo_open=True)

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"thermal size must be at least 1x1, got {self.width}x{self.height}")
        if self.netd_k < 0 or self.blur_px < 0:
            raise ValueError("netd_k and blur_px must be >= 0")


RAY_OFFSET_M = 1e-3  # start reflected rays this far off the surface so they do not hit it


@dataclass(kw_only=True)
class ThermalScene:
    """What the thermal model needs of a run's scene: drawn and computed once."""

    gradient_dir: np.ndarray  # (2,) unit horizontal direction of the along-the-arena gradient (world)
    centre_xy: np.ndarray  # (2,) where that gradient is zero (world)
    fpn: np.ndarray  # (2, h, w): F0 (K) and the unit drift pattern F1
    metal: np.ndarray  # (ngeom,) bool: geoms that mirror their surroundings
    model: mujoco.MjModel | None = None  # the scene, for reflected rays (None: no reflections)
    data: mujoco.MjData | None = None  # a copy of the scene's static state, for ray casts only


def make_thermal_scene(
    spec: ThermalSpec,
    rng: np.random.Generator,
    centre_xy: np.ndarray,
    metal: np.ndarray,
    model: mujoco.MjModel | None = None,
    data: mujoco.MjData | None = None,
) -> ThermalScene:
    """Draw the gradient's direction and the fixed patterns (in this order) from ``rng``."""
    a = rng.uniform(0.0, 2.0 * np.pi)
    f0 = rng.standard_normal((spec.height, spec.width)) * spec.fpn_sigma_k
    f1 = rng.standard_normal((spec.height, spec.width))
    return ThermalScene(
        gradient_dir=np.array([np.cos(a), np.sin(a)]),
        centre_xy=np.asarray(centre_xy, dtype=float),
        fpn=np.stack([f0, f1]).astype(np.float32),
        metal=np.asarray(metal, dtype=bool),
        model=model,
        data=data,
    )


def air_temperature(p_world: np.ndarray, spec: ThermalSpec, scene: ThermalScene) -> np.ndarray:
    """The ambient temperature at points (..., 3): ambient + vertical + horizontal gradients.

    >>> spec = ThermalSpec(vertical_gradient_c_per_m=1.0, horizontal_gradient_c_per_m=0.5)
    >>> sc = ThermalScene(gradient_dir=np.array([1.0, 0.0]), centre_xy=np.zeros(2),
    ...                   fpn=np.zeros((2, 1, 1)), metal=np.zeros(0, bool))
    >>> air_temperature(np.array([[2.0, 5.0, 1.5]]), spec, sc).tolist()
    [22.0]
    """
    p = np.asarray(p_world, dtype=float)
    along = (p[..., :2] - scene.centre_xy) @ scene.gradient_dir
    return (
        spec.ambient_c
        + spec.vertical_gradient_c_per_m * (p[..., 2] - spec.reference_height_m)
        + spec.horizontal_gradient_c_per_m * along
    )


def fixed_pattern(spec: ThermalSpec, scene: ThermalScene, t_s: float) -> np.ndarray:
    """F0 + fpn_drift_k_per_min (time since the last flat-field correction, min) F1."""
    since = (t_s % spec.ffc_interval_s) / 60.0
    return scene.fpn[0] + np.float32(spec.fpn_drift_k_per_min * since) * scene.fpn[1]


@dataclass(kw_only=True)
class ThermalView:
    """Where the segmentation image's pixels lie: z-depth ``z_m`` (H, W) of a camera with
    intrinsics ``K`` (of that size) at ``T_world_optical``."""

    z_m: np.ndarray
    K: Intrinsics
    T_world_optical: np.ndarray

    @classmethod
    def from_depth(cls, z_m: np.ndarray, K: Intrinsics, T_world_optical: np.ndarray, width: int, height: int):
        """The view of a ``width`` x ``height`` image of the same camera, from a z-depth image
        (sampled as :func:`sample_grid` samples)."""
        z = sample_grid(np.asarray(z_m, np.float32), width, height)
        return cls(z_m=z, K=K.scaled(width, height), T_world_optical=np.asarray(T_world_optical, float))

    def _rays(self) -> tuple[np.ndarray, np.ndarray]:
        """(u', v') = ((u - ppx) / fx, (v - ppy) / fy) per column and row."""
        H, W = self.z_m.shape
        return (np.arange(W) - self.K.ppx) / self.K.fx, (np.arange(H) - self.K.ppy) / self.K.fy

    def air_temperature(self, spec: ThermalSpec, scene: ThermalScene) -> np.ndarray:
        """:func:`air_temperature` at every pixel's surface point. The air's temperature is
        linear in the point, T = c + g . p, and p = R z (u', v', 1) + t, so per pixel it is
        c + g . t + z (k . (u', v', 1)) with k = R^T g: no 3D points needed."""
        g = np.array(
            [
                spec.horizontal_gradient_c_per_m * scene.gradient_dir[0],
                spec.horizontal_gradient_c_per_m * scene.gradient_dir[1],
                spec.vertical_gradient_c_per_m,
            ]
        )
        c = (
            spec.ambient_c
            - spec.vertical_gradient_c_per_m * spec.reference_height_m
            - spec.horizontal_gradient_c_per_m * float(scene.centre_xy @ scene.gradient_dir)
        )
        R, t = self.T_world_optical[:3, :3], self.T_world_optical[:3, 3]
        k = R.T @ g
        up, vp = self._rays()
        per_ray = (k[0] * up[None, :] + k[1] * vp[:, None] + k[2]).astype(np.float32)
        return np.float32(c + g @ t) + self.z_m * per_ray

    def points(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World points, unit normals facing the camera (from the neighbouring pixels' points)
        and unit view rays, each (n, 3), of the ``mask`` pixels."""
        H, W = mask.shape
        up, vp = self._rays()
        R, t = self.T_world_optical[:3, :3], self.T_world_optical[:3, 3]

        def point(y: np.ndarray, x: np.ndarray) -> np.ndarray:
            ray = np.stack([up[x], vp[y], np.ones(len(x))], axis=1)
            return (ray * self.z_m[y, x, None]) @ R.T + t

        ys, xs = np.nonzero(mask)
        P = point(ys, xs)
        du = point(ys, np.minimum(xs + 1, W - 1)) - point(ys, np.maximum(xs - 1, 0))
        dv = point(np.minimum(ys + 1, H - 1), xs) - point(np.maximum(ys - 1, 0), xs)
        n = np.cross(du, dv)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        d = np.stack([up[xs], vp[ys], np.ones(len(xs))], axis=1) @ R.T
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        n = np.where((np.sum(n * d, axis=1) > 0)[:, None], -n, n)
        return P, n, d


def reflected_temperature(
    origins: np.ndarray,
    directions: np.ndarray,
    geom_temp_c: np.ndarray,
    spec: ThermalSpec,
    scene: ThermalScene,
) -> np.ndarray:
    """The temperature seen along rays (n, 3) from ``origins`` (n, 3): the hit geom's own
    temperature, or the air's at the hit point where it has none (NaN in ``geom_temp_c``),
    or the ambient where the ray leaves the scene."""
    out = np.full(len(origins), spec.ambient_c, dtype=float)
    if scene.model is None or scene.data is None:
        return out
    geomid = np.array([-1], dtype=np.int32)
    for i, (o, d) in enumerate(zip(origins, directions, strict=True)):
        dist = mujoco.mj_ray(scene.model, scene.data, o, d, None, 1, -1, geomid)
        g = int(geomid[0])
        if dist < 0 or g < 0:
            continue
        own = geom_temp_c[g]
        out[i] = own if np.isfinite(own) else float(air_temperature(o + dist * d, spec, scene))
    return out


def thermal_image(
    seg_geom: np.ndarray,
    temp_of_geom: np.ndarray,
    spec: ThermalSpec,
    rng: np.random.Generator,
    noise: bool,
    *,
    scene: ThermalScene | None = None,
    view: ThermalView | None = None,
    t_s: float = 0.0,
) -> np.ndarray:
    """seg_geom: (H, W) int geom ids (-1 background); temp_of_geom: (ngeom,) deg C, NaN for
    "the air's where it is". ``view``: where each pixel's surface lies (with ``scene``:
    gradients and reflections; without: the air is ``ambient_c`` everywhere)."""
    temps = np.append(temp_of_geom.astype(np.float32), np.float32(np.nan))  # index -1 -> the air's
    full = temps[seg_geom]
    air = np.isnan(full)
    if scene is not None and view is not None:
        full[air] = view.air_temperature(spec, scene)[air]
        metal = (seg_geom >= 0) & scene.metal[np.maximum(seg_geom, 0)]
        if metal.any():
            P, n, d = view.points(metal)
            mirror = d - 2.0 * np.sum(d * n, axis=1, keepdims=True) * n
            t_refl = reflected_temperature(P + RAY_OFFSET_M * n, mirror, temp_of_geom, spec, scene)
            e = spec.metal_emissivity
            full[metal] = e * full[metal] + (1.0 - e) * t_refl
    else:
        full[air] = spec.ambient_c
    img = cv2.resize(full.astype(np.float32), (spec.width, spec.height), interpolation=cv2.INTER_AREA)
    if noise:
        if spec.blur_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), spec.blur_px)
        if scene is not None:
            img = img + fixed_pattern(spec, scene, t_s)
        img = img + rng.standard_normal(img.shape, dtype=np.float32) * np.float32(spec.netd_k)
    return img.astype(np.float32)


@dataclass(kw_only=True)
class ThermalSensor:
    """The thermal camera as a frame sensor (:class:`sim.sensors.base.FrameSensor`): each geom's
    own temperature ``temp_of_geom`` (NaN: the air's), the run's ``scene``, and the view of
    the colour camera's depth (``intrinsics``) for the air along each ray."""

    frame_field = "thermal_c"
    spec: ThermalSpec
    noise: bool
    intrinsics: Intrinsics
    temp_of_geom: np.ndarray
    scene: ThermalScene

    def measure(self, shot: Shot, rng: np.random.Generator) -> np.ndarray:
        full = shot.geom_ids()
        if full is None:
            raise RuntimeError("the thermal camera needs the segmentation render's geom ids")
        h, w = full.shape
        w2 = min(self.spec.width * THERMAL_SUPERSAMPLE, w)
        h2 = min(self.spec.height * THERMAL_SUPERSAMPLE, h)
        geoms = sample_grid(full, w2, h2)
        view = ThermalView.from_depth(shot.z_m, self.intrinsics, shot.T_world_optical, w2, h2)
        return thermal_image(
            geoms, self.temp_of_geom, self.spec, rng, self.noise, scene=self.scene, view=view, t_s=shot.t_s
        )
