"""Resolving a scene: every check that a run's options make sense together, before any work.

:func:`resolve` runs when a :class:`~lunarviz.scene.resolved.ResolvedScene` is made: single options
are checked against the schema (:func:`lunarviz.options.validate`), then everything that depends on
several (a method and the meshes, a date and the observer, a preset and its map, a spectral run
and its Earth), and the inputs that come from files (maps, meshes, a TLE) are read once, so that
a bad value fails in one line before any worker starts. Where an option resolves to another value
(a preset's lunar map, ``--moon-albedo-map none``, canonical time labels), the resolved value is
written back: the resolved scene says exactly what runs.
"""

from __future__ import annotations

import warnings

from lunarviz.errors import LunarvizError, LunarvizWarning, unknown_choice
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.settings import body_mesh_m
from lunarviz.options import BY_NAME, METHODS, default_moon_model, earth_params, validate
from lunarviz.photometry.presets import moon_model_map
from lunarviz.sky.ephemeris import time_list
from lunarviz.spectral.moon import parameters_at
from lunarviz.surfaces.earth_surface import EarthSurface

#: the analytic method's point Sun is refused within this angle of new Moon (θ = 180° itself,
#: where the exact reference is 4e-20 W m-2, is kept): its moonshine is 13 % low at 179°, 60 %
#: at 179.5° and 0 from 179.8° where the extended Sun still lights a crescent
ANALYTIC_CRESCENT_LIMIT_DEG = 1.0
#: the sharpest Henyey-Greenstein lobe a sweep accepts: at b = 0.95 the lobe's width, about
#: (1 - b) rad = 3°, still spans the Earth's 1.9° disc seen from the Moon; at b = 0.999999 the
#: analytic earthshine came out 1e4 W m-2 (the exact reference: 4e-7)
MAX_LOBE_ASYMMETRY = 0.95
#: beyond this many days from a TLE's epoch a sweep warns (SGP4 errors of km grow within weeks)
TLE_MAX_AGE_DAYS = 30.0


def resolve(scene) -> None:
    """Check a :class:`~lunarviz.scene.resolved.ResolvedScene` and write its resolved values back;
    a bad value raises a one-line :class:`~lunarviz.errors.LunarvizError` naming it."""
    validate(scene)
    if scene.params is None:
        object.__setattr__(scene, "params", {})
    if scene.moon_model is None:  # the paper's Moon in the paper's scene; on dates the observed Moon
        object.__setattr__(scene, "moon_model", default_moon_model(scene.times is not None, scene.method,
                                                                   scene.h_function, scene.brdfs))
    _check_tasks(scene)
    check_physical_earth(scene)
    for b in scene.params:
        if b != "earth" and b not in scene.brdfs:
            raise LunarvizError(f"params name BRDF {b!r}, which is not in this run ({', '.join(scene.brdfs)})")
    _check_times(scene)
    _check_observer(scene)
    _check_meshes_need_raytrace(scene)
    if scene.times is not None and scene.earth_rotation_deg is not None:
        raise LunarvizError("--earth-rotation-deg turns the Earth of the θ scene; on dates (--time) the "
                            "Earth turns with the date")
    _resolve_moon_map(scene)
    models = scene.brdf_models()  # validates parameters early
    check_validity(scene, models)
    check_spectral(scene, models)
    _check_maps(scene, models)
    _read_files_once(scene)


def _check_tasks(scene) -> None:
    if scene.method not in METHODS:
        raise unknown_choice("method", scene.method, METHODS)
    if not scene.phases_deg:
        raise LunarvizError("no phase given")
    if scene.times is None and len(set(scene.phases_deg)) != len(scene.phases_deg):
        dup = next(p for p in scene.phases_deg if list(scene.phases_deg).count(p) > 1)
        raise LunarvizError(f"phase {dup:g} is listed twice")


def _check_times(scene) -> None:
    if scene.times is not None:
        if not scene.times:
            raise LunarvizError("no time given")
        object.__setattr__(scene, "times", time_list(",".join(scene.times)))  # canonical labels, checked
        if len(set(scene.times)) != len(scene.times):
            dup = next(t for t in scene.times if scene.times.count(t) > 1)
            raise LunarvizError(f"time {dup} is listed twice")
        if scene.detector is not None:
            raise LunarvizError("--detector places a detector in the θ scene; with --time use --observer")
    if scene.detector is not None and scene.times is None:
        for th in scene.phases_deg:  # a detector inside the Sun or the Moon, before any work
            SceneGeometry(float(th), detector=scene.detector)


