"""Accuracy as the input: the settings that meet a relative tolerance at least cost.

The error models are measured, not derived (docs: accuracy, "Where the choices come from"): every setting a
tolerance may choose over the paper's scene (θ = 5-175° every 2.5°, three BRDFs, both paths)
against the exact reference at a high order and keeps, per setting, the largest relative error
and the time per phase in ``lunarviz/data/error_models.json`` (regenerate it when a method
changes). A tolerance ``rtol`` takes the cheapest setting whose measured error is at most
``rtol / SAFETY``; each row reports ``rtol``, the bound its own setting meets: ``SAFETY`` times
that setting's measured error (the scene's geometry moves the error a little: dates, distances,
observers; the factor covers it, see the tests).

What the models cover, and what rows report where they do not:

* ``raytrace`` (deterministic): the lune rule on the packaged exact-sphere Moon, with the facet
  samples of an icosphere level as the fallback where the rule does not apply (an eclipse's
  penumbra or an outside detector's Earth limb across the lune); a lunar map: with a tolerance
  the mapped lune rule (the map's cells in its weights, :mod:`lunarviz.geometry.mapped_lune`;
  against its order 128 with finer sums and sources), its
  fallback and, without a tolerance, the facets on the mapped Moon (against the finest level:
  self-convergence). A user's Moon mesh, a mapped or physical Earth: no model (the rows'
  ``rtol`` is NaN; the settings are the defaults).
* ``montecarlo``: the ray count from each path's largest relative standard deviation of one
  ray; rows report two standard errors of their mean.
* ``analytic``: the Gauss order, against the method's own converged value (the analytic method
  is the paper's point-source model: its distance from the extended reference is a model error).
* ``reference``: its outer and inner orders, against higher orders.
"""

from __future__ import annotations

import copy
import json
import math
from dataclasses import replace

import numpy as np

import lunarviz.constants as C
from lunarviz.caches import BoundedCache, memoize
from lunarviz.errors import LunarvizError
from lunarviz.options import BY_NAME, model_earth
from lunarviz.resources import DATA_DIR

#: a setting is chosen when its measured largest error is at most rtol / SAFETY
SAFETY = 2.0
#: each method's tolerance when none is given (the deterministic tracer's: what the facets at
#: level 4 meet, 8.7e-5 on the paper's scene)
DEFAULT_RTOL = {"raytrace": 1e-4, "analytic": 1e-6, "reference": 1e-6}
#: Monte Carlo without a tolerance: the paper's 50,000 rays per run
DEFAULT_RAYS = C.PAPER_RAYS
#: the most rays per run a tolerance may ask for (the ``rays`` option's bound)
MAX_RAYS = BY_NAME["rays"].hi
#: choices are nested: a tolerance takes at least the orders and level of NEST times it, up to LOOSEST
#: (the cheapest setting per tolerance need not grow monotonically; refinement must never make a
#: result worse)
NEST, LOOSEST = 10.0, 1e-2
#: the source beam order of each path in the models
SOURCE_ORDER = {"moonshine": "sun_order", "earthshine": "earth_order"}
#: a model row measured phase by phase (``errors_by_phase``) bounds a scene at θ by its largest
#: error at the phases within this many degrees of θ (six or seven phases at 5° steps): the
#: error swings with θ and with the map under the lune, and dates turn the map by their
#: libration; within 10°, one of 40 orbit dates errs by 1.1x its bound (order 12 at θ = 168°;
#: docs: accuracy), and low orders' lucky phases (errors falling 10-100x where a sign changes)
#: get chosen
PHASE_WINDOW_DEG = 15.0


@memoize(maxsize=1)
def error_models() -> dict:
    """The measured error models (``lunarviz/data/error_models.json``)."""
    return json.loads((DATA_DIR / "error_models.json").read_text())


