"""``poibench regress``: run a suite and compare its scores with a baseline file.

The baseline (JSON) records the suite, its version, the detector, rules and
pipeline settings, each scenario's score fraction and their mean. A run
regresses when its mean fraction falls below the baseline's by more than the
tolerance; each scenario is reported too (a scenario that fell by more than the
tolerance fails its own JUnit test case, so CI shows which one), and a trial
that errored fails. The JUnit XML has one test case per scenario plus one for
the mean.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

BASELINE_VERSION = 1


class RegressError(ValueError):
    """A baseline cannot be read or does not fit the run (one line)."""


@dataclass(kw_only=True)
class Verdict:
    passed: bool
    mean: float
    baseline_mean: float | None
    lines: list[str]


def baseline_doc(df, suite, detector: str, rules: str, settings: list[str]) -> dict:
    return {
        "poibench_baseline": BASELINE_VERSION,
        "suite": suite.name,
        "suite_version": suite.version,
        "detector": detector,
        "rules": rules,
        "settings": settings,
        "mean_fraction": round(float(df["fraction"].astype(float).mean()), 6),
        "scenarios": {r.scenario: round(float(r.fraction), 6) for r in df.itertuples()},
    }


def load_baseline(path: Path) -> dict:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RegressError(f"{path}: no such baseline; write one with --update") from None
    except json.JSONDecodeError as e:
        raise RegressError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("poibench_baseline") != BASELINE_VERSION:
        raise RegressError(f"{path}: not a poibench baseline (poibench_baseline: {BASELINE_VERSION} missing)")
    for key in ("suite", "suite_version", "mean_fraction", "scenarios"):
        if key not in doc:
            raise RegressError(f"{path}: missing field {key!r}")
    return doc


def check_baseline_run(
    baseline: dict, path: Path, detector: str, rules: str | None, settings: list[str]
) -> str | None:
    """Before a run is judged against ``baseline`` (read from ``path``): refuse other scoring
    rules (score fractions under two rule sets measure different things), and say, in one line
    for the verdict, where the run's detector or ``--set`` differ from the baseline's (the
    change a regression test is there to judge), None where they do not."""
    if "rules" in baseline and baseline["rules"] != rules:
        raise RegressError(
            f"{path}: the baseline was scored with rules {baseline['rules'] or 'each scenario its own'}, this run "
            f"with {rules or 'each scenario its own'}; give the same --rules or write a new baseline with --update"
        )
    changed = []
    if "detector" in baseline and baseline["detector"] != detector:
        changed.append(f"detector {baseline['detector']} -> {detector}")
    if "settings" in baseline and list(baseline["settings"]) != list(settings):
        changed.append(f"--set {' '.join(baseline['settings']) or '(none)'} -> {' '.join(settings) or '(none)'}")
    return f"note: against a baseline of another pipeline: {'; '.join(changed)}" if changed else None


def compare(df, baseline: dict, tolerance: float, suite) -> Verdict:
    """Verdict of a run's rows against a baseline."""
    if baseline["suite"] != suite.name or baseline["suite_version"] != suite.version:
        raise RegressError(
            f"the baseline is for suite {baseline['suite']} v{baseline['suite_version']}, "
            f"this run is {suite.name} v{suite.version}; write a new baseline with --update"
        )
    failed = df[df["error"] != ""]
    ok = df[df["error"] == ""]
    mean = float(ok["fraction"].astype(float).mean()) if len(ok) else 0.0
    base_mean = float(baseline["mean_fraction"])
    lines = []
    passed = len(failed) == 0 and mean >= base_mean - tolerance
    for r in df.itertuples():
        b = baseline["scenarios"].get(r.scenario)
        if r.error:
            lines.append(f"FAIL {r.scenario}: trial error: {r.error}")
            continue
        f = float(r.fraction)
        verdict = "ok  " if b is None or f >= b - tolerance else "DROP"
        lines.append(f"{verdict} {r.scenario}: {f:.3f}" + ("" if b is None else f" (baseline {b:.3f})"))
    lines.append(
        f"{'PASS' if passed else 'FAIL'} mean score fraction {mean:.4f}, baseline {base_mean:.4f}, "
        f"tolerance {tolerance}"
    )
    return Verdict(passed=passed, mean=mean, baseline_mean=base_mean, lines=lines)


def write_junit(path: Path, df, baseline: dict | None, tolerance: float, suite_name: str) -> None:
    """One test case per scenario and one for the mean; failures carry the numbers."""
    cases = []
    for r in df.itertuples():
        b = None if baseline is None else baseline["scenarios"].get(r.scenario)
        msg = None
        if r.error:
            msg = f"trial error: {r.error}"
        elif b is not None and float(r.fraction) < b - tolerance:
            msg = f"score fraction {float(r.fraction):.4f} < baseline {b:.4f} - {tolerance}"
        cases.append((r.scenario, float(r.wall_s), msg))
    ok = df[df["error"] == ""]
    mean = float(ok["fraction"].astype(float).mean()) if len(ok) else 0.0
    if baseline is not None:
        bm = float(baseline["mean_fraction"])
        cases.append(
            ("mean", 0.0, None if mean >= bm - tolerance else f"mean {mean:.4f} < {bm:.4f} - {tolerance}")
        )
    suite_el = ET.Element(
        "testsuite",
        name=f"poibench.{suite_name}",
        tests=str(len(cases)),
        failures=str(sum(1 for c in cases if c[2])),
        errors="0",
    )
    for name, secs, msg in cases:
        case = ET.SubElement(
            suite_el, "testcase", classname=f"poibench.{suite_name}", name=name, time=f"{secs:.2f}"
        )
        if msg:
            ET.SubElement(case, "failure", message=msg).text = msg
    root = ET.Element("testsuites")
    root.append(suite_el)
    ET.indent(root)
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
