"""poi.estimation.shapes: the registry, and each shape built from its row of localize.types."""

from __future__ import annotations

import typing

import numpy as np
import pytest

from poi.config import SHAPES, TypeShapeConfig, apply_overrides, load_config
from poi.core.types import Intrinsics
from poi.estimation import shapes
from poi.estimation.shapes import Body, FlatSign, Leaf, TurnedSquare, shape_of

K = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=319.5, ppy=239.5)


def test_the_registry_has_each_shape_the_config_names():
    assert set(shapes.SHAPES) == set(SHAPES)
    assert set(typing.get_args(typing.get_type_hints(TypeShapeConfig)["shape"])) == set(SHAPES)


def test_each_default_type_gets_its_shape_and_numbers():
    lc = load_config().localize
    assert isinstance(shape_of("qr", lc), FlatSign) and not isinstance(shape_of("qr", lc), TurnedSquare)
    assert isinstance(shape_of("hazmat", lc), TurnedSquare) and shape_of("hazmat", lc).aspect == 1.0
    assert shape_of("exit-sign", lc).aspect == 2.0
    door = shape_of("door", lc)
    assert isinstance(door, Leaf) and (door.box_width_m, door.box_height_m) == (0.793, 1.362)
    assert door.extent_sigmas() == (0.032, 0.038)
    valve = shape_of("valve", lc)
    assert type(valve) is Body and valve.surface_to_center_m == -0.056
    ball = shape_of("ball", lc)
    assert type(ball) is Body and ball.box_width_m is None and ball.extent_sigmas() == (0.0, 0.0)
    # a type without a row: a body of no known size, its depth's surface its reference point
    target = shape_of("landolt-c", lc)
    assert type(target) is Body and target.surface_to_center_m == 0.0 and target.box_height_m is None
    # a row set to another shape: the type is localised by it
    cfg = apply_overrides(load_config(), ["localize.types.qr={shape: turned-square, aspect: 1.0}"])
    assert isinstance(shape_of("qr", cfg.localize), TurnedSquare)


def test_a_shapes_point_is_the_deprojection_moved_to_its_reference_point():
    """surface_to_center_m along the ray: a ball of radius 0.105 m seen straight ahead at 2 m."""
    ball = shape_of("ball", load_config().localize)
    assert ball.point(K)(319.5, 239.5, 2.0) == pytest.approx(np.array([0.0, 0.0, 2.105]))
    assert Body().point(K)(319.5, 239.5, 2.0) == pytest.approx(np.array([0.0, 0.0, 2.0]))
    assert Body(extent_sigma_m=0.1).extent_sigmas() == (0.1, 0.1)  # along the ray: as across
