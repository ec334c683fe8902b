"""pyright on poi/ (pyproject's [tool.pyright]): the pipeline teams port to their robots type-checks
clean, so CI fails on a new type error there.

pyright's PyPI wheel carries the checker itself and runs it on the machine's Node.js; with
``--outputjson`` it asks no server for a newer version, so the check runs offline.
"""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

pytestmark = [
    pytest.mark.slow,  # a whole-package analysis: about 20 s of CPU
    pytest.mark.skipif(
        (importlib.util.find_spec("pyright") is None or shutil.which("node") is None) and not os.environ.get("CI"),
        reason="pyright (extra 'test') or Node.js missing; CI has both and never skips this",
    ),
]


def test_pyright_is_clean_on_poi():
    result = subprocess.run(
        [sys.executable, "-m", "pyright", "--outputjson"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "PYRIGHT_PYTHON_IGNORE_WARNINGS": "1"},
    )
    try:
        report = json.loads(result.stdout)
    except json.JSONDecodeError:
        output = result.stdout[-2000:] + result.stderr[-2000:]
        pytest.fail(f"pyright gave no report (exit {result.returncode}): {output}")
    errors = [
        f"{Path(d['file']).relative_to(ROOT)}:{d['range']['start']['line'] + 1}: {d['message']} ({d.get('rule')})"
        for d in report["generalDiagnostics"]
        if d["severity"] == "error"
    ]
    # it looked at every module of poi/, not at nothing
    assert report["summary"]["filesAnalyzed"] >= len(list((ROOT / "poi").rglob("*.py"))), report["summary"]
    assert errors == [], "\n".join(errors)