def row_error(row: dict, theta: float | None = None) -> float:
    """A model row's error bound before :data:`SAFETY`: its largest error over every phase, or,
    at a scene's θ [deg] inside the phases it was measured at one by one (``errors_by_phase``),
    its largest at the phases within :data:`PHASE_WINDOW_DEG` of θ."""
    if theta is None or "errors_by_phase" not in row:
        return row["max_rel_error"]
    th = float(theta) % 360.0
    th = min(th, 360.0 - th)
    phases = np.asarray(row["phases_deg"], dtype=float)
    if not phases.min() <= th <= phases.max():
        return row["max_rel_error"]
    return float(np.max(np.asarray(row["errors_by_phase"])[np.abs(phases - th) <= PHASE_WINDOW_DEG]))


def _best(rows: list, limit: float, fixed: dict, theta: float | None = None) -> dict | None:
    """The cheapest row whose error (at θ: :func:`row_error`) is at most ``limit`` and whose
    settings agree with ``fixed``."""
    ok = [r for r in rows if row_error(r, theta) <= limit and all(r.get(k, v) == v for k, v in fixed.items())]
    return min(ok, key=lambda r: r["seconds_per_phase"]) if ok else None


def _most_accurate(rows: list, fixed: dict, theta: float | None = None) -> dict | None:
    ok = [r for r in rows if all(r.get(k, v) == v for k, v in fixed.items())]
    return min(ok, key=lambda r: (row_error(r, theta), r["seconds_per_phase"])) if ok else None


def _paired(table: dict, key: str, rtols: dict, fixed: dict) -> dict:
    """The cheapest ``key`` value (lune order or level) with a source order per path that meets
    each path's tolerance (``rtols``: {path: rtol}); the most accurate pair where none does."""
    values = sorted({r[key] for r in table["moonshine"]} & {r[key] for r in table["earthshine"]})
    if key in fixed:
        values = [v for v in values if v == fixed[key]]
    best = None
    for v in values:
        pair = {p: _best(table[p], rtols[p] / SAFETY, {**_for(fixed, p), key: v}) for p in table}
        if all(pair.values()):
            cost = sum(r["seconds_per_phase"] for r in pair.values())
            if best is None or cost < best[0]:
                best = (cost, pair)
    if best is None:  # nothing meets it: the most accurate the model has
        pair = {p: _most_accurate(table[p], _for(fixed, p)) for p in table}
        return {} if not all(pair.values()) else pair
    return best[1]


def _for(fixed: dict, path: str) -> dict:
    """The fixed settings that concern ``path`` (the other path's source order does not)."""
    other = SOURCE_ORDER["earthshine" if path == "moonshine" else "moonshine"]
    return {k: v for k, v in fixed.items() if k != other}


#: :func:`trace_choice`'s answers by their inputs (θ by what the models see of it: :func:`_phase_key`):
#: a dated sweep plans every date, with the same few inputs
_CHOICES = BoundedCache(4096)


def _phase_key(theta: float | None):
    """What :func:`row_error` reads of θ, for every phase grid of the mapped lune rule's rows:
    whether θ lies inside the grid and which of its phases lie within :data:`PHASE_WINDOW_DEG`
    (two θ of one key give every row the same error, bit for bit)."""
    if theta is None:
        return None
    th = float(theta) % 360.0
    th = min(th, 360.0 - th)
    out = []
    for grid in _phase_grids():
        phases = np.asarray(grid, dtype=float)
        out.append((bool(phases.min() <= th <= phases.max()), tuple(np.abs(phases - th) <= PHASE_WINDOW_DEG)))
    return tuple(out)


@memoize(maxsize=1)
def _phase_grids() -> tuple:
    """The distinct ``phases_deg`` of the error models' rows measured phase by phase."""
    rows = [r for table in error_models().get("raytrace_lune_mapped", {}).values() for r in table]
    return tuple(sorted({tuple(r["phases_deg"]) for r in rows if "errors_by_phase" in r}))


