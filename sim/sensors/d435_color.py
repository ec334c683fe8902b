"""The D435 colour stream as a camera makes it: exposure, noise, blur, optics and compression.

The renderer's image is taken as display-encoded (the textures are sRGB-authored), so it is
decoded to linear light with the display gamma, ``x = (v / 255) ** gamma``; a decoded 1 is a
white surface lit at the scene's illuminance ``lux``. The sensor collects
``e = x * lux * K * t`` electrons in an exposure of ``t`` ms (K =
``sensitivity_e_per_lux_ms``); the signal after analog gain G, relative to the ADC's full
scale, is ``s = e * G / FW`` (FW = ``full_well_e``). Its variance, shot noise (Poisson: var e
= e) plus read noise ``sigma_r`` electrons, is linear in the signal::

    var(s) = a * s + b,   a = G / FW,   b = (G * sigma_r / FW) ** 2

Then the signal is clipped to [0, 1] and encoded, ``255 * s ** (1 / gamma)``.

Auto-exposure meters the mean linear level m of the decoded render and picks the exposure
product P = t * G (ms) that brings the mean signal to the target ``ae_target ** gamma``:
``P = target * FW / (m * lux * K)``; exposure first (clamped to its range), then gain. Over
frames it follows a first-order lag of time constant tau on log P: frame k's log P is the
mean of the steady-state log P of frames k, k - 1, ... weighted by (1 - alpha) ** i,
alpha = 1 - exp(-dt / tau) (:func:`lagged_exposure`).

Motion blur: the image moves by (du, dv) pixels during the exposure (the camera's own motion,
:func:`poi.core.motion_blur.image_motion_px`); the image is convolved with a line of that
length and direction (:func:`poi.core.motion_blur.motion_kernel`)
(one kernel for the whole frame, from the motion of the image centre: exact for a pure
rotation about the optical centre's small angles, an approximation for translation, which
moves near things more). Defocus: a Gaussian of ``defocus_sigma_px``. Vignetting: the
irradiance falls as cos^4 of the off-axis angle theta (the cos^4 law of a thin lens); the lens
is assumed to correct part of it (a judgement: no public D435 figure),
``V = 1 - v * (1 - cos^4 theta)`` (:func:`vignette_map`).
White balance: per-channel gains on the linear signal (the cast left after the camera's auto
white balance). Compression: JPEG at a quality.

The D435's colour imager (an OmniVision OV2740, rolling shutter, 1920 x 1080 at most,
[IntelD400]) is simulated global-shutter: the rolling readout's skew is left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from poi.core.loader import number
from poi.core.motion_blur import motion_kernel
from sim.sensors.base import Exposure, Shot
from sim.sensors.noise_pool import NoisePool


@dataclass(kw_only=True)
class ColourSpec:
    """The D435 colour stream's camera effects (sim/sensors/d435_color.py; docs/FACTS.md
    "D435 colour camera"). Each is a setting and can be switched off; ``sensors.noise: false``
    switches off the random ones (noise) and the blurs, compression and white-balance cast,
    leaving exposure and tone.

    Light: ``lux`` is the illuminance on a white surface the robot's lamp lights (default: the
    lighting preset's level, ``sim.world.world.LIGHT_LEVEL_LUX``; the render's shading sets the rest,
    ``sim.world.world.lux_of_decoded_one``); a white surface in full light gives
    ``sensitivity_e_per_lux_ms`` electrons per lux and millisecond of exposure at unit gain.
    Auto-exposure (``auto_exposure``) meters the mean linear level and sets exposure first
    (``min_exposure_ms`` .. ``max_exposure_ms``), then analog gain (1 .. ``max_gain``), so the
    mean lands at ``ae_target`` (encoded, 0..1), with a first-order lag ``ae_time_constant_s``;
    without it, ``exposure_ms`` and ``gain`` hold. Noise: shot noise (Poisson in electrons)
    plus ``read_noise_e``, relative to ``full_well_e``. Output: display gamma ``gamma``.
    Blurs: the camera's own motion during the exposure (``motion_blur``), ``defocus_sigma_px``
    (Gaussian). ``vignetting``: the fraction of the cos^4 falloff left after the lens'
    correction (0: none). ``wb_gains``: per-channel (R, G, B) gains on the linear signal, the
    colour cast left after the camera's auto white balance (whites a little cool, fitted to real
    placard photos: docs/FACTS.md "D435 colour camera").
    ``jpeg_quality``: JPEG compression of the delivered image (0, the default: off, as the
    D435 sends its colour frames uncompressed over USB; a robot that sends them on as JPEG
    sets its quality).
    """

    auto_exposure: bool = True
    ae_target: float = number(0.6, lo=0.0, hi=1.0, lo_open=True, hi_open=True)
    ae_time_constant_s: float = number(0.15, lo=0.0)
    exposure_ms: float = number(10.0, lo=0.0, lo_open=True)
    gain: float = number(1.0, lo=1.0)
    min_exposure_ms: float = number(0.1, lo=0.0, lo_open=True)
    max_exposure_ms: float = number(10.0, lo=0.0, lo_open=True)
    max_gain: float = number(16.0, lo=1.0)
    lux: float | None = number(None, lo=0.0, lo_open=True)
    sensitivity_e_per_lux_ms: float = number(0.2, lo=0.0, lo_open=True)
    full_well_e: float = number(5000.0, lo=1.0)
    read_noise_e: float = number(3.0, lo=0.0)
    shot_noise: bool = True
    gamma: float = number(2.2, lo=1.0, hi=4.0)
    motion_blur: bool = True
    defocus_sigma_px: float = number(0.5, lo=0.0, hi=20.0)
    vignetting: float = number(0.4, lo=0.0, hi=1.0)
    wb_gains: tuple[float, float, float] = number((1.0, 1.0, 1.15), lo=0.0, lo_open=True)
    jpeg_quality: int = number(0, lo=0, hi=100)

    def __post_init__(self) -> None:
        if self.min_exposure_ms > self.max_exposure_ms:
            raise ValueError(
                f"min_exposure_ms ({self.min_exposure_ms}) must not exceed "
                f"max_exposure_ms ({self.max_exposure_ms})"
            )


AE_MAX_HISTORY = 8  # frames the auto-exposure lag looks back at most
AE_METER_STEP = 8  # the meter reads every 8th pixel in each direction


def decode_lut(gamma: float) -> np.ndarray:
    """(256,) float32: the linear level of each 8-bit encoded value, ``(v / 255) ** gamma``."""
    return (np.arange(256, dtype=np.float64) / 255.0) ** gamma


def meter(rgb: np.ndarray, gamma: float) -> float:
    """The mean linear level of an encoded image, read on a grid of every ``AE_METER_STEP``-th pixel."""
    sub = rgb[::AE_METER_STEP, ::AE_METER_STEP]
    return float(decode_lut(gamma)[sub].mean())


def steady_state_exposure(meter_x: float, spec: ColourSpec, lux: float) -> Exposure:
    """The exposure that brings a mean linear level ``meter_x`` to the target: exposure time
    first, within [min_exposure_ms, max_exposure_ms], then gain within [1, max_gain].

    >>> s = ColourSpec(ae_target=0.5, gamma=1.0, full_well_e=1000.0, sensitivity_e_per_lux_ms=1.0)
    >>> steady_state_exposure(0.25, s, lux=100.0)  # P = 0.5 * 1000 / (0.25 * 100 * 1) = 20 ms
    Exposure(exposure_ms=10.0, gain=2.0)
    """
    if meter_x <= 0.0:
        return Exposure(exposure_ms=spec.max_exposure_ms, gain=spec.max_gain)
    target = spec.ae_target**spec.gamma
    # s = m * lux * K * P / FW = target
    P = target * spec.full_well_e / (meter_x * lux * spec.sensitivity_e_per_lux_ms)
    t = min(max(P, spec.min_exposure_ms), spec.max_exposure_ms)
    G = min(max(P / t, 1.0), spec.max_gain)
    return Exposure(exposure_ms=t, gain=G)


def ae_history_frames(tau_s: float, dt_s: float) -> int:
    """Frames (the current one included) the lag reads: until the weight falls below e^-4."""
    if tau_s <= 0.0:
        return 1
    return min(AE_MAX_HISTORY, 1 + math.ceil(4.0 * tau_s / dt_s))


def lagged_exposure(steady: list[Exposure], spec: ColourSpec, dt_s: float) -> Exposure:
    """First-order lag of the exposure product: ``steady[0]`` is this frame's steady state,
    ``steady[i]`` the one i frames back; log P = sum_i w_i log P_i / sum_i w_i with
    w_i = (1 - alpha) ** i, alpha = 1 - exp(-dt / tau). A constant scene gives its steady state.
    """
    if spec.ae_time_constant_s <= 0.0 or len(steady) == 1:
        return steady[0]
    keep = math.exp(-dt_s / spec.ae_time_constant_s)  # 1 - alpha
    w = np.array([keep**i for i in range(len(steady))])
    logP = float(np.dot(w, [math.log(e.product_ms) for e in steady]) / w.sum())
    P = math.exp(logP)
    t = min(max(P, spec.min_exposure_ms), spec.max_exposure_ms)
    return Exposure(exposure_ms=t, gain=min(max(P / t, 1.0), spec.max_gain))


def vignette_map(
    width: int, height: int, fx: float, fy: float, ppx: float, ppy: float, strength: float
) -> np.ndarray:
    """(H, W) float32 relative irradiance ``1 - strength * (1 - cos^4 theta)``, theta the angle
    of the pixel's ray off the optical axis: cos^2 theta = 1 / (1 + ((u - ppx)/fx)^2 + ((v - ppy)/fy)^2)."""
    u = (np.arange(width, dtype=np.float64) - ppx) / fx
    v = (np.arange(height, dtype=np.float64) - ppy) / fy
    tan2 = v[:, None] ** 2 + u[None, :] ** 2
    cos4 = 1.0 / (1.0 + tan2) ** 2
    return (1.0 - strength * (1.0 - cos4)).astype(np.float32)


