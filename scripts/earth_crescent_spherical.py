"""The crescent Earth in a spherical shell: the plane-parallel tables against a spherical-shell code.

lunarviz's Rayleigh layer is plane-parallel with zenith angles held at 89° beyond it; a crescent
Earth is seen and lit at grazing angles. Here a whole Earth of Rayleigh air (550 nm, lunarviz's τ = 0.0971,
no ozone) over Lambert grounds of albedo 0, 0.06 and 0.3 is summed place by place
(:func:`lunarviz.surfaces.earth_polarisation.disc_places`: the weights of the geometric albedo) with
each place's reflectance factor from

* SASKTRAN2 in spherical geometry (``sasktran2``: the Sun's rays and the line of sight through a
  spherical shell, the multiple-scattering source by discrete ordinates at several solar zenith
  angles along the line of sight), air of scale height 8 km up to 100 km, 16 streams;
* SASKTRAN2 in plane-parallel geometry, the same air (the control: the geometry alone differs);
* lunarviz's scalar tables (:func:`lunarviz.earth_optics.classes.lambert_ground_toa`).

Writes ``benchmarks/earth_physical/crescent_spherical.md``. Needs ``pip install -e ".[earth-tables]"``
(sasktran2); about 10 minutes a phase angle at the default 3° places (one solution per place).

Run ``python scripts/earth_crescent_spherical.py [--phases 90,120,150,165] [--rows 60]``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from make_earth_tables import rayleigh_greek

from lunarviz.earth_optics import rayleigh
from lunarviz.earth_optics.classes import lambert_ground_toa
from lunarviz.surfaces.earth_polarisation import disc_places

SCALE_HEIGHT_M, TOP_M = 8000.0, 100000.0
ALBEDOS = np.array([0.0, 0.06, 0.3])
WAVELENGTH_NM = 550.0
TAU = float(rayleigh.optical_depth(WAVELENGTH_NM))  # lunarviz's own at sea level (Bodhaine et al. 1999)


def place_reflectance(mu0: float, mu: float, phi_deg: float, spherical: bool, streams: int = 16) -> np.ndarray:
    """(albedos,) one place's TOA reflectance factor πI/(μ₀F) by SASKTRAN2."""
    import sasktran2 as sk
    cfg = sk.Config()
    cfg.num_stokes, cfg.num_streams, cfg.num_singlescatter_moments = 1, streams, streams
    cfg.multiple_scatter_source = sk.MultipleScatterSource.DiscreteOrdinates
    alt = np.arange(0.0, TOP_M + 1.0, 500.0)
    kind = sk.GeometryType.Spherical if spherical else sk.GeometryType.PlaneParallel
    geo = sk.Geometry1D(cos_sza=float(mu0), solar_azimuth=0.0, earth_radius_m=6371000.0, altitude_grid_m=alt,
                        geometry_type=kind)
    rays = sk.ViewingGeometry()  # SASKTRAN2's relative azimuth 0 is forward scattering: 180 − lunarviz's
    rays.add_ray(sk.GroundViewingSolar(float(mu0), float(np.radians(180.0 - phi_deg)), float(mu), 200000.0))
    atmo = sk.Atmosphere(geo, cfg, numwavel=len(ALBEDOS), calculate_derivatives=False)
    k = np.exp(-alt / SCALE_HEIGHT_M)
    atmo.storage.total_extinction[:] = (k * TAU / np.trapezoid(k, alt))[:, None]
    atmo.storage.ssa[:] = 1.0
    atmo.storage.leg_coeff[:] = rayleigh_greek(streams)[::4][:, None, None]  # the scalar's a1
    atmo.surface.albedo[:] = ALBEDOS[None, :]
    return sk.Engine(cfg, geo, rays).calculate_radiance(atmo).radiance.values[:, 0, 0] * np.pi / mu0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--phases", default="90,120,150,165", help="phase angles [deg]")
    ap.add_argument("--rows", type=int, default=60, help="latitude rows of the places (60: 3° cells)")
    ap.add_argument("--out", default="benchmarks/earth_physical/crescent_spherical.md")
    a = ap.parse_args(argv)
    lines = ["# The crescent Earth in a spherical shell", "",
             f"Command: `python scripts/earth_crescent_spherical.py --phases {a.phases} --rows {a.rows}`. "
             f"A whole Earth of Rayleigh air (550 nm, τ = {TAU:.5f}, scale height 8 km, no ozone) over Lambert "
             "grounds, summed over its lit and seen places with the geometric albedo's weights; each "
             "place's reflectance by SASKTRAN2 in spherical and in plane-parallel geometry, and by "
             "lunarviz's plane-parallel tables (zenith angles held at 89° beyond it).", "",
             "| phase α [deg] | places | ground | I(α) spherical | spherical / plane-parallel − 1 | "
             "plane-parallel / lunarviz − 1 | seconds |", "| --- | --- | --- | --- | --- | --- | --- |"]
    for alpha in (float(x) for x in a.phases.split(",")):
        t0 = time.perf_counter()
        d = disc_places(alpha, a.rows)
        geometry = list(zip(d["mu0"], d["mu"], d["phi_deg"]))
        sph = np.array([place_reflectance(*g, spherical=True) for g in geometry])
        pp = np.array([place_reflectance(*g, spherical=False) for g in geometry])
        ours = np.stack([lambert_ground_toa(g, WAVELENGTH_NM, d["mu0"], d["mu"], d["phi_deg"], {"ozone_du": 0.0})
                         for g in ALBEDOS], -1)
        i_sph, i_pp, i_ours = d["weight"] @ sph, d["weight"] @ pp, d["weight"] @ ours
        seconds = time.perf_counter() - t0
        for j, g in enumerate(ALBEDOS):
            lines.append(f"| {alpha:g} | {len(geometry)} | {g:g} | {i_sph[j]:.5f} | {i_sph[j] / i_pp[j] - 1:+.4f} | "
                         f"{i_pp[j] / i_ours[j] - 1:+.4f} | {seconds:.0f} |")
        print(lines[-1], flush=True)
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
