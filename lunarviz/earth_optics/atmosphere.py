"""The Rayleigh atmosphere over a surface: top-of-atmosphere reflectance factor.

The packaged DISORT tables (:mod:`.tables`) give, for a Rayleigh layer of optical depth τ over a
black surface, the path reflectance factor ρ_R(μ₀, μ, φ) (three Fourier modes, exact for the
order-2 phase function), the total transmittance T(μ) = e^{−τ/μ} + t(μ) and the spherical albedo
S. Over a Lambert surface of albedo A the top-of-atmosphere reflectance factor is exactly (in the
plane-parallel scalar equation; Chandrasekhar 1950, §72)::

    R = ρ_R + T(μ₀) T(μ) A / (1 − S A)

Over a surface of reflectance factor ρ_s(μ₀, μ, φ) the paths are taken one by one (Tanré, Herman
& Deschamps 1983; Vermote et al. 1997, Eq. 11, with its isotropic sky replaced by the tabulated
one)::

    R = ρ_R + e₀ e ρ_s + e/π ∫ t(μ₀; Ω') ρ_s(Ω', Ω) μ' dΩ' + e₀/π ∫ t(μ; Ω') ρ_s(Ω₀, Ω') μ' dΩ'
        + t₀ t ρ̿ + T₀ T S ρ̿² / (1 − S ρ̿)

with e = e^{−τ/μ}, t = T − e, and t(μ₀; Ω') = π I↓(Ω')/(μ₀F) the diffuse sky at the bottom (its
three Fourier modes tabulated on Gauss nodes, so that each integral is a sum over three modes and
the surface's azimuthal Fourier coefficients): the direct beam is reflected by the full BRDF, the
sky reflected once with its own shape (it brightens toward the horizon and the Sun, which a glinting
sea mirrors), the Sun's reflection scattered toward the viewer by the same integral (reciprocity),
and only the light that meets the surface after scattering twice or more goes through the
bi-hemispherical albedo ρ̿. Checked against disortpp over RPV surfaces (≤ 0.7 %) and against a
Monte Carlo of the ocean (≤ 1.7 %) (docs: the Earth as it reflects, "What it is checked
against"). Lambert surfaces take the exact form above.
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics.disort_tables import RAYLEIGH_TAU, THETA_DEG, cubic_weights, load, sky_nodes, theta_of
from lunarviz.errors import LunarvizError


def tau_weights(tau):
    tau = np.asarray(tau, dtype=float)
    # below the first node the quantities over τ are held (single scattering: exact to O(τ))
    if np.any(tau > RAYLEIGH_TAU[-1] * (1 + 1e-12)):
        raise LunarvizError(f"Rayleigh optical depth {float(np.max(tau)):.4g} is beyond the tables' "
                            f"{RAYLEIGH_TAU[-1]:g} (wavelengths below ~280 nm at sea level)")
    return cubic_weights(np.log(RAYLEIGH_TAU), np.log(tau))


def path_reflectance(tau: float, mu0, mu, phi_deg) -> np.ndarray:
    """ρ_R: the Rayleigh layer's reflectance factor over a black surface (broadcast over μ₀, μ, φ;
    φ = 0 with the viewer on the Sun's side)."""
    t = load("rayleigh")
    ti, tw = tau_weights(np.asarray(tau, float).reshape(1))
    per_tau = np.tensordot(tw[0], t["rho_m"][ti[0]] / RAYLEIGH_TAU[ti[0], None, None, None], axes=1) * tau
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    i0, w0 = cubic_weights(THETA_DEG, theta_of(mu0))
    i1, w1 = cubic_weights(THETA_DEG, theta_of(mu))
    modes = np.einsum("...a,...b,...abm->...m", w0, w1, per_tau[i0[..., :, None], i1[..., None, :]])
    ph = np.radians(phi)
    return modes[..., 0] + modes[..., 1] * np.cos(ph) + modes[..., 2] * np.cos(2 * ph)


def transmittance(tau: float, mu) -> np.ndarray:
    """T(μ): total (direct + diffuse) transmittance of the layer for a beam at cos θ = μ."""
    t = load("rayleigh")
    ti, tw = tau_weights(np.asarray(tau, float).reshape(1))
    loss = np.tensordot(tw[0], (1.0 - t["trans"][ti[0]]) / RAYLEIGH_TAU[ti[0], None], axes=1) * tau
    i1, w1 = cubic_weights(THETA_DEG, theta_of(mu))
    return 1.0 - np.einsum("...a,...a->...", w1, loss[i1])


def spherical_albedo(tau: float) -> float:
    """S: the layer's reflectance for isotropic light from below."""
    t = load("rayleigh")
    ti, tw = tau_weights(np.asarray(tau, float).reshape(1))
    return float(np.dot(tw[0], t["sph"][ti[0]] / RAYLEIGH_TAU[ti[0]]) * tau)


@memoize(maxsize=256)
def _sky_at_nodes(tau: float) -> np.ndarray:
    """(N, K, 3) :func:`sky_modes` at the tables' zenith nodes."""
    t = load("rayleigh")
    ti, tw = tau_weights(np.asarray(tau, float).reshape(1))
    out = np.tensordot(tw[0], t["sky_m"][ti[0]] / RAYLEIGH_TAU[ti[0], None, None, None], axes=1) * tau
    out.setflags(write=False)
    return out


