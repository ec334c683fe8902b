"""The thermal camera (sim/sensors/thermal.py): air gradients, fixed-pattern noise, metal reflections."""

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from poi.core.geometry import make_transform
from poi.core.types import Intrinsics
from sim.sensors.thermal import (
    ThermalScene,
    ThermalSpec,
    ThermalView,
    make_thermal_scene,
    sample_grid,
    thermal_image,
)

QUIET = ThermalSpec(width=40, height=30, netd_k=0.0, blur_px=0.0, fpn_sigma_k=0.0, fpn_drift_k_per_min=0.0)


def _scene(spec, metal=(False,), model=None, data=None, seed=0):
    return make_thermal_scene(spec, np.random.default_rng(seed), np.zeros(2), np.array(metal), model, data)


# optical (x right, y down, z forward) to world (x forward, y left, z up), camera 0.5 m up
R_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
K_SEG = Intrinsics(width=80, height=60, fx=40.0, fy=40.0, ppx=39.5, ppy=29.5)


def _wall_view():
    """A wall 2 m ahead of a level camera 0.5 m up: each row's height z_w = 0.5 - 2 (v - 29.5) / 40."""
    return ThermalView(
        z_m=np.full((60, 80), 2.0, np.float32), K=K_SEG, T_world_optical=make_transform(R_LEVEL, [0, 0, 0.5])
    )


def test_air_warms_upward_and_along_the_gradient_direction():
    spec = replace(QUIET, vertical_gradient_c_per_m=1.5, horizontal_gradient_c_per_m=0.0, reference_height_m=0.5)
    seg = np.zeros((60, 80), np.int32)  # one geom with no temperature of its own: the air's
    temps = np.array([np.nan])
    img = thermal_image(seg, temps, spec, np.random.default_rng(0), False, scene=_scene(spec), view=_wall_view())
    # thermal row 0 averages rows v = 0 and 1: mean height 0.5 + 2 * 29 / 40 = 1.95 m
    assert img[0, 0] == pytest.approx(20.0 + 1.5 * (1.95 - 0.5), abs=1e-4)
    assert img[0, 0] - img[-1, 0] == pytest.approx(1.5 * 2.9, abs=1e-4)  # rows 0 and 29: 2.9 m apart
    assert np.ptp(img[10]) == pytest.approx(0.0, abs=1e-4)  # no horizontal gradient asked for
    # 0.4 C/m along the direction drawn from the seed; thermal column 0 (u = 0, 1) is at
    # y_w = 2 * 39 / 40 = 1.95 m, column 39 at -1.95 m, both at x_w = 2 m
    spec_h = replace(QUIET, vertical_gradient_c_per_m=0.0, horizontal_gradient_c_per_m=0.4)
    sc = _scene(spec_h)
    img = thermal_image(seg, temps, spec_h, np.random.default_rng(0), False, scene=sc, view=_wall_view())
    assert img[5, 0] == pytest.approx(20.0 + 0.4 * (sc.gradient_dir @ [2.0, 1.95]), abs=1e-4)
    assert img[5, 0] - img[5, -1] == pytest.approx(0.4 * sc.gradient_dir[1] * 3.9, abs=1e-4)


def test_without_scene_the_air_is_ambient_and_own_temperatures_stay():
    seg = np.full((60, 80), -1, np.int32)
    seg[:30] = 1
    img = thermal_image(seg, np.array([np.nan, 80.0]), QUIET, np.random.default_rng(0), False)
    assert img[2, 2] == pytest.approx(80.0) and img[-2, 2] == pytest.approx(20.0)


def test_fixed_pattern_noise_has_its_size_drifts_and_resets_at_flat_field_correction():
    spec = replace(QUIET, width=160, height=120, fpn_sigma_k=0.3, fpn_drift_k_per_min=0.5, ffc_interval_s=120.0)
    sc = _scene(spec, seed=5)
    seg = np.zeros((240, 320), np.int32)
    temps = np.array([25.0])

    def at(t):
        return thermal_image(seg, temps, spec, np.random.default_rng(1), True, scene=sc, t_s=t)

    f0 = at(0.0) - 25.0
    assert np.std(f0) == pytest.approx(0.3, rel=0.03)  # 19200 pixels: the std is good to 0.5%
    drift = at(60.0) - at(0.0)  # one minute: 0.5 K of the unit drift pattern
    assert np.std(drift) == pytest.approx(0.5, rel=0.03)
    assert abs(np.corrcoef(f0.ravel(), drift.ravel())[0, 1]) < 0.05  # a second, independent pattern
    assert np.array_equal(at(120.0), at(0.0))  # the flat-field correction resets the drift
    # the pattern is the camera's: fixed for a run, the same for the same seed
    assert np.array_equal(
        make_thermal_scene(spec, np.random.default_rng(5), np.zeros(2), np.zeros(1, bool)).fpn, sc.fpn
    )
    assert at(30.0).tobytes() == at(30.0).tobytes()
    other = _scene(spec, seed=6)
    assert not np.array_equal(other.fpn, sc.fpn)


