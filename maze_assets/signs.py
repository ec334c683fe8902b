"""Safety signs drawn with OpenCV: an emergency exit sign and a fire extinguisher sign.

The exit sign follows ISO 7010 E002 with a direction arrow: a safety-green
landscape (2:1) sign with a white running figure heading into a white door frame
and a white arrow. The fire extinguisher sign follows ISO 7010 F001: a safety-red
square with a white extinguisher and a flame. Both are drawn at ``SUPERSAMPLE``
times their size and reduced by area averaging (smooth, deterministic).

>>> draw_exit_sign(128).shape
(64, 128, 3)
>>> tuple(int(v) for v in draw_exit_sign(128)[32, 4])  # green field left of the figure
(0, 122, 61)
>>> tuple(int(v) for v in draw_fire_extinguisher_sign(64)[1, 1])  # red corner
(196, 30, 45)
"""

from __future__ import annotations

import cv2
import numpy as np

SUPERSAMPLE = 4
MIN_SIZE_PX = 32
SAFETY_GREEN = (0, 122, 61)
SAFETY_RED = (196, 30, 45)
WHITE = (255, 255, 255)


class SignSizeError(ValueError):
    """A sign size too small to draw."""


def _check(name: str, size_px: int) -> int:
    if int(size_px) < MIN_SIZE_PX:
        raise SignSizeError(f"{name}: size_px must be >= {MIN_SIZE_PX}, got {size_px}")
    return int(size_px)


class _Pen:
    """Draws in units of the sign's height (x right, y down) on a supersampled image."""

    def __init__(self, img: np.ndarray, unit_px: float) -> None:
        self.img, self.k = img, unit_px

    def p(self, x: float, y: float) -> tuple[int, int]:
        return int(round(x * self.k)), int(round(y * self.k))

    def line(self, pts, w: float, color=WHITE) -> None:
        for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:], strict=False):
            cv2.line(
                self.img,
                self.p(x0, y0),
                self.p(x1, y1),
                color,
                max(1, int(w * self.k)),
                cv2.LINE_AA,
            )
        for x, y in pts:  # round joints
            cv2.circle(self.img, self.p(x, y), max(1, int(w * self.k / 2)), color, -1, cv2.LINE_AA)

    def poly(self, pts, color=WHITE) -> None:
        arr = np.round(np.asarray(pts, float) * self.k).astype(np.int32)
        cv2.fillPoly(self.img, [arr], color, cv2.LINE_AA)

    def circle(self, x: float, y: float, r: float, color=WHITE) -> None:
        cv2.circle(self.img, self.p(x, y), max(1, int(r * self.k)), color, -1, cv2.LINE_AA)

    def rect(self, x0, y0, x1, y1, color=WHITE, w: float | None = None) -> None:
        th = -1 if w is None else max(1, int(w * self.k))
        cv2.rectangle(self.img, self.p(x0, y0), self.p(x1, y1), color, th, cv2.LINE_AA)


def _running_figure(pen: _Pen, cx: float, foot_y: float, h: float) -> None:
    """A white figure running toward +x; (cx, foot_y) is the ground point, h its height."""

    def q(x: float, y: float) -> tuple[float, float]:  # figure units: y up, 0..1
        return cx + x * h, foot_y - y * h

    w = 0.13 * h
    pen.circle(*q(0.20, 0.88), 0.10 * h)
    pen.line([q(0.12, 0.70), q(-0.04, 0.42)], 0.16 * h)  # torso
    pen.line([q(0.10, 0.68), q(0.27, 0.56), q(0.42, 0.66)], w)  # front arm
    pen.line([q(0.08, 0.68), q(-0.12, 0.60), q(-0.28, 0.46)], w)  # back arm
    pen.line([q(-0.04, 0.42), q(0.20, 0.26), q(0.16, 0.03), q(0.28, 0.03)], w)  # front leg
    pen.line([q(-0.04, 0.42), q(-0.16, 0.20), q(-0.40, 0.12)], w)  # back leg


