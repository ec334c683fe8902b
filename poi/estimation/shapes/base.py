"""What every shape shares: its settings from a row of ``localize.types``, its deprojection, its
extent, and the record of what it measured ([Avevor2022]_ 2.2-2.3).

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from poi.core.types import Detection, Intrinsics
from poi.estimation.box_depth import BoxDepth
from poi.estimation.projection import BOX_CORNER_TO_CENTER_PX, deproject_pixel_to_point, surface_to_center

if TYPE_CHECKING:
    from poi.config import LocalizeConfig, TypeShapeConfig


@dataclass(kw_only=True)
class Measured:
    """What a shape measures of a detection, in the camera frame: the centre ``p_c`` deprojected
    from pixel (``u``, ``v``) at depth ``d`` (m) and moved to the item's reference point;
    Sigma_1's centre sigmas (px) and depth variance (m^2) ([Avevor2022]_ 2.2.2); the variances
    (px^2, across u and v) of a hidden length that moves the centre across the ray only (J2,
    not J1); and the axes (u, v) on which its box is cut."""

    p_c: np.ndarray
    u: float
    v: float
    d: float
    sigma_u: float
    sigma_v: float
    var_depth: float
    hidden_var: tuple[float, float] = (0.0, 0.0)
    box_cut: tuple[bool, bool] = (False, False)


@dataclass(kw_only=True)
class Shape:
    """A geometry that localises a type: its settings are a row of ``localize.types``
    (:class:`poi.config.TypeShapeConfig`); :meth:`measure` gives its :class:`Measured`.

    ``surface_to_center_m``: from the surface the depth hits to the reference point, along the
    ray (:func:`poi.estimation.projection.surface_to_center`); ``extent_sigma_m`` and
    ``extent_ray_sigma_m``: the reference point's spread across and along the ray
    (:func:`poi.estimation.localize.extent_covariance`; along, as across when None)."""

    surface_to_center_m: float = 0.0
    extent_sigma_m: float = 0.0
    extent_ray_sigma_m: float | None = None
    # its depth read on the box's depth plane (a flat item), whose fit then gives the plane
    # depth's variance (poi.estimation.box_depth.read_box_depth); else the median's
    plane_depth: ClassVar[bool] = False

    @classmethod
    def from_row(cls, row: TypeShapeConfig) -> Shape:
        """The shape with the numbers of ``row`` that it takes (the row's check says which)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in dataclasses.asdict(row).items() if k in names})

    def point(self, intr: Intrinsics) -> Callable[[float, float, float], np.ndarray]:
        """p(u, v, d): pixel and depth to the reference point, surface_to_center(deproject(u, v, d), r)."""
        r = self.surface_to_center_m

        def point(a: float, b: float, c: float) -> np.ndarray:
            return surface_to_center(deproject_pixel_to_point(intr, a, b, c), r)

        return point

    def extent_sigmas(self) -> tuple[float, float]:
        """(sigma_lat, sigma_ray): across and along the ray (:func:`poi.estimation.localize.extent_covariance`)."""
        ray = self.extent_sigma_m if self.extent_ray_sigma_m is None else self.extent_ray_sigma_m
        return self.extent_sigma_m, ray

    def measure(
        self,
        detection: Detection,
        intr: Intrinsics,
        depth_m: np.ndarray,
        depth: BoxDepth,
        lc: LocalizeConfig,
        sigmas: tuple[float, float],
    ) -> Measured | None:
        """The detection measured (``sigmas``: its box centre's, [Avevor2022]_ 2.1.4); None
        where the shape gives no observation (a depth out of range, a box it cannot use)."""
        raise NotImplementedError


def box_pixel(detection: Detection) -> tuple[float, float]:
    """The box centre as a pixel coordinate: u = cx - 0.5 (corner to pixel-centre convention)."""
    cx, cy = detection.center_uv
    return cx - BOX_CORNER_TO_CENTER_PX, cy - BOX_CORNER_TO_CENTER_PX


def in_range(d: float, lc: LocalizeConfig) -> bool:
    """``localize.min_depth_m`` <= d <= ``localize.max_depth_m``."""
    return lc.min_depth_m <= d <= lc.max_depth_m


def border_margin(lc: LocalizeConfig, n_sigmas: float, sigmas: tuple[float, float]) -> tuple[float, float]:
    """(u, v): ``localize.border_px`` plus ``n_sigmas`` of the box centre's sigmas on each axis."""
    return lc.border_px + n_sigmas * sigmas[0], lc.border_px + n_sigmas * sigmas[1]
