"""Fit the lunar BRDFs to ROLO band by band: the spectral ``rolo-fit`` and ``rolo-fit-map`` presets.

    python scripts/fit_rolo_spectral.py          # ~15 min on 2 cores; needs the optional rimopy

At each of ROLO's 32 band wavelengths (Kieffer & Stone 2005, Table 3; rimopy's coefficients,
350-2383.6 nm) ROLO's disk reflectance (zero libration, phase 2:96:2°, waxing and waning) is fitted
by each BRDF on the same analytic disk model as the grey fit (``scripts/fit_rolo.py``, order 48,
the preset's lunar map). Free per band: w, the phase function and, on the mapped Moon, the map's
contrast k (:mod:`lunarviz.spectral.moon`: the maria's colour;
ROLO's waxing/waning asymmetry grows toward the infrared and k with it). The roughness θ̄ is one
value for all bands (a roughness that changed with λ would make every wavelength its own
shadowing geometry, which the compiled spectral shading computes once), chosen from a few
candidates by the worst rms log residual over five bands 440-1060 nm (with B0 and h free). The
opposition effect (B0, h) is also one for all bands, from a fit at 549 nm with everything free:
ROLO's phase curve starts at 2° and constrains the surge poorly band by band, while earthshine is
seen within ~1° of opposition, where band-to-band changes of B0 would show as false colour. Lambert: its albedo (a
Lambert sphere cannot fit the phase curve, rms log residual ~0.4, and drives k to 0, erasing the
map: k stays 1). The fit starts at 549 nm
from the grey preset and continues band by band outward, each band from its neighbour's
solution, so the table stays on one branch of Hapke's degeneracies and varies smoothly enough
to interpolate (parameters are linear in λ between bands).

Writes the ``spectral`` table of each preset into ``lunarviz/data/moon_models.json`` (the grey
entries untouched), ``benchmarks/rolo_fit/spectral_fit.{json,png}`` (parameters and rms log
residual per band) and ``benchmarks/rolo_fit/spectral_residuals.json`` (model/ROLO − 1 per band
and phase, both branches; ``--residuals`` rewrites only this file from the kept table).
"""

from __future__ import annotations

import csv
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "rolo_fit"
MODELS = ROOT / "lunarviz" / "data" / "moon_models.json"
PHASES = np.arange(2.0, 96.1, 2.0)
ORDER = 48
PRESETS = {"rolo-fit-map": "synthetic", "rolo-fit": None}
#: free per band (``map_contrast`` only where the preset carries a map); θ̄ is one value for all
#: bands (see the module docstring), chosen from THETA_GRID
FREE = {"dhg": ("w", "b", "c", "B0", "h", "map_contrast"), "shg": ("w", "xi", "B0", "h", "map_contrast"),
        "lambert": ("albedo",)}
#: candidate roughness θ̄ [deg] per BRDF, and the bands whose worst rms log residual chooses it
THETA_GRID = {"dhg": (32.0, 36.0, 40.0, 44.0), "shg": (8.0, 12.0, 16.0, 20.0)}
CHOOSE_NM = (441.6, 549.1, 745.3, 865.3, 1059.5)
#: the band the continuation starts from (from the grey fit), then outward band by band
START_NM = 549.1


def rolo_wavelengths() -> list[float]:
    """ROLO's 32 band wavelengths [nm], from rimopy's coefficient table."""
    import rimopy
    path = Path(rimopy.__file__).parent / "data" / "coefficients.csv"
    with open(path) as f:
        return [float(r["nm"]) for r in csv.DictReader(f)]


def fit_preset(preset: str, brdfs=tuple(FREE)) -> dict:
    from lunarviz.workflows.fit import DiskModel, fit, rolo_reflectance
    from lunarviz.photometry.presets import moon_model_params
    mp = PRESETS[preset]
    G = np.concatenate([PHASES, PHASES])
    W = np.concatenate([np.ones(len(PHASES), bool), np.zeros(len(PHASES), bool)])
    dm = DiskModel(G, order=ORDER, waxing=W, moon_map=mp)
    lams = rolo_wavelengths()
    table = {}
    i0 = lams.index(START_NM)
    for brdf in brdfs:
        free = tuple(k for k in FREE[brdf] if k != "map_contrast" or mp is not None)
        grey = moon_model_params(preset, brdf)
        if brdf in THETA_GRID:  # one roughness for every band: the compiled spectral shading's
            worst = {}
            for tb in THETA_GRID[brdf]:
                st = {**grey, "theta_bar": tb}
                worst[tb] = max(fit(brdf, G, rolo_reflectance(G, W, band=(lam, lam)), W, free=free, start=st,
                                    fixed={k: v for k, v in st.items() if k not in free}, moon_map=mp, order=ORDER,
                                    disk_model=dm).rms_log_residual for lam in CHOOSE_NM)
                print(f"{preset} {brdf} theta_bar {tb:g}: worst rms {worst[tb]:.4f}", flush=True)
            grey = {**grey, "theta_bar": min(worst, key=worst.get)}
            # the opposition effect (B0, h) is one for all bands too, from the start band's fit:
            # ROLO's 2-96° curve constrains it poorly band by band, and earthshine is seen within
            # ~1° of opposition, where B0 changing between neighbouring bands (1.32 at 939 nm,
            # 1.51 at 942 nm when free) put a false 20 % step into the earthshine/moonshine ratio
            lam0 = lams[i0]
            r0 = fit(brdf, G, rolo_reflectance(G, W, band=(lam0, lam0)), W, free=free, start=grey,
                     fixed={k: v for k, v in grey.items() if k not in free}, moon_map=mp, order=ORDER, disk_model=dm)
            grey = {**grey, **{k: r0.params[k] for k in ("B0", "h")}}
            free = tuple(k for k in free if k not in ("B0", "h"))
        results = {}
        # continuation: each band starts from its neighbour's solution (toward START_NM), so the
        # table follows one branch of Hapke's degeneracies and is smooth enough to interpolate
        for order in (range(i0, len(lams)), range(i0 - 1, -1, -1)):
            prev = dict(grey) if i0 not in results else dict(results[i0].params)
            for i in order:
                lam = lams[i]
                target = rolo_reflectance(G, W, band=(lam, lam))
                fixed = {k: v for k, v in grey.items() if k not in free}
                res = fit(brdf, G, target, W, free=free, start=prev, fixed=fixed, moon_map=mp, order=ORDER,
                          disk_model=dm)
                prev = {k: res.params[k] for k in res.params}
                results[i] = res
                print(f"{preset} {brdf} {lam:7.1f} nm: rms {res.rms_log_residual:.4f} "
                      + " ".join(f"{k}={res.params[k]:.4g}" for k in free), flush=True)
        keys = list(grey) + (["map_contrast"] if "map_contrast" in free else [])
        table[brdf] = {"wavelength_nm": lams,
                       "params": {k: [float(results[i].params[k]) for i in range(len(lams))] for k in keys},
                       "free": list(free), "rms_log_residual": [results[i].rms_log_residual for i in range(len(lams))]}
    return table


