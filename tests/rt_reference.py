"""Independent radiative-transfer references for tests/test_earth_optics.py: disortpp (DisORT++,
a C++ discrete-ordinates code written apart from the CDISORT that made lunarviz's tables) solving
the Rayleigh layer over a Lambert surface, or a Henyey–Greenstein cloud, directly at the asked
angles; and the closed form of single scattering."""

from __future__ import annotations

import numpy as np


def disortpp_toa(tau, mu0, mus, phis_deg, *, albedo=0.0, moments=None, hg_g=None, ssalb=1.0, nstr=32):
    """TOA reflectance factor πI/(μ₀F) at cos θ = ``mus`` (rows) and azimuths ``phis_deg``
    (columns; 0 = viewer on the Sun's side, lunarviz's convention) of one layer over a Lambert
    surface: Legendre ``moments`` (DISORT's normalisation) or a Henyey–Greenstein ``hg_g``."""
    import disortpp as dp
    mus = np.asarray(mus, float)
    order = np.argsort(mus)
    nmom = nstr if hg_g is None else 4 * nstr
    c = dp.DisortConfig(1, nstr, nmom)
    c.num_user_mu, c.num_phi, c.num_user_tau = len(mus), len(phis_deg), 1
    c.flags.use_user_mu = c.flags.use_user_tau = c.flags.use_lambertian_surface = True
    if hg_g is not None:
        c.flags.intensity_corr_nakajima = True
    c.allocate()
    c.delta_tau, c.single_scat_albedo = [float(tau)], [float(ssalb)]
    if hg_g is None:
        pm = np.zeros(nmom + 1)
        pm[:len(moments)] = moments
        c.phase_function_moments = [pm.tolist()]
    else:
        c.set_henyey_greenstein(float(hg_g))
    c.tau_user = [0.0]
    c.mu_user = mus[order].tolist()
    c.phi_user = [180.0 - float(p) for p in phis_deg]  # DISORT's 0 is the forward direction
    c.bc.direct_beam_flux, c.bc.direct_beam_mu, c.bc.direct_beam_phi = 1.0, float(mu0), 0.0
    c.bc.surface_albedo = float(albedo)
    r = dp.DisortSolver().solve(c)
    out = np.array([[r.intensities(i, 0, j) for j in range(len(phis_deg))] for i in range(len(mus))])
    return out[np.argsort(order)] * np.pi / mu0


def single_scattering(tau, mu0, mu, phi_deg, phase_function):
    """Reflectance factor of single scattering in a non-absorbing layer over a black surface:
    ρ = P(Θ) (1 − e^{−τ(1/μ₀ + 1/μ)}) / (4 (μ₀ + μ)) (Chandrasekhar 1950; Hansen & Travis
    1974, Eq. 3.16)."""
    s0, s1 = np.sqrt(1 - mu0**2), np.sqrt(1 - mu**2)
    cos_theta = -mu0 * mu - s0 * s1 * np.cos(np.radians(phi_deg))  # phi 0: backscatter side
    return phase_function(cos_theta) * (1 - np.exp(-tau * (1 / mu0 + 1 / mu))) / (4 * (mu0 + mu))