def trace_choice(rtol: float, fixed: dict, mapped_moon: bool, theta: float | None = None,
                 earthshine_rtol: float | None = None, earthshine_by_phase: bool = True) -> dict:
    """:func:`choose_trace` (same arguments), remembered by its inputs (θ by :func:`_phase_key`,
    and only for a mapped Moon, whose models alone read it); a fresh copy each call. The answers are
    those of the packaged models (:func:`error_models`): :func:`lunarviz.caches.release_caches`
    forgets them with the models."""
    key = (rtol, tuple(sorted((k, type(v), v) for k, v in fixed.items())), bool(mapped_moon),
           _phase_key(theta) if mapped_moon else None, earthshine_rtol,
           bool(earthshine_by_phase))  # (a value's type: the answer carries it)
    choice = _CHOICES.get(key)
    if choice is None:
        choice = choose_trace(rtol, fixed, mapped_moon, theta, earthshine_rtol, earthshine_by_phase)
        _CHOICES[key] = choice
    return copy.deepcopy(choice)


def choose_trace(rtol: float, fixed: dict, mapped_moon: bool, theta: float | None = None,
                 earthshine_rtol: float | None = None, earthshine_by_phase: bool = True) -> dict:
    """Settings for the deterministic tracer at ``rtol`` (the earthshine's at ``earthshine_rtol``
    where given: the part of its tolerance left to the lunar side): ``lune_order`` (the Sun's path, the
    Earth's), ``moon_level``, ``sun_order``, ``earth_order`` (with a lunar map, those of the
    facets; the lune rule's own source orders are ``lune_source_orders``; those in ``fixed`` kept; nested: at
    least those of a looser tolerance, :data:`NEST`), and per path and sample kind the bound each
    meets (``bounds``: {("lune"|"facets", path): bound}). ``theta`` [deg]: the scene's θ, where the
    mapped lune rule's model was measured phase by phase (:func:`row_error`): the orders that
    phase needs, and its bounds; with ``earthshine_by_phase`` False the earthshine's lune rule takes
    the model's largest error over every phase instead (a surging BRDF seen off the Earth's centre:
    the phase-by-phase model was measured from it, and near full Moon its low orders erred there by
    up to 3.8x what their phases' rows hold: docs, accuracy)."""
    m = error_models()
    bounds = {}
    rtols = {"moonshine": rtol, "earthshine": rtol if earthshine_rtol is None else earthshine_rtol}
    if mapped_moon:  # the map's cells dominate: rows by level (the Earth's order is not the limit)
        table = m["raytrace_facets_mapped"]
        level = fixed.get("moon_level")
        if level is None:
            pair = _paired(table, "moon_level", rtols, {})
            level = pair["moonshine"]["moon_level"] if pair else None
        for p in ("moonshine", "earthshine"):
            row = next((r for r in table[p] if r["moon_level"] == level), None)
            bounds[("facets", p)] = SAFETY * row["max_rel_error"] if row else math.nan
        row = {p: next((r for r in table[p] if r["moon_level"] == level), {}) for p in table}
        out = {"lune_order": None, "moon_level": level,
               "sun_order": fixed.get("sun_order", row["moonshine"].get("sun_order")),
               "earth_order": fixed.get("earth_order", row["earthshine"].get("earth_order")), "bounds": bounds}
        if "moon_level" not in fixed and "raytrace_lune_mapped" in m:  # the mapped lune rule
            th = {"moonshine": theta, "earthshine": theta if earthshine_by_phase else None}
            lune = {p: _best(m["raytrace_lune_mapped"][p], rtols[p] / SAFETY, _for(fixed, p), th[p]) or
                    _most_accurate(m["raytrace_lune_mapped"][p], _for(fixed, p), th[p]) for p in SOURCE_ORDER}
            if all(lune.values()):
                out["lune_order"] = (lune["moonshine"]["lune_order"], lune["earthshine"]["lune_order"])
                for p, r in lune.items():
                    bounds[("lune", p)] = SAFETY * row_error(r, th[p])
                # each sample kind its own source orders (the lune rule's beams, the facets'), as measured
                out["lune_source_orders"] = tuple(fixed.get(SOURCE_ORDER[p], lune[p][SOURCE_ORDER[p]])
                                                  for p in ("moonshine", "earthshine"))
        return out
    # the lune rule: each path its own order (one rule per path); the facets: one level for both
    lune = {p: _best(m["raytrace_lune"][p], rtols[p] / SAFETY, _for(fixed, p)) or
            _most_accurate(m["raytrace_lune"][p], _for(fixed, p)) for p in ("moonshine", "earthshine")}
    lune = lune if all(lune.values()) else {}
    facets = _paired(m["raytrace_facets"], "moon_level", rtols, fixed)
    out = {"lune_order": (lune["moonshine"]["lune_order"], lune["earthshine"]["lune_order"]) if lune else None,
           "moon_level": facets["moonshine"]["moon_level"] if facets else fixed.get("moon_level")}
    for name in ("sun_order", "earth_order"):  # one order serves both sample kinds: the larger
        p = "moonshine" if name == "sun_order" else "earthshine"
        got = [t[p][name] for t in (lune, facets) if t]
        out[name] = fixed.get(name, max(got) if got else None)
    if min(rtols.values()) * NEST < LOOSEST:  # nested: never fewer nodes than a looser tolerance takes
        looser = trace_choice(rtol * NEST, fixed, False, earthshine_rtol=rtols["earthshine"] * NEST)
        for key in ("moon_level", "sun_order", "earth_order"):
            if out[key] is not None and looser[key] is not None:
                out[key] = max(out[key], looser[key])
        if out["lune_order"] is not None and looser["lune_order"] is not None:
            out["lune_order"] = tuple(max(a, b) for a, b in zip(out["lune_order"], looser["lune_order"]))
    # the bound each sample kind meets with the orders finally used (a row of the model, if any)
    kinds = (("lune", m["raytrace_lune"], "lune_order"), ("facets", m["raytrace_facets"], "moon_level"))
    for kind, table, key in kinds:
        for i, p in enumerate(("moonshine", "earthshine")):
            value = out[key][i] if kind == "lune" and out[key] is not None else out[key]
            want = {key: value, SOURCE_ORDER[p]: out[SOURCE_ORDER[p]]}
            row = next((r for r in table[p] if all(r.get(k) == v for k, v in want.items())), None)
            bounds[(kind, p)] = SAFETY * row["max_rel_error"] if row else math.nan
    out["bounds"] = bounds
    return out