def _check_observer(scene) -> None:
    obs = scene.observer_model()  # validates (reads a TLE file) before any work
    if obs.kind != "geocentre" and scene.times is None:
        raise LunarvizError(f"--observer {scene.observer} needs a date: give --time or --time-range")
    if obs.kind == "tle":
        age = max(abs(obs.epoch_age_days(t)) for t in (scene.times[0], scene.times[-1]))
        if age > TLE_MAX_AGE_DAYS:
            warnings.warn(f"TLE {scene.observer!r} is propagated {age:.0f} days from its epoch; SGP4 errors grow "
                          f"to many km within weeks (rows carry tle_epoch_age_days)", LunarvizWarning,
                          stacklevel=5)


def _check_meshes_need_raytrace(scene) -> None:
    if scene.method == "raytrace":
        return
    for value, default, flag in (
            (scene.mesh_units, "m", "--mesh-units"), (scene.moon_level, None, "--mesh-level"),
            (scene.earth_level, None, "--earth-level"), (scene.sun_level, None, "--sun-level"),
            (scene.shading, "auto", "--shading"), (scene.self_shadow, True, "--no-self-shadow")):
        if value != default:
            raise LunarvizError(f"{flag} cannot be used with --method {scene.method}, which has no meshes; "
                                f"use --method raytrace")
    for body in ("moon", "earth", "sun"):
        if getattr(scene, f"{body}_mesh") is not None:
            raise LunarvizError(f"--{body}-mesh cannot be used with --method {scene.method}, which assumes "
                                f"exact spheres; use --method raytrace")


def _resolve_moon_map(scene) -> None:
    """A preset fitted on a mapped Moon brings its map; ``--moon-albedo-map none`` drops any."""
    if scene.moon_albedo_map is None and scene.moon_model != "paper":
        preset_map = moon_model_map(scene.moon_model)
        if preset_map is not None:
            object.__setattr__(scene, "moon_albedo_map", preset_map)
    if isinstance(scene.moon_albedo_map, str) and scene.moon_albedo_map.strip().lower() == "none":
        object.__setattr__(scene, "moon_albedo_map", None)


def _check_maps(scene, models: dict) -> None:
    sf = scene.surfaces()  # reads and checks the maps before any work
    if sf is not None and sf.moon_map is not None:
        sf.moon_map.check_brdfs(models)
        if scene.h_function == "exact" and any(b != "lambert" for b in scene.brdfs):
            raise LunarvizError(f"--h-function exact takes one w, not a per-facet map ({scene.moon_albedo_map}, "
                                f"from --moon-albedo-map or --moon-model {scene.moon_model}): use hapke1981 or "
                                f"hapke2002, or --moon-albedo-map none")
    if sf is not None and scene.method == "reference":
        raise LunarvizError("--method reference integrates the paper's uniform bodies (a check, exact only "
                            "there): with surface maps use --method raytrace (or analytic)")
    if scene.times is None and ((sf is not None and sf.moon_map is not None and scene.moon_mesh is not None)
                                or (not scene.earth_uniform and scene.earth_mesh is not None)):
        raise LunarvizError("a surface map on a user mesh needs a date (--time): in the θ scene a mesh keeps the "
                            "scene's axes while maps take the tidal/sub-solar frame")


def _read_files_once(scene) -> None:
    """The land mask and user meshes read once, here, before any worker (each then finds them in
    its caches: the same arguments as the tracer's own calls)."""
    if not scene.earth_uniform:
        EarthSurface(earth_surface=scene.earth_surface, clouds=scene.clouds).clear_map()
    ts = scene.trace_settings()
    if scene.method == "raytrace":
        for body in ("moon", "earth", "sun"):
            path = getattr(scene, f"{body}_mesh")
            if path is not None:
                from lunarviz.bodies.meshes import NOMINAL_RADII  # trimesh: only when a mesh is given
                body_mesh_m(body, getattr(ts, f"{body}_level"), path, scene.mesh_units, NOMINAL_RADII[body])
    scene.analytic_settings()


