"""Detectors written in Python by a team: ``python:MODULE:CLASS`` and the ``poibench.detectors`` entry points.

A team's detector is any class (or factory) whose objects follow the
:class:`poi.detectors.base.Detector` protocol: ``detect(frame: Frame) -> list[Detection]``.
It is named either by import path, ``python:mypkg.detect:MyDetector``, or, when an installed
package registers it in the entry point group ``poibench.detectors``
(``[project.entry-points."poibench.detectors"] mydet = "mypkg.detect:MyDetector"``), by that
name. Its keyword arguments are the pipeline config's ``detector.options``
(``--set detector.options.weights=best.pt``).

Every mistake is one line naming the detector: a module that does not import, a missing
attribute, something not callable, options it does not take (with those it does), an object
without ``detect``, and, at the first frame that shows it, output that is not a list of
:class:`poi.core.types.Detection` with class names in :data:`poi.core.names.CLASSES`.

>>> parse_python_spec("python:mypkg.detect:MyDetector")
('mypkg.detect', 'MyDetector')
>>> parse_python_spec("python:mypkg")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
poi.detectors.base.DetectorConfigError: detector 'python:mypkg': expected python:MODULE:CLASS, ...
"""

from __future__ import annotations

import importlib
import importlib.metadata
import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from poi.core.names import CLASSES, class_to_identity
from poi.core.types import Detection, Frame
from poi.detectors.base import REGISTRY, DetectorConfigError, canonical_class

PYTHON_PREFIX = "python:"
ENTRY_POINT_GROUP = "poibench.detectors"


class DetectorOutputError(DetectorConfigError):
    """A Python detector failed on a frame or returned something that is not a list of Detections;
    ``detector`` (its name) and ``reason`` as well as the one-line message, for a caller that
    names the frame its own way (an image file)."""

    def __init__(self, message: str, *, detector: str = "", reason: str = "") -> None:
        super().__init__(message)
        self.detector, self.reason = detector, reason


def is_python_spec(choice: str) -> bool:
    """Whether ``choice`` names a detector by import path (``python:MODULE:CLASS``)."""
    return choice.startswith(PYTHON_PREFIX)


def parse_python_spec(choice: str) -> tuple[str, str]:
    """(module, attribute) of ``python:MODULE:CLASS``; the attribute may be dotted (``Outer.Inner``)."""
    body = choice[len(PYTHON_PREFIX) :] if is_python_spec(choice) else choice
    module, sep, attr = body.partition(":")
    if not sep or not module or not attr or ":" in attr or module.startswith("."):
        raise DetectorConfigError(
            f"detector {choice!r}: expected python:MODULE:CLASS, e.g. python:mypkg.detect:MyDetector"
        )
    return module, attr


def _entry_points() -> dict[str, importlib.metadata.EntryPoint]:
    """The installed ``poibench.detectors`` entry points by name (the first of a duplicated name)."""
    found: dict[str, importlib.metadata.EntryPoint] = {}
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        found.setdefault(ep.name, ep)
    return found


def entry_point_names() -> list[str]:
    """The detector names installed packages register in the ``poibench.detectors`` group."""
    return sorted(_entry_points())


def is_entry_point(choice: str) -> bool:
    """Whether an installed package registers ``choice`` in the ``poibench.detectors`` group."""
    return choice in _entry_points()


def is_team_detector(choice: str) -> bool:
    """Whether ``choice`` names a team's Python detector: ``python:MODULE:CLASS``, or an entry point
    name that is not a built-in detector's (the registry's names come first)."""
    return is_python_spec(choice) or (choice not in REGISTRY and is_entry_point(choice))


