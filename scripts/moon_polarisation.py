"""The Moon's polarised light: its disc polarisation against phase, and a lunation's moonshine Stokes rows.

Writes ``benchmarks/moon_polarisation/``:

* ``phase_curve.png``: the signed degree of linear polarisation P(g) of the Moon's disc
  (:mod:`lunarviz.photometry.moon_polarisation`, ESA's LIME) at 440, 500, 675 and 870 nm, waxing and
  waning, with Lyot's (1929) whole-Moon maxima at the quarters (visual: 6.6 % waxing, 8.8 % waning);
* ``lunation.png``: a lunation of nightly dates from Big Bear in the V band through
  ``lunarviz sweep --stokes`` (the moonshine's degree of polarisation and the scattering plane's
  position angle on the sky);
* ``report.md``: the negative branch's minimum and inversion angle, the value at 90° per wavelength and
  branch, against Lyot; the lunation's rows.

About 20 s. Run ``python scripts/moon_polarisation.py [--out DIR]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import lunarviz
from lunarviz.photometry import moon_polarisation as mp

WAVELENGTHS_NM = (440.0, 500.0, 675.0, 870.0)
#: Lyot (1929): the whole Moon's polarisation at the quarters, visual [fraction]
LYOT_QUARTERS = {"waxing": 0.066, "waning": 0.088}
SITE = "site:34.26,-116.92,2067"
LUNATION = "2026-02-17T03:00Z,2026-03-18T03:00Z,1d"
COMMAND = (f"lunarviz sweep --method raytrace --observer {SITE} --band V --brdf dhg --time-range {LUNATION} "
           "--stokes --out lunation.csv")


def features(lam: float, branch: str) -> dict:
    """The negative branch's minimum (P, g), the inversion angle and P(90°) of one curve."""
    g = np.arange(2.0, 90.001, 0.05)
    p = mp.disc_polarisation(g, lam, branch)
    k = int(np.argmin(p))
    up = np.flatnonzero((p[:-1] < 0) & (p[1:] >= 0))
    return {"p_min": p[k], "g_min": g[k], "g_inv": g[up[0]] if len(up) else np.nan, "p90": p[-1]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/moon_polarisation", help="output folder")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    ds = lunarviz.sweep(method="raytrace", observer=SITE, bands="V", brdfs=("dhg",), time_range=LUNATION,
                        stokes=True)
    seconds = time.perf_counter() - t0
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    g = np.linspace(2.0, 90.0, 353)
    colours = dict(zip(WAVELENGTHS_NM, ("tab:blue", "tab:green", "tab:red", "tab:brown")))
    fig, ax = plt.subplots(figsize=(7, 4.4))
    for lam in WAVELENGTHS_NM:
        for branch, style in (("waxing", "--"), ("waning", "-")):
            ax.plot(g, 100 * mp.disc_polarisation(g, lam, branch), style, color=colours[lam],
                    label=f"{lam:g} nm, {branch}")
    for branch, marker in (("waxing", "o"), ("waning", "s")):
        ax.plot([90.0], [100 * LYOT_QUARTERS[branch]], marker, color="k", mfc="none",
                label=f"Lyot 1929, visual, {branch} quarter")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set(xlabel="phase angle g [deg]", ylabel="degree of linear polarisation P [%] (+: ⊥ scattering plane)",
           title="the Moon's disc polarisation (ESA LIME, CIMEL 2025)")
    ax.legend(fontsize=6.5, ncol=2)
    fig.tight_layout()
    fig.savefig(out / "phase_curve.png", dpi=130)
    plt.close(fig)

    up = ds["skip_reason"].values == ""
    t = np.arange(len(ds["time"]))
    dolp = ds["moonshine_dolp"].values[0, :, 0]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    axes[0].plot(ds["phase_angle"].values[up], 100 * dolp[up], "o")
    axes[0].set(xlabel="phase angle [deg]", ylabel="moonshine degree of polarisation [%], V",
                title="a lunation from Big Bear (nightly, 03:00 UTC): Moon up")
    axes[1].plot(t[up], ds["scattering_plane_position_angle"].values[up], "o")
    axes[1].set(xlabel="night from 2026-02-17", ylabel="position angle of the scattering plane [deg]",
                title="the scattering plane on the sky (north through east)")
    fig.tight_layout()
    fig.savefig(out / "lunation.png", dpi=130)
    plt.close(fig)

    lines = ["# The Moon's polarised light", "",
             "`python scripts/moon_polarisation.py`: the disc polarisation of "
             "`lunarviz/data/lunar_fits/lime_polarisation.csv` (ESA LIME, CIMEL 1088, 2025-10-10) and a lunation's "
             "moonshine Stokes rows.", "",
             "## The phase curve against Lyot (1929)", "",
             "| wavelength | branch | P_min [%] | at g [deg] | inversion g [deg] | P(90°) [%] | Lyot, quarter [%] |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for lam in WAVELENGTHS_NM + (550.0,):
        for branch in ("waxing", "waning"):
            f = features(lam, branch)
            lines.append(f"| {lam:g} nm | {branch} | {100 * f['p_min']:.2f} | {f['g_min']:.1f} | {f['g_inv']:.1f} | "
                         f"{100 * f['p90']:.2f} | {100 * LYOT_QUARTERS[branch]:.1f} (visual) |")
    below = [1 - features(550.0, b)["p90"] / LYOT_QUARTERS[b] for b in ("waxing", "waning")]
    lines += ["", f"At 550 nm the model's P(90°) is {100 * min(below):.0f}-{100 * max(below):.0f} % below Lyot's "
              "visual maxima at the quarters; the ratio of waning to waxing is "
              f"{features(550.0, 'waning')['p90'] / features(550.0, 'waxing')['p90']:.2f} against Lyot's 1.33. "
              "LIME's polynomial stops at 90°; Lyot's numbers are the largest he read near the quarters, by eye, "
              "in visual light, so they bound P(90°) from above rather than equal it.", "",
              "## A lunation's moonshine Stokes rows", "", f"`{COMMAND}` ({seconds:.1f} s through the API), "
              "V band: rows with the Moon up and a phase angle of 2-90° carry the disc's polarisation; beyond 90° "
              "the rows' Stokes fields are NaN (outside the model).", "",
              "| date (UTC) | phase angle [deg] | moonshine_dolp | moonshine_aolp_deg | "
              "scattering plane PA [deg] | skipped |", "| --- | --- | --- | --- | --- | --- |"]
    for k, time_label in enumerate(ds["time"].values):
        lines.append(f"| {str(time_label)[:16]} | {float(ds['phase_angle'].values[k]):.1f} | {dolp[k]:.4f} | "
                     f"{float(ds['moonshine_aolp'].values[0, k, 0]):.0f} | "
                     f"{float(ds['scattering_plane_position_angle'].values[k]):.1f} | "
                     f"{ds['skip_reason'].values[k] or ''} |")
    (out / "report.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {out}/phase_curve.png, lunation.png and report.md ({seconds:.1f} s for the lunation)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