def check_validity(scene, models: dict) -> None:
    """Refuse what the methods cannot compute correctly: lobes narrower than the Earth's disc,
    and the analytic method's point Sun next to new Moon."""
    for name, model in models.items():  # lobes the methods' source rules cannot resolve
        phase = getattr(model, "phase", None)
        g = abs(getattr(phase, "b", getattr(phase, "xi", 0.0)))
        if g > MAX_LOBE_ASYMMETRY:
            raise LunarvizError(f"{name}: a Henyey-Greenstein lobe with b (or |xi|) = {g:g} is narrower than the "
                                f"Earth's disc seen from the Moon (1.9°); the methods' point or Gauss-rule "
                                f"Earth cannot resolve it: use b ≤ {MAX_LOBE_ASYMMETRY:g}")
    if scene.method == "analytic" and scene.times is None:
        thin = [t for t in scene.phases_deg if 0.0 < abs(180.0 - float(t)) < ANALYTIC_CRESCENT_LIMIT_DEG]
        if thin:
            raise LunarvizError(
                f"phase {thin[0]:g}: within {ANALYTIC_CRESCENT_LIMIT_DEG:g}° of new Moon the analytic method's "
                f"point Sun misses the thin crescent the extended Sun lights (at 179.9° it gives 0, the exact "
                f"reference 9.8e-15 W m-2); use --method raytrace or reference there")


def check_spectral(scene, models: dict) -> None:
    """Refuse what a spectral run cannot compute, before any work."""
    req = scene.spectral_request()
    if scene.stokes and scene.method == "reference":
        raise LunarvizError("--stokes needs --method analytic or raytrace and --wavelengths or --band (the exact "
                            "reference is grey)")
    if req is None:
        for name, value in (("solar_spectrum", scene.solar_spectrum), ("earth_spectra", scene.earth_spectra)):
            if value != BY_NAME[name].default:
                raise LunarvizError(f"{BY_NAME[name].cli_flag} {value} needs --wavelengths or --band (without them "
                                    f"the run is grey)")
        if scene.stokes:
            raise LunarvizError("--stokes needs --wavelengths or --band, and --method analytic or raytrace: the Moon's "
                                "polarisation depends on the wavelength (a grey run has none)")
        return
    if scene.method == "reference":
        raise LunarvizError("--wavelengths/--band need --method analytic or raytrace (the exact reference "
                            "is grey: a check of the paper's scene)")
    if scene.method == "raytrace" and not scene.earth_uniform and (
            scene.estimator == "montecarlo" or scene.mapped_earth != "facets"):
        raise LunarvizError("a spectral run with a mapped Earth (--earth-surface/--clouds) needs the "
                            "deterministic estimator")
    for k, b in models.items():
        if req.kind == "band":  # name the band that leaves the lunar table's range
            for label, row in zip(req.labels, req.weights):
                try:
                    parameters_at(scene.moon_model, k, req.nodes[row > 0], scene.params.get(k), grey_model=b)
                except LunarvizError as exc:
                    raise LunarvizError(f"band {label}: {exc}") from None
        parameters_at(scene.moon_model, k, req.nodes, scene.params.get(k), grey_model=b)


def check_physical_earth(scene) -> None:
    """``--param earth.NAME`` only with ``--earth-brdf physical``, which takes its classes' own
    albedos and spectra, not the Lambert Earth's options."""
    if "earth" in scene.params:
        earth_params(scene.params["earth"])
        if scene.earth_brdf != "physical":
            raise LunarvizError("earth parameters (--param earth.NAME=VALUE) need --earth-brdf physical")
        if "ground_albedo" in scene.params["earth"] and scene.earth_surface != "uniform":
            raise LunarvizError(f"earth.ground_albedo is the uniform Earth's ground: --earth-surface "
                                f"{scene.earth_surface} brings its own")
        if "wavelength_nm" in scene.params["earth"] and (scene.wavelengths or scene.bands):
            raise LunarvizError("earth.wavelength_nm is a grey run's wavelength: a spectral run takes each "
                                "of its own")
    if scene.earth_brdf == "physical" and scene.earth_albedo != BY_NAME["earth_albedo"].default:
        raise LunarvizError(f"--earth-albedo {scene.earth_albedo:g} is the Lambert Earth's albedo: the physical "
                            "Earth's comes from its air, clouds and ground; set the ground under the air with "
                            "--param earth.ground_albedo=A or --earth-surface landocean|FILE")
    if scene.earth_brdf == "physical" and scene.earth_spectra != BY_NAME["earth_spectra"].default:
        raise LunarvizError("--earth-spectra is the Lambert Earth's: --earth-brdf physical takes its classes' own")
    EarthSurface.from_options(scene)  # the Lambert Earth's albedos refused with the physical one
