"""Thermal hot spots on synthetic 160x120 images registered to a 640x480 colour camera.

The thermal intrinsics are the colour ones scaled by 1/4, so a thermal box with
pixel edges (x1, y1, x2, y2) is (4 x1, 4 y1, 4 x2, 4 y2) in colour pixels.
"""

from __future__ import annotations

import numpy as np
import pytest

from poi.core.names import CLASS_INDEX, RESCUE_CLASSES
from poi.core.types import Frame, Intrinsics
from poi.detectors import ThermalFrameError, ThermalHotSpotDetector, build_detector
from poi.detectors.base import DetectorConfigError

K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)
K_T = K.scaled(160, 120)
AMBIENT_C = 22.0
BOX_TOL_PX = 1e-6  # an affine map of small integers: exact up to float rounding


def _frame(temp_c: np.ndarray | None, K_t: Intrinsics | None = K_T) -> Frame:
    return Frame(
        index=3,
        timestamp_s=0.1,
        rgb=np.zeros((480, 640, 3), np.uint8),
        intrinsics=K,
        thermal_c=temp_c,
        thermal_intrinsics=K_t if temp_c is not None else None,
    )


def _room(rng: np.random.Generator) -> np.ndarray:
    """22 C walls with 0.3 C sensor noise."""
    return (AMBIENT_C + 0.3 * rng.standard_normal((120, 160))).astype(np.float32)


def test_hot_block_box_and_confidence():
    T = _room(np.random.default_rng(0))
    T[30:36, 40:48] = 60.0  # rows 30..35, cols 40..47: edges (40, 30, 48, 36)
    T[32, 44] = 62.5  # peak: confidence 0.5 + 0.49 * (62.5 - 45) / (80 - 45) = 0.745
    (d,) = ThermalHotSpotDetector().detect(_frame(T))
    assert np.allclose(d.box_xyxy, (160.0, 120.0, 192.0, 144.0), atol=BOX_TOL_PX)
    assert (d.class_name, d.type, d.text, d.source) == ("heat-source", "heat-source", "", "thermal")
    assert d.confidence == pytest.approx(0.745, abs=1e-9)
    p = d.class_probs
    assert p[CLASS_INDEX["heat-source"]] == pytest.approx(0.745)
    # the rest spread over the other 23 rescue classes; a rescue detector never says "pillar"
    rescue = p[: len(RESCUE_CLASSES)]
    assert np.allclose(np.delete(rescue, CLASS_INDEX["heat-source"]), 0.255 / 23)
    assert np.all(p[len(RESCUE_CLASSES) :] == 0.0)


def test_doll_at_body_temperature_is_not_a_heat_source():
    T = _room(np.random.default_rng(1))
    T[50:80, 60:90] = 37.0  # a doll filling 900 thermal pixels, 15 C above ambient
    assert ThermalHotSpotDetector().detect(_frame(T)) == []


def test_ambient_delta_gate_in_a_warm_room():
    # Ambient 40 C: a 48 C patch passes 45 C but is only 8 C (< 10) above ambient; 55 C passes.
    T = np.full((120, 160), 40.0, np.float32)
    T[10:14, 10:14] = 48.0
    T[60:64, 100:104] = 55.0
    (d,) = ThermalHotSpotDetector().detect(_frame(T))
    assert np.allclose(d.box_xyxy, (400, 240, 416, 256), atol=BOX_TOL_PX)


def test_min_area_and_connectivity():
    T = _room(np.random.default_rng(2))
    T[5, 5:8] = 70.0  # 3 pixels: below the default 4
    T[20:22, 20:22] = 50.0  # 2x2 block ...
    T[22:24, 22:24] = 55.0  # ... touching it diagonally: one 8-connected region of 8 px
    out = ThermalHotSpotDetector().detect(_frame(T))
    assert len(out) == 1
    assert np.allclose(out[0].box_xyxy, (80, 80, 96, 96), atol=BOX_TOL_PX)
    out = ThermalHotSpotDetector(min_area_px=3).detect(_frame(T))
    # Hottest first: the 70 C strip (conf 0.5 + 0.49 * 25 / 35 = 0.85) then the 55 C block.
    assert [round(d.confidence, 6) for d in out] == [0.85, 0.64]
    assert np.allclose(out[0].box_xyxy, (20, 20, 32, 24), atol=BOX_TOL_PX)