def montecarlo_rays(rtol: float, runs: int) -> int:
    """Rays per run so that two standard errors of the mean of ``runs`` runs are at most
    ``rtol`` for both paths (each path's largest relative σ of one ray in the models)."""
    sigma = max(error_models()["montecarlo_sigma_one_ray"].values())
    rays = max(1, math.ceil((SAFETY * sigma / rtol) ** 2 / runs))
    if rays > MAX_RAYS:
        raise LunarvizError(f"--rtol {rtol:g} with Monte Carlo needs {rays:.2g} rays per run (at most "
                            f"{MAX_RAYS:.0e}): give --runs {math.ceil(rays / MAX_RAYS * runs)} or more, or use the "
                            "deterministic estimator")
    return rays


def in_model_range(scene) -> bool:
    """Whether a scene lies inside the geometry the models were measured on: θ (the Sun-Earth-Moon
    angle, also on dates) within the phases measured (5-175°). Nearer full or new Moon the lune or
    the Earth's crescent gets thinner than any measured, the opposition surge sharper, and rows
    report no bound."""
    phases = error_models()["phases_deg"]
    th = float(scene.theta_deg) % 360.0
    th = min(th, 360.0 - th)
    return min(phases) <= th <= max(phases)


#: the detector's largest angle [rad] off the Earth's centre, seen from the Moon's, at which the
#: earthshine models hold for a BRDF with an opposition surge or roughness
#: (:func:`earth_source_modelled`): they were measured with the detector at the Earth's centre
EARTH_CENTRE_TOLERANCE = 1e-6


def peaks_at_zero_phase(brdf) -> bool:
    """Whether ``brdf`` has an opposition surge (B0 > 0) or roughness (its i = e kink; coherent
    backscatter): features at zero phase that an extended Earth's beam rules resolve only about
    their pole (:func:`earth_source_modelled`)."""
    return getattr(brdf, "rough", False) or getattr(brdf, "B0", 0.0) > 0.0