def _import_attr(choice: str, module: str, attr: str) -> Any:
    try:
        mod = importlib.import_module(module)
    except ImportError as exc:
        raise DetectorConfigError(f"detector {choice!r}: cannot import module {module!r} ({exc})") from exc
    except Exception as exc:  # the module's own code failed (SyntaxError, an error at import time)
        raise DetectorConfigError(
            f"detector {choice!r}: importing module {module!r} failed: {type(exc).__name__}: {exc}"
        ) from exc
    obj: Any = mod
    for part in attr.split("."):
        if not hasattr(obj, part):
            offered = sorted(
                n for n, v in vars(mod).items() if inspect.isclass(v) and callable(getattr(v, "detect", None))
            )
            hint = f"; it defines {', '.join(offered)}" if offered else ""
            raise DetectorConfigError(f"detector {choice!r}: module {module!r} has no attribute {attr!r}{hint}")
        obj = getattr(obj, part)
    return obj


def resolve_factory(choice: str) -> Callable[..., Any]:
    """The class (or factory) ``choice`` names: ``python:MODULE:CLASS`` or a ``poibench.detectors`` entry point."""
    if is_python_spec(choice):
        obj = _import_attr(choice, *parse_python_spec(choice))
    else:
        ep = _entry_points().get(choice)
        if ep is None:
            names = ", ".join(entry_point_names()) or "none installed"
            raise DetectorConfigError(
                f"detector {choice!r}: not a {ENTRY_POINT_GROUP} entry point (installed: {names})"
            )
        if not ep.attr:
            raise DetectorConfigError(
                f"detector {choice!r}: its {ENTRY_POINT_GROUP} entry point {ep.value!r} names no class "
                "(expected MODULE:CLASS)"
            )
        obj = _import_attr(choice, ep.module, ep.attr)
    if not callable(obj):
        raise DetectorConfigError(
            f"detector {choice!r}: {type(obj).__name__} object is not a class or callable; "
            "expected a class whose objects have detect(frame)"
        )
    return obj


