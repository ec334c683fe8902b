"""The Landolt-C reader on rendered D435 frames (bench/bench_landolt.py's scene and colour model).

Rendering checks what drawn-image tests cannot: the card's texture reaches the camera the
right way round (a mirrored texture swaps 45 and 135 degrees), and the colour model's noise,
defocus and JPEG leave the 3rd ring readable at 0.3 m (its 1.8 mm gap 3.7 px) and unreadable,
not misread, at 2 m (0.6 px).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from sim.scenario import load_scenario

_spec = importlib.util.spec_from_file_location(
    "bench_landolt", Path(__file__).parents[2] / "bench" / "bench_landolt.py"
)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)

pytestmark = pytest.mark.slow  # it renders


def test_rendered_targets_read_near_and_are_none_far():
    counts = bench.measure(load_scenario("default"), [0.3, 2.0], n_targets=3, poses=1, seed=2)
    right, wrong, none = counts[..., 0], counts[..., 1], counts[..., 2]
    assert wrong.sum() == 0
    assert right[0, :3].tolist() == [3, 3, 3]  # 0.3 m: rings 1-3 (gaps 20, 8.6, 3.7 px)
    assert none[0, 4] == 3  # ring 5's 0.33 mm gap is 0.7 px
    assert right[1, 0] == 3 and none[1, 2] == 3  # 2 m: ring 1 (3 px) reads, ring 3 (0.6 px) does not
