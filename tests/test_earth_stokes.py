"""The Earth's polarised light (lunarviz.earth_optics.stokes) against references written here, apart
from the package and from the vector discrete-ordinates solver that made its table:

* single scattering, built from vectors (the scattering plane, the meridian plane and the angle
  between them), with the Rayleigh phase matrix of Hansen & Travis (1974, Eq. 2.16);
* a vector Monte Carlo of the layer (photons carry a Stokes vector in their own frame; collisions
  sampled from P₁₁, the Stokes vector weighted by the phase matrix over P₁₁; the radiance by the
  local estimate toward each view; a Lambert ground depolarises), a different method from the
  discrete ordinates of the table;
* the degree of polarisation ≤ 1 everywhere (near nadir and the horizon too); a rotation of the
  reference plane; the whole Earth's U = 0 (a mirror-symmetric scene).
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

import lunarviz
from lunarviz.cli import main
from lunarviz.earth_optics import stokes
from lunarviz.earth_optics.atmosphere import lambert_toa
from lunarviz.earth_optics.disort_tables import RAYLEIGH_TAU
from lunarviz.earth_optics.rayleigh import DEPOLARISATION
from lunarviz.surfaces.earth_polarisation import disc_stokes

DELTA = (1.0 - DEPOLARISATION) / (1.0 + DEPOLARISATION / 2.0)


def phase_matrix(c):
    """P₁₁, P₁₂, P₂₂, P₃₃ of Rayleigh scattering with depolarisation (Hansen & Travis 1974, Eq. 2.16:
    Δ times the pure Rayleigh matrix plus 1 − Δ of isotropic, unpolarised light), ⟨P₁₁⟩ = 1."""
    return (0.75 * DELTA * (1 + c * c) + 1 - DELTA, 0.75 * DELTA * (c * c - 1), 0.75 * DELTA * (1 + c * c),
            1.5 * DELTA * c)


def unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def sun_and_view(mu0, mu, phi_deg):
    """The sunlight's direction (the Sun at azimuth 0) and the viewed light's, counterclockwise about z."""
    s0, s1, ph = np.sqrt(1 - mu0 ** 2), np.sqrt(1 - mu ** 2), np.radians(phi_deg)
    return np.array([-s0, 0.0, -mu0]), np.array([s1 * np.cos(ph), s1 * np.sin(ph), mu])


def meridian_frame(k):
    """(e_∥, e_⊥) of light travelling along k: e_⊥ = z × k/|z × k|, e_∥ = e_⊥ × k."""
    e_perp = unit(np.cross(np.array([0.0, 0.0, 1.0]), k))
    return np.cross(e_perp, k), e_perp


def rotation(stokes_v, e_par_from, e_perp_from, e_par_to):
    """Stokes vectors (..., 3) from the frame (e_par_from, e_perp_from) to one with e_par_to."""
    c = np.sum(e_par_from * e_par_to, -1)
    s = np.sum(e_perp_from * e_par_to, -1)
    c2, s2 = c * c - s * s, 2 * s * c
    i, q, u = stokes_v[..., 0], stokes_v[..., 1], stokes_v[..., 2]
    return np.stack([i, c2 * q + s2 * u, -s2 * q + c2 * u], -1)


def single_scattering(tau, mu0, mu, phi_deg):
    """R_I, R_Q, R_U of single scattering by the layer over a black surface, in the meridian frame."""
    k0, k = sun_and_view(mu0, mu, phi_deg)
    p11, p12, _, _ = phase_matrix(k0 @ k)
    r = (1 - np.exp(-tau * (1 / mu0 + 1 / mu))) / (4 * (mu0 + mu))
    n = unit(np.cross(k0, k))
    e_par_m, _ = meridian_frame(k)
    return rotation(np.array([r * p11, r * p12, 0.0]), np.cross(n, k), n, e_par_m)


@pytest.mark.parametrize("mu0", [1.0, 0.8, 0.35])
def test_single_scattering_limit(mu0):
    # at the table's thinnest layer (τ = 1e-4) the light is single scattering but for O(τ) ~ 3e-4
    # of multiple scattering (measured: 2e-4-3.5e-4 of I): 1e-3 of I is the bar, on I, Q and U,
    # at azimuths on both sides of the principal plane (U's sign)
    # (and within 4° of nadir, where the table's nadir node takes the meridian plane's limit)
    tau = RAYLEIGH_TAU[0]
    for mu in (np.cos(np.radians(0.5)), np.cos(np.radians(3.0)), 0.95, 0.7, 0.3):
        for phi in (0.0, 45.0, 90.0, 150.0, 180.0, 230.0, 300.0):
            ref = single_scattering(tau, mu0, mu, phi)
            got = stokes.lambert_stokes(tau, 0.0, mu0, mu, phi)
            assert np.all(np.abs(got - ref) <= 1e-3 * ref[0]), (mu0, mu, phi, got / ref[0], ref / ref[0])


def test_degree_of_polarisation_at_most_one():
    # zenith angles every 0.5° within 6° of nadir and 10° of the horizon (where the nodes' frames and
    # the interpolation bend most), every 2° between, and azimuths: the interpolation between nodes
    # must not make more polarised light than light
    theta = np.radians(np.r_[np.arange(0.0, 6.0, 0.5), np.arange(6.0, 80.0, 2.0), np.arange(80.0, 89.6, 0.5)])
    mu0, mu = np.meshgrid(np.cos(theta), np.cos(theta), indexing="ij")
    for tau in (1e-4, 0.01, 0.1, 0.5, 2.0):
        for albedo in (0.0, 0.3, 1.0):
            for phi in (0.0, 10.0, 45.0, 91.0, 130.0, 180.0, 270.0):
                dolp = stokes.degree_and_angle(stokes.lambert_stokes(tau, albedo, mu0, mu, phi))[0]
                assert np.max(dolp) <= 1.0, (tau, albedo, phi, np.max(dolp))


def test_rotation_of_the_reference_plane():
    rng = np.random.default_rng(4)
    k = unit(rng.normal(size=3))
    e_par, e_perp = meridian_frame(k)
    s = np.array([1.0, 0.3, -0.2])
    for eta in (10.0, 45.0, 90.0, 133.0):
        e = np.radians(eta)
        turned = np.cos(e) * e_par + np.sin(e) * e_perp  # e_∥ turned toward e_⊥
        np.testing.assert_allclose(stokes.rotate(s, eta), rotation(s, e_par, e_perp, turned), atol=1e-14)
        # the degree is the frame's to keep; the angle turns by −η
        d0, a0 = stokes.degree_and_angle(s)
        d1, a1 = stokes.degree_and_angle(stokes.rotate(s, eta))
        assert d1 == pytest.approx(d0, rel=1e-12)
        assert np.remainder(a1 - (a0 - eta) + 90.0, 180.0) - 90.0 == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(stokes.rotate(s, 90.0), [1.0, -0.3, 0.2], atol=1e-14)


def lambert_ground(albedo):
    """A Lambert ground for :func:`vector_monte_carlo`: it reflects unpolarised light."""
    def reflect(k_in, st, e_par, e_perp, k_out):
        return np.stack([albedo * st[:, 0], 0 * st[:, 0], 0 * st[:, 0]], -1), meridian_frame(k_out)[0]
    return reflect


def vector_monte_carlo(tau, ground, mu0, views, photons, seed):
    """(V, 3) reflectance factors π(I, Q, U)/(μ₀F) toward ``views`` (μ, φ) and their standard
    errors, by a forward vector Monte Carlo of the layer over ``ground`` (:func:`lambert_ground`, or
    any reflection ``(k_in, S, e_∥, e_⊥, k_out) → (S_out, e_∥ out)``; module docstring): at the
    ground, the local estimate toward each view and a cosine-weighted new direction, each with the
    ground's reflection matrix."""
    rng = np.random.default_rng(seed)
    k_views = np.array([sun_and_view(mu0, m, p)[1] for m, p in views])
    k0 = sun_and_view(mu0, 0.5, 0.0)[0]
    k = np.tile(k0, (photons, 1))
    e_par = np.tile(meridian_frame(k0)[0], (photons, 1))  # any frame: sunlight is unpolarised
    st = np.tile([1.0, 0.0, 0.0], (photons, 1))
    depth = np.zeros(photons)  # optical depth below the top
    alive = np.ones(photons, bool)
    tally = np.zeros((photons, len(views), 3))
    for _ in range(200):
        if not alive.any():
            break
        idx = np.flatnonzero(alive)
        step = -np.log(rng.random(len(idx)))
        depth[idx] += step * -k[idx, 2]
        out_top = depth[idx] < 0.0
        alive[idx[out_top]] = False
        hit = idx[depth[idx] >= tau]
        if len(hit):
            kin, ep = k[hit], e_par[hit]
            ex = np.cross(kin, ep)
            for v, kd in enumerate(k_views):  # local estimate toward each view
                kd_all = np.tile(kd, (len(hit), 1))
                s_out, e_out = ground(kin, st[hit], ep, ex, kd_all)
                e_par_m, _ = meridian_frame(kd)
                tally[hit, v] += rotation(s_out, e_out, np.cross(kd_all, e_out), e_par_m) * np.exp(-tau / kd[2])
            cos_t, az = np.sqrt(rng.random(len(hit))), 2 * np.pi * rng.random(len(hit))
            sin_t = np.sqrt(1 - cos_t ** 2)
            k_new = np.stack([sin_t * np.cos(az), sin_t * np.sin(az), cos_t], -1)
            st[hit], e_par[hit] = ground(kin, st[hit], ep, ex, k_new)
            k[hit], depth[hit] = k_new, tau
            alive[hit[st[hit, 0] < 1e-9]] = False
        sc = idx[(~out_top) & (depth[idx] < tau)]
        if not len(sc):
            continue
        s_in, kin, ep = st[sc], k[sc], e_par[sc]
        ex = np.cross(kin, ep)  # e_⊥ of the photon's frame
        for v, kd in enumerate(k_views):  # local estimate toward each view
            n = unit(np.cross(kin, kd))
            s_rot = rotation(s_in, ep, ex, np.cross(n, kin))
            p11, p12, p22, p33 = phase_matrix(kin @ kd)
            scat = np.stack([p11 * s_rot[:, 0] + p12 * s_rot[:, 1], p12 * s_rot[:, 0] + p22 * s_rot[:, 1],
                             p33 * s_rot[:, 2]], -1)
            e_par_m, _ = meridian_frame(kd)
            s_m = rotation(scat, np.cross(n, kd), n, e_par_m)
            tally[sc, v] += s_m * (np.exp(-depth[sc] / kd[2]) / (4 * kd[2]))[:, None]
        # the next direction from P₁₁ (rejection from the isotropic), the Stokes vector weighted by P/P₁₁
        kn = np.empty_like(kin)
        todo = np.arange(len(sc))
        while len(todo):
            d = unit(rng.normal(size=(len(todo), 3)))
            ok = rng.random(len(todo)) * (1 + 0.5 * DELTA) <= phase_matrix(np.sum(kin[todo] * d, -1))[0]
            kn[todo[ok]] = d[ok]
            todo = todo[~ok]
        n = unit(np.cross(kin, kn))
        s_rot = rotation(s_in, ep, ex, np.cross(n, kin))
        p11, p12, p22, p33 = phase_matrix(np.sum(kin * kn, -1))
        st[sc] = np.stack([p11 * s_rot[:, 0] + p12 * s_rot[:, 1], p12 * s_rot[:, 0] + p22 * s_rot[:, 1],
                           p33 * s_rot[:, 2]], -1) / p11[:, None]
        k[sc], e_par[sc] = kn, np.cross(n, kn)
    batches = tally.reshape(20, -1, len(views), 3).mean(1)
    return batches.mean(0), batches.std(0, ddof=1) / np.sqrt(20)


