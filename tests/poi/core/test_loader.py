"""The one YAML loader (poi.core.loader): every bad input is one project error naming file and line.

Hand-written cases for each hostile input (bad bytes, deep nesting, alias bombs, size,
huge integers, NaN/inf, duplicate keys), for the typed conversion, and for each of the
five loaders (scenario, pipeline config, rules, suite, calibration) refusing an unknown
key with file:line. The hypothesis fuzzing of the same entry points is in
test_loader_fuzz.py.
"""

from __future__ import annotations

import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest
import yaml

import poi.core.loader as loader_module
from eval.experiments.suites import SuiteError, load_suite
from eval.scoring.rules import RulesError, load_rules
from eval.trial.trial_config import TrialConfigError, load_trial_config
from poi.config import ConfigError, apply_overrides, load_config
from poi.core.loader import (
    MAX_BYTES,
    MAX_DEPTH,
    FieldError,
    LoadError,
    build,
    load_yaml,
    load_yaml_file,
    number,
    read_text,
    safe_load,
)
from poi.estimation.covariance import CalibrationError, load_calibration
from sim.scenario import ScenarioError, apply_settings, load_scenario, parse_scenario

REPO = Path(__file__).resolve().parents[3]

# 342 bytes that PyYAML expands to 9**8 = 43 million strings ("billion laughs")
ALIAS_BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{n}: &{n} [{', '.join([f'*{p}'] * 9)}]\n" for p, n in zip("abcdefgh", "bcdefghi", strict=True)
)


def _write(tmp_path: Path, text: str | bytes, name: str = "f.yaml") -> Path:
    p = tmp_path / name
    if isinstance(text, bytes):
        p.write_bytes(text)
    else:
        p.write_text(text, encoding="utf-8")
    return p


def _one_line_at(message: str, path: Path | str, line: int) -> None:
    assert "\n" not in message, message
    assert re.match(rf"{re.escape(str(path))}:{line}\b", message), message


# ---------------------------------------------------------------------------------------------
# Hostile input, through the reader


def test_non_utf8_bytes_name_file_line_and_column(tmp_path):
    p = _write(tmp_path, b"seed: 1\nname: caf\xe9\n")
    with pytest.raises(LoadError) as e:
        read_text(p)
    _one_line_at(str(e.value), p, 2)
    assert "2:10: not UTF-8 text: byte 0xe9" in str(e.value)


def test_text_with_a_byte_of_no_utf8_is_refused():
    """Command-line text holds such bytes as lone surrogates (os.fsdecode); libyaml cannot encode them."""
    with pytest.raises(ConfigError, match=r"--set tracker\.gate:1: not UTF-8 text: byte 0xe9"):
        apply_overrides(load_config(), ["tracker.gate=4" + os.fsdecode(b"\xe9")])


def test_a_utf8_byte_order_mark_is_dropped(tmp_path):
    p = _write(tmp_path, b"\xef\xbb\xbfseed: 1\n")
    assert load_yaml_file(p)[0] == {"seed": 1}


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("[" * 1000 + "]" * 1000, 1),  # flow nesting: the scanner stops at the limit
        ("a: " + "{b: " * 1000 + "}" * 1000, 1),
        ("- " * 1000 + "x\n", 1),  # block sequences on one line
        ("".join(" " * i + "k:\n" for i in range(200)), MAX_DEPTH),  # block mappings by indentation
    ],
)
def test_deep_nesting_is_refused_without_recursing(text, line):
    t0 = time.perf_counter()
    with pytest.raises(LoadError, match=f"nested more than {MAX_DEPTH} levels deep") as e:
        safe_load(text, "deep.yaml")
    assert time.perf_counter() - t0 < 2.0
    _one_line_at(str(e.value), "deep.yaml", line)


def test_nesting_up_to_the_limit_loads():
    depth = MAX_DEPTH - 1
    assert safe_load("[" * depth + "1" + "]" * depth) is not None


def test_alias_bomb_is_refused_at_once_by_the_scenario_loader(tmp_path):
    p = _write(tmp_path, ALIAS_BOMB, "bomb.yaml")
    assert len(ALIAS_BOMB.encode()) < 400
    t0 = time.perf_counter()
    with pytest.raises(ScenarioError, match="anchors .* are not allowed") as e:
        load_scenario(p)
    assert time.perf_counter() - t0 < 0.5  # it hung `poibench run` before
    _one_line_at(str(e.value), p, 1)


