"""What a tolerance chooses: the orders and mesh levels that meet ``--rtol`` at least cost, the
bounds rows report, and the warnings when a tolerance is beyond what the error models hold.

The functions take a :class:`~lunarviz.scene.resolved.ResolvedScene` and are its methods; the
error models themselves and their choices are :mod:`lunarviz.methods.accuracy`.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from lunarviz.errors import LooseRowsWarning, LunarvizError, LunarvizWarning, UnboundedRowsWarning
from lunarviz.methods import accuracy
from lunarviz.options import DEFAULT_LEVELS, DEFAULT_ORDERS
from lunarviz.photometry.presets import moon_model_map
from lunarviz.scene import inputs
from lunarviz.surfaces.earth_spectra import weights_toward
from lunarviz.surfaces.earth_surface import CLOUDS, EARTH_SURFACES


def rtol_or_default(scene) -> float:
    """The tolerance asked for, or the method's default (:data:`lunarviz.methods.accuracy.DEFAULT_RTOL`)."""
    return scene.rtol if scene.rtol is not None else accuracy.DEFAULT_RTOL.get(scene.method, 1e-4)


def reference_orders(scene) -> tuple[int, int, float]:
    """The exact reference's (outer, inner) orders and the bound they meet: from the
    tolerance when one is given, else ``reference_outer``, ``reference_inner``. Off the Earth's
    centre with a Hapke BRDF (:func:`earth_pole_at_zero_phase`) the inner order is at least the
    one whose zero-phase rule error, cut along the kinks (:func:`reference_earth_pole`,
    :func:`lunarviz.methods.accuracy.off_centre_earth_error`), fits half the tolerance (the most
    accurate measured where none does), and the bound adds it."""
    if scene.rtol is not None:
        outer, inner, bound = accuracy.reference_choice(scene.rtol)
    else:
        outer, inner = scene.reference_outer, scene.reference_inner
        row = next((r for r in accuracy.error_models()["reference"]
                    if (r["outer"], r["inner"]) == (outer, inner)), None)
        bound = math.nan if row is None else accuracy.SAFETY * max(row["moonshine"], row["earthshine"])
    if earth_pole_at_zero_phase(scene):
        mapped = scene.mapped_moon()
        inner = max(inner, accuracy.off_centre_earth_order(scene.rtol_or_default / 2 / accuracy.SAFETY, mapped,
                                                           cut=True))
        bound = bound + accuracy.SAFETY * accuracy.off_centre_earth_error(inner, mapped, cut=True)
    return outer, inner, bound


def reference_earth_pole(scene) -> str:
    """The exact reference's Earth pole (:attr:`lunarviz.methods.reference.ReferenceSettings.earth_pole`):
    the sub-point, or (:func:`earth_pole_at_zero_phase`) the zero-phase point with the rule cut
    along the roughness's kinks, the more accurate of the two rules about it at any order."""
    return "detector-cut" if earth_pole_at_zero_phase(scene) else "centre"



