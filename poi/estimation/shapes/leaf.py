"""A 3-D item whose hidden part goes on along its depth plane: a door's leaf, a doll lying along
the floor ([Avevor2022]_ 2.2.2: J1 carries the plane's slope).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from poi.estimation.shapes.body import Body

if TYPE_CHECKING:
    from poi.config import LocalizeConfig


@dataclass(kw_only=True)
class Leaf(Body):
    """A :class:`~poi.estimation.shapes.body.Body` whose box keeps ``localize.border_px`` (its
    hidden length moves its depth along its plane, so a box called cut in error costs a thin R)
    and whose hidden half-length widens Sigma_1's centre sigmas, sigma_u' = hypot(sigma_u,
    hid_u / 2), so that J1 carries it along the plane's slope into the depth."""

    def border_sigmas(self, lc: LocalizeConfig) -> float:
        return 0.0

    def hidden(self, sigmas: tuple[float, float], hid: tuple[float, float]) -> tuple[tuple[float, float], tuple]:
        return (math.hypot(sigmas[0], 0.5 * hid[0]), math.hypot(sigmas[1], 0.5 * hid[1])), (0.0, 0.0)