def test_an_alias_alone_is_refused_too():
    with pytest.raises(LoadError, match=r"x\.yaml:2:4: not valid YAML: aliases"):
        safe_load("a: 1\nb: *a\n", "x.yaml")


def test_shipped_yaml_files_use_no_anchors_and_all_load():
    files = [p for p in REPO.glob("**/*.yaml") if not {".git", "build", ".venv"} & set(p.parts)]
    assert len(files) >= 10
    for p in files:
        load_yaml_file(p)  # raises on an anchor, an alias, a duplicate key, ...


def test_a_file_over_the_size_limit_is_refused_unread(tmp_path):
    p = _write(tmp_path, b"#" * (MAX_BYTES + 1))
    with pytest.raises(LoadError, match=rf"{re.escape(str(p))}: {MAX_BYTES + 1} bytes, over the 256 KiB limit"):
        read_text(p)
    with pytest.raises(ConfigError, match="over the 256 KiB limit"):
        load_config(p)


def test_duplicate_keys_are_refused_naming_both_lines():
    with pytest.raises(LoadError) as e:
        safe_load("tracker:\n  gate: 4\n  n_min: 2\n  gate: 5\n", "c.yaml")
    assert str(e.value) == "c.yaml:4: tracker.gate: duplicate key (first given on line 2)"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("a: 0x" + "f" * 5000 + "\n", "a: cannot read '0xffff"),  # would not even print
        ("a: " + "9" * 5000 + "\n", "more than 4300 digits"),
        ("a: 2001-13-45\n", "a: cannot read '2001-13-45'"),
        ("a: !!python/object:os.system x\n", "a: cannot read"),
        ("a: !!set {x}\n", "a: tag 'tag:yaml.org,2002:set' is not supported"),
        ("<<: {a: 1}\n", "merge keys (<<) are not supported"),
        ("? [a]\n: 1\n", "expected a plain key"),
        ("a: 1\n---\nb: 2\n", "x.yaml:2:1: not valid YAML"),
        ("a: \x00\n", "characters are not allowed #x0000"),
    ],
)
def test_scalars_tags_and_keys_yaml_cannot_give_as_data_are_refused(text, message):
    with pytest.raises(LoadError, match=re.escape(message)) as e:
        safe_load(text, "x.yaml")
    assert "\n" not in str(e.value) and str(e.value).startswith("x.yaml:")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[" * 1000 + "]" * 1000, "x.yaml:1:65: not valid YAML: nested more than 64 levels deep"),
        (ALIAS_BOMB, "x.yaml:1:4: not valid YAML: anchors (&name) are not allowed"),
        ("a: 1\nb: *a\n", "x.yaml:2:4: not valid YAML: aliases (*name) are not allowed"),
        ("a: 1\n---\nb: 2\n", "x.yaml:2:1: not valid YAML: but found another document"),
        ("a: [1\n", "x.yaml:2:1: not valid YAML: expected ',' or ']', but got '<stream end>'"),
    ],
)
def test_the_pure_python_parser_is_bounded_the_same_way(monkeypatch, text, message):
    """Without libyaml, PyYAML's own parser is used (with the depth limit in its scanner)."""
    monkeypatch.setattr(loader_module, "_PARSER", loader_module._BoundedLoader)
    t0 = time.perf_counter()
    with pytest.raises(LoadError) as e:
        safe_load(text, "x.yaml")
    assert time.perf_counter() - t0 < 2.0
    assert str(e.value) == message
    assert safe_load("a: {b: [1, 2.5, x, null, true]}\n") == {"a": {"b": [1, 2.5, "x", None, True]}}


