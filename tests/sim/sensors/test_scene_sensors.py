"""The simulator's scene inputs to the T265 and thermal models: light and texture, lamps, metal."""

import mujoco
import numpy as np
import pytest

from sim.scenario import apply_settings, load_scenario
from sim.simulator import Simulation

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI


@pytest.fixture(scope="module")
def sims():
    out = {}
    for lighting in ("bright", "dim"):
        sc = apply_settings(load_scenario("default"), [f"lighting={lighting}", "robot.max_duration_s=30"])
        out[lighting] = Simulation(sc)
    yield out
    for s in out.values():
        s.close()


def test_drift_multiplier_follows_the_light(sims):
    bright = sims["bright"].tracking_conditions.multiplier
    dim = sims["dim"].tracking_conditions.multiplier
    # the same maze and route: the texture term is the same, the dim room adds
    # dim_gain (1 - 80 lux / 500 lux) = 1.68 everywhere (no lamps but the robot's own)
    assert dim - bright == pytest.approx(np.full(len(dim), 2.0 * (1 - 80 / 500)), abs=1e-9)
    assert bright.min() >= 1.0
    # and so the pose drifts further in the dim room, seed for seed
    e_b, e_d = sims["bright"].pose_track.error_m, sims["dim"].pose_track.error_m
    assert np.nanmean(e_d) > 1.5 * np.nanmean(e_b)


def test_lamps_are_warm_and_steel_is_metal(sims):
    sim = sims["bright"]
    m = sim.world.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "" for g in range(m.ngeom)]
    lamps = [g for g, n in enumerate(names) if n.startswith("hall_lamp")]
    trusses = [g for g, n in enumerate(names) if n.startswith("hall_truss")]
    assert lamps and np.all(sim._temp_of_geom[lamps] == sim.scenario.sensors.thermal.lamp_c)
    assert trusses and sim._thermal_scene.metal[trusses].all()
    hot = [g for g, oid in enumerate(sim.world.geom_object_id) if oid >= 0 and np.isfinite(sim._temp_of_geom[g])]
    assert hot and not sim._thermal_scene.metal[hot].any()  # a heat source's own parts keep their heat
    walls = [g for g, n in enumerate(names) if n.startswith("wall") or n == "floor"]
    assert walls and np.all(np.isnan(sim._temp_of_geom[walls]))  # the air's temperature where they are
