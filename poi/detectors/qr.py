"""QR codes: read the text in a detector's 'qr' box, or find and read codes on their own.

docs/DESIGN.md "What real means here": QR codes carry real encoded text and are
decoded from rendered pixels, by zxing-cpp ([ZXingCpp]_), chosen by measurement
(bench/bench_qr.py; docs/FACTS.md "QR codes"): on the maze's rendered codes it
read every view OpenCV's ``QRCodeDetector`` and ``QRCodeDetectorAruco`` read and
many more (at 1.5-2 px a module, 100 % of the default trial's whole, still views
against 7 %), at about a hundredth of their CPU; OpenCV added no read, so it was
dropped (it stays the encoder, maze_assets/qr.py).

A detector box is cropped with a margin (the quiet zone round the code, which a
tight box cuts off) and tried as it is, upscaled twice (cubic), stretched to a
square when it is narrow (a code on a side wall seen along a corridor is
foreshortened across), and upscaled and sharpened (an unsharp mask against the
camera's defocus); the first text found wins. A failed box costs about 0.4 ms.

Where the frame says how the camera turned during the exposure (the tracking camera's
gyro, and the exposure time or, where the camera does not report it, a ladder of
exposures below its cap: :class:`poi.core.motion_blur.CameraMotion`) and the box's image
moved by ``DEBLUR_MIN_PX`` or more, a box the tries above do not read is tried
deblurred: the crop Wiener-deconvolved by the line kernel of that motion
(:func:`poi.core.motion_blur.wiener_deconvolve`), as it is and upscaled, for each
exposure in turn. A scanning head's slew smears a code by two modules and more, which
no sharpening undoes; a wrong kernel reads nothing rather than something else (a QR
code's Reed-Solomon check).

References
----------
Full entries in docs/SOURCES.md.

.. [ZXingCpp] A. Bösch et al., "zxing-cpp", a C++ port of ZXing with Python bindings
   (github.com/zxing-cpp/zxing-cpp, Apache-2.0).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
import zxingcpp

from poi.core.motion_blur import CameraMotion, motion_kernel, wiener_deconvolve
from poi.core.types import Detection, Frame
from poi.detectors.base import DetectorConfigError, make_detection, one_class_probs, register

MARGIN_FRAC = 0.15  # crop margin on each side, as a fraction of the box's longer side
UPSCALE = 2.0  # the second try's scale (cubic): 1.5-2 px modules become 3-4 px
NARROW_ASPECT = 0.8  # a crop narrower than this (width / height) is also tried stretched square
SHARPEN_SIGMA_PX = 2.0  # unsharp mask of the upscaled crop: img + a (img - blur(img, sigma))
SHARPEN_AMOUNT = 1.5
# Boxes whose shorter side is under this many pixels are not tried: a version-1 code and its
# quiet zone (29 modules) at 0.7 px a module. None under 1 px a module decoded in the default
# trial (bench/bench_qr.py); a failed try costs well under a millisecond.
MIN_BOX_PX = 20.0
DEBLUR_MIN_PX = 2.0  # a box whose image moved less than this during the exposure is not deblurred
# the Wiener filter's noise-to-signal power ratios, tried in turn: in the default trial's slews (13
# views whole in the image, 6-7 px a module, smeared 13-15 px) each alone read 12, the two 13
DEBLUR_NSR = (0.01, 0.003)
_QR = zxingcpp.BarcodeFormats(zxingcpp.BarcodeFormat.QRCode)


def _to_gray(rgb: np.ndarray) -> np.ndarray:
    if rgb.ndim == 2:
        return rgb
    if rgb.ndim == 3 and rgb.shape[2] == 3:
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    raise ValueError(f"expected an RGB (H, W, 3) or grey (H, W) image, got shape {rgb.shape}")


def _read(gray: np.ndarray) -> str | None:
    """The text of the first QR code zxing-cpp finds in ``gray`` ([ZXingCpp]_), or None."""
    found = zxingcpp.read_barcodes(np.ascontiguousarray(gray), formats=_QR)
    return found[0].text if found and found[0].text else None


def _attempts(crop: np.ndarray) -> Iterator[np.ndarray]:
    """The images one box is tried as, cheapest first (module docstring); ``crop`` is only read."""
    yield crop
    up = cv2.resize(crop, None, fx=UPSCALE, fy=UPSCALE, interpolation=cv2.INTER_CUBIC)  # (2h, 2w)
    yield up
    h, w = crop.shape
    if w < NARROW_ASPECT * h:
        square = cv2.resize(crop, (h, h), interpolation=cv2.INTER_CUBIC)  # (h, h): width stretched
        yield square
        yield cv2.resize(square, None, fx=UPSCALE, fy=UPSCALE, interpolation=cv2.INTER_CUBIC)
    # unsharp mask: up + a (up - G_sigma * up)
    blurred = cv2.GaussianBlur(up, (0, 0), SHARPEN_SIGMA_PX)
    yield cv2.addWeighted(up, 1.0 + SHARPEN_AMOUNT, blurred, -SHARPEN_AMOUNT, 0.0)


def _deblurred(crop: np.ndarray, motion_px: tuple[float, float]) -> Iterator[np.ndarray]:
    """``crop`` Wiener-deconvolved by the line kernel of ``motion_px`` at each of ``DEBLUR_NSR``,
    as it is and upscaled; nothing under ``DEBLUR_MIN_PX``."""
    if np.hypot(*motion_px) < DEBLUR_MIN_PX:
        return
    kernel = motion_kernel(*motion_px)
    if kernel is None:
        return
    for nsr in DEBLUR_NSR:
        sharp = wiener_deconvolve(crop, kernel, nsr)
        yield sharp
        yield cv2.resize(sharp, None, fx=UPSCALE, fy=UPSCALE, interpolation=cv2.INTER_CUBIC)


def decode_qr(
    rgb: np.ndarray,
    box_xyxy: Sequence[float],
    *,
    margin_frac: float = MARGIN_FRAC,
    min_box_px: float = MIN_BOX_PX,
    motion: CameraMotion | None = None,
) -> str | None:
    """The text of the QR code inside ``box_xyxy`` (pixels of ``rgb``), or None.

    Boxes with a side under ``min_box_px`` are not tried (None). The crop is
    the box grown by ``margin_frac`` of its longer side on every side, clipped
    to the image, and is tried as the module docstring says; with ``motion``,
    deblurred last by the motion at the box's centre.
    """
    x1, y1, x2, y2 = (float(v) for v in box_xyxy)
    if not all(np.isfinite([x1, y1, x2, y2])) or min(x2 - x1, y2 - y1) < max(min_box_px, 1e-9):
        return None
    gray = _to_gray(rgb)
    h, w = gray.shape
    m = margin_frac * max(x2 - x1, y2 - y1)
    c1, r1 = max(int(np.floor(x1 - m)), 0), max(int(np.floor(y1 - m)), 0)
    c2, r2 = min(int(np.ceil(x2 + m)), w), min(int(np.ceil(y2 + m)), h)
    if c2 - c1 < 8 or r2 - r1 < 8:
        return None
    crop = gray[r1:r2, c1:c2]  # (r2 - r1, c2 - c1), a view: only read below
    for img in _attempts(crop):
        text = _read(img)
        if text is not None:
            return text
    if motion is not None:
        for exposure_s in motion.exposures_s:
            for img in _deblurred(crop, motion.motion_px((x1 + x2) / 2.0, (y1 + y2) / 2.0, exposure_s)):
                text = _read(img)
                if text is not None:
                    return text
    return None


def attach_qr_text(
    rgb: np.ndarray, detections: Sequence[Detection], motion: CameraMotion | None = None
) -> list[Detection]:
    """Copies of ``detections`` with the decoded text on every 'qr' one ("" if unreadable);
    ``motion``: the camera's during the exposure, where the frame gives it (:func:`decode_qr`).

    Other detections are returned unchanged; the inputs are not modified.
    """
    out = []
    for det in detections:
        if det.type == "qr":
            text = decode_qr(rgb, det.box_xyxy, motion=motion)
            det = dataclasses.replace(det, text=text or "")
        out.append(det)
    return out


def box_iou(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Intersection over union of two boxes (x1, y1, x2, y2); 0 when both are empty."""
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


