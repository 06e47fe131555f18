"""The model Earth's visual phase curve against the Earth's observed one: geometric albedo p,
spherical albedo A_s and phase integral q = A_s / p in the V band.

    python scripts/earth_phase_curve.py [--out benchmarks/earth_physical] [--quick]

Observed (the Earth's visual values from ground-based earthshine and spacecraft phase curves):
p = 0.242, A_s = 0.294, q = 1.22 (Robinson 2025, *Inferring and interpreting the visual geometric
albedo and phase function of Earth*). Model: ``lunarviz.surfaces.earth_albedos`` (exact over every
direction; not Eq. 17) of the physical Earth (``--earth-brdf physical``, land–ocean map, zonal
clouds) in the θ scene (an equinox), V band (Bessell; solar- and response-weighted), at the
default cloud optical depth and, as a sensitivity (not a fit), at others; and with no clouds.
Also the Earth's B − V from its B and V albedos, against Thejll et al. (2014)'s 0.44 ± 0.02.
Writes ``phase_curve.json`` and ``phase_curve.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OBSERVED = {"geometric_albedo": 0.242, "spherical_albedo": 0.294, "phase_integral": 1.22,
            "source": "Robinson 2025, Inferring and interpreting the visual geometric albedo and phase function "
                      "of Earth (ground-based earthshine and spacecraft phase curves)",
            "earth_b_minus_v": 0.44, "earth_b_minus_v_sigma": 0.02,
            "colour_source": "Thejll et al. 2014, A&A 563, A38 (earthshine, Mauna Loa)"}
#: the Sun's B − V (Ramírez et al. 2012, ApJ 752, 5: 0.653 ± 0.003): the Earth's colour is the Sun's
#: reddened or blued by the ratio of its B and V albedos
SUN_B_MINUS_V = 0.653
TAUS = (2.0, 3.6, 6.0, 10.0, 23.0)


def model(clouds: str, tau: float | None, band: str = "V") -> dict:
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.earth_own_albedos import run_earth_albedos
    params = {"earth": {} if tau is None else {"cloud_optical_depth": tau}}
    s = ResolvedScene(phases_deg=(90.0,), bands=("B", band), earth_brdf="physical", earth_surface="landocean",
                      clouds=clouds, params=params)
    t = time.perf_counter()
    a = run_earth_albedos(s)
    colour = {f"earth_b_minus_v_{k}": SUN_B_MINUS_V - 2.5 * math.log10(a[f"earth_{k}_albedo"]["B"]
                                                                        / a[f"earth_{k}_albedo"][band])
              for k in ("spherical", "geometric")}
    return {"clouds": clouds, "cloud_optical_depth": tau, "band": band, **colour,
            "geometric_albedo": a["earth_geometric_albedo"][band],
            "spherical_albedo": a["earth_spherical_albedo"][band],
            "phase_integral": a["earth_phase_integral"][band], "seconds": time.perf_counter() - t}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "earth_physical"))
    ap.add_argument("--quick", action="store_true", help="the default optical depth only")
    a = ap.parse_args(argv)
    from lunarviz.options import EARTH_PARAMETER_DEFAULTS
    default_tau = EARTH_PARAMETER_DEFAULTS["cloud_optical_depth"]
    rows = [model("zonal", None, "V")]
    rows += [model("zonal", t, "V") for t in ([] if a.quick else TAUS) if t != default_tau]
    rows.append(model("none", None, "V"))
    for r in rows:
        print(f"{r['clouds']:6s} τ={r['cloud_optical_depth'] or default_tau:5g}: p {r['geometric_albedo']:.4f}  "
              f"A_s {r['spherical_albedo']:.4f}  q {r['phase_integral']:.4f}  B−V {r['earth_b_minus_v_spherical']:.3f} "
              f"({r['seconds']:.0f} s)", flush=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "phase_curve.json").write_text(json.dumps({"observed": OBSERVED, "model": rows}, indent=1))
    lines = ["# The model Earth's visual phase curve against the observed one", "",
             "`python scripts/earth_phase_curve.py`: the physical Earth (land–ocean, zonal clouds of liquid droplets "
             "with their Mie phase function), the θ scene's equinox, V band; exact over every direction "
             "(`lunarviz.surfaces.earth_albedos`), not Eq. 17.", "",
             f"Observed: p = {OBSERVED['geometric_albedo']}, A_s = {OBSERVED['spherical_albedo']}, "
             f"q = {OBSERVED['phase_integral']} ({OBSERVED['source']}).", "",
             f"The Earth's B − V: the Sun's ({SUN_B_MINUS_V}, Ramírez et al. 2012) − 2.5 log₁₀ of the ratio of its "
             "B and V albedos (spherical: the reflected light of every phase; geometric: the full Earth); observed "
             f"{OBSERVED['earth_b_minus_v']} ± {OBSERVED['earth_b_minus_v_sigma']} ({OBSERVED['colour_source']}).", "",
             "| clouds | optical depth | p | A_s | q | p/obs − 1 | A_s/obs − 1 | q/obs − 1 | B − V (A_s) | B − V (p) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        tau = "—" if r["clouds"] == "none" else f"{r['cloud_optical_depth'] or default_tau:g}" + (
            " (default)" if r["cloud_optical_depth"] is None else "")
        lines.append(f"| {r['clouds']} | {tau} | {r['geometric_albedo']:.4f} | {r['spherical_albedo']:.4f} | "
                     f"{r['phase_integral']:.4f} | {r['geometric_albedo'] / OBSERVED['geometric_albedo'] - 1:+.1%} | "
                     f"{r['spherical_albedo'] / OBSERVED['spherical_albedo'] - 1:+.1%} | "
                     f"{r['phase_integral'] / OBSERVED['phase_integral'] - 1:+.1%} | "
                     f"{r['earth_b_minus_v_spherical']:.3f} | {r['earth_b_minus_v_geometric']:.3f} |")
    lines += ["", "The other optical depths are a sensitivity, not a fit: every place's cloud has one optical depth "
              "here, where the observed clouds have a distribution of them (a climatology is not shipped)."]
    (out / "phase_curve.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out / 'phase_curve.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
