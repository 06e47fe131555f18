"""Regenerate the packaged radiative-transfer tables of the physical Earth with DISORT.

Solver: ``nanodisort`` (Python bindings of CDISORT 2.1.3, Buras, Dowling & Emde 2011, after
Stamnes et al. 1988), plane-parallel, scalar. Writes into ``lunarviz/data/earth_optics/``:

* ``rayleigh.npz``: a Rayleigh layer (single-scattering albedo 1, phase function of
  :mod:`lunarviz.earth_optics.rayleigh`) over a black surface, at optical depths ``tau`` (log
  spaced 1e-4 … 2): the TOA reflectance factor's three azimuthal Fourier modes ``rho_m`` (tau,
  mu0, mu, m) (a phase function of Legendre order 2 has exactly m = 0, 1, 2), the diffuse sky
  at the bottom ``sky_m`` (tau, mu0, mu', m) as π I↓/(μ₀F) toward the source azimuth (0: the Sun's
  side) on Gauss nodes mu' (``tables.sky_nodes``), the total
  (direct + diffuse) transmittance ``trans`` (tau, mu) and the spherical albedo ``sph`` (tau),
  on zenith angles ``theta_deg`` 0 … 89°;
* ``cloud.npz``: a plane-parallel liquid water cloud of droplets (Hansen & Travis 1974's gamma size
  distribution, effective radius 10 µm, effective variance 0.1; Mie theory by ``miepython`` at
  550 nm, its full phase function with the glory, the rainbow and the forward peak as 1000
  Legendre moments) over a surface of albedo 0.06, as a surface: its reflectance factor ``rf``
  (tau, mu0, mu, phi) at optical depths ``tau`` with azimuth 0 = viewer on the Sun's side, 36
  streams, delta-M with the Nakajima–Tanaka intensity correction (which takes every moment);
  also the moments, the single-scattering albedo and the phase function on 3601 points in cos Θ.

Run ``python scripts/make_earth_tables.py`` (``pip install -e ".[earth-tables]"``: nanodisort and
miepython; about four minutes, most of it the droplets' Mie sums and the cloud's DISORT solutions).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

from lunarviz.earth_optics import rayleigh
from lunarviz.earth_optics.disort_tables import (CLOUD, CLOUD_PHI_DEG, CLOUD_TAU, RAYLEIGH_TAU, TABLE_DIR, THETA_DEG,
                                                 sky_nodes)

#: streams: 36 puts no computational angle on a table node (32 has one at 36°, 34 at 60°)
NSTR = 36


def _state(nmom, umu, phi, tau_layers, ssalb, pmom, mu0, albedo, correction=False):
    import nanodisort as nd
    s = nd.DisortState()
    s.nstr, s.nlyr, s.nmom = NSTR, len(tau_layers), nmom
    s.numu, s.nphi, s.ntau = len(umu), len(phi), 2
    s.usrtau = s.usrang = s.lamber = s.quiet = True
    s.onlyfl = s.planck = False
    s.intensity_correction = s.old_intensity_correction = correction
    s.allocate()
    s.dtauc = np.asarray(tau_layers, float)
    s.ssalb = np.asarray(ssalb, float)
    s.pmom = pmom
    s.utau = np.array([0.0, float(np.sum(tau_layers))])
    s.umu = np.sort(np.asarray(umu, float))  # DISORT wants them increasing
    s.phi = np.asarray(phi, float)
    s.fbeam, s.umu0, s.phi0, s.albedo, s.fisot, s.accur = 1.0, float(mu0), 0.0, float(albedo), 0.0, 0.0
    s.solve()
    return s


def _uu_top(s, umu) -> np.ndarray:
    """(numu, nphi) intensity at the top, in the order of ``umu`` (DISORT sorts them)."""
    order = np.argsort(np.argsort(np.asarray(umu, float)))
    return np.asarray(s.uu)[order, 0, :]


def _uu_bottom(s, umu) -> np.ndarray:
    """(numu, nphi) intensity at the bottom, in the order of ``umu``."""
    order = np.argsort(np.argsort(np.asarray(umu, float)))
    return np.asarray(s.uu)[order, 1, :]


def _modes(u0, u90, u180) -> np.ndarray:
    """(n, 3) Fourier modes a, b, c of u(φ) = a + b cos φ + c cos 2φ (exact for Legendre order 2)
    from its values at φ = 0, 90, 180."""
    return np.stack([0.25 * (u0 + u180) + 0.5 * u90, 0.5 * (u0 - u180), 0.25 * (u0 + u180) - 0.5 * u90], -1)


def rayleigh_tables() -> dict:
    mu = np.cos(np.radians(THETA_DEG))
    pm = np.zeros((NSTR + 1, 1))
    pm[0, 0], pm[2, 0] = 1.0, rayleigh.legendre_moment_2()
    # DISORT's azimuth is measured from the beam's own direction (0 = forward); lunarviz's 0 is
    # the viewer on the Sun's side: phi_lunarviz = 180 - phi_disort
    phi_d = np.array([180.0, 90.0, 0.0])  # lunarviz 0, 90, 180
    sky_mu = sky_nodes()[0]
    up = np.r_[mu, -sky_mu]  # upward at the top (lunarviz's nodes), downward at the bottom (Gauss nodes)
    rho = np.zeros((len(RAYLEIGH_TAU), len(mu), len(mu), 3))
    sky = np.zeros((len(RAYLEIGH_TAU), len(mu), len(sky_mu), 3))
    trans = np.zeros((len(RAYLEIGH_TAU), len(mu)))
    sph = np.zeros(len(RAYLEIGH_TAU))
    for k, tau in enumerate(RAYLEIGH_TAU):
        for i, mu0 in enumerate(mu):
            s = _state(NSTR, up, phi_d, [tau], [1.0], pm, mu0, 0.0)
            u = _uu_top(s, up)[:len(mu)] * np.pi / mu0  # (mu, phi): reflectance factor
            rho[k, i] = _modes(u[:, 0], u[:, 1], u[:, 2])
            # the sky at the bottom: π I↓/(μ₀ F) toward the source azimuth φ' (0: the Sun's side);
            # DISORT's azimuth of a downward photon is φ' itself (phi_d 180, 90, 0 → φ' 180, 90, 0)
            d = _uu_bottom(s, up)[len(mu):] * np.pi / mu0
            sky[k, i] = _modes(d[:, 2], d[:, 1], d[:, 0])
            trans[k, i] = (np.asarray(s.rfldir)[1] + np.asarray(s.rfldn)[1]) / mu0
        # spherical albedo from the surface's coupling: F↓(A) = F↓(0) / (1 - S A)
        down = []
        for albedo in (0.0, 1.0):
            s = _state(NSTR, mu[:1], [0.0], [tau], [1.0], pm, 1.0, albedo)
            down.append(np.asarray(s.rfldir)[1] + np.asarray(s.rfldn)[1])
        sph[k] = 1.0 - down[0] / down[1]
    return {"tau": RAYLEIGH_TAU, "theta_deg": THETA_DEG, "rho_m": rho, "trans": trans, "sph": sph, "sky_m": sky,
            "depolarisation": np.array(rayleigh.DEPOLARISATION)}


def droplet_size_grid() -> tuple[np.ndarray, np.ndarray]:
    """Radii [µm] and trapezoid weights of the droplets' size distribution: Hansen & Travis (1974,
    Eq. 2.56) gamma n(r) ∝ r^((1 − 3b)/b) e^(−r/(ab)) with a = r_eff, b = v_eff, normalised."""
    a, b = CLOUD["r_eff_um"], CLOUD["v_eff"]
    r = np.arange(0.25, 60.0 + 1e-9, 0.02)
    n = r ** ((1.0 - 3.0 * b) / b) * np.exp(-r / (a * b))
    w = n * np.gradient(r)
    return r, w / w.sum()


def droplet_phase_function(nodes: int = 6000) -> dict:
    """The droplets' phase function P(Θ) (∫ P dΩ = 4π) on Gauss–Legendre nodes in cos Θ, its
    Legendre moments χ_l = ½ ∫ P P_l dμ (DISORT's normalisation), the single-scattering albedo
    and the asymmetry parameter: Mie theory (``miepython``, Wiscombe 1980's algorithm) over the
    size distribution at the table's wavelength, refractive index of water from Hale & Querry
    (1973, Appl. Opt. 12, 555) at 550 nm."""
    os.environ.setdefault("MIEPYTHON_USE_JIT", "1")  # (compiled: ~50x faster at size parameters of ~100)
    import miepython as mp
    mu, wmu = np.polynomial.legendre.leggauss(nodes)
    lam = CLOUD["wavelength_um"]
    m = complex(CLOUD["n_real"], -CLOUD["n_imag"])  # miepython: absorption as a negative imaginary part
    r, w = droplet_size_grid()
    pf = np.zeros(nodes)
    c_sca = c_ext = 0.0  # the distribution's cross sections [µm²]
    for ri, wi in zip(r, w):
        x = 2.0 * np.pi * ri / lam
        qext, qsca, _, _ = mp.efficiencies_mx(m, x)
        # (|S1|² + |S2|²)/2 / k² integrates to a fixed multiple (4) of this size's C_sca in miepython's
        # "bohren" normalisation (checked at 2, 10 and 30 µm): the sum weights sizes by their
        # scattered power, and the constant goes in the normalisation below
        s1, s2 = mp.S1_S2(m, x, mu, norm="bohren")
        k2 = (2.0 * np.pi / lam) ** 2
        pf += wi * 0.5 * (np.abs(s1) ** 2 + np.abs(s2) ** 2) / k2
        c_sca += wi * qsca * np.pi * ri**2
        c_ext += wi * qext * np.pi * ri**2
    pf /= 0.5 * wmu @ pf  # ∫ P dΩ = 4π (the weights above are each size's own scattered power)
    leg = np.polynomial.legendre.legvander(mu, CLOUD["moments"])  # (nodes, L + 1)
    moments = 0.5 * (wmu * pf) @ leg
    return {"mu": mu, "phase_function": pf, "moments": moments, "ssalb": c_sca / c_ext,
            "asymmetry": float(moments[1])}


def cloud_table() -> dict:
    mu = np.cos(np.radians(THETA_DEG))
    drop = droplet_phase_function()
    pm = drop["moments"][:, None]
    phi_d = 180.0 - CLOUD_PHI_DEG
    rf = np.zeros((len(CLOUD_TAU), len(mu), len(mu), len(CLOUD_PHI_DEG)), dtype=np.float32)
    for k, tau in enumerate(CLOUD_TAU):
        for i, mu0 in enumerate(mu):
            s = _state(CLOUD["moments"], mu, phi_d, [tau], [drop["ssalb"]], pm, mu0, CLOUD["surface_albedo"],
                       correction=True)
            rf[k, i] = _uu_top(s, mu) * np.pi / mu0
        print(f"cloud τ = {tau:g}: done", flush=True)
    keep = np.linspace(-1.0, 1.0, 3601)  # the phase function, for documentation and figures
    return {"theta_deg": THETA_DEG, "phi_deg": CLOUD_PHI_DEG, "tau": CLOUD_TAU, "rf": rf,
            "moments": drop["moments"], "ssalb": np.array(drop["ssalb"]),
            "phase_mu": keep, "phase_function": np.interp(keep, drop["mu"], drop["phase_function"]),
            "setup": np.array(json.dumps({**CLOUD, "ssalb": drop["ssalb"], "asymmetry": drop["asymmetry"]}))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(TABLE_DIR), help="folder for rayleigh.npz and cloud.npz")
    ap.add_argument("--only", choices=("rayleigh", "cloud"), help="make one table only")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, make in (("rayleigh", rayleigh_tables), ("cloud", cloud_table)):
        if a.only in (None, name):
            np.savez_compressed(out / f"{name}.npz", **make())
            print(f"wrote {out / name}.npz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
