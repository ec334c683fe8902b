"""The annotated camera view: boxes coloured by type with names, track ids and confidence.

[Avevor2022]_ section 1: "show the detection live in the GUI and identify the object by name,
e.g. 'Oxidizer'". A small HUD gives the frame time and the number of confirmed objects.
Draws with OpenCV on a copy; the input image is never modified.

>>> img = np.zeros((60, 80, 3), np.uint8)
>>> out = annotate(img, [], [], 1.5)
>>> out.shape, int(img.sum())
((60, 80, 3), 0)

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from poi.core.names import display_name
from poi.core.types import Detection, TrackSnapshot

# RGB colours per type (orange for hazards, blue for QR codes, red for victims, as the
# competition map colours in docs/FACTS.md "Competition map conventions"; the rest chosen to be told apart).
# The one table of type colours: the boxes here, the live view and map.png (eval/scoring/map_plot.py).
TYPE_COLORS_RGB: dict[str, tuple[int, int, int]] = {
    "hazmat": (255, 100, 30),
    "qr": (10, 10, 240),
    "door": (150, 90, 40),
    "valve": (220, 0, 220),
    "baby-doll": (240, 10, 10),
    "fire-extinguisher": (255, 200, 0),
    "exit-sign": (0, 200, 60),
    "fire-extinguisher-sign": (200, 0, 90),
    "heat-source": (255, 255, 255),
    # the TurtleBot goal arena: each in a contrasting hue to its paint, so the box shows
    "pillar-blue": (0, 230, 255),
    "pillar-red": (255, 0, 160),
    "pillar-green": (170, 255, 0),
    "ball": (120, 60, 255),
    "landolt-c": (0, 140, 120),  # a teal the other types do not use
}
DEFAULT_COLOR_RGB = (200, 200, 200)
FONT = cv2.FONT_HERSHEY_SIMPLEX
FONT_SCALE = 0.45
LINE_PX = 2


def _label(det: Detection, snap: TrackSnapshot | None) -> str:
    name = display_name(det.type, det.text)
    parts = [name]
    if snap is not None and snap.report_id is not None:
        parts.append(f"#{snap.report_id}")
    elif det.track_id is not None:
        parts.append(f"t{det.track_id}")
    parts.append(f"{det.confidence:.2f}")
    return " ".join(parts)


def _text_box(img: np.ndarray, text: str, x: int, y: int, color: tuple[int, int, int]) -> None:
    """Text on a filled box whose top-left corner is (x, y), kept inside the image."""
    (tw, th), base = cv2.getTextSize(text, FONT, FONT_SCALE, 1)
    H, W = img.shape[:2]
    x = int(np.clip(x, 0, max(W - tw - 2, 0)))
    y = int(np.clip(y, 0, max(H - th - base - 2, 0)))
    cv2.rectangle(img, (x, y), (x + tw + 2, y + th + base + 2), color, -1)
    luminance = 0.299 * color[0] + 0.587 * color[1] + 0.114 * color[2]
    fg = (0, 0, 0) if luminance > 140 else (255, 255, 255)
    cv2.putText(img, text, (x + 1, y + th + 1), FONT, FONT_SCALE, fg, 1, cv2.LINE_AA)


def annotate(
    frame_rgb: np.ndarray,
    detections: Sequence[Detection],
    tracks: Sequence[TrackSnapshot] | None = None,
    timestamp_s: float | None = None,
) -> np.ndarray:
    """A copy of ``frame_rgb`` (H, W, 3 uint8) with detections and a HUD drawn on it.

    ``tracks`` (snapshots, e.g. ``pipeline.confirmed()``) give the report id shown for a
    detection whose ``track_id`` belongs to a confirmed track; the HUD counts the
    confirmed ones.
    """
    if frame_rgb.ndim != 3 or frame_rgb.shape[2] != 3 or frame_rgb.dtype != np.uint8:
        raise ValueError(
            f"annotate: expected an RGB uint8 image (H, W, 3), got {frame_rgb.dtype} {frame_rgb.shape}"
        )
    img = np.ascontiguousarray(frame_rgb.copy())
    by_id = {t.track_id: t for t in (tracks or [])}
    labels = []
    for det in detections:  # every box first, then every label: no box edge crosses a label
        color = TYPE_COLORS_RGB.get(det.type, DEFAULT_COLOR_RGB)
        x1, y1, x2, y2 = (int(round(c)) for c in det.box_xyxy)
        cv2.rectangle(img, (x1, y1), (x2 - 1, y2 - 1), color, LINE_PX)
        snap = by_id.get(det.track_id) if det.track_id is not None else None
        labels.append((_label(det, snap), x1, y1, color))
    for label, x1, y1, color in labels:
        (_, th), base = cv2.getTextSize(label, FONT, FONT_SCALE, 1)
        _text_box(img, label, x1, y1 - th - base - 2, color)
    n_confirmed = sum(1 for t in (tracks or []) if t.confirmed)
    hud = f"confirmed {n_confirmed}"
    if timestamp_s is not None:
        hud = f"t {timestamp_s:7.2f} s  " + hud
    _text_box(img, hud, 0, img.shape[0], (0, 0, 0))
    return img
