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

import os
from dataclasses import replace
from pathlib import Path

import numpy as np

import lunarviz.constants as C
from lunarviz.errors import LunarvizError, any_case, did_you_mean, short_repr, unknown_choice
from lunarviz.methods.tracer.facet_result import FacetResult
from lunarviz.options import BY_NAME, OPTIONS, defaults, numpydoc_parameters

#: options of :class:`Scene` and their defaults (the command line's defaults), from the schema
SCENE_DEFAULTS = defaults()


#: θ in [0, 180] is the paper's half orbit (waxing: the Moon east of the Sun, full Moon at 0,
#: new Moon at 180); θ in (180, 360) is its mirror image, the waning half (same phase angle at
#: θ and 360 - θ, the other limb lit): with a lunar albedo map the two differ.
THETA_MAX = 360.0


def _phases(phases) -> tuple:
    from lunarviz.parsing import parse_float_list
    if phases is None:
        return C.PAPER_PHASES_DEG
    if isinstance(phases, str):
        return tuple(parse_float_list(phases, "phase", 0.0, THETA_MAX))
    try:
        if isinstance(phases, (bool, np.bool_)):
            raise TypeError
        vals = np.atleast_1d(np.asarray(phases, dtype=float))
    except (TypeError, ValueError, OverflowError):
        raise LunarvizError(f"phases {str(phases)[:40]!r} must be numbers (θ [deg]) or a string a,b,c / "
                            f"start:stop:step") from None
    if vals.ndim != 1 or vals.size == 0 or not np.all(np.isfinite(vals)) or np.any((vals < 0) | (vals > THETA_MAX)):
        raise LunarvizError(f"phases {phases!r} must be finite angles θ in [0, 360] deg")
    return tuple(float(v) for v in vals)


def _number(value, name: str) -> float:
    """``value`` as a float, or a one-line error naming it (a string, a list, None)."""
    try:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError
        return float(value)
    except (TypeError, OverflowError):
        raise LunarvizError(f"{name} {short_repr(value)} must be a number") from None


def _pixels(pixels) -> tuple[int, int]:
    """``pixels``: N, (W, H), or the command line's ``"N"`` / ``"WxH"`` → (W, H)."""
    from lunarviz.methods.camera import parse_pixels
    if isinstance(pixels, str):
        return parse_pixels(pixels)
    sides = (pixels, pixels) if np.isscalar(pixels) else tuple(pixels) if isinstance(pixels, (list, tuple)) else ()
    if len(sides) != 2 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in sides):
        raise LunarvizError(f"pixels {pixels!r} must be an integer N or integers (W, H)")
    return int(sides[0]), int(sides[1])


def _key_list(keys) -> list:
    """``keys``: a list of θ [deg] or UTC times (a string alone would be read letter by letter)."""
    if isinstance(keys, (str, bytes)) or not isinstance(keys, (list, tuple, np.ndarray)):
        raise LunarvizError(f"keys {keys!r} must be a list of phases θ or times (one key: key=...)")
    return list(keys)


def _brdf_name(brdf) -> str:
    """A lunar BRDF's name in any case (``DHG``: ``dhg``), or the one-line error."""
    from lunarviz.photometry.brdf import BRDF_NAMES
    name = any_case(brdf.strip(), BRDF_NAMES) if isinstance(brdf, str) else None
    if name is None:
        raise unknown_choice("BRDF", brdf, BRDF_NAMES)
    return name


def _check_key(sc: "Scene", key):
    """A task key for ``sc``: a phase θ [deg] in [0, 360], or (a scene with times) a UTC time."""
    if key is None:
        return sc.keys[0]
    if sc.times is not None:
        from lunarviz.sky.ephemeris import time_list
        if not isinstance(key, str):
            raise LunarvizError(f"this scene is dated: give a UTC time, not {key!r}")
        times = time_list(key)
        if len(times) != 1:
            raise LunarvizError(f"give one time, got {key!r}")
        return times[0]
    try:
        th = float(key)
    except (TypeError, ValueError):
        raise LunarvizError(f"phase {key!r} is not a number (this scene has no times)") from None
    if not (np.isfinite(th) and 0.0 <= th <= THETA_MAX):
        raise LunarvizError(f"phase {key!r} is out of range [0, 360] deg")
    return th



