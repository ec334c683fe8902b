"""The detector protocol, the detector registry and the class-probability rule.

A detector takes a :class:`poi.core.types.Frame` and returns a list of
:class:`poi.core.types.Detection`. Each detector is a keyword-only dataclass of its
settings, registered by name so a config can say
``{"name": "onnx", "model": "m.onnx", "conf": 0.25}`` (docs/DESIGN.md, "Models and
registries").

>>> build_detector({"name": "thermal", "min_temp_c": 50.0}).min_temp_c
50.0
>>> build_detector({"name": "thermal", "min_tmp_c": 50.0})  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
poi.detectors.base.DetectorConfigError: detector 'thermal': unknown key 'min_tmp_c'; ...
>>> spread_class_probs(np.array([0.0, 0.8, 0.1, 0.1]), top=1)
array([0. , 0.8, 0.1, 0.1])

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np

from poi.core.names import CLASS_INDEX, CLASSES, class_domain, class_to_identity, identity_to_class
from poi.core.types import Detection, Frame

# The built-in detectors register themselves when poi.detectors is imported,
# which importing this module (poi.detectors.base) always does first.


class DetectorConfigError(ValueError):
    """A detector spec or a detector's data (model, names file) is not usable."""


@runtime_checkable
class Detector(Protocol):
    """Frame in, detections out."""

    name: str

    def detect(self, frame: Frame) -> list[Detection]: ...


REGISTRY: dict[str, type] = {}


def register(name: str) -> Callable[[type], type]:
    """Class decorator: make a detector dataclass buildable as ``{"name": name, ...}``."""

    def wrap(cls: type) -> type:
        if name in REGISTRY and REGISTRY[name] is not cls:
            raise DetectorConfigError(f"detector name {name!r} is already registered")
        REGISTRY[name] = cls
        return cls

    return wrap


CPU_PROVIDER = "CPUExecutionProvider"


@dataclasses.dataclass(frozen=True)
class ProviderChoice:
    """The onnxruntime execution providers a session is opened with, and the one line that says
    which requested ones this onnxruntime lacks (empty when it has them all)."""

    providers: list[str]
    note: str


def choose_providers(requested: Sequence[str] | None, error: type[Exception]) -> ProviderChoice:
    """The requested providers this onnxruntime has, in order, CPU last as the fallback.

    A name onnxruntime does not know at all (``ort.get_all_providers()``) raises ``error``; one
    it knows but was not built with (CUDA in the CPU wheel) is skipped and named in the note.
    """
    import onnxruntime as ort

    names = [CPU_PROVIDER] if requested is None else [] if isinstance(requested, str) else list(requested)
    if not names or not all(isinstance(n, str) for n in names):
        raise error(f"providers: expected a list of onnxruntime execution provider names, got {requested!r}")
    known = ort.get_all_providers()
    for n in names:
        if n not in known:
            raise error(f"providers: {n!r} is not an onnxruntime execution provider; expected some of {known}")
    available = ort.get_available_providers()
    chosen = [n for n in dict.fromkeys(names) if n in available]
    missing = [n for n in dict.fromkeys(names) if n not in available]
    if CPU_PROVIDER not in chosen:
        chosen.append(CPU_PROVIDER)
    note = ""
    if missing:
        verb = "is" if len(missing) == 1 else "are"
        note = (
            f"{', '.join(missing)} {verb} not available in this onnxruntime {ort.__version__} "
            f"(it has {', '.join(available)}); running on {chosen[0]}"
        )
    return ProviderChoice(chosen, note)


def check_model_file(path: str | Path, error: type[Exception], what: str = "model") -> None:
    """Raise ``error`` with one line unless ``path`` is a file: not there, or a folder."""
    p = Path(path)
    if p.is_dir():
        raise error(f"{what} {p}: is a folder, not an ONNX file")
    if not p.is_file():
        raise error(f"{what} file not found: {p}")


def open_onnx_session(
    path: Path,
    threads: int,
    error: type[Exception],
    what: str = "model",
    providers: list[str] | None = None,
) -> Any:
    """An onnxruntime session for ``path`` (``threads`` intra-op threads, quiet logging) on
    ``providers`` (default the CPU; see :func:`choose_providers` for unavailable ones);
    a missing or unloadable file raises ``error`` with one line naming it."""
    import onnxruntime as ort

    check_model_file(path, error, what)
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = int(threads)
    opts.inter_op_num_threads = 1
    # Idle intra-op threads block instead of spinning: with spinning two threads cost twice
    # one thread's CPU for the same boxes; without it about the same CPU as one thread and
    # less wall time on an idle second core (issue 18; onnxruntime's session option
    # ``session.intra_op.allow_spinning`` [OnnxRuntimeThreads]).
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    opts.log_severity_level = 3
    try:
        return ort.InferenceSession(str(path), sess_options=opts, providers=providers or [CPU_PROVIDER])
    except Exception as exc:  # onnxruntime raises its own Fail / InvalidProtobuf types
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise error(f"{path}: not a loadable ONNX model ({first[:200]})") from exc


