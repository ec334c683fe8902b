"""QR codes: read the text in a detector's 'qr' box, or find and read codes on their own.

docs/DESIGN.md "What real means here": QR codes carry real encoded text and are
decoded from rendered pixels, with OpenCV's ``QRCodeDetector`` and, where this
OpenCV has it, ``QRCodeDetectorAruco`` (a second, more tolerant finder).

A detector box is cropped with a margin (the quiet zone round the code) and
upscaled when small so that a module of the densest code we expect is at least
``min_module_px`` pixels; the crop is also tried binarised and with a white
border added, for boxes that cut the quiet zone off.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from poi.core.types import Detection, Frame
from poi.detectors.base import DetectorConfigError, make_detection, one_class_probs, register

MIN_MODULE_PX = 3.0  # smallest module size, in pixels, the decoders read reliably
MAX_MODULES = 33  # modules across a version-4 code (21 + 4 * 3), the densest we size for
MAX_UPSCALE = 8.0  # never blow a crop up more than this
MARGIN_FRAC = 0.15  # crop margin on each side, as a fraction of the box's longer side
QUIET_ZONE_MODULES = 4  # white border the QR standard asks for round a code
# Boxes whose shorter side is under this many pixels are not tried: in the default
# trial none of 92 such boxes decoded (under 2 px per module of a version-1 code),
# and each failed try costs tens of milliseconds.
MIN_BOX_PX = 40.0


_DECODERS: list[cv2.QRCodeDetector] = []


def _decoders() -> list[cv2.QRCodeDetector]:
    """OpenCV's decoders, built once: the tolerant Aruco-based finder first (a failed try
    costs about a tenth of the classic one's), then the classic ``QRCodeDetector``."""
    if not _DECODERS:
        if hasattr(cv2, "QRCodeDetectorAruco"):
            _DECODERS.append(cv2.QRCodeDetectorAruco())
        _DECODERS.append(cv2.QRCodeDetector())
    return _DECODERS


def _to_gray(rgb: np.ndarray) -> np.ndarray:
    if rgb.ndim == 2:
        return rgb
    if rgb.ndim == 3 and rgb.shape[2] == 3:
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    raise ValueError(f"expected an RGB (H, W, 3) or grey (H, W) image, got shape {rgb.shape}")


def _decode_gray(gray: np.ndarray) -> str | None:
    for decoder in _decoders():
        try:
            text, _points, _straight = decoder.detectAndDecode(gray)
        except cv2.error:
            continue
        if text:
            return text
    return None


def decode_qr(
    rgb: np.ndarray,
    box_xyxy: Sequence[float],
    *,
    margin_frac: float = MARGIN_FRAC,
    min_module_px: float = MIN_MODULE_PX,
    max_modules: int = MAX_MODULES,
    min_box_px: float = MIN_BOX_PX,
) -> str | None:
    """The text of the QR code inside ``box_xyxy`` (pixels of ``rgb``), or None.

    Boxes with a side under ``min_box_px`` are not tried (None). The crop is
    the box grown by ``margin_frac`` of its longer side on every side, clipped
    to the image. It is scaled by
    s = clip(min_module_px * max_modules / min(box w, h), 1, MAX_UPSCALE), so a
    module of a code ``max_modules`` wide covers at least ``min_module_px``
    pixels, and then by 2 s (sharper finder patterns for the decoders); at each
    scale the grey crop and the crop with a white quiet zone added are tried
    with each decoder, the first text found wins. (An Otsu-binarised crop was
    tried too until it was measured to add no read in the default trial.)
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
    s0 = float(np.clip(min_module_px * max_modules / min(x2 - x1, y2 - y1), 1.0, MAX_UPSCALE))
    for s in dict.fromkeys((s0, min(2.0 * s0, MAX_UPSCALE))):
        img = crop if s == 1.0 else cv2.resize(crop, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
        b = int(np.ceil(QUIET_ZONE_MODULES * min(img.shape) / max_modules))
        bordered = cv2.copyMakeBorder(img, b, b, b, b, cv2.BORDER_CONSTANT, value=255)
        for candidate in (img, bordered):
            text = _decode_gray(candidate)
            if text is not None:
                return text
    return None


def attach_qr_text(rgb: np.ndarray, detections: Sequence[Detection]) -> list[Detection]:
    """Copies of ``detections`` with the decoded text on every 'qr' one ("" if unreadable).

    Other detections are returned unchanged; the inputs are not modified.
    """
    out = []
    for det in detections:
        if det.type == "qr":
            text = decode_qr(rgb, det.box_xyxy)
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
    since a QR report without its text cannot score. ``dedupe_iou``: a code found
    by the second decoder overlapping one already found by more than this is the
    same code.
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
        gray = _to_gray(frame.rgb)
        h, w = gray.shape
        found: list[tuple[str, tuple[float, float, float, float]]] = []
        for decoder in _decoders():
            try:
                ok, texts, points, _straight = decoder.detectAndDecodeMulti(gray)
            except cv2.error:
                continue
            if not ok or points is None:
                continue
            for text, pts in zip(texts, np.asarray(points, dtype=np.float64), strict=False):
                if not text or not np.all(np.isfinite(pts)):
                    continue
                box = (
                    float(np.clip(pts[:, 0].min(), 0, w)),
                    float(np.clip(pts[:, 1].min(), 0, h)),
                    float(np.clip(pts[:, 0].max(), 0, w)),
                    float(np.clip(pts[:, 1].max(), 0, h)),
                )
                if box[2] <= box[0] or box[3] <= box[1]:
                    continue
                if any(box_iou(box, b) > self.dedupe_iou for _t, b in found):
                    continue
                found.append((text, box))
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
