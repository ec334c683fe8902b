"""A hazmat placard: a square diamond hung at an unknown in-plane turn (49 CFR 172.519: a
placard is a square on point; here it may hang turned from that).

References
----------
Full entries in docs/SOURCES.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from poi.estimation.shapes.flat_sign import FlatSign


@dataclass(kw_only=True)
class TurnedSquare(FlatSign):
    """A :class:`~poi.estimation.shapes.flat_sign.FlatSign` whose corners touch its box at its
    centre line (a diamond), hung at an unknown turn: where its plane's tilt is known, its
    centre is the mean over the turns of a square, and Sigma_1's centre sigmas grow by that
    centre's spread over them (:func:`~poi.estimation.shapes.plane_item.flat_item` with
    ``turned``)."""

    diamond: ClassVar[bool] = True
    turned: ClassVar[bool] = True
