"""Which OpenGL window VTK opens: EGL (offscreen) on a Linux machine with no display.

Without a display (no ``DISPLAY`` or ``WAYLAND_DISPLAY``), VTK is told to open EGL render
windows directly (``VTK_DEFAULT_OPENGL_WINDOW``) instead of trying X first and warning. A
user's own setting of that variable wins; ours is marked, and dropped again in a process (e.g.
a child) that has a display. Called when a plotter is made, never at import.
"""

from __future__ import annotations

import os
import sys

#: environment variable that marks ``VTK_DEFAULT_OPENGL_WINDOW`` as set by lunarviz
MARK = "_LUNARVIZ_SET_VTK_EGL"


def choose_render_window(environ=None) -> None:
    """Set (or drop our own setting of) ``VTK_DEFAULT_OPENGL_WINDOW`` in ``environ``
    (default ``os.environ``) for this machine's display."""
    env = os.environ if environ is None else environ
    if not sys.platform.startswith("linux"):
        return
    if not (env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")):
        if "VTK_DEFAULT_OPENGL_WINDOW" not in env:
            env["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
            env[MARK] = "1"
    elif env.get(MARK) == "1":
        env.pop("VTK_DEFAULT_OPENGL_WINDOW", None)
        env.pop(MARK, None)