def build_detector(spec: dict[str, Any]) -> Detector:
    """Build the detector a spec names; every other key is one of its settings.

    Unknown names and unknown keys raise :class:`DetectorConfigError` naming them.
    """
    if not isinstance(spec, dict):
        raise DetectorConfigError(f"detector spec must be a mapping, got {type(spec).__name__}")
    if "name" not in spec:
        raise DetectorConfigError(f"detector spec has no 'name' key: {sorted(spec)}")
    name = spec["name"]
    if name not in REGISTRY:
        raise DetectorConfigError(f"unknown detector {name!r}; expected one of {sorted(REGISTRY)}")
    cls = REGISTRY[name]
    settings = {
        f.name for f in dataclasses.fields(cls) if f.init and f.name != "name"
    }  # 'name' is the registry key, not a setting
    kwargs = {k: v for k, v in spec.items() if k != "name"}
    for key in kwargs:
        if key not in settings:
            raise DetectorConfigError(
                f"detector {name!r}: unknown key {key!r}; expected some of {sorted(settings)}"
            )
    return cls(**kwargs)


def spread_class_probs(scores: np.ndarray, top: int) -> np.ndarray:
    """A distribution over classes from one detection's score vector ([Avevor2022]_ section 2.1.5).

    The top class keeps its score p; the remaining mass 1 - p is spread over the
    other classes in proportion to their scores, or uniformly when they are all
    zero: Pr(B | detected A) = (1 - p) Pr(B | A misclassified).
    ``scores`` must be finite and in [0, 1]; the result sums to 1.
    """
    s = np.asarray(scores, dtype=np.float64)  # (K,)
    K = s.shape[0]
    if s.ndim != 1 or K == 0:
        raise ValueError(f"scores must be a non-empty 1-D vector, got shape {s.shape}")
    if not np.all(np.isfinite(s)) or s.min() < 0.0 or s.max() > 1.0:
        raise ValueError("scores must be finite and in [0, 1]")
    if not 0 <= top < K:
        raise ValueError(f"top index {top} out of range for {K} classes")
    p = float(s[top])
    probs = np.zeros(K, dtype=np.float64)
    probs[top] = p
    if K == 1:
        probs[top] = 1.0
        return probs
    others = np.ones(K, dtype=bool)
    others[top] = False
    rest = s[others]  # (K-1,)
    total = float(rest.sum())
    if total > 0.0:
        # Pr(B | A misclassified) ~ score of B among the others.
        probs[others] = (1.0 - p) * rest / total
    else:
        probs[others] = (1.0 - p) / (K - 1)
    return probs


def one_class_probs(class_name: str, p: float) -> np.ndarray:
    """Class probabilities over CLASSES for a detector that knows only its top class.

    ``class_name`` gets ``p``, every other class of its domain (the rescue classes, or
    the arena's: :func:`poi.core.names.class_domain`) (1 - p) / (domain size - 1), the other
    domain 0 ([Avevor2022]_ section 2.1.5 with no information on the misclassification).

    >>> pr = one_class_probs("heat-source", 0.9)
    >>> round(float(pr[CLASS_INDEX["heat-source"]]), 3), round(float(pr.sum()), 6)
    (0.9, 1.0)
    >>> round(float(pr[CLASS_INDEX["door"]]) * 23, 6), float(pr[CLASS_INDEX["ball"]])
    (0.1, 0.0)
    """
    domain = [CLASS_INDEX[c] for c in class_domain(class_name)]
    scores = np.zeros(len(domain))
    k = domain.index(CLASS_INDEX[class_name])
    scores[k] = p
    probs = np.zeros(len(CLASSES))
    probs[domain] = spread_class_probs(scores, k)
    return probs


def canonical_class(model_name: str) -> str | None:
    """The name in CLASSES a model's class name stands for, or None if unknown.

    >>> canonical_class("Toxic"), canonical_class("QR code"), canonical_class("car")
    ('inhalation-hazard', 'qr', None)
    """
    identity = class_to_identity(model_name)
    if identity is None:
        return None
    return identity_to_class(*identity)


@functools.lru_cache(maxsize=256)
def _identity(class_name: str) -> tuple[str, str] | None:
    return class_to_identity(class_name)


def make_detection(
    class_name: str,
    box_xyxy: tuple[float, float, float, float],
    confidence: float,
    *,
    source: str,
    class_probs: np.ndarray | None,
    text: str | None = None,
) -> Detection:
    """A Detection for a name in CLASSES, its type and text taken from the name."""
    identity = _identity(class_name)
    if identity is None:
        raise ValueError(f"class {class_name!r} is not in poi.core.names.CLASSES")
    type_, label = identity
    x1, y1, x2, y2 = (float(c) for c in box_xyxy)
    return Detection(
        class_name=class_name,
        type=type_,
        text=label if text is None else text,
        box_xyxy=(x1, y1, x2, y2),
        confidence=float(confidence),
        source=source,
        class_probs=class_probs,
    )
