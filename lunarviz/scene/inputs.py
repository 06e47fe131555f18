"""The typed inputs a resolved scene gives the methods: each layer below takes only its own.

The functions take a :class:`~lunarviz.scene.resolved.ResolvedScene` and are its methods
(``scene.brdf_models()``, ``scene.trace_settings()``, ...): the BRDF models (photometry), the
spectral request and inputs (spectral), the surfaces and the Earth model (surfaces), the
analytic, reference and tracer settings (methods) and one task's geometry (geometry and sky).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods import accuracy
from lunarviz.methods.analytic import AnalyticSettings
from lunarviz.methods.reference import ReferenceSettings
from lunarviz.methods.tracer.settings import TraceSettings
from lunarviz.options import group
from lunarviz.photometry.brdf import make_brdf
from lunarviz.sky.dated_scene import sky_scene
from lunarviz.sky.observers import parse_observer
from lunarviz.spectral.request import spectral_request as make_request
from lunarviz.spectral.shading_inputs import SpectralInputs
from lunarviz.surfaces.earth_surface import EarthSurface
from lunarviz.surfaces.moon_map import MoonAlbedoMap
from lunarviz.surfaces.point_values import Surfaces


def brdf_models(scene) -> dict:
    """``{name: BRDF}``: the scene's lunar BRDFs with its preset, conventions and overrides."""
    return {b: make_brdf(b, dhg_convention=scene.dhg_convention, h_function=scene.h_function,
                         params=scene.params.get(b, {}), moon_model=scene.moon_model) for b in scene.brdfs}


def spectral_request(scene):
    """The run's :class:`~lunarviz.spectral.request.SpectralRequest`, or ``None`` (grey)."""
    if scene.wavelengths is None and scene.bands is None:
        return None
    return make_request(scene.wavelengths, scene.bands, scene.solar_spectrum)


def spectral_inputs(scene, request=None):
    """The :class:`~lunarviz.spectral.shading_inputs.SpectralInputs` of a spectral run (``request``: one
    that replaces the scene's wavelengths or bands, e.g. an instrument's photon-counting
    response), or ``None`` for a grey run."""
    request = scene.spectral_request() if request is None else request
    if request is None:
        return None
    return SpectralInputs(request, scene.moon_model, dict(scene.params), scene.earth_spectra)


def earth_model(scene, model_earth: bool = False):
    """The Earth model (:class:`~lunarviz.surfaces.earth_surface.EarthSurface`); ``model_earth``:
    the uniform Lambert Earth of ``earth_albedo`` that an inversion assumes."""
    return EarthSurface(earth_albedo=scene.earth_albedo) if model_earth else EarthSurface.from_options(scene)


def surfaces(scene, model_earth: bool = False):
    """The scene's :class:`~lunarviz.surfaces.point_values.Surfaces` for the quadrature methods;
    ``model_earth``: with the uniform Earth of ``earth_albedo`` (what an inversion assumes), the
    lunar map kept; ``None`` when both are the paper's."""
    earth = scene.earth_model(model_earth)
    moon = None if scene.moon_albedo_map is None else MoonAlbedoMap.parse(scene.moon_albedo_map)
    if moon is None and earth.uniform:
        return None
    return Surfaces(moon, earth, scene.earth_rotation_deg or 0.0)


def mapped_moon(scene) -> bool:
    """A lunar map with any contrast (a uniform map is the scalar)."""
    if scene.moon_albedo_map in (None, "none"):
        return False
    return bool(np.ptp(MoonAlbedoMap.parse(scene.moon_albedo_map).values()) > 0)


def analytic_settings(scene, model_earth: bool = False) -> AnalyticSettings:
    """The analytic method's settings: the order from ``order``, else from the tolerance (96 with a
    lunar map, whose nodes read the map: no error model)."""
    order = scene.order
    if order is None:
        order = 96 if scene.mapped_moon() else accuracy.analytic_choice(scene.rtol_or_default)[0]
    return AnalyticSettings(grid=scene.grid, order=order, paper_step_deg=scene.paper_step_deg,
                            earth_law=scene.earth_law, earth_albedo=scene.earth_albedo,
                            surfaces=scene.surfaces(model_earth))


def point_calibration_settings(scene) -> AnalyticSettings:
    """The point-source calibration's analytic settings (the lunar terms of Eq. 15, and the
    point-against-extended comparison): the scene's, on the converged grid with the correct
    Lambert-sphere Earth law."""
    return replace(scene.analytic_settings(), grid="converged", earth_law="lambert")


def reference_settings(scene) -> ReferenceSettings:
    """The exact reference's settings at the orders :func:`~lunarviz.scene.tolerance.reference_orders`
    chooses."""
    outer, inner, _ = scene.reference_orders()
    return ReferenceSettings(outer, inner, scene.earth_albedo, surfaces=scene.surfaces(),
                             earth_pole=scene.reference_earth_pole())


def trace_settings(scene, threads: int | None = None, plan: dict | None = None):
    """The tracer's :class:`~lunarviz.methods.tracer.settings.TraceSettings`; ``threads`` per trace
    (``None``: the machine's cores; sweeps over several worker processes pass 1). Results do not
    depend on it. The tolerance's choices (``plan``, :func:`~lunarviz.scene.tolerance.trace_plan`
    if not given) fill the options left unset."""
    kw = {o.name: getattr(scene, o.name) for o in group(*TraceSettings.GROUPS)}
    kw.update((scene.trace_plan() if plan is None else plan)["settings"])
    return TraceSettings(threads=threads, mapped_earth=scene.mapped_earth,
                         earth_params=tuple(sorted(scene.params.get("earth", {}).items())), **kw)


def observer_model(scene):
    """The parsed observer (an orbit's epoch defaults to the first time)."""
    obs = parse_observer(scene.observer)
    return obs.with_epoch(scene.times[0]) if scene.times else obs


def task(scene, key) -> tuple[SceneGeometry, dict]:
    """The geometry of one task (a phase θ [deg], or a UTC time of a dated scene) and the fields its
    rows start with (θ; or the time, distances, sub-points and flags of the real sky)."""
    if scene.times is not None:
        return sky_scene(str(key), scene.observer_model())
    sc = SceneGeometry(float(key), detector=scene.detector)
    return sc, {"theta_deg": float(key)}


def geometry(scene, key) -> SceneGeometry:
    """The :class:`~lunarviz.geometry.scene_geometry.SceneGeometry` of one task (:func:`task`)."""
    return scene.task(key)[0]