def trace_plan(scene, theta: float | None = None, mapped_part: float | None = None,
               mapped_level: int | None = None) -> dict:
    """What the tolerance chooses for the ray tracer: ``settings`` (the options left unset, and
    ``lune_order``) and ``bounds`` ({(sample kind, path): bound},
    :func:`lunarviz.methods.accuracy.trace_choice`). ``mapped_part``: a mapped Earth's expected
    part of the task's rows' bounds (:func:`expected_mapped_part`), which sets the earthshine's
    lunar-side tolerance (:func:`mapped_lunar_tolerance`), at the mapped Earth's level
    ``mapped_level`` (:func:`expected_mapped_level`; the asked or default level without one).
    Monte Carlo: the rays, where a tolerance is given and the rays are not. No model: a user's
    Moon mesh, a mapped or physical Earth (bounds empty; an explicit tolerance is refused for a
    user's Moon mesh). ``theta`` [deg]: the task's θ, where a model was measured phase by phase
    (the mapped lune rule's)."""
    none = {"settings": {}, "bounds": {}}
    if scene.method != "raytrace":
        return none
    if scene.estimator == "montecarlo":
        if scene.rays is None and scene.rtol is not None:
            return {"settings": {"rays": accuracy.montecarlo_rays(scene.rtol, scene.runs)}, "bounds": {}}
        return none
    if scene.moon_mesh is not None:
        if scene.rtol is not None:
            raise LunarvizError(f"--rtol {scene.rtol:g}: the error models cover the packaged Moon, not a user's "
                                "Moon mesh (its facets are the model): give --sun-order and --earth-order")
        return none
    fixed = {k: getattr(scene, k) for k in ("moon_level", "sun_order", "earth_order")
             if getattr(scene, k) is not None}
    asked_level = "moon_level" in fixed
    # without a tolerance the facets take level 4 (8.7e-5 measured; the rows report 2x that) and
    # the lune rule the default tolerance's orders; a lunar map's facets at level 4 err by 6e-4, so
    # a mapped Moon takes the default tolerance's choice whole (its lune rule, or finer facets)
    if scene.rtol is None and (asked_level or not scene.mapped_moon()):
        fixed.setdefault("moon_level", DEFAULT_LEVELS["moon"])
        if asked_level:  # a mesh level asked for without a tolerance: the default source orders too
            fixed.setdefault("sun_order", DEFAULT_ORDERS["sun"])
            fixed.setdefault("earth_order", DEFAULT_ORDERS["earth"])
    # the Earth's rule about the zero-phase point (or a mapped Earth's facets) takes half the
    # earthshine's tolerance (or the share that costs least), the lunar side the rest; the
    # moonshine keeps the whole
    mapped_earth = traced_earth_mapped(scene)
    pole = earth_pole_at_zero_phase(scene) and not mapped_earth
    rtol = scene.rtol_or_default
    # (beside the zero-phase rule the earthshine's lune rule takes its model's worst phase:
    # accuracy.choose_trace's earthshine_by_phase)
    choice = accuracy.trace_choice(rtol, fixed, scene.mapped_moon(), theta,
                                   earthshine_rtol=rtol / 2 if pole or mapped_earth else rtol,
                                   earthshine_by_phase=not pole)
    # an explicit mesh level asks for the facets (mesh studies), and so does a rough BRDF (Hapke's
    # roughness changes form where i = e, a kink inside the lune); otherwise the lune rule where it applies
    # (a mapped Moon's lune rule was measured with rolo-fit-map's rough presets)
    rough = any(getattr(m, "rough", False) for m in scene.brdf_models().values())
    lune = not (asked_level or rough and not scene.mapped_moon())
    if pole and not fixed.get("earth_order"):  # the split of the earthshine's tolerance that costs least
        choice = _cheapest_split(scene, rtol, fixed, theta, lune) or choice
    if mapped_earth:  # beside a mapped Earth the lunar side takes what its expected part leaves, where
        # that is more than half, or where half would leave too little for that part
        rest = mapped_lunar_tolerance(rtol, mapped_part)
        kind = "lune" if lune and choice.get("lune_order") is not None else "facets"
        half = choice.get("bounds", {}).get((kind, "earthshine"), math.inf)
        if rest > rtol / 2 or rest < rtol / 2 and not half + MAPPED_PART_MARGIN * mapped_part <= rtol:
            choice = accuracy.trace_choice(rtol, fixed, scene.mapped_moon(), theta, earthshine_rtol=rest)
    settings = {k: choice.get(k) for k in ("moon_level", "sun_order", "earth_order")
                if k not in fixed and choice.get(k) is not None}
    settings["lune_order"] = choice.get("lune_order") if lune else None
    if settings["lune_order"] is not None and choice.get("lune_source_orders") is not None:
        settings["lune_source_orders"] = choice["lune_source_orders"]
    bounds = choice.get("bounds", {}) if scene.modelled() else {}
    if pole:  # the Earth's rule about the zero-phase point, its order and bound
        _zero_phase_earth(scene, settings, fixed, bounds)
    elif mapped_earth and bounds:  # the mapped Earth's facets: their level (their bound is each row's)
        _mapped_earth(scene, settings, mapped_level)
    return {"settings": settings, "bounds": bounds}