def test_a_file_at_the_size_cap_loads_in_bounded_time():
    text = "[" + "1, " * (MAX_BYTES // 3 - 1) + "1]"
    t0 = time.process_time()
    assert len(safe_load(text)) == MAX_BYTES // 3
    # A bound on a hang, not a speed figure (bench/bench_fuzz_loaders.py measures): under 1.5 s with libyaml.
    assert time.process_time() - t0 < 15.0


# ---------------------------------------------------------------------------------------------
# Typed conversion


@dataclass(kw_only=True)
class Inner:
    size: tuple[int, int] = (1, 1)
    ratio: float = number(0.5, lo=0.0, hi=1.0, lo_open=True)


@dataclass(kw_only=True)
class Outer:
    name: str
    mode: Literal["a", "b"] = "a"
    inner: Inner = field(default_factory=Inner)
    extra: Inner | None = None
    tags: list[str] = field(default_factory=list)
    weights: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if "bad" in self.weights:
            raise FieldError("weights.bad", "expected a known name")


def _build(text: str) -> Outer:
    return build(Outer, *load_yaml(text, "o.yaml"))


def test_build_converts_nested_dataclasses_lists_tuples_and_optionals():
    o = _build("name: x\nmode: b\ninner: {size: [2, 3], ratio: 1}\nextra: {}\ntags: [p, q]\nweights: {w: 2}\n")
    assert o == Outer(
        name="x", mode="b", inner=Inner(size=(2, 3), ratio=1.0), extra=Inner(), tags=["p", "q"], weights={"w": 2.0}
    )
    assert isinstance(o.inner.ratio, float) and _build("name: x\nextra: null\n").extra is None


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "name: x\nnmae: y\n",
            "o.yaml:2: nmae: unknown key; expected one of name, mode, inner, extra, tags, weights",
        ),
        ("mode: a\n", "o.yaml: (top): missing key 'name' (a string)"),
        ("name: 3\n", "o.yaml:1: name: expected a string, got 3"),
        ("name: x\nmode: c\n", "o.yaml:2: mode: expected one of 'a', 'b', got 'c'"),
        (
            "name: x\ninner:\n  size: [1, 2, 3]\n",
            "o.yaml:3: inner.size: expected a list of 2 numbers, got [1, 2, 3]",
        ),
        ("name: x\ninner:\n  size: [1, 2.5]\n", "o.yaml:3: inner.size[1]: expected an integer, got 2.5"),
        ("name: x\ninner: {ratio: 0}\n", "o.yaml:2: inner.ratio: expected a value > 0 and <= 1, got 0"),
        ("name: x\ninner: {ratio: .nan}\n", "o.yaml:2: inner.ratio: expected a finite number, got nan"),
        ("name: x\ninner: {ratio: -.inf}\n", "o.yaml:2: inner.ratio: expected a finite number, got -inf"),
        (
            "name: x\ninner: {ratio: " + "9" * 400 + "}\n",
            "inner.ratio: expected a finite number, got an integer of",
        ),
        ("name: x\ninner: {ratio: true}\n", "o.yaml:2: inner.ratio: expected a number, got True"),
        ("name: x\nextra: [1]\n", "o.yaml:2: extra: expected a mapping, got [1]"),
        ("name: x\ntags:\n  - a\n  - {b: 1}\n", "o.yaml:4: tags[1]: expected a string, got {'b': 1}"),
        ("name: x\nweights:\n  1: 2\n", "o.yaml:3: weights.1: expected a string key, got 1"),
        ("name: x\nweights:\n  a: 1\n  bad: 2\n", "o.yaml:4: weights.bad: expected a known name"),
        ("[1, 2]\n", "o.yaml: (top): expected a mapping, got [1, 2]"),
        (
            "name: " + "x" * 10000 + "\nmode: " + "y" * 10000 + "\n",
            "o.yaml:2: mode: expected one of 'a', 'b', got",
        ),
    ],
)
def test_build_refuses_with_file_line_field_and_what_was_expected(text, message):
    with pytest.raises(LoadError) as e:
        _build(text)
    assert message in str(e.value)
    assert "\n" not in str(e.value) and len(str(e.value)) < 300


def test_build_raises_the_callers_error_class():
    with pytest.raises(ConfigError, match="o.yaml:1: nmae: unknown key"):
        build(Outer, *load_yaml("nmae: 1\n", "o.yaml"), error=ConfigError)


# ---------------------------------------------------------------------------------------------
# The five loaders: unknown keys, and what they used to let through


def test_each_loader_refuses_an_unknown_key_with_file_and_line(tmp_path):
    cases = [
        (
            load_scenario,
            ScenarioError,
            "seed: 1\nsensors:\n  fps: 10\n  fpss: 5\n",
            4,
            "sensors.fpss: unknown key",
        ),
        (load_config, ConfigError, "tracker:\n  gate: 4\n  nmin: 3\n", 3, "tracker.nmin: unknown key"),
        (
            load_rules,
            RulesError,
            (REPO / "eval/scoring/rules/ex3.yaml").read_text() + "bonus: 3\n",
            None,
            "field 'bonus' is unknown",
        ),
        (
            load_suite,
            SuiteError,
            "poibench_suite: 1\nname: s\nversion: 1\nscenarios:\n  - {name: a, seed: 1, scenario: b, x: 1}\n",
            5,
            "scenarios[0].x: unknown key",
        ),
        (load_calibration, CalibrationError, "poibench_calibration: 1\n\nextra: 1\n", 3, "extra: unknown key"),
    ]
    for loader, error, text, line, message in cases:
        p = _write(tmp_path, text, f"{loader.__name__}.yaml")
        if line is None:  # the rules file: the line of the appended key
            line = text.count("\n")
        with pytest.raises(error) as e:
            loader(p)
        _one_line_at(str(e.value), p, line)
        assert message in str(e.value), str(e.value)


