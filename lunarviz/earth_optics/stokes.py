"""The Rayleigh atmosphere's polarised light: the top-of-atmosphere Stokes vector (I, Q, U).

The packaged vector table (``rayleigh_stokes.npz``: SASKTRAN2's vector discrete-ordinates solution
of the layer of :mod:`.rayleigh`, with its depolarisation; made by ``scripts/make_earth_tables.py``)
holds, per optical depth τ, the reflectance factors π(I, Q, U)/(μ₀F) of the layer over a black
surface as Fourier series in the azimuth φ (exact for the Rayleigh phase matrix, whose expansion
ends at order 2)::

    R_I = i₀ + i₁ cos φ + i₂ cos 2φ,   R_Q = q₀ + q₁ cos φ + q₂ cos 2φ,   R_U = u₁ sin φ + u₂ sin 2φ

and, over a Lambert ground of albedo A (which reflects unpolarised light), exactly::

    R_I(A) = R_I(0) + A T(μ₀) T(μ) / (1 − S A),   R_Q(A) = R_Q(0) + A T(μ₀) t_Q(μ) / (1 − S A)

and U the black surface's: T is the layer's total transmittance (the same down and up, by
reciprocity), t_Q the Q the air gives the ground's light on its way up, S the layer's spherical
albedo (each the vector solution's: they differ from the scalar ones by up to a few per cent).

Conventions (the reference plane and the sign of U): the Stokes vector of light leaving the top
toward the viewer, in the meridian plane of the view (the plane holding the local zenith and the
direction of the light). With k the direction of the light, e_⊥ = z × k/|z × k| and e_∥ = e_⊥ × k
(in the meridian plane, (e_∥, e_⊥, k) right-handed): Q = I_∥ − I_⊥ (Q < 0: polarised across the
meridian plane, as Rayleigh light is in the principal plane) and U = I(+45°) − I(−45°), with +45°
the direction (e_∥ + e_⊥)/√2 (turning from e_∥ toward e_⊥: counterclockwise as the viewer sees the
light arrive). The azimuth φ is the viewer's azimuth less the Sun's, both seen from the place,
counterclockwise about the local zenith (φ = 0: the viewer on the Sun's side); U is odd in φ
(mirror images carry opposite U). At nadir, where z × k vanishes, the meridian plane is the limit
of the view's along its azimuth φ. The angle of linear polarisation ½ atan2(U, Q) is measured from
e_∥ toward e_⊥.

Interpolation as the scalar tables (:mod:`.disort_tables`): cubic in log τ of the quantities over
τ, cubic in the zenith angles (2° nodes, 1° beyond 86°, held at 89°). Neglected: circular
polarisation (V = 0 for Rayleigh scattering of sunlight), the polarisation of land, clouds and
the sea under the air (only black and Lambert grounds are coupled with the layer; the bare sea's
glint is :func:`lunarviz.earth_optics.ocean.glint_stokes`), ozone's (none: it absorbs I, Q and U
alike).
"""

from __future__ import annotations

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics.atmosphere import tau_weights
from lunarviz.earth_optics.disort_tables import RAYLEIGH_TAU, THETA_DEG, cubic_weights, load, theta_of


@memoize(maxsize=64)
def _at_tau(tau: float) -> dict:
    """The vector table's quantities at optical depth τ (read-only arrays)."""
    t = load("rayleigh_stokes")
    ti, tw = tau_weights(np.asarray(tau, float).reshape(1))
    ti, tw = ti[0], tw[0]

    def per_tau(name, extra):
        return np.tensordot(tw, t[name][ti] / RAYLEIGH_TAU[ti].reshape((-1,) + (1,) * extra), axes=1) * tau

    out = {"i_m": per_tau("i_m", 3), "q_m": per_tau("q_m", 3), "u_m": per_tau("u_m", 3),
           "loss": np.tensordot(tw, (1.0 - t["trans_v"][ti]) / RAYLEIGH_TAU[ti, None], axes=1) * tau,
           "ground_q": per_tau("ground_q", 1), "sph": float(np.dot(tw, t["sph_v"][ti] / RAYLEIGH_TAU[ti]) * tau)}
    for v in out.values():
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    return out


