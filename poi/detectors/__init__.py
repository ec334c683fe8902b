"""Detectors: frame in, list of detections out, built by name from a config.

>>> sorted(REGISTRY)
['landolt', 'onnx', 'qr', 'thermal']
"""

from poi.detectors.base import (
    REGISTRY,
    Detector,
    DetectorConfigError,
    build_detector,
    register,
    spread_class_probs,
)
from poi.detectors.landolt import LandoltFinder, attach_landolt_text, read_landolt
from poi.detectors.onnx_yolo import OnnxModelError, OnnxYoloDetector
from poi.detectors.plugins import (
    ENTRY_POINT_GROUP,
    CheckedDetector,
    DetectorOutputError,
    build_python_detector,
    entry_point_names,
    is_team_detector,
)
from poi.detectors.qr import QrDetector, attach_qr_text, decode_qr
from poi.detectors.thermal import ThermalFrameError, ThermalHotSpotDetector

__all__ = [
    "ENTRY_POINT_GROUP",
    "REGISTRY",
    "CheckedDetector",
    "Detector",
    "DetectorConfigError",
    "DetectorOutputError",
    "LandoltFinder",
    "OnnxModelError",
    "OnnxYoloDetector",
    "QrDetector",
    "ThermalFrameError",
    "ThermalHotSpotDetector",
    "attach_landolt_text",
    "attach_qr_text",
    "build_detector",
    "build_python_detector",
    "decode_qr",
    "entry_point_names",
    "is_team_detector",
    "read_landolt",
    "register",
    "spread_class_probs",
]
