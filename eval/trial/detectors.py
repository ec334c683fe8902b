"""The detectors of a run: the ``--detector`` choice checked, and built beside the world it sees.

:func:`make_detectors` builds them for a trial (:func:`eval.trial.run.run_trial`), the
perception record (:mod:`eval.trial.sources`) and a replay of a recording
(:mod:`eval.ros.replay`); the shipped detector's files are :mod:`poi.models`'.
"""

from __future__ import annotations

from pathlib import Path

from eval.trial.pipeline_config import onnx_settings_set, refuse_detector_model
from poi import models as shipped

DETECTOR_CHOICES = "default | oracle | FILE.onnx | python:MODULE:CLASS | an installed detector's name"


def check_detector_choice(choice: str) -> None:
    """Refuse a ``--detector`` that names nothing, before the trial starts: a team's Python
    detector must import and be callable, anything else but default and oracle is an ONNX file."""
    from poi.detectors import DetectorConfigError, entry_point_names, is_team_detector
    from poi.detectors.plugins import resolve_factory

    if choice in ("default", "oracle"):
        return
    if is_team_detector(choice):
        resolve_factory(choice)
    elif choice.endswith(".onnx") or Path(choice).is_dir():
        from poi.detectors.base import check_model_file

        check_model_file(choice, DetectorConfigError)
    elif not Path(choice).exists():
        installed = ", ".join(entry_point_names()) or "none installed"
        raise DetectorConfigError(
            f"unknown detector {choice!r}; expected {DETECTOR_CHOICES} (installed: {installed})"
        )


def _team_detector(choice: str, cfg, notes: list[str]):
    from poi.detectors import build_python_detector

    unused = onnx_settings_set(cfg.detector)
    det = build_python_detector(choice, cfg.detector.options)
    if unused:
        notes.append(
            f"{choice} takes its settings from detector.options only; {', '.join(unused)} "
            "(the ONNX detector's) do not reach it"
        )
    return det


def _onnx_or_oracle(choice: str, cfg, sim, notes: list[str]):
    """(detector, oracle or None): the ONNX model of ``choice``, or the oracle where the shipped
    model knows none of the world's types."""
    from poi.detectors import build_detector
    from sim.oracle import oracle_for

    model = shipped.DEFAULT_MODEL if choice == shipped.SHIPPED else Path(choice)
    spec = dict(cfg.detector_spec()) if hasattr(cfg, "detector_spec") else dict(cfg.detector)
    spec["name"] = "onnx"
    spec["model"] = str(model)
    onnx = build_detector(spec)
    notes.extend(onnx.notes)  # e.g. an execution provider this onnxruntime lacks, one line
    wanted = {o.type for o in sim.truth_objects()}
    if cfg.thermal.enabled:
        wanted.discard("heat-source")  # the thermal detector reports those
    wanted.discard("landolt-c")  # the Landolt-C finder reports those
    if cfg.fiducials.enabled:
        wanted.discard("fiducial")  # the fiducial mapper finds those in depth
    if choice == shipped.SHIPPED and wanted and not wanted & onnx.known_types:
        # the shipped model is the rescue maze's; this world holds nothing it knows
        notes.append(
            f"the default detector ({model.name}) knows none of this scenario's types "
            f"({', '.join(sorted(wanted))}): using the oracle detector"
        )
        oracle = oracle_for(sim)
        return oracle, oracle
    unknown = sorted(wanted - onnx.known_types)
    if unknown:
        notes.append(f"the detector ({model.name}) cannot report this scenario's {', '.join(unknown)}")
    return onnx, None


def make_detectors(choice: str, cfg, sim, notes: list[str]):
    """The detectors for a trial and the oracle (when used, it needs the truth of each frame).

    In a world with Landolt-C targets the oracle gives their boxes (their rings are read from
    the pixels by the pipeline); any other detector runs with the Landolt-C finder beside it.
    A config naming ``detector.model`` is refused (:func:`refuse_detector_model`)."""
    from poi.detectors import build_detector, is_team_detector
    from sim.oracle import oracle_for

    refuse_detector_model(cfg)
    if choice == shipped.SHIPPED and not shipped.DEFAULT_MODEL.exists():
        notes.append(
            "no trained default detector is shipped yet: using the oracle detector (ground-truth boxes "
            "with a noise model)"
        )
        choice = "oracle"
    if choice == "oracle":
        oracle = oracle_for(sim)  # seeded by the scenario, knowing its world's classes
        dets = [oracle]
    elif choice != shipped.SHIPPED and is_team_detector(choice):  # the built-in names come first
        oracle, dets = None, [_team_detector(choice, cfg, notes)]
    else:
        det, oracle = _onnx_or_oracle(choice, cfg, sim, notes)
        dets = [det]
    if cfg.thermal.enabled:
        dets.append(build_detector({"name": "thermal"}))
    if oracle is None and any(o.type == "landolt-c" for o in sim.truth_objects()):
        # an RMRC test with Landolt-C targets: the finder proposes and reads them from pixels
        dets.append(build_detector({"name": "landolt"}))
        notes.append(
            "the scenario has Landolt-C targets: the Landolt-C finder (poi/detectors/landolt.py) runs too"
        )
    return dets, oracle