def extended_earth(method: str, estimator: str | None) -> bool:
    """Whether ``method`` (and ``estimator``) integrate over the Earth's disc with beam rules:
    the tracer's deterministic estimator and the reference (not the analytic point Earth, nor
    Monte Carlo, whose standard errors do not depend on a rule)."""
    return method == "reference" or (method == "raytrace" and estimator != "montecarlo")


def earth_source_modelled(scene, brdf) -> bool:
    """Whether the earthshine error models hold for ``brdf`` on ``scene``.

    They were measured with the detector at the Earth's centre. Seen from the Moon, the Earth's
    disc is then centred on the direction of zero phase, which is the pole of the Earth's beam
    rules, where the opposition surge's cusp (B(g) ∝ 1/(1 + tan(g/2)/h): |g| at g = 0) and the
    roughness's kink (i = e) are resolved. A detector elsewhere (on the ground, in orbit: up to
    ~1° off the centre) puts them off that pole, inside or beside the disc, and the beam rules
    converge slowly there. Measured: Hapke DHG of rolo-fit-map from a 550 km orbit, earthshine
    at Earth order 7 against 28, 7.6e-4 and 2.7e-3 on two dates; against the reference rule up
    to 4.7e-3 on 80 dates (docs: accuracy). Lambert is smooth there and
    keeps its bound."""
    if not peaks_at_zero_phase(brdf):
        return True
    u, v = scene.det - scene.moon, scene.earth - scene.moon
    c = float(np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)))
    return math.acos(min(1.0, max(-1.0, c))) <= EARTH_CENTRE_TOLERANCE


def _off_centre_table(cut: bool):
    return error_models().get("earth_rule_off_centre_cut" if cut else "earth_rule_off_centre")


def off_centre_earth_error(order: int, mapped_moon: bool, cut: bool = False) -> float:
    """The largest relative error of the earthshine from the Earth's beam rules about the
    zero-phase point at Earth ``order`` (``earth_rule_off_centre`` in the models, or with ``cut``
    the rule cut along the roughness's kinks, ``earth_rule_off_centre_cut``: at the largest order
    measured at or below ``order``; NaN below the smallest), measured with the detector off the
    Earth's centre on orbit and site dates against a higher order of the cut rule (docs: accuracy,
    "Observers off the Earth's centre"). The largest over every date and phase: the error at a
    low order swings by 100x from one date to the next, so no phase window of a few dates bounds it."""
    table = _off_centre_table(cut)
    if table is None:
        return math.nan
    measured = [o for o in table["orders"] if o <= order]
    if not measured:
        return math.nan
    return float(table["max_rel_error"]["rolo-fit-map" if mapped_moon else "paper"][str(max(measured))])


def off_centre_earth_order(limit: float, mapped_moon: bool, cut: bool = False) -> int:
    """The smallest Earth order of the zero-phase rule (``cut``: cut along the kinks) whose
    measured error is at most ``limit``, else the largest measured (the most accurate)."""
    table = _off_centre_table(cut)
    if table is None:
        return max(DEFAULT_EARTH_ORDERS)
    ok = [o for o in table["orders"] if off_centre_earth_error(o, mapped_moon, cut) <= limit]
    return min(ok) if ok else max(table["orders"])


def off_centre_earth_seconds(order: int, mapped_moon: bool, cut: bool = False) -> float:
    """The time a date's earthshine took with the zero-phase rule at Earth ``order`` in its
    measurement (``seconds``: mean over the dates; inf where not measured)."""
    table = _off_centre_table(cut) or {}
    return float(table.get("seconds", {}).get("rolo-fit-map" if mapped_moon else "paper", {}).get(str(order), math.inf))


