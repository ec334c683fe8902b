"""Heat sources from a thermal image registered to the colour camera.

``frame.thermal_c`` is float32 degrees Celsius at a low resolution (h, w), taken
through the colour camera's optics resampled: ``frame.thermal_intrinsics`` is
``frame.intrinsics.scaled(w, h)``. A pixel is hot when it is at least
``min_temp_c`` and at least ``min_delta_c`` above the ambient (the median of the
image); 8-connected hot regions of at least ``min_area_px`` thermal pixels are
heat sources. With the defaults a body at 37 C (a baby doll) is never one.

Hot regions up to ``merge_gap_px`` thermal pixels apart are one source: a finned
heater seen close shows each fin as a hot stripe with the cooler gap between them under
the threshold (the shipped heater's 1.3 cm gaps are 5-7 px at 0.3-0.4 m; without this
rule it gave one box per fin, five to seven in a frame). The hot pixels are dilated by a
(gap + 1)-square before labelling, which bridges a gap of up to ``merge_gap_px``; each
source's box, area and peak come from its own hot pixels only.

A region's box in thermal pixel edges (a pixel i covers [i, i + 1)) maps to
colour pixels through the two intrinsics, u_c = ppx_c + (fx_c / fx_t)(u_t - ppx_t)
on pixel centres, which for scaled intrinsics is x_c = x_t * W / w on edges.

Confidence rises linearly with the peak temperature T:
c = min_conf + (max_conf - min_conf) * clip((T - min_temp_c) / (full_conf_temp_c - min_temp_c),
0, 1).

>>> d = ThermalHotSpotDetector()
>>> d.confidence_for(45.0), d.confidence_for(62.5), d.confidence_for(200.0)
(0.5, 0.745, 0.99)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from poi.core.types import Detection, Frame, Intrinsics
from poi.detectors.base import DetectorConfigError, make_detection, one_class_probs, register


class ThermalFrameError(ValueError):
    """The frame's thermal image or thermal intrinsics are not usable."""


def thermal_box_to_colour(
    box_t: tuple[float, float, float, float], K_t: Intrinsics, K_c: Intrinsics
) -> tuple[float, float, float, float]:
    """A box in thermal pixel edges to colour pixel edges, clipped to the colour image.

    >>> K_c = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
    >>> thermal_box_to_colour((10.0, 20.0, 14.0, 26.0), K_c.scaled(160, 120), K_c)
    (40.0, 80.0, 56.0, 104.0)
    """
    x1, y1, x2, y2 = box_t

    def u(e: float) -> float:
        # edge -> centre coordinate, across the optics, centre -> edge
        return K_c.ppx + (K_c.fx / K_t.fx) * (e - 0.5 - K_t.ppx) + 0.5

    def v(e: float) -> float:
        return K_c.ppy + (K_c.fy / K_t.fy) * (e - 0.5 - K_t.ppy) + 0.5

    W, H = K_c.width, K_c.height
    out = (
        min(max(u(x1), 0.0), W),
        min(max(v(y1), 0.0), H),
        min(max(u(x2), 0.0), W),
        min(max(v(y2), 0.0), H),
    )
    a, b, c, d = (round(c, 9) for c in out)  # drop float dust from the affine map
    return a, b, c, d


