"""The shipped detector, its placard label classifier and its calibration, and the one rule
that goes with them: the shipped detector brings the shipped label model and calibration.

A run whose detector choice is ``default`` runs ``default.onnx`` with ``default_labels.onnx``
(which names the placards it finds) and ``default_calibration.yaml`` (``poibench calibrate``
of the two: the shipped model's own error model, [Avevor2022]_ 2.1.4-2.1.5), unless its
configuration names a label model or a calibration of its own (:func:`shipped_settings`).
A trial (``eval.trial``), a replay of a recording (``eval.ros.replay``) and the tools that
evaluate the shipped detector take them from here.

References
----------
Full entries in docs/SOURCES.md.

.. [Avevor2022] E. Avevor, "Proposed solution to RoboCupRescue EX3", University of Cambridge,
   2022.
"""

from __future__ import annotations

from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent
DEFAULT_MODEL = MODELS_DIR / "default.onnx"
DEFAULT_LABEL_MODEL = MODELS_DIR / "default_labels.onnx"  # names the placards DEFAULT_MODEL finds
DEFAULT_CALIBRATION = MODELS_DIR / "default_calibration.yaml"  # poibench calibrate of the two
SHIPPED = "default"  # the detector choice that names the shipped detector


def shipped_settings(choice: str, cfg, *, runs_oracle: bool = False) -> list[str]:
    """The pipeline settings (``--set`` items) that give a run of detector ``choice`` the
    shipped label model and calibration: none unless ``choice`` is the shipped detector;
    ``detector.label_model`` unless ``cfg`` (a ``poi.config.PipelineConfig``) names one;
    ``calibration`` unless ``cfg`` names one or the oracle runs in the shipped detector's place
    (``runs_oracle``: no model is shipped, or it knows none of the world's types), whose errors
    are not the model's. A file that is not there is left out.

    >>> from poi.config import load_config
    >>> [s.split("=")[0] for s in shipped_settings("default", load_config())]
    ['detector.label_model', 'calibration']
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