@pytest.mark.parametrize("tau,mu0,albedo", [(0.25, 0.6, 0.0), (0.25, 0.6, 0.3), (0.61, 0.25, 0.1)])
def test_against_a_vector_monte_carlo(tau, mu0, albedo):
    # τ = 0.25 (the Rayleigh layer near 440 nm) and 0.61 (near 350 nm, off the table's nodes, a low
    # Sun): multiple scattering is a third to a half of the light and changes I by up to 5 % against
    # the scalar equation. Bar: 5 standard errors of the Monte Carlo (2e5 photons: 0.1-0.6 % of I)
    # plus 2e-3 of I for the table's discretisation (32 streams; 16 streams move I by 3e-4 at
    # τ = 0.25) on I, Q and U; the scalar table is 4σ off at least one view (the comparison sees
    # the polarisation's effect on I)
    views = [(0.9, 30.0), (0.5, 0.0), (0.5, 90.0), (0.3, 140.0), (0.2, 250.0), (np.cos(np.radians(2.0)), 60.0)]
    mc, err = vector_monte_carlo(tau, lambert_ground(albedo), mu0, views, photons=200_000, seed=11)
    got = np.array([stokes.lambert_stokes(tau, albedo, mu0, m, p) for m, p in views])
    bar = 5 * err + 2e-3 * got[:, :1]
    assert np.all(np.abs(got - mc) <= bar), (got, mc, err)
    scalar = np.array([lambert_toa(tau, albedo, mu0, m, p) for m, p in views])
    assert np.max(np.abs(scalar - mc[:, 0]) / err[:, 0]) > 4.0