MIRROR_XML = """
<mujoco><worldbody>
  <geom name="metal_floor" type="box" pos="2 0 -0.01" size="3 3 0.01"/>
  <geom name="heater" type="box" pos="3.5 0 3" size="0.5 6 3"/>
</worldbody></mujoco>
"""


def test_metal_mirrors_a_warm_source():
    # a metal floor seen from 1 m up, looking 45 degrees down: each view ray reflects up
    # into a heater wall at 80 C, so the metal reads e * 20 + (1 - e) * 80 = 74 C with
    # e = 0.1 (and its own 20 C with e = 1)
    model = mujoco.MjModel.from_xml_string(MIRROR_XML)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    spec = replace(QUIET, vertical_gradient_c_per_m=0.0, horizontal_gradient_c_per_m=0.0)
    r = np.sqrt(0.5)
    R = np.array([[0.0, -r, r], [-1.0, 0.0, 0.0], [0.0, -r, -r]])  # columns: optical x, y, z in world
    K = Intrinsics(width=80, height=60, fx=80.0, fy=80.0, ppx=39.5, ppy=29.5)
    vp = (np.arange(60) - 29.5) / 80.0
    z = np.repeat((np.sqrt(2.0) / (1.0 + vp))[:, None], 80, axis=1).astype(np.float32)  # to the floor
    view = ThermalView(z_m=z, K=K, T_world_optical=make_transform(R, [0, 0, 1.0]))
    seg = np.zeros((60, 80), np.int32)
    temps = np.array([np.nan, 80.0])
    sc = _scene(spec, metal=(True, False), model=model, data=data)
    img = thermal_image(seg, temps, spec, np.random.default_rng(0), False, scene=sc, view=view)
    assert img == pytest.approx(np.full((30, 40), 0.1 * 20.0 + 0.9 * 80.0), abs=1e-4)
    matte = replace(spec, metal_emissivity=1.0)
    img = thermal_image(seg, temps, matte, np.random.default_rng(0), False, scene=sc, view=view)
    assert img == pytest.approx(np.full((30, 40), 20.0), abs=1e-4)
    # the same floor not metal: it reads the air's temperature
    plain = ThermalScene(gradient_dir=sc.gradient_dir, centre_xy=sc.centre_xy, fpn=sc.fpn, metal=np.zeros(2, bool))
    img = thermal_image(seg, temps, spec, np.random.default_rng(0), False, scene=plain, view=view)
    assert img == pytest.approx(np.full((30, 40), 20.0), abs=1e-4)


@pytest.mark.parametrize(
    ("H", "W", "h", "w"), [(480, 640, 240, 320), (48, 64, 24, 32), (481, 641, 240, 320), (60, 80, 7, 9)]
)
def test_a_grid_sample_is_the_image_pixel_under_the_grid_pixels_centre(H, W, h, w):
    # each pixel holds its own row and column: the sample must be the pixel that contains the
    # centre ((i + 1/2) W / w, (j + 1/2) H / h) of grid pixel (j, i), whole steps or not
    rows, cols = np.mgrid[0:H, 0:W]
    got = sample_grid(np.stack([rows, cols], axis=-1), w, h)
    centre_y = (np.arange(h) + 0.5) * H / h
    centre_x = (np.arange(w) + 0.5) * W / w
    assert got.shape == (h, w, 2)
    assert np.all((got[..., 0] <= centre_y[:, None]) & (centre_y[:, None] < got[..., 0] + 1))
    assert np.all((got[..., 1] <= centre_x[None, :]) & (centre_x[None, :] < got[..., 1] + 1))
