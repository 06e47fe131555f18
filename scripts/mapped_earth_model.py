"""The error model of the ray tracer's mapped Earth (land, ocean, clouds), measured against the
map's own cells.

    python scripts/mapped_earth_model.py [--write] [--quick] [--workers N] [--out DIR]
    python scripts/mapped_earth_model.py --held-out     (cases never in the tables, against them)

The tracer sums a mapped Lambert Earth per facet of its mesh and gathers the facets into cells of
the Earth's disc seen from the Moon (:mod:`lunarviz.methods.tracer.mapped_earth`). This script
measures, for each Earth mesh level and each of the packaged maps (``--earth-surface landocean``
with ``--clouds zonal`` or ``none``, ``--earth-surface uniform --clouds zonal``), the error of the
earthshine carried by each of the map's components (:func:`lunarviz.surfaces.earth_spectra.weights_at`:
ocean, vegetation, desert, snow, cloud, or the clear sky), as a share of the earthshine of an Earth
of albedo 1: ``ε_c = |δI_c| / I₁``, the largest over dates, observers and lunar BRDFs (the paper's
Lambert, SHG and DHG, rolo-fit-map's DHG). Any Earth on that map is a non-negative combination of
its components (``α_c`` ≥ 0: the grey albedos, or a spectral run's albedos at each wavelength), so
its earthshine errs by at most ``Σ_c α_c ε_c / A``, with ``A = E / I₁`` the row's
``earth_visible_lit_albedo`` (:func:`lunarviz.methods.accuracy.mapped_earth_bound`).

The reference is :mod:`lunarviz.methods.map_cell_reference` (the map's own 0.1° cells, two by two, split
near the terminator and the limb; no mesh, no facet averages, no disc cells). Its own error, its
Earth of albedo 1 against the exact Lambert-sphere rule on each date (≤ 1.4e-6 at θ = 20-170°,
8.2e-6 at θ = 10°), is added to every component's. Both sides take the same lunar points (the
reference's outer rule at order 6 over the lunar sphere the Earth lights, seen from the date's
detector): the error is the Earth's part alone (the lunar side has its own models). Dates: θ =
20-160° of the paper's scene (the Earth turned every 45°, every 22.5° at 20°), four nights from Big Bear and four from
Paranal, every 37th hour of 15 days from a 550 km orbit; dates whose Moon is hidden, whose Earth the
Moon's shadow may touch, or outside θ = 5-175° are left out. Rows at θ = 20-160° take those
dates' table; rows at 15-20° a table that adds θ = 15° of the paper's scene, rows at 10-15° one
that adds 15° and 10° (a thinner crescent errs more: a row at 17° is not held to the error at
10°), rows at 160-170° one that adds θ = 170° (each side its own dates: θ =
10° would loosen the 160-170° rows up to 7.7-fold). ``--tables-from FILE`` rebuilds the tables from
an earlier run's stored dates (``mapped_earth.json``), measuring only the paper's scene at a θ or an
Earth turn that run lacks. A finer level is never
allowed more error than a coarser one (each table is made non-increasing). ``--write`` stores the table in
``lunarviz/data/error_models.json`` (key ``mapped_earth``); the report goes to
``benchmarks/error_models/mapped_earth.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
LEVELS = (4, 5, 6, 7)
#: the packaged maps: (earth_surface, clouds)
MAPS = (("landocean", "zonal"), ("landocean", "none"), ("uniform", "zonal"))
OUTER_ORDER = 6
#: the θ [deg] of the core table's dates (every site and orbit date lies within); beyond each end,
#: bands whose tables add the paper's scene at :data:`BEYOND`'s θ on that side, nearest first: a
#: band [15°, 20°] adds θ = 15°, a band [10°, 15°] adds 15° and 10° (a thinner crescent errs more,
#: so a row at 17° is not held to the error at 10°), and [160°, 170°] adds 170° (each side its own
#: dates, so neither loosens the other)
CORE = (20.0, 160.0)
BEYOND = ((15.0, 10.0), (170.0,))
#: the steps [deg] of the paper's scene's Earth turns at θ ≤ 20° and beyond: an error peak as
#: narrow as ±10° of turn (a coast along the disc's cells; 20x smaller 7.5° either side of it)
#: slipped between turns 90° apart (θ = 20°, turned 67.5°: 2.6x the core table of four turns)
ROTATION_STEP_DEG = (22.5, 45.0)
GROUP = 2  # map cells a reference cell, each way


def cases(quick: bool) -> list[tuple[str, str | float, float]]:
    """(observer, task key, Earth rotation [deg]) of the model: θ of the paper's scene, site nights,
    orbit hours."""
    if quick:
        out = [("geocentre", th, 0.0) for th in (30.0, 120.0)]
    else:  # the Earth turned every 22.5° at thin crescents, 45° elsewhere (its coasts under the disc's cells)
        out = [("geocentre", th, rot) for th in (20.0, 60.0, 100.0, 140.0, 160.0, 15.0, 10.0, 170.0)
               for rot in np.arange(0.0, 360.0, ROTATION_STEP_DEG[0] if th <= CORE[0] else ROTATION_STEP_DEG[1])]
    nights = 2 if quick else 4
    for obs in ("site:34.26,-116.92,2067", "site:-24.63,-70.40,2635"):
        for k in range(nights):
            day = dt.date(2026, 1, 5) + dt.timedelta(days=7 * k + (3 if "-24" in obs else 0))
            out.append((obs, f"{day.isoformat()}T03:00:00Z", 0.0))
    start = dt.datetime(2026, 2, 1, 1)
    for h in range(0, 24 * (2 if quick else 15), 37):
        out.append(("orbit:550,97.6,0,0", (start + dt.timedelta(hours=h)).strftime("%Y-%m-%dT%H:%M:00Z"), 0.0))
    return out


def scene_of(obs, key, rot, surface="landocean", clouds="zonal", level=None, **options):
    """The resolved scene of a case (``options``: further scene options, e.g. ``earth_brdf``)."""
    from lunarviz.scene import ResolvedScene
    kw = dict(brdfs=("lambert", "shg", "dhg"), earth_surface=surface, clouds=clouds, earth_level=level,
              method="raytrace", **options)
    if obs == "geocentre":
        return ResolvedScene(phases_deg=(float(key),), earth_rotation_deg=rot, **kw)
    return ResolvedScene(times=[key], observer=obs, **kw)


def case_points(s, key):
    """``(scene, x, n, mu, geom, o)``: a date's geometry and the lunar points both sides take (the
    reference's outer rule at :data:`OUTER_ORDER` over the lunar sphere the Earth lights, seen from
    the date's detector); ``None`` for a date left out (its Moon hidden, θ outside 5-175°, the
    Moon's shadow possibly on the Earth)."""
    from lunarviz.methods.analytic import lunar_surface_rule
    from lunarviz.methods.tracer.estimators import TraceScene
    from lunarviz.methods.transport import detector_geometry
    from lunarviz.workflows.skips import skip_reason
    sc, _ = s.task(key)
    if skip_reason(s, sc) or not 5.0 <= sc.theta_deg <= 175.0 \
            or TraceScene(sc, s.trace_settings(threads=1)).sampling.moon_shadow_on_earth_possible():
        return None
    x, n, dA = lunar_surface_rule(sc, sc.earth, sc.radii["earth"], OUTER_ORDER)
    mu, geom, o = detector_geometry(x, n, dA, sc.det, sc.det_normal)
    geom = np.where(sc.sight_lines_clear(x), geom, 0.0)
    k = geom > 0
    return sc, x[k], n[k], mu[k], geom[k], o[k]