def test_brdf_stokes_columns(tmp_path):
    out = tmp_path / "sky.csv"
    assert main(["brdf", "--body", "earth", "--surface", "lambert:0.1", "--stokes", "--wavelengths", "450,865",
                 "--incidence", "60", "--emission", "0:80:40", "--azimuth", "0,90,270", "--out", str(out)]) == 0
    with open(out) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 3 * 3
    assert {"q_reflectance_factor", "u_reflectance_factor", "dolp", "aolp_deg", "reflectance_factor"} <= set(rows[0])
    for r in rows:
        i, q, u = (float(r[k]) for k in ("reflectance_factor", "q_reflectance_factor", "u_reflectance_factor"))
        assert float(r["dolp"]) == pytest.approx(np.hypot(q, u) / i, rel=1e-9) and 0.0 <= float(r["dolp"]) <= 1.0
    by = {(r["wavelength_nm"], r["emission_deg"], r["azimuth_deg"]): r for r in rows}
    # the mirror: U at 270° is minus U at 90°; the blue sky is the more polarised at 90° from the Sun
    assert float(by["450.0", "40.0", "270.0"]["u_reflectance_factor"]) == pytest.approx(
        -float(by["450.0", "40.0", "90.0"]["u_reflectance_factor"]), rel=1e-9)
    api = lunarviz.brdf(body="earth", surface="lambert:0.1", stokes=True, wavelengths=[450.0], incidence=60,
                        emission=40, azimuth=90)
    assert api[0]["dolp"] == pytest.approx(float(by["450.0", "40.0", "90.0"]["dolp"]), rel=1e-12)


