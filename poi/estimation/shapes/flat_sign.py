"""A flat sign (a QR code, a fire-extinguisher sign, an exit sign): measured on its box's depth
plane, its cut judged by its aspect ([Avevor2022]_ 2.1.4, 2.2).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from poi.core.sensor_noise import depth_sigma_m
from poi.core.types import Detection, Intrinsics
from poi.estimation.box_cuts import border_sides, box_at_border, hidden_lengths_px, occluded_sides
from poi.estimation.box_depth import (
    BoxDepth,
    box_depth_plane,
    median_depth_variance,
    plane_depth_variance,
    plane_slope_sigma,
)
from poi.estimation.shapes.base import Measured, Shape, border_margin, box_pixel, in_range
from poi.estimation.shapes.plane_item import flat_item

if TYPE_CHECKING:
    from poi.config import LocalizeConfig


@dataclass(kw_only=True)
class FlatMeasure:
    """A flat item measured from its box (:meth:`FlatSign.measure_item`): its centre on the depth
    plane (camera frame; None where the plane's tilt is not known well enough), the pixels its
    box leaves out across u and v, the move of the box centre (px) that puts it at the centre of
    the whole item where the image border cut it (0 elsewhere), and the centre's spread over an
    unknown in-plane turn (px along u and v: :func:`~poi.estimation.shapes.plane_item.flat_item`)."""

    centre: np.ndarray | None
    hidden_w: float
    hidden_h: float
    shift_u: float = 0.0
    shift_v: float = 0.0
    turn_sigma_px: tuple[float, float] = (0.0, 0.0)


def least_tilted_gradient(
    grad: tuple[float, float], var_g: tuple[float, float], n_sigmas: float
) -> tuple[float, float]:
    """The depth gradient (m / px) of the most face-on plane a measured one allows: each
    axis's slope moved toward 0 by ``n_sigmas`` of its standard errors, not past 0. A plane
    seen face-on makes an item look widest, so a box judged on this plane is called cut only
    when no tilt within ``n_sigmas`` explains its shortfall.

    >>> [round(g, 6) for g in least_tilted_gradient((0.01, -0.001), (1e-6, 1e-6), 2.0)]
    [0.008, -0.0]
    """
    out = []
    for g, var in zip(grad, var_g, strict=True):
        shrink = n_sigmas * math.sqrt(max(var, 0.0))
        out.append(math.copysign(max(abs(g) - shrink, 0.0), g))
    return out[0], out[1]


def whole_item_sigmas(
    sigmas: tuple[float, float],
    size_wh: tuple[float, float],
    hidden: tuple[float, float],
    shifted: tuple[bool, bool],
    hidden_length_sigma: float,
) -> tuple[float, float]:
    """The centre sigmas (px) of a box moved to the whole item's centre on each ``shifted`` axis:
    sigma' = hypot(sigma, (w + hid) s / 2, k hid) with s = hypot(2 sigma_u / w, 2 sigma_v / h)
    the box shape's relative error (a side errs by both its edges, each as the centre: twice
    the centre's sigma) and k = ``hidden_length_sigma`` / 2, half the hidden length's own error.

    >>> [round(s, 3) for s in whole_item_sigmas((2.0, 2.0), (100.0, 60.0), (0.0, 40.0), (False, True), 0.25)]
    [2.0, 6.642]
    """
    (sigma_u, sigma_v), (w, h), (hid_w, hid_h) = sigmas, size_wh, hidden
    shape_sigma = math.hypot(2.0 * sigma_u / w, 2.0 * sigma_v / h)
    k = 0.5 * hidden_length_sigma
    if shifted[0]:
        sigma_u = math.hypot(sigma_u, 0.5 * (w + hid_w) * shape_sigma, k * hid_w)
    if shifted[1]:
        sigma_v = math.hypot(sigma_v, 0.5 * (h + hid_h) * shape_sigma, k * hid_h)
    return sigma_u, sigma_v


@dataclass(kw_only=True)
class FlatSign(Shape):
    """A flat rectangle of width / height ``aspect``, measured on its box's depth plane.

    Its depth is the plane's at the box centre (:meth:`poi.estimation.box_depth.DepthPlane.
    depth_at`, variance :func:`poi.estimation.box_depth.plane_depth_variance`; the median and
    its variance where no plane fits): on a sloping sign the median is the depth where the
    block's valid pixels centre, off the box centre's where holes lie to one side. Its point is
    its centre measured on the plane (:func:`~poi.estimation.shapes.plane_item.flat_item`).

    Its box is cut on an axis only where the image border (``localize.border_px`` plus
    ``localize.flat_border_sigmas`` of its centre sigmas) or a nearer surface
    (:func:`poi.estimation.box_cuts.occluded_sides`) borders it; its shape says by how much
    (:meth:`measure_item`), and Sigma_1's centre sigma there grows by half the hidden length.
    Cut by the image border on one side, it is centred on the whole item instead
    (:func:`whole_item_sigmas`). A box at the border on both axes gives no observation: its
    shape cannot say how much is hidden.
    """

    aspect: float = 1.0
    plane_depth: ClassVar[bool] = True
    # a diamond's corners touch its box at its centre line; a turned one's anywhere
    # (poi.estimation.shapes.plane_item.flat_item)
    diamond: ClassVar[bool] = False
    turned: ClassVar[bool] = False

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
        plane = depth.plane
        d = (plane.depth_at(u, v) if plane is not None else depth.median) * lc.depth_scale
        if not in_range(d, lc):
            return None
        point = self.point(intr)
        p_c = point(u, v, d)
        margin = border_margin(lc, lc.flat_border_sigmas, sigmas)
        at = box_at_border(detection.box_xyxy, intr.width, intr.height, margin)
        if all(at):
            return None
        occ = (False, False)
        if lc.occluder_margin_m > 0.0:
            occ = occluded_sides(depth_m, detection.box_xyxy, depth.surface, lc.occluder_margin_m / lc.depth_scale)
        toward = border_sides(detection.box_xyxy, intr.width, intr.height, margin)
        cause = (at[0] or occ[0], at[1] or occ[1])
        item = self.measure_item(
            detection, intr, (u, v, d), depth, lc, depth_m, at_border=at, cause=cause, toward=toward
        )
        shifted = (item.shift_u != 0.0, item.shift_v != 0.0)
        hid = (item.hidden_w, item.hidden_h)
        if any(shifted):
            # the whole item's box centre, and its depth on the plane there
            u, v = u + item.shift_u, v + item.shift_v
            if plane is not None:
                d = plane.depth_at(u, v) * lc.depth_scale
            p_c = point(u, v, d)
            sigmas = whole_item_sigmas(sigmas, detection.size_wh, hid, shifted, lc.hidden_length_sigma)
            hid = (0.0 if shifted[0] else hid[0], 0.0 if shifted[1] else hid[1])
        turn = (0.0, 0.0)
        if item.centre is not None:
            p_c, turn = item.centre, item.turn_sigma_px
        # sigma'^2 = sigma^2 + turn^2 + (hid / 2)^2: the turn's spread, half the hidden length
        sigma_u = math.hypot(math.hypot(sigmas[0], turn[0]), 0.5 * hid[0])
        sigma_v = math.hypot(math.hypot(sigmas[1], turn[1]), 0.5 * hid[1])
        if plane is not None:
            var_depth = plane_depth_variance(plane, u, v, lc.depth_scale)
        else:
            var_depth = median_depth_variance(depth_m, detection.box_xyxy, lc, d, depth.median)
        return Measured(
            p_c=p_c, u=u, v=v, d=d, sigma_u=sigma_u, sigma_v=sigma_v, var_depth=var_depth, box_cut=(at[0], at[1])
        )

    def measure_item(
        self,
        detection: Detection,
        intr: Intrinsics,
        uvd: tuple[float, float, float],
        depth: BoxDepth,
        lc: LocalizeConfig,
        depth_m: np.ndarray,
        *,
        at_border: tuple[bool, bool],
        cause: tuple[bool, bool],
        toward: tuple[int, int],
    ) -> FlatMeasure:
        """The item measured from its box at pixel and depth ``uvd`` (:class:`FlatMeasure`): its
        centre on the depth plane (:func:`~poi.estimation.shapes.plane_item.flat_item`) when the
        plane's tilt is known to ``localize.flat_max_slope_sigma`` (of its tangent,
        :func:`poi.estimation.box_depth.plane_slope_sigma`), else None; and the pixels its box
        leaves out on each axis with a ``cause`` (the image border or a nearer surface beside it:
        a sign on a wall is hidden only by something), from its shape against ``aspect``
        (:func:`poi.estimation.box_cuts.hidden_lengths_px`; no tolerance on an axis
        ``at_border``).

        The shape is judged on the plane when its tilt is known: a plane tilted by its error
        theta lengthens a side by 1 / cos(theta) - 1, about theta^2 / 2, so the tolerance grows by
        slope_sigma^2 (two sigmas' worth). Else on the most face-on plane the depth allows
        (:func:`least_tilted_gradient`, ``localize.flat_tilt_sigmas``), fitted to the whole box
        (a wider base than the inner block), or to the inner block when that fit fails: the
        widest the item can look, so the hidden length is a bound at that many sigmas.

        Where the image border on side ``toward`` (-1 left / top, +1 right / bottom:
        :func:`poi.estimation.box_cuts.border_sides`) cut the box and the tilt is known, the box
        is taken to go on past that border by the hidden length, and the centre is the whole
        item's (``shift_u``, ``shift_v``: the move of the box centre in pixels).
        """
        u, v, d = uvd
        slope_sigma = plane_slope_sigma(depth.var_g, intr, d)
        fitted = slope_sigma <= lc.flat_max_slope_sigma
        turned = fitted and self.turned  # the turn model only where the centre is kept
        item = flat_item(intr, u, v, d, depth.grad, detection.box_xyxy, self.diamond, turned)
        shape = item if fitted else self._face_on_item(intr, uvd, depth, lc, depth_m, detection.box_xyxy)
        hid_w = hid_h = 0.0
        if shape is not None:
            tol = lc.truncation_tolerance + (slope_sigma**2 if fitted else 0.0)
            hid_w, hid_h = self._hidden(detection.size_wh, (shape.width_m, shape.height_m), tol, at_border)
            hid_w, hid_h = (hid_w if cause[0] else 0.0), (hid_h if cause[1] else 0.0)
        # the hidden part's side is known at the border, and its length where the tilt is (else
        # the face-on bound is an upper bound only)
        shift_u = 0.5 * hid_w * toward[0] if fitted else 0.0
        shift_v = 0.5 * hid_h * toward[1] if fitted else 0.0
        if shift_u or shift_v:
            # the whole item's box: the cut one gone on past the border by the hidden length
            x1, y1, x2, y2 = (float(c) for c in detection.box_xyxy)
            whole = (
                x1 + min(2.0 * shift_u, 0.0),
                y1 + min(2.0 * shift_v, 0.0),
                x2 + max(2.0 * shift_u, 0.0),
                y2 + max(2.0 * shift_v, 0.0),
            )
            item = flat_item(intr, u, v, d, depth.grad, whole, self.diamond, turned)
        centre = item.center if item is not None and fitted else None
        turn = item.turn_sigma_px if item is not None and centre is not None else (0.0, 0.0)
        return FlatMeasure(
            centre=centre, hidden_w=hid_w, hidden_h=hid_h, shift_u=shift_u, shift_v=shift_v, turn_sigma_px=turn
        )

    def _face_on_item(self, intr, uvd, depth: BoxDepth, lc: LocalizeConfig, depth_m: np.ndarray, box_xyxy):
        """The item on the most face-on plane within ``localize.flat_tilt_sigmas`` of the whole
        box's depth plane (of the inner block's, where the whole box's fails)."""
        u, v, d = uvd
        grad, var_g = depth.grad, depth.var_g
        sigma_px = depth_sigma_m(d, sigma_d_px=lc.sigma_d_px, fx_depth_px=lc.fx_depth_px, baseline_m=lc.baseline_m)
        wide = box_depth_plane(depth_m, box_xyxy, 1.0, lc.depth_window_px, sigma_px, split_m=lc.depth_split_m)
        if wide is not None:
            grad, var_g = (wide.g_u, wide.g_v), (wide.var_g_u, wide.var_g_v)
        least = least_tilted_gradient(grad, var_g, lc.flat_tilt_sigmas)
        return flat_item(intr, u, v, d, least, box_xyxy, self.diamond)

    def _hidden(
        self, size_wh: tuple[float, float], size_m: tuple[float, float], tol: float, at_border: tuple[bool, bool]
    ) -> tuple[float, float]:
        """Pixels hidden across u and v: by the shape at tolerance ``tol``, and at no tolerance on
        an axis whose box touches the image border."""
        hid_w, hid_h = hidden_lengths_px(size_wh, size_m, self.aspect, tol)
        at_u, at_v = at_border
        if at_u or at_v:
            bw, bh = hidden_lengths_px(size_wh, size_m, self.aspect, 0.0)
            hid_w = max(hid_w, bw) if at_u else hid_w
            hid_h = max(hid_h, bh) if at_v else hid_h
        return hid_w, hid_h
