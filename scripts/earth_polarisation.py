"""The whole Earth's polarisation against its phase angle: a Rayleigh atmosphere over Lambert grounds.

Writes ``benchmarks/earth_polarisation/``: ``phase_curve.png`` (the degree of linear polarisation
−Q/I and the phase curve I(α) of the disc-integrated Stokes vector, :mod:`lunarviz.surfaces.earth_polarisation`)
and ``report.md`` (the largest degree and its phase angle per wavelength and ground; the vector
solution's I against the scalar one's over the same disc). Grounds: black (the sea outside its
glint, ~0), 0.06 (the sea's albedo with its glint) and 0.3 (the paper's Earth); air above 1013 hPa,
300 DU of ozone. About 40 s.

Run ``python scripts/earth_polarisation.py [--out DIR]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from lunarviz.earth_optics.classes import lambert_ground_toa
from lunarviz.surfaces import earth_polarisation

WAVELENGTHS_NM = (443.0, 550.0, 670.0, 865.0)
GROUNDS = (0.0, 0.06, 0.3)
PHASES_DEG = np.arange(0.0, 171.0, 5.0)


def scalar_disc(alpha_deg: float, wavelength_nm: float, albedo: float) -> float:
    """The scalar solution's I(α) over the same places and weights as the vector one's."""
    d = earth_polarisation.disc_places(alpha_deg)
    return float(np.sum(d["weight"] * lambert_ground_toa(albedo, wavelength_nm, d["mu0"], d["mu"], d["phi_deg"])))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/earth_polarisation", help="output folder")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    curves = {(lam, g): np.array([earth_polarisation.disc_stokes(al, lam, g) for al in PHASES_DEG])
              for lam in WAVELENGTHS_NM for g in GROUNDS}
    seconds = time.perf_counter() - t0
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    colours = dict(zip(WAVELENGTHS_NM, ("tab:blue", "tab:green", "tab:red", "tab:brown")))
    styles = dict(zip(GROUNDS, ("-", "--", ":")))
    for (lam, g), c in curves.items():
        label = f"{lam:g} nm, ground {g:g}"
        axes[0].plot(PHASES_DEG, -c[:, 1] / c[:, 0], styles[g], color=colours[lam], label=label)
        axes[1].plot(PHASES_DEG, c[:, 0], styles[g], color=colours[lam])
    axes[0].set(xlabel="phase angle α [deg]", ylabel="degree of linear polarisation −Q/I",
                title="the whole Earth: Rayleigh air over a Lambert ground")
    axes[1].set(xlabel="phase angle α [deg]", ylabel="I(α) (geometric albedo at α = 0)", yscale="log",
                title="its phase curve")
    axes[0].legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "phase_curve.png", dpi=130)
    lines = ["# The whole Earth's polarisation: a Rayleigh atmosphere over Lambert grounds", "",
             "Command: `python scripts/earth_polarisation.py` "
             f"({seconds:.0f} s for {len(curves)} curves of {len(PHASES_DEG)} phases). "
             "Air above 1013.25 hPa, 300 DU of ozone; the disc-integrated Stokes vector "
             "(`lunarviz.surfaces.earth_polarisation`), the plane of scattering as reference.", "",
             "| λ [nm] | ground | largest −Q/I | at α [deg] | −Q/I at 90° | I(90°) vector / scalar − 1 |",
             "| --- | --- | --- | --- | --- | --- |"]
    for (lam, g), c in curves.items():
        pol = -c[:, 1] / c[:, 0]
        k = int(np.argmax(pol))
        at90 = int(np.flatnonzero(PHASES_DEG == 90.0)[0])
        ratio = c[at90, 0] / scalar_disc(90.0, lam, g) - 1.0
        lines.append(f"| {lam:g} | {g:g} | {pol[k]:.3f} | {PHASES_DEG[k]:g} | {pol[at90]:.3f} | {ratio:+.4f} |")
    lines += ["", "![the whole Earth's polarisation](phase_curve.png)", ""]
    (out / "report.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