@pytest.mark.parametrize("argv,needle", [
    (["--body", "earth", "--surface", "ocean", "--stokes"], "surface 'ocean' is not modelled under the air"),
    (["--body", "earth", "--surface", "snow", "--stokes"], "surface 'snow' is not modelled"),
    (["--body", "moon", "--model", "dhg", "--stokes"], "--stokes are the Earth's"),
])
def test_stokes_refusals_are_one_line(tmp_path, capsys, argv, needle):
    out = tmp_path / "x.csv"
    assert main(["brdf", "--incidence", "30", "--emission", "0", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert needle in err and err.count("\n") == 1
    assert not out.exists()


def test_the_whole_earth_in_the_single_scattering_limit():
    # an optically thin Rayleigh atmosphere over a black ground: every place scatters at the same
    # angle Θ = 180° − α, across the same plane, so the disc's degree of polarisation is the single
    # scattering's, −P₁₂/P₁₁ at Θ (exact), whatever the planet's shape; U vanishes by symmetry.
    # Bar: 2e-3 (multiple scattering at τ = 1e-4, the table's 1e-3, the 1° grid's edges)
    params = {"surface_hpa": 450.0}  # τ = 1.0e-4 at 2500 nm (no ozone there)
    for alpha in (30.0, 60.0, 90.0, 120.0, 150.0):
        i, q, u = disc_stokes(alpha, 2500.0, 0.0, params, rows=90)
        p11, p12, _, _ = phase_matrix(np.cos(np.radians(180.0 - alpha)))
        assert -q / i == pytest.approx(-p12 / p11, abs=2e-3), alpha
        assert abs(u) < 1e-6 * i


def test_the_whole_earth_of_a_bright_ground_follows_lambert():
    # no air to speak of over a Lambert ground of 0.3: the Lambert sphere's phase law, p = 2A/3 and
    # Φ(α) = (sin α + (π − α) cos α)/π (Russell 1916), and no polarisation (1° grid: 2e-3)
    params = {"surface_hpa": 450.0}  # τ = 1.0e-4 at 2500 nm
    for alpha in (0.0, 45.0, 100.0, 150.0):
        a = np.radians(alpha)
        i, q, u = disc_stokes(alpha, 2500.0, 0.3, params, rows=90)
        assert i == pytest.approx(0.2 * (np.sin(a) + (np.pi - a) * np.cos(a)) / np.pi, rel=2e-3, abs=2e-5)
        assert abs(q) < 2e-3 * i and abs(u) < 1e-6 * i


def test_api_refuses_stokes_for_the_moon():
    with pytest.raises(lunarviz.LunarvizError, match="stokes='no'"):
        lunarviz.brdf(body="moon", model="dhg", stokes="no", incidence=30, emission=0)


GLINT_GEOMETRIES = [(30.0, 30.0, 180.0), (30.0, 40.0, 150.0), (30.0, 40.0, 210.0), (60.0, 20.0, 120.0),
                    (10.0, 50.0, 90.0), (40.0, 0.0, 0.0), (55.0, 55.0, 170.0)]


def test_bare_sea_glint_against_the_coxmunk_package():
    # Harmel's coxmunk gives the glint's Stokes vector in the meridian plane: I and Q equal to 1e-6
    # (the scalar glint's bar); its U has the opposite sign (the same azimuth, U of the other
    # handedness): lunarviz's sign is the one the vector construction below and the Rayleigh table share
    cm = pytest.importorskip("coxmunk.coxmunk")
    from lunarviz.earth_optics.ocean import glint_stokes
    for sza, vza, azi in GLINT_GEOMETRIES:
        ref = np.ravel(np.asarray(cm.sunglint(sza, vza, azi, m=1.34).sunglint(7.0, stats="cm_iso", shadow=True)))
        got = glint_stokes(np.cos(np.radians(sza)), np.cos(np.radians(vza)), azi, 7.0)
        np.testing.assert_allclose(got, [ref[0], ref[1], -ref[2]], rtol=1e-6, atol=1e-12)


def test_bare_sea_glint_is_polarised_across_the_plane_of_scattering():
    # a facet reflecting specularly: the light is polarised across the plane of scattering by the
    # degree (|r_s|² − |r_p|²)/(|r_s|² + |r_p|²) of Fresnel's equations (written here) at the facets'
    # incidence ω, cos 2ω = −k₀·k; its direction, from the vector construction of single scattering
    # (the same planes), is the Rayleigh light's at that geometry
    from lunarviz.earth_optics.ocean import glint_stokes
    n = 1.34
    for sza, vza, azi in GLINT_GEOMETRIES[1:5]:
        mu0, mu = np.cos(np.radians(sza)), np.cos(np.radians(vza))
        k0, k = sun_and_view(mu0, mu, azi)
        ci = np.sqrt(0.5 * (1.0 - k0 @ k))
        ct = np.sqrt(1.0 - (1.0 - ci * ci) / n ** 2)
        rs, rp = (ci - n * ct) / (ci + n * ct), (n * ci - ct) / (n * ci + ct)
        got = glint_stokes(mu0, mu, azi, 7.0)
        dolp, angle = stokes.degree_and_angle(got)
        ref_dolp, ref_angle = stokes.degree_and_angle(single_scattering(1e-4, mu0, mu, azi))
        assert dolp == pytest.approx((rs * rs - rp * rp) / (rs * rs + rp * rp), rel=1e-9)
        assert np.remainder(angle - ref_angle + 90.0, 180.0) - 90.0 == pytest.approx(0.0, abs=1e-7)


def test_brdf_stokes_of_the_bare_sea(tmp_path):
    out = tmp_path / "sea.csv"
    assert main(["brdf", "--body", "earth", "--surface", "ocean", "--no-atmosphere", "--stokes",
                 "--wavelengths", "865", "--incidence", "30", "--emission", "30", "--azimuth", "180",
                 "--out", str(out)]) == 0
    with open(out) as f:
        row = next(csv.DictReader(f))
    # the specular direction: Fresnel at 30° polarises the glint 44.1 % (coxmunk's Q/I above), the
    # unpolarised whitecaps and water (6.3e-4, 0.3 % of I at 7 m/s and 865 nm) dilute it a little
    assert 0.4 < float(row["dolp"]) < 0.45 and float(row["q_reflectance_factor"]) < 0.0
