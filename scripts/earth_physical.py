"""The physical Earth: its reflectance against independent codes,
its phase function and what the Lambert assumption does to the inferred albedo, and the colour of
the earthshine.

    python scripts/earth_physical.py [--out benchmarks/earth_physical] [--quick]

Writes ``results.json``, ``report.md``, ``phase_function.png`` and ``colour.png``:

* validation: ``lunarviz brdf --body earth``'s TOA reflectance factor for a Rayleigh atmosphere over a
  black surface and over a Lambert surface of 0.3 against disortpp (a DISORT written apart from the
  CDISORT that made the tables), and over the ocean at 7 m/s against a forward Monte Carlo with
  local estimates (tests/rt_reference.py), at 450, 550, 865 nm, solar zenith 30° and 60°, view
  zenith 0–70°, azimuths 0, 90, 180°; the glint lobe is where the bare glint is ≥ 10 % of the total;
* phase function (a crescent Earth, β ≳ 140°, is lit and seen at grazing angles, where the
  plane-parallel atmosphere held at 89° is not valid: a(β) there is indicative): the model Earth
  (landocean, zonal clouds, physical, 550 nm; the θ scene, an equinox) and the same map as
  Lambert facets: apparent albedo a(β) (what a geocentric detector's earthshine inverts to, p*),
  Bond and geometric albedo, the bias of reading one night's p* as the Bond albedo (the Lambert
  assumption: a Lambert Earth's p* is its Bond albedo at every β), Eq. 17 with every β sampled,
  and with only 30–150° observed (held constant beyond, or extrapolated with a model's phase
  function, the uniform physical Earth's); a year (geocentric, DE421): per month, the nights with
  β in 40–140° against that month's Bond albedo;
* colour: Δ(B−V) = (B−V)_earthshine − (B−V)_moonshine over a lunation from Mauna Loa (the site of
  Thejll et al. 2014, A&A 563, A38, who measured −0.150 ± 0.005 mag), ROLO-fitted Moon with its
  phase reddening (``--moon-model rolo-fit-map``), the physical Earth and the Lambert one.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))  # the independent references live with the tests
sys.path.insert(0, str(ROOT / "scripts"))
from earth_phase_curve import SUN_B_MINUS_V  # noqa: E402 (the Sun's B − V both colour figures take)

VIEW_ZENITH = np.arange(0.0, 71.0, 10.0)
AZIMUTHS = np.array([0.0, 90.0, 180.0])
MAUNA_LOA = "site:19.536,-155.576,3397"
#: the Moon's lowest altitude kept [deg]
MIN_ALTITUDE_DEG = 15.0
THEJLL_2014 = {"delta_b_minus_v": -0.150, "sigma": 0.005,
               "source": "Thejll et al. 2014, A&A 563, A38 (Mauna Loa, B and V CCD images)"}


def validation(quick: bool) -> list[dict]:
    from rt_reference import disortpp_toa, monte_carlo_toa, sample_rayleigh_cos

    from lunarviz.earth_optics import rayleigh
    from lunarviz.earth_optics.ocean import glint, ocean_reflectance
    from lunarviz.earth_optics.classes import surface_from_name, toa_reflectance
    mu = np.cos(np.radians(VIEW_ZENITH))
    out = []
    for name in ("black", "lambert:0.3", "ocean"):
        s = surface_from_name(name)
        for lam in (450.0, 550.0, 865.0):
            tau = float(rayleigh.optical_depth(lam))
            for sza in (30.0, 60.0):
                mu0 = math.cos(math.radians(sza))
                # the references know no ozone: the scattering is compared (the ozone above it is
                # a factor, checked against its closed form in tests/test_earth_own_albedos.py)
                got = toa_reflectance(s, lam, mu0, mu[:, None], AZIMUTHS[None, :], params={"ozone_du": 0.0})
                if name == "ocean":
                    ref = monte_carlo_toa(tau, mu0, mu, AZIMUTHS, lambda a, b, c: ocean_reflectance(lam, a, b, c, 7.0),
                                          rayleigh.phase_function, sample_rayleigh_cos(rayleigh.gamma()),
                                          photons=100_000 if quick else 1_200_000, seed=7)
                    lobe = glint(mu0, mu[:, None], AZIMUTHS[None, :], 7.0) >= 0.1 * got
                    code = "Monte Carlo (local estimates)"
                else:
                    ref = disortpp_toa(tau, mu0, mu, AZIMUTHS, albedo=0.0 if name == "black" else 0.3,
                                       moments=[1.0, 0.0, rayleigh.legendre_moment_2()])
                    lobe = np.zeros(got.shape, bool)
                    code = "disortpp"
                err = got / ref - 1
                out.append({"surface": name, "wavelength_nm": lam, "sza_deg": sza, "reference": code,
                            "max_abs_error_outside_lobe": float(np.abs(err[~lobe]).max()),
                            "max_abs_error_in_lobe": float(np.abs(err[lobe]).max()) if lobe.any() else None,
                            "rms_error": float(np.sqrt(np.mean(err**2)))})
    return out


def phase_function(quick: bool) -> dict:
    from lunarviz.surfaces.earth_albedos import earth_albedos
    from lunarviz.surfaces.physical_earth import apparent_albedo
    from lunarviz.surfaces.earth_surface import EarthSurface
    from lunarviz.surfaces.maps import map_frame
    from lunarviz.surfaces.point_values import Surfaces
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.photometry.albedo_inversion import bond_albedo as eq17
    sc = SceneGeometry(90.0)
    frame = map_frame(sc, "earth", 0.0)
    phys = EarthSurface(earth_surface="landocean", clouds="zonal", earth_brdf="physical")
    lamb = Surfaces(None, EarthSurface(earth_surface="landocean", clouds="zonal"), 0.0)
    betas = np.array([30.0, 90.0, 150.0]) if quick else np.arange(5.0, 176.0, 10.0)
    a_phys = np.array([apparent_albedo(phys, sc, frame, b, 0.0, 550.0) for b in betas])
    from lunarviz.surfaces.physical_earth import _direction
    far = 1e3 * np.linalg.norm(sc.moon - sc.earth)
    a_lamb = np.array([lamb.earth_albedo_toward(sc, sc.earth + far * _direction(sc, b, 0.0)) for b in betas])
    own = earth_albedos(phys, sc, frame, [550.0])  # (exact over every direction: not the sampled β)
    bond, geometric = float(own["spherical"][0]), float(own["geometric"][0])
    # Eq. 17 from p*(β) in the Moon's plane: every 5° (all of a lunation), and 30–150° only
    full = np.arange(0.0, 181.0, 30.0 if quick else 5.0)
    p_full = np.array([apparent_albedo(phys, sc, frame, max(b, 0.5), 0.0, 550.0) for b in full])
    seen = (full >= 30.0) & (full <= 150.0)
    held = np.interp(full, full[seen], p_full[seen])  # held constant beyond the observed range
    # or extrapolated with a model's phase function: the uniform physical Earth (Lambert 0.3 under
    # the Rayleigh layer), scaled to the observed p*
    uniform = EarthSurface(earth_brdf="physical")
    shape = np.array([apparent_albedo(uniform, sc, frame, max(b, 0.5), 0.0, 550.0) for b in full])
    k = float(np.mean(p_full[seen] / shape[seen]))
    modelled = np.where(seen, p_full, k * shape)
    return {"scene": "theta scene (equinox), landocean + zonal clouds, 550 nm, viewer in the Moon's plane",
            "beta_deg": betas.tolist(), "apparent_albedo_physical": a_phys.tolist(),
            "apparent_albedo_lambert": a_lamb.tolist(), "bond_albedo_physical": bond,
            "geometric_albedo_physical": geometric,
            "lambert_assumption_bias": (a_phys / bond - 1).tolist(),
            "eq17_all_beta": eq17(full, p_full), "eq17_30_150_held": eq17(full, held),
            "eq17_30_150_model_shape": eq17(full, modelled)}


def year(quick: bool) -> list[dict]:
    """Per month of 2026 (geocentric): the Bond albedo on the 15th, and p* on every day whose Earth
    phase angle is in the range where earthshine is measured (β 40–140°)."""
    import lunarviz
    from lunarviz.surfaces.earth_albedos import earth_albedos
    from lunarviz.surfaces.physical_earth import albedo_toward_moon
    from lunarviz.surfaces.earth_surface import EarthSurface
    from lunarviz.surfaces.maps import map_frame
    from lunarviz.surfaces.point_values import Surfaces
    phys = EarthSurface(earth_surface="landocean", clouds="zonal", earth_brdf="physical")
    surfaces = Surfaces(None, phys, 0.0)
    rows = []
    for m in ((1, 7) if quick else range(1, 13)):
        sc, _ = lunarviz.Scene(time=f"2026-{m:02d}-15T00:00Z").geometry()
        bond = float(earth_albedos(phys, sc, map_frame(sc, "earth", 0.0), [550.0])["spherical"][0])
        bias = []
        for day in ((5, 20) if quick else range(1, 29)):
            sc, _ = lunarviz.Scene(time=f"2026-{m:02d}-{day:02d}T00:00Z").geometry()
            if 40.0 <= sc.beta_deg <= 140.0:
                bias.append(float(albedo_toward_moon(surfaces, sc, [550.0])[0]) / bond - 1)
        rows.append({"month": f"2026-{m:02d}", "bond_albedo": bond, "nights": len(bias),
                     "bias_min": min(bias, default=float("nan")), "bias_max": max(bias, default=float("nan")),
                     "bias_mean": float(np.mean(bias)) if bias else float("nan")})
    return rows


def colour(quick: bool) -> dict:
    import lunarviz
    span = "2026-03-24T06:00,2026-03-26T06:00,2d" if quick else "2026-03-20T06:00,2026-04-17T18:00,12h"
    out = {}
    for brdf_earth in ("physical", "lambert"):
        res = lunarviz.run(method="analytic", time_range=span, observer=MAUNA_LOA, brdfs=("dhg",),
                           moon_model="rolo-fit-map", earth_surface="landocean", clouds="zonal",
                           earth_brdf=brdf_earth, bands="B,V")
        by: dict = {}
        for r in res["rows"]:
            by.setdefault(r["time_utc"], {})[r["band"]] = r
        rows = []
        for t, d in sorted(by.items()):
            if d["V"]["moon_altitude_deg"] < MIN_ALTITUDE_DEG or d["V"]["earthshine_W_m2"] <= 0:
                continue  # the Moon below the site's horizon (or too low to observe)
            es = d["B"]["earthshine_W_m2"] / d["V"]["earthshine_W_m2"]
            ms = d["B"]["moonshine_W_m2"] / d["V"]["moonshine_W_m2"]
            # the Earth's own colour toward the Moon that night (its B over V albedo toward it) and
            # what is left of Δ(B−V): the Moon's reddening of the earthshine (lunar phase ~0°) less
            # its reddening of the moonshine (at α)
            earth = SUN_B_MINUS_V - 2.5 * math.log10(d["B"]["earth_visible_lit_albedo"]
                                                     / d["V"]["earth_visible_lit_albedo"])
            delta = -2.5 * math.log10(es / ms)
            rows.append({"time": t, "alpha_deg": d["V"]["alpha_deg"], "beta_deg": d["V"]["beta_deg"],
                         "delta_b_minus_v": delta, "earth_b_minus_v": earth,
                         "moon_term": delta - (earth - SUN_B_MINUS_V)})
        out[brdf_earth] = rows
    return out


def _plots(out: Path, r: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    pf = r["phase_function"]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].semilogy(pf["beta_deg"], pf["apparent_albedo_physical"], "o-", label="physical Earth: a(β) = p*")
    ax[0].semilogy(pf["beta_deg"], pf["apparent_albedo_lambert"], "s--", label="same map, Lambert facets")
    ax[0].axhline(pf["bond_albedo_physical"], color="k", lw=0.8, label="physical Earth's Bond albedo")
    ax[0].set(xlabel="Earth phase angle β [deg]", ylabel="apparent albedo p* (log scale)", title="550 nm, equinox")
    ax[0].legend(fontsize=8)
    ax[1].semilogy(pf["beta_deg"], np.array(pf["apparent_albedo_physical"]) / pf["bond_albedo_physical"], "o-")
    ax[1].axhline(1.0, color="k", lw=0.8)
    ax[1].set(xlabel="Earth phase angle β [deg]", ylabel="p* / A_B (log scale)",
              title="one night's p* read as the Bond albedo")
    ax[1].text(0.03, 0.97, "p*: the albedo of the Lambert sphere that\nsends the same light. Toward a crescent\n"
               "(β → 180°) that sphere's light f_L(β) → 0,\nthe real Earth's forward scattering (glint,\n"
               "cloud and haze peaks) does not: p*/A_B\nreaches 20× at β = 175°",
               transform=ax[1].transAxes, va="top", fontsize=7.5)
    fig.tight_layout()
    fig.savefig(out / "phase_function.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(6, 4))
    for k, style in (("physical", "o-"), ("lambert", "s--")):
        rows = sorted(r["colour"][k], key=lambda x: x["alpha_deg"])  # (drawn along the phase, not the date)
        ax.plot([x["alpha_deg"] for x in rows], [x["delta_b_minus_v"] for x in rows], style, label=f"{k} Earth")
    ob = THEJLL_2014
    ax.axhspan(ob["delta_b_minus_v"] - ob["sigma"], ob["delta_b_minus_v"] + ob["sigma"], color="0.8",
               label="Thejll et al. 2014")
    ax.set(xlabel="lunar phase angle [deg]", ylabel="Δ(B−V) earthshine − moonshine [mag]",
           title="Mauna Loa, March–April 2026")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "colour.png", dpi=120)
    plt.close(fig)


def _report(r: dict) -> str:
    flag = " --quick" if r["quick"] else ""
    lines = ["# The physical Earth", "", f"Made by `python scripts/earth_physical.py{flag}` "
             f"in {r['seconds']:.0f} s.", "", "## TOA reflectance against independent codes", "",
             "| surface | λ [nm] | SZA | reference | max |err| outside lobe | max |err| in lobe | rms |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for v in r["validation"]:
        lobe = "" if v["max_abs_error_in_lobe"] is None else f"{100 * v['max_abs_error_in_lobe']:.2f} %"
        lines.append(f"| {v['surface']} | {v['wavelength_nm']:g} | {v['sza_deg']:g}° | {v['reference']} | "
                     f"{100 * v['max_abs_error_outside_lobe']:.2f} % | {lobe} | {100 * v['rms_error']:.2f} % |")
    pf = r["phase_function"]
    lines += ["", "## Phase function and the inversion", "", pf["scene"], "",
              f"Bond albedo {pf['bond_albedo_physical']:.4f}, geometric albedo {pf['geometric_albedo_physical']:.4f}; "
              f"Eq. 17 with p* at every β: {pf['eq17_all_beta']:.4f}; with β 30–150° observed and held beyond: "
              f"{pf['eq17_30_150_held']:.4f}; with the model's phase function: {pf['eq17_30_150_model_shape']:.4f}.",
              "", "| β [deg] | p* physical | p* Lambert facets | p*/A_B − 1 |", "| --- | --- | --- | --- |"]
    for b, a, lam, bias in zip(pf["beta_deg"], pf["apparent_albedo_physical"], pf["apparent_albedo_lambert"],
                               pf["lambert_assumption_bias"]):
        lines.append(f"| {b:g} | {a:.4f} | {lam:.4f} | {100 * bias:+.1f} % |")
    lines += ["", "A year (geocentric; each night at 0 h UTC with the Earth's phase angle in 40–140°, "
              "against the month's Bond albedo on the 15th):", "",
              "| month | Bond | nights | p*/A_B − 1 min | mean | max |", "| --- | --- | --- | --- | --- | --- |"]
    for y in r["year"]:
        lines.append(f"| {y['month']} | {y['bond_albedo']:.4f} | {y['nights']} | {100 * y['bias_min']:+.1f} % | "
                     f"{100 * y['bias_mean']:+.1f} % | {100 * y['bias_max']:+.1f} % |")
    lines += ["", "## Colour of the earthshine (Mauna Loa)", "",
              f"Observed: Δ(B−V) = {THEJLL_2014['delta_b_minus_v']} ± {THEJLL_2014['sigma']} mag "
              f"({THEJLL_2014['source']}).",
              f"The Earth's own B − V toward the Moon (the Sun's {SUN_B_MINUS_V} less 2.5 log₁₀ of its B over V "
              "albedo toward it): observed 0.44 ± 0.02 (the same paper). Δ(B−V) = (Earth − Sun) + the Moon's term "
              "(its reddening of the earthshine, seen near a lunar phase of 0°, less that of the moonshine).",
              "", "| time | lunar phase angle | Earth phase | Δ(B−V) physical | Earth B − V | the Moon's term | "
              "Δ(B−V) Lambert |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for p, q in zip(r["colour"]["physical"], r["colour"]["lambert"]):
        lines.append(f"| {p['time']} | {p['alpha_deg']:.1f}° | {p['beta_deg']:.1f}° | {p['delta_b_minus_v']:+.3f} | "
                     f"{p['earth_b_minus_v']:.3f} | {p['moon_term']:+.3f} | {q['delta_b_minus_v']:+.3f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "earth_physical"))
    ap.add_argument("--quick", action="store_true", help="a smoke run: fewer photons, angles, dates")
    ap.add_argument("--plot-only", action="store_true", help="redraw the figures from the kept results.json")
    a = ap.parse_args(argv)
    if a.plot_only:
        _plots(Path(a.out), json.loads((Path(a.out) / "results.json").read_text()))
        return 0
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    r = {"quick": a.quick, "validation": validation(a.quick), "phase_function": phase_function(a.quick),
         "year": year(a.quick), "colour": colour(a.quick)}
    r["seconds"] = time.perf_counter() - t0
    (out / "results.json").write_text(json.dumps(r, indent=1) + "\n")
    (out / "report.md").write_text(_report(r))
    _plots(out, r)
    print(f"wrote {out}/results.json, report.md, phase_function.png, colour.png ({r['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
