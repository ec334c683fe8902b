"""eval.experiments.extent_fit: the offset and the spreads along and across the ray, recovered from errors
drawn with known ones."""

from __future__ import annotations

import numpy as np
import pytest

from eval.experiments.extent_fit import ExtentSample, fit_extents, fit_type, fitted_settings
from poi.config import apply_overrides, load_config


def _samples(type_: str, ray: np.ndarray, bias: float, s_ray: float, s_lat: float, n: int, seed: int):
    rng = np.random.default_rng(seed)
    r = ray / np.linalg.norm(ray)
    u = np.cross(r, [0.0, 0.0, 1.0]) if abs(r[2]) < 0.9 else np.cross(r, [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(r, u)
    S = (0.005**2) * np.eye(3)  # the sensor part, drawn too
    out = []
    for i in range(n):
        e = (bias + s_ray * rng.standard_normal()) * r + s_lat * (
            rng.standard_normal() * u + rng.standard_normal() * v
        )
        e = e + rng.multivariate_normal(np.zeros(3), S)
        out.append(ExtentSample(type=type_, object_key=i % 3, e_cam=e, Sigma_c=S, ray=r))
    return out


def test_an_oblique_ray_separates_the_spread_along_it_from_the_spread_across():
    along = fit_type(_samples("door", np.array([1.0, 1.0, 1.0]), 0.08, 0.05, 0.0, 3000, 0))
    assert along.offset_change_m == pytest.approx(-0.08, abs=0.003)  # observed farther: the offset shrinks
    assert along.sigma_ray_m == pytest.approx(0.05, rel=0.05) and along.sigma_lat_m < 0.005
    across = fit_type(_samples("door", np.array([-0.3, 0.2, 1.0]), 0.0, 0.0, 0.04, 3000, 1))
    assert across.sigma_lat_m == pytest.approx(0.04, rel=0.05) and across.sigma_ray_m < 0.005
    assert across.objects == 3


def test_fitted_settings_start_from_the_configs_offsets_and_load():
    cfg = load_config()
    samples = _samples("valve", np.array([0.0, 0.0, 1.0]), 0.1, 0.02, 0.03, 2000, 2)
    samples += _samples("door", np.array([0.0, 0.0, 1.0]), -0.02, 0.05, 0.05, 2000, 3)
    fits = fit_extents(samples)
    assert [f.type for f in fits] == ["door", "valve"]
    new = apply_overrides(cfg, fitted_settings(fits, cfg)).localize
    old = cfg.localize.types
    assert new.types["valve"].surface_to_center_m == pytest.approx(
        old["valve"].surface_to_center_m - 0.1, abs=0.005
    )
    assert new.types["door"].surface_to_center_m == pytest.approx(
        old["door"].surface_to_center_m + 0.02, abs=0.005
    )
    assert new.types["valve"].extent_ray_sigma_m == pytest.approx(0.02, abs=0.003)
    assert new.types["ball"] == old["ball"]  # a type with no samples keeps its row
    assert new.types["door"].box_width_m == old["door"].box_width_m  # no box size fitted: kept
    # a type without a row gets one, a body
    (landolt,) = fit_extents(_samples("landolt-c", np.array([0.0, 0.0, 1.0]), 0.1, 0.02, 0.03, 200, 5))
    row = apply_overrides(cfg, fitted_settings([landolt], cfg)).localize.types["landolt-c"]
    assert row.shape == "body" and row.surface_to_center_m == round(landolt.offset_change_m, 3)


def test_the_box_size_is_the_75th_percentile_of_the_uncut_boxes_and_loads():
    """Boxes of 0.10-0.50 m by 0.2-1.0 m (uniform) in full view, and a border-cut one that is
    smaller still (ignored): the fitted size is the uncut boxes' 75th percentile, 0.4 x 0.8 m."""
    cfg = load_config()
    samples = _samples("valve", np.array([0.0, 0.0, 1.0]), 0.0, 0.02, 0.03, 401, 4)
    for i, s in enumerate(samples):
        s.box_m = (0.1 + 0.4 * i / 400, 0.2 + 0.8 * i / 400)
    samples[0].box_m = None
    (fit,) = fit_extents(samples)
    assert (fit.box_width_m, fit.box_height_m) == pytest.approx((0.401, 0.802), abs=0.002)
    new = apply_overrides(cfg, fitted_settings([fit], cfg)).localize
    assert (new.types["valve"].box_width_m, new.types["valve"].box_height_m) == (
        round(fit.box_width_m, 3),
        round(fit.box_height_m, 3),
    )
    assert new.types["door"].box_height_m == cfg.localize.types["door"].box_height_m  # no samples: kept
    for s in samples:
        s.box_m = None
    assert fit_type(samples).box_width_m is None  # no box in full view: no size