@pytest.mark.parametrize(
    ("loader", "error"),
    [
        (load_scenario, ScenarioError),
        (load_config, ConfigError),
        (load_rules, RulesError),
        (load_suite, SuiteError),
        (load_calibration, CalibrationError),
        (load_trial_config, TrialConfigError),
    ],
)
@pytest.mark.parametrize(
    "content",
    [b"a: 1\nb: \xff\n", ("[" * 1000 + "]" * 1000).encode(), ALIAS_BOMB.encode(), b"a: 1\na: 2\n"],
    ids=["bad-bytes", "deep", "alias-bomb", "duplicate"],
)
def test_each_loader_refuses_hostile_files_with_its_own_error(tmp_path, loader, error, content):
    p = _write(tmp_path, content, "hostile.yaml")
    t0 = time.perf_counter()
    with pytest.raises(error) as e:
        loader(p)
    assert time.perf_counter() - t0 < 2.0
    assert isinstance(e.value, LoadError)
    assert re.match(rf"{re.escape(str(p))}:\d+", str(e.value)), str(e.value)


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ("sensors.d435.width=0", "sensors.d435.width: expected a value >= 1 and <= 4096, got 0"),
        ("sensors.d435.height=100000", "sensors.d435.height: expected a value >= 1 and <= 4096, got 100000"),
        ("sensors.d435.fx=0", "sensors.d435.fx: expected a value > 0, got 0"),
        ("sensors.d435.fy=-3", "sensors.d435.fy: expected a value > 0, got -3"),
        ("seed=-5", "seed: expected a value >= 0, got -5"),
        ("maze={generate: {rows: 100000, cols: 100000}}", "maze.generate.rows: expected a value >= 1 and <= 64"),
        ("sensors.t265.drift_fraction=.inf", "sensors.t265.drift_fraction: expected a finite number, got inf"),
        ("sensors.thermal.width=0", "sensors.thermal.width: expected a value >= 1 and <= 4096, got 0"),
    ],
)
def test_scenario_sizes_that_cannot_run_are_refused_in_files_and_settings(tmp_path, setting, message):
    with pytest.raises(ScenarioError, match=re.escape(f"--set: {message}")):
        apply_settings(load_scenario("default"), [setting])
    key, value = setting.split("=", 1)
    parts = key.split(".")
    text = "".join(f"{'  ' * i}{part}:\n" for i, part in enumerate(parts[:-1]))
    text += f"{'  ' * (len(parts) - 1)}{parts[-1]}: {value}\n"
    with pytest.raises(ScenarioError) as e:
        parse_scenario(text, "s.yaml")
    assert message in str(e.value) and str(e.value).startswith(f"s.yaml:{len(parts)}: ")


def test_a_float_field_takes_exponent_notation_without_a_point():
    """YAML 1.1 (PyYAML) reads 1e6 and 2E-3 as strings; a float field takes them as numbers, an
    integer field does not, and a string that only looks like one stays an error."""
    assert _build("name: x\ninner: {ratio: 5e-1}\n").inner.ratio == 0.5
    assert _build("name: x\nweights: {w: 2E+3, v: -1e0}\n").weights == {"w": 2000.0, "v": -1.0}
    cfg = apply_overrides(load_config(), ["tracker.gate=1e1"])
    assert cfg.tracker.gate == 10.0
    with pytest.raises(LoadError, match="inner.size\\[0\\]: expected an integer, got '1e3'"):
        _build("name: x\ninner: {size: [1e3, 1]}\n")
    with pytest.raises(LoadError, match="inner.ratio: expected a number, got '1e'"):
        _build("name: x\ninner: {ratio: 1e}\n")
    with pytest.raises(ConfigError, match="tracker.gate: expected a finite number, got inf"):
        apply_overrides(load_config(), ["tracker.gate=1e999"])


