"""Choose a headless GL backend (MUJOCO_GL) before any test or doctest imports mujoco."""

import sim.gl  # noqa: F401
