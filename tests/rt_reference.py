"""Independent radiative-transfer references for tests/test_earth_optics.py: disortpp (DisORT++,
a C++ discrete-ordinates code written apart from the CDISORT that made lunarviz's tables) solving
the Rayleigh layer over a Lambert surface, or a Henyey–Greenstein cloud, directly at the asked
angles; and the closed form of single scattering."""

from __future__ import annotations

import numpy as np


def disortpp_toa(tau, mu0, mus, phis_deg, *, albedo=0.0, moments=None, hg_g=None, ssalb=1.0, nstr=32,
                 nakajima=None):
    """TOA reflectance factor πI/(μ₀F) at cos θ = ``mus`` (rows) and azimuths ``phis_deg``
    (columns; 0 = viewer on the Sun's side, lunarviz's convention) of one layer over a Lambert
    surface: Legendre ``moments`` (DISORT's normalisation; all of them are kept for the intensity
    correction) or a Henyey–Greenstein ``hg_g``; ``nakajima``: Nakajima–Tanaka's intensity
    correction (default: with a Henyey–Greenstein phase function)."""
    import disortpp as dp
    mus = np.asarray(mus, float)
    order = np.argsort(mus)
    nmom = (max(nstr, len(moments) - 1) if hg_g is None else 4 * nstr)
    c = dp.DisortConfig(1, nstr, nmom)
    c.num_user_mu, c.num_phi, c.num_user_tau = len(mus), len(phis_deg), 1
    c.flags.use_user_mu = c.flags.use_user_tau = c.flags.use_lambertian_surface = True
    if (hg_g is not None) if nakajima is None else nakajima:
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


def rpv(rho0, k, theta, mu0, mu, phi_deg):
    """Rahman, Pinty & Verstraete (1993) reflectance factor (φ = 0: the hot spot, viewer on the
    Sun's side), as the I3RC reference code writes it."""
    phi = np.radians(phi_deg)
    m = mu0 ** (k - 1) * mu ** (k - 1) / (mu0 + mu) ** (1 - k)
    s0, s1 = np.sqrt(1 - mu0**2), np.sqrt(1 - mu**2)
    cos_g = mu0 * mu + s0 * s1 * np.cos(phi)
    f = (1 - theta**2) / (1 + 2 * theta * cos_g + theta**2) ** 1.5
    t0, t1 = s0 / mu0, s1 / mu
    g = np.sqrt(np.maximum(t0**2 + t1**2 - 2 * t0 * t1 * np.cos(phi), 0.0))
    return rho0 * m * f * (1 + (1 - rho0) / (1 + g))


def disortpp_rpv_toa(tau, mu0, mus, phis_deg, rpv_params, moments, nstr=32):
    """TOA reflectance factor of a layer (Legendre ``moments``) over an RPV surface
    (``rpv_params`` = (rho0, k, theta)), solved with the surface as DISORT's lower boundary."""
    import disortpp as dp
    mus = np.asarray(mus, float)
    order = np.argsort(mus)
    c = dp.DisortConfig(1, nstr, nstr)
    c.num_user_mu, c.num_phi, c.num_user_tau = len(mus), len(phis_deg), 1
    c.flags.use_user_mu = c.flags.use_user_tau = True
    c.flags.use_lambertian_surface = False
    c.flags.brdf_type = dp.BrdfType.RPV
    c.allocate()
    c.delta_tau, c.single_scat_albedo = [float(tau)], [1.0]
    pm = np.zeros(nstr + 1)
    pm[:len(moments)] = moments
    c.phase_function_moments = [pm.tolist()]
    c.tau_user = [0.0]
    c.mu_user = mus[order].tolist()
    c.phi_user = [180.0 - float(p) for p in phis_deg]
    c.bc.direct_beam_flux, c.bc.direct_beam_mu, c.bc.direct_beam_phi = 1.0, float(mu0), 0.0
    spec = dp.RpvBrdfSpec()
    spec.rho0, spec.k, spec.theta = rpv_params
    spec.sigma = spec.t1 = spec.t2 = 0.0
    spec.scale = 1.0
    c.brdf.set_rpv(spec)
    r = dp.DisortSolver().solve(c)
    out = np.array([[r.intensities(i, 0, j) for j in range(len(phis_deg))] for i in range(len(mus))])
    return out[np.argsort(order)] * np.pi / mu0