class Scene:
    """What to simulate: the geometry (θ or dates and an observer), the bodies, the BRDFs.

    Every option but ``phases``, ``time`` and ``time_range`` is declared in :mod:`lunarviz.options`
    (the command line's flag is the keyword with ``-`` for ``_``, except where shown). Everything
    is checked when the scene is made (meshes are read, dates and observers parsed); a bad value
    raises :class:`~lunarviz.errors.LunarvizError` naming it.

    Parameters
    ----------
    phases : float, sequence of float or str, optional
        Orbital angles θ [deg] of the paper's scene (Eq. 3), or ``"start:stop:step"``.
        Default 0:180:5. Ignored when a time is given.
    time : str or sequence of str, optional
        UTC times (ISO 8601). The real sky from DE421 replaces θ.
    time_range : str, optional
        ``"START,STOP,STEP"`` with steps like ``30s``, ``10min``, ``1h``, ``1d``.
{options}
    """

    def __init__(self, phases=None, *, time=None, time_range=None, observer: str = BY_NAME["observer"].default,
                 **options):
        unknown = set(options) - set(SCENE_DEFAULTS)
        if unknown:
            name = sorted(unknown)[0]
            raise LunarvizError(f"unknown Scene option {name!r}{did_you_mean(name, SCENE_DEFAULTS)}; known: "
                                f"{', '.join(SCENE_DEFAULTS)}")
        from lunarviz.sky.ephemeris import time_list
        if phases is not None and (time is not None or time_range is not None):
            raise LunarvizError("give phases (the θ scene) or time/time_range (the real sky), not both")
        if time is not None and not isinstance(time, str):
            if not isinstance(time, (list, tuple)) or not all(isinstance(t, str) for t in time):
                raise LunarvizError(f"time {time!r} must be an ISO 8601 string or a list of them")
            time = ",".join(time)
        self.times = None if time is None and time_range is None else time_list(time, time_range)
        self.phases = _phases(phases)
        self.options = {**SCENE_DEFAULTS, **options, "observer": observer}
        for name in ("brdfs", "params", "detector"):  # normalised here; the rest by the settings
            self.options[name] = BY_NAME[name].check(self.options[name])
        self.settings("raytrace")  # validates everything (raytrace accepts every option)

    __doc__ = __doc__.format(options=numpydoc_parameters(OPTIONS, "    "))

    def settings(self, method: str = "analytic"):
        """The resolved scene: every option of this scene checked, for one method.

        Parameters
        ----------
        method : {"analytic", "raytrace", "reference"}
            The method the scene is resolved for (meshes and shading are the ray tracer's).

        Returns
        -------
        lunarviz.scene.resolved.ResolvedScene
            Immutable; its ``to_json()`` saves it and ``ResolvedScene.from_json`` restores it.

        Examples
        --------
        >>> import lunarviz
        >>> rs = lunarviz.Scene(phases="90", brdfs=("dhg",)).settings("raytrace")
        >>> rs.method, rs.phases_deg, rs.brdfs
        ('raytrace', (90.0,), ('dhg',))
        """
        from lunarviz.scene import ResolvedScene
        o = dict(self.options)
        o["brdfs"] = tuple(o["brdfs"])
        o["params"] = o["params"] or {}
        o["detector"] = None if o["detector"] is None else tuple(float(c) for c in o["detector"])
        return ResolvedScene(phases_deg=self.phases, times=self.times, method=method, **o)

    @property
    def keys(self) -> list:
        """One task key per phase θ [deg] or UTC time label (list of float or str)."""
        return list(self.times) if self.times is not None else list(self.phases)

    def geometry(self, key=None):
        """The geometry of one task.

        Parameters
        ----------
        key : float or str, optional
            Phase θ [deg], or a UTC time of a dated scene (default: the scene's first).

        Returns
        -------
        (SceneGeometry, dict)
            The bodies' positions [m] (:class:`~lunarviz.geometry.scene_geometry.SceneGeometry`) and
            the row fields (time, distances, libration, flags).
        """
        return self.settings("raytrace").task(self.keys[0] if key is None else key)

    def __repr__(self) -> str:
        def few(v):
            return repr(tuple(v)) if len(v) <= 4 else f"<{len(v)}: {v[0]} .. {v[-1]}>"
        where = f"time={few(self.times)}" if self.times else f"phases={few(self.phases)}"
        diff = {k: v for k, v in self.options.items() if SCENE_DEFAULTS[k] != v}
        return f"lunarviz.Scene({where}, {', '.join(f'{k}={v!r}' for k, v in diff.items())})".replace(", )", ")")