def traced_earth_mapped(scene) -> bool:
    """Whether the ray tracer sums this run's Earth per facet of a map
    (:mod:`lunarviz.methods.tracer.mapped_earth`, as its ``FacetSurfaces.earth_mapped`` decides):
    a Lambert or physical Earth whose albedo is not one value, or whose parts differ in colour (a
    spectral run)."""
    return scene.mapped_earth == "facets" and scene.earth_model().varies(in_colour=scene.spectral_request() is not None)


def _mapped_earth(scene, settings: dict, level: int | None = None) -> None:
    """A mapped Earth's facets: ``level`` (the task's, :func:`expected_mapped_level`), else the
    level asked for or the default, which the plan states (``settings["earth_level"]``). Its
    error depends on each row's own albedos and light (:func:`mapped_earth_row_bound`), so the
    plan's earthshine bounds stay the lunar side's."""
    settings["earth_level"] = level if level is not None else _asked_earth_level(scene)


def _asked_earth_level(scene) -> int:
    return scene.earth_level if scene.earth_level is not None else DEFAULT_LEVELS["earth"]


#: The least share of the earthshine's tolerance its lunar side takes beside a mapped Earth
#: (:func:`mapped_lunar_tolerance`): a thinner one costs lune orders of 64-96
LEAST_LUNAR_SHARE = 0.2

#: The mapped Earth's finest level that a task takes where the default would not meet the
#: tolerance (:func:`expected_mapped_level`; its error model's finest, 4x the default's
#: transport time)
FINEST_MAPPED_LEVEL = 7


#: A mapped Earth's expected part of a row's bound (:func:`expected_mapped_part`) is taken this
#: many times over before the lunar side takes the rest of the tolerance: the expectation weights
#: each component's light toward the Moon's centre as a Lambert Earth lit by a point Sun does, the
#: row by the lunar BRDF across the disc and the Moon's face. Their ratio (row over expected) was
#: 1.000-1.008 with zonal clouds (a Big Bear lunation in V, orbit dates, Mauna Kea in B), up to
#: 1.08 without clouds, where the map's part alone exceeds the tolerance (docs: accuracy, "A
#: mapped Earth"; tests/test_observer_dates.py)
MAPPED_PART_MARGIN = 1.03


def mapped_lunar_tolerance(rtol: float, part: float | None) -> float:
    """The earthshine's lunar-side tolerance beside a mapped Earth whose expected part of the rows'
    bounds is ``part`` (:func:`expected_mapped_part`): what :data:`MAPPED_PART_MARGIN` times
    ``part`` leaves of ``rtol``, at least a fifth of it (a thinner lunar share costs lune orders
    of 64-96: the rows exceed the tolerance by what the map's part takes beyond four fifths).
    Half, as beside the Earth's rule about the zero-phase point, where ``part`` is unknown (no
    error model for the map) or takes the whole tolerance (the rows exceed it at any lunar
    order: none is spent on them). :func:`trace_plan` takes it where it is more than half, and
    where it is less only if half's choice would not leave room for the map's part (its orders are
    discrete: half's often meets less than half)."""
    if part is None or not math.isfinite(part) or MAPPED_PART_MARGIN * part >= rtol:
        return rtol / 2
    return max(rtol - MAPPED_PART_MARGIN * part, LEAST_LUNAR_SHARE * rtol)


#: The grid of :func:`expected_mapped_part`'s weights toward the Moon: rows of latitude (0.5° cells;
#: each component's weight within 0.22 % of the maps' own 0.1° grid's at Big Bear, Mauna Kea and
#: orbit dates, in 0.04 s instead of 0.3-0.5 s)
EXPECTED_PART_ROWS = 360


