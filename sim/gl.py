"""Pick a headless OpenGL backend for MuJoCo before mujoco is imported.

MuJoCo reads ``MUJOCO_GL`` once, at import. With no display (``DISPLAY`` unset)
we choose ``egl`` (Mesa's llvmpipe renders on the CPU) and fall back to
``osmesa``; a user's explicit ``MUJOCO_GL`` is always respected.
Import this module (``import sim.gl``) before ``import mujoco`` anywhere in ``sim``.

The same frame on every x86 CPU: llvmpipe compiles its shaders for the CPU it runs on, and its
AoS texture path (8-bit fixed-point filtering of RGBA8 textures, [MesaGallivm]_) does not give the
same pixels on all of them. Frame 0 of the default tour rendered on this project's AVX-512
machine and under an emulated Haswell (``qemu-x86_64 -cpu Haswell``, AVX2): 18% of the pixels
differed, up to 42 levels, on the textured walls seen at an angle; with the AoS path off
(``GALLIVM_PERF=no_aos_sampling``: llvmpipe filters those textures in float as it does every
other) the two machines' renders are the same bit for bit, and so are the delivered colour, depth,
thermal and truth images of frames 0, 37 and 250, for the same render CPU (24.3 ms a frame of
colour, depth and segmentation passes, both ways, 120 frames, 3 runs each). So for Mesa's
software renderers (``egl`` and ``osmesa`` without a GPU) :func:`portable_llvmpipe` adds
``no_aos_sampling`` to ``GALLIVM_PERF`` (a user's other flags kept), which Mesa reads once, when
the first context is made (tests/sim/test_gl.py renders under emulation and compares).

References
----------
Full entries in docs/SOURCES.md.

.. [MesaGallivm] Mesa 3D, ``src/gallium/auxiliary/gallivm/lp_bld_init.c`` (the ``GALLIVM_PERF``
   flags) and ``lp_bld_sample_aos.c`` (the AoS sampling path).
"""

from __future__ import annotations

import ctypes.util
import functools
import os
import sys

_CHOSEN: str | None = None
GALLIVM_PERF_PORTABLE = "no_aos_sampling"  # llvmpipe's AoS texture path: other pixels on other CPUs


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
    if backend in ("egl", "osmesa"):
        if not os.environ.get("PYOPENGL_PLATFORM"):
            os.environ["PYOPENGL_PLATFORM"] = backend
        os.environ["GALLIVM_PERF"] = portable_llvmpipe(os.environ.get("GALLIVM_PERF", ""))
    _CHOSEN = backend
    return backend


def portable_llvmpipe(flags: str) -> str:
    """``GALLIVM_PERF`` flags (comma-separated, as Mesa parses them) with ``no_aos_sampling`` among
    them, so llvmpipe renders the same pixels on every CPU (module docstring).

    >>> portable_llvmpipe(""), portable_llvmpipe("brilinear"), portable_llvmpipe("no_aos_sampling")
    ('no_aos_sampling', 'brilinear,no_aos_sampling', 'no_aos_sampling')
    """
    names = [f.strip() for f in flags.split(",") if f.strip()]
    if GALLIVM_PERF_PORTABLE not in names:
        names.append(GALLIVM_PERF_PORTABLE)
    return ",".join(names)


@functools.lru_cache(maxsize=1)
def renderer_identity() -> str:
    """What draws the frames, as OpenGL names it (``GL_VENDOR``, ``GL_RENDERER``, ``GL_VERSION``)
    with llvmpipe's ``GALLIVM_PERF`` flags, read once a process from a 1x1 context of the chosen
    backend: e.g. ``Mesa/X.org; llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Compatibility Profile)
    Mesa 22.3.6; GALLIVM_PERF=no_aos_sampling``. Another Mesa or LLVM draws other pixels, so the
    perception cache keys its records by it (eval.trial.perception_cache). Where no context can
    be made, the reason, so that such a machine's key differs from a rendering one's."""
    import mujoco
    from OpenGL import GL

    flags = f"GALLIVM_PERF={os.environ.get('GALLIVM_PERF', '')}"
    try:
        ctx = mujoco.GLContext(1, 1)
    except Exception as err:  # noqa: BLE001 (any backend failure: the key says so, recording will fail loudly)
        return f"no context ({type(err).__name__}); {flags}"
    try:
        ctx.make_current()
        names = [GL.glGetString(n) for n in (GL.GL_VENDOR, GL.GL_RENDERER, GL.GL_VERSION)]
        return "; ".join([*(n.decode("ascii", "replace") if n else "?" for n in names), flags])
    finally:
        ctx.free()


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