def _scene(scene, scene_options) -> Scene:
    if scene is None:
        return Scene(**scene_options)
    if scene_options:
        raise LunarvizError(f"give a Scene or scene options, not both ({', '.join(scene_options)})")
    if not isinstance(scene, Scene):
        raise LunarvizError(f"scene must be a lunarviz.Scene, got {type(scene).__name__}")
    return scene


def _grey_only(sc: Scene, what: str) -> None:
    """Refuse the spectral options where a function has no spectral output (they would be
    silently ignored): per-facet arrays and the 3-D views are grey."""
    if sc.options.get("wavelengths") is not None or sc.options.get("bands") is not None:
        raise LunarvizError(f"{what} is grey: --wavelengths/--band apply to sweep and image")
    _unpolarised(sc, what)


def _unpolarised(sc: Scene, what: str) -> None:
    """Refuse ``stokes`` where a function has no Stokes output (it would be silently ignored)."""
    if sc.options.get("stokes"):
        raise LunarvizError(f"{what} has no Stokes output: --stokes applies to sweep")


def run(scene: Scene | None = None, method: str = "analytic", workers: int | None = None,
        progress: bool = False, executor: str = "local", scheduler: str | None = None, **scene_options) -> dict:
    """Run a sweep and return the raw result, the structure written to JSON.

    Parameters
    ----------
    scene, method, workers, progress
        As for :func:`sweep`.
    executor : {"local", "dask"}
        Local worker processes, or a Dask distributed cluster (``scheduler`` address such as
        ``tcp://host:8786``; without one, a local cluster of ``workers`` processes).

    Returns
    -------
    dict
        ``{"settings", "rows", "bond_albedo", "wall_seconds", ...}``; each row has
        ``moonshine_W_m2``, ``earthshine_W_m2`` [W m-2], angles [deg], ``apparent_albedo``.
    """
    from lunarviz.workflows.sweeps import run_sweep
    if workers is not None and not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise LunarvizError(f"workers={workers!r} must be a positive integer")
    sc = _scene(scene, scene_options)
    return run_sweep(sc.settings(method), workers=workers, progress=progress, executor=executor, scheduler=scheduler)