def test_nan_and_inf_pixels_are_ignored():
    T = _room(np.random.default_rng(3))
    T[:, :40] = np.nan  # a dead quarter of the sensor
    T[100, 150] = np.inf  # a stuck pixel: not a heat source
    T[100:104, 60:64] = 50.0
    T[101, 61] = np.nan  # a hole inside the hot patch: its region is still found, peak 50
    (d,) = ThermalHotSpotDetector().detect(_frame(T))
    assert np.allclose(d.box_xyxy, (240, 400, 256, 416), atol=BOX_TOL_PX)
    assert d.confidence == pytest.approx(0.5 + 0.49 * 5 / 35)
    assert ThermalHotSpotDetector().detect(_frame(np.full((120, 160), np.nan, np.float32))) == []


def test_no_thermal_gives_nothing():
    assert ThermalHotSpotDetector().detect(_frame(None)) == []


def test_general_intrinsics_mapping():
    # A thermal camera with its own principal point: u_c = 314.3 + 4 (e - 0.5 - 80) + 0.5 on
    # x edges e, v_c = 237.8 + 4 (e - 0.5 - 60) + 0.5 on y edges.
    K_t = Intrinsics(width=160, height=120, fx=153.1, fy=152.65, ppx=80.0, ppy=60.0)
    T = _room(np.random.default_rng(4))
    T[30:36, 40:48] = 60.0
    (d,) = ThermalHotSpotDetector().detect(_frame(T, K_t))
    expected = (
        314.3 + 4 * (40 - 80.5) + 0.5,
        237.8 + 4 * (30 - 60.5) + 0.5,
        314.3 + 4 * (48 - 80.5) + 0.5,
        237.8 + 4 * (36 - 60.5) + 0.5,
    )
    assert np.allclose(d.box_xyxy, expected, atol=1e-6)


def test_missing_thermal_intrinsics_defaults_to_scaled_colour():
    T = _room(np.random.default_rng(5))
    T[30:36, 40:48] = 60.0
    (d,) = ThermalHotSpotDetector().detect(_frame(T, None))
    assert np.allclose(d.box_xyxy, (160, 120, 192, 144), atol=BOX_TOL_PX)


def test_bad_inputs_and_settings():
    with pytest.raises(ThermalFrameError, match="thermal_intrinsics are 160x120 but thermal_c"):
        ThermalHotSpotDetector().detect(_frame(np.zeros((60, 80), np.float32)))
    with pytest.raises(ThermalFrameError, match="must be \\(h, w\\)"):
        ThermalHotSpotDetector().detect(_frame(np.zeros((120, 160, 3), np.float32)))
    with pytest.raises(DetectorConfigError, match="full_conf_temp_c"):
        ThermalHotSpotDetector(min_temp_c=90.0)
    det = build_detector({"name": "thermal", "min_temp_c": 40.0, "min_area_px": 2})
    assert isinstance(det, ThermalHotSpotDetector) and det.name == "thermal"


def test_a_finned_heaters_stripes_are_one_source():
    """A heater seen close: seven 62 C fins 6 px wide with 5 px gaps at ambient between them
    (the shipped heater's 1.3 cm gaps at about 0.35 m) are one source whose box spans them
    all; a second source 9 px further (over the default 8 px gap) stays apart; with
    ``merge_gap_px: 0`` each fin is its own."""
    T = _room(np.random.default_rng(6))
    for k in range(7):
        T[100:120, 10 + 11 * k : 16 + 11 * k] = 62.0  # cols 10..15, 21..26, ..., 76..81
    T[100:110, 91:95] = 70.0  # 9 px right of the last fin (cols 82..90 cool)
    heater, lamp = sorted(ThermalHotSpotDetector().detect(_frame(T)), key=lambda d: d.box_xyxy[0])
    assert np.allclose(heater.box_xyxy, (40, 400, 328, 480), atol=BOX_TOL_PX)
    assert np.allclose(lamp.box_xyxy, (364, 400, 380, 440), atol=BOX_TOL_PX)
    assert len(ThermalHotSpotDetector(merge_gap_px=0).detect(_frame(T))) == 8
    # a gap of exactly merge_gap_px bridges, one more does not
    assert len(ThermalHotSpotDetector(merge_gap_px=5).detect(_frame(T))) == 2
    assert len(ThermalHotSpotDetector(merge_gap_px=4).detect(_frame(T))) == 8
    with pytest.raises(DetectorConfigError, match="merge_gap_px must be >= 0"):
        ThermalHotSpotDetector(merge_gap_px=-1)
