"""numba, where it can be used: the switch and the compile helper shared by every kernel module.

numba is a dependency, but compiled kernels are optional at run time: ``LUNARVIZ_NUMBA=0`` or a
failed import falls back to numpy, with the same numbers to rounding. Compiled code is cached
on disk (``cache=True``), so worker processes load it instead of compiling.
"""

from __future__ import annotations

import os

try:  # pragma: no cover - exercised through available()
    if os.environ.get("LUNARVIZ_NUMBA", "1") == "0":
        raise ImportError("disabled by LUNARVIZ_NUMBA=0")
    import numba
    NUMBA = True
except ImportError:  # pragma: no cover
    numba = None
    NUMBA = False


def available() -> bool:
    """Whether compiled kernels can be used in this process."""
    return NUMBA


def jit(fn, **kw):
    """``numba.njit`` with an on-disk cache where one can be written (the package folder or
    numba's user cache), else without: a read-only install must not stop lunarviz."""
    kw.setdefault("error_model", "numpy")  # x/0 gives inf/NaN as in numpy, never raises
    try:
        return numba.njit(cache=True, **kw)(fn)
    except Exception:  # noqa: BLE001 (numba raises RuntimeError "no locator available")
        return numba.njit(cache=False, **kw)(fn)
