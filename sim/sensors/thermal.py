"""A low-resolution thermal camera registered to the colour camera.

Every geom has a surface temperature (ambient unless its object has one: the
heat source, dolls at body temperature). The thermal image is the
segmentation render mapped through that table, area-averaged down to the
thermal resolution (each thermal pixel integrates its footprint), blurred by
the optics and given NETD noise. Degrees Celsius, float32.
"""

from __future__ import annotations

import cv2
import numpy as np

from sim.scenario import ThermalSpec


def thermal_image(
    seg_geom: np.ndarray,
    temp_of_geom: np.ndarray,
    spec: ThermalSpec,
    rng: np.random.Generator,
    noise: bool,
) -> np.ndarray:
    """seg_geom: (H, W) int geom ids (-1 background); temp_of_geom: (ngeom,) deg C."""
    lut = np.append(temp_of_geom.astype(np.float32), np.float32(spec.ambient_c))  # index -1 -> ambient
    full = lut[seg_geom]
    img = cv2.resize(full, (spec.width, spec.height), interpolation=cv2.INTER_AREA)
    if noise:
        if spec.blur_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), spec.blur_px)
        img = img + rng.standard_normal(img.shape, dtype=np.float32) * np.float32(spec.netd_k)
    return img.astype(np.float32)