class ColourCamera:
    """The per-frame colour model for one image size and settings (tables built once)."""

    def __init__(self, spec: ColourSpec, width: int, height: int, fx: float, fy: float, ppx: float, ppy: float):
        self.spec = spec
        self.width, self.height = width, height
        self._decode = decode_lut(spec.gamma).astype(np.float32)
        self._vignette = None
        if spec.vignetting > 0:
            v = vignette_map(width, height, fx, fy, ppx, ppy, spec.vignetting)
            self._vignette = np.repeat(v[:, :, None], 3, axis=2)

    def render(
        self,
        rgb: np.ndarray,
        exposure: Exposure,
        lux: float,
        *,
        rng: np.random.Generator,
        pool: NoisePool | None,
        motion_px: tuple[float, float] = (0.0, 0.0),
        effects: bool = True,
    ) -> np.ndarray:
        """The delivered (H, W, 3) uint8 RGB from the encoded render ``rgb``.

        ``effects`` False keeps exposure and tone only (no noise, blur, vignetting, white-balance
        error or compression): the clean run. Noise samples come from ``pool`` (read through
        windows at offsets from ``rng``) or, without one, from ``rng``.
        """
        sp = self.spec
        img = rgb
        if effects and sp.motion_blur:
            k = motion_kernel(*motion_px)
            if k is not None:
                # only the kernel's non-zero rows and columns: a pan's line is 2 rows high
                ys, xs = np.nonzero(k)
                r = k.shape[0] // 2
                crop = np.ascontiguousarray(k[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1])
                anchor = (r - int(xs.min()), r - int(ys.min()))
                img = cv2.filter2D(img, -1, crop, anchor=anchor, borderType=cv2.BORDER_REFLECT)
        if effects and sp.defocus_sigma_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), sp.defocus_sigma_px)
        # linear signal relative to full scale: s = x * lux * K * t * G / FW, per channel x wb
        scale = lux * sp.sensitivity_e_per_lux_ms * exposure.product_ms / sp.full_well_e
        wb = np.asarray(sp.wb_gains if effects else (1.0, 1.0, 1.0), np.float32)
        lut = (self._decode[:, None] * np.float32(scale) * wb[None, :]).reshape(256, 1, 3)
        s = cv2.LUT(np.ascontiguousarray(img), lut)  # (H, W, 3) float32
        if effects and self._vignette is not None:
            cv2.multiply(s, self._vignette, dst=s)
        noisy = effects and (sp.shot_noise or sp.read_noise_e > 0)
        if noisy:
            G = exposure.gain
            a = np.float32(G / sp.full_well_e) if sp.shot_noise else np.float32(0.0)
            b = np.float32((G * sp.read_noise_e / sp.full_well_e) ** 2)
            # var(s) = a s + b
            sigma = cv2.max(s, 0.0)
            sigma *= a
            sigma += b
            cv2.sqrt(sigma, dst=sigma)
            n = pool.take(rng, s.shape) if pool is not None else rng.standard_normal(s.shape, dtype=np.float32)
            sigma *= n
            s += sigma
        # encode: 255 * clip(s, 0, 1) ** (1 / gamma), rounded (convertScaleAbs saturates at 255)
        if noisy:
            cv2.max(s, 0.0, dst=s)
        if sp.gamma != 1.0:
            cv2.pow(s, 1.0 / sp.gamma, dst=s)
        out = cv2.convertScaleAbs(s, alpha=255.0)
        if effects and sp.jpeg_quality > 0:
            bgr = cv2.cvtColor(out, cv2.COLOR_RGB2BGR)
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, sp.jpeg_quality])
            if not ok:
                raise RuntimeError("JPEG encoding failed")
            out = cv2.cvtColor(cv2.imdecode(buf, cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
        return out


@dataclass(kw_only=True)
class ColourSensor:
    """The colour stream as a frame sensor (:class:`sim.sensors.base.FrameSensor`): ``camera``
    under ``lux`` (:meth:`ColourCamera.render`), its noise from ``pool``; ``effects`` False is
    the clean run."""

    frame_field = "rgb"
    camera: ColourCamera
    lux: float
    pool: NoisePool | None
    effects: bool

    def measure(self, shot: Shot, rng: np.random.Generator) -> np.ndarray:
        return self.camera.render(
            shot.rgb,
            shot.exposure,
            self.lux,
            rng=rng,
            pool=self.pool,
            motion_px=shot.motion_px,
            effects=self.effects,
        )
