"""The shapes that localise a detection, one geometry a module, registered by name: the name a
type's row of ``localize.types`` gives (poi/configs/default.yaml).

>>> from poi.config import LocalizeConfig
>>> type(shape_of("hazmat", LocalizeConfig())).__name__, shape_of("door", LocalizeConfig()).box_width_m
('TurnedSquare', 0.793)
>>> type(shape_of("landolt-c", LocalizeConfig())).__name__  # no row: a body of no known size
'Body'
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from poi.estimation.shapes.base import Measured, Shape
from poi.estimation.shapes.body import Body
from poi.estimation.shapes.flat_sign import FlatSign
from poi.estimation.shapes.leaf import Leaf
from poi.estimation.shapes.turned_square import TurnedSquare

if TYPE_CHECKING:
    from poi.config import LocalizeConfig

__all__ = ["SHAPES", "Body", "FlatSign", "Leaf", "Measured", "Shape", "TurnedSquare", "shape_of"]

# poi.config.SHAPES names the same four, for the check of a row at load
SHAPES: dict[str, type[Shape]] = {"flat": FlatSign, "turned-square": TurnedSquare, "body": Body, "leaf": Leaf}


def shape_of(type_name: str, lc: LocalizeConfig) -> Shape:
    """The shape, with its numbers, of ``localize.types``' row for a type (none: a :class:`Body`
    of no known size)."""
    row = lc.types.get(type_name)
    return Body() if row is None else SHAPES[row.shape].from_row(row)
