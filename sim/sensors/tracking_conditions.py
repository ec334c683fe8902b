"""How well the T265 can see where the robot is: light and texture along the route.

A visual-inertial tracker drifts faster where its cameras see little: in the dark,
and in front of bare walls with nothing to track ([T265Issues]). Rendering the
T265's fisheye views would cost a render a frame, so the simulator uses two cheap
proxies from the scene it built (**poibench**'s model, docs/FACTS.md "T265 tracking
camera"):

* light (lux): the lighting preset's level, LIGHT_LEVEL_LUX, for what the robot's own
  lamp lights (sim/world/world.py), plus each scene lamp's share at the tracker's position as
  OpenGL's fixed-function model gives it, diffuse * spot / (a0 + a1 d + a2 d^2) with
  spot = cos(angle)^exponent inside the cutoff (a directional lamp: its diffuse), in
  the same units (level / LAMP_WHITE_LEVEL * lux). Walls do not shadow the lamps.
* texture: the RMS contrast (grey standard deviation over mean) of the textures of the
  walls and floor near the tracker (within ``radius_m`` of their nearest point), weighted
  by 1 / (0.25 + d^2).

:func:`drift_multiplier` turns them into the factor on the drift rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from poi.core.loader import number
from sim.world.world import LAMP_WHITE_LEVEL, LIGHT_LEVEL_LUX


@dataclass(kw_only=True)
class T265ConditionsSpec:
    """How the scene's light and texture where the robot is scale the T265's drift
    (sim/sensors/tracking_conditions.py; **poibench**'s model, docs/FACTS.md "T265 tracking camera").

    The drift rate (and the false-jump rate) is multiplied by
    1 + dim_gain * clip(1 - lux / good_lux, 0, 1) + bare_gain * clip(1 - contrast / good_contrast, 0, 1)
    with ``lux`` the light the robot's lamp and the scene's lamps give where it is and
    ``contrast`` the RMS contrast of the wall and floor textures around it.
    """

    good_lux: float = number(500.0, lo=0.0, lo_open=True)
    dim_gain: float = number(2.0, lo=0.0)
    good_contrast: float = number(0.12, lo=0.0, lo_open=True)
    bare_gain: float = number(2.0, lo=0.0)
    radius_m: float = number(1.5, lo=0.0, lo_open=True)  # walls this near the robot count


NEAR_M2 = 0.25  # texture weights 1 / (NEAR_M2 + d^2): surfaces within about 0.5 m count fully
RGB_ROLE = int(mujoco.mjtTextureRole.mjTEXROLE_RGB)


def drift_multiplier(lux: np.ndarray, contrast: np.ndarray, spec: T265ConditionsSpec) -> np.ndarray:
    """1 + dim_gain clip(1 - lux / good_lux, 0, 1) + bare_gain clip(1 - contrast / good_contrast, 0, 1).

    >>> spec = T265ConditionsSpec()
    >>> drift_multiplier(np.array([1000.0, 80.0]), np.array([0.2, 0.06]), spec).round(2).tolist()
    [1.0, 3.68]
    """
    dim = np.clip(1.0 - np.asarray(lux, float) / spec.good_lux, 0.0, 1.0)
    bare = np.clip(1.0 - np.asarray(contrast, float) / spec.good_contrast, 0.0, 1.0)
    return 1.0 + spec.dim_gain * dim + spec.bare_gain * bare


def scene_lux(model: mujoco.MjModel, data: mujoco.MjData, lighting: str, p_world: np.ndarray) -> np.ndarray:
    """Illuminance (lux) at points ``p_world`` (n, 3): the robot's lamp plus the scene's lamps."""
    p = np.atleast_2d(np.asarray(p_world, dtype=float))
    level = np.full(len(p), LAMP_WHITE_LEVEL[lighting])
    for i in range(model.nlight):
        if not model.light_active[i]:
            continue
        diffuse = float(np.mean(model.light_diffuse[i]))
        if int(model.light_type[i]) == int(mujoco.mjtLightType.mjLIGHT_DIRECTIONAL):
            level += diffuse
            continue
        v = p - data.light_xpos[i]
        d = np.linalg.norm(v, axis=1)
        a0, a1, a2 = model.light_attenuation[i]
        gain = diffuse / (a0 + a1 * d + a2 * d * d)
        if int(model.light_type[i]) == int(mujoco.mjtLightType.mjLIGHT_SPOT):
            cos = (v @ data.light_xdir[i]) / np.maximum(d, 1e-9)
            inside = cos >= np.cos(np.deg2rad(model.light_cutoff[i]))
            gain = gain * np.where(inside, np.clip(cos, 0.0, 1.0) ** model.light_exponent[i], 0.0)
        level += gain
    return LIGHT_LEVEL_LUX[lighting] * level / LAMP_WHITE_LEVEL[lighting]


def _texture_contrast(model: mujoco.MjModel, tex: int) -> float:
    adr, w, h, c = (
        int(x) for x in (model.tex_adr[tex], model.tex_width[tex], model.tex_height[tex], model.tex_nchannel[tex])
    )
    pix = model.tex_data[adr : adr + w * h * c].astype(float).reshape(-1, c)[:, : min(c, 3)].mean(axis=1)
    mean = float(pix.mean())
    return float(pix.std() / mean) if mean > 0 else 0.0


def texture_contrast(
    model: mujoco.MjModel, data: mujoco.MjData, geom_object_id: np.ndarray, p_world: np.ndarray, radius_m: float
) -> np.ndarray:
    """Weighted RMS contrast of the textured walls and floor (geoms of no object) near ``p_world``."""
    p = np.atleast_2d(np.asarray(p_world, dtype=float))
    num, den = np.zeros(len(p)), np.zeros(len(p))
    contrast: dict[int, float] = {}
    for g in range(model.ngeom):
        if geom_object_id[g] >= 0 or model.geom_matid[g] < 0:
            continue
        gtype = int(model.geom_type[g])
        if gtype not in (int(mujoco.mjtGeom.mjGEOM_BOX), int(mujoco.mjtGeom.mjGEOM_PLANE)):
            continue
        tex = int(np.atleast_1d(model.mat_texid[model.geom_matid[g]])[RGB_ROLE])
        if tex < 0:
            continue
        if tex not in contrast:
            contrast[tex] = _texture_contrast(model, tex)
        local = (p - data.geom_xpos[g]) @ data.geom_xmat[g].reshape(3, 3)  # into the geom's frame
        if gtype == int(mujoco.mjtGeom.mjGEOM_PLANE):
            d = np.abs(local[:, 2])
        else:
            d = np.linalg.norm(local - np.clip(local, -model.geom_size[g], model.geom_size[g]), axis=1)
        w = np.where(d <= radius_m, 1.0 / (NEAR_M2 + d * d), 0.0)
        num += w * contrast[tex]
        den += w
    return np.divide(num, den, out=np.zeros(len(p)), where=den > 0)
