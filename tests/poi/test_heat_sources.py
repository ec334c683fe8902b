"""poi.heat_sources: heat-source boxes of a colour network stand where the thermal camera sees heat."""

from __future__ import annotations

import numpy as np
import pytest

from poi.config import apply_overrides, load_config
from poi.core.types import Frame, Intrinsics
from poi.detectors.base import make_detection
from poi.detectors.thermal import ThermalHotSpotDetector
from poi.heat_sources import frame_has_thermal_view, vouched_for
from poi.pipeline import Pipeline

K = Intrinsics(width=640, height=480, fx=500.0, fy=500.0, ppx=319.5, ppy=239.5)
HEATER_BOX = (280.0, 200.0, 360.0, 280.0)  # the colour network's box on a hot heater
CRATE_BOX = (40.0, 360.0, 120.0, 440.0)  # its box on a cold red crate


def det(name, box, source, conf=0.6):
    return make_detection(name, box, conf, source=source, class_probs=None)


def test_a_colour_box_stands_only_where_a_thermal_box_overlaps_it():
    thermal = det("heat-source", (300.0, 220.0, 330.0, 250.0), "thermal", 0.9)
    onnx_on_heater = det("heat-source", HEATER_BOX, "onnx")
    onnx_on_crate = det("heat-source", CRATE_BOX, "onnx")
    door = det("door", CRATE_BOX, "onnx")  # other types are not the thermal camera's to judge
    kept = vouched_for([onnx_on_crate, thermal, door, onnx_on_heater])
    assert kept == [thermal, door, onnx_on_heater]


def test_boxes_that_only_touch_do_not_overlap_and_no_thermal_box_drops_every_colour_one():
    touching = det("heat-source", (360.0, 200.0, 400.0, 280.0), "onnx")  # shares the edge x = 360
    thermal = det("heat-source", HEATER_BOX, "thermal", 0.9)
    assert vouched_for([touching, thermal]) == [thermal]
    assert vouched_for([det("heat-source", HEATER_BOX, "onnx")]) == []


def frame(index: int, thermal_c: np.ndarray | None, rgb: bool = True) -> Frame:
    return Frame(
        index=index,
        timestamp_s=0.1 * index,
        rgb=np.full((K.height, K.width, 3), 40, np.uint8) if rgb else np.zeros((0, 0, 3), np.uint8),
        intrinsics=K,
        depth_m=np.full((K.height, K.width), 2.0, np.float32),
        pose=np.eye(4),
        thermal_c=thermal_c,
    )


def thermal_image(hot_box_colour_px: tuple[int, int, int, int] | None) -> np.ndarray:
    """A 160 x 120 thermal image at 20 C, with a 70 C patch under the given colour-pixel box."""
    t = np.full((120, 160), 20.0, np.float32)
    if hot_box_colour_px is not None:
        x1, y1, x2, y2 = (v // 4 for v in hot_box_colour_px)  # the thermal image is the colour one / 4
        t[y1:y2, x1:x2] = 70.0
    return t


class ColourBoxes:
    """A colour network that boxes the heater and the crate as heat sources every frame."""

    def detect(self, frame: Frame):
        return [det("heat-source", HEATER_BOX, "onnx"), det("heat-source", CRATE_BOX, "onnx")]


def pipeline(*sets: str) -> Pipeline:
    cfg = apply_overrides(load_config(), ["slam.odometry_latency_s=0", "qr.enabled=false", *sets])
    return Pipeline(cfg, [ColourBoxes(), ThermalHotSpotDetector()])


def colour_boxes(res) -> list[tuple[float, float, float, float]]:
    return [d.box_xyxy for d in res.detections if d.source == "onnx"]


def test_the_pipeline_drops_the_crate_the_thermal_camera_sees_cold():
    res = pipeline().process(frame(0, thermal_image((288, 208, 352, 272))))
    assert colour_boxes(res) == [HEATER_BOX]
    assert [d.source for d in res.detections].count("thermal") == 1
    # the crate never becomes a track: only the heater's two boxes are observed
    assert len(res.observations) == 2


@pytest.mark.parametrize(
    ("sets", "thermal_c", "rgb", "kept"),
    [
        (["thermal.confirm_colour_boxes=false"], "cold", True, 2),  # the rule off
        (["thermal.enabled=false"], "cold", True, 2),  # no thermal detector: nothing vouches
        ([], None, True, 2),  # a colour frame with no thermal image paired to it
        ([], "cold", True, 0),  # a thermal image showing nothing hot
        ([], None, False, 0),  # a replayed frame (no pixels): recorded with the thermal detector
    ],
)
def test_when_the_rule_applies(sets, thermal_c, rgb, kept):
    t = thermal_image(None) if thermal_c == "cold" else None
    f = frame(0, t, rgb=rgb)
    assert frame_has_thermal_view(f) == (t is not None or not rgb)
    res = pipeline(*sets).process(f)
    assert len(colour_boxes(res)) == kept
