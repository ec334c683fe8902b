"""Choose a headless GL backend (MUJOCO_GL) before any test or doctest imports mujoco; keep the
test tiers honest.

The tiers (docs/guides/testing.md): a test marked ``slow`` builds a simulation, renders, or runs
the CLI in a subprocess; ``browser`` drives the live view in Chromium; ``ros`` reads or writes
ROS logs; ``train`` needs the train extra (torch, Ultralytics). ``python -m pytest -m "not slow
and not browser and not ros"`` is the fast tier.

Markers are written by hand (a module-level ``pytestmark`` where a whole file is slow), but a
hand-written marker goes stale as tests are added, so every unmarked test runs under a guard:
building a ``Simulation``, a renderer (``sim.render.SceneRenderer``, ``mujoco.Renderer``), a
process pool, a Playwright browser or a ``poibench`` subprocess fails it, and so does
``pytest.importorskip`` of torch or Ultralytics (a test that would be skipped everywhere but in
the train extra's environment, which runs only ``-m train``), naming the marker it lacks. A name
rule (say, "a test using the fixture ``sim``") would miss the many tests that build their
simulation inline or through the CLI; the guard sees what a test does, whichever way it does it.
Every ``tests/eval/ros/`` test is marked ``ros`` by its folder (they all need the ``ros``
extra's rosbags).
"""

import sim.gl  # noqa: F401  # first: it sets MUJOCO_GL, which mujoco reads when imported

# isort: split
import subprocess
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import mujoco
import numpy as np
import pytest

import sim.render
import sim.simulator

ROS_TESTS = Path(__file__).parent / "tests" / "eval" / "ros"
# what the train extra brings; .ci/run runs the tests marked train in an environment that has it
TRAIN_MODULES = ("torch", "ultralytics")

# (class, what building one means, the marker it needs)
_GUARDED = (
    (sim.simulator.Simulation, "builds a Simulation", "slow"),
    (sim.render.SceneRenderer, "renders (sim.render.SceneRenderer)", "slow"),
    (mujoco.Renderer, "renders (mujoco.Renderer)", "slow"),
    # a sweep's trials run in spawned workers, which no guard here reaches
    (ProcessPoolExecutor, "starts a process pool (sweep workers)", "slow"),
)


class UnmarkedTestError(RuntimeError):
    """A test does what its tier's marker says, without the marker."""


def _refusal(nodeid: str, what: str, marker: str) -> UnmarkedTestError:
    return UnmarkedTestError(
        f"{nodeid} {what} but is not marked {marker}: add @pytest.mark.{marker} "
        f"(or pytestmark = pytest.mark.{marker} for a whole file); see docs/guides/testing.md"
    )


def _is_cli(args) -> bool:
    """Whether a subprocess's argv runs the poibench CLI (``poibench ...``, ``python -m eval.cli.main``)."""
    argv = [args] if isinstance(args, (str, bytes, Path)) else list(args)
    words = [str(a) for a in argv]
    return any(Path(w).name == "poibench" or w.startswith("eval.cli") for w in words)


def _guards(mp: pytest.MonkeyPatch, item: pytest.Item) -> None:
    nodeid = item.nodeid
    if item.get_closest_marker("slow") is None:
        for cls, what, marker in _GUARDED:

            def refuse(self, *args, _what=what, _marker=marker, **kwargs):
                raise _refusal(nodeid, _what, _marker)

            mp.setattr(cls, "__init__", refuse)
        popen_init = subprocess.Popen.__init__

        def guarded_popen(self, args, *rest, **kwargs):
            if _is_cli(args):
                raise _refusal(nodeid, "runs the poibench CLI in a subprocess", "slow")
            popen_init(self, args, *rest, **kwargs)

        mp.setattr(subprocess.Popen, "__init__", guarded_popen)
    if item.get_closest_marker("train") is None:
        importorskip = pytest.importorskip

        def guarded_importorskip(modname, *args, **kwargs):
            if modname.split(".")[0] in TRAIN_MODULES:
                raise _refusal(nodeid, f"needs {modname} (the train extra)", "train")
            return importorskip(modname, *args, **kwargs)

        mp.setattr(pytest, "importorskip", guarded_importorskip)
    if item.get_closest_marker("browser") is None:
        try:
            import playwright.sync_api as sync_api
        except ImportError:
            return

        def no_browser(*args, **kwargs):
            raise _refusal(nodeid, "starts a browser (Playwright)", "browser")

        mp.setattr(sync_api, "sync_playwright", no_browser)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if ROS_TESTS in Path(str(item.path)).parents:
            item.add_marker(pytest.mark.ros)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Run an item (its fixtures' setup, the test, the teardown) under the tier guards, and give
    the next one numpy's print options as they were: Ultralytics sets its own when imported (the
    ``train`` extra's tests import it), which would change how later doctests print arrays."""
    mp = pytest.MonkeyPatch()
    _guards(mp, item)
    printoptions = np.get_printoptions()
    try:
        yield
    finally:
        mp.undo()
        np.set_printoptions(**printoptions)


@pytest.fixture(autouse=True, scope="session")
def _private_cache_home(tmp_path_factory):
    """Commands that cache (the perception cache of sweeps) write under a temporary
    XDG_CACHE_HOME, never the user's ~/.cache; subprocesses inherit it."""
    mp = pytest.MonkeyPatch()
    mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
    yield
    mp.undo()
