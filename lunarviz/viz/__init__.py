"""PyVista views (the only part of lunarviz that imports PyVista; loaded on first use).

Without a display (no DISPLAY or WAYLAND_DISPLAY), VTK is told to open EGL render windows
directly (``VTK_DEFAULT_OPENGL_WINDOW``), instead of trying X first and warning. A user's own
setting of that variable wins; ours is marked, and dropped again in a process (e.g. a child)
that has a display.
"""

import os as _os
import sys as _sys

_MARK = "_LUNARVIZ_SET_VTK_EGL"
if _sys.platform.startswith("linux"):
    if not (_os.environ.get("DISPLAY") or _os.environ.get("WAYLAND_DISPLAY")):
        if "VTK_DEFAULT_OPENGL_WINDOW" not in _os.environ:
            _os.environ["VTK_DEFAULT_OPENGL_WINDOW"] = "vtkEGLRenderWindow"
            _os.environ[_MARK] = "1"
    elif _os.environ.get(_MARK) == "1":
        _os.environ.pop("VTK_DEFAULT_OPENGL_WINDOW", None)
        _os.environ.pop(_MARK, None)