def off_centre_earth_rule(limit: float, mapped_moon: bool) -> tuple[int, bool]:
    """``(order, cut)``: of the two zero-phase rules, plain and cut along the kinks, the one
    whose smallest order meeting ``limit`` took less time in the measurement
    (:func:`off_centre_earth_seconds`); the more accurate where neither meets it."""
    options = []
    for cut in (False, True):
        if _off_centre_table(cut) is None:
            continue
        order = off_centre_earth_order(limit, mapped_moon, cut)
        err = off_centre_earth_error(order, mapped_moon, cut)
        cost = off_centre_earth_seconds(order, mapped_moon, cut)
        options.append((not err <= limit, cost if err <= limit else err, cut, order))
    if not options:
        return max(DEFAULT_EARTH_ORDERS), False
    _, _, cut, order = min(options)
    return order, cut


#: the Earth orders the zero-phase rule falls back to without a measured table
DEFAULT_EARTH_ORDERS = (5, 6, 7, 8, 10, 14, 20)


def mapped_earth_epsilon(level: int, surface, hapke: bool, theta_deg: float) -> dict | None:
    """``{component: ε_c}`` of the ray tracer's mapped Earth (its facets at icosphere ``level``,
    gathered into the disc's cells: :mod:`lunarviz.methods.tracer.mapped_earth`) on ``surface``'s
    packaged map (an :class:`~lunarviz.surfaces.earth_surface.EarthSurface`): the largest error of
    the earthshine each component carries, as a share of the earthshine of an Earth of albedo 1,
    over dates, observers and the lunar BRDFs of a group (Lambert; ``hapke``: those with an
    opposition surge), measured against the map's own cells
    (:mod:`lunarviz.methods.map_cell_reference`; ``mapped_earth`` in the models, docs: accuracy,
    "A mapped Earth"): the core dates' table at θ = 20-160°, beyond it a band's table (those dates
    and the paper's scene at θ = 10° or 170°). ``None`` where not measured (another level, a
    user's map, the physical Earth, θ [deg] outside every table's range: a thinner crescent errs
    more)."""
    table = error_models().get("mapped_earth")
    if table is None or surface.physical or level not in table["levels"]:
        return None
    eps = mapped_earth_tables(theta_deg, table)
    if eps is None:
        return None
    maps = eps["hapke" if hapke else "lambert"]
    key = f"{surface.earth_surface}+{surface.clouds}"
    if key not in maps:
        return None
    i = table["levels"].index(level)
    return {c: float(e[i]) for c, e in maps[key].items()}


def mapped_earth_tables(theta_deg: float, model: dict) -> dict | None:
    """The ε tables of a mapped Earth's error ``model`` (``mapped_earth`` in the models) that rows
    at θ [deg] take: the core dates' within their θ, beyond it a band's (those dates and the
    paper's scene there), the first whose range holds θ; ``None`` outside every range."""
    return next((t["epsilon"] for t in [model] + model.get("bands", [])
                 if t["theta_range_deg"][0] <= theta_deg <= t["theta_range_deg"][1]), None)


def mapped_earth_unmeasured(theta_deg: float) -> str:
    """Why a mapped Earth's row has no bound where the rest of its row has one."""
    table = error_models().get("mapped_earth") or {}
    ranges = [t["theta_range_deg"] for t in [table] + table.get("bands", []) if "theta_range_deg" in t]
    lo, hi = (min(r[0] for r in ranges), max(r[1] for r in ranges)) if ranges else (math.nan, math.nan)
    if not lo <= theta_deg <= hi:
        return f"a mapped Earth outside theta = {lo:g}-{hi:g} deg (its error model's range)"
    return "no error model for a mapped Earth at this Earth level (measured: levels 4-7 of the packaged maps)"


