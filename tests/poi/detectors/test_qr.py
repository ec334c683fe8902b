"""QR reading: real cv2.QRCodeEncoder codes pasted, scaled and rotated, into a textured image."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from poi.core.motion_blur import EXPOSURE_LADDER, CameraMotion, motion_kernel
from poi.core.names import CLASS_INDEX
from poi.core.types import Frame, Intrinsics
from poi.detectors import QrDetector, attach_qr_text, build_detector, decode_qr, qr
from poi.detectors.base import make_detection

K = Intrinsics(width=640, height=480, fx=612.4, fy=610.6, ppx=314.3, ppy=237.8)


def _textured(rng: np.random.Generator) -> np.ndarray:
    """A 640x480 wall: blurred noise in 60..190 (no black/white areas to look like a code)."""
    noise = rng.integers(60, 190, size=(480, 640), dtype=np.uint8)
    grey = cv2.GaussianBlur(noise, (0, 0), 3.0)
    tint = np.array([1.0, 0.9, 0.8])
    return np.clip(grey[..., None] * tint, 0, 255).astype(np.uint8)


def _paste(
    rgb: np.ndarray, text: str, centre_xy: tuple[float, float], module_px: float, angle_deg: float
) -> tuple[float, float, float, float]:
    """Paste a code (white sheet with its quiet zone) in place; return its axis-aligned box."""
    code = cv2.QRCodeEncoder.create().encode(text)  # (n, n) uint8, 0/255, quiet zone included
    n = code.shape[0]
    side = int(round(n * module_px))
    patch = cv2.resize(code, (side, side), interpolation=cv2.INTER_NEAREST).astype(np.float32)
    cx, cy = centre_xy
    # Affine map from patch pixels to image pixels: rotate about the patch centre, then move.
    M = cv2.getRotationMatrix2D((side / 2, side / 2), angle_deg, 1.0)
    M[:, 2] += (cx - side / 2, cy - side / 2)
    h, w = rgb.shape[:2]
    warped = cv2.warpAffine(patch, M, (w, h), flags=cv2.INTER_LINEAR, borderValue=0)
    mask = cv2.warpAffine(np.ones_like(patch), M, (w, h), flags=cv2.INTER_LINEAR, borderValue=0)
    blend = rgb.astype(np.float32) * (1 - mask[..., None]) + warped[..., None] * mask[..., None]
    rgb[:] = np.clip(np.round(blend), 0, 255).astype(np.uint8)
    corners = np.array([[0, 0, 1], [side, 0, 1], [side, side, 1], [0, side, 1]], float) @ M.T
    return (corners[:, 0].min(), corners[:, 1].min(), corners[:, 0].max(), corners[:, 1].max())


def test_decode_rotated_code_in_its_box():
    rgb = _textured(np.random.default_rng(1))
    box = _paste(rgb, "Chart M", (320, 240), module_px=5.0, angle_deg=8.0)
    before = rgb.copy()
    assert decode_qr(rgb, box) == "Chart M"
    assert np.array_equal(rgb, before)  # the image is only read


def test_decode_small_code_needs_upscaling():
    # 25 modules at 2 px, rotated 3 deg: a 50 px code OpenCV's decoders cannot read at its
    # own size; decode_qr (zxing-cpp, upscaled crops) reads it.
    rgb = _textured(np.random.default_rng(2))
    box = _paste(rgb, "QR-17", (200, 150), module_px=2.0, angle_deg=3.0)
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    plain = cv2.cvtColor(rgb[y1 - 8 : y2 + 8, x1 - 8 : x2 + 8], cv2.COLOR_RGB2GRAY)
    assert cv2.QRCodeDetector().detectAndDecode(plain)[0] == ""
    assert cv2.QRCodeDetectorAruco().detectAndDecode(plain)[0] == ""
    assert decode_qr(rgb, box) == "QR-17"


@pytest.mark.parametrize("module_px", [2.0, 3.0, 5.0])
@pytest.mark.parametrize("angle_deg", [0.0, 4.0, -8.0])
def test_decode_over_sizes_and_angles(module_px, angle_deg):
    # Measured: every seed decodes from 2 px a module up (1.6 px fails most of the time).
    rgb = _textured(np.random.default_rng(7))
    box = _paste(rgb, "Chart M 12", (330, 250), module_px=module_px, angle_deg=angle_deg)
    assert decode_qr(rgb, box) == "Chart M 12"


@pytest.mark.parametrize(("module_px", "sigma_px"), [(2.0, 1.0), (2.5, 1.3)])
def test_decode_defocused_code_by_sharpening(module_px, sigma_px):
    # Measured over seeds 0-5: zxing-cpp on the crop and on it upscaled reads none of these
    # defocused codes; the sharpened try reads all six.
    rgb = _textured(np.random.default_rng(8))
    box = _paste(rgb, "Chart M", (320, 240), module_px=module_px, angle_deg=3.0)
    blurred = cv2.GaussianBlur(rgb, (0, 0), sigma_px)
    x1, y1, x2, y2 = (int(round(v)) for v in box)
    crop = cv2.cvtColor(blurred[y1 - 12 : y2 + 12, x1 - 12 : x2 + 12], cv2.COLOR_RGB2GRAY)
    up = cv2.resize(crop, None, fx=2, fy=2, interpolation=cv2.INTER_CUBIC)
    assert qr._read(crop) is None and qr._read(up) is None
    assert decode_qr(blurred, box) == "Chart M"


def test_decode_code_foreshortened_across():
    # a code on a side wall seen along a corridor: 3 px a module tall, squeezed to 0.35 across
    # (about 70 degrees off its normal): 1.05 px a module wide
    rgb = _textured(np.random.default_rng(9))
    x1, y1, x2, y2 = _paste(rgb, "Chart M", (320, 240), module_px=3.0, angle_deg=0.0)
    k = 0.35
    M = np.float32([[k, 0, 320 * (1 - k)], [0, 1, 0]])
    squeezed = cv2.warpAffine(rgb, M, (640, 480), flags=cv2.INTER_AREA, borderMode=cv2.BORDER_REFLECT)
    assert decode_qr(squeezed, (320 - (320 - x1) * k, y1, 320 + (x2 - 320) * k, y2)) == "Chart M"


def test_decode_nothing_there():
    rgb = _textured(np.random.default_rng(3))
    assert decode_qr(rgb, (100, 100, 200, 200)) is None
    assert decode_qr(rgb, (100, 100, 100, 200)) is None  # empty box
    assert decode_qr(rgb, (np.nan, 100, 200, 200)) is None


def test_qr_detector_finds_and_reads_two_codes():
    rgb = _textured(np.random.default_rng(4))
    box_a = _paste(rgb, "Chart M", (170, 200), module_px=5.0, angle_deg=5.0)
    box_b = _paste(rgb, "Chart 42", (470, 260), module_px=4.0, angle_deg=-6.0)
    det = build_detector({"name": "qr"})
    assert isinstance(det, QrDetector)
    out = det.detect(Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=K))
    by_text = {d.text: d for d in out}
    assert set(by_text) == {"Chart M", "Chart 42"}
    # The decoder's corners are the code's own corners, inside the quiet zone: 2 modules
    # (the encoder's border) in from the sheet, so its box is within the sheet's box and
    # no more than 2 modules x sqrt(2) (rotation) + 2 px inside it on any side.
    for text, box, module_px in (("Chart M", box_a, 5.0), ("Chart 42", box_b, 4.0)):
        d = by_text[text]
        assert (d.class_name, d.type, d.source) == ("qr", "qr", "qr")
        slack = 2 * module_px * np.sqrt(2) + 2
        inner = np.array(d.box_xyxy) - np.array(box)
        assert np.all(inner[:2] >= -2) and np.all(inner[:2] <= slack), (text, inner)
        assert np.all(inner[2:] <= 2) and np.all(inner[2:] >= -slack), (text, inner)
        assert d.class_probs[CLASS_INDEX["qr"]] == pytest.approx(0.95)
        assert d.class_probs.sum() == pytest.approx(1.0)


def test_qr_detector_empty_image():
    rgb = _textured(np.random.default_rng(5))
    assert QrDetector().detect(Frame(index=0, timestamp_s=0.0, rgb=rgb, intrinsics=K)) == []


def test_attach_qr_text_fills_only_qr_detections():
    rgb = _textured(np.random.default_rng(6))
    box = _paste(rgb, "Chart M", (320, 240), module_px=4.0, angle_deg=-4.0)
    readable = make_detection("qr", box, 0.8, source="onnx", class_probs=None)
    unreadable = make_detection("qr", (20, 20, 90, 90), 0.6, source="onnx", class_probs=None)
    door = make_detection("door", box, 0.7, source="onnx", class_probs=None)
    dets = [readable, unreadable, door]
    snapshot = [dataclasses.replace(d) for d in dets]
    out = attach_qr_text(rgb, dets)
    assert [d.text for d in out] == ["Chart M", "", ""]
    assert out[2] is door and out[0].box_xyxy == readable.box_xyxy
    assert dets == snapshot  # inputs untouched


def test_qr_detector_settings_checked():
    from poi.detectors import DetectorConfigError

    with pytest.raises(DetectorConfigError, match="confidence must be in"):
        QrDetector(confidence=0.0)


def _slewed(
    module_px: float, seed: int, exposure_s: float = 0.010
) -> tuple[np.ndarray, tuple[float, float, float, float], np.ndarray]:
    """A code at the image centre smeared as a 120 deg/s pan smears it in an exposure of
    ``exposure_s`` (12.8 px along u in 10 ms), with sensor noise (sigma 2) and JPEG at 90; and
    the gyro's rate in the camera's axes."""
    rng = np.random.default_rng(seed)
    rgb = _textured(rng)
    box = _paste(rgb, "Chart M 12", (K.ppx, K.ppy), module_px=module_px, angle_deg=4.0)
    omega = np.array([0.0, np.radians(120.0), 0.0])
    du, dv = CameraMotion(omega_optical=omega, exposures_s=(exposure_s,), intrinsics=K).motion_px(
        K.ppx, K.ppy, exposure_s
    )
    smeared = cv2.filter2D(rgb.astype(np.float32), -1, motion_kernel(du, dv), borderType=cv2.BORDER_REFLECT)
    smeared = np.clip(smeared + rng.normal(0, 2, smeared.shape), 0, 255).astype(np.uint8)
    _, jpg = cv2.imencode(".jpg", smeared, [cv2.IMWRITE_JPEG_QUALITY, 90])
    return cv2.imdecode(jpg, cv2.IMREAD_UNCHANGED), box, omega


@pytest.mark.parametrize("module_px", [4.0, 6.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_code_smeared_by_a_pan_reads_deblurred_by_the_gyro_s_motion(module_px, seed):
    # a slew smears the code by two to three modules: no try on the pixels reads it; the crop
    # deconvolved by the kernel of the motion the exposure and the gyro give reads it
    rgb, box, omega = _slewed(module_px, seed)
    motion = CameraMotion(omega_optical=omega, exposures_s=(0.010,), intrinsics=K)
    assert decode_qr(rgb, box) is None
    assert decode_qr(rgb, box, motion=motion) == "Chart M 12"
    det = make_detection("qr", box, 0.9, source="onnx", class_probs=None)
    assert attach_qr_text(rgb, [det], motion)[0].text == "Chart M 12"


def test_an_unreported_exposure_is_found_on_the_ladder_below_the_cap():
    # smeared in 7 ms (9 px) where the camera reports no exposure: the 10 ms kernel (12.8 px)
    # reads nothing, the ladder's second rung (7.1 ms) reads it
    rgb, box, omega = _slewed(4.0, 2, exposure_s=0.007)
    at_cap = CameraMotion(omega_optical=omega, exposures_s=(0.010,), intrinsics=K)
    ladder = CameraMotion(omega_optical=omega, exposures_s=tuple(0.010 * f for f in EXPOSURE_LADDER), intrinsics=K)
    assert decode_qr(rgb, box, motion=at_cap) is None
    assert decode_qr(rgb, box, motion=ladder) == "Chart M 12"


def test_a_motion_under_two_pixels_is_not_deblurred(monkeypatch):
    rgb, box, _ = _slewed(6.0, 0)
    still = CameraMotion(omega_optical=np.array([0.0, np.radians(15.0), 0.0]), exposures_s=(0.010,), intrinsics=K)
    tried = []
    monkeypatch.setattr(qr, "wiener_deconvolve", lambda *a: tried.append(a) or a[0])
    assert decode_qr(rgb, box, motion=still) is None  # 1.6 px: not deblurred
    assert tried == []
