"""Pick a headless OpenGL backend for MuJoCo before mujoco is imported.

MuJoCo reads ``MUJOCO_GL`` once, at import. With no display (``DISPLAY`` unset)
we choose ``egl`` (Mesa's llvmpipe renders on the CPU) and fall back to
``osmesa``; a user's explicit ``MUJOCO_GL`` is always respected.
Import this module (``import sim.gl``) before ``import mujoco`` anywhere in ``sim``.
"""

from __future__ import annotations

import ctypes.util
import os
import sys

_CHOSEN: str | None = None


class RenderingUnavailableError(RuntimeError):
    """No usable OpenGL backend for headless rendering (sim.render.SceneRenderer could not make
    its context); the message is one line that says what to install."""


def _lib_available(name: str) -> bool:
    return ctypes.util.find_library(name) is not None


def choose_backend() -> str:
    """Set ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``) if unset and return the backend name."""
    global _CHOSEN
    if _CHOSEN is not None:
        return _CHOSEN
    backend = os.environ.get("MUJOCO_GL")
    if not backend:
        if os.environ.get("DISPLAY") and sys.platform.startswith("linux"):
            backend = "glfw"
        elif _lib_available("EGL"):
            backend = "egl"
        elif _lib_available("OSMesa"):
            backend = "osmesa"
        else:
            backend = "egl"  # let MuJoCo fail; sim.render turns that into RenderingUnavailableError
        os.environ["MUJOCO_GL"] = backend
    if backend in ("egl", "osmesa") and not os.environ.get("PYOPENGL_PLATFORM"):
        os.environ["PYOPENGL_PLATFORM"] = backend
    _CHOSEN = backend
    return backend


def missing_backend_message(err: BaseException) -> str:
    r"""One-line explanation of what to install when no backend works.

    >>> msg = missing_backend_message(ImportError("libEGL.so.1: cannot open shared object file\nmore"))
    >>> "(ImportError: libEGL.so.1: cannot open shared object file); install Mesa's EGL" in msg, "\n" in msg
    (True, False)
    """
    first = (str(err).splitlines() or [""])[0]
    return (
        f"headless rendering failed with MUJOCO_GL={os.environ.get('MUJOCO_GL')!r} "
        f"({type(err).__name__}: {first}); "
        "install Mesa's EGL (apt-get install libegl1 libgl1-mesa-dri) or OSMesa "
        "(apt-get install libosmesa6) and set MUJOCO_GL=egl or MUJOCO_GL=osmesa"
    )


choose_backend()
