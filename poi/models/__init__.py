"""The shipped detector, its placard label classifier, its calibration and its operating point,
and the one rule that goes with them: the shipped detector brings the shipped label model,
calibration and operating point.

A run whose detector choice is ``default`` runs ``default.onnx`` with ``default_labels.onnx``
(which names the placards it finds), ``default_calibration.yaml`` (``poibench calibrate`` of
the two: the shipped model's own error model, [Avevor2022]_ 2.1.4-2.1.5) and
``default_operating_point.yaml`` (the minimum score of each type whose boxes the pair scores
differently from the others, ``detector.type_conf``, chosen on the ``tune`` suite), unless its
configuration names a label model, a calibration or a ``detector.type_conf`` of its own
(:func:`shipped_settings`).
A trial (``eval.trial``), a replay of a recording (``eval.ros.replay``) and the tools that
evaluate the shipped detector take them from here.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from poi.config import check_per_type
from poi.core.loader import FieldError, LoadError, build, load_yaml_file

MODELS_DIR = Path(__file__).resolve().parent
DEFAULT_MODEL = MODELS_DIR / "default.onnx"
DEFAULT_LABEL_MODEL = MODELS_DIR / "default_labels.onnx"  # names the placards DEFAULT_MODEL finds
DEFAULT_CALIBRATION = MODELS_DIR / "default_calibration.yaml"  # poibench calibrate of the two
DEFAULT_OPERATING_POINT = MODELS_DIR / "default_operating_point.yaml"  # detector.type_conf of the pair
# the photos of hazmat-photos-dev that every shipped model trained on it held back (score them only)
SHIPPED_HOLDOUT = MODELS_DIR / "photos_holdout.json"
SHIPPED = "default"  # the detector choice that names the shipped detector
OPERATING_POINT_VERSION = 1


class OperatingPointError(LoadError):
    """An operating point file that cannot be used; the message names the file and the key."""


@dataclass(kw_only=True)
class OperatingPoint:
    """A detector's own operating point: per object type, the minimum score of its boxes in
    place of ``detector.conf`` (``detector.type_conf``)."""

    poibench_operating_point: int = OPERATING_POINT_VERSION
    type_conf: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.poibench_operating_point != OPERATING_POINT_VERSION:
            raise FieldError(
                "poibench_operating_point",
                f"expected {OPERATING_POINT_VERSION}, got {self.poibench_operating_point!r}",
            )
        check_per_type("type_conf", self.type_conf, lambda c: 0.0 <= c <= 1.0, "a score in [0, 1]")


def load_operating_point(path: str | Path) -> OperatingPoint:
    """The operating point in a YAML file, validated (:class:`OperatingPointError` naming the
    file, the line and the key).

    >>> load_operating_point(DEFAULT_OPERATING_POINT).poibench_operating_point
    1
    """
    data, src = load_yaml_file(path, what="operating point", error=OperatingPointError)
    return build(OperatingPoint, data, src, error=OperatingPointError)


def shipped_settings(choice: str, cfg, *, runs_oracle: bool = False) -> list[str]:
    """The pipeline settings (``--set`` items) that give a run of detector ``choice`` the
    shipped label model, calibration and operating point: none unless ``choice`` is the shipped
    detector; ``detector.label_model`` unless ``cfg`` (a ``poi.config.PipelineConfig``) names
    one; ``calibration`` and ``detector.type_conf`` unless ``cfg`` names its own or the oracle
    runs in the shipped detector's place (``runs_oracle``: no model is shipped, or it knows none
    of the world's types), whose errors and scores are not the model's. A file that is not there
    is left out.

    >>> from poi.config import load_config
    >>> [s.split("=")[0] for s in shipped_settings("default", load_config())]
    ['detector.label_model', 'calibration', 'detector.type_conf']
    >>> [s.split("=")[0] for s in shipped_settings("default", load_config(), runs_oracle=True)]
    ['detector.label_model']
    >>> shipped_settings("oracle", load_config())
    []
    """
    if choice != SHIPPED:
        return []
    sets = []
    if cfg.detector.label_model is None and DEFAULT_LABEL_MODEL.exists():
        sets.append(f"detector.label_model={DEFAULT_LABEL_MODEL}")
    if not runs_oracle and cfg.calibration is None and DEFAULT_CALIBRATION.exists():
        sets.append(f"calibration={DEFAULT_CALIBRATION}")
    if not runs_oracle and not cfg.detector.type_conf and DEFAULT_OPERATING_POINT.exists():
        type_conf = load_operating_point(DEFAULT_OPERATING_POINT).type_conf
        if type_conf:
            sets.append(f"detector.type_conf={json.dumps(type_conf, sort_keys=True)}")
    return sets


def model_file(choice: str) -> Path | None:
    """The ONNX file a detector choice runs (None: the oracle, or a team's Python detector)."""
    if choice == SHIPPED:
        return DEFAULT_MODEL if DEFAULT_MODEL.exists() else None
    if choice.endswith(".onnx"):
        return Path(choice)
    return None


def detector_label(choice: str) -> str:
    """How results name a detector choice: the shipped one by its files
    (``onnx:default.onnx+default_labels.onnx``), ``oracle`` when none is shipped."""
    if choice == SHIPPED:
        if not DEFAULT_MODEL.exists():
            return "oracle"
        labels = f"+{DEFAULT_LABEL_MODEL.name}" if DEFAULT_LABEL_MODEL.exists() else ""
        return f"onnx:{DEFAULT_MODEL.name}{labels}"
    return choice
