"""Pictures of lunarviz in colour: spectra of moonshine and earthshine per phase, and the Moon in three bands.

    python scripts/spectral_figures.py          # ~1 min

Writes ``benchmarks/spectral/``:

* ``spectrum.png`` and ``spectrum.json``: moonshine and earthshine [W m⁻² nm⁻¹] at the
  geocentre, 400-1000 nm every 10 nm, and their ratio, at θ = 30-150° (``lunarviz sweep
  --method analytic --moon-model rolo-fit-map --brdf dhg --earth-surface landocean --clouds zonal
  --wavelengths 400:1000:10``); the ratio's slope is the Earth's colour over the Moon's;
* ``moon_rvb.png``: ``lunarviz image --phase 120 --band R,V,B`` of the same scene, the sunlit and
  the earthlit Moon side by side, white-balanced to the Sun (Moon mesh level 6: the map per
  facet, about a pixel each).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "spectral"
SCENE = dict(moon_model="rolo-fit-map", brdfs=("dhg",), earth_surface="landocean", clouds="zonal")
PHASES = (30.0, 60.0, 90.0, 120.0, 150.0)


def main() -> int:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import lunarviz.api as api
    from lunarviz.methods.camera import Camera
    from lunarviz.outputs.writers import save_figure, write_results
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_sweep
    OUT.mkdir(parents=True, exist_ok=True)
    res = run_sweep(ResolvedScene(phases_deg=PHASES, method="analytic", wavelengths="400:1000:10", **SCENE))
    write_results(OUT / "spectrum.json", res)
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.4))
    for th, col in zip(PHASES, plt.cm.viridis(np.linspace(0, 0.9, len(PHASES)))):
        rows = [r for r in res["rows"] if r["theta_deg"] == th]
        lam = np.array([r["wavelength_nm"] for r in rows])
        ms = np.array([r["moonshine_W_m2_nm"] for r in rows])
        es = np.array([r["earthshine_W_m2_nm"] for r in rows])
        ax[0].semilogy(lam, ms, color=col, label=f"θ = {th:g}°")
        ax[1].semilogy(lam, es, color=col, label=f"θ = {th:g}°")
        ax[2].plot(lam, es / ms / (es / ms)[np.argmin(abs(lam - 550))], color=col, label=f"θ = {th:g}°")
    ax[0].set_ylabel("moonshine [W m⁻² nm⁻¹]")
    ax[1].set_ylabel("earthshine [W m⁻² nm⁻¹]")
    ax[2].set_ylabel("earthshine / moonshine, relative to 550 nm")
    for a in ax:
        a.set_xlabel("wavelength [nm]")
    # one legend for the three panels, beside them (in a panel it hid the curves)
    fig.legend(*ax[0].get_legend_handles_labels(), loc="center right", fontsize=8, title="phase")
    fig.suptitle("geocentre, rolo-fit-map DHG Moon, land/ocean Earth with zonal clouds (USGS spectra), TSIS-1 Sun; "
                 "`python scripts/spectral_figures.py`", fontsize=9)
    fig.tight_layout(rect=(0, 0, 0.93, 1))
    save_figure(fig, OUT / "spectrum.png", dpi=110)
    plt.close(fig)
    # the albedo map is sampled per facet: level 6 (81,920 facets, ~17 km, about a pixel each)
    # keeps the maria's outlines (level 5 drew them as hexagonal blobs)
    scene = api.Scene(phases=[120.0], bands="R,V,B", moon_level=6, **SCENE)
    api.image(scene, camera=Camera(fov_deg=0.6, width=320, height=320, supersample=2), out=OUT / "moon_rvb.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