@register("qr")
@dataclass(kw_only=True)
class QrDetector:
    """Finds and reads QR codes over the whole image (codes a model missed).

    Every decoded code becomes a Detection of class 'qr' with its text, its box
    the bounding box of the four corner points, and ``confidence`` (a decoded
    code is almost surely a QR code); codes found but not decoded are dropped,
    since a QR report without its text cannot score. ``dedupe_iou``: a code
    overlapping one already found by more than this is the same code.
    """

    confidence: float = 0.95
    dedupe_iou: float = 0.3
    name: str = field(default="qr", init=False)

    def __post_init__(self) -> None:
        if not 0.0 < float(self.confidence) <= 1.0:
            raise DetectorConfigError(f"detector 'qr': confidence must be in (0, 1], got {self.confidence}")
        if not 0.0 <= float(self.dedupe_iou) <= 1.0:
            raise DetectorConfigError(f"detector 'qr': dedupe_iou must be in [0, 1], got {self.dedupe_iou}")

    def detect(self, frame: Frame) -> list[Detection]:
        """Every QR code zxing-cpp reads in the whole frame ([ZXingCpp]_), one Detection each."""
        gray = _to_gray(frame.rgb)
        h, w = gray.shape
        found: list[tuple[str, tuple[float, float, float, float]]] = []
        for code in zxingcpp.read_barcodes(np.ascontiguousarray(gray), formats=_QR):
            p = code.position
            xs = [p.top_left.x, p.top_right.x, p.bottom_right.x, p.bottom_left.x]
            ys = [p.top_left.y, p.top_right.y, p.bottom_right.y, p.bottom_left.y]
            box = (
                float(np.clip(min(xs), 0, w)),
                float(np.clip(min(ys), 0, h)),
                float(np.clip(max(xs), 0, w)),
                float(np.clip(max(ys), 0, h)),
            )
            if not code.text or box[2] <= box[0] or box[3] <= box[1]:
                continue
            if any(box_iou(box, b) > self.dedupe_iou for _t, b in found):
                continue
            found.append((code.text, box))
        probs = one_class_probs("qr", float(self.confidence))
        return [
            make_detection(
                "qr",
                box,
                float(self.confidence),
                source="qr",
                class_probs=probs.copy(),
                text=text,
            )
            for text, box in found
        ]
