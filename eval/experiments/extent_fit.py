"""Fit a 3-D object type's centre offset and extent spreads from camera-frame errors.

A 3-D object's observation is the surface the depth hits, moved its type's
``surface_to_center_m`` (``localize.types``) along the camera ray r; R gets the spread of what
remains, ``extent_ray_sigma_m`` along r and ``extent_sigma_m`` across it
(:func:`poi.estimation.localize.extent_covariance`). Given the
camera-frame errors e = observation - truth of many observations of one type, each with its
sensor covariance Sigma_c (the detection and depth model alone) and its ray r, this module finds
the values that make them consistent (``poibench consistency --fit-extents``):

* the offset: the mean b of e . r is how much farther along the ray the observation lies than
  the truth, so the offset changes by -b (a thin valve's median depth reads the wall behind
  it: its offset comes out negative, the reference point in front of the surface seen);
* sigma_ray: the root of mean((e . r - b)^2 / (r^T Sigma_c r + sigma^2)) = 1, the NEES along r;
* sigma_lat: the root of the mean 2-D NEES across r, with sigma^2 I added to Sigma_c's
  block there, = 2;

each 0 when the sensor model alone already brings its NEES down to the target. The fit is the
method of moments on the NEES, so a few gross errors weigh in full, as they do in the NEES.

It also gives the width and height a type's box spans in full view (its row's ``box_width_m``,
``box_height_m``: how much of an item the image border hides, :func:`poi.estimation.box_cuts.
hidden_solid_px`): the 75th percentile of w z / fx and h z / fy over the boxes that touch no
image border.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

SIGMA_MAX_M = 1.0  # the largest spread searched


@dataclass(kw_only=True)
class ExtentSample:
    """One observation of a 3-D object: its camera-frame error, sensor covariance and ray."""

    type: str
    object_key: object  # which object in which run, to count objects
    e_cam: np.ndarray
    Sigma_c: np.ndarray
    ray: np.ndarray  # unit vector from the camera to the observation
    # the box's (w z / fx, h z / fy) in metres at the observation's depth z; None when it is cut
    # (Observation.box_cut: by the image border or a nearer surface; not the item's full size)
    box_m: tuple[float, float] | None = None


@dataclass(kw_only=True)
class ExtentFit:
    """What one type's samples say: the offset to add, and the spreads along and across the ray."""

    type: str
    n: int
    objects: int
    offset_change_m: float
    sigma_ray_m: float
    sigma_lat_m: float
    box_width_m: float | None  # None: no box in full view
    box_height_m: float | None


BOX_SIZE_PERCENTILE = 75.0


def box_size_m(samples: list[ExtentSample]) -> tuple[float, float] | tuple[None, None]:
    """The (width, height) in metres three in four of the samples' uncut boxes span no more
    than (their 75th percentile); None when none is uncut.

    >>> xs = [ExtentSample(type="valve", object_key=0, e_cam=np.zeros(3), Sigma_c=np.eye(3), ray=np.ones(3),
    ...                    box_m=(0.1 * k, 0.2 * k)) for k in range(1, 6)]
    >>> [round(x, 3) for x in box_size_m(xs + [ExtentSample(type="valve", object_key=0, e_cam=np.zeros(3),
    ...                                    Sigma_c=np.eye(3), ray=np.ones(3))])]
    [0.4, 0.8]
    """
    sizes = np.array([s.box_m for s in samples if s.box_m is not None], dtype=float).reshape(-1, 2)
    if len(sizes) == 0:
        return None, None
    w, h = np.percentile(sizes, BOX_SIZE_PERCENTILE, axis=0)
    return float(w), float(h)


def _solve_spread(nees_of_variance, target: float) -> float:
    """The sigma >= 0 whose variance brings ``nees_of_variance`` down to ``target`` (it falls
    as the variance grows); 0 when it is already at or below the target."""
    f = lambda s: nees_of_variance(s * s) - target  # noqa: E731
    if f(0.0) <= 0.0:
        return 0.0
    if f(SIGMA_MAX_M) > 0.0:
        return SIGMA_MAX_M
    return float(brentq(f, 0.0, SIGMA_MAX_M, xtol=1e-5))