def sky_modes(tau: float, mu0) -> np.ndarray:
    """(..., K, 3) the diffuse sky at the bottom for a beam at cos θ = μ₀: Fourier modes of
    π I↓(μ'_k, φ')/(μ₀ F) in the source azimuth φ' (0: the Sun's side), at the Gauss nodes μ'_k of
    :func:`~lunarviz.earth_optics.disort_tables.sky_nodes`."""
    i0, w0 = cubic_weights(THETA_DEG, theta_of(mu0))
    return np.einsum("...a,...akm->...km", w0, _sky_at_nodes(float(tau))[i0])


@memoize(maxsize=1024)
def _coupling(surface, wavelength_nm: float, tau: float) -> np.ndarray:
    """(N, N, 3) the sky reflected once, at the tables' zenith nodes: M_m[a, b] = Σ_k w_k μ'_k
    sky_m(θ_a; μ'_k) c_m(μ'_k, θ_b), with the sky of a beam at θ_a and the surface's azimuthal
    Fourier coefficients toward θ_b (:meth:`Surface.fourier_nodes`). Both factors are cubic in
    their zenith angle between the nodes, so the bicubic interpolation of M is the sum over the
    sky's nodes of the two interpolated factors, exactly; kept per class, wavelength and layer
    (each 47 × 47 × 3 numbers: 53 kB), keyed by the surface's value (a frozen
    :class:`~lunarviz.earth_optics.classes.Surface`; another surface must hash by its content)."""
    mu_k, w_k = sky_nodes()
    out = np.einsum("akm,kbm,k->abm", _sky_at_nodes(tau), surface.fourier_nodes(wavelength_nm), w_k * mu_k)
    out.setflags(write=False)
    return out


def _sky_reflected(e_out, coupling, beam, view, phi_deg) -> np.ndarray:
    """e_out/π Σ_m cos(mφ) M_m(θ_beam, θ_view): light of the tabulated sky of a beam reflected once
    toward the viewer by the surface, then direct; ``beam`` and ``view``: the cubic stencils
    (indices, weights) of their zenith angles."""
    (ia, wa), (ib, wb) = beam, view
    per_m = np.einsum("...a,...b,...abm->...m", wa, wb, coupling[ia[..., :, None], ib[..., None, :]])
    ph = np.radians(phi_deg)
    return e_out / np.pi * (per_m[..., 0] + per_m[..., 1] * np.cos(ph) + per_m[..., 2] * np.cos(2 * ph))


def direct(tau: float, mu) -> np.ndarray:
    """e^{−τ/μ}: the direct beam's transmittance (μ held at cos 89° as the tables are)."""
    return np.exp(-tau / np.cos(np.radians(theta_of(mu))))


def lambert_toa(tau: float, albedo, mu0, mu, phi_deg) -> np.ndarray:
    """R = ρ_R + T(μ₀) T(μ) A / (1 − S A): a Lambert surface of albedo A (a scalar, or an array
    broadcast with the angles: a map) under the layer, exactly."""
    S = spherical_albedo(tau)
    return path_reflectance(tau, mu0, mu, phi_deg) + transmittance(tau, mu0) * transmittance(tau, mu) * albedo \
        / (1.0 - S * albedo)


def toa_reflectance(tau: float, surface, wavelength_nm: float, mu0, mu, phi_deg, geometry: dict | None = None
                    ) -> np.ndarray:
    """Top-of-atmosphere reflectance factor πL/(μ₀E₀) of ``surface`` (a
    :class:`~lunarviz.earth_optics.classes.Surface`) under a Rayleigh layer of optical depth
    ``tau`` (τ = 0: the bare surface); ``geometry``: kept between wavelengths at the same angles
    (:meth:`Surface.reflectance`)."""
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    rs = surface.reflectance(wavelength_nm, mu0, mu, phi, geometry)
    if tau <= 0.0:
        return rs
    bhr = surface.bihemispherical(wavelength_nm)
    if surface.lambertian:
        return lambert_toa(tau, bhr, mu0, mu, phi)
    rr = path_reflectance(tau, mu0, mu, phi)
    T0, T1, S = transmittance(tau, mu0), transmittance(tau, mu), spherical_albedo(tau)
    e0, e1 = direct(tau, mu0), direct(tau, mu)
    t0, t1 = T0 - e0, T1 - e1
    # the sky reflected toward the viewer, and the Sun's reflection scattered toward it (by
    # reciprocity the same integral with the roles of μ₀ and μ exchanged), with the sky's own shape
    coupling = _coupling(surface, float(wavelength_nm), float(tau))
    sun, view = cubic_weights(THETA_DEG, theta_of(mu0)), cubic_weights(THETA_DEG, theta_of(mu))
    sky_down = _sky_reflected(e1, coupling, sun, view, phi)
    sun_up = _sky_reflected(e0, coupling, view, sun, phi)
    return (rr + e0 * e1 * rs + sky_down + sun_up + t0 * t1 * bhr
            + T0 * T1 * S * bhr * bhr / (1.0 - S * bhr))
