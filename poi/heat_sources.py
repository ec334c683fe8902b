"""Heat-source boxes the thermal camera vouches for.

A heat source is defined by its heat: the Robot League's heat sources are found by their
temperature, and a robot that carries a thermal camera sees whether a place is hot. A colour
network's heat-source class learns what heaters look like, and now and then boxes something of
their colour and shape that is cold (docs/FACTS.md "Thermal camera"). So with the thermal camera on, a
heat-source box of another detector stands only where a thermal detection
(poi.detectors.thermal, ``source == "thermal"``) of the same frame overlaps it: their boxes,
both in colour-image pixels, share some area. The thermal detections themselves always stand.

A frame with pixels but no thermal image (a recording's colour frame with none paired to it)
keeps every box: nothing there says a place is cold. A replayed frame of the perception cache
has no pixels; its detections were recorded with the thermal detector beside the others.

>>> from poi.detectors.base import make_detection
>>> warm = make_detection("heat-source", (100, 100, 140, 160), 0.9, source="thermal", class_probs=None)
>>> near = make_detection("heat-source", (120, 130, 200, 220), 0.6, source="onnx", class_probs=None)
>>> cold = make_detection("heat-source", (300, 100, 360, 160), 0.6, source="onnx", class_probs=None)
>>> [d.box_xyxy for d in vouched_for([warm, near, cold])]
[(100.0, 100.0, 140.0, 160.0), (120.0, 130.0, 200.0, 220.0)]
"""

from __future__ import annotations

import numpy as np

from poi.core.geometry import iou_matrix
from poi.core.types import Detection, Frame

HEAT_SOURCE = "heat-source"
THERMAL_SOURCE = "thermal"


def vouched_for(detections: list[Detection]) -> list[Detection]:
    """``detections`` less the heat-source boxes of other detectors that no thermal
    heat-source box of the list overlaps (the order of the rest kept)."""
    hot = np.array([d.box_xyxy for d in detections if d.type == HEAT_SOURCE and d.source == THERMAL_SOURCE])

    def stands(d: Detection) -> bool:
        if d.type != HEAT_SOURCE or d.source == THERMAL_SOURCE:
            return True
        return bool((iou_matrix(np.array([d.box_xyxy]), hot) > 0).any())

    return [d for d in detections if stands(d)]


def frame_has_thermal_view(frame: Frame) -> bool:
    """Whether the thermal detector saw this frame: it carries a thermal image, or it is a
    replayed frame without pixels (recorded with the thermal detector running)."""
    return frame.thermal_c is not None or frame.rgb.size == 0
