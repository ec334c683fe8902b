"""A trial's ``config.yaml`` (written by :func:`eval.trial.run.run_trial`): its schema and loader.

``poibench run --config FILE`` reruns a trial from it. The file is read by
:mod:`poi.core.loader` (bounded, file:line errors); the scenario and the pipeline
settings are checked as a scenario file and a pipeline config are::

    poibench_trial: 1
    scenario: {...}       # a scenario (sim.scenario.Scenario)
    pipeline: {...}       # pipeline settings (poi.config.PipelineConfig), any subset
    detector: default     # default | oracle | FILE.onnx | python:MODULE:CLASS | an installed name
    rules: ex3            # or null: the scenario's own, else ex3
    max_frames: null      # or a number of frames >= 1
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from poi.config import PipelineConfig
from poi.core.loader import build, load_yaml_file, number
from sim.scenario import Scenario, ScenarioError

TRIAL_CONFIG_VERSION = 1


class TrialConfigError(ScenarioError):
    """A trial config that cannot be used; the message is one line naming the file, line and key."""


@dataclass(kw_only=True)
class TrialConfig:
    """The parsed ``config.yaml``: what :func:`eval.trial.run.run_trial` was given."""

    poibench_trial: int
    scenario: Scenario
    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    detector: str = "default"
    rules: str | None = None
    max_frames: int | None = number(None, lo=1)

    def __post_init__(self) -> None:
        if self.poibench_trial != TRIAL_CONFIG_VERSION:
            raise ValueError(
                f"not a poibench trial config (expected 'poibench_trial: {TRIAL_CONFIG_VERSION}', "
                f"got {self.poibench_trial})"
            )


def load_trial_config(path: str | Path) -> tuple[TrialConfig, dict[str, Any]]:
    """The checked config and the mapping as given (its keys say which settings the file sets)."""
    data, src = load_yaml_file(path, what="trial config", error=TrialConfigError)
    if isinstance(data, dict) and "poibench_scenario" in data:
        raise TrialConfigError(
            f"{path}: a scenario file, not a trial's config.yaml; run it with poibench run {path}"
        )
    return build(TrialConfig, data, src, error=TrialConfigError), data if isinstance(data, dict) else {}