def fit_type(samples: list[ExtentSample]) -> ExtentFit:
    """The fit of one type's samples (module docstring).

    >>> rng = np.random.default_rng(0)
    >>> S = 1e-4 * np.eye(3)
    >>> spread = rng.normal([0.0, 0.0, 0.05], [0.03, 0.03, 0.02], (4000, 3))  # the extent's
    >>> e = spread + rng.normal(0.0, 0.01, (4000, 3))  # and the sensor's, Sigma_c
    >>> xs = [ExtentSample(type="door", object_key=i % 4, ray=np.array([0.0, 0.0, 1.0]), Sigma_c=S, e_cam=e[i])
    ...       for i in range(4000)]
    >>> f = fit_type(xs)
    >>> round(f.offset_change_m, 2), round(f.sigma_ray_m, 2), round(f.sigma_lat_m, 2), f.objects
    (-0.05, 0.02, 0.03, 4)
    """
    if not samples:
        raise ValueError("fit_type: no samples")
    e = np.array([s.e_cam for s in samples], dtype=float)
    S = np.array([s.Sigma_c for s in samples], dtype=float)
    r = np.array([s.ray for s in samples], dtype=float)
    along = np.einsum("ij,ij->i", e, r)
    bias = float(along.mean())
    s_rr = np.einsum("ij,ijk,ik->i", r, S, r)
    # an orthonormal basis (u, v) of the plane across each ray
    helper = np.where(np.abs(r[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(r, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(r, u)
    B = np.stack([u, v], axis=2)  # n x 3 x 2
    x = np.einsum("ijk,ij->ik", B, e)  # the error across the ray, in (u, v)
    S_lat = np.einsum("ijk,ijl,ilm->ikm", B, S, B)  # B^T Sigma_c B

    def ray_nees(var: float) -> float:
        return float(np.mean((along - bias) ** 2 / (s_rr + var)))

    def lat_nees(var: float) -> float:
        return float(
            np.mean(np.einsum("ik,ik->i", x, np.linalg.solve(S_lat + var * np.eye(2), x[..., None])[..., 0]))
        )

    box_w, box_h = box_size_m(samples)
    return ExtentFit(
        box_width_m=box_w,
        box_height_m=box_h,
        type=samples[0].type,
        n=len(samples),
        objects=len({s.object_key for s in samples}),
        offset_change_m=-bias,
        sigma_ray_m=_solve_spread(ray_nees, 1.0),
        sigma_lat_m=_solve_spread(lat_nees, 2.0),
    )


def fit_extents(samples: list[ExtentSample]) -> list[ExtentFit]:
    """One fit per type, in type order."""
    by_type: dict[str, list[ExtentSample]] = {}
    for s in samples:
        by_type.setdefault(s.type, []).append(s)
    return [fit_type(by_type[t]) for t in sorted(by_type)]


def fitted_settings(fits: list[ExtentFit], cfg) -> list[str]:
    """The ``localize.types`` settings the fits give, one ``KEY=VALUE`` a number of a type's row,
    from the pipeline config ``cfg`` the samples were taken with (its offsets are where the new
    ones start from; a type without a row gets one, a body)."""
    out = []
    for f in fits:
        row = cfg.localize.types.get(f.type)
        values = {
            "surface_to_center_m": round((0.0 if row is None else row.surface_to_center_m) + f.offset_change_m, 3),
            "extent_ray_sigma_m": round(f.sigma_ray_m, 3),
            "extent_sigma_m": round(f.sigma_lat_m, 3),
        }
        if f.box_width_m is not None:
            values.update(box_width_m=round(f.box_width_m, 3), box_height_m=round(f.box_height_m, 3))
        out += [f"localize.types.{f.type}.{k}={v:g}" for k, v in values.items()]
    return out


def format_fits(fits: list[ExtentFit]) -> str:
    """The table ``poibench consistency --fit-extents`` prints."""
    cols = f"{'offset change (m)':>18} {'sigma ray (m)':>14} {'sigma lat (m)':>14} {'box w x h (m)':>14}"
    head = f"{'type':<20} {'N':>5} {'objects':>7} {cols}"
    lines = [head, "-" * len(head)]
    for f in fits:
        box = "-" if f.box_width_m is None else f"{f.box_width_m:.3f} x {f.box_height_m:.3f}"
        fit = f"{f.offset_change_m:>18.3f} {f.sigma_ray_m:>14.3f} {f.sigma_lat_m:>14.3f} {box:>14}"
        lines.append(f"{f.type:<20} {f.n:>5} {f.objects:>7} {fit}")
    return "\n".join(lines) + "\n"