def expected_mapped_level(scene, sc, albedos: dict, averages=(None,)) -> tuple[int, float | None]:
    """A task's mapped Earth level and its expected part of the rows' bounds
    (:func:`expected_mapped_part`): the level asked for (``--earth-level``); else the coarsest
    from the default up to :data:`FINEST_MAPPED_LEVEL` with which the task is expected to meet the
    tolerance (:func:`_expected_to_meet`: a thin crescent's map errs most, and from Big Bear at
    θ = 17° in V level 6 left the row 1.36e-4 at 1e-4, level 7 9.3e-5). The default where none
    is (the rows exceed the tolerance at any level: no finer level is paid for them) or no model
    covers the map."""
    level = _asked_earth_level(scene)
    part = expected_mapped_part(scene, sc, albedos, averages, level)
    if scene.earth_level is not None or part is None or _expected_to_meet(scene, sc.theta_deg, part):
        return level, part
    for finer in range(level + 1, FINEST_MAPPED_LEVEL + 1):
        got = expected_mapped_part(scene, sc, albedos, averages, finer)
        if got is not None and _expected_to_meet(scene, sc.theta_deg, got):
            return finer, got
    return level, part


def _expected_to_meet(scene, theta: float, part: float) -> bool:
    """Whether a task beside a mapped Earth expected to take ``part`` of its rows' bounds meets the
    tolerance: its plan's lunar-side earthshine bound (:func:`trace_plan` with that part) plus
    :data:`MAPPED_PART_MARGIN` times the part."""
    plan = trace_plan(scene, theta, part)
    kind = "lune" if plan["settings"].get("lune_order") is not None else "facets"
    lunar = plan["bounds"].get((kind, "earthshine"))
    return lunar is not None and lunar + MAPPED_PART_MARGIN * part <= scene.rtol_or_default


def expected_mapped_part(scene, sc, albedos: dict, averages=(None,), level: int | None = None) -> float | None:
    """A mapped Earth's expected part of the bounds of a task's rows (relative, the largest over its
    outputs and its BRDFs' groups): :func:`lunarviz.methods.accuracy.mapped_earth_error` at the
    Earth's ``level`` (the asked or default one without it), each component's light taken as its
    weight toward the Moon's centre on a Lambert Earth lit by a point Sun
    (:func:`lunarviz.surfaces.earth_spectra.weights_toward`; ``sc``: the task's
    :class:`~lunarviz.geometry.scene_geometry.SceneGeometry`). ``albedos``: each component's
    albedo, one value or per node (a spectral run's, with ``averages`` mapping node values to
    each output's). ``None`` where the error model does not cover the map or θ for every BRDF of
    the run, or no light reaches the Moon."""
    level = _asked_earth_level(scene) if level is None else level
    groups = {accuracy.peaks_at_zero_phase(b) for b in scene.brdf_models().values()}  # (Hapke or Lambert tables)
    tables = [accuracy.mapped_earth_epsilon(level, scene.earth_model(), hapke, sc.theta_deg) for hapke in groups]
    if any(eps is None or set(albedos) - set(eps) for eps in tables):
        return None
    w = weights_toward(inputs.surfaces(scene), sc, sc.moon, rows=EXPECTED_PART_ROWS)  # (C,): the components' shares
    if not w.sum() > 0:
        return None
    nodes = np.broadcast_shapes(*(np.shape(a) for a in albedos.values()))
    unit = np.ones(nodes)
    light = sum(wc * np.asarray(albedos[c], dtype=float) for wc, c in zip(w, albedos)) * unit
    return max(accuracy.mapped_earth_error(eps, albedos, unit, float((avg or np.sum)(light)), avg)
               for eps in tables for avg in averages)


