"""The Python API: a :class:`Scene` and the functions that run it.

    >>> import lunarviz
    >>> scene = lunarviz.Scene(phases="30:150:30", brdfs=("lambert", "dhg"))
    >>> ds = lunarviz.sweep(scene, method="raytrace")        # xarray.Dataset, brdf × phase
    >>> ds.moonshine.sel(brdf="dhg").plot()                   # doctest: +SKIP
    >>> facets = lunarviz.trace(scene, 90.0)                  # per-facet arrays
    >>> facets.to_pyvista().plot(scalars="moonshine_radiance_W_m2_sr")  # doctest: +SKIP

A date and an observer instead of θ:

    >>> leo = lunarviz.Scene(time_range="2026-06-01,2026-06-03,1d", observer="orbit:550,97.6,0,0")

Units are SI throughout: irradiance [W m⁻²], radiance [W m⁻² sr⁻¹], lengths [m], angles
[deg]. The command line (:mod:`lunarviz.cli`) is a thin layer over these functions.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .errors import LunarvizError
from .facets import FacetResult

#: options of :class:`Scene` and their defaults (the command line's defaults)
SCENE_DEFAULTS = {
    "brdfs": ("lambert", "shg", "dhg"), "observer": "geocentre", "detector": None,
    "moon_mesh": None, "earth_mesh": None, "sun_mesh": None, "mesh_units": "m",
    "moon_level": None, "earth_level": None, "sun_level": None,
    "occlusion": True, "self_shadow": True, "shading": "auto",
    "earth_albedo": 0.3, "earth_law": "lambert", "dhg_convention": "paper", "h_function": "hapke1981",
    "moon_model": "paper",
    "params": None, "estimator": "deterministic", "rays": 50_000, "runs": 1, "seed": 0,
    "earth_order": 6, "sun_order": 2, "grid": "converged", "order": 24,
}


def _phases(phases) -> tuple:
    from .parsing import parse_float_list
    if phases is None:
        return tuple(float(p) for p in range(0, 181, 5))
    if isinstance(phases, str):
        return tuple(parse_float_list(phases, "phase", 0.0, 180.0))
    vals = np.atleast_1d(np.asarray(phases, dtype=float))
    if vals.size == 0 or not np.all(np.isfinite(vals)) or np.any((vals < 0) | (vals > 180)):
        raise LunarvizError(f"phases {phases!r} must be finite angles θ in [0, 180] deg")
    return tuple(float(v) for v in vals)


class Scene:
    """What to simulate: the geometry (θ or dates and an observer), the bodies, the BRDFs.

    Parameters
    ----------
    phases : float, sequence of float or str, optional
        Orbital angles θ [deg] of the paper's scene (Eq. 3), or ``"start:stop:step"``.
        Default 0:180:5. Ignored when a time is given.
    time : str or sequence of str, optional
        UTC times (ISO 8601). The real sky from DE421 replaces θ.
    time_range : str, optional
        ``"START,STOP,STEP"`` with steps like ``30s``, ``10min``, ``1h``, ``1d``.
    observer : str
        ``geocentre`` (default), ``site:LAT,LON[,HEIGHT_M]``, ``tle:FILE`` or
        ``orbit:ALT_KM,INC_DEG,RAAN_DEG,ARGLAT_DEG[,EPOCH]``; needs a time.
    brdfs : sequence of str
        Lunar BRDFs among ``lambert``, ``shg``, ``dhg``.
    **options
        Every other option of the command line, by its Python name: ``detector`` (x, y, z) [m],
        ``moon_mesh``/``earth_mesh``/``sun_mesh`` (paths), ``mesh_units``, ``moon_level``,
        ``earth_level``, ``sun_level``, ``occlusion``, ``self_shadow``, ``shading``,
        ``earth_albedo``, ``earth_law``, ``dhg_convention``, ``h_function``, ``moon_model``
        (``paper`` or ``rolo-fit``), ``params``
        (``{brdf: {name: value}}``), ``estimator``, ``rays``, ``runs``, ``seed``,
        ``earth_order``, ``sun_order``, ``grid``, ``order`` (see :data:`SCENE_DEFAULTS`).

    Everything is checked when the scene is made (meshes are read, dates and observers
    parsed); a bad value raises :class:`~lunarviz.errors.LunarvizError` naming it.
    """

    def __init__(self, phases=None, *, time=None, time_range=None, observer: str = "geocentre", **options):
        unknown = set(options) - set(SCENE_DEFAULTS)
        if unknown:
            raise LunarvizError(f"unknown Scene option {sorted(unknown)[0]!r}; known: {', '.join(SCENE_DEFAULTS)}")
        from .ephemeris import time_list
        if time is not None and not isinstance(time, str):
            time = ",".join(str(t) for t in time)
        self.times = None if time is None and time_range is None else time_list(time, time_range)
        self.phases = _phases(phases)
        self.options = {**SCENE_DEFAULTS, **options, "observer": observer}
        if isinstance(self.options["brdfs"], str):
            self.options["brdfs"] = tuple(b.strip() for b in self.options["brdfs"].split(","))
        self.settings("raytrace")  # validates everything (raytrace accepts every option)

    def settings(self, method: str = "analytic"):
        """The :class:`~lunarviz.sweeps.SweepSettings` of this scene for ``method``."""
        from .sweeps import SweepSettings
        o = dict(self.options)
        o["brdfs"] = tuple(o["brdfs"])
        o["params"] = o["params"] or {}
        o["detector"] = None if o["detector"] is None else tuple(float(c) for c in o["detector"])
        return SweepSettings(phases_deg=self.phases, times=self.times, method=method, **o)

    @property
    def keys(self) -> list:
        """One task key per phase θ [deg] or UTC time label."""
        return list(self.times) if self.times is not None else list(self.phases)

    def geometry(self, key=None):
        """The low-level :class:`~lunarviz.geometry.Scene` (positions [m]) of one task, and its
        row fields (time, distances, libration, flags)."""
        return self.settings("raytrace").scene_and_fields(self.keys[0] if key is None else key)

    def __repr__(self) -> str:
        where = f"times={len(self.times)} from {self.times[0]}" if self.times else f"phases={len(self.phases)}"
        diff = {k: v for k, v in self.options.items() if SCENE_DEFAULTS.get(k, "geocentre") != v}
        return f"lunarviz.Scene({where}, {', '.join(f'{k}={v!r}' for k, v in diff.items())})".replace(", )", ")")


def _scene(scene, scene_options) -> Scene:
    if scene is None:
        return Scene(**scene_options)
    if scene_options:
        raise LunarvizError(f"give a Scene or scene options, not both ({', '.join(scene_options)})")
    if not isinstance(scene, Scene):
        raise LunarvizError(f"scene must be a lunarviz.Scene, got {type(scene).__name__}")
    return scene


def run(scene: Scene | None = None, method: str = "analytic", workers: int | None = None,
        progress: bool = False, **scene_options) -> dict:
    """Run a sweep and return the raw result (``{"settings", "rows", "bond_albedo", ...}``),
    the structure written to JSON. See :func:`sweep` for the Dataset."""
    from .sweeps import run_sweep
    sc = _scene(scene, scene_options)
    return run_sweep(sc.settings(method), workers=workers, progress=progress)


def sweep(scene: Scene | None = None, method: str = "analytic", workers: int | None = None,
          progress: bool = False, **scene_options):
    """Moonshine, earthshine and albedo at every phase or time, as an ``xarray.Dataset``.

    Parameters
    ----------
    scene : Scene, optional
        The scene; or give its options as keywords (``lunarviz.sweep(phases="30,90")``).
    method : {"analytic", "raytrace", "reference"}
        Paper's point-source quadrature, Embree ray tracing of the meshes, or the exact
        extended-source reference.
    workers : int, optional
        Local worker processes (default: one per core for raytrace/reference).

    Returns
    -------
    xarray.Dataset
        Dimensions ``brdf`` × ``phase`` (θ [deg]) or ``brdf`` × ``time``; variables
        ``moonshine`` and ``earthshine`` [W m-2], ``apparent_albedo``, the geometry, and
        ``bond_albedo`` (per BRDF); units and descriptions in each variable's ``attrs``
        (CF conventions). ``attrs["settings_json"]`` reruns it.
    """
    from .tables import to_dataset
    return to_dataset(run(scene, method, workers, progress, **scene_options))


class Facets(FacetResult):
    """Per-facet results of :func:`trace` (arrays in ``cell_data``, totals in ``totals``)."""

    def to_pyvista(self, bodies: bool = False):
        """The lunar mesh as a ``pyvista.PolyData`` with every per-facet array (Moon-centred [m]);
        with ``bodies=True`` a ``MultiBlock`` of Moon, Earth and Sun in scene coordinates."""
        from .viz.meshio import facet_polydata, multiblock
        return multiblock(self) if bodies else facet_polydata(self)

    def save(self, path) -> None:
        """Write ``.vtp``/``.vtk``/``.ply`` (the Moon) or ``.vtm`` (every body), atomically."""
        from .io import check_output_path
        from .viz.meshio import check_vtm_target, write_facet_mesh
        check_output_path(path, (".vtp", ".vtk", ".ply", ".vtm"))
        if str(path).lower().endswith(".vtm"):
            check_vtm_target(path)
        write_facet_mesh(path, self)


def trace(scene: Scene | None = None, key=None, brdf: str | None = None, **scene_options) -> Facets:
    """Ray trace one phase θ [deg] or UTC time (default: the scene's first) and return the
    per-facet arrays (:mod:`lunarviz.facets`) for every BRDF of the scene; ``brdf`` (default
    the first) names the unsuffixed arrays."""
    from .facets import trace_facets
    sc = _scene(scene, scene_options)
    settings = sc.settings("raytrace")
    key = sc.keys[0] if key is None else key
    if brdf is not None and brdf not in settings.brdfs:
        raise LunarvizError(f"BRDF {brdf!r} is not among the scene's {', '.join(settings.brdfs)}")
    res = trace_facets(settings, key, brdf)
    return Facets(**{f: getattr(res, f) for f in ("vertices", "faces", "cell_data", "totals", "info", "bodies")})


def render(scene: Scene | None = None, key=None, brdf: str = "dhg", view: str = "composite",
           size=(1600, 900), out=None, **scene_options) -> np.ndarray:
    """An offscreen picture (RGB array, height × width × 3) of one phase or time; written
    as PNG to ``out`` when given. ``view`` is composite, moon, rays or maps."""
    from .viz import views
    sc = _scene(scene, scene_options)
    if view not in views.VIEWS:
        raise LunarvizError(f"unknown view {view!r}: choose from {', '.join(views.VIEWS)}")
    settings = replace(sc.settings("raytrace"), brdfs=(brdf,))
    key = sc.keys[0] if key is None else key
    return views.render_image(settings, key, brdf, view=view, size=tuple(size), out=out)


def view(scene: Scene | None = None, key=None, brdf: str = "dhg", size=(1600, 900), web: bool = False,
         port: int = 0, host: str = "127.0.0.1", **scene_options):
    """The interactive viewer: a desktop window, or with ``web=True`` a trame server on
    ``host:port`` (127.0.0.1 unless asked; port 0 picks a free one) for a browser or notebook."""
    sc = _scene(scene, scene_options)
    settings = replace(sc.settings("raytrace"), brdfs=(brdf,))
    key = sc.keys[0] if key is None else key
    if web:
        from .viz.web import serve
        return serve(settings, key, brdf, host=host, port=port, size=tuple(size))
    from .viz.viewer import run_viewer
    return run_viewer(settings, key, brdf, size=tuple(size))


def image(scene: Scene | None = None, key=None, *, keys=None, camera=None, fov_deg: float = 0.75, pixels=256,
          supersample: int = 4, pointing: str = "moon", psf: str | None = None, halo: str | None = None, out=None,
          gif=None, progress: bool = False, **scene_options):
    """Synthetic camera images (:mod:`lunarviz.camera`) in radiance [W m-2 sr-1].

    Parameters
    ----------
    scene : Scene
        Every BRDF of the scene gets a MOONSHINE and an EARTHSHINE plane.
    key : float or str, optional
        One phase θ [deg] or UTC time (default: the scene's first); ``keys`` for several frames.
    camera : lunarviz.camera.Camera, optional
        Or ``fov_deg`` [deg], ``pixels`` (N or (W, H)), ``supersample`` (K×K rays per pixel),
        ``pointing`` ("moon" or "RA,DEC" [deg]).
    psf, halo : str, optional
        ``gaussian:FWHM_ARCSEC`` or a .npy kernel; ``FRACTION,INDEX[,CORE_ARCSEC]`` power-law wing
        (:mod:`lunarviz.image_io`).
    out : path, optional
        ``.fits`` (one HDU per plane, BUNIT, TAN WCS), ``.npy`` or ``.png``; several frames are
        numbered ``FILE_000.ext``.

    Returns
    -------
    ImageResult (one key, no ``out``) or list of ImageResult; with ``out``, the files written.
    """
    from .camera import Camera, synthesize
    from .image_io import apply_optics, parse_halo, parse_psf, write_fits, write_npy, write_png
    sc = _scene(scene, scene_options)
    if camera is None:
        w, h = (pixels, pixels) if np.isscalar(pixels) else tuple(pixels)
        camera = Camera(fov_deg=fov_deg, width=int(w), height=int(h), supersample=supersample, pointing=pointing)
    settings = sc.settings("raytrace")
    keys = list(keys) if keys is not None else [sc.keys[0] if key is None else key]
    pix_arcsec = float(np.degrees(camera.scale_rad)) * 3600.0
    k_psf = parse_psf(psf, pix_arcsec, (camera.height, camera.width))
    k_halo = parse_halo(halo, pix_arcsec, (camera.height, camera.width))
    if out is not None:
        from .io import check_output_path
        out = check_output_path(out, (".fits", ".npy", ".png"))
    results, files = [], []
    it = keys
    if progress and len(keys) > 1:
        from tqdm import tqdm
        it = tqdm(keys, desc="image", unit="frame", leave=False)
    for n, k in enumerate(it):
        res = synthesize(settings, k, camera)
        for comp in res.planes:
            for b in res.planes[comp]:
                res.planes[comp][b] = apply_optics(res.planes[comp][b], k_psf, k_halo)
        results.append(res)
        if out is not None:
            target = out if len(keys) == 1 else out.with_name(f"{out.stem}_{n:03d}{out.suffix}")
            suffix = target.suffix.lower()
            extra = {"psf": psf, "halo": halo, "settings": settings.to_dict()}
            if suffix == ".fits":
                write_fits(target, res, res.planes, extra)
            elif suffix == ".npy":
                write_npy(target, res.planes)
            else:
                write_png(target, res, res.planes)
            files.append(target)
    if gif is not None and len(results) > 1:
        import io as _io

        from PIL import Image

        from .io import write_bytes_atomic
        frames = []
        for res in results:
            b = next(iter(res.planes["moonshine"]))
            tot = res.planes["moonshine"][b] + res.planes["earthshine"][b]
            v = np.arcsinh(tot / max(np.percentile(tot[tot > 0], 5) if (tot > 0).any() else 1.0, 1e-30))
            v = (255 * v / max(v.max(), 1e-30)).astype(np.uint8)[::-1]
            frames.append(Image.fromarray(v))
        buf = _io.BytesIO()
        frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=250, loop=0)
        write_bytes_atomic(gif, buf.getvalue())
        files.append(gif)
    if out is not None:
        return files
    return results[0] if len(results) == 1 else results
