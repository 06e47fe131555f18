"""Measure the mapped lune rule's error model and add it to the error models.

    python scripts/mapped_lune_models.py [--quick]

The lune rule on ``rolo-fit-map`` (its rough Hapke presets on the synthetic lunar map;
:mod:`lunarviz.geometry.mapped_lune`): for each lune order, the largest relative error of the
moonshine and of the earthshine over the paper's scene (θ = 5-175° every 5°, lambert, shg and
dhg, no occlusion) and its time per phase (one thread), against the same rule at order 128 with
finer sums over the cells that the rule's edges cut (8 lines and points), every block at the full
order (no thin blocks: ``mapped_lune.THIN_WIDTH``), every whole cell by its own rule (no
panels: ``mapped_lune.PANEL_CELLS``) and finer source rules (Sun order 4, Earth
order 12). The reference's own error is estimated phase by phase from the same reference at
order 96 and added to every row's error there: DHG (θ̄ = 45°) converges slowest, as order^-1.8
near full Moon to order^-3 (a fit to the rows at θ = 10-25°), so with order^-p, p =
:data:`SLOWEST_RATE` = 1.5, the order-128 reference errs by at most r/(1 - r) |ref₉₆ - ref₁₂₈|,
r = (96/128)^p: 1.85 times the two references' difference (1.8e-6 at θ = 15-25°). A reference at
order 48 errs by 1.1e-5 there. Both sides sum the whole cells outside panels by the same rectangle rule (its
error, exact for cubics: ≤ 1e-6 against the plain lune rule for a constant map, tests). Writes the
``raytrace_lune_mapped`` section of ``lunarviz/data/error_models.json`` (the rest is kept) and
``benchmarks/error_models/mapped_lune.md``. Independent checks of the rule itself (a brute-force
sum over the map's cells, the facets, Embree stubbed): ``tests/test_mapped_lune.py``.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BRDFS = ("lambert", "shg", "dhg")
PATHS = {"moonshine": "sun", "earthshine": "earth"}
SOURCE = {"moonshine": "sun_order", "earthshine": "earth_order"}
ORDERS = (8, 12, 16, 20, 24, 32, 48, 64, 96)
#: the source orders measured with each lune order (the Sun's 2; the Earth's 7: at 6 the
#: earthshine erred by 5.6-8.8e-5 at lune orders 20-32 in this model, where the plain lune rule's
#: 1.7e-5 would have left room)
SOURCE_ORDERS = ({"sun_order": 2, "earth_order": 7},)
REFERENCE = {"lune_order": 128, "sun_order": 4, "earth_order": 12}
#: the reference's own convergence is measured against it at this lune order (same sources and sums)
REFERENCE_COARSE_ORDER = 96
#: the slowest rate (error ∝ order^-p) assumed of the reference's own convergence (fits at θ = 10-25°: 1.8-2.1)
SLOWEST_RATE = 1.5
REFERENCE_EDGE_NODES = 8
#: the reference rule's own settings (mapped_lune_rule's keywords): finer cut-cell sums, full
#: orders, 8 albedo nodes in γ (3e-11 in the reflectance, mapped_lune.GAMMA_NODES)
REFERENCE_RULE = {"edge_nodes": REFERENCE_EDGE_NODES, "thin": False, "panels": False, "albedo_nodes": 8,
                  "cut_rings": True}
#: the phases measured [deg]: every 5° (each row keeps its error at each, ``errors_by_phase``: a
#: date takes the orders that its own θ's neighbours need, accuracy.trace_choice)
PHASES = tuple(float(t) for t in range(5, 176, 5))


def with_rule(rule: dict | None, fn):
    """``fn()`` with the mapped lune rule's keyword defaults set to ``rule`` (the others kept)."""
    from lunarviz.geometry import mapped_lune
    saved = mapped_lune.mapped_lune_rule.__defaults__
    if rule:
        import inspect
        names = [p for p, v in inspect.signature(mapped_lune.mapped_lune_rule).parameters.items()
                 if v.default is not inspect.Parameter.empty]
        mapped_lune.mapped_lune_rule.__defaults__ = tuple(rule.get(n, d) for n, d in zip(names, saved))
    try:
        return fn()
    finally:
        mapped_lune.mapped_lune_rule.__defaults__ = saved


def _run(phases, base, brdfs, settings: dict, rule: dict | None = None) -> dict:
    """{(path, θ): (means, seconds, rays)} with the mapped lune rule at ``settings``."""
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.methods.tracer.estimators import TraceScene, trace_path

    def run():
        out = {}
        for th in phases:
            for path, body in PATHS.items():
                ts = TraceScene(SceneGeometry(th), replace(base, **settings))
                t0 = time.perf_counter()
                r = trace_path(ts, path, brdfs)
                if not ts.sampling.lune_rule_applies(body):
                    raise SystemExit(f"θ = {th}: the mapped lune rule does not apply")
                out[(path, th)] = (r.mean, time.perf_counter() - t0, r.rays)
        return out
    return with_rule(rule, run)