def _relative_azimuth(a, b):
    """Azimuth [deg] between the horizontal parts of unit vectors a and b (..., 3) (0: same side)."""
    ah, bh = a[..., :2], b[..., :2]
    den = np.linalg.norm(ah, axis=-1) * np.linalg.norm(bh, axis=-1)
    c = np.where(den > 1e-12, np.sum(ah * bh, axis=-1) / np.maximum(den, 1e-300), 1.0)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def monte_carlo_toa(tau, mu0, view_mu, view_phi_deg, surface_rf, phase_function, sample_cos_scattering,
                    photons=200_000, seed=1, max_orders=30):
    """TOA reflectance factor of a non-absorbing plane-parallel layer over a surface of reflectance
    factor ``surface_rf(mu_in, mu_out, phi_deg)`` by forward Monte Carlo with local estimates
    (Marchuk et al. 1980): every collision and surface hit adds its photon's probability of
    reaching the top toward each view direction, ``w P(Θ)/(4π) e^{−z/μ}/μ`` in the layer and
    ``w f_r e^{−τ/μ}`` at the surface; reflection directions are cosine-weighted with weight
    ``π f_r``. A method of its own, sharing no code with lunarviz's tables or coupling. Photons run
    in batches of 50 000 (batch b from ``default_rng([seed, b])``)."""
    acc = 0.0
    for b, start in enumerate(range(0, photons, 50_000)):
        acc = acc + _mc_batch(tau, mu0, view_mu, view_phi_deg, surface_rf, phase_function, sample_cos_scattering,
                              min(50_000, photons - start), np.random.default_rng([seed, b]), max_orders)
    return (np.pi * acc / photons).reshape(len(view_mu), -1)


def _mc_batch(tau, mu0, view_mu, view_phi_deg, surface_rf, phase_function, sample_cos_scattering, photons, rng,
              max_orders):
    vm = np.asarray(view_mu, float)[:, None]
    vp = np.radians(np.asarray(view_phi_deg, float))[None, :]
    sv = np.sqrt(1 - vm**2)
    views = np.stack(np.broadcast_arrays(sv * np.cos(vp), sv * np.sin(vp), vm), -1).reshape(-1, 3)
    acc = np.zeros(len(views))
    n = photons
    d = np.tile([-np.sqrt(1 - mu0**2), 0.0, -mu0], (n, 1))
    z = np.zeros(n)  # optical depth below the top
    w = np.ones(n)
    for _ in range(max_orders):
        s = -np.log(rng.random(n))
        down = d[:, 2] < 0
        to_edge = np.where(down, (tau - z) / np.maximum(-d[:, 2], 1e-300), z / np.maximum(d[:, 2], 1e-300))
        hit = down & (s >= to_edge)
        escape = ~down & (s >= to_edge)
        scat = ~hit & ~escape
        # collisions in the layer
        i = np.flatnonzero(scat)
        zc = z[i] + s[i] * (-d[i, 2])
        cos_t = d[i] @ views.T
        acc += np.sum(w[i, None] * phase_function(cos_t) / (4 * np.pi) * np.exp(-zc[:, None] / views[None, :, 2])
                      / views[None, :, 2], axis=0)
        # surface hits
        j = np.flatnonzero(hit)
        to_sun = -d[j]
        mu_in = to_sun[:, 2]
        phi = _relative_azimuth(to_sun[:, None, :], views[None, :, :])
        fr = surface_rf(mu_in[:, None], views[None, :, 2], phi) / np.pi
        acc += np.sum(w[j, None] * fr * np.exp(-tau / views[None, :, 2]), axis=0)
        # new directions: Rayleigh-like phase sampling in the layer, cosine-weighted off the surface
        new_d = d.copy()
        new_w = w.copy()
        new_z = z.copy()
        new_z[i] = zc
        new_d[i] = _scatter(d[i], sample_cos_scattering(rng, len(i)), rng)
        u1, u2 = rng.random(len(j)), rng.random(len(j))
        r, ph = np.sqrt(u1), 2 * np.pi * u2
        out = np.stack([r * np.cos(ph), r * np.sin(ph), np.sqrt(1 - u1)], -1)
        phi_o = _relative_azimuth(to_sun, out)
        new_w[j] = w[j] * surface_rf(mu_in, out[:, 2], phi_o)  # π f_r
        new_d[j] = out
        new_z[j] = tau
        alive = np.flatnonzero(~escape & (new_w > 1e-6))
        d, w, z, n = new_d[alive], new_w[alive], new_z[alive], len(alive)
        if n == 0:
            break
    return acc