def one_case(case) -> dict | None:
    from lunarviz.methods.map_cell_reference import cell_radiances, earth_cells, exact_unit_earthshine
    from lunarviz.methods.tracer.estimators import TraceScene
    from lunarviz.methods.transport import Transport
    from lunarviz.scene import ResolvedScene
    from lunarviz.surfaces.earth_spectra import components, weights_at
    from lunarviz.surfaces.maps import map_frame
    obs, key, rot = case
    s = scene_of(obs, key, rot)
    points = case_points(s, key)
    if points is None:
        return None
    sc, x, n, mu, geom, o = points
    brdfs = dict(s.brdf_models())
    brdfs["rolo dhg"] = ResolvedScene(moon_model="rolo-fit-map", brdfs=("dhg",)).brdf_models()["dhg"]
    t0 = time.perf_counter()
    surfaces = {m: scene_of(obs, key, rot, *m).earth_model() for m in MAPS}
    names = {m: components(surf) for m, surf in surfaces.items()}

    def values(d):  # albedo 1, then every map's components
        return np.concatenate([np.ones((len(d), 1))] + [weights_at(surf, d) for surf in surfaces.values()], 1)
    cen, wts = earth_cells(sc, values, (1800, 3600), map_frame(sc, "earth", rot), group=GROUP)
    ref = cell_radiances(sc, x, n, o, mu, cen, wts, brdfs)
    ref_s = time.perf_counter() - t0
    ref_e = {b: geom @ L for b, L in ref.items()}  # (P,) per BRDF
    # the reference's own error: its Earth of albedo 1 against the exact sphere rule (≤ 1.4e-6 at
    # θ = 20-170°, 8.2e-6 at θ = 10°), added to every component's measured error
    exact = exact_unit_earthshine(sc, x, n, o, mu, geom, brdfs)
    self_err = {b: abs(ref_e[b][0] / exact[b] - 1.0) for b in brdfs}
    out = {"observer": obs, "key": key, "earth_rotation_deg": rot, "theta_deg": sc.theta_deg, "nodes": int(len(x)),
           "reference_cells": int(len(cen)), "reference_s": ref_s, "reference_self_error": self_err, "levels": {}}
    for level in LEVELS:
        got, secs = {}, 0.0
        col = 1
        for m in MAPS:
            ls = scene_of(obs, key, rot, *m, level=level)
            ts = TraceScene(sc, ls.trace_settings(threads=1))
            ts.surfaces.earth_parts = names[m]
            t1 = time.perf_counter()
            tr = ts.mapped_earth.transport(x, n, o, mu, geom)
            secs += time.perf_counter() - t1
            eps = {}
            for c, name in enumerate(names[m]):
                part = Transport(mu0=tr.mu0, sin_hg=tr.sin_hg, cos_hg=tr.cos_hg, e_beam=tr.e_beam_parts[name],
                                 mu=tr.mu, geom=tr.geom)
                eps[name] = {b: abs(float(part.radiances(brdf)[0] @ geom) - ref_e[b][col + c]) / ref_e[b][0]
                             for b, brdf in brdfs.items()}
            eps["albedo 1"] = {b: abs(float(tr.radiances(brdf)[1] @ geom) / ref_e[b][0] - 1.0)
                               for b, brdf in brdfs.items()}
            col += len(names[m])
            got["+".join(m)] = eps
        out["levels"][level] = {"errors_vs_albedo_1": got, "transport_s": secs / len(MAPS),
                                "max": max(v for e in got.values() for c in e.values() for v in c.values())}
    print(f"{obs} {key} rot {rot:g}: theta {sc.theta_deg:.1f}, " + ", ".join(
        f"L{lv} {r['max']:.1e}" for lv, r in out["levels"].items()) + f" (reference {ref_s:.0f} s)", flush=True)
    return out


