"""A trial's whole pipeline configuration, resolved in one function (:func:`trial_pipeline_config`).

The trial's pipeline (:func:`eval.trial.run.run_trial`), the perception cache's key and the
recording behind it (:mod:`eval.trial.perception_cache`, :mod:`eval.trial.sources`),
``config.yaml`` and a consistency run (:mod:`eval.experiments.consistency`) all take their
configuration from it, so what a trial runs and what its cache is keyed by cannot drift apart.
"""

from __future__ import annotations

from poi.models import shipped_settings


def rules_settings(rules) -> list[str]:
    """What a rules preset asks of the pipeline: a preset that judges the QR mapping bonus by
    fiducials has it map them, one that scores Landolt-C rings has Landolt-C targets reported
    once those rings read."""
    sets = []
    if getattr(rules, "qr_mapping", "radius") == "fiducials":
        sets.append("fiducials.enabled=true")
    rings = getattr(rules, "landolt_rings", None)
    if rings is not None:
        sets.append(f"tracker.landolt_required_rings={list(rings)}")
    return sets


def trial_pipeline_config(
    detector: str,
    pipeline_sets=(),
    *,
    rules=None,
    sensor_sets=(),
    runs_oracle: bool = False,
):
    """The pipeline configuration (``poi.config.PipelineConfig``) of a trial of detector choice
    ``detector``, applied in this order to the defaults (``poi/configs/default.yaml``):

    1. ``sensor_sets``: what the trial tells the pipeline of its sensors, as a team knows them
       (:mod:`eval.trial.sensor_settings`; the nominal camera mount, the simulator uses the
       true one);
    2. what the ``rules`` preset asks of it (:func:`rules_settings`);
    3. the user's ``pipeline_sets`` (``--set``);
    4. the shipped detector's label model, calibration and operating point
       (:func:`poi.models.shipped_settings`; ``runs_oracle``: the oracle runs in the shipped
       detector's place).

    Where the oracle runs, the ONNX detector's settings are refused (:func:`refuse_oracle_thresholds`).

    None of 1 and 4's calibration reaches detection, so the perception cache keys a record by
    this configuration resolved without the sensors (they are read off the simulation, or the
    record, later).

    >>> cfg = trial_pipeline_config("oracle", ["tracker.gate=4"], sensor_sets=["slam.sigma_xy_m=0"])
    >>> cfg.tracker.gate, cfg.slam.sigma_xy_m, cfg.calibration
    (4.0, 0.0, None)
    """
    from poi.config import apply_overrides, load_config

    sets = list(sensor_sets) + rules_settings(rules) + list(pipeline_sets)
    cfg = apply_overrides(load_config(), sets)
    if runs_oracle:
        refuse_oracle_thresholds(cfg)
    return apply_overrides(cfg, shipped_settings(detector, cfg, runs_oracle=runs_oracle))


def onnx_settings_set(det_cfg) -> list[str]:
    """The ``detector.*`` settings other than ``options`` that differ from the default config's, dotted."""
    import dataclasses

    from poi.config import DetectorConfig, load_config

    default = load_config().detector
    return [
        f"detector.{f.name}"
        for f in dataclasses.fields(DetectorConfig)
        if f.name not in ("name", "options") and getattr(det_cfg, f.name) != getattr(default, f.name)
    ]


def refuse_oracle_thresholds(cfg) -> None:
    """Refuse the ONNX detector's settings (``detector.conf``, ``type_conf``, ``label_model``, ...:
    :func:`onnx_settings_set`) where the oracle detects: its boxes come from
    the truth with their own noise model, with no network, scores or classifier for them to
    reach, so they could never take effect."""
    from poi.detectors import DetectorConfigError

    unused = onnx_settings_set(cfg.detector) + [f"detector.options.{k}" for k in sorted(cfg.detector.options)]
    if unused:
        raise DetectorConfigError(
            f"{', '.join(unused)}: the oracle detector takes none of these (its boxes come from the truth, "
            "with no detector scores or label classifier); they take effect with an ONNX detector "
            "(--detector default or FILE.onnx)"
        )


def refuse_detector_model(cfg) -> None:
    """Refuse a config that names ``detector.model``: a trial's (or replay's) detector is the
    ``--detector`` choice, which also picks the label model, the calibration and the perception
    cache's key, so the file ``detector.model`` names could never take effect."""
    from poi.detectors import DetectorConfigError

    model = cfg.detector.model
    if model is not None:
        raise DetectorConfigError(
            f"detector.model={model}: a trial's detector is chosen with --detector FILE.onnx, not "
            "detector.model (a sweep compares detectors by one run per --detector)"
        )


def check_trial_settings(pipeline_sets, detector: str = "default") -> None:
    """Refuse, before a trial starts, pipeline ``--set`` items that cannot take effect in a
    trial of detector choice ``detector`` (``detector.model``: :func:`refuse_detector_model`;
    the ONNX detector's settings with the oracle: :func:`refuse_oracle_thresholds`)."""
    from poi.config import apply_overrides, load_config

    cfg = apply_overrides(load_config(), list(pipeline_sets))
    refuse_detector_model(cfg)
    if detector == "oracle":
        refuse_oracle_thresholds(cfg)