def _scatter(d, cos_t, rng):
    """Directions at angle acos(cos_t) from d, uniformly in azimuth about it."""
    sin_t = np.sqrt(np.clip(1 - cos_t**2, 0, None))
    ph = 2 * np.pi * rng.random(len(d))
    a = np.where(np.abs(d[:, 2:3]) < 0.9, np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    e1 = np.cross(d, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(d, e1)
    return cos_t[:, None] * d + sin_t[:, None] * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2)


def sample_rayleigh_cos(gamma):
    """A sampler of cos Θ from the phase function a + b cos²Θ (``gamma``: the depolarisation's γ), by
    rejection against its maximum."""
    def sample(rng, n):
        a = 3 * (1 + 3 * gamma) / (4 * (1 + 2 * gamma))
        b = 3 * (1 - gamma) / (4 * (1 + 2 * gamma))
        out = np.empty(0)
        while len(out) < n:
            c = rng.uniform(-1, 1, 2 * n)
            keep = rng.random(2 * n) * (a + b) < a + b * c * c
            out = np.r_[out, c[keep]]
        return out[:n]
    return sample


class RpvSurface:
    """An RPV surface with the interface lunarviz's coupling asks of a surface
    (:class:`lunarviz.earth_optics.classes.Surface`): reflectance, directional and bi-hemispherical
    albedo, azimuthal Fourier coefficients at the sky's nodes, each by its own quadrature here."""

    lambertian = False

    def __init__(self, rho0, k, theta):
        self.p = (rho0, k, theta)
        x, w = np.polynomial.legendre.leggauss(96)
        self.mu, self.w = 0.5 * (x + 1), 0.5 * w
        self.psi = np.arange(180) + 0.5  # 1° midpoints over 0 … 180 (RPV is even in the azimuth)

    def __eq__(self, other):  # keyed by content where the package keeps per-surface tables
        return isinstance(other, RpvSurface) and other.p == self.p

    def __hash__(self):
        return hash(("rpv", self.p))

    def reflectance(self, wavelength_nm, mu0, mu, phi_deg, geometry=None):
        return rpv(*self.p, mu0, mu, phi_deg)

    def directional(self, wavelength_nm, mu):
        mu = np.asarray(mu, float)
        r = rpv(*self.p, self.mu[None, :, None], mu.reshape(-1)[:, None, None], self.psi[None, None, :])
        return (2 * np.einsum("ijk,j->i", r, self.w * self.mu) / len(self.psi)).reshape(mu.shape)

    def bihemispherical(self, wavelength_nm):
        return float(2 * np.sum(self.directional(wavelength_nm, self.mu) * self.w * self.mu))

    def fourier_nodes(self, wavelength_nm):
        """(K, N, 3) at the sky's nodes and the tables' zenith nodes (the coupling interpolates)."""
        from lunarviz.earth_optics.disort_tables import THETA_DEG, sky_nodes
        mk = sky_nodes()[0]
        mu = np.cos(np.radians(THETA_DEG))
        r = rpv(*self.p, mk[:, None, None], mu[None, :, None], self.psi[None, None, :])
        cos_m = np.cos(np.outer(np.arange(3), np.radians(self.psi)))
        return 2 * np.einsum("knp,mp->knm", r, cos_m) * np.radians(1.0)