#: held-out cases (never in the tables): the paper's scene at θ and Earth turns between the
#: model's (the thin crescents' narrow peaks of turn), and nights from Big Bear
HELD_OUT = [("geocentre", th, rot) for th, rot in ((17.0, 67.5), (17.5, 78.75), (12.5, 56.25), (25.0, 67.5),
                                                  (16.0, 11.25), (18.5, 146.25), (40.0, 112.5), (11.0, 191.25),
                                                  (10.25, 33.75), (10.5, 33.75), (10.5, 11.25), (14.9, 67.5),
                                                  (20.0, 33.75), (30.0, 67.5), (60.0, 22.5), (165.0, 67.5))] \
    + [("site:34.26,-116.92,2067", key, 0.0) for key in ("2026-03-02T03:00:00Z", "2026-01-04T03:00:00Z")]


def held_out_ratios(got: list, models: dict) -> list:
    """Each held-out case's largest error over the table its θ takes
    (:func:`lunarviz.methods.accuracy.mapped_earth_tables`), per level: ``[{"observer", "key",
    "earth_rotation_deg", "theta_deg", "levels": {level: [ratio, "map component BRDF"]}}]``. A
    component with no error of its own is left out (its ratio would be the reference's own error
    over the table)."""
    from lunarviz.methods.accuracy import mapped_earth_tables
    out = []
    for r in got:
        table = mapped_earth_tables(r["theta_deg"], models)
        if table is None:
            continue
        worst = {}
        for i, lv in enumerate(LEVELS):
            for m, comps in r["levels"][lv]["errors_vs_albedo_1"].items():
                for c, by_brdf in comps.items():
                    for b, v in by_brdf.items():
                        eps = table["lambert" if b == "lambert" else "hapke"][m][c][i]
                        ratio = (v + r["reference_self_error"][b]) / eps if v > 0 else 0.0
                        if ratio > worst.get(lv, [0.0])[0]:
                            worst[lv] = [ratio, f"{m} {c} {b}"]
        out.append({k: r[k] for k in ("observer", "key", "earth_rotation_deg", "theta_deg")} | {"levels": worst})
    return out