def mapped_earth_row_bound(scene, plan: dict, paths: dict, brdf, albedos: dict, unit, earthshine: float,
                           theta_deg: float, average=None) -> tuple[float, str]:
    """A traced row of a mapped Earth (:func:`traced_earth_mapped`): its bound and why it has none.
    The larger of the moonshine's bound and the earthshine's (``paths``:
    :func:`lunarviz.methods.accuracy.traced_path_bounds`), the earthshine's with the mapped
    Earth's part added, :func:`lunarviz.methods.accuracy.mapped_earth_error` at the plan's level for
    the row's BRDF, its components' ``albedos``, the albedo-1 earthshine ``unit``, the row's
    ``earthshine``, its θ [deg] and ``average`` (a band's); NaN where that model does not hold."""
    eps = accuracy.mapped_earth_epsilon(plan["settings"].get("earth_level", DEFAULT_LEVELS["earth"]),
                                        scene.earth_model(), accuracy.peaks_at_zero_phase(brdf), theta_deg)
    part = math.nan if eps is None or set(albedos) - set(eps) else \
        accuracy.mapped_earth_error(eps, albedos, unit, earthshine, average)
    if math.isnan(part):
        return math.nan, accuracy.mapped_earth_unmeasured(theta_deg)
    return max(paths["moonshine"], paths["earthshine"] + part), ""


def detector_off_centre(scene) -> bool:
    """Whether the detector is off the Earth's centre: a detector position, or dates seen from a
    site or an orbit."""
    return scene.detector is not None or (scene.times is not None and scene.observer_model().kind != "geocentre")


def earth_pole_at_zero_phase(scene) -> bool:
    """Whether the Earth's beam rules (the tracer's deterministic ones, the reference's) take the
    zero-phase point as their pole: a detector off the Earth's centre and a BRDF with an
    opposition surge or roughness (:func:`lunarviz.methods.accuracy.peaks_at_zero_phase`), whose
    peak and kink lie there. A Lambert-only run keeps the sub-point pole (smooth there)."""
    return detector_off_centre(scene) and any(accuracy.peaks_at_zero_phase(b) for b in scene.brdf_models().values())


#: The lunar side's shares of the earthshine's tolerance that :func:`_cheapest_split` weighs
#: against the Earth's rule about the zero-phase point (which takes what the lunar side leaves)
EARTHSHINE_SPLITS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


def _cheapest_split(scene, rtol: float, fixed: dict, theta, lune: bool) -> dict | None:
    """The tracer's choice (:func:`lunarviz.methods.accuracy.trace_choice`) at the lunar side's
    share of the earthshine's tolerance (:data:`EARTHSHINE_SPLITS`) whose earthshine costs least
    of those that meet the tolerance with the Earth's rule about the zero-phase point at the order
    the rest asks for (:func:`_zero_phase_earth`). The cost: the lunar samples (the lune rule's
    earthshine order squared, or 4^level for the facets) times the Earth rule's measured time at
    its order (:func:`lunarviz.methods.accuracy.off_centre_earth_seconds`). Both rules' orders are
    discrete, so half and half often leaves one of them far inside its share: at a 550 km orbit's
    dates, a lunar side at 0.6 took lune order 16 beside Earth order 10 where half took 20 beside
    10. Of equal costs, the share nearest half (the settings and bounds half gives). ``None`` where
    no share meets the tolerance (half then runs, the most accurate)."""
    mapped = scene.mapped_moon()
    best = None
    for share in EARTHSHINE_SPLITS:
        choice = accuracy.trace_choice(rtol, fixed, mapped, theta, earthshine_rtol=share * rtol,
                                       earthshine_by_phase=False)  # (only beside the zero-phase rule)
        kind = "lune" if lune and choice.get("lune_order") is not None else "facets"
        lunar = choice.get("bounds", {}).get((kind, "earthshine"), math.nan)
        order, cut = accuracy.off_centre_earth_rule((rtol - lunar) / accuracy.SAFETY, mapped)
        if not lunar + accuracy.SAFETY * accuracy.off_centre_earth_error(order, mapped, cut) <= rtol:
            continue
        samples = choice["lune_order"][1] ** 2 if kind == "lune" else 4.0 ** choice["moon_level"]
        key = (samples * accuracy.off_centre_earth_seconds(order, mapped, cut), abs(share - 0.5))  # (ties: half)
        if best is None or key < best[0]:
            best = (key, choice)
    return None if best is None else best[1]