def plot(tables: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 3, figsize=(14, 4))
    for preset, tab in tables.items():
        ls = "-" if preset == "rolo-fit-map" else "--"
        for brdf, t in tab.items():
            lam = np.array(t["wavelength_nm"])
            key = "albedo" if brdf == "lambert" else "w"
            ax[0].plot(lam, t["params"][key], ls, marker=".", label=f"{preset} {brdf} {key}")
            ax[2].plot(lam, t["rms_log_residual"], ls, marker=".", label=f"{preset} {brdf}")
            if brdf == "dhg":
                for k in ("b", "c", "B0"):
                    ax[1].plot(lam, t["params"][k], ls, marker=".", label=f"{preset} dhg {k}")
    ax[0].set_ylabel("w (Hapke) or albedo (Lambert)")
    ax[1].set_ylabel("DHG b, c, B0")
    ax[2].set_ylabel("rms log residual of the fit")
    ax[2].set_title("phase 2-96°, both branches", fontsize=9)
    for a in ax:
        a.set_xlabel("wavelength [nm]")
        a.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def residuals() -> dict:
    """Per preset, BRDF and band: the kept table's model/ROLO − 1 at every fitted phase (both
    branches), from the table itself (``--residuals`` rewrites only this file)."""
    from lunarviz.photometry.brdf import make_brdf
    from lunarviz.workflows.fit import DiskModel, rolo_reflectance
    from lunarviz.spectral.moon import MAP_CONTRAST, parameters_at
    G = np.concatenate([PHASES, PHASES])
    W = np.concatenate([np.ones(len(PHASES), bool), np.zeros(len(PHASES), bool)])
    out = {"phase_deg": G.tolist(), "waxing": W.tolist()}
    for preset, mp in PRESETS.items():
        dm = DiskModel(G, order=ORDER, waxing=W, moon_map=mp)
        out[preset] = {}
        for brdf in FREE:
            lams = rolo_wavelengths()
            par = parameters_at(preset, brdf, lams)
            rows = []
            for i, lam in enumerate(lams):
                p = {k: float(v[i]) for k, v in par.items()}
                k = p.pop(MAP_CONTRAST, 1.0)
                m = dm.reflectance(make_brdf(brdf, params=p), k)
                r = m / rolo_reflectance(G, W, band=(lam, lam)) - 1
                rows.append({"wavelength_nm": lam, "max_abs_to_90deg": float(np.abs(r[G <= 90]).max()),
                             "relative_residual": [float(x) for x in r]})
            out[preset][brdf] = rows
    return out


def main() -> int:
    if "--plot-only" in sys.argv:  # redraw spectral_fit.png from the kept spectral_fit.json
        plot(json.loads((OUT / "spectral_fit.json").read_text()), OUT / "spectral_fit.png")
        return 0
    if "--residuals" in sys.argv:
        (OUT / "spectral_residuals.json").write_text(json.dumps(residuals()) + "\n")
        return 0
    with ProcessPoolExecutor(2) as ex:
        tables = dict(zip(PRESETS, ex.map(fit_preset, PRESETS)))
    models = json.loads(MODELS.read_text())
    for preset, tab in tables.items():
        models["models"][preset]["spectral"] = tab
    models["spectral_provenance"] = (
        "scripts/fit_rolo_spectral.py: each BRDF fitted to ROLO (Kieffer & Stone 2005, rimopy) at each of its 32 "
        "band wavelengths, phase 2:96:2 deg both branches, zero libration, analytic disk model order "
        f"{ORDER}; free per band: dhg w, b, c, map_contrast; shg w, xi, map_contrast; lambert albedo "
        "(map_contrast only on the mapped Moon); theta_bar one value per BRDF chosen over 5 bands, B0 and h one "
        "value per BRDF from a 549.1 nm fit with them free; the other parameters at the grey fit's values; each "
        "entry's own 'free' lists its band-by-band parameters")
    MODELS.write_text(json.dumps(models, indent=2) + "\n")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "spectral_fit.json").write_text(json.dumps(tables, indent=1) + "\n")
    plot(tables, OUT / "spectral_fit.png")
    (OUT / "spectral_residuals.json").write_text(json.dumps(residuals()) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