def measure(phases, orders) -> dict:
    import lunarviz
    st = lunarviz.Scene(phases=list(phases), moon_model="rolo-fit-map", brdfs=list(BRDFS)).settings("raytrace")
    brdfs = st.brdf_models()
    base = replace(st.trace_settings(threads=1), occlusion=False)
    ref = _run(phases, base, brdfs, REFERENCE, REFERENCE_RULE)
    coarse = _run(phases, base, brdfs, {**REFERENCE, "lune_order": REFERENCE_COARSE_ORDER}, REFERENCE_RULE)
    ratio = (REFERENCE_COARSE_ORDER / REFERENCE["lune_order"]) ** SLOWEST_RATE
    ref_error = {key: ratio / (1.0 - ratio) * max(abs(coarse[key][0][k] / ref[key][0][k] - 1.0) for k in BRDFS)
                 for key in ref}
    rows = {p: [] for p in PATHS}
    for sources in SOURCE_ORDERS:
        for o in orders:
            got = _run(phases, base, brdfs, {"lune_order": o, **sources})
            for p in PATHS:
                if any(r["lune_order"] == o and r[SOURCE[p]] == sources[SOURCE[p]] for r in rows[p]):
                    continue  # (this path's source order measured already)
                by_phase = [max(abs(got[(p, th)][0][k] / ref[(p, th)][0][k] - 1.0) for k in BRDFS)
                            + ref_error[(p, th)] for th in phases]
                rows[p].append({"lune_order": o, SOURCE[p]: sources[SOURCE[p]], "max_rel_error": max(by_phase),
                                "phases_deg": list(phases), "errors_by_phase": by_phase,
                                "reference_error_by_phase": [ref_error[(p, th)] for th in phases],
                                "rays_per_phase": float(np.mean([got[(p, th)][2] for th in phases])),
                                "seconds_per_phase": float(np.mean([got[(p, th)][1] for th in phases]))})
    return rows


def _by_phase_table(rows: dict, phases) -> list:
    """The errors at each phase (the rows' ``errors_by_phase``): what a date's own θ chooses from."""
    out = ["", "Largest relative error over the BRDFs at each phase, the reference's own estimated error "
           "included (a date's orders come from its θ's neighbours: accuracy.trace_choice); the last two "
           "columns: that estimate, moonshine and earthshine:", ""]
    cols = [(p, r) for p, rs in rows.items() for r in rs]
    ref_cols = [rs[0]["reference_error_by_phase"] for rs in rows.values()]
    heads = [f"{p[:5]} {r['lune_order']}" for p, r in cols] + ["ref moons", "ref earth"]
    out.append("| θ [deg] | " + " | ".join(heads) + " |")
    out.append("| --- " * (len(cols) + 3) + "|")
    for i, th in enumerate(phases):
        out.append(f"| {th:g} | " + " | ".join(f"{r['errors_by_phase'][i]:.1e}" for _, r in cols)
                   + " | " + " | ".join(f"{c[i]:.1e}" for c in ref_cols) + " |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="three phases, two orders; print only")
    a = ap.parse_args(argv)
    phases = (30.0, 90.0, 150.0) if a.quick else PHASES
    orders = (8, 12) if a.quick else ORDERS
    t0 = time.perf_counter()
    rows = measure(phases, orders)
    wall = time.perf_counter() - t0
    lines = ["# The mapped lune rule's error model", "",
             f"`python scripts/mapped_lune_models.py` ({wall:.0f} s, one thread): `rolo-fit-map` (rough Hapke on the "
             f"synthetic map), θ = {phases[0]:g}-{phases[-1]:g}° ({len(phases)} phases), {', '.join(BRDFS)}, no "
             f"occlusion; error against lune order {REFERENCE['lune_order']}, Sun order {REFERENCE['sun_order']}, "
             f"Earth "
             f"order {REFERENCE['earth_order']}, {REFERENCE_EDGE_NODES} lines and points a piece in cut cells, "
             f"every block at full order (no thin blocks), cells cut at the t-rings too, 8 albedo nodes in γ; "
             f"each error includes the reference's own, estimated from the same reference at order "
             f"{REFERENCE_COARSE_ORDER} (error ∝ order^-{SLOWEST_RATE:g}).",
             "",
             "| path | lune order | source order | max relative error | rays per phase | seconds per phase |",
             "| --- | --- | --- | --- | --- | --- |"]
    for path, rs in rows.items():
        for r in rs:
            lines.append(f"| {path} | {r['lune_order']} | {r[SOURCE[path]]} | {r['max_rel_error']:.1e} | "
                         f"{r['rays_per_phase']:.0f} | {r['seconds_per_phase']:.3f} |")
    lines += _by_phase_table(rows, phases)
    text = "\n".join(lines) + "\n"
    print(text)
    if a.quick:
        return 0
    f = ROOT / "lunarviz" / "data" / "error_models.json"
    models = json.loads(f.read_text())
    models["raytrace_lune_mapped"] = rows
    f.write_text(json.dumps(models, indent=1) + "\n")
    (ROOT / "benchmarks" / "error_models" / "mapped_lune.md").write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