def mapped_earth_error(epsilon: dict, albedos: dict, unit, earthshine: float, average=None) -> float:
    """The bound on a mapped Earth's part of a row's relative earthshine error.

    The row's earthshine is ``E = Σ_c α_c I_c`` over the map's components (``albedos``: their
    albedos α_c, per node wavelength or one value), each of whose errors is at most ``ε_c I₁``
    (``epsilon``: :func:`mapped_earth_epsilon`; ``unit``: I₁, the earthshine of an Earth of albedo
    1, per node), and ``Σ_c I_c = I₁`` (the components' weights sum to 1), so for any ``ᾱ``
    ``|δE| ≤ ᾱ ε₁ I₁ + Σ_c |α_c - ᾱ| ε_c I₁`` (ε₁: the albedo-1 Earth's own error, ``"albedo 1"``).
    The components' errors are large where a map's edge crosses a facet or a cell of the Earth's
    disc and cancel in their sum: the bound takes the best ᾱ among the components' albedos (or 0;
    per node, the same component at every node), then ``SAFETY · |δE| / E``. ``average`` maps
    per-node values to the row's (a band's average, linear; none for one node). 0 where no
    component carries light; NaN where they do but the earthshine is not positive."""
    avg = average or (lambda v: float(np.sum(v)))
    unit = np.asarray(unit, dtype=float)
    alb = {c: np.broadcast_to(np.asarray(v, dtype=float), unit.shape) for c, v in albedos.items()}
    best = math.inf
    for ref in [np.zeros(unit.shape)] + list(alb.values()):
        spread = sum(epsilon[c] * np.abs(a - ref) for c, a in alb.items())
        best = min(best, float(avg((epsilon["albedo 1"] * ref + spread) * unit)))
    if best == 0.0:  # no Earthlight (or an Earth of albedo 0): no error to bound
        return 0.0
    return SAFETY * best / earthshine if earthshine > 0 else math.nan


def row_bound(bound: float, scene, method: str, estimator: str | None, brdf, why: str = "",
              pole_at_zero_phase: bool = False) -> tuple[float, str]:
    """The bound a row reports, and why it has none: ``bound`` (its settings' in the models; ``why``
    it is NaN, where it is) where the models hold for the row's scene and BRDF: θ within the
    phases measured (:func:`in_model_range`) and, for an extended Earth's beam rules (the
    tracer's deterministic estimator, the reference), :func:`earth_source_modelled` unless their
    pole is the zero-phase point (``pole_at_zero_phase``: its own bound is in ``bound``); 0 for exact
    zeros (a Moon wholly hidden); NaN elsewhere, with the reason (``""`` where bounded)."""
    if bound == 0.0:
        return 0.0, ""
    if math.isnan(bound):
        return math.nan, why or "no error model holds for this row's settings"
    if not in_model_range(scene):
        lo, hi = min(error_models()["phases_deg"]), max(error_models()["phases_deg"])
        return math.nan, f"theta outside the phases the error models were measured at ({lo:g}-{hi:g} deg)"
    if extended_earth(method, estimator) and not pole_at_zero_phase and not earth_source_modelled(scene, brdf):
        return math.nan, OFF_CENTRE_REASON
    return bound, ""


#: why a row whose Moon the Earth's exact sphere covers whole has no bound (the packaged Earth's
#: facets, inside the sphere, leave a sliver in sight:
#: :meth:`~lunarviz.methods.tracer.lunar_sampling.LunarSampling.earth_covers_moon`)
EARTH_COVERS_MOON_REASON = "the Earth's sphere covers the whole Moon; only its facets' sag leaves a sliver in sight"
#: why a Hapke row's earthshine seen off the Earth's centre has no bound (:func:`earth_source_modelled`)
OFF_CENTRE_REASON = ("earthshine of a BRDF with an opposition surge or roughness seen off the Earth's centre: "
                     "the Earth's beam rules are not measured there")


def analytic_choice(rtol: float) -> tuple[int, float]:
    """(order, bound) of the analytic method at ``rtol`` (the most accurate order if none meets it)."""
    rows = error_models()["analytic"]
    err = [(max(r["moonshine"], r["earthshine"]), r) for r in rows]
    ok = [(r["seconds_per_phase"], r["order"], e) for e, r in err if e <= rtol / SAFETY]
    if ok:
        _, order, e = min(ok)
    else:
        e, r = min(err, key=lambda t: t[0])
        order = r["order"]
    return order, SAFETY * e


def analytic_bound(order: int) -> float:
    """The bound the analytic method's ``order`` meets (NaN outside the model)."""
    r = next((r for r in error_models()["analytic"] if r["order"] == order), None)
    return math.nan if r is None else SAFETY * max(r["moonshine"], r["earthshine"])


