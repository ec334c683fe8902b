"""The lighting presets' light level reaches the colour camera once: a dim room's placards read
dim, not dim twice over."""

from __future__ import annotations

import numpy as np
import pytest

from poi.core.geometry import make_transform, rot_z
from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation
from sim.world.world import lux_of_decoded_one


def test_lux_of_a_decoded_one_undoes_the_renders_own_shading():
    assert lux_of_decoded_one("bright", 1000.0, 2.2) == pytest.approx(1000.0)
    # dim: the lamp-lit white renders 0.45, decoded 0.45 ** 2.2 = 0.17261
    assert lux_of_decoded_one("dim", 80.0, 2.2) == pytest.approx(80.0 / 0.17261, rel=1e-4)


@pytest.mark.parametrize("lighting", ["dim", "uneven"])
@pytest.mark.slow
def test_placard_whites_seen_face_on_are_light(lighting):
    """Each placard seen face on from 1 m: its whites (p90 grey) read at least 160 (real
    photos: about 220; a D435 at its longest exposure and highest gain in a room lit by the
    robot's lamp reads about 180). Counting the dim render and the low lux both gave 60-80."""
    sc = apply_settings(with_noise(load_scenario("default"), False), [f"lighting={lighting}"])
    whites = []
    with Simulation(sc) as sim:
        for o in (o for o in sim.objects if o.type == "hazmat"):
            n = np.array([np.cos(o.yaw), np.sin(o.yaw)])
            cam = o.position[:2] + n * 1.0
            T = sim.T_map_world @ make_transform(rot_z(np.arctan2(-n[1], -n[0])), [cam[0], cam[1], o.position[2]])
            frame, truth = sim.view(T, 0)
            mask = truth.object_mask == o.id
            if mask.sum() > 400:
                whites.append(np.percentile(frame.rgb.astype(float).mean(axis=2)[mask], 90))
    assert len(whites) >= 4 and min(whites) >= 160, whites
