"""lunarviz: real-scale ray-traced earthshine and moonshine (Sun, Earth and Moon meshes, Embree).

The Python API (see :mod:`lunarviz.api` and the documentation's user guide):

* :class:`Scene` — the paper's θ scene or dates and an observer, bodies, meshes, BRDFs;
* :func:`sweep` — an ``xarray.Dataset`` of moonshine, earthshine and albedo (brdf × phase|time);
* :func:`trace` — per-facet results with ``.to_pyvista()``;
* :func:`render`, :func:`view` — pictures and the interactive viewer (``web=True``: trame);
* :func:`image` — synthetic camera images in radiance units (FITS with a TAN WCS);
* :func:`lunarviz.study.mesh <lunarviz.workflows.study.mesh>` — mesh-resolution studies
  (``lunarviz.study`` is :mod:`lunarviz.workflows.study`).

Attributes are imported on first use, so ``import lunarviz`` stays light.
"""

import importlib

__version__ = "0.1.0"

__all__ = ["Scene", "sweep", "run", "trace", "render", "view", "image", "measure", "plan", "brdf", "study",
           "LunarvizError",
           "__version__"]


#: where each public name lives (imported on first use, so ``import lunarviz`` stays light and
#: the package's ``__init__`` imports none of its modules)
_PUBLIC = {"Scene": "lunarviz.api", "sweep": "lunarviz.api", "run": "lunarviz.api", "trace": "lunarviz.api",
           "render": "lunarviz.api", "view": "lunarviz.api", "image": "lunarviz.api", "measure": "lunarviz.api",
           "plan": "lunarviz.api", "brdf": "lunarviz.api",
           "LunarvizError": "lunarviz.errors"}


def __getattr__(name):
    if name == "study":
        return importlib.import_module("lunarviz.workflows.study")
    if name in _PUBLIC:
        return getattr(importlib.import_module(_PUBLIC[name]), name)
    raise AttributeError(f"module 'lunarviz' has no attribute {name!r}")