def _zero_phase_earth(scene, settings: dict, fixed: dict, bounds: dict) -> None:
    """The tracer's Earth rule about the zero-phase point: its Earth order (for the facets' samples
    and the lune rule's), the smallest whose measured off-centre error
    (:func:`lunarviz.methods.accuracy.off_centre_earth_error`) leaves the earthshine's lunar-side
    bound (of the sample kind the plan takes: the lune rule where it has an order, else the
    facets) within the tolerance; each kind's earthshine bound grows by that error (the two
    added: the lunar side's model was measured with the sub-point rule at the Earth's centre)."""
    mapped = scene.mapped_moon()
    kind = "lune" if settings.get("lune_order") is not None else "facets"
    lunar = bounds.get((kind, "earthshine"), 0.0)
    limit = (scene.rtol_or_default - (lunar if math.isfinite(lunar) else 0.0)) / accuracy.SAFETY
    if fixed.get("earth_order"):  # an order asked for: the plain rule at it
        order, cut = fixed["earth_order"], False
    else:
        order, cut = accuracy.off_centre_earth_rule(limit, mapped)
    settings["earth_pole"] = "detector-cut" if cut else "detector"
    settings["earth_order"] = order
    if settings.get("lune_source_orders") is not None:
        settings["lune_source_orders"] = (settings["lune_source_orders"][0], order)
    extra = accuracy.SAFETY * accuracy.off_centre_earth_error(order, mapped, cut)
    for key in [k for k in bounds if k[1] == "earthshine"]:
        bounds[key] = bounds[key] + extra


def modelled(scene) -> bool:
    """Whether the error models hold for this run's bodies and photometry: they were measured
    with the paper's BRDF presets (rolo-fit-map's on its own map, for the mapped Moon), no
    parameter overrides, the uniform Lambert Earth and the packaged spheres shaded exactly
    (:func:`unmodelled_reason` says which does not)."""
    return not unmodelled_reason(scene)


def unmodelled_reason(scene) -> str:
    """Why the error models do not hold for this run's bodies and photometry (``""`` where they
    do): the first of the conditions of :func:`modelled` that the run breaks."""
    if scene.mapped_moon():  # the mapped model is rolo-fit-map's, on its own map
        if scene.moon_model != "rolo-fit-map" or scene.moon_albedo_map != moon_model_map("rolo-fit-map"):
            return "no error model for this lunar map and preset (measured: rolo-fit-map on its own map)"
    elif scene.moon_model != "paper":
        return f"no error model for the {scene.moon_model} Moon (measured: the paper's presets, rolo-fit-map's map)"
    checks = ((any(v for b, v in scene.params.items() if b != "earth"), "lunar BRDF parameters overridden"),
              (scene.earth_brdf != "lambert", "a physical Earth"),
              (not scene.earth_uniform and not _mapped_earth_modelled(scene),
               "a mapped Earth (surface classes or clouds) outside the ray tracer's facets"),
              (not scene.earth_uniform and (scene.earth_surface not in EARTH_SURFACES or scene.clouds not in CLOUDS),
               "a user's Earth map"),
              (scene.earth_mesh is not None, "a user's Earth mesh"),
              (scene.sun_mesh is not None, "a user's Sun mesh"),
              (scene.moon_mesh is not None, "a user's Moon mesh"),
              (scene.shading != "auto", f"--shading {scene.shading}"))
    for broken, what in checks:
        if broken:
            return f"no error model for {what} (measured: the paper's bodies, a uniform Lambert Earth)"
    return ""


def _mapped_earth_modelled(scene) -> bool:
    """Whether a mapped Earth is in the error models: the deterministic ray tracer's per-facet sums
    (``mapped_earth="facets"``), measured on the packaged maps (:func:`traced_earth_mapped`,
    :func:`lunarviz.methods.accuracy.mapped_earth_error`); the analytic method and the exact
    reference read a map at their nodes, whose error at its edges is not measured."""
    return scene.method == "raytrace" and scene.estimator == "deterministic" and scene.mapped_earth == "facets"


