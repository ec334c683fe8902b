"""A solid 3-D item (a valve, an extinguisher, a heater, a goal pillar or ball): its median depth
moved to its centre along the ray, its box cut by the image border or a nearer surface widened
by the length its known size says is hidden ([Bouda2025]_ 2.1.3, [Avevor2022]_ 2.1.4).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
.. [Bouda2025] M. Bouda, E. Doležal, O. Váňa, "Řešení úkolu pro TurtleBot s detekcí objektů
   a SLAM" ("A solution of the TurtleBot task with object detection and SLAM"), 2025.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from poi.core.types import Detection, Intrinsics
from poi.estimation.box_cuts import box_at_border, hidden_solid_px, occluded_sides
from poi.estimation.box_depth import BoxDepth, median_depth_variance
from poi.estimation.shapes.base import Measured, Shape, border_margin, box_pixel, in_range

if TYPE_CHECKING:
    from poi.config import LocalizeConfig


@dataclass(kw_only=True)
class Body(Shape):
    """A solid item, ``box_width_m`` x ``box_height_m`` in full view at its centre's depth (None:
    not known, and its box never counts as cut).

    Its depth is the box's median (:func:`poi.estimation.box_depth.box_depth`), its variance the
    median's (:func:`poi.estimation.box_depth.median_depth_variance`); its point moves
    ``surface_to_center_m`` along the ray. A box that comes within ``localize.border_px`` plus
    ``localize.body_border_sigmas`` of its centre sigmas of the image border, or that a nearer
    surface borders (:func:`poi.estimation.box_cuts.occluded_sides`), is cut on that axis, and
    f S / z - w pixels are hidden (:func:`poi.estimation.box_cuts.hidden_solid_px`): its centre
    is off the item's by up to half of that. Its visible part's slope says nothing of the hidden
    part's depth, so that half moves the centre across the ray only
    (``Measured.hidden_var``: through J2, not J1).
    """

    box_width_m: float | None = None
    box_height_m: float | None = None

    def border_sigmas(self, lc: LocalizeConfig) -> float:
        """How many centre sigmas beyond ``localize.border_px`` a box edge may lie and touch the border."""
        return lc.body_border_sigmas

    def hidden(self, sigmas: tuple[float, float], hid: tuple[float, float]) -> tuple[tuple[float, float], tuple]:
        """The centre sigmas and the J2-only variances with a hidden length ``hid`` (px): a
        body's half-length variance (hid / 2)^2 goes through J2 alone."""
        return sigmas, ((0.5 * hid[0]) ** 2, (0.5 * hid[1]) ** 2)

    def measure(
        self,
        detection: Detection,
        intr: Intrinsics,
        depth_m: np.ndarray,
        depth: BoxDepth,
        lc: LocalizeConfig,
        sigmas: tuple[float, float],
    ) -> Measured | None:
        u, v = box_pixel(detection)
        d = depth.median * lc.depth_scale
        if not in_range(d, lc):
            return None
        p_c = self.point(intr)(u, v, d)
        sized = self.box_width_m is not None or self.box_height_m is not None
        margin = border_margin(lc, self.border_sigmas(lc) if sized else 0.0, sigmas)
        at = box_at_border(detection.box_xyxy, intr.width, intr.height, margin)
        hid = (0.0, 0.0)
        if sized:
            if lc.occluder_margin_m > 0.0:
                occ = occluded_sides(
                    depth_m, detection.box_xyxy, depth.surface, lc.occluder_margin_m / lc.depth_scale
                )
                at = (at[0] or occ[0], at[1] or occ[1])
            size_m = (self.box_width_m or 0.0, self.box_height_m or 0.0)
            hid = hidden_solid_px(detection.size_wh, size_m, float(p_c[2]), (intr.fx, intr.fy), at)
        (sigma_u, sigma_v), hidden_var = self.hidden(sigmas, hid)
        return Measured(
            p_c=p_c,
            u=u,
            v=v,
            d=d,
            sigma_u=sigma_u,
            sigma_v=sigma_v,
            var_depth=median_depth_variance(depth_m, detection.box_xyxy, lc, d, depth.median),
            hidden_var=hidden_var,
            box_cut=(bool(at[0]), bool(at[1])),
        )
