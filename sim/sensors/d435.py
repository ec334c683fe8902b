"""The RealSense D435's settings (``sensors.d435``): its colour imager's size and intrinsics
(``sim/camera.py`` makes them a MuJoCo camera), and its two streams' effects, each beside its
model: the colour stream's (:class:`~sim.sensors.d435_color.ColourSpec`) and the depth stream's,
aligned to colour (:class:`~sim.sensors.d435_depth.DepthSpec`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from poi.core.loader import number
from sim.sensors.base import MAX_IMAGE_PX
from sim.sensors.d435_color import ColourSpec
from sim.sensors.d435_depth import DepthSpec


@dataclass(kw_only=True)
class D435Spec:
    enabled: bool = True
    width: int = number(640, lo=1, hi=MAX_IMAGE_PX)
    height: int = number(480, lo=1, hi=MAX_IMAGE_PX)
    fx: float = number(612.4, lo=0.0, lo_open=True)
    fy: float = number(610.6, lo=0.0, lo_open=True)
    ppx: float = 314.3
    ppy: float = 237.8
    colour: ColourSpec = field(default_factory=ColourSpec)
    depth: DepthSpec = field(default_factory=DepthSpec)