def reference_choice(rtol: float) -> tuple[int, int, float]:
    """(outer, inner, bound) of the exact reference at ``rtol``: the lowest orders in the model
    that meet it, else the orders the model was measured against (bound: the next lower's error)."""
    m = error_models()
    rows = sorted(m["reference"], key=lambda r: (r["outer"], r["inner"]))
    for r in rows:
        e = max(r["moonshine"], r["earthshine"])
        if e <= rtol / SAFETY:
            return r["outer"], r["inner"], SAFETY * e
    outer, inner = m["reference_orders"]
    return outer, inner, SAFETY * max(rows[-1]["moonshine"], rows[-1]["earthshine"])


def traced_bound(bounds: dict, ts, ms, es, why: str = "") -> tuple[float, str]:
    """The relative error bound a traced row meets, and why it has none (``""`` where it has one):
    from ``bounds`` (:func:`trace_choice`'s, by sample kind and path; empty: ``why``) for the
    kind each path took (lune rule or facets: ``ts``, the
    :class:`~lunarviz.methods.tracer.trace_scene.TraceScene`); Monte Carlo: two standard errors of
    the mean (``ms``, ``es``: the paths' results); NaN without a model."""
    if ts.settings.estimator == "montecarlo":
        rel = [r.sem[k] / r.mean[k] for r in (ms, es) for k in r.mean if r.mean[k] > 0]
        return (SAFETY * max(rel), "") if rel else (math.nan, "Monte Carlo: no positive mean to scale its error by")
    if ts.sampling.eclipse_possible() or ts.sampling.moon_shadow_on_earth_possible():  # measured without occlusion
        return math.nan, "an eclipse's penumbra or the Moon's shadow on the Earth: not in the error models"
    got, why = traced_path_bounds(bounds, ts, why)
    return (max(got.values()), "") if got else (math.nan, why)


def traced_path_bounds(bounds: dict, ts, why: str = "") -> tuple[dict, str]:
    """``({"moonshine": bound, "earthshine": bound}, "")`` of a deterministic trace, from
    ``bounds`` for the kind of samples each path took (:func:`traced_bound`), or ``({}, why)``
    where either path has none."""
    if not bounds:
        return {}, why or "no error model holds for this row's settings"
    if ts.sampling.earth_covers_moon():
        return {}, EARTH_COVERS_MOON_REASON
    got = {}
    for path, body in (("moonshine", "sun"), ("earthshine", "earth")):
        if ts.sampling.lune_rule_applies(body):
            if ts.sampling.view_edge_missed(body):
                return {}, "the Earth's limb or a horizon grazes the Moon closer than the facets' sight lines find"
            got[path] = bounds.get(("lune", path), math.nan)
        elif ts.sampling.edges_found(body):  # a horizon, an Earth limb or a cast shadow across the Moon: not measured
            return {}, "a horizon, the Earth's limb or a cast shadow across the Moon: not in the error models"
        else:
            got[path] = bounds.get(("facets", path), math.nan)
    if any(math.isnan(b) for b in got.values()):
        return {}, "no error model row for these orders"
    return got, ""


def calibration_settings(ts_set, moon_level_asked, mapped_moon: bool):
    """The deterministic tracer's settings for an inversion's calibration (the *model* Earth, the
    nominal Lambert sphere, on the same scene) where the run itself cannot calibrate (Monte Carlo,
    a user's Earth mesh): ``ts_set`` with the model Earth, at the deterministic tracer's default
    tolerance unless a mesh level was asked for (``moon_level_asked``)."""
    choice = {} if moon_level_asked else trace_choice(DEFAULT_RTOL["raytrace"], {}, mapped_moon)
    cal = {k: choice[k] for k in ("lune_order", "sun_order", "earth_order", "lune_source_orders")
           if choice.get(k) is not None}
    return replace(ts_set, estimator="deterministic", earth_mesh=None, **model_earth(ts_set), **cal)