@register("thermal")
@dataclass(kw_only=True)
class ThermalHotSpotDetector:
    """Hot spots in ``frame.thermal_c`` reported as 'heat-source' detections."""

    min_temp_c: float = 45.0
    min_delta_c: float = 10.0
    min_area_px: int = 4
    merge_gap_px: int = 8
    full_conf_temp_c: float = 80.0
    min_conf: float = 0.5
    max_conf: float = 0.99
    name: str = field(default="thermal", init=False)

    def __post_init__(self) -> None:
        if not np.isfinite(self.min_temp_c) or not np.isfinite(self.min_delta_c):
            raise DetectorConfigError("detector 'thermal': min_temp_c and min_delta_c must be finite")
        if self.min_delta_c < 0:
            raise DetectorConfigError(f"detector 'thermal': min_delta_c must be >= 0, got {self.min_delta_c}")
        if int(self.merge_gap_px) < 0:
            raise DetectorConfigError(f"detector 'thermal': merge_gap_px must be >= 0, got {self.merge_gap_px}")
        if int(self.min_area_px) < 1:
            raise DetectorConfigError(f"detector 'thermal': min_area_px must be >= 1, got {self.min_area_px}")
        if not self.full_conf_temp_c > self.min_temp_c:
            raise DetectorConfigError(
                f"detector 'thermal': full_conf_temp_c ({self.full_conf_temp_c}) must exceed "
                f"min_temp_c ({self.min_temp_c})"
            )
        if not 0.0 < self.min_conf <= self.max_conf <= 1.0:
            raise DetectorConfigError(
                f"detector 'thermal': need 0 < min_conf <= max_conf <= 1, got {self.min_conf}, {self.max_conf}"
            )

    def confidence_for(self, peak_c: float) -> float:
        """Confidence of a hot spot whose hottest pixel is ``peak_c`` degrees C."""
        frac = np.clip((peak_c - self.min_temp_c) / (self.full_conf_temp_c - self.min_temp_c), 0.0, 1.0)
        return round(float(self.min_conf + (self.max_conf - self.min_conf) * frac), 12)

    def _regions(self, hot: np.ndarray) -> tuple[int, np.ndarray]:
        """Label count and labels (0: not hot) of the hot pixels, grouped 8-connected across
        gaps of up to ``merge_gap_px`` pixels."""
        mask = hot.astype(np.uint8)
        g = int(self.merge_gap_px)
        grouped = cv2.dilate(mask, np.ones((g + 1, g + 1), np.uint8)) if g > 0 else mask
        n, labels = cv2.connectedComponents(grouped, connectivity=8)
        return n, np.where(hot, labels, 0)

    def detect(self, frame: Frame) -> list[Detection]:
        """Heat sources in the frame's thermal image, hottest first; [] without one."""
        if frame.thermal_c is None:
            return []
        temp_c = np.asarray(frame.thermal_c, dtype=np.float32)  # (h, w), deg C
        if temp_c.ndim != 2 or temp_c.size == 0:
            raise ThermalFrameError(f"frame {frame.index}: thermal_c must be (h, w), got shape {temp_c.shape}")
        h, w = temp_c.shape
        K_t = frame.thermal_intrinsics or frame.intrinsics.scaled(w, h)
        if (K_t.width, K_t.height) != (w, h):
            raise ThermalFrameError(
                f"frame {frame.index}: thermal_intrinsics are {K_t.width}x{K_t.height} but thermal_c is {w}x{h}"
            )
        valid = np.isfinite(temp_c)  # NaN / inf pixels are unmeasured
        if not np.any(valid):
            return []
        ambient_c = float(np.median(temp_c[valid]))
        # hot: T >= min_temp_c and T >= ambient + min_delta_c
        threshold_c = max(self.min_temp_c, ambient_c + self.min_delta_c)
        hot = valid & (temp_c >= threshold_c)
        n, labels = self._regions(hot)
        probs_cache: dict[float, np.ndarray] = {}
        dets = []
        for k in range(1, n):  # label 0 is the background
            rows, cols = np.nonzero(labels == k)
            if rows.size < self.min_area_px:
                continue
            peak_c = float(temp_c[rows, cols].max())
            c = self.confidence_for(peak_c)
            box_t = (int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1)
            box = thermal_box_to_colour(box_t, K_t, frame.intrinsics)
            if box[2] <= box[0] or box[3] <= box[1]:
                continue
            if c not in probs_cache:
                probs_cache[c] = one_class_probs("heat-source", c)
            dets.append(make_detection("heat-source", box, c, source="thermal", class_probs=probs_cache[c].copy()))
        dets.sort(key=lambda d: -d.confidence)
        return dets
