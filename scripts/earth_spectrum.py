"""The model Earth's own reflectance spectrum: its spherical (Bond) albedo and geometric albedo from
350 to 1000 nm, with and without the ozone, and without clouds.

    python scripts/earth_spectrum.py [--out benchmarks/earth_physical] [--quick]

The physical Earth (land–ocean map, zonal clouds of droplets, the θ scene's equinox) through
``lunarviz.surfaces.earth_albedos`` (exact over every direction) at every 10 nm (``--quick``: every
50 nm). What it shows is what the model holds: the Rayleigh blue, the ozone's Chappuis band
around 600 nm, the vegetation's red edge near 700 nm under the clouds' grey; what it does not hold
(O₂ A and B bands, water vapour, aerosols) is absent. Writes ``spectrum.json`` and
``spectrum.png``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def albedos(wavelengths, clouds: str = "zonal", ozone_du: float | None = None) -> dict:
    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.surfaces.earth_albedos import earth_albedos
    from lunarviz.surfaces.earth_surface import EarthSurface
    from lunarviz.surfaces.maps import map_frame
    params = () if ozone_du is None else (("ozone_du", ozone_du),)
    surface = EarthSurface(earth_brdf="physical", earth_surface="landocean", clouds=clouds, earth_params=params)
    sc = SceneGeometry(90.0)
    a = earth_albedos(surface, sc, map_frame(sc, "earth", 0.0), wavelengths)
    return {"spherical": a["spherical"].tolist(), "geometric": a["geometric"].tolist()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "earth_physical"))
    ap.add_argument("--quick", action="store_true", help="every 50 nm")
    a = ap.parse_args(argv)
    lam = np.arange(350.0, 1000.1, 50.0 if a.quick else 10.0)
    t0 = time.perf_counter()
    res = {"wavelength_nm": lam.tolist(), "default": albedos(lam), "no_ozone": albedos(lam, ozone_du=0.0),
           "no_clouds": albedos(lam, clouds="none")}
    res["seconds"] = time.perf_counter() - t0
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "spectrum.json").write_text(json.dumps(res, indent=1))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(lam, res["default"]["spherical"], "k-", label="spherical albedo (default: ozone 300 DU)")
    ax.plot(lam, res["no_ozone"]["spherical"], "k:", label="the same without ozone")
    ax.plot(lam, res["default"]["geometric"], "b-", label="geometric albedo")
    ax.plot(lam, res["no_clouds"]["spherical"], "g--", label="spherical albedo, no clouds")
    ax.axvspan(500, 700, color="0.93", zorder=0)
    ax.text(600, 0.02, "Chappuis band", ha="center", fontsize=8)
    ax.set(xlabel="wavelength [nm]", ylabel="albedo", ylim=(0, None),
           title="the model Earth's own spectrum (land–ocean, zonal clouds, equinox)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "spectrum.png", dpi=120)
    plt.close(fig)
    i = int(np.argmin(np.abs(lam - 600.0)))
    print(f"600 nm: spherical albedo {res['default']['spherical'][i]:.4f} with ozone, "
          f"{res['no_ozone']['spherical'][i]:.4f} without ({res['seconds']:.0f} s); wrote {out / 'spectrum.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
