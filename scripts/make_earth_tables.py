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
* ``cloud.npz``: a plane-parallel water cloud (optical depth 10, single-scattering albedo
  0.99999, Henyey–Greenstein g = 0.85; Hansen & Travis 1974's typical droplet cloud in the
  visible) over a surface of albedo 0.06, as a surface: its reflectance factor ``rf`` (mu0, mu,
  phi) with azimuth 0 = viewer on the Sun's side, 36 streams, delta-M with the Nakajima–Tanaka
  intensity correction.

Run ``python scripts/make_earth_tables.py`` (``pip install nanodisort``; about a minute).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from lunarviz.earth_optics import rayleigh
from lunarviz.earth_optics.disort_tables import CLOUD, CLOUD_PHI_DEG, RAYLEIGH_TAU, TABLE_DIR, THETA_DEG, sky_nodes

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


def cloud_table() -> dict:
    mu = np.cos(np.radians(THETA_DEG))
    nmom = 4 * NSTR
    g = CLOUD["g"]
    pm = (g ** np.arange(nmom + 1))[:, None]
    phi_d = 180.0 - CLOUD_PHI_DEG
    rf = np.zeros((len(mu), len(mu), len(CLOUD_PHI_DEG)))
    for i, mu0 in enumerate(mu):
        s = _state(nmom, mu, phi_d, [CLOUD["tau"]], [CLOUD["ssalb"]], pm, mu0, CLOUD["surface_albedo"],
                   correction=True)
        rf[i] = _uu_top(s, mu) * np.pi / mu0
    return {"theta_deg": THETA_DEG, "phi_deg": CLOUD_PHI_DEG, "rf": rf, "setup": np.array(json.dumps(CLOUD))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(TABLE_DIR), help="folder for rayleigh.npz and cloud.npz")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out / "rayleigh.npz", **rayleigh_tables())
    np.savez_compressed(out / "cloud.npz", **cloud_table())
    print(f"wrote {out / 'rayleigh.npz'} and {out / 'cloud.npz'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