def _finish(img: np.ndarray, w: int, h: int) -> np.ndarray:
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)


def draw_exit_sign(size_px: int = 256) -> np.ndarray:
    """RGB uint8 (size_px // 2, size_px, 3): ISO 7010 E002-style exit sign with an arrow."""
    W = _check("draw_exit_sign", size_px)
    H = W // 2
    img = np.empty((H * SUPERSAMPLE, W * SUPERSAMPLE, 3), np.uint8)
    img[:] = SAFETY_GREEN
    pen = _Pen(img, H * SUPERSAMPLE)  # unit = sign height; the sign is 2 units wide
    pen.rect(0.035, 0.035, 1.965, 0.965, WHITE, w=0.025)  # white inset border
    pen.rect(0.80, 0.15, 1.22, 0.86, WHITE, w=0.055)  # door frame
    pen.rect(0.80, 0.83, 1.30, 0.86, WHITE)  # threshold / floor line
    _running_figure(pen, 0.56, 0.84, 0.66)
    # arrow pointing right
    pen.poly(
        [
            (1.40, 0.43),
            (1.64, 0.43),
            (1.64, 0.30),
            (1.86, 0.50),
            (1.64, 0.70),
            (1.64, 0.57),
            (1.40, 0.57),
        ]
    )
    return _finish(img, W, H)


def _flame(pen: _Pen, cx: float, base_y: float, h: float) -> None:
    pts = np.array(
        [
            (-0.30, 0.0),
            (-0.42, 0.25),
            (-0.30, 0.55),
            (-0.28, 0.80),
            (-0.12, 0.55),
            (-0.05, 1.0),
            (0.12, 0.62),
            (0.22, 0.80),
            (0.40, 0.35),
            (0.30, 0.0),
        ]
    )
    for _ in range(2):  # corner cutting: round the tongues
        nxt = np.roll(pts, -1, axis=0)
        pts = np.stack([0.75 * pts + 0.25 * nxt, 0.25 * pts + 0.75 * nxt], axis=1).reshape(-1, 2)
    pen.poly(np.stack([cx + pts[:, 0] * h, base_y - pts[:, 1] * h], axis=1))


def draw_fire_extinguisher_sign(size_px: int = 256) -> np.ndarray:
    """RGB uint8 (size_px, size_px, 3): ISO 7010 F001-style fire extinguisher sign."""
    S = _check("draw_fire_extinguisher_sign", size_px)
    img = np.empty((S * SUPERSAMPLE, S * SUPERSAMPLE, 3), np.uint8)
    img[:] = SAFETY_RED
    pen = _Pen(img, S * SUPERSAMPLE)
    pen.rect(0.04, 0.04, 0.96, 0.96, WHITE, w=0.025)
    # extinguisher body: a rounded cylinder
    x0, x1, y0, y1 = 0.46, 0.70, 0.36, 0.88
    r = 0.12
    pen.rect(x0, y0 + r, x1, y1 - 0.03)
    pen.circle(0.58, y0 + r, r)
    pen.rect(x0 + 0.02, y1 - 0.05, x1 - 0.02, y1)
    pen.rect(0.545, 0.26, 0.615, 0.37)  # neck / valve
    pen.line([(0.56, 0.25), (0.76, 0.17)], 0.035)  # top lever
    pen.line([(0.60, 0.31), (0.76, 0.29)], 0.03)  # carry handle
    pen.line([(0.55, 0.28), (0.40, 0.30), (0.34, 0.45), (0.36, 0.66)], 0.035)  # hose
    pen.poly([(0.33, 0.64), (0.39, 0.64), (0.41, 0.75), (0.31, 0.75)])  # nozzle
    _flame(pen, 0.19, 0.46, 0.26)
    return _finish(img, S, S)