def held_out(a) -> int:
    """``--held-out``: :data:`HELD_OUT` against the stored tables (``mapped_earth_held_out.md``)."""
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex:
        got = [r for r in ex.map(one_case, HELD_OUT) if r is not None]
    models = json.loads((ROOT / "lunarviz" / "data" / "error_models.json").read_text())["mapped_earth"]
    rows = held_out_ratios(got, models)
    res = {"rows": rows, "wall_s": time.perf_counter() - t0,
           "command": "python scripts/mapped_earth_model.py --held-out"}
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "mapped_earth_held_out.json").write_text(json.dumps(res, indent=1) + "\n")
    lines = ["# The mapped Earth's error model, held out", "",
             f"`{res['command']}` ({len(rows)} cases, {res['wall_s']:.0f} s): cases never in the tables (the "
             "paper's scene at θ and Earth turns between the model's; Big Bear nights), each component's error "
             "against the map's own cells (the reference's own error added) over the table its θ takes, the largest "
             "per level. Rows report twice the table.", "",
             "| observer | date or θ | Earth turn [deg] | θ [deg] | "
             + " | ".join(f"level {lv}" for lv in LEVELS) + " |",
             "|---|---|---|---|" + "---|" * len(LEVELS)]
    for r in rows:
        lines.append(f"| {r['observer']} | {r['key']} | {r['earth_rotation_deg']:g} | {r['theta_deg']:.1f} | "
                     + " | ".join(f"{r['levels'][lv][0]:.2f} ({r['levels'][lv][1]})" if lv in r["levels"] else "-"
                                  for lv in LEVELS) + " |")
    worst = {lv: max((r["levels"][lv][0] for r in rows if lv in r["levels"]), default=0.0) for lv in LEVELS}
    lines += ["", "Largest: " + ", ".join(f"level {lv} {w:.2f}" for lv, w in worst.items())]
    (out / "mapped_earth_held_out.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def model_table(got: list) -> dict:
    """{"lambert" | "hapke": {map: {component: [ε at each level]}}}: the largest over dates and the
    group's BRDFs (Lambert; the Hapke BRDFs, whose opposition surge the disc's cells resolve least)
    of the error against the reference plus the reference's own (its Earth of albedo 1 against
    the exact sphere rule), non-increasing with the level (refinement never loosens a bound)."""
    table = {}
    for group in ("lambert", "hapke"):
        for m in MAPS:
            key = "+".join(m)
            for name in got[0]["levels"][LEVELS[0]]["errors_vs_albedo_1"][key]:
                eps = [max(v + r["reference_self_error"][b]
                           for r in got for b, v in r["levels"][lv]["errors_vs_albedo_1"][key][name].items()
                           if (b == "lambert") == (group == "lambert")) for lv in LEVELS]
                for i in range(len(eps) - 2, -1, -1):
                    eps[i] = max(eps[i], eps[i + 1])
                table.setdefault(group, {}).setdefault(key, {})[name] = eps
    return table


def _table_lines(table: dict) -> list[str]:
    """A model table (:func:`model_table`) as markdown rows."""
    lines = ["| BRDFs | map | component | " + " | ".join(f"level {lv}" for lv in LEVELS) + " |",
             "|---|---|---|" + "---|" * len(LEVELS)]
    for group, maps in table.items():
        for m, comps in maps.items():
            lines += [f"| {group} | {m} | {c} | " + " | ".join(f"{e:.1e}" for e in eps) + " |"
                      for c, eps in comps.items()]
    return lines


def model_arguments(description: str, write: bool = True) -> argparse.ArgumentParser:
    """The command line of an Earth error model's script: ``--write`` (where it stores a model),
    ``--quick``, ``--workers``, ``--out``."""
    ap = argparse.ArgumentParser(description=description)
    if write:
        ap.add_argument("--write", action="store_true", help="store the table in lunarviz/data/error_models.json")
    ap.add_argument("--quick", action="store_true", help="a few dates (a smoke run)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "error_models"))
    ap.add_argument("--tables-from", metavar="FILE", help="rebuild the tables from an earlier run's dates (its .json)")
    return ap


def band_tables(got: list, core: list) -> list:
    """The tables of rows beyond the core dates' θ (:data:`BEYOND`): ``[{"theta_range_deg",
    "epsilon"}]``, each band taking the core's dates and the paper's scene from the core's edge out
    to the band's far end."""
    bands = []
    eps = 1e-6  # [deg] (θ of the paper's scene, computed: 15° may come back a hair under)
    for side, edges in zip((-1, 1), BEYOND):
        near = CORE[0] if side < 0 else CORE[1]
        for i, edge in enumerate(edges):
            last = i == len(edges) - 1  # (the farthest band takes every case beyond the core on its side)
            beyond = [r for r in got if (r["theta_deg"] < CORE[0] and (last or r["theta_deg"] >= edge - eps)
                                         if side < 0 else
                                         r["theta_deg"] > CORE[1] and (last or r["theta_deg"] <= edge + eps))]
            if beyond:
                th = [r["theta_deg"] for r in beyond]
                far = min(edge, round(min(th), 1)) if side < 0 else max(edge, round(max(th), 1))
                bands.append({"theta_range_deg": sorted([far, near]), "epsilon": model_table(core + beyond)})
            near = edge
    return bands


def measured_cases(a) -> tuple[list, float]:
    """The cases' results and the seconds they took: measured, or (``--tables-from``) an earlier
    run's stored cases, with the paper's scene at any θ of :func:`cases` it lacks measured now (the
    dates it lacks, it left out: their Moon hidden or the Moon's shadow possibly on the Earth)."""
    todo = cases(a.quick)
    got, wall = [], 0.0
    if a.tables_from:
        stored = json.loads(Path(a.tables_from).read_text())
        got = [dict(r, levels={int(k): v for k, v in r["levels"].items()}) for r in stored["cases"]]
        wall = stored["wall_s"]
        have = {(r["observer"], r["key"], r["earth_rotation_deg"]) for r in got}
        todo = [c for c in todo if c[0] == "geocentre" and c not in have]
    t0 = time.perf_counter()
    if todo:
        with ProcessPoolExecutor(a.workers) as ex:
            got += [r for r in ex.map(one_case, todo) if r is not None]
    return got, wall + time.perf_counter() - t0


def main(argv=None) -> int:
    ap = model_arguments(__doc__.splitlines()[0])
    ap.add_argument("--held-out", action="store_true",
                    help="check cases never in the tables against them (mapped_earth_held_out.md)")
    a = ap.parse_args(argv)
    if a.held_out:
        return held_out(a)
    got, wall = measured_cases(a)
    core = [r for r in got if CORE[0] <= r["theta_deg"] <= CORE[1]]
    table = model_table(core)
    bands = band_tables(got, core)
    seconds = [float(np.mean([r["levels"][lv]["transport_s"] for r in got])) for lv in LEVELS]
    res = {"cases": got, "table": table, "bands": bands, "seconds": seconds,
           "wall_s": wall,
           "command": "python scripts/mapped_earth_model.py" + (" --quick" if a.quick else "")
           + (f" --tables-from {a.tables_from}" if a.tables_from else "")}
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = "mapped_earth_quick" if a.quick else "mapped_earth"
    (out / f"{stem}.json").write_text(json.dumps(res, indent=1) + "\n")
    lines = ["# The mapped Earth's error model", "", f"`{res['command']}` ({len(got)} dates, "
             f"{res['wall_s']:.0f} s): the earthshine each component of a map carries, the tracer's mapped Earth "
             "(its facets at each level, the disc's cells) against the map's own cells "
             "(`lunarviz.methods.map_cell_reference`) on the same lunar points, as a share of the earthshine of an "
             "Earth of albedo 1 (ε_c); the largest over dates and lunar BRDFs (paper Lambert, SHG, DHG; "
             "rolo-fit-map's DHG), made non-increasing with the level. A row's Earth part errs by at most "
             "Σ_c α_c ε_c / A (its components' albedos α_c, its `earth_visible_lit_albedo` A).", "",
             "Each value adds the reference's own error on its date (its Earth of albedo 1 against the exact "
             "sphere rule; the per-date table below leaves it out).", "",
             f"Rows at θ = {CORE[0]:g}-{CORE[1]:g}° take the dates there:", "", *_table_lines(table)]
    for band in bands:
        lo, hi = band["theta_range_deg"]
        lines += ["", f"Rows at θ = {lo:g}-{hi:g}° take those dates and the paper's scene at "
                  f"θ = {lo if lo < CORE[0] else hi:g}°:", "", *_table_lines(band["epsilon"])]
    lines += ["", "Transport time a date (180 lunar points, mean) [s]: "
              + ", ".join(f"level {lv} {t:.2f}" for lv, t in zip(LEVELS, seconds)), "",
              "| observer | date or θ | θ [deg] | " + " | ".join(f"level {lv}" for lv in LEVELS) + " |",
              "|---|---|---|" + "---|" * len(LEVELS)]
    for r in got:
        where = r["key"] if r["observer"] != "geocentre" else f"θ {r['key']:g}, Earth {r['earth_rotation_deg']:g}°"
        lines.append(f"| {r['observer']} | {where} | {r['theta_deg']:.1f} | "
                     + " | ".join(f"{r['levels'][lv]['max']:.1e}" for lv in LEVELS) + " |")
    (out / f"{stem}.md").write_text("\n".join(lines) + "\n")
    if a.write:
        f = ROOT / "lunarviz" / "data" / "error_models.json"
        models = json.loads(f.read_text())
        # (rows outside the dates' θ carry no bound: thinner crescents err more)
        th = [r["theta_deg"] for r in core]
        models["mapped_earth"] = {"levels": list(LEVELS), "epsilon": table, "seconds": seconds,
                                  "theta_range_deg": [round(min(th), 1), round(max(th), 1)],
                                  "bands": bands,
                                  "about": "per map and component: the largest |dI_c| / I_1 over dates and lunar "
                                           "BRDFs, at each Earth level, the reference's own error added; bands: "
                                           "the tables of rows beyond the core dates' theta",
                                  "source": res["command"]}
        f.write_text(json.dumps(models, indent=1) + "\n")
    print("\n".join(lines[:8 + sum(len(c) for g in table.values() for c in g.values())]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