def test_pipeline_overrides_refuse_non_finite_and_huge_numbers():
    cfg = load_config()
    for value in (".nan", ".inf", "9" * 400):
        with pytest.raises(ConfigError, match="--set: tracker.gate: expected a finite number"):
            apply_overrides(cfg, [f"tracker.gate={value}"])
    with pytest.raises(ConfigError, match="--set tracker.gate:1:1: not valid YAML: anchors"):
        apply_overrides(cfg, ["tracker.gate=&a 3"])
    # an earlier item that replaced a mapping (found by bench/bench_fuzz_loaders.py)
    with pytest.raises(ConfigError, match="localize.types: expected a mapping to set 'door' in, got"):
        apply_overrides(cfg, ["localize.types=[1]", "localize.types.door.extent_sigma_m=0.3"])


def test_rules_and_calibration_refuse_integers_beyond_float_range(tmp_path):
    ex3 = (REPO / "eval/scoring/rules/ex3.yaml").read_text()
    big = "9" * 400
    p = _write(tmp_path, re.sub(r"points: \d+", f"points: {big}", ex3, count=1), "r.yaml")
    with pytest.raises(RulesError, match=r"r\.yaml:\d+: field 'types\.\w+\.points': expected a finite number"):
        load_rules(p)
    cal = f"poibench_calibration: 1\ncenter_variance_px2:\n  door: {{u: [{big}], v: [1]}}\n"
    with pytest.raises(CalibrationError, match=r"c\.yaml:3: center_variance_px2\.door\.u: expected a non-empty"):
        load_calibration(_write(tmp_path, cal, "c.yaml"))
    matrix = f"poibench_calibration: 1\nconfusion: {{matrix: [[{big}]]}}\n"
    with pytest.raises(CalibrationError, match=r"m\.yaml:2: confusion\.matrix: expected a square matrix"):
        load_calibration(_write(tmp_path, matrix, "m.yaml"))


@pytest.mark.parametrize(
    ("generate", "message"),
    [
        ("{cols: l}", "scenarios[0].generate.cols: expected an integer, got 'l'"),
        ("{cols: {}}", "scenarios[0].generate.cols: expected an integer, got {}"),
        ("{rows: -1}", "scenarios[0].generate.rows: expected a value >= 1 and <= 64, got -1"),
        ("{rows: 3, preset: rcll}", "scenarios[0].generate.preset: expected one of 'rrl', 'rmrc', got 'rcll'"),
        ("{rows: 3, loops: 2}", "scenarios[0].generate.loops: unknown key"),
    ],
)
def test_suite_generate_values_are_checked_at_load(tmp_path, generate, message):
    text = f"poibench_suite: 1\nname: s\nversion: 1\nscenarios:\n  - {{name: a, seed: 1, generate: {generate}}}\n"
    p = _write(tmp_path, text, "suite.yaml")
    with pytest.raises(SuiteError) as e:
        load_suite(p)
    _one_line_at(str(e.value), p, 5)
    assert message in str(e.value)


def test_trial_config_is_read_by_the_loader_with_lines(tmp_path):
    sc = load_scenario("default")
    doc = {"poibench_trial": 1, "scenario": sc.to_dict(), "pipeline": {"tracker": {"gate": 4}}, "max_frames": 5}
    p = _write(tmp_path, yaml.safe_dump(doc, sort_keys=False), "config.yaml")
    cfg, given = load_trial_config(p)
    assert cfg.scenario == sc and cfg.pipeline.tracker.gate == 4.0 and cfg.max_frames == 5
    assert given["pipeline"] == {"tracker": {"gate": 4}}
    text = re.sub(r"\bfx: 612\.4", "fx: 0", p.read_text())
    bad = _write(tmp_path, text, "bad.yaml")
    with pytest.raises(TrialConfigError) as e:
        load_trial_config(bad)
    line = next(i for i, t in enumerate(text.splitlines(), 1) if t.strip() == "fx: 0")
    assert str(e.value).startswith(f"{bad}:{line}: scenario.sensors.d435.fx: expected a value > 0")


def test_no_module_reads_yaml_but_the_loader():
    """One YAML reader: every other module goes through poi.core.loader (yaml.safe_dump is fine)."""
    reader = re.compile(r"yaml\.(safe_load|load|full_load|unsafe_load|compose|parse|scan)\w*\(")
    offenders = [
        str(p.relative_to(REPO))
        for top in ("poi", "sim", "eval", "maze_assets")
        for p in (REPO / top).rglob("*.py")
        if p != REPO / "poi/core/loader.py" and reader.search(p.read_text(encoding="utf-8"))
    ]
    assert offenders == []
