"""Error propagation from a detection to its map position ([Avevor2022]_ sections 2.1.4, 2.2.2, 2.3.2).

The chain is (u, v) -> (u, v, d) -> (x_c, y_c, z_c) -> (x_w, y_w, z_w):

* Sigma_1 = diag(sigma_u^2, sigma_v^2, sigma_d^2): centre error of the box (a model in
  the box size, or a per-class calibration) and depth noise of the D435,
  sigma_z = z^2 sigma_d_px / (f B) (docs/FACTS.md "D435 depth"; :func:`poi.core.sensor_noise.depth_sigma_m`);
* J1 adds the depth change from a centre error, d(u, v) read from the depth image's
  central differences; Sigma_2 = J1 Sigma_1 J1^T;
* J2 is the Jacobian of the deprojection f(u, v, d), by central differences;
  Sigma_c = J2 J1 Sigma_1 J1^T J2^T;
* R = Q Q0 Sigma_c Q0^T Q^T + Sigma_eps in the map frame.

The calibration file (YAML) holds what [Avevor2022]_ says to fit on a validation set::

    poibench_calibration: 1
    # sigma_u^2(w) = sum_k u[k] w^k and sigma_v^2(h) = sum_k v[k] h^k, in px^2, for a
    # box w x h px; keys are class names of poi.core.names.CLASSES, or `default` for the rest.
    # Coefficients are >= 0 so the variance is positive for every box size.
    center_variance_px2:
      default: {u: [1.0, 0.06, 0.0009], v: [1.0, 0.06, 0.0009]}
      door: {u: [4.0, 0.1], v: [4.0, 0.1]}
    # Optional. Row A: Pr(actually class B | detected A, A misclassified) ([Avevor2022] 2.1.5);
    # a C x C matrix over `classes`: each of poi.core.names.CLASSES once, or each of the 24
    # poi.core.names.RESCUE_CLASSES once (what `poibench calibrate` writes for a rescue
    # detector); without `classes`, the matrix size says which, in that order. Zero
    # diagonal; rows sum to 1.
    confusion:
      classes: [explosive, ...]
      matrix: [[0.0, 0.1, ...], ...]

A confusion matrix over the rescue classes only is expanded to all of CLASSES
(:func:`expand_confusion`): a covered class keeps its row (and is never mistaken for
a class the matrix does not know: 0 there); a class it does not cover gets a uniform
row, so the tracker's p(actual B | detected A) = (1 - p) C[A, B] spreads its 1 - p
evenly over the other classes, as with no calibration.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from poi.core.loader import LoadError, Source, is_finite_number, load_yaml_file
from poi.core.names import CLASS_INDEX, CLASSES, RESCUE_CLASSES
from poi.core.sensor_noise import center_sigma_px

# Central-difference steps for J2. The deprojection is bilinear in (u, d) and (v, d) for
# model "none", so any step is exact there; for Brown-Conrady the error is O(step^2) of a
# smooth function: 1e-3 px and 1e-4 m keep it far below 1e-9 relative while staying well
# above float64 rounding of the pixel coordinate (~1e-13 px).
J2_STEP_PX = 1e-3
J2_STEP_M = 1e-4
CONFUSION_ROW_SUM_TOL = 1e-3

CALIBRATION_VERSION = 1


class CalibrationError(LoadError):
    """A calibration file that cannot be used; the message names the file and key."""


def _valid(d: float) -> bool:
    return math.isfinite(d) and d > 0.0


def depth_jacobian(depth_m: np.ndarray, u: float, v: float, depth_scale: float = 1.0) -> np.ndarray:
    """J1 of [Avevor2022]_ section 2.2.2 at pixel (u, v) (pixel-centre coordinates, rounded).

    The last row holds dd/du and dd/dv from central differences of the depth image,
    0.5 (d(u+1, v) - d(u-1, v)) and 0.5 (d(u, v+1) - d(u, v-1)). At the border the
    neighbour index is clamped and the difference divided by the actual index distance
    (a one-sided difference); a gradient with an invalid (0, NaN) neighbour is 0.

    >>> d = np.array([[1.0, 2.0, 4.0], [1.0, 2.0, 4.0]])
    >>> depth_jacobian(d, 1, 0)[2].tolist()
    [1.5, 0.0, 1.0]
    """
    H, W = depth_m.shape
    ui = int(np.clip(round(u), 0, W - 1))
    vi = int(np.clip(round(v), 0, H - 1))

    def grad(a0: int, a1: int, get: Callable[[int], float]) -> float:
        if a1 == a0:
            return 0.0
        d0, d1 = float(get(a0)), float(get(a1))
        if not (_valid(d0) and _valid(d1)):
            return 0.0
        return depth_scale * (d1 - d0) / (a1 - a0)

    ddu = grad(max(ui - 1, 0), min(ui + 1, W - 1), lambda i: depth_m[vi, i])
    ddv = grad(max(vi - 1, 0), min(vi + 1, H - 1), lambda j: depth_m[j, ui])
    J1 = np.eye(3)
    J1[2, 0] = ddu
    J1[2, 1] = ddv
    return J1


def deprojection_jacobian(
    f: Callable[[float, float, float], np.ndarray],
    u: float,
    v: float,
    d: float,
    *,
    step_px: float = J2_STEP_PX,
    step_m: float = J2_STEP_M,
) -> np.ndarray:
    """J2 = d(x_c, y_c, z_c) / d(u, v, d') by central differences ([Avevor2022]_ section 2.2.2).

    Column k is (f(a + h e_k) - f(a - h e_k)) / (2 h) with h = ``step_px`` for u and v
    and ``step_m`` for d.
    """
    a = np.array([u, v, d], dtype=float)
    steps = (step_px, step_px, step_m)
    J2 = np.empty((3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = steps[k]
        J2[:, k] = (np.asarray(f(*(a + e))) - np.asarray(f(*(a - e)))) / (2.0 * steps[k])
    return J2


def camera_covariance(J1: np.ndarray, J2: np.ndarray, Sigma_1: np.ndarray) -> np.ndarray:
    """Sigma_c = J2 J1 Sigma_1 J1^T J2^T ([Avevor2022]_ section 2.2.2)."""
    # Sigma_2 = J1 Sigma_1 J1^T, Sigma_c = J2 Sigma_2 J2^T
    Sigma_2 = J1 @ Sigma_1 @ J1.T
    Sigma_c = J2 @ Sigma_2 @ J2.T
    return 0.5 * (Sigma_c + Sigma_c.T)


def map_covariance(Sigma_c: np.ndarray, Q: np.ndarray, Q0: np.ndarray, sigma_eps_m: float) -> np.ndarray:
    """R = Q Q0 Sigma_c Q0^T Q^T + Sigma_eps, Sigma_eps = sigma_eps^2 I ([Avevor2022]_ section 2.3.2).

    >>> R = map_covariance(np.diag([1.0, 4.0, 9.0]), np.eye(3), np.eye(3), 0.0)
    >>> np.diag(R).tolist()
    [1.0, 4.0, 9.0]
    """
    QQ0 = Q @ Q0
    R = QQ0 @ Sigma_c @ QQ0.T + (sigma_eps_m**2) * np.eye(3)
    return 0.5 * (R + R.T)


def mount_covariance(q: np.ndarray, sigma_rad: float, sigma_m: float) -> np.ndarray:
    """The map-frame covariance of a point from an error in the camera's mount calibration.

    The pipeline places a point by the nominal mount (Q0, t0); if the true one is
    Q0 exp(S(delta)), t0 + delta_t (S(v) the cross-product matrix, S(v) w = v x w), the point
    moves by Q Q0 (delta x p_c) + Q delta_t = -S(q) (Q Q0 delta) + Q delta_t with q = Q Q0 p_c
    the camera-to-point vector in the map frame (first order). For isotropic
    delta ~ N(0, sigma_rad^2 I) and delta_t ~ N(0, sigma_m^2 I):
    ``sigma_rad^2 (|q|^2 I - q q^T) + sigma_m^2 I``, since S(q) S(q)^T = |q|^2 I - q q^T. A
    rotation error moves far points more, and never along the line of sight.

    >>> mount_covariance(np.array([2.0, 0.0, 0.0]), 0.01, 0.0).diagonal().round(8).tolist()
    [0.0, 0.0004, 0.0004]
    """
    q = np.asarray(q, dtype=float)
    return sigma_rad**2 * (float(q @ q) * np.eye(3) - np.outer(q, q)) + sigma_m**2 * np.eye(3)


def tilt_covariance(q: np.ndarray, sigma_rad: float) -> np.ndarray:
    """The map-frame covariance of a point from an error in the tracker's roll and pitch.

    A tilt error delta = (delta_x, delta_y, 0) about the map's horizontal axes (the tracker's
    heading error is the SLAM's) moves a point q from the tracker (map frame) by delta x q =
    -S(q) delta (first order, as :func:`mount_covariance`); for delta_x, delta_y ~
    N(0, sigma_rad^2) that is ``sigma_rad^2 S(q) diag(1, 1, 0) S(q)^T``. A point straight
    ahead moves up and down only, by its distance times the pitch error.

    >>> tilt_covariance(np.array([2.0, 0.0, 0.0]), 0.01).diagonal().round(8).tolist()
    [0.0, 0.0, 0.0004]
    """
    q = np.asarray(q, dtype=float)
    # the columns of S(q) for the x and y axes: e_x x q and e_y x q, negated (the sign cancels)
    c = np.array([[0.0, -q[2], q[1]], [q[2], 0.0, -q[0]]])
    return sigma_rad**2 * (c.T @ c)


@dataclass(kw_only=True)
class CenterVariance:
    """sigma_u^2(w) = sum_k u[k] w^k, sigma_v^2(h) = sum_k v[k] h^k in px^2 ([Avevor2022]_ 2.1.4)."""

    u: tuple[float, ...]
    v: tuple[float, ...]

    def variances(self, w: float, h: float) -> tuple[float, float]:
        var_u = sum(c * w**k for k, c in enumerate(self.u))
        var_v = sum(c * h**k for k, c in enumerate(self.v))
        return float(var_u), float(var_v)


@dataclass(kw_only=True)
class Calibration:
    """Per-class centre-error models and an optional confusion matrix (see module docstring)."""

    center_variance: dict[str, CenterVariance] = field(default_factory=dict)
    confusion: np.ndarray | None = None  # (C, C) over poi.core.names.CLASSES
    source: str = "<calibration>"

    def center_model(self, class_name: str) -> CenterVariance | None:
        return self.center_variance.get(class_name, self.center_variance.get("default"))


def center_sigmas_px(
    class_name: str,
    w: float,
    h: float,
    *,
    a_px: float,
    b: float,
    calibration: Calibration | None = None,
) -> tuple[float, float]:
    """(sigma_u, sigma_v) in px for a w x h box: the calibration's model for the class, or a + b w.

    >>> center_sigmas_px("door", 100.0, 50.0, a_px=1.0, b=0.03)
    (4.0, 2.5)
    """
    model = calibration.center_model(class_name) if calibration is not None else None
    if model is None:
        return (center_sigma_px(w, a_px=a_px, b=b), center_sigma_px(h, a_px=a_px, b=b))
    var_u, var_v = model.variances(w, h)
    return (math.sqrt(var_u), math.sqrt(var_v))


def _coeffs(value: Any, where: str) -> tuple[float, ...]:
    ok = isinstance(value, list) and len(value) >= 1
    ok = ok and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in value)
    if not ok or not all(is_finite_number(c) and c >= 0 for c in value):
        raise CalibrationError(f"{where}: expected a non-empty list of coefficients >= 0, got {value!r}")
    if value[0] <= 0:
        raise CalibrationError(f"{where}: expected a constant term > 0 (a positive variance), got {value[0]!r}")
    return tuple(float(c) for c in value)


def calibration_from_dict(doc: Any, source: str | Source = "<calibration>") -> Calibration:
    """Validate and build a :class:`Calibration` from the parsed YAML document.

    ``source`` names it in errors (a :class:`poi.core.loader.Source` adds each key's line).
    """
    src = source if isinstance(source, Source) else Source(source)
    source = src.name
    if not isinstance(doc, dict):
        raise CalibrationError(f"{source}: expected a mapping, got {type(doc).__name__}")
    allowed = {"poibench_calibration", "center_variance_px2", "confusion"}
    for k in doc:
        if k not in allowed:
            raise CalibrationError(
                f"{src.where(str(k))}: {k}: unknown key; expected one of {', '.join(sorted(allowed))}"
            )
    if doc.get("poibench_calibration") != CALIBRATION_VERSION:
        raise CalibrationError(
            f"{src.where('poibench_calibration')}: poibench_calibration: expected {CALIBRATION_VERSION}, "
            f"got {doc.get('poibench_calibration')!r}"
        )
    centers: dict[str, CenterVariance] = {}
    cv = doc.get("center_variance_px2", {}) or {}
    if not isinstance(cv, dict):
        raise CalibrationError(
            f"{src.where('center_variance_px2')}: center_variance_px2: expected a mapping of class -> {{u, v}}"
        )
    for name, entry in cv.items():
        where = f"{src.where(f'center_variance_px2.{name}')}: center_variance_px2.{name}"
        if name != "default" and name not in CLASS_INDEX:
            raise CalibrationError(
                f"{where}: unknown class; expected 'default' or a name of poi.core.names.CLASSES"
            )
        if not isinstance(entry, dict) or set(entry) != {"u", "v"}:
            raise CalibrationError(f"{where}: expected a mapping with keys u and v, got {entry!r}")
        centers[name] = CenterVariance(u=_coeffs(entry["u"], where + ".u"), v=_coeffs(entry["v"], where + ".v"))
    confusion = None
    if doc.get("confusion") is not None:
        confusion = _confusion(doc["confusion"], f"{src.where('confusion')}: confusion")
    return Calibration(center_variance=centers, confusion=confusion, source=source)


def _confusion(entry: Any, where: str) -> np.ndarray:
    """The (C, C) matrix over CLASSES from a ``confusion`` entry over CLASSES or RESCUE_CLASSES."""
    if not isinstance(entry, dict) or "matrix" not in entry or not set(entry) <= {"classes", "matrix"}:
        raise CalibrationError(f"{where}: expected a mapping with keys matrix (and optionally classes)")
    try:
        M = np.array(entry["matrix"], dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise CalibrationError(f"{where}.matrix: expected a square matrix of numbers") from None
    spaces = {len(CLASSES): CLASSES, len(RESCUE_CLASSES): RESCUE_CLASSES}
    expected = (
        f"each of the {len(RESCUE_CLASSES)} names of poi.core.names.RESCUE_CLASSES once, "
        f"or each of the {len(CLASSES)} of CLASSES once"
    )
    if "classes" in entry:
        classes = entry["classes"]
        space = spaces.get(len(classes)) if isinstance(classes, list) else None
        if space is None or not all(isinstance(c, str) for c in classes) or sorted(classes) != sorted(space):
            raise CalibrationError(f"{where}.classes: expected {expected}")
    else:
        space = spaces.get(M.shape[0]) if M.ndim == 2 else None
        if space is None:
            raise CalibrationError(
                f"{where}.matrix: expected a {len(RESCUE_CLASSES)} x {len(RESCUE_CLASSES)} (RESCUE_CLASSES) "
                f"or {len(CLASSES)} x {len(CLASSES)} (CLASSES) matrix of numbers, got shape {M.shape}"
            )
        classes = list(space)
    C = len(classes)
    if M.shape != (C, C) or not np.all(np.isfinite(M)):
        raise CalibrationError(f"{where}.matrix: expected a {C} x {C} matrix of numbers, got shape {M.shape}")
    if np.any(M < 0):
        raise CalibrationError(f"{where}.matrix: expected probabilities >= 0")
    if np.any(np.diag(M) != 0):
        raise CalibrationError(f"{where}.matrix: expected a zero diagonal (a misclassified class is another one)")
    sums = M.sum(axis=1)
    bad = np.flatnonzero(np.abs(sums - 1.0) > CONFUSION_ROW_SUM_TOL)
    if bad.size:
        i = int(bad[0])
        raise CalibrationError(f"{where}.matrix: row {i} ({classes[i]}) sums to {sums[i]:.6f}, expected 1")
    M = M / sums[:, None]
    return expand_confusion(M, classes)


def expand_confusion(M: np.ndarray, classes: list[str] | tuple[str, ...]) -> np.ndarray:
    """The (C, C) confusion matrix over CLASSES, in CLASSES order, from ``M`` over ``classes``.

    Rows and columns of ``classes`` keep their values (a covered class is misread only as
    another covered class); the row of a class ``classes`` lacks is uniform over the
    other C - 1 classes, so its (1 - p) spreads evenly. Rows sum to 1 and the diagonal
    stays 0.

    >>> E = expand_confusion(np.array([[0.0, 1.0], [1.0, 0.0]]), ["qr", "door"])
    >>> E.shape == (len(CLASSES), len(CLASSES)), float(E[CLASS_INDEX["qr"], CLASS_INDEX["door"]])
    (True, 1.0)
    >>> ball = E[CLASS_INDEX["ball"]]
    >>> float(ball[CLASS_INDEX["ball"]]), round(float(ball[CLASS_INDEX["qr"]] * (len(CLASSES) - 1)), 12)
    (0.0, 1.0)
    """
    C = len(CLASSES)
    idx = [CLASS_INDEX[c] for c in classes]
    E = np.full((C, C), 1.0 / (C - 1))
    E[idx, :] = 0.0  # covered rows: only their own (covered) columns below
    E[np.ix_(idx, idx)] = M
    np.fill_diagonal(E, 0.0)
    return E


def load_calibration(path: str | Path) -> Calibration:
    """Load and validate a calibration YAML file (format in the module docstring)."""
    data, src = load_yaml_file(path, what="calibration", error=CalibrationError)
    return calibration_from_dict(data, src)
