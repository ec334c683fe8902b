"""A team's detector written in Python, numpy and OpenCV only: the tests' stand-in for the README's torch one.

``RedBlobDetector`` has the README example's constructor, ``(*, weights: str, conf: float = 0.25)``:
its "model" is a per-pixel logistic classifier read from an ``.npz`` file (``w`` (3,), ``b``,
``min_area_px``), score = sigmoid(w . rgb / 255 + b); the connected regions scoring 0.5 or more
with at least ``min_area_px`` pixels are fire extinguishers, their confidence the region's mean score.
"""

from __future__ import annotations

import cv2
import numpy as np

from poi.core.types import Detection, Frame
from poi.detectors.base import make_detection


def write_weights(path, w=(12.0, -14.0, -14.0), b=-6.0, min_area_px=40) -> str:
    """A weights file that finds the simulator's extinguisher red (0.78, 0.05, 0.04) and not the
    arena's walls, a red-painted one exposed bright (about 0.95, 0.30, 0.25: logit -2.3) included."""
    np.savez(path, w=np.asarray(w, float), b=float(b), min_area_px=int(min_area_px))
    return str(path)


class RedBlobDetector:
    name = "red-blob"

    def __init__(self, *, weights: str, conf: float = 0.25) -> None:
        with np.load(weights) as z:
            self.w = np.asarray(z["w"], np.float32)
            self.b = float(z["b"])
            self.min_area_px = int(z["min_area_px"])
        self.conf = conf

    def detect(self, frame: Frame) -> list[Detection]:
        x = frame.rgb.astype(np.float32) / 255.0 @ self.w + self.b  # (H, W) logits
        score = 1.0 / (1.0 + np.exp(-x))
        n, labels, stats, _ = cv2.connectedComponentsWithStats((score >= 0.5).astype(np.uint8), connectivity=8)
        out = []
        for k in range(1, n):
            x0, y0, w, h, area = (int(v) for v in stats[k])
            p = float(score[labels == k].mean())
            if area >= self.min_area_px and p >= self.conf:
                box = (x0, y0, x0 + w, y0 + h)
                out.append(make_detection("fire-extinguisher", box, p, source=self.name, class_probs=None))
        return out


class WrongOutput:
    """Returns what its ``kind`` option says, to test the checks on a detector's output."""

    def __init__(self, *, kind: str) -> None:
        self.kind = kind

    def detect(self, frame: Frame):
        box = (1.0, 2.0, 30.0, 40.0)
        if self.kind == "dict":
            return {"boxes": []}
        if self.kind == "tuple":
            return [(1.0, 2.0, 30.0, 40.0, 0.9, 3)]
        if self.kind == "class":
            return [Detection(class_name="Toxic", type="hazmat", text="", box_xyxy=box, confidence=0.9)]
        if self.kind == "unknown-class":
            return [Detection(class_name="car", type="car", text="", box_xyxy=box, confidence=0.9)]
        if self.kind == "raise":
            raise ZeroDivisionError("division by zero")
        return []


class NoDetect:
    def __init__(self) -> None:
        pass


def make_detector(*, conf: float = 0.5, **extra) -> RedBlobDetector:
    """A factory function taking any option (``**extra``)."""
    raise RuntimeError(f"weights missing for {sorted(extra)}")


NOT_CALLABLE = 3
