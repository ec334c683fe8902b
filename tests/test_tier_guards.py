"""The project's conftest refuses a test that does its tier's work without the tier's marker.

The conftest is run as it is on a few small tests in a separate pytest process (``pytester``),
so that this test's own guards (it is unmarked) do not stand in front of theirs.
"""

from pathlib import Path

import pytest

pytest_plugins = ("pytester",)

ROOT_CONFTEST = Path(__file__).resolve().parents[1] / "conftest.py"

INNER_TESTS = """
import subprocess

import pytest

import sim.simulator


def test_importorskip_torch_unmarked():
    pytest.importorskip("torch")


@pytest.mark.train
def test_importorskip_torch_marked():
    pytest.importorskip("torch")


def test_importorskip_other_module_unmarked():
    pytest.importorskip("numpy")


def test_simulation_unmarked():
    sim.simulator.Simulation(None)


@pytest.mark.slow
def test_simulation_marked():
    # past the guard: the real constructor, which fails on the missing scenario
    with pytest.raises(Exception) as err:
        sim.simulator.Simulation(None)
    assert type(err.value).__name__ != "UnmarkedTestError"


def test_cli_subprocess_unmarked():
    subprocess.Popen(["poibench", "--help"])


def test_browser_unmarked():
    sync_api = pytest.importorskip("playwright.sync_api")
    sync_api.sync_playwright()
"""


@pytest.fixture
def inner(pytester: pytest.Pytester) -> pytest.RunResult:
    pytester.makeconftest(ROOT_CONFTEST.read_text(encoding="utf-8"))
    pytester.makepyfile(test_inner=INNER_TESTS)
    return pytester.runpytest_subprocess("-p", "no:cacheprovider", "-v")


def _outcome(result: pytest.RunResult, name: str) -> str:
    """PASSED, FAILED, SKIPPED ... of the inner test ``name``, from its ``-v`` line."""
    words = [ln.split()[1] for ln in result.outlines if ln.startswith(f"test_inner.py::{name} ")]
    assert len(words) == 1, result.stdout.str()
    return words[0]


def test_the_guards_refuse_unmarked_tier_work_and_let_marked_tests_through(inner: pytest.RunResult):
    out = inner.stdout.str()
    assert _outcome(inner, "test_importorskip_torch_unmarked") == "FAILED"
    assert "test_importorskip_torch_unmarked needs torch (the train extra) but is not marked train" in out
    # marked train: skipped where torch is missing (this environment), passed in the train extra's
    assert _outcome(inner, "test_importorskip_torch_marked") in ("SKIPPED", "PASSED")
    assert _outcome(inner, "test_importorskip_other_module_unmarked") == "PASSED"
    assert _outcome(inner, "test_simulation_unmarked") == "FAILED"
    assert "test_simulation_unmarked builds a Simulation but is not marked slow" in out
    assert _outcome(inner, "test_simulation_marked") == "PASSED"
    assert _outcome(inner, "test_cli_subprocess_unmarked") == "FAILED"
    assert "test_cli_subprocess_unmarked runs the poibench CLI in a subprocess but is not marked slow" in out
    if _outcome(inner, "test_browser_unmarked") != "SKIPPED":  # skipped without the gui extra's Playwright
        assert "test_browser_unmarked starts a browser (Playwright) but is not marked browser" in out
