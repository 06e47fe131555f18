"""lunarviz: real-scale ray-traced earthshine and moonshine (Sun, Earth and Moon meshes, Embree).

The Python API (see :mod:`lunarviz.api` and README.md, "Python"):

* :class:`Scene` — the paper's θ scene or dates and an observer, bodies, meshes, BRDFs;
* :func:`sweep` — an ``xarray.Dataset`` of moonshine, earthshine and albedo (brdf × phase|time);
* :func:`trace` — per-facet results with ``.to_pyvista()``;
* :func:`render`, :func:`view` — pictures and the interactive viewer (``web=True``: trame);
* :func:`image` — synthetic camera images in radiance units (FITS with a TAN WCS);
* :func:`lunarviz.study.mesh` — mesh-resolution studies.

Attributes are imported on first use, so ``import lunarviz`` stays light.
"""

__version__ = "0.1.0"

__all__ = ["Scene", "sweep", "run", "trace", "render", "view", "image", "study", "LunarvizError", "__version__"]


def __getattr__(name):
    if name in ("Scene", "sweep", "run", "trace", "render", "view", "image"):
        from lunarviz.__init__ import api
        return getattr(api, name)
    if name == "study":
        import importlib
        return importlib.import_module(".study", __name__)
    if name == "LunarvizError":
        from lunarviz.__init__.errors import LunarvizError
        return LunarvizError
    raise AttributeError(f"module 'lunarviz' has no attribute {name!r}")
