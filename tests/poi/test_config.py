"""poi.config: defaults, YAML loading, validation, dotted overrides."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import yaml

from poi.config import (
    DEFAULT_CONFIG_PATH,
    ConfigError,
    PipelineConfig,
    TypeShapeConfig,
    apply_overrides,
    config_from_dict,
    config_to_dict,
    flatten_config,
    load_config,
    mount_matrix,
)
from poi.core.geometry import R_BODY_OPTICAL


def test_default_yaml_equals_dataclass_defaults_and_documents_every_key():
    cfg = load_config()
    assert cfg == PipelineConfig()

    # every key of the dataclasses is written in the shipped file (it is the documentation); a
    # row of localize.types gives only its shape's numbers (the comment above them says each)
    def keys(data: dict) -> set[str]:
        rows = {f"localize.types.{t}" for t in cfg.localize.types}
        return {k.rsplit(".", 1)[0] if k.rsplit(".", 1)[0] in rows else k for k, _ in flatten_config(data)}

    written = yaml.safe_load(DEFAULT_CONFIG_PATH.read_text())
    assert keys(written) == keys(config_to_dict(cfg))
    comment = DEFAULT_CONFIG_PATH.read_text().split("  types:\n")[0].rsplit("\n\n", 1)[-1]
    assert all(f.name in comment for f in dataclasses.fields(TypeShapeConfig))


def test_brief_defaults():
    c = load_config()
    assert (c.tracker.gate, c.tracker.n_min, c.tracker.t_max) == (9.0, 3, 5.0)
    assert c.tracker.settle_sigma_m == 0.3 and c.tracker.assignment == "greedy"
    assert c.localize.inner_fraction == 0.5 and c.localize.sigma_d_px == 0.08
    assert c.localize.baseline_m == 0.05 and c.localize.depth_scale == 1.0
    # nominal mount: optical frame in the body-like tracker frame, 45 mm up
    T = mount_matrix(c)
    assert np.allclose(T[:3, :3], R_BODY_OPTICAL, atol=1e-12)
    assert np.allclose(T[:3, 3], [0.0, 0.0, 0.045])


def test_overrides_parse_yaml_scalars_and_lists():
    cfg = apply_overrides(
        load_config(),
        [
            "tracker.gate=4",
            "detector.conf=0.3",
            "tracker.assignment=hungarian",
            "qr.enabled=false",
            "mount.T_tracker_camera.translation_m=[0.1, 0, 0.2]",
            "tracker.gates.door=16",
            "detector.model=models/x.onnx",
            "calibration=null",
        ],
    )
    assert cfg.tracker.gate == 4.0 and isinstance(cfg.tracker.gate, float)
    assert cfg.detector.conf == 0.3
    assert cfg.tracker.assignment == "hungarian"
    assert cfg.qr.enabled is False
    assert cfg.mount.T_tracker_camera.translation_m == (0.1, 0.0, 0.2)
    assert cfg.tracker.gates == {"door": 16.0}
    assert cfg.detector_spec() == {
        "name": "onnx",
        "conf": 0.3,
        "nms_iou": 0.45,
        "model": "models/x.onnx",
    }


def test_overrides_do_not_modify_the_input():
    cfg = load_config()
    apply_overrides(cfg, ["tracker.gate=4"])
    assert cfg.tracker.gate == 9.0


@pytest.mark.parametrize(
    ("item", "message"),
    [
        ("tracker.gaet=4", "tracker.gaet: unknown key"),
        ("trackr.gate=4", "trackr: unknown key"),
        ("tracker.gate=abc", "tracker.gate: expected a number"),
        ("tracker.gate=0", "tracker.gate: expected a value > 0"),
        ("tracker.n_min=2.5", "tracker.n_min: expected an integer"),
        ("tracker.n_min=true", "tracker.n_min: expected an integer"),
        ("tracker.assignment=auction", "tracker.assignment: expected one of 'greedy', 'hungarian'"),
        ("tracker.gate.x=1", "tracker.gate: is a single setting"),
        ("tracker.gates.dor=3", "tracker.gates.dor: unknown type"),
        ("detector.conf=1.5", "detector.conf: expected a value >= 0 and <= 1"),
        ("localize.inner_fraction=0", "localize.inner_fraction: expected a value > 0 and <= 1"),
        ("localize.max_depth_m=0.1", "localize.max_depth_m: expected a value > min_depth_m"),
        ("mount.T_tracker_camera.quaternion_wxyz=[1, 1, 0, 0]", "expected a unit quaternion"),
        ("mount.T_tracker_camera.translation_m=[1, 2]", "expected a list of 3 numbers"),
        ("report.mode=X", "report.mode: expected one of 'T', 'A'"),
        ("tracker.gate", "expected KEY=VALUE"),
    ],
)
def test_bad_overrides_name_the_key(item, message):
    with pytest.raises(ConfigError, match=message.replace("|", r"\|").replace("[", r"\[")):
        apply_overrides(load_config(), [item])


def test_yaml_file_unknown_key_names_file_and_key(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("tracker:\n  gate: 4\n  nmin: 3\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:3: tracker\.nmin: unknown key"):
        load_config(p)
    p.write_text("tracker: [1, 2]\n")
    with pytest.raises(ConfigError, match=r"c\.yaml:1: tracker: expected a mapping"):
        load_config(p)


def test_partial_file_keeps_other_defaults_and_round_trips(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("tracker:\n  gate: 4\n")
    cfg = load_config(p)
    assert cfg.tracker.gate == 4.0 and cfg.tracker.n_min == 3
    # config_to_dict -> YAML -> load gives the same config (what config.yaml relies on)
    p.write_text(yaml.safe_dump(config_to_dict(cfg)))
    assert load_config(p) == cfg
    # and the dotted form the CLI rebuilds from config.yaml gives it too
    sets = [
        f"{k}={yaml.safe_dump(v, default_flow_style=True).strip()}" for k, v in flatten_config(config_to_dict(cfg))
    ]
    assert apply_overrides(PipelineConfig(), sets) == cfg
    assert config_from_dict(None) == PipelineConfig()
