"""Choose a headless GL backend (MUJOCO_GL) before any test or doctest imports mujoco."""

import pytest

import sim.gl  # noqa: F401


@pytest.fixture(autouse=True, scope="session")
def _private_cache_home(tmp_path_factory):
    """Commands that cache (the perception cache of sweeps) write under a temporary
    XDG_CACHE_HOME, never the user's ~/.cache; subprocesses inherit it."""
    mp = pytest.MonkeyPatch()
    mp.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
    yield
    mp.undo()
