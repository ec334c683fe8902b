"""Placards get a printed variant and an in-plane turn from the scenario seed alone."""

from __future__ import annotations

import numpy as np

from maze_assets.objects import PlacedObject
from sim.world.placement import UPRIGHT_SHARE, assign_placard_looks


def _placards(n: int) -> list[PlacedObject]:
    return [PlacedObject(id=i, type="hazmat", text="poison") for i in range(n)] + [
        PlacedObject(id=n, type="qr", text="Chart M")
    ]


def test_same_seed_same_looks_other_seed_other_looks():
    a, b, c = _placards(40), _placards(40), _placards(40)
    assign_placard_looks(a, 7)
    assign_placard_looks(b, 7)
    assign_placard_looks(c, 8)
    assert [(o.look_seed, o.roll) for o in a] == [(o.look_seed, o.roll) for o in b]
    assert [o.look_seed for o in a[:40]] != [o.look_seed for o in c[:40]]
    assert a[40].look_seed is None and a[40].roll == 0.0  # only placards


def test_half_upright_half_at_any_angle():
    objs = _placards(2000)
    assign_placard_looks(objs, 3)
    rolls = np.rad2deg([o.roll for o in objs[:2000]])
    upright = np.abs(rolls) < 12  # 4 sd of the upright jitter
    # the any-angle half also falls within 12 degrees 24/360 of the time
    expected = UPRIGHT_SHARE + (1 - UPRIGHT_SHARE) * 24 / 360
    assert abs(upright.mean() - expected) < 0.04
    assert np.abs(rolls).max() > 170  # any angle, upside down included


def test_a_given_look_is_kept():
    objs = [PlacedObject(id=0, type="hazmat", text="poison", look_seed=5)]
    assign_placard_looks(objs, 1)
    assert objs[0].look_seed == 5 and objs[0].roll == 0.0
