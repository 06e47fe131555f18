"""Phase sweeps: one independent, picklable task per phase, mapped through an executor.

Every task computes the BRDF-independent transport once and shades every requested BRDF,
so a sweep over three BRDFs costs one trace per phase. Tasks run in local worker processes
(``workers``) so a distributed executor (e.g. Dask's ``Client.map``) can take the same
:func:`run_phase` calls when a study outgrows one machine.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.methods import accuracy
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import AnalyticSettings, DetectorIrradiance, analytic_irradiance
from lunarviz.methods.reference import ReferenceSettings, reference_irradiance
from lunarviz.options import BY_NAME, DEFAULT_LEVELS, GROUPS, compose, from_settings_dict, group, validate
from lunarviz.photometry import albedo_inversion as alb
from lunarviz.photometry.brdf import make_brdf

METHODS = ("analytic", "raytrace", "reference")
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


@dataclass(frozen=True)
@compose(*GROUPS)
class SweepSettings:
    """Everything needed to rerun a sweep (written to the output's ``settings``).

    Its fields are every option of :mod:`lunarviz.options` (the :class:`lunarviz.Scene`
    keywords) and the method's own settings below. :meth:`from_dict` rereads :meth:`to_dict`.
    """

    phases_deg: tuple = tuple(float(p) for p in range(0, 181, 5))
    method: str = "analytic"
    params: dict = field(default_factory=dict)  # {brdf: {name: value}}; the schema's None is {}
    #: the paper grid's step [deg] (``grid="paper"``)
    paper_step_deg: float = 1.0
    #: the exact reference's outer and inner Gauss orders
    reference_outer: int = 24
    reference_inner: int = 8
    #: UTC times (ISO 8601): when given, one task per time on the real sky, not per phase θ
    times: tuple | None = None
    #: ``facets`` (default) or ``beams``: see :class:`lunarviz.methods.tracer.estimators.TraceSettings`
    mapped_earth: str = "facets"

    def __post_init__(self):
        validate(self)
        if self.params is None:
            object.__setattr__(self, "params", {})
        if self.method not in METHODS:
            raise LunarvizError(f"unknown method {self.method!r}: choose from {', '.join(METHODS)}")
        if not self.phases_deg:
            raise LunarvizError("no phase given")
        if self.times is None and len(set(self.phases_deg)) != len(self.phases_deg):
            dup = next(p for p in self.phases_deg if list(self.phases_deg).count(p) > 1)
            raise LunarvizError(f"phase {dup:g} is listed twice")
        self._check_physical_earth()
        for b in self.params:
            if b != "earth" and b not in self.brdfs:
                raise LunarvizError(f"params name BRDF {b!r}, which is not in this run ({', '.join(self.brdfs)})")
        if self.times is not None:
            from lunarviz.sky.ephemeris import time_list
            if not self.times:
                raise LunarvizError("no time given")
            object.__setattr__(self, "times", time_list(",".join(self.times)))  # canonical labels, checked
            if len(set(self.times)) != len(self.times):
                dup = next(t for t in self.times if self.times.count(t) > 1)
                raise LunarvizError(f"time {dup} is listed twice")
            if self.detector is not None:
                raise LunarvizError("--detector places a detector in the θ scene; with --time use --observer")
        if self.detector is not None and self.times is None:
            for th in self.phases_deg:  # a detector inside the Sun or the Moon, before any work
                SceneGeometry(float(th), detector=self.detector)
        obs = self.observer_model()  # validates (reads a TLE file) before any work
        if obs.kind != "geocentre" and self.times is None:
            raise LunarvizError(f"--observer {self.observer} needs a date: give --time or --time-range")
        if obs.kind == "tle":
            age = max(abs(obs.epoch_age_days(t)) for t in (self.times[0], self.times[-1]))
            if age > TLE_MAX_AGE_DAYS:
                import warnings

                from lunarviz.errors import LunarvizWarning
                warnings.warn(f"TLE {self.observer!r} is propagated {age:.0f} days from its epoch; SGP4 errors grow "
                              f"to many km within weeks (rows carry tle_epoch_age_days)", LunarvizWarning,
                              stacklevel=2)
        if self.method != "raytrace":
            for value, default, flag in (
                    (self.mesh_units, "m", "--mesh-units"), (self.moon_level, None, "--mesh-level"),
                    (self.earth_level, None, "--earth-level"), (self.sun_level, None, "--sun-level"),
                    (self.shading, "auto", "--shading"), (self.self_shadow, True, "--no-self-shadow")):
                if value != default:
                    raise LunarvizError(f"{flag} cannot be used with --method {self.method}, which has no meshes; "
                                     f"use --method raytrace")
            for body in ("moon", "earth", "sun"):
                if getattr(self, f"{body}_mesh") is not None:
                    raise LunarvizError(f"--{body}-mesh cannot be used with --method {self.method}, which assumes "
                                     f"exact spheres; use --method raytrace")
        if self.times is not None and self.earth_rotation_deg is not None:
            raise LunarvizError("--earth-rotation-deg turns the Earth of the θ scene; on dates (--time) the "
                                "Earth turns with the date")
        if self.moon_albedo_map is None and self.moon_model != "paper":
            from lunarviz.photometry.presets import moon_model_map
            preset_map = moon_model_map(self.moon_model)  # a preset fitted on a mapped Moon brings its map
            if preset_map is not None:
                object.__setattr__(self, "moon_albedo_map", preset_map)
        if isinstance(self.moon_albedo_map, str) and self.moon_albedo_map.strip().lower() == "none":
            object.__setattr__(self, "moon_albedo_map", None)  # --moon-albedo-map none: no map, even a preset's
        models = self.brdf_models()  # validates parameters early
        self._check_validity(models)
        self._check_spectral(models)
        sf = self.surfaces()  # reads and checks the maps before any work
        if sf is not None and sf.moon_map is not None:
            sf.moon_map.check_brdfs(models)
            if self.h_function == "exact" and any(b != "lambert" for b in self.brdfs):
                raise LunarvizError(f"--h-function exact takes one w, not a per-facet map ({self.moon_albedo_map}, "
                                    f"from --moon-albedo-map or --moon-model {self.moon_model}): use hapke1981 or "
                                    f"hapke2002, or --moon-albedo-map none")
        if sf is not None and self.method == "reference":
            raise LunarvizError("--method reference integrates the paper's uniform bodies (a check, exact only "
                                "there): with surface maps use --method raytrace (or analytic)")
        if self.times is None and ((sf is not None and sf.moon_map is not None and self.moon_mesh is not None)
                                   or (not self.earth_uniform and self.earth_mesh is not None)):
            raise LunarvizError("a surface map on a user mesh needs a date (--time): in the θ scene a mesh keeps the "
                                "scene's axes while maps take the tidal/sub-solar frame")
        if not self.earth_uniform:
            from lunarviz.bodies.surfaces import EarthSurface
            EarthSurface(self.earth_surface, self.clouds).clear_map()  # the land mask, once, before workers
        ts = self.trace_settings()
        if self.method == "raytrace":  # read and check user meshes once, before any work
            for body in ("moon", "earth", "sun"):
                path = getattr(self, f"{body}_mesh")
                if path is not None:  # same arguments as TraceScene's call: the cached mesh is reused
                    from lunarviz.bodies.meshes import NOMINAL_RADII  # trimesh: only when a mesh is given
                    from lunarviz.methods.tracer.settings import body_mesh_m
                    body_mesh_m(body, getattr(ts, f"{body}_level"), path, self.mesh_units, NOMINAL_RADII[body])
        self.analytic_settings()

    def _check_validity(self, models: dict) -> None:
        """Refuse what the methods cannot compute correctly: lobes narrower than the Earth's disc,
        and the analytic method's point Sun next to new Moon."""
        for name, model in models.items():  # lobes the methods' source rules cannot resolve
            phase = getattr(model, "phase", None)
            g = abs(getattr(phase, "b", getattr(phase, "xi", 0.0)))
            if g > MAX_LOBE_ASYMMETRY:
                raise LunarvizError(f"{name}: a Henyey-Greenstein lobe with b (or |xi|) = {g:g} is narrower than the "
                                    f"Earth's disc seen from the Moon (1.9°); the methods' point or Gauss-rule "
                                    f"Earth cannot resolve it: use b ≤ {MAX_LOBE_ASYMMETRY:g}")
        if self.method == "analytic" and self.times is None:
            thin = [t for t in self.phases_deg if 0.0 < abs(180.0 - float(t)) < ANALYTIC_CRESCENT_LIMIT_DEG]
            if thin:
                raise LunarvizError(
                    f"phase {thin[0]:g}: within {ANALYTIC_CRESCENT_LIMIT_DEG:g}° of new Moon the analytic method's "
                    f"point Sun misses the thin crescent the extended Sun lights (at 179.9° it gives 0, the exact "
                    f"reference 9.8e-15 W m-2); use --method raytrace or reference there")

    def spectral_request(self):
        """The run's :class:`~lunarviz.spectral.request.SpectralRequest`, or ``None`` (grey)."""
        if self.wavelengths is None and self.bands is None:
            return None
        from lunarviz.spectral.request import spectral_request
        return spectral_request(self.wavelengths, self.bands, self.solar_spectrum)

    def _check_spectral(self, models: dict) -> None:
        """Refuse what a spectral run cannot compute, before any work."""
        req = self.spectral_request()
        if req is None:
            for name, value in (("solar_spectrum", self.solar_spectrum), ("earth_spectra", self.earth_spectra)):
                if value != BY_NAME[name].default:
                    raise LunarvizError(f"{BY_NAME[name].cli_flag} {value} needs --wavelengths or --band (without them "
                                        f"the run is grey)")
            return
        if self.method == "reference":
            raise LunarvizError("--wavelengths/--band need --method analytic or raytrace (the exact reference "
                                "is grey: a check of the paper's scene)")
        if self.method == "raytrace" and not self.earth_uniform and (
                self.estimator == "montecarlo" or self.mapped_earth != "facets"):
            raise LunarvizError("a spectral run with a mapped Earth (--earth-surface/--clouds) needs the "
                                "deterministic estimator")
        from lunarviz.spectral.moon import parameters_at
        for k, b in models.items():
            if req.kind == "band":  # name the band that leaves the lunar table's range
                for label, row in zip(req.labels, req.weights):
                    try:
                        parameters_at(self.moon_model, k, req.nodes[row > 0], self.params.get(k), grey_model=b)
                    except LunarvizError as exc:
                        raise LunarvizError(f"band {label}: {exc}") from None
            parameters_at(self.moon_model, k, req.nodes, self.params.get(k), grey_model=b)

    def _check_physical_earth(self) -> None:
        """``--param earth.NAME`` only with ``--earth-brdf physical``, which takes its classes' own
        albedos and spectra, not the Lambert Earth's options."""
        from lunarviz.bodies.surfaces import EarthSurface
        if "earth" in self.params:
            from lunarviz.earth_optics.surfaces import earth_params
            earth_params(self.params["earth"])
            if self.earth_brdf != "physical":
                raise LunarvizError("earth parameters (--param earth.NAME=VALUE) need --earth-brdf physical")
            if "wavelength_nm" in self.params["earth"] and (self.wavelengths or self.bands):
                raise LunarvizError("earth.wavelength_nm is a grey run's wavelength: a spectral run takes each "
                                    "of its own")
        if self.earth_brdf == "physical" and self.earth_spectra != BY_NAME["earth_spectra"].default:
            raise LunarvizError("--earth-spectra is the Lambert Earth's: --earth-brdf physical takes its classes' own")
        EarthSurface.from_options(self)  # the Lambert Earth's albedos refused with the physical one

    def brdf_models(self) -> dict:
        return {b: make_brdf(b, dhg_convention=self.dhg_convention, h_function=self.h_function,
                             params=self.params.get(b, {}), moon_model=self.moon_model) for b in self.brdfs}

    def surfaces(self, model_earth: bool = False):
        """The scene's :class:`~lunarviz.bodies.surfaces.Surfaces`; ``model_earth``: with the uniform
        Earth of ``earth_albedo`` (what an inversion assumes), the lunar map kept; ``None`` when
        both are the paper's."""
        from lunarviz.bodies.surfaces import EarthSurface, MoonAlbedoMap, Surfaces
        earth = EarthSurface(albedo=self.earth_albedo) if model_earth else EarthSurface.from_options(self)
        moon = None if self.moon_albedo_map is None else MoonAlbedoMap.parse(self.moon_albedo_map)
        if moon is None and earth.uniform:
            return None
        return Surfaces(moon, earth, self.earth_rotation_deg or 0.0)

    @property
    def earth_uniform(self) -> bool:
        """One Lambert albedo over the whole Earth (the paper's)."""
        return self.earth_surface == "uniform" and self.clouds == "none" and self.earth_brdf == "lambert"

    def _mapped_moon(self) -> bool:
        """A lunar map with any contrast (a uniform map is the scalar)."""
        if self.moon_albedo_map in (None, "none"):
            return False
        from lunarviz.bodies.surfaces import MoonAlbedoMap
        return bool(np.ptp(MoonAlbedoMap.parse(self.moon_albedo_map).values()) > 0)

    def analytic_settings(self, model_earth: bool = False) -> AnalyticSettings:
        order = self.order
        if order is None:  # from the tolerance; 96 for a lunar map (no model: its nodes read the map)
            order = 96 if self._mapped_moon() else accuracy.analytic_choice(self.rtol_or_default)[0]
        return AnalyticSettings(grid=self.grid, order=order, paper_step_deg=self.paper_step_deg,
                                earth_law=self.earth_law, earth_albedo=self.earth_albedo,
                                surfaces=self.surfaces(model_earth))

    def reference_orders(self) -> tuple[int, int, float]:
        """The exact reference's (outer, inner) orders and the bound they meet: from the
        tolerance when one is given, else :attr:`reference_outer`, :attr:`reference_inner`."""
        if self.rtol is not None:
            return accuracy.reference_choice(self.rtol)
        row = next((r for r in accuracy.error_models()["reference"]
                    if (r["outer"], r["inner"]) == (self.reference_outer, self.reference_inner)), None)
        bound = math.nan if row is None else accuracy.SAFETY * max(row["moonshine"], row["earthshine"])
        return self.reference_outer, self.reference_inner, bound

    @property
    def rtol_or_default(self) -> float:
        """The tolerance asked for, or the method's default (:data:`accuracy.DEFAULT_RTOL`)."""
        return self.rtol if self.rtol is not None else accuracy.DEFAULT_RTOL.get(self.method, 1e-4)

    def trace_plan(self, theta: float | None = None) -> dict:
        """What the tolerance chooses for the ray tracer: ``settings`` (the options left unset,
        and ``lune_order``) and ``bounds`` ({(sample kind, path): bound},
        :func:`lunarviz.methods.accuracy.trace_choice`). Monte Carlo: the rays, where a tolerance
        is given and the rays are not. No model: a user's Moon mesh, a mapped or physical Earth
        (bounds empty; an explicit tolerance is refused for a user's Moon mesh). ``theta`` [deg]:
        the task's θ, where a model was measured phase by phase (the mapped lune rule's)."""
        none = {"settings": {}, "bounds": {}}
        if self.method != "raytrace":
            return none
        if self.estimator == "montecarlo":
            if self.rays is None and self.rtol is not None:
                return {"settings": {"rays": accuracy.montecarlo_rays(self.rtol, self.runs)}, "bounds": {}}
            return none
        if self.moon_mesh is not None:
            if self.rtol is not None:
                raise LunarvizError(f"--rtol {self.rtol:g}: the error models cover the packaged Moon, not a user's "
                                    "Moon mesh (its facets are the model): give --sun-order and --earth-order")
            return none
        fixed = {k: getattr(self, k) for k in ("moon_level", "sun_order", "earth_order")
                 if getattr(self, k) is not None}
        asked_level = "moon_level" in fixed
        if self.rtol is None:  # without a tolerance the facets keep the former default, level 4 (8.7e-5
            fixed.setdefault("moon_level", DEFAULT_LEVELS["moon"])  # measured; the rows report 2x that)
            if asked_level:  # a mesh level asked for without a tolerance: the former default orders too
                from lunarviz.methods.tracer.settings import DEFAULT_ORDERS
                fixed.setdefault("sun_order", DEFAULT_ORDERS["sun"])
                fixed.setdefault("earth_order", DEFAULT_ORDERS["earth"])
        choice = accuracy.trace_choice(self.rtol_or_default, fixed, self._mapped_moon(), theta)
        settings = {k: choice.get(k) for k in ("moon_level", "sun_order", "earth_order")
                    if k not in fixed and choice.get(k) is not None}
        # an explicit mesh level asks for the facets (mesh studies), and so does a rough BRDF (Hapke's
        # roughness changes form where i = e, a kink inside the lune); otherwise the lune rule where it applies
        # (a mapped Moon's lune rule was measured with rolo-fit-map's rough presets)
        rough = any(getattr(m, "rough", False) for m in self.brdf_models().values())
        settings["lune_order"] = None if asked_level or rough and not self._mapped_moon() else choice.get("lune_order")
        if settings["lune_order"] is not None and choice.get("lune_source_orders") is not None:
            settings["lune_source_orders"] = choice["lune_source_orders"]
        return {"settings": settings, "bounds": choice.get("bounds", {}) if self.modelled() else {}}

    def modelled(self) -> bool:
        """Whether the error models hold for this run's bodies and photometry: they were measured
        with the paper's BRDF presets (rolo-fit-map's on its own map, for the mapped Moon), no
        parameter overrides, the uniform Lambert Earth and the packaged spheres shaded exactly."""
        lunar_params = any(v for b, v in self.params.items() if b != "earth")
        if self._mapped_moon():  # the mapped model is rolo-fit-map's, on its own map
            from lunarviz.photometry.presets import moon_model_map
            moon = self.moon_model == "rolo-fit-map" and self.moon_albedo_map == moon_model_map("rolo-fit-map")
        else:
            moon = self.moon_model == "paper"
        return moon and not lunar_params and self.earth_uniform and self.earth_brdf == "lambert" \
            and self.earth_mesh is None and self.sun_mesh is None and self.moon_mesh is None and self.shading == "auto"

    def warn_unmet_tolerance(self) -> None:
        """Warn once, before a ray-traced run, when the tolerance asked for is beyond what the
        error models hold (the most accurate setting runs; its rows report what it meets)."""
        if self.rtol is None:
            return
        self._warn_earthshine_off_centre()
        if self.method in ("analytic", "reference"):
            met = accuracy.analytic_choice(self.rtol)[1] if self.method == "analytic" else self.reference_orders()[2]
            if not met <= self.rtol:
                import warnings

                from lunarviz.errors import LunarvizWarning
                warnings.warn(f"--rtol {self.rtol:g} is beyond the {self.method} method's error model: its most "
                              f"accurate orders meet {met:.1e} (rows report it)", LunarvizWarning, stacklevel=3)
            return
        if self.method != "raytrace" or self.estimator != "deterministic":
            return
        plan = self.trace_plan()
        kinds = ("facets",) if plan["settings"].get("lune_order") is None else ("lune",)
        met = [plan["bounds"].get((k, p), math.nan) for k in kinds for p in ("moonshine", "earthshine")]
        if plan["bounds"] and not max(met) <= self.rtol:
            import warnings

            from lunarviz.errors import LunarvizWarning
            warnings.warn(f"--rtol {self.rtol:g} is beyond the error models here: the most accurate setting they "
                          f"hold meets {max(met):.1e} (rows report it)", LunarvizWarning, stacklevel=3)

    def _warn_earthshine_off_centre(self) -> None:
        """Warn where the tolerance cannot be met: the earthshine of a BRDF with an opposition
        surge or roughness seen off the Earth's centre by an extended Earth's beam rules (the
        deterministic tracer's, the reference's; :func:`accuracy.earth_source_modelled`)."""
        off_centre = self.detector is not None or (self.times is not None and self.observer_model().kind != "geocentre")
        surged = [k for k, b in self.brdf_models().items() if accuracy.peaks_at_zero_phase(b)]
        if accuracy.extended_earth(self.method, self.estimator) and off_centre and surged:
            import warnings

            from lunarviz.errors import LunarvizWarning
            warnings.warn(f"--rtol {self.rtol:g} is not met by the earthshine of {', '.join(surged)} seen off the "
                          "Earth's centre (the opposition surge's cusp and the roughness's kink lie off the pole "
                          "of the Earth's beam rules: up to ~5e-3 measured from orbit); those rows carry no bound",
                          LunarvizWarning, stacklevel=4)

    def trace_settings(self, threads: int | None = None, plan: dict | None = None):
        """The tracer's settings; ``threads`` per trace (``None``: the machine's cores; sweeps
        over several worker processes pass 1). Results do not depend on it. The tolerance's
        choices (``plan``, :meth:`trace_plan` if not given) fill the options left unset."""
        from lunarviz.methods.tracer.settings import TraceSettings
        kw = {o.name: getattr(self, o.name) for o in group(*TraceSettings.GROUPS)}
        kw.update((self.trace_plan() if plan is None else plan)["settings"])
        return TraceSettings(threads=threads, mapped_earth=self.mapped_earth,
                             earth_params=tuple(sorted(self.params.get("earth", {}).items())), **kw)

    def observer_model(self):
        """The parsed observer (an orbit's epoch defaults to the first time)."""
        from lunarviz.sky.observers import parse_observer
        obs = parse_observer(self.observer)
        return obs.with_epoch(self.times[0]) if self.times else obs

    def tasks(self) -> list:
        """One key per independent task: UTC labels with ``times``, else the phases θ [deg]."""
        return list(self.times) if self.times is not None else [float(p) for p in self.phases_deg]

    def scene(self, key) -> SceneGeometry:
        return self.scene_and_fields(key)[0]

    def scene_and_fields(self, key) -> tuple[SceneGeometry, dict]:
        """The scene of one task and the geometry fields its rows start with."""
        if self.times is not None:
            from lunarviz.sky.dated_scene import sky_scene
            return sky_scene(str(key), self.observer_model())
        sc = SceneGeometry(float(key), detector=self.detector)
        return sc, {"theta_deg": float(key)}

    @classmethod
    def from_dict(cls, d: dict) -> "SweepSettings":
        """The settings a :meth:`to_dict` (an output's ``settings``, a Dataset's
        ``attrs["settings_json"]``) describes."""
        return from_settings_dict(cls, d)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["brdfs"] = list(self.brdfs)
        d["phases_deg"] = list(self.phases_deg)
        if self.times is not None:
            d["times"] = list(self.times)
            d.pop("phases_deg")
        return d


def run_phase(settings: SweepSettings, key, threads: int | None = None) -> list[dict]:
    """All rows (one per BRDF) for one task: a phase θ [deg], or a UTC time with ``times``.
    Pure function of its arguments (``threads``, the trace's threads, changes no number)."""
    sc, fields = settings.scene_and_fields(key)
    base = {**fields, "alpha_deg": sc.alpha_deg, "beta_deg": sc.beta_deg}
    t0 = time.perf_counter()
    if settings.spectral_request() is not None:
        from lunarviz.workflows.spectral_phase import spectral_rows
        return spectral_rows(settings, sc, base, threads)
    brdfs = settings.brdf_models()
    rows = []
    # point-source calibration (lunar terms of Eq. 15, and the point-vs-extended comparison):
    # converged grid, correct Lambert-sphere Earth law
    # (an inversion assumes a uniform Earth of earth_albedo: a mapped Earth never calibrates its
    # own inversion; the lunar map, which an observer knows, stays)
    a0 = settings.earth_albedo
    uniform = settings.earth_uniform

    def model_es(es, es_unit):
        """Earthshine of the model Earth (uniform albedo a0) on the same transport."""
        return es if uniform else a0 * es_unit
    cal_settings = replace(settings.analytic_settings(), grid="converged", earth_law="lambert")
    point = None if settings.method == "raytrace" else analytic_irradiance(sc, brdfs, cal_settings)
    if settings.method == "analytic":
        res = point if settings.analytic_settings() == cal_settings else \
            analytic_irradiance(sc, brdfs, settings.analytic_settings())
        bound = math.nan if settings._mapped_moon() or not settings.modelled() else \
            accuracy.analytic_bound(settings.analytic_settings().order)
        for k, v in res.items():
            cal = point[k]
            rows.append({**base, "brdf": k, "method": "analytic",
                         "moonshine_W_m2": v.moonshine_W_m2, "earthshine_W_m2": v.earthshine_W_m2,
                         "earth_visible_lit_albedo": v.earth_visible_lit_albedo,
                         "_terms": alb.lunar_terms(sc, model_es(cal.earthshine_W_m2, cal.earthshine_unit_W_m2),
                                                   cal.moonshine_W_m2, a0)})
    elif settings.method == "reference":
        outer, inner, bound = settings.reference_orders()
        bound = bound if settings.modelled() else math.nan
        res = reference_irradiance(sc, brdfs, ReferenceSettings(outer, inner, settings.earth_albedo,
                                                                surfaces=settings.surfaces()))
        for k, v in res.items():
            pt = point[k]
            rows.append({**base, "brdf": k, "method": "reference",
                         "moonshine_W_m2": v.moonshine_W_m2, "earthshine_W_m2": v.earthshine_W_m2,
                         "earth_visible_lit_albedo": v.earth_visible_lit_albedo,
                         "earthshine_point_source_W_m2": pt.earthshine_W_m2,
                         "_terms": alb.lunar_terms(sc, model_es(v.earthshine_W_m2, v.earthshine_unit_W_m2),
                                                   v.moonshine_W_m2, a0),
                         "_terms_point": alb.lunar_terms(sc, model_es(pt.earthshine_W_m2, pt.earthshine_unit_W_m2),
                                                         pt.moonshine_W_m2, a0)})
    else:
        rows, bound = _traced_rows(settings, sc, base, brdfs, cal_settings, model_es, threads)
    dt = time.perf_counter() - t0
    for r in rows:
        es_, ms_ = r["earthshine_W_m2"], r["moonshine_W_m2"]
        # a ratio of round-off (no measurable sunlit Moon: new Moon, eclipse, occultation) is no ratio
        measurable = ms_ > 0 and alb.lunar_terms(sc, 0.0, ms_, settings.earth_albedo).pb_fb > alb.MIN_LUNAR_TERM
        r["ratio_earthshine_moonshine"] = es_ / ms_ if measurable else float("nan")
        pe = alb.geometric_albedo_term(sc, es_, ms_, r.pop("_terms"))
        r["geometric_albedo_term"] = pe
        r["apparent_albedo"] = alb.apparent_albedo(sc.beta_deg, pe)
        if "_terms_point" in r:
            pp = alb.geometric_albedo_term(sc, es_, ms_, r.pop("_terms_point"))
            r["apparent_albedo_point_source_inversion"] = alb.apparent_albedo(sc.beta_deg, pp)
            pt_es = r["earthshine_point_source_W_m2"]
            pt_terms = alb.lunar_terms(sc, pt_es, ms_, settings.earth_albedo)
            r["extended_over_point_earthshine"] = es_ / pt_es \
                if pt_es > 0 and pt_terms.pa_fa > alb.MIN_LUNAR_TERM else float("nan")
        r["seconds"] = dt / len(rows)
        r["rtol"] = accuracy.row_bound(bound, sc, settings.method, settings.estimator, brdfs[r["brdf"]])
    return rows


def _traced_rows(settings: SweepSettings, sc, base: dict, brdfs: dict, cal_settings, model_es, threads):
    """The ray tracer's rows of one task (before the inversion's fields) and their bound. The
    point-source calibration (``cal_settings``) runs on the mapped lune rule the trace used where it
    used one (:meth:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling.mapped_rule_used`: the
    map's cells exact in its weights), else on the analytic grid."""
    from lunarviz.methods.tracer.estimators import PathResult, TraceScene, trace_path
    a0 = settings.earth_albedo
    rows = []
    plan = settings.trace_plan(sc.theta_deg)  # once per task: the settings and the bounds both come from it
    ts_set = settings.trace_settings(threads, plan)
    if hidden_moon(settings, ts_set, sc):  # nothing of the Moon reaches the detector: nothing to trace
        ts, ms, es, bound = None, PathResult.zero(brdfs), PathResult.zero(brdfs), 0.0
    else:
        ts = TraceScene(sc, ts_set)
        ms = trace_path(ts, "moonshine", brdfs)
        es = trace_path(ts, "earthshine", brdfs)
        bound = accuracy.traced_bound(plan["bounds"], ts, ms, es)
    if ts is None:  # (the Moon wholly hidden: the point sources' sight lines are blocked too)
        point = {k: DetectorIrradiance(0.0, 0.0, 0.0) for k in brdfs}
    else:
        rules = {b: r for b in ("sun", "earth") if (r := ts.mapped_rule_used(b)) is not None}
        point = analytic_irradiance(sc, brdfs, cal_settings, rules=rules)
    if ts_set.estimator == "deterministic" and ts_set.earth_mesh is None:
        cal_ms = ms.mean
        cal_es = {k: model_es(es.mean[k], es.mean_unit[k]) for k in brdfs}
    else:
        # lunar terms from a deterministic transport of the same scene with the *model*
        # Earth (the nominal Lambert sphere): the Earth is what the inversion measures, so a
        # user's Earth mesh must not calibrate its own inversion (that is an identity)
        dts = TraceScene(sc, accuracy.calibration_settings(ts_set, settings.moon_level is not None,
                                                           settings._mapped_moon()))
        cal_ms = trace_path(dts, "moonshine", brdfs).mean
        cal_es = trace_path(dts, "earthshine", brdfs).mean
    for k in brdfs:
        row = {**base, "brdf": k, "method": "raytrace", "estimator": ts_set.estimator,
               "moonshine_W_m2": ms.mean[k], "earthshine_W_m2": es.mean[k],
               "earth_visible_lit_albedo": es.mean[k] / es.mean_unit[k] if es.mean_unit[k] else float("nan"),
               "earthshine_point_source_W_m2": point[k].earthshine_W_m2,
               "_terms": alb.lunar_terms(sc, cal_es[k], cal_ms[k], settings.earth_albedo),
               "_terms_point": alb.lunar_terms(sc, model_es(point[k].earthshine_W_m2,
                                                            point[k].earthshine_unit_W_m2),
                                               point[k].moonshine_W_m2, a0),
               "rays": ms.rays + es.rays}
        if ts_set.estimator == "montecarlo":
            row["moonshine_std_W_m2"] = ms.std[k]
            row["earthshine_std_W_m2"] = es.std[k]
            row["moonshine_sem_W_m2"] = ms.sem[k]
            row["earthshine_sem_W_m2"] = es.sem[k]
            row["runs"] = ts_set.runs
            row["rays_per_run"] = ts_set.rays
        rows.append(row)
    return rows, bound


def hidden_moon(settings: SweepSettings, ts_set, sc: SceneGeometry) -> bool:
    """A date whose whole Moon the observer's Earth (the packaged sphere, level ≥ 3) or horizon
    hides (:meth:`SceneGeometry.moon_wholly_hidden`): its rows are zeros without a trace (a third
    of the dates from a low orbit)."""
    return settings.times is not None and ts_set.earth_mesh is None and ts_set.earth_level >= 3 \
        and sc.moon_wholly_hidden()


def _run_phase_star(args):
    return run_phase(*args, threads=1)  # one of several worker processes: one thread each


def bond_table(rows: list[dict], key: str = "apparent_albedo") -> dict:
    """``{brdf: {method: Bond albedo}}`` from rows' apparent albedo (corrected Eq. 17)."""
    out: dict = {}
    groups: dict = {}
    for r in rows:
        if key in r:
            groups.setdefault((r["brdf"], r["method"], spectral_label(r)), []).append(r)
    for (b, m, lab), rs in groups.items():
        beta = np.array([r["beta_deg"] for r in rs])
        ps = np.array([np.nan if r[key] is None else r[key] for r in rs], dtype=float)
        if lab is None:
            out.setdefault(b, {})[m] = alb.bond_albedo(beta, ps)
        else:  # a spectral run: one per wavelength or band
            out.setdefault(b, {}).setdefault(m, {})[lab] = alb.bond_albedo(beta, ps)
    return out


def spectral_label(row: dict) -> str | None:
    """A spectral row's wavelength (as text, e.g. ``"550"``, 12 significant digits) or band name;
    ``None`` for a grey row."""
    if "wavelength_nm" in row:
        from lunarviz.spectral.request import wavelength_label
        return wavelength_label(row["wavelength_nm"])
    return row.get("band")


EXECUTORS = ("local", "dask")


def worker_count(requested: int | None, tasks: int, method: str = "raytrace") -> int:
    """Worker processes actually started: at most one per task and one per core (``requested``
    is an upper bound, never a count to fork blindly; ``None``: one per core, or one for the
    analytic method, whose tasks take milliseconds)."""
    cores = os.cpu_count() or 1
    if requested is None:
        return 1 if method == "analytic" else max(1, min(tasks, cores))
    return max(1, min(int(requested), tasks, cores))


def dask_client(scheduler: str | None, workers: int | None):
    """A Dask client: to ``scheduler`` (an address such as tcp://host:8786), or to a new local
    cluster of ``workers`` single-threaded processes (closed with the client)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise LunarvizError("--executor dask needs the optional packages dask and distributed: "
                            "pip install 'lunarviz[dask]'") from None
    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:
            raise LunarvizError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    cluster = LocalCluster(n_workers=min(workers or os.cpu_count() or 1, os.cpu_count() or 1), threads_per_worker=1,
                           processes=True, dashboard_address=None)
    return Client(cluster), cluster


def run_sweep(settings: SweepSettings, workers: int | None = None, progress: bool = False,
              executor: str = "local", scheduler: str | None = None) -> dict:
    """Run every phase or time; returns ``{"settings", "rows", "bond_albedo", ...}``.

    ``executor="local"``: worker processes of this machine (``workers``). ``"dask"``: the same
    :func:`run_phase` tasks on a Dask distributed cluster (``scheduler`` address, or a local
    cluster of ``workers``). Tasks carry only the settings and the key; each worker builds its
    Embree scenes itself and caches them (``tracer.bodies``), nothing Embree is pickled. The
    rows are identical whichever executor runs them.
    """
    if executor not in EXECUTORS:
        raise LunarvizError(f"unknown executor {executor!r}: choose from {', '.join(EXECUTORS)}")
    if scheduler is not None and executor != "dask":
        raise LunarvizError("--scheduler goes with --executor dask")
    phases = settings.tasks()
    settings.warn_unmet_tolerance()
    t0 = time.perf_counter()
    if executor == "dask":
        client, cluster = dask_client(scheduler, None if workers is None else min(workers, len(phases)))
        try:
            futures = client.map(run_phase, [settings] * len(phases), phases, threads=1, pure=False)
            results = client.gather(futures)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
        return _assemble(settings, results, t0)
    workers = worker_count(workers, len(phases), settings.method)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(phases), desc=f"{settings.method} sweep", unit="time" if settings.times else "phase",
                   leave=False)
    results = []
    if workers <= 1:
        for th in phases:
            results.append(run_phase(settings, th))
            if bar:
                bar.update()
    else:
        _warm_before_fork(settings)
        # the costliest phases first (thin crescents, θ near 180°, refine their lune) so that no
        # worker is left with one at the end; rows come back in the sweep's order
        order = list(range(len(phases)))
        if not settings.times:
            order.sort(key=lambda i: abs(float(phases[i]) - 180.0))  # (θ in [0, 360]: both crescents)
        results = [None] * len(phases)
        ex = ProcessPoolExecutor(workers, initializer=_worker_init)
        # dates go to the workers in runs of consecutive times (one message per run, and each
        # worker's caches serve neighbouring dates); phases one by one, costliest first
        chunk = 1 if not settings.times else max(1, min(32, len(phases) // (workers * 8)))
        try:
            for i, res in zip(order, ex.map(_run_phase_star, [(settings, phases[i]) for i in order], chunksize=chunk)):
                results[i] = res
                if bar:
                    bar.update()
        except BaseException:  # an error, Ctrl-C or SIGTERM: end the workers now, not after their tasks
            _quiet_pool_teardown()
            ex.shutdown(wait=False, cancel_futures=True)
            for proc in multiprocessing.active_children():
                proc.terminate()
            raise
        ex.shutdown(wait=True)
    if bar:
        bar.close()
    return _assemble(settings, results, t0)


def _quiet_pool_teardown() -> None:
    """Ending a pool whose futures were just cancelled races the pool's manager thread, which
    may then set an exception on a cancelled future and print InvalidStateError's traceback
    (CPython's concurrent.futures, fixed in later versions): that thread's report is dropped, so
    an interrupted run still ends in one line."""
    import threading
    from concurrent.futures import InvalidStateError
    previous = threading.excepthook

    def hook(args):
        if not issubclass(args.exc_type, InvalidStateError):
            previous(args)
    threading.excepthook = hook


def _worker_init() -> None:
    """In a worker: SIGTERM ends it at once, silently (the parent ends its workers that way), and
    BLAS runs on one thread: each worker is one of ``cpu_count`` single-threaded processes, and
    OpenBLAS's own threads (one per core by default) fought the other workers for the cores (a
    mapped Moon's dates, whose weights are GEMMs: 1.47 s a date on 2 workers, 0.94 s with one
    BLAS thread each; ``benchmarks/speed``)."""
    import signal
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    from threadpoolctl import threadpool_limits
    threadpool_limits(1)


def _warm_before_fork(settings: SweepSettings) -> None:
    """Import the tracer and load the compiled kernels in this process before the worker
    pool starts: forked workers inherit both instead of each paying ~1.5 s for them (a third
    of a 2-worker paper sweep's start-up; no Embree object is made here, so nothing
    thread-bound crosses the fork). Harmless where workers are spawned instead."""
    if settings.method != "raytrace":
        return
    from lunarviz.methods.tracer import estimators, ray_kernels  # noqa: F401 (the import is the warm-up)
    ray_kernels.warm_up()


def _assemble(settings: SweepSettings, results: list, t0: float) -> dict:
    rows = [r for res in results for r in res]
    out = {"settings": settings.to_dict(), "rows": rows, "bond_albedo": bond_table(rows),
           "wall_seconds": time.perf_counter() - t0}
    if any("apparent_albedo_point_source_inversion" in r for r in rows):
        out["bond_albedo_point_source_inversion"] = bond_table(rows, "apparent_albedo_point_source_inversion")
    return out
