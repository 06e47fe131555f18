"""BRDF tables: the lunar models' and the Earth's reflectance, one row per geometry (what
``lunarviz brdf`` writes and :func:`lunarviz.brdf` returns).

Columns: ``incidence_deg``, ``emission_deg``, ``azimuth_deg`` (0 = the viewer on the source's
side), ``phase_deg``, ``brdf_per_sr`` and ``reflectance_factor`` (π · BRDF); the Earth's rows add
``wavelength_nm`` and give its top-of-atmosphere reflectance factor πL/(μ₀E₀) (the bare surface's
with ``atmosphere=False``); with ``stokes=True`` (black and Lambert grounds, the bare sea) the reflectance factor
is the vector solution's I, and the rows add ``q_reflectance_factor`` and ``u_reflectance_factor``
(πQ/(μ₀E₀), πU/(μ₀E₀) in the meridian plane of the view), ``dolp`` and ``aolp_deg``
(:mod:`lunarviz.earth_optics.stokes`: the reference plane and the sign of U).
"""

from __future__ import annotations

import numpy as np

from lunarviz.earth_optics.classes import surface_from_name, toa_reflectance, toa_stokes
from lunarviz.earth_optics.stokes import degree_and_angle
from lunarviz.errors import LunarvizError
from lunarviz.options import earth_params
from lunarviz.photometry.brdf import brdf_from_angles, half_angle_from_angles


#: the most rows a table may have (incidences × emissions × azimuths × wavelengths): ~1 GB of rows
MAX_TABLE_ROWS = 1_000_000


def _geometry(inc, emi, azi, wavelengths: int = 1):
    """(incidence, emission, azimuth) triples [deg] in row order, and their phase angles [deg]."""
    n = len(inc) * len(emi) * len(azi) * wavelengths
    if n > MAX_TABLE_ROWS:
        raise LunarvizError(f"the table would have {n:,} rows ({len(inc)} incidences × {len(emi)} emissions × "
                            f"{len(azi)} azimuths" + (f" × {wavelengths} wavelengths" if wavelengths > 1 else "")
                            + f"): at most {MAX_TABLE_ROWS:,}; use coarser steps")
    grid = np.array([(i, e, z) for i in inc for e in emi for z in azi], dtype=float).reshape(-1, 3)
    ir, er, zr = np.radians(grid.T)
    s, c = half_angle_from_angles(ir, er, zr)
    return grid, np.degrees(2 * np.arctan2(s, c))


def _row(g, phase, f) -> dict:
    return {"incidence_deg": float(g[0]), "emission_deg": float(g[1]), "azimuth_deg": float(g[2]),
            "phase_deg": float(phase), "brdf_per_sr": float(f) / np.pi, "reflectance_factor": float(f)}


def lunar_rows(model, inc, emi, azi) -> list[dict]:
    """Rows of a lunar BRDF ``model`` (:func:`lunarviz.photometry.brdf.make_brdf`)."""
    grid, phase = _geometry(inc, emi, azi)
    f = np.pi * np.asarray(brdf_from_angles(model, *np.radians(grid.T)), dtype=float)  # (all rows at once)
    return [_row(g, p, v) for g, p, v in zip(grid, phase, f)]


def _stokes_columns(st) -> dict:
    dolp, aolp = degree_and_angle(st)
    return {"q_reflectance_factor": float(st[1]), "u_reflectance_factor": float(st[2]), "dolp": float(dolp),
            "aolp_deg": float(aolp)}


def earth_rows(surface: str, wavelengths, inc, emi, azi, atmosphere: bool = True, params: dict | None = None,
               stokes: bool = False) -> tuple[list[dict], dict]:
    """Rows of the Earth's class ``surface`` (:func:`lunarviz.earth_optics.classes.surface_from_name`)
    at each wavelength [nm], and the settings that made them; ``stokes``: the Stokes vector's
    columns too (module docstring)."""
    if "wavelength_nm" in (params or {}):
        raise LunarvizError("earth.wavelength_nm is a grey sweep's wavelength: the Earth's table takes --wavelengths")
    if "ground_albedo" in (params or {}):
        raise LunarvizError("earth.ground_albedo is a sweep's uniform Earth's ground: the Earth's table takes "
                            "--surface lambert:A")
    p = earth_params(params)
    p.pop("ground_albedo")  # (not this table's: --surface names its class)
    grid, phase = _geometry(inc, emi, azi, len(wavelengths))
    s = surface_from_name(surface, wind_speed=p["wind_speed"], cloud_optical_depth=p["cloud_optical_depth"],
                          chlorophyll=p["chlorophyll"])
    mu0, mu = np.cos(np.radians(grid[:, 0])), np.cos(np.radians(grid[:, 1]))
    rows = []
    for lam in wavelengths:
        if stokes:
            st = toa_stokes(s, float(lam), mu0, mu, grid[:, 2], atmosphere=atmosphere, params=p)
            rows += [{"wavelength_nm": float(lam), **_row(g, ph, v[0]), **_stokes_columns(v)}
                     for g, ph, v in zip(grid, phase, st)]
            continue
        rf = toa_reflectance(s, float(lam), mu0, mu, grid[:, 2], atmosphere=atmosphere, params=p)
        rows += [{"wavelength_nm": float(lam), **_row(g, ph, f)} for g, ph, f in zip(grid, phase, rf)]
    if not atmosphere:  # the bare surface: no air, no ozone above it
        p = {k: v for k, v in p.items() if k not in ("ozone_du", "cloud_top_hpa", "surface_hpa")}
    settings = {"body": "earth", "surface": surface, "atmosphere": "rayleigh+ozone" if atmosphere else "none",
                "params": p, "model": "lunarviz.earth_optics (packaged DISORT tables)"}
    if stokes:
        settings.update(stokes=True, model="lunarviz.earth_optics.stokes (packaged vector table, SASKTRAN2)")
    return rows, settings
