"""Choosing MuJoCo's OpenGL backend before ``mujoco`` is imported.

MuJoCo reads ``MUJOCO_GL`` once, when it is first imported, so the choice is made here, in a
module that imports nothing heavy: ``auto`` keeps a backend the user already set, uses the
window system when there is a display, and otherwise EGL (Mesa's surfaceless platform on a
CPU-only machine, the GPU's EGL on a GPU machine) if ``libEGL`` is installed, else OSMesa.
"""

from __future__ import annotations

import ctypes.util
import logging
import os
import sys

from factory.errors import RenderError

log = logging.getLogger(__name__)

BACKENDS = ("auto", "egl", "osmesa", "glfw")


def configure_gl(backend: str = "auto") -> str:
    """Sets ``MUJOCO_GL`` (and ``PYOPENGL_PLATFORM``/``EGL_PLATFORM``) for offscreen rendering.

    Args:
        backend: ``auto``, ``egl``, ``osmesa`` or ``glfw``.

    Returns:
        the backend in effect.

    Raises:
        RenderError: unknown backend, or a different backend was requested after ``mujoco`` was
            imported with another one.
    """
    if backend not in BACKENDS:
        raise RenderError(f"render.gl={backend!r} is not one of {', '.join(BACKENDS)}")
    current = os.environ.get("MUJOCO_GL", "")
    if backend == "auto":
        if current:
            return current
        if os.environ.get("DISPLAY"):
            chosen = "glfw"
        elif ctypes.util.find_library("EGL"):
            chosen = "egl"
        elif ctypes.util.find_library("OSMesa"):
            chosen = "osmesa"
        else:
            chosen = "egl"
            log.warning(
                "no libEGL or libOSMesa found: rendering will fail; install the system packages "
                "libegl1 libegl-mesa0 libgl1-mesa-dri (or libosmesa6), as scripts/setup.sh does"
            )
    else:
        chosen = backend
    ctx_module = sys.modules.get("mujoco.rendering.classic.gl_context")
    if ctx_module is not None:
        in_effect = getattr(ctx_module, "_MUJOCO_GL", current) or "glfw"
        if in_effect != chosen:
            raise RenderError(
                f"mujoco was imported before the OpenGL backend was chosen (it uses "
                f"{in_effect!r}, {chosen!r} is needed): set MUJOCO_GL={chosen} in the "
                "environment, or call factory.sim.gl.configure_gl() before importing mujoco"
            )
        return in_effect
    os.environ["MUJOCO_GL"] = chosen
    if chosen in ("egl", "osmesa"):
        os.environ.setdefault("PYOPENGL_PLATFORM", chosen)
    if chosen == "egl" and not os.path.exists("/dev/nvidiactl"):
        os.environ.setdefault("EGL_PLATFORM", "surfaceless")
    return chosen