def _bicubic(nodes, mu0, mu) -> np.ndarray:
    """``nodes`` (N, N, M) at (μ₀, μ), cubic in both zenith angles: (..., M)."""
    i0, w0 = cubic_weights(THETA_DEG, theta_of(mu0))
    i1, w1 = cubic_weights(THETA_DEG, theta_of(mu))
    return np.einsum("...a,...b,...abm->...m", w0, w1, nodes[i0[..., :, None], i1[..., None, :]])


def _cubic(nodes, mu) -> np.ndarray:
    """``nodes`` (N,) at μ, cubic in the zenith angle."""
    i, w = cubic_weights(THETA_DEG, theta_of(mu))
    return np.einsum("...a,...a->...", w, nodes[i])


def lambert_stokes(tau: float, albedo, mu0, mu, phi_deg) -> np.ndarray:
    """(..., 3): the reflectance factors (R_I, R_Q, R_U) at the top of a Rayleigh layer of optical
    depth ``tau`` over a Lambert ground of ``albedo`` (0: black), in the module's conventions."""
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    albedo = np.asarray(albedo, float)
    q = _at_tau(float(tau))
    ph = np.radians(phi)
    ri, rq, ru = (_bicubic(q[k], mu0, mu) for k in ("i_m", "q_m", "u_m"))
    out = np.stack([ri[..., 0] + ri[..., 1] * np.cos(ph) + ri[..., 2] * np.cos(2 * ph),
                    rq[..., 0] + rq[..., 1] * np.cos(ph) + rq[..., 2] * np.cos(2 * ph),
                    ru[..., 0] * np.sin(ph) + ru[..., 1] * np.sin(2 * ph)], -1)
    if np.any(albedo != 0.0):
        gain = albedo / (1.0 - q["sph"] * albedo) * (1.0 - _cubic(q["loss"], mu0))
        out[..., 0] += gain * (1.0 - _cubic(q["loss"], mu))
        out[..., 1] += gain * _cubic(q["ground_q"], mu)
    return out


def degree_and_angle(stokes) -> tuple[np.ndarray, np.ndarray]:
    """The degree of linear polarisation √(Q² + U²)/I and its angle ½ atan2(U, Q) [deg] (from e_∥
    toward e_⊥, in −90 … 90) of Stokes vectors (..., 3); the degree is 0 where I is 0."""
    s = np.asarray(stokes, float)
    i, q, u = s[..., 0], s[..., 1], s[..., 2]
    p = np.hypot(q, u)
    dolp = np.divide(p, i, out=np.zeros_like(p), where=i > 0)
    return dolp, 0.5 * np.degrees(np.arctan2(u, q))


def frame_angle(e_par_from, e_perp_from, e_par_to) -> np.ndarray:
    """The angle [deg] that turns a reference frame (e_∥, e_⊥) of light, from e_∥ toward e_⊥, onto
    another frame of the same light whose e_∥ is ``e_par_to`` (unit vectors (..., 3)): the
    ``angle_deg`` of :func:`rotate` from the one to the other."""
    return np.degrees(np.arctan2(np.einsum("...i,...i->...", e_perp_from, e_par_to),
                                 np.einsum("...i,...i->...", e_par_from, e_par_to)))


def rotate(stokes, angle_deg) -> np.ndarray:
    """The Stokes vectors (..., 3) in a reference frame turned by ``angle_deg`` from e_∥ toward
    e_⊥: Q' = Q cos 2η + U sin 2η, U' = −Q sin 2η + U cos 2η (I unchanged)."""
    s = np.asarray(stokes, float)
    e = 2.0 * np.radians(angle_deg)
    c, sn = np.cos(e), np.sin(e)
    return np.stack([s[..., 0], c * s[..., 1] + sn * s[..., 2], -sn * s[..., 1] + c * s[..., 2]], -1)
