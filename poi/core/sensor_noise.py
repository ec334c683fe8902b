"""Noise models the simulator and the pipeline share, so each is written once.

* D435 depth: Intel's RMS depth-error formula ([IntelTuning]_, "Tuning depth cameras
  for best performance": RMS error = distance^2 * subpixel / (focal length in pixels *
  baseline); docs/FACTS.md "D435 depth": sigma_z = z^2 sigma_d / (f B), subpixel sigma_d about 0.08 px).
  The simulator produces this error by perturbing the disparity
  (:func:`sim.sensors.d435_depth.disparity_noise`); the pipeline puts it into each
  observation's covariance (:mod:`poi.estimation.localize`).
* Detector box-centre error ([Avevor2022]_ section 2.1.4): sigma_u = a + b w and
  sigma_v = a + b h pixels for a w x h px box. :data:`CENTER_SIGMA_A_PX` and
  :data:`CENTER_SIGMA_B` are the defaults of both the oracle detector's noise
  (``sim.oracle.OracleSettings``) and the pipeline's model of it
  (``localize.center_sigma_px`` in ``poi/configs/default.yaml``).

>>> round(depth_sigma_m(2.0, sigma_d_px=0.08, fx_depth_px=384.2, baseline_m=0.05), 6)  # 0.32 / 19.21
0.016658

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [IntelTuning] A. Grunnet-Jepsen, J. N. Sweetser, J. Woodfill, "Tuning depth cameras for best
   performance", Intel RealSense white paper.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

CENTER_SIGMA_A_PX = 1.0
CENTER_SIGMA_B = 0.03

Depth = TypeVar("Depth", float, np.ndarray)


def center_sigma_px(size_px: float, *, a_px: float, b: float) -> float:
    """Detector box-centre error in pixels along one axis of a box ``size_px`` wide (or high):
    sigma = a + b size ([Avevor2022]_ section 2.1.4). The oracle detector draws its centre noise with it
    and the pipeline puts the same model into each observation's covariance.

    >>> center_sigma_px(100.0, a_px=CENTER_SIGMA_A_PX, b=CENTER_SIGMA_B)
    4.0
    """
    return a_px + b * size_px


def depth_sigma_m(z_m: Depth, *, sigma_d_px: float, fx_depth_px: float, baseline_m: float) -> Depth:
    """D435 depth noise in metres at depth ``z_m`` (a number or an array of depths):
    sigma_z = z^2 sigma_d / (f B) (Intel's RMS error = distance^2 * subpixel / (focal_px *
    baseline) [IntelTuning]_; docs/FACTS.md "D435 depth").

    >>> depth_sigma_m(np.array([1.0, 2.0]), sigma_d_px=0.1, fx_depth_px=400.0, baseline_m=0.05)
    array([0.005, 0.02 ])
    """
    return z_m * z_m * sigma_d_px / (fx_depth_px * baseline_m)


def window_correlation(window_px: int, step_px: int = 1) -> np.ndarray:
    """The correlation of the D435's depth noise between pixels k ``step_px`` apart along a row
    (or a column), k = -K..K: rho = max(0, 1 - |k| step / w) for noise that is the box mean of
    white noise over a w = ``window_px`` square (:func:`sim.sensors.d435_depth.window_noise`,
    the stereo matching window); in two dimensions the product of a row's and a column's.

    >>> window_correlation(4).tolist(), window_correlation(7, 4).round(3).tolist()
    ([0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25], [0.429, 1.0, 0.429])
    """
    if window_px < 1 or step_px < 1:
        raise ValueError(
            f"window_correlation: expected window_px >= 1 and step_px >= 1, got {window_px}, {step_px}"
        )
    k_max = (window_px - 1) // step_px
    k = np.arange(-k_max, k_max + 1)
    return 1.0 - np.abs(k) * step_px / window_px