def sweep(scene: Scene | None = None, method: str = "analytic", workers: int | None = None,
          progress: bool = False, executor: str = "local", scheduler: str | None = None, **scene_options):
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
    progress : bool
        Show a progress bar over the phases or dates (tqdm, on stderr); off by default in the
        API, on in the command line (``--quiet`` turns it off).
    executor, scheduler
        ``"local"`` or ``"dask"`` (see :func:`run`).

    Returns
    -------
    xarray.Dataset
        Dimensions ``brdf`` × ``phase`` (θ [deg]) or ``brdf`` × ``time``; variables
        ``moonshine`` and ``earthshine`` [W m-2], ``apparent_albedo``, the geometry, and
        ``bond_albedo`` (per BRDF); units and descriptions in each variable's ``attrs``
        (CF conventions). ``attrs["settings_json"]`` reruns it.
    """
    from lunarviz.outputs.tables import to_dataset
    return to_dataset(run(scene, method, workers, progress, executor, scheduler, **scene_options))


class Facets(FacetResult):
    """Per-facet results of :func:`trace` (arrays in ``cell_data``, totals in ``totals``)."""

    def to_pyvista(self, bodies: bool = False):
        """The per-facet results as PyVista data.

        Parameters
        ----------
        bodies : bool
            False: the Moon only, Moon-centred [m] in its body frame (MOON_ME on dates).
            True: a ``MultiBlock`` of Moon, Earth and Sun in scene coordinates [m].

        Returns
        -------
        pyvista.PolyData or pyvista.MultiBlock
            Cell arrays as in :mod:`lunarviz.methods.tracer.facets` (radiance [W m-2 sr-1], irradiance [W m-2],
            contributions [W m-2], angles [deg], lit fractions).
        """
        from lunarviz.viz.meshio import facet_polydata, multiblock
        return multiblock(self) if bodies else facet_polydata(self)

    def save(self, path) -> None:
        """Write the per-facet results to a VTK or PLY file, atomically.

        Parameters
        ----------
        path : path
            ``.vtp``, ``.vtk`` or ``.ply`` (the Moon with its cell arrays), or ``.vtm`` (a multiblock
            of every body in scene coordinates [m]).
        """
        from lunarviz.outputs.writers import check_output_path
        from lunarviz.viz.meshio import check_vtm_target, write_facet_mesh
        check_output_path(path, (".vtp", ".vtk", ".ply", ".vtm"))
        if str(path).lower().endswith(".vtm"):
            check_vtm_target(path)
        write_facet_mesh(path, self)


def trace(scene: Scene | None = None, key=None, brdf: str | None = None, **scene_options) -> Facets:
    """Ray trace one phase or time and return per-facet results.

    Parameters
    ----------
    scene : Scene
        The scene (or its options as keywords).
    key : float or str, optional
        Phase θ [deg] in [0, 360], or a UTC time for a dated scene (default: the scene's first).
    brdf : str, optional
        The BRDF of the unsuffixed arrays (default: the scene's first); every BRDF of the
        scene has suffixed arrays.

    Returns
    -------
    Facets
        ``cell_data`` (per-facet arrays: radiance [W m-2 sr-1], irradiance and contributions
        [W m-2], angles [deg]), ``totals`` (detector irradiance [W m-2]), ``info``;
        ``.to_pyvista()``, ``.save(path)``.
    """
    from lunarviz.workflows.tasks import facets
    sc = _scene(scene, scene_options)
    _grey_only(sc, "trace")
    settings = sc.settings("raytrace")
    key = _check_key(sc, key)
    brdf = None if brdf is None else _brdf_name(brdf)
    if brdf is not None and brdf not in settings.brdfs:
        raise LunarvizError(f"BRDF {brdf!r} is not among the scene's {', '.join(settings.brdfs)}")
    res = facets(settings, key, brdf)
    return Facets(**{f: getattr(res, f) for f in ("vertices", "faces", "cell_data", "totals", "info", "bodies")})


def render(scene: Scene | None = None, key=None, brdf: str = "dhg", view: str = "composite",
           size=(1600, 900), out=None, **scene_options) -> np.ndarray:
    """An offscreen picture for people (PyVista) of one phase or time.

    Parameters
    ----------
    scene, key
        As for :func:`trace`.
    brdf : str
        The BRDF shown.
    view : {"composite", "moon", "rays", "maps"}
        The panels.
    size : (int, int)
        Width and height [pixels], 64..8192.
    out : path, optional
        Also write the picture as PNG.

    Returns
    -------
    numpy.ndarray
        RGB, (height, width, 3), uint8. For radiance images see :func:`image`.
    """
    from lunarviz.viz import views
    from lunarviz.workflows.tasks import view_data
    sc = _scene(scene, scene_options)
    _grey_only(sc, "render")
    if view not in views.VIEWS:
        raise unknown_choice("view", view, views.VIEWS)
    size = _check_size(size)
    if out is not None:
        from lunarviz.outputs.writers import check_output_path
        out = check_output_path(out, (".png",))
    brdf = _brdf_name(brdf)
    settings = replace(sc.settings("raytrace"), brdfs=(brdf,))
    return views.render_image(view_data(settings, _check_key(sc, key), brdf), view=view, size=size, out=out)


def _check_size(size) -> tuple[int, int]:
    if not isinstance(size, (list, tuple)) or len(size) != 2 \
            or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in size):
        raise LunarvizError(f"size {size!r} must be (width, height): two whole numbers of pixels")
    w, h = (int(v) for v in size)
    if not (64 <= w <= 8192 and 64 <= h <= 8192):
        raise LunarvizError(f"size {size!r}: each side must be 64..8192 pixels")
    return w, h


def view(scene: Scene | None = None, key=None, brdf: str = "dhg", size=(1600, 900), web: bool = False,
         port: int = 0, host: str = "127.0.0.1", **scene_options):
    """The interactive viewer.

    Parameters
    ----------
    scene, key, brdf, size
        As for :func:`render`.
    web : bool
        False: a desktop window (needs a display). True: a trame server for a browser or a
        notebook, rendering on the server.
    port : int
        TCP port for ``web`` (0: a free one).
    host : str
        Interface to bind for ``web``: 127.0.0.1 unless asked otherwise.

    Returns
    -------
    None
        Blocks until the window is closed or the server is interrupted.
    """
    from functools import partial

    from lunarviz.workflows.tasks import view_data
    sc = _scene(scene, scene_options)
    _grey_only(sc, "view")
    settings = replace(sc.settings("raytrace"), brdfs=(brdf,))
    key = _check_key(sc, key)
    size = _check_size(size)
    compute = partial(view_data, settings)
    if web:
        if not (isinstance(port, (int, np.integer)) and not isinstance(port, bool) and 0 <= port <= 65535):
            raise LunarvizError(f"port {port!r} is not a TCP port (0-65535; 0 picks a free one)")
        from lunarviz.viz.web import serve
        return serve(compute, key, brdf, settings.times, host=str(host), port=int(port), size=size)
    from lunarviz.viz.viewer import run_viewer
    return run_viewer(compute, key, brdf, settings.times, size=size)


def _instrument_images(sc: Scene, keys, instrument, exposure, frames: int, seed: int, out, progress: bool):
    """:func:`image` with an instrument (``salex``, ``bbso`` or a TOML file, :mod:`lunarviz.instrument.spec`):
    its camera, band and optics; the FITS file adds ``EXPECTED_COUNTS`` and ``frames`` noisy
    ``COUNTS`` of ``exposure`` [s] (frame k from ``numpy.random.default_rng([seed, k])``; default:
    the scene's ``seed``). Without ``out``: :class:`~lunarviz.instrument.observation.Observation` objects."""
    import json

    from lunarviz.instrument.frames import append_counts
    from lunarviz.instrument.spec import load_instrument
    from lunarviz.outputs.images import write_fits
    from lunarviz.outputs.writers import StagedFiles, check_output_path, numbered_paths
    from lunarviz.workflows.measurement import MAX_FRAMES, check_count, check_seed, observation
    inst = load_instrument(instrument)
    keys = [_check_key(sc, k) for k in keys]
    frames = check_count(frames, "--frames", MAX_FRAMES)
    settings = sc.settings("raytrace")
    settings_dict = settings.to_dict()
    seed = check_seed(settings.seed if seed is None else seed)
    targets = []
    if out is not None:
        targets = numbered_paths(check_output_path(out, (".fits",)), len(keys))
        for target in targets:
            check_output_path(target, (".fits",))
    it = keys
    if progress and len(keys) > 1:
        from tqdm import tqdm
        it = tqdm(keys, desc="image", unit="frame", leave=False)
    results = []
    with StagedFiles() as staged:
        for n, k in enumerate(it):
            obs = observation(settings, k, inst, exposure)
            results.append(obs)
            if out is not None:
                tmp = staged.stage(targets[n])
                write_fits(tmp, obs.image, obs.image.planes, {"psf": inst.psf, "halo": inst.halo,
                                                              "settings": settings_dict})
                append_counts(tmp, obs, k, json.dumps(settings_dict), frames, seed)
    if out is not None:
        return targets
    return results[0] if len(results) == 1 else results


def measure(path=None, *, expected: bool = False, scene: Scene | None = None, simulate: int | None = None,
            instrument=None, exposure: float | None = None, frames: int = 1, seed: int | None = None, lunar_fit=None,
            progress: bool = False, **scene_options) -> dict:
    """The Earth's apparent albedo p* measured from frames in counts (:mod:`lunarviz.instrument.pipeline`).

    Parameters
    ----------
    path : path, optional
        A FITS file of :func:`image` with an instrument; ``expected``: measure its noise-free plane.
    scene, simulate, instrument : optional
        Instead of a file: ``simulate`` measurements of the scene's first phase or time by
        ``instrument`` (``salex``, ``bbso``, a TOML file), ``frames`` frames of ``exposure`` [s]
        each, measurement i frame j from ``numpy.random.default_rng([seed, i, j])`` (default: the
        scene's ``seed``).
    lunar_fit : path, optional
        A ``lunarviz fit`` result whose covariance is the lunar model's uncertainty.

    Returns
    -------
    dict with ``rows`` (``p_star``, ``p_star_sigma`` (random), ``sigma_*`` terms,
    ``p_star_sigma_systematic``, ``p_star_sigma_total``, ``p_star_U_k2``) and, simulated, a
    ``summary`` of the standardised errors against the sweep's p*.
    """
    from lunarviz.workflows.measurement import measure_file
    from lunarviz.workflows.measurement import simulate as run_simulation
    if simulate is None:
        if path is None:
            raise LunarvizError("measure needs a FITS file or simulate=N")
        if not isinstance(path, (str, os.PathLike)):
            raise LunarvizError(f"measure's path {path!r} must be a file name")
        given = [k for k, v in (("scene", scene), ("instrument", instrument), ("exposure", exposure),
                                ("frames", None if frames == 1 else frames), ("seed", seed)) if v is not None]
        if given or scene_options:
            raise LunarvizError(f"measure of a file takes its scene, instrument and exposure from the file: drop "
                                f"{(given + list(scene_options))[0]} (or simulate=N)")
        if not isinstance(expected, (bool, np.bool_)):
            raise LunarvizError(f"expected {expected!r} must be True or False")
        return measure_file(path, bool(expected), lunar_fit)
    from lunarviz.instrument.spec import load_instrument
    sc = _scene(scene, scene_options)
    _unpolarised(sc, "measure")
    settings = sc.settings("raytrace")
    return run_simulation(settings, sc.keys[0], load_instrument(instrument), simulate,
                          settings.seed if seed is None else seed, exposure, frames,
                          lunar_fit, progress)


def plan(scene: Scene | None = None, *, instrument, snr: float, key=None, per: str = "patch",
         **scene_options) -> dict:
    """The exposure that reaches a signal-to-noise ratio on the earthlit patch with nothing saturated.

    Parameters
    ----------
    scene : Scene, optional
        The scene (or its options as keywords); one lunar BRDF.
    instrument : str or Instrument
        ``salex``, ``bbso`` or a TOML file (:mod:`lunarviz.instrument.spec`).
    snr : float
        The signal-to-noise ratio in one frame of the earthlit patch's mean charge (``per="patch"``,
        what the measurement uses) or of one of its pixels (``per="pixel"``).
    key : float or str, optional
        Phase θ [deg] or a UTC time (default: the scene's first).

    Returns
    -------
    dict
        ``exposure_s`` [s] (``None`` when no exposure reaches ``snr`` unsaturated), ``feasible``,
        ``saturation_exposure_s``, ``frames_needed_at_saturation_exposure``, the patch's signal
        [e⁻ s⁻¹] and the definition of the SNR (:func:`lunarviz.workflows.measurement.plan`).
    """
    from lunarviz.instrument.spec import instrument_spec_text, load_instrument
    from lunarviz.workflows.measurement import plan as plan_exposure
    sc = _scene(scene, scene_options)
    _unpolarised(sc, "plan")
    if key is None and len(sc.keys) > 1:
        raise LunarvizError(f"plan takes one phase or time: the scene has {len(sc.keys)} (give key=...)")
    res = plan_exposure(sc.settings("raytrace"), _check_key(sc, key), load_instrument(instrument), _number(snr, "snr"),
                        per=per)
    return {**res, "instrument_spec": instrument_spec_text(instrument)}


def image(scene: Scene | None = None, key=None, *, keys=None, camera=None, fov_deg: float | None = None, pixels=None,
          supersample: int | None = None, pointing: str | None = None, psf: str | None = None, halo: str | None = None,
          out=None,
          gif=None, progress: bool = False, instrument=None, exposure: float | None = None, frames: int = 1,
          seed: int | None = None, **scene_options):
    """Synthetic camera images (:mod:`lunarviz.methods.camera`) in radiance [W m-2 sr-1].

    Parameters
    ----------
    scene : Scene
        Every BRDF of the scene gets a MOONSHINE and an EARTHSHINE plane.
    key : float or str, optional
        One phase θ [deg] or UTC time (default: the scene's first); ``keys`` for several frames.
    camera : lunarviz.methods.camera.Camera, optional
        Or ``fov_deg`` [deg, default 0.75], ``pixels`` (N or (W, H), default 256), ``supersample``
        (K×K rays per pixel, default 4), ``pointing`` ("moon", the default, or "RA,DEC" [deg]); an
        instrument sets them all itself.
    psf, halo : str, optional
        ``gaussian:FWHM_ARCSEC`` or a .npy kernel; ``FRACTION,INDEX[,CORE_ARCSEC]`` power-law wing
        (:mod:`lunarviz.outputs.images`).
    out : path, optional
        ``.fits`` (one HDU per plane, BUNIT, TAN WCS), ``.npy`` or ``.png``; several frames are
        numbered ``FILE_000.ext``.
    progress : bool
        Show a progress bar over the frames (tqdm, on stderr) when there are several.
    instrument : str or Instrument, optional
        ``salex``, ``bbso`` or a TOML file: see :func:`_instrument_images` (``exposure``, ``frames``, ``seed``).

    Returns
    -------
    ImageResult (one key, no ``out``) or list of ImageResult; with ``out``, the files written.
    """
    from lunarviz.instrument.optics import apply_optics, parse_halo, parse_psf
    from lunarviz.methods.camera import Camera
    from lunarviz.outputs.images import write_fits, write_npy, write_png
    from lunarviz.workflows.tasks import image as task_image
    sc = _scene(scene, scene_options)
    _unpolarised(sc, "image")
    given = [k for k, v in (("camera", camera), ("fov_deg", fov_deg), ("pixels", pixels), ("supersample", supersample),
                            ("pointing", pointing), ("gif", gif)) if v is not None] + \
        [k for k, v in (("psf", psf), ("halo", halo)) if v not in (None, "none")]
    if instrument is not None:
        if given:
            raise LunarvizError(f"an instrument sets the camera and its optics: drop {given[0]}")
        return _instrument_images(sc, _key_list(keys) if keys is not None else [key], instrument, exposure, frames,
                                  seed, out, progress)
    if exposure is not None or frames != 1:
        raise LunarvizError("exposure and frames go with an instrument (instrument=...)")
    if camera is None:
        w, h = _pixels(256 if pixels is None else pixels)
        camera = Camera(fov_deg=_number(0.75 if fov_deg is None else fov_deg, "fov_deg"), width=w, height=h,
                        supersample=4 if supersample is None else supersample,
                        pointing="moon" if pointing is None else pointing)
    settings = sc.settings("raytrace")
    keys = [_check_key(sc, k) for k in _key_list(keys)] if keys is not None else [_check_key(sc, key)]
    req = settings.spectral_request()
    if req is not None and req.kind == "wavelength" and out is not None and str(out).lower().endswith(".fits"):
        from lunarviz.outputs.images import check_cube_wavelengths
        check_cube_wavelengths(req.labels)
    pix_arcsec = float(np.degrees(camera.scale_rad)) * 3600.0
    k_psf = parse_psf(psf, pix_arcsec, (camera.height, camera.width))
    k_halo = parse_halo(halo, pix_arcsec, (camera.height, camera.width))
    from lunarviz.outputs.writers import StagedFiles, check_output_path, numbered_paths
    if out is not None:
        out = check_output_path(out, (".fits", ".npy", ".png"))
    results, files = [], []
    targets = [] if out is None else numbered_paths(out, len(keys))
    for target in targets + ([gif] if gif is not None and len(keys) > 1 else []):
        check_output_path(target, (Path(target).suffix.lower(),))  # a folder in the way: refused before work
    it = keys
    if progress and len(keys) > 1:
        from tqdm import tqdm
        it = tqdm(keys, desc="image", unit="frame", leave=False)
    with StagedFiles() as staged:  # every frame (and the GIF) or none
        for n, k in enumerate(it):
            res = task_image(settings, k, camera)
            for comp in res.planes:
                for b in res.planes[comp]:
                    res.planes[comp][b] = apply_optics(res.planes[comp][b], k_psf, k_halo)
            results.append(res)
            if out is not None:
                target = targets[n]
                suffix = target.suffix.lower()
                extra = {"psf": psf, "halo": halo, "settings": settings.to_dict()}
                tmp = staged.stage(target)
                if suffix == ".fits":
                    write_fits(tmp, res, res.planes, extra)
                elif suffix == ".npy":
                    write_npy(tmp, res.planes)
                else:
                    write_png(tmp, res, res.planes)
                files.append(target)
        if gif is not None and len(results) > 1:
            _write_gif(results, staged.stage(gif))
            files.append(gif)
    if out is not None:
        return files
    return results[0] if len(results) == 1 else results


def _write_gif(results: list, path) -> None:
    """An animated GIF of images' first plane (moonshine + earthshine, an asinh stretch), atomically."""
    import io as bytes_io

    from PIL import Image

    from lunarviz.outputs.writers import write_bytes_atomic
    frames = []
    for res in results:
        b = next(iter(res.planes["moonshine"]))
        tot = res.planes["moonshine"][b] + res.planes["earthshine"][b]
        v = np.arcsinh(tot / max(np.percentile(tot[tot > 0], 5) if (tot > 0).any() else 1.0, 1e-30))
        v = (255 * v / max(v.max(), 1e-30)).astype(np.uint8)[::-1]
        frames.append(Image.fromarray(v))
    buf = bytes_io.BytesIO()
    frames[0].save(buf, format="GIF", save_all=True, append_images=frames[1:], duration=250, loop=0)
    write_bytes_atomic(path, buf.getvalue())


def _angles(values, what: str, lo: float, hi: float) -> tuple:
    try:
        if isinstance(values, str):
            from lunarviz.parsing import parse_float_list
            values = parse_float_list(values, what, lo, hi)
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise LunarvizError(f"{what} {short_repr(values, 60)} must be a number or a list of numbers") from None
    if arr.ndim > 1 or not np.all(np.isfinite(arr)):
        raise LunarvizError(f"{what} {short_repr(values, 60)} must be a finite number or a flat list of them")
    out = tuple(float(v) for v in np.atleast_1d(arr))
    bad = [v for v in out if not (lo <= v <= hi)]
    if not out or bad:
        raise LunarvizError(f"{what} {bad[0] if bad else short_repr(values, 60)} must be in {lo:g}…{hi:g}")
    return out


def brdf(*, body: str = "moon", model: str | None = None, surface: str | None = None, wavelengths=(550.0,),
         incidence, emission, azimuth=(0.0,), atmosphere: bool = True, params: dict | None = None,
         stokes: bool = False, **moon_options) -> list[dict]:
    """Rows of a lunar BRDF or of the Earth's top-of-atmosphere reflectance, as ``lunarviz brdf``
    writes them (:mod:`lunarviz.workflows.brdf_tables`).

    Parameters
    ----------
    body : {"moon", "earth"}
        A lunar BRDF (``model``) or an Earth surface class under the Rayleigh atmosphere and the ozone
        (``surface``).
    model : str, optional
        The Moon: ``lambert``, ``shg`` or ``dhg``.
    surface : str, optional
        The Earth: ``black``, ``lambert:A``, ``ocean``, ``land``, ``vegetation``, ``desert``, ``snow``
        or ``cloud``.
    wavelengths : sequence of float
        The Earth: wavelengths [nm], 300-2500.
    incidence, emission : float or sequence of float
        Incidence and emission angles [deg], 0-90.
    azimuth : float or sequence of float
        Azimuths [deg]; 0 is the viewer on the source's side.
    atmosphere : bool
        The Earth: with the Rayleigh layer (False: the bare surface).
    params : dict, optional
        The Moon's model parameters ``{name: value}`` (w, b, c, …) or the Earth's
        (:data:`lunarviz.options.EARTH_PARAMETERS`: wind_speed [m s⁻¹], cloud_top_hpa, surface_hpa).
    stokes : bool
        The Earth, black and ``lambert:A`` grounds and the bare sea (``atmosphere=False``): the
        vector solution, its ``q_reflectance_factor``,
        ``u_reflectance_factor``, ``dolp`` and ``aolp_deg`` in the meridian plane of the view
        (:mod:`lunarviz.earth_optics.stokes`).
    **moon_options
        The Moon: ``dhg_convention``, ``h_function``, ``moon_model``.

    Returns
    -------
    list of dict
        One row per (wavelength,) incidence, emission and azimuth: the angles [deg], the BRDF
        [sr⁻¹] and ``reflectance_factor`` (πL/(μ₀E₀)).
    """
    from lunarviz.workflows.brdf_tables import earth_rows, lunar_rows
    inc = _angles(incidence, "incidence", 0.0, 90.0)
    emi = _angles(emission, "emission", 0.0, 90.0)
    azi = _angles(azimuth, "azimuth", -360.0, 360.0)
    if body == "earth":
        if surface is None or model is not None or moon_options:
            raise LunarvizError("brdf(body='earth') takes surface=..., not a lunar model or its options")
        for name, flag in (("atmosphere", atmosphere), ("stokes", stokes)):
            if not isinstance(flag, bool):
                raise LunarvizError(f"{name}={flag!r} must be True or False")
        lam = _angles(wavelengths, "wavelength", 300.0, 2500.0)
        return earth_rows(surface, lam, inc, emi, azi, atmosphere=atmosphere, params=params, stokes=stokes)[0]
    if body != "moon":
        raise LunarvizError(f"body {body!r} must be 'moon' or 'earth'")
    from lunarviz.photometry.brdf import make_brdf
    if model is None or surface is not None:
        raise LunarvizError("brdf(body='moon') takes model=... (lambert, shg, dhg), not a surface")
    if stokes is not False:
        raise LunarvizError(f"stokes={stokes!r}: the Moon's BRDF has no Stokes columns (its polarisation is its "
                            "disc's: sweep(..., stokes=True))")
    known = ("dhg_convention", "h_function", "moon_model")
    for k in moon_options:
        if k not in known:
            raise unknown_choice("brdf() option", k, known)
    return lunar_rows(make_brdf(model, params=params, **moon_options), inc, emi, azi)
