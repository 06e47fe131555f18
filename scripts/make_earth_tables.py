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
  also the moments, the single-scattering albedo and the phase function on 3601 points in cos Θ;
* ``rayleigh_stokes.npz``: the same Rayleigh layer solved for the Stokes vector (I, Q, U) by
  SASKTRAN2's vector discrete-ordinates source (``sasktran2``; Bourassa, Degenstein & Llewellyn
  2008, JQSRT 109, 52; Zawada et al. 2015, AMT 8, 2609), plane-parallel, 32 streams, 41 levels,
  the polarised phase matrix with the depolarisation of :mod:`lunarviz.earth_optics.rayleigh`
  (Hansen & Travis 1974, Eq. 2.16): over a black surface the modes ``i_m``, ``q_m`` (cos mφ,
  m = 0, 1, 2) and ``u_m`` (sin mφ, m = 1, 2) of the reflectance factor (tau, mu0, mu, m) in the
  meridian plane of the view; over a Lambert ground, from runs at albedos 0, ½ and 1, the
  spherical albedo ``sph_v`` (tau), the transmittance ``trans_v`` (tau, mu) and the Q of the
  ground's light at the top ``ground_q`` (tau, mu), with R(A) = R(0) + A T(μ₀) (T(μ), t_Q(μ)) /
  (1 − S A) for I and Q (a Lambert ground reflects unpolarised light).

Run ``python scripts/make_earth_tables.py`` (``pip install -e ".[earth-tables]"``: nanodisort,
miepython and sasktran2; about twenty-five minutes, most of it the droplets' Mie sums, the cloud's DISORT
solutions and the vector solutions).
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


#: Stokes tables: streams of the vector solver, its levels across the layer (spaced geometrically
#: from 5 cm below the top: a grazing view's light comes from the top's first Δτ ~ μ, and two
#: levels leave I 1.7 % low at 78° for τ = 0.25, against a vector Monte Carlo), the albedos of its
#: Lambert ground and the azimuths [deg] of its rays (lunarviz's: 0 = viewer on the Sun's side)
STOKES_STREAMS = 32
STOKES_LEVELS = 41
STOKES_ALBEDOS = np.array([0.0, 0.5, 1.0])
STOKES_PHI_DEG = np.array([0.0, 45.0, 90.0, 180.0])
#: the beams at which the ground's light is solved (its nodes' indices): the first makes the table,
#: the second checks the product form T(μ₀) t(μ)
STOKES_GROUND_BEAMS = (0, 30)


def rayleigh_greek(moments: int) -> np.ndarray:
    """SASKTRAN2's stacked Greek coefficients (a1, a2, a3, b1 per order) of the Rayleigh phase
    matrix with depolarisation (Hansen & Travis 1974, Eq. 2.16; de Rooij & van der Stap 1984):
    a1 = 1, Δ/2 at orders 0, 2; a2 = 3Δ and b1 = √6 Δ/2 at order 2, with
    Δ = (1 − ρₙ)/(1 + ρₙ/2)."""
    d = rayleigh.DEPOLARISATION
    delta = (1.0 - d) / (1.0 + d / 2.0)
    out = np.zeros((moments, 4))
    out[0, 0], out[2, 0], out[2, 1], out[2, 3] = 1.0, delta / 2.0, 3.0 * delta, np.sqrt(6.0) * delta / 2.0
    return out.reshape(-1)


def _stokes_at(mu0: float, albedos) -> np.ndarray:
    """(tau, albedo, mu, phi, stokes) TOA reflectance factors π(I, Q, U)/(μ₀F) for a beam at μ₀,
    every optical depth and albedo batched as SASKTRAN2 "wavelengths"."""
    import sasktran2 as sk
    cfg = sk.Config()
    cfg.num_stokes, cfg.num_streams, cfg.num_singlescatter_moments = 3, STOKES_STREAMS, STOKES_STREAMS
    cfg.num_forced_azimuth = 3  # the Rayleigh phase matrix has azimuthal modes 0, 1, 2 only
    cfg.multiple_scatter_source = sk.MultipleScatterSource.DiscreteOrdinates
    depth = np.r_[0.0, np.geomspace(0.05, 1000.0, STOKES_LEVELS - 1)]  # below the top of a 1 km layer [m]
    geo = sk.Geometry1D(cos_sza=float(mu0), solar_azimuth=0.0, earth_radius_m=6371000.0,
                        altitude_grid_m=np.sort(1000.0 - depth), geometry_type=sk.GeometryType.PlaneParallel)
    mu = np.cos(np.radians(THETA_DEG))
    rays = sk.ViewingGeometry()
    for m in mu:
        for p in STOKES_PHI_DEG:  # SASKTRAN2's relative azimuth 0 is forward scattering: 180 − lunarviz's
            rays.add_ray(sk.GroundViewingSolar(float(mu0), float(np.radians(180.0 - p)), float(m), 2000.0))
    albedos = np.asarray(albedos, float)
    tau = np.repeat(RAYLEIGH_TAU, len(albedos))
    atmo = sk.Atmosphere(geo, cfg, numwavel=len(tau), calculate_derivatives=False)
    atmo.storage.total_extinction[:] = (tau / 1000.0)[None, :]  # uniform: a layer of optical depth τ
    atmo.storage.ssa[:] = 1.0
    atmo.storage.leg_coeff[:] = rayleigh_greek(cfg.num_singlescatter_moments)[:, None, None]
    atmo.surface.albedo[:] = np.tile(albedos, len(RAYLEIGH_TAU))[None, :]
    r = sk.Engine(cfg, geo, rays).calculate_radiance(atmo).radiance.values  # (wavelength, ray, stokes), F = 1
    return r.reshape(len(RAYLEIGH_TAU), len(albedos), len(mu), len(STOKES_PHI_DEG), 3) * np.pi / mu0