def analytic_row_bound(scene) -> tuple[float, str]:
    """The analytic method's bound (its Gauss order's, in the models) and why it has none
    (``""`` where it has one)."""
    if scene.mapped_moon():
        return math.nan, "no error model for the analytic method on a lunar map"
    why = unmodelled_reason(scene)
    if why:
        return math.nan, why
    bound = accuracy.analytic_bound(scene.analytic_settings().order)
    return bound, "" if math.isfinite(bound) else "no error model row for this Gauss order"


def warn_unmet_tolerance(scene) -> None:
    """Warn once, before a run, where the tolerance asked for is beyond what the error models hold
    (the most accurate setting runs; its rows report what it meets). Rows without a bound are
    told after the run (:func:`warn_unbounded_rows`)."""
    if scene.rtol is None:
        return
    if scene.method in ("analytic", "reference"):
        met = accuracy.analytic_choice(scene.rtol)[1] if scene.method == "analytic" else scene.reference_orders()[2]
        if not met <= scene.rtol:
            warnings.warn(f"--rtol {scene.rtol:g} is beyond the {scene.method} method's error model: its most "
                          f"accurate orders meet {met:.1e} (rows report it)", LunarvizWarning, stacklevel=3)
        return
    if scene.method != "raytrace" or scene.estimator != "deterministic":
        return
    plan = scene.trace_plan()
    kinds = ("facets",) if plan["settings"].get("lune_order") is None else ("lune",)
    met = [plan["bounds"].get((k, p), math.nan) for k in kinds for p in ("moonshine", "earthshine")]
    if plan["bounds"] and not max(met) <= scene.rtol:
        warnings.warn(f"--rtol {scene.rtol:g} is beyond the error models here: the most accurate setting they "
                      f"hold meets {max(met):.1e} (rows report it)", LunarvizWarning, stacklevel=3)


def warn_unbounded_rows(rows: list[dict]) -> None:
    """Warn once, after a run, when some of its rows carry no bound (NaN ``rtol``), with their
    reasons (each row's ``no_bound_reason``) and how many rows each concerns."""
    reasons: dict = {}
    for r in rows:
        rtol = r.get("rtol")
        if rtol is None or (isinstance(rtol, float) and math.isnan(rtol)):
            why = r.get("no_bound_reason") or "no error model"
            reasons[why] = reasons.get(why, 0) + 1
    if reasons:
        n = sum(reasons.values())
        said = "; ".join(f"{why} ({k} row{'' if k == 1 else 's'})"
                         for why, k in sorted(reasons.items(), key=lambda t: -t[1]))
        warnings.warn(f"{n} of {len(rows)} rows carry no error bound (rtol NaN, the rows' no_bound_reason): {said}",
                      UnboundedRowsWarning, stacklevel=3)


def warn_loose_rows(scene, rows: list[dict]) -> None:
    """Warn once, after a run of a mapped Earth's rows (:func:`traced_earth_mapped`), when some of
    their bounds exceed the tolerance (asked for, or the method's default): their bounds depend on
    each row's own albedos and light (:func:`mapped_earth_row_bound`), so the settings could not
    be chosen ahead for them (other rows' bounds are foreseen: :func:`warn_unmet_tolerance`)."""
    if not traced_earth_mapped(scene):
        return
    rtol = scene.rtol_or_default
    loose = [r["rtol"] for r in rows if isinstance(r.get("rtol"), float) and r["rtol"] > rtol]
    if loose:
        warnings.warn(f"{len(loose)} of {len(rows)} rows carry a bound above the tolerance {rtol:g} (largest "
                      f"{max(loose):.1e}; rtol column): a mapped Earth's error at its level (docs: accuracy, "
                      "'A mapped Earth')", LooseRowsWarning, stacklevel=3)
