"""Lamps that cast shadows (issue 17, item 5): the ``shadows`` setting turns them on for the
sun of ``bright`` and the spot lamps of ``uneven``; a shadow only takes light away."""

from __future__ import annotations

import numpy as np
import pytest

from sim.scenario import apply_settings, load_scenario, with_noise
from sim.simulator import Simulation
from sim.world.world import SHADOW_MAP_PX

pytestmark = pytest.mark.slow  # every test here builds a simulation, renders or runs the CLI

FRAMES = (40, 120, 200, 330)  # frames of the earlier sweeping tour with walls and floor in view


def _raw_frames(lighting: str, shadows: bool) -> tuple[str, list[np.ndarray]]:
    sc = with_noise(load_scenario("default"), False)
    sets = [f"lighting={lighting}", f"shadows={str(shadows).lower()}", "robot.max_duration_s=40"]
    sc = apply_settings(sc, [*sets, "robot.pan.mode=sweep"])
    with Simulation(sc) as sim:
        rgb = [sim.on_gl_thread(sim._render_colour_depth, k).rgb.astype(np.int16) for k in FRAMES]
        return sim.world.xml, rgb


@pytest.mark.parametrize("lighting", ["bright", "uneven"])
def test_shadows_only_darken_and_darken_a_real_share_of_the_frame(lighting):
    xml_off, off = _raw_frames(lighting, False)
    xml_on, on = _raw_frames(lighting, True)
    assert 'castshadow="true"' not in xml_off and "shadowsize" not in xml_off
    assert 'castshadow="true"' in xml_on and f'shadowsize="{SHADOW_MAP_PX}"' in xml_on
    darker = []
    for a, b in zip(off, on, strict=True):
        # the same scene, a light taken away where a shadow falls: nowhere brighter
        assert (b - a).max() <= 2
        luma_a, luma_b = a.mean(axis=2), b.mean(axis=2)
        darker.append(np.mean(luma_b < 0.85 * luma_a - 2))
    # walls shade the floor and corners beside them in some views
    assert max(darker) > 0.03, darker


def test_the_robot_lamp_alone_casts_none():
    """``dim`` has only the robot's own lamp (the headlight): ``shadows`` changes nothing."""
    xml_off, off = _raw_frames("dim", False)
    xml_on, on = _raw_frames("dim", True)
    assert 'castshadow="true"' not in xml_on
    assert all(np.array_equal(a, b) for a, b in zip(off, on, strict=True))