def _ground_light(black: np.ndarray, lit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(S (tau,), X (tau, mu, 2)): from R(A) − R(0) = A X / (1 − S A) at A = ½ and 1 (the same at
    every azimuth: the mean is kept) for I and Q; ``black`` (tau, mu, phi, stokes), ``lit`` (tau, 2, ...)."""
    d_half, d_one = lit[:, 0] - black, lit[:, 1] - black
    s = (d_one[..., 0] - 2.0 * d_half[..., 0]) / (d_one[..., 0] - d_half[..., 0])  # 2 d½ (1 − S/2) = d₁ (1 − S)
    sph = np.median(s.reshape(len(s), -1), axis=1)
    return sph, (d_one[..., :2] * (1.0 - sph[:, None, None, None])).mean(2)


def rayleigh_stokes_tables() -> dict:
    mu = np.cos(np.radians(THETA_DEG))
    n_tau, n_mu = len(RAYLEIGH_TAU), len(mu)
    i_m, q_m, u_m = np.zeros((n_tau, n_mu, n_mu, 3)), np.zeros((n_tau, n_mu, n_mu, 3)), np.zeros((n_tau, n_mu, n_mu, 2))
    blacks = {}
    for i, mu0 in enumerate(mu):
        black = _stokes_at(mu0, [0.0])[:, 0]  # (tau, mu, phi, stokes) at φ = 0, 45, 90, 180
        blacks[i] = black
        i_m[:, i] = _modes(black[..., 0, 0], black[..., 2, 0], black[..., 3, 0])
        q_m[:, i] = _modes(black[..., 0, 1], black[..., 2, 1], black[..., 3, 1])
        u90, u45 = black[..., 2, 2], black[..., 1, 2]
        u_m[:, i] = np.stack([u90, u45 - u90 / np.sqrt(2.0)], -1)  # U = b₁ sin φ + b₂ sin 2φ
        # at nadir the meridian plane is undefined and SASKTRAN2 gives Q in a fixed frame (the
        # same at every azimuth); lunarviz's is the limit of the view's meridian plane along its
        # azimuth φ, turned by φ from that frame: Q = Q_n cos 2φ, U = −Q_n sin 2φ
        q_nadir = q_m[:, i, 0, 0].copy()
        q_m[:, i, 0], u_m[:, i, 0] = 0.0, 0.0
        q_m[:, i, 0, 2], u_m[:, i, 0, 1] = q_nadir, -q_nadir
        print(f"Stokes μ₀ = {mu0:.4f}: done", flush=True)
    # a Lambert ground: X(μ₀, μ) = T(μ₀) t(μ) for I and Q; by reciprocity t = T for I, so one beam
    # gives T(μ) = X_I(μ*, μ)/√X_I(μ*, μ*) and t_Q(μ) = X_Q(μ*, μ)/T(μ*); a second beam checks it
    (sph, x), (sph2, x2) = [_ground_light(blacks[i], _stokes_at(mu[i], STOKES_ALBEDOS[1:]))
                            for i in STOKES_GROUND_BEAMS]
    j = STOKES_GROUND_BEAMS[0]
    trans = x[..., 0] / np.sqrt(x[:, j, 0])[:, None]
    t_q = x[..., 1] / trans[:, j, None]
    k = STOKES_GROUND_BEAMS[1]
    departure = max(np.max(np.abs(x2[..., 0] - trans[:, k, None] * trans)) / np.max(x2[..., 0]),
                    np.max(np.abs(x2[..., 1] - trans[:, k, None] * t_q)) / np.max(x2[..., 0]),
                    np.max(np.abs(sph2 - sph)))
    print(f"ground's light: the product form holds to {departure:.1e} of the largest X_I (and S)")
    return {"tau": RAYLEIGH_TAU, "theta_deg": THETA_DEG,  # the modes as float32 (7 digits; half the size)
            "i_m": i_m.astype(np.float32), "q_m": q_m.astype(np.float32), "u_m": u_m.astype(np.float32),
            "sph_v": sph, "trans_v": trans, "ground_q": t_q,
            "depolarisation": np.array(rayleigh.DEPOLARISATION), "streams": np.array(STOKES_STREAMS),
            "levels": np.array(STOKES_LEVELS)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(TABLE_DIR), help="folder for the .npz tables")
    ap.add_argument("--only", choices=("rayleigh", "cloud", "rayleigh_stokes"), help="make one table only")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    tables = (("rayleigh", rayleigh_tables), ("cloud", cloud_table), ("rayleigh_stokes", rayleigh_stokes_tables))
    for name, make in tables:
        if a.only in (None, name):
            np.savez_compressed(out / f"{name}.npz", **make())
            print(f"wrote {out / name}.npz")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