def _check_options(choice: str, factory: Callable[..., Any], options: Mapping[str, Any]) -> None:
    """Refuse options the factory does not take and required ones that are missing, naming what it takes."""
    try:
        sig = inspect.signature(factory)
    except (TypeError, ValueError):  # a builtin without a signature: let the call decide
        return
    params = list(sig.parameters.values())
    named = [p for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    takes = ", ".join(p.name for p in named) or "no options"
    if not any(p.kind is p.VAR_KEYWORD for p in params):
        unknown = sorted(set(options) - {p.name for p in named})
        if unknown:
            raise DetectorConfigError(
                f"detector {choice!r}: unknown option(s) {', '.join(unknown)}; it takes {takes}"
            )
    positional = [p.name for p in params if p.kind is p.POSITIONAL_ONLY and p.default is p.empty]
    if positional:
        raise DetectorConfigError(
            f"detector {choice!r}: it needs positional-only argument(s) {', '.join(positional)}; "
            "expected keyword arguments only, which detector.options gives"
        )
    missing = [p.name for p in named if p.default is p.empty and p.name not in options]
    if missing:
        raise DetectorConfigError(f"detector {choice!r}: missing option(s) {', '.join(missing)}; it takes {takes}")


def check_python_detector(choice: str, options: Mapping[str, Any] | None = None) -> None:
    """Raise what :func:`build_python_detector` would for the spec and the options, without building it."""
    _check_options(choice, resolve_factory(choice), dict(options or {}))


def build_python_detector(choice: str, options: Mapping[str, Any] | None = None) -> CheckedDetector:
    """Build the detector ``choice`` names from ``options`` (its keyword arguments), checked.

    The result checks each frame's output (:class:`CheckedDetector`).
    """
    opts = dict(options or {})
    factory = resolve_factory(choice)
    _check_options(choice, factory, opts)
    try:
        obj = factory(**opts)
    except Exception as exc:
        raise DetectorConfigError(f"detector {choice!r}: building it failed: {type(exc).__name__}: {exc}") from exc
    if not callable(getattr(obj, "detect", None)):
        raise DetectorConfigError(
            f"detector {choice!r}: the {type(obj).__name__} object it built has no detect(frame) method "
            "(the poi.detectors.Detector protocol)"
        )
    return CheckedDetector(name=choice, inner=obj)


def _bad_class(name: Any) -> str:
    hint = ""
    if isinstance(name, str):
        canon = canonical_class(name)
        if canon is not None:
            hint = f" (did you mean {canon!r}?)"
    return f"class_name {name!r} is not in poi.core.names.CLASSES{hint}"


def check_detection(det: Any, image_wh: tuple[int, int] | None = None) -> str | None:
    """Why ``det`` is not a usable :class:`Detection`, or None; with ``image_wh`` (width,
    height) its box must also cover some of the image."""
    if not isinstance(det, Detection):
        return f"a {type(det).__name__}, not a poi.core.types.Detection"
    for name in ("text", "source"):
        if not isinstance(getattr(det, name), str):
            return f"{name} {getattr(det, name)!r} is not a str"
    identity = class_to_identity(det.class_name) if isinstance(det.class_name, str) else None
    if identity is None or det.class_name not in CLASSES:
        return _bad_class(det.class_name)
    if det.type != identity[0]:
        return (
            f"class_name {det.class_name!r} has type {det.type!r}, expected {identity[0]!r} "
            "(poi.detectors.base.make_detection sets it)"
        )
    box = det.box_xyxy
    try:
        values = [float(v) for v in box]
    except (TypeError, ValueError):
        return f"box_xyxy {box!r} is not 4 numbers"
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        return f"box_xyxy {box!r} is not 4 finite numbers"
    if values[2] < values[0] or values[3] < values[1]:
        return f"box_xyxy {box!r} is not (x1, y1, x2, y2) with x1 <= x2 and y1 <= y2"
    if values[2] == values[0] or values[3] == values[1]:
        return f"box_xyxy {box!r} has no area"
    if image_wh is not None:
        w, h = image_wh
        if values[2] <= 0 or values[3] <= 0 or values[0] >= w or values[1] >= h:
            return f"box_xyxy {box!r} lies outside the {w}x{h} image"
    if isinstance(det.confidence, bool):
        return f"confidence {det.confidence!r} is a bool, not a score"
    try:
        conf = float(det.confidence)
    except (TypeError, ValueError):
        return f"confidence {det.confidence!r} is not a number"
    if not 0.0 <= conf <= 1.0:
        return f"confidence {det.confidence!r} is not in [0, 1]"
    if det.class_probs is not None:
        p = np.asarray(det.class_probs)
        if p.shape != (len(CLASSES),) or not np.all(np.isfinite(p)) or np.any(p < 0) or not p.sum() > 0:
            return (
                f"class_probs of shape {p.shape} is not {len(CLASSES)} finite values >= 0 (one per class) "
                "with a positive sum, or None"
            )
    return None


@dataclass(kw_only=True)
class CheckedDetector:
    """A team's detector with its output checked on every frame.

    A detector that raises, or returns anything but a list (or tuple) of valid
    :class:`Detection`, stops the trial with a :class:`DetectorOutputError` naming the
    detector, the frame and the bad value.
    """

    name: str
    inner: Any

    def detect(self, frame: Frame) -> list[Detection]:
        try:
            out = self.inner.detect(frame)
        except Exception as exc:
            raise self._error(frame, f"{type(exc).__name__}: {exc}") from exc
        if not isinstance(out, list | tuple):
            raise self._error(frame, f"returned a {type(out).__name__}, expected a list of Detection")
        image_wh = None if frame.rgb is None else (int(frame.rgb.shape[1]), int(frame.rgb.shape[0]))
        for k, det in enumerate(out):
            why = check_detection(det, image_wh)
            if why is not None:
                raise self._error(frame, f"detection {k}: {why}")
        return list(out)

    def _error(self, frame: Frame, reason: str) -> DetectorOutputError:
        return DetectorOutputError(
            f"detector {self.name!r} on frame {frame.index}: {reason}", detector=self.name, reason=reason
        )
