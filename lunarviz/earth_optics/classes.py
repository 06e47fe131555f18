"""The Earth's surface classes by name, each with its reflectance factor and albedos, and the
top-of-atmosphere reflectance factor of a class: what ``lunarviz brdf --body earth`` tabulates.

Names (``--surface``): ``black`` and ``lambert:A`` (bare Lambert surfaces of albedo 0 and A),
``ocean`` (:mod:`.ocean`, wind from ``wind_speed``), ``land`` (vegetation), ``vegetation``,
``desert``, ``snow`` (:mod:`.land`, the packaged USGS spectra of :mod:`lunarviz.surfaces.earth_spectra`
as white-sky albedo) and ``cloud`` (:mod:`.cloud`, under the Rayleigh layer above its top).

Directional albedo ρ̄(μ) = (1/π) ∫ ρ(μ', μ, φ) μ' dμ' dφ and bi-hemispherical albedo ρ̿ = 2 ∫ ρ̄ μ dμ
are computed by Gauss–Legendre quadrature in μ' (:data:`ALBEDO_ORDER` nodes) and the midpoint
rule in φ (every 2.5°), on the tables' zenith nodes, and interpolated cubically between them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lunarviz.caches import memoize
from lunarviz.earth_optics import ozone, rayleigh, stokes
from lunarviz.earth_optics.atmosphere import lambert_toa
from lunarviz.earth_optics.atmosphere import toa_reflectance as couple
from lunarviz.earth_optics.cloud import cloud_reflectance
from lunarviz.earth_optics.disort_tables import THETA_DEG, cubic_weights, sky_nodes, theta_of
from lunarviz.earth_optics.land import land_directional, land_parts, land_shape
from lunarviz.earth_optics.spectra import class_spectrum
from lunarviz.errors import LunarvizError
from lunarviz.options import EARTH_PARAMETER_DEFAULTS, earth_params

#: Gauss nodes in cos θ' for the albedos (the glint lobe of a 2 m s⁻¹ sea is ~10° wide)
ALBEDO_ORDER = 96
#: classes with a packaged spectrum serving as albedo
LAND_CLASSES = ("vegetation", "desert", "snow")
SURFACE_NAMES = ("black", "lambert:A", "ocean", "land", *LAND_CLASSES, "cloud")
@dataclass(frozen=True)
class Surface:
    """One class: ``kind`` (lambert, ocean, land, cloud; internally also glint and shape, the sea's
    and the land's wavelength-free shapes), its albedo (lambert), land class, wind."""
    kind: str
    albedo: float = 0.0
    land_class: str = ""
    wind_speed: float = EARTH_PARAMETER_DEFAULTS["wind_speed"]
    #: a cloud's optical depth at 550 nm
    optical_depth: float = EARTH_PARAMETER_DEFAULTS["cloud_optical_depth"]
    #: the ocean's chlorophyll concentration [mg m⁻³]
    chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]

    @property
    def lambertian(self) -> bool:
        return self.kind == "lambert"

    def reflectance(self, wavelength_nm, mu0, mu, phi_deg, geometry: dict | None = None) -> np.ndarray:
        """The bare surface's reflectance factor (πBRDF); ``geometry``: a dict in which the
        wavelength-free parts at these angles are kept between calls (the glint, the land's shape,
        the cloud)."""
        if geometry is not None:
            key = (self.kind, self.wind_speed, self.optical_depth)
            if key not in geometry:
                geometry[key] = self._wavelength_free(mu0, mu, phi_deg)
            return self._at_wavelength(wavelength_nm, geometry[key])
        if self.kind == "lambert":
            return np.full(np.broadcast(np.asarray(mu0), np.asarray(mu), np.asarray(phi_deg)).shape, self.albedo)
        if self.kind == "cloud":
            return cloud_reflectance(mu0, mu, phi_deg, self.optical_depth)
        # the sea and the land: their shape at λ; glint and shape: the shapes alone
        return self._at_wavelength(wavelength_nm, self._wavelength_free(mu0, mu, phi_deg))

    def _wavelength_free(self, mu0, mu, phi_deg):
        if self.kind in ("ocean", "glint"):
            from lunarviz.earth_optics.ocean import glint
            return glint(mu0, mu, phi_deg, self.wind_speed)
        if self.kind in ("land", "shape"):
            return land_shape(mu0, mu, phi_deg)
        return self.reflectance(550.0, mu0, mu, phi_deg)  # Lambert, cloud: grey

    def _at_wavelength(self, wavelength_nm, part):
        if self.kind in ("ocean", "land"):
            constant, scale = self._parts(wavelength_nm)
            return constant + scale * part
        return part

    def _parts(self, wavelength_nm) -> tuple[float, float]:
        """(constant, scale): the sea and the land reflect ρ = constant + scale × their wavelength-free
        shape (:meth:`_wavelength_free`: the glint, the Ross–Li shape) at λ, so that what is
        linear in ρ (its albedos, its Fourier coefficients) is the shape's, once, rescaled."""
        if self.kind == "ocean":
            from lunarviz.earth_optics.ocean import ocean_parts
            constant, scale = ocean_parts(wavelength_nm, self.wind_speed, self.chlorophyll)
        else:
            constant, scale = land_parts(self.land_albedo(wavelength_nm))
        return float(constant), float(scale)

    def land_albedo(self, wavelength_nm) -> float:
        lam, a = class_spectrum(self.land_class)
        return float(np.interp(float(wavelength_nm), lam, a))

    def _albedos(self, wavelength_nm) -> tuple[np.ndarray, float]:
        # a cloud is grey: its albedos do not depend on λ
        return _albedos(self, None if self.kind == "cloud" else float(wavelength_nm))

    @staticmethod
    def _interp(nodes_values, mu) -> np.ndarray:
        i, w = cubic_weights(THETA_DEG, theta_of(mu))
        return np.einsum("...a,...a->...", w, nodes_values[i])

    def directional(self, wavelength_nm, mu) -> np.ndarray:
        """ρ̄(μ): the directional (= hemispherical-directional, by reciprocity) albedo."""
        if self.lambertian:
            return np.full(np.shape(mu), self.albedo)
        return self._interp(self._albedos(wavelength_nm)[0], np.asarray(mu, float))

    def fourier_nodes(self, wavelength_nm) -> np.ndarray:
        """(K, N, 3) c_m(μ'_k, μ_n) = ∫₀^{2π} cos(mψ) ρ(μ'_k, μ_n, ψ) dψ, m = 0, 1, 2, at the sky's
        Gauss nodes μ'_k (:func:`~lunarviz.earth_optics.disort_tables.sky_nodes`) and the tables'
        zenith nodes μ_n (cubic between them)."""
        return _fourier(self, None if self.kind in ("cloud", "lambert") else float(wavelength_nm))

    def bihemispherical(self, wavelength_nm) -> float:
        """ρ̿: the albedo under isotropic light."""
        return self.albedo if self.lambertian else self._albedos(wavelength_nm)[1]


@memoize(maxsize=4096)
def _albedos(surface: Surface, wavelength_nm) -> tuple[np.ndarray, float]:
    """(directional albedo on the zenith nodes, bi-hemispherical albedo) of a class (module docstring)."""
    lam = 550.0 if wavelength_nm is None else wavelength_nm
    if surface.kind == "land":  # linear in the kernels' shape: closed form
        return land_directional(surface.land_albedo(lam))
    if surface.kind == "ocean":  # linear in the glint: its albedos, once, rescaled
        constant, scale = surface._parts(lam)
        dhr, bhr = _albedos(Surface("glint", wind_speed=surface.wind_speed), None)
        out = constant + scale * dhr
        out.setflags(write=False)
        return out, constant + scale * bhr
    x, w = np.polynomial.legendre.leggauss(ALBEDO_ORDER)
    mup, wmu = 0.5 * (x + 1.0), 0.5 * w
    nphi = 72  # over 0 … 180 (symmetric)
    phi = (np.arange(nphi) + 0.5) * 180.0 / nphi
    mu_nodes = np.cos(np.radians(THETA_DEG))
    r = surface.reflectance(lam, mup[None, :, None], mu_nodes[:, None, None], phi[None, None, :])
    dhr = 2.0 * np.einsum("ijk,j->i", r, wmu * mup) / nphi  # (1/π) ∫ dφ over 2π = 2/nphi Σ over 0…180
    dhr.setflags(write=False)
    xg, wg = np.polynomial.legendre.leggauss(48)
    mug = 0.5 * (xg + 1.0)
    return dhr, float(2.0 * np.sum(0.5 * wg * mug * Surface._interp(dhr, mug)))


@memoize(maxsize=4096)
def _fourier(surface: Surface, wavelength_nm) -> np.ndarray:
    """(K, N, 3) azimuthal Fourier coefficients of a class's reflectance factor at the sky's Gauss
    nodes μ'_k and the tables' zenith nodes: c_m = 2 ∫₀^π cos(mψ) ρ dψ (ρ even in ψ; midpoint rule,
    1° steps: the 1 m s⁻¹ glint lobe is ~10° wide)."""
    mu_k = sky_nodes()[0]
    mu_n = np.cos(np.radians(THETA_DEG))
    if surface.kind in ("lambert", "ocean", "land"):
        # a constant's modes, plus the wavelength-free shape's (the glint, the Ross–Li shape) rescaled
        constant, scale = (surface.albedo, 0.0) if surface.kind == "lambert" else surface._parts(wavelength_nm)
        out = np.zeros((len(mu_k), len(mu_n), 3))
        if scale:
            shape = Surface("glint" if surface.kind == "ocean" else "shape", wind_speed=surface.wind_speed)
            out += scale * _fourier(shape, None)
        out[..., 0] += 2 * np.pi * constant
        out.setflags(write=False)
        return out
    psi = np.arange(180) + 0.5
    r = surface.reflectance(550.0 if wavelength_nm is None else wavelength_nm,
                            mu_k[:, None, None], mu_n[None, :, None], psi[None, None, :])
    cos_m = np.cos(np.outer(np.arange(3), np.radians(psi)))
    out = 2 * np.einsum("knp,mp->knm", r, cos_m) * np.radians(1.0)
    out.setflags(write=False)
    return out


def surface_from_name(text: str, wind_speed: float = EARTH_PARAMETER_DEFAULTS["wind_speed"],
                      cloud_optical_depth: float = EARTH_PARAMETER_DEFAULTS["cloud_optical_depth"],
                      chlorophyll: float = EARTH_PARAMETER_DEFAULTS["chlorophyll"]) -> Surface:
    """A :class:`Surface` from ``black``, ``lambert:A``, ``ocean`` (of ``chlorophyll`` mg m⁻³),
    ``land``, ``vegetation``, ``desert``, ``snow`` or ``cloud`` (of optical depth
    ``cloud_optical_depth``); a bad name or albedo raises one line naming it."""
    if not isinstance(text, str):
        raise LunarvizError(f"earth surface {text!r} must be a name such as 'ocean' or 'lambert:0.3'")
    name = text.strip().lower()
    if name == "black":
        return Surface("lambert", 0.0)
    if name.startswith("lambert:"):
        try:
            a = float(name.split(":", 1)[1])
        except ValueError:
            a = float("nan")
        if not 0.0 <= a <= 1.0:
            raise LunarvizError(f"earth surface {text!r}: lambert:A needs an albedo A in 0…1")
        return Surface("lambert", a)
    if name == "ocean":
        return Surface("ocean", wind_speed=float(wind_speed), chlorophyll=float(chlorophyll))
    if name in ("land",) + LAND_CLASSES:
        return Surface("land", land_class="vegetation" if name == "land" else name)
    if name == "cloud":
        return Surface("cloud", optical_depth=float(cloud_optical_depth))
    raise LunarvizError(f"earth surface {text!r} is not one of {', '.join(SURFACE_NAMES)}")


def lambert_ground_toa(albedo, wavelength_nm: float, mu0, mu, phi_deg, params: dict | None = None) -> np.ndarray:
    """Top-of-atmosphere reflectance factor of a Lambert ground of ``albedo`` (a scalar, or an
    array broadcast with the angles: a map's places) under the air above ``surface_hpa`` and the
    ozone, exactly (:func:`~lunarviz.earth_optics.atmosphere.lambert_toa`): what
    :func:`toa_reflectance` gives a ``lambert:A`` class, for albedos that vary place by place."""
    p = earth_params(params)
    tau = float(rayleigh.optical_depth(wavelength_nm, p["surface_hpa"]))
    return lambert_toa(tau, albedo, mu0, mu, phi_deg) * ozone.transmittance(wavelength_nm, p["ozone_du"], mu0, mu)


def toa_reflectance(surface: Surface, wavelength_nm: float, mu0, mu, phi_deg, atmosphere: bool = True,
                    params: dict | None = None, geometry: dict | None = None) -> np.ndarray:
    """Top-of-atmosphere reflectance factor πL/(μ₀E₀) of ``surface`` at λ; ``atmosphere=False``
    gives the bare surface. A cloud sits under the Rayleigh layer above ``cloud_top_hpa``; the ozone
    column absorbs above them all (:mod:`.ozone`)."""
    p = earth_params(params)
    if not atmosphere:
        return couple(0.0, surface, wavelength_nm, mu0, mu, phi_deg, geometry)
    top = p["cloud_top_hpa"] if surface.kind == "cloud" else p["surface_hpa"]
    tau = float(rayleigh.optical_depth(wavelength_nm, top))
    return couple(tau, surface, wavelength_nm, mu0, mu, phi_deg, geometry) \
        * ozone.transmittance(wavelength_nm, p["ozone_du"], mu0, mu)


def toa_stokes(surface: Surface, wavelength_nm: float, mu0, mu, phi_deg, atmosphere: bool = True,
               params: dict | None = None) -> np.ndarray:
    """(..., 3): the top-of-atmosphere reflectance factors of the Stokes vector (I, Q, U) of a
    ``black`` or ``lambert:A`` class (or the bare sea) at λ under the air above ``surface_hpa`` and
    the ozone, in the meridian plane of the view (:mod:`.stokes`: the vector solution; its I differs from
    :func:`toa_reflectance`'s scalar one by up to a few per cent). A bare Lambert surface reflects
    unpolarised light; the bare sea (``atmosphere=False``) its polarised glint
    (:func:`~lunarviz.earth_optics.ocean.glint_stokes`) beside its unpolarised whitecaps and water.
    Other classes, and the sea under the air: one line naming the class (not modelled)."""
    name = surface.land_class or surface.kind
    p = earth_params(params)
    mu0, mu, phi = np.broadcast_arrays(np.asarray(mu0, float), np.asarray(mu, float), np.asarray(phi_deg, float))
    if surface.kind == "ocean" and not atmosphere:
        from lunarviz.earth_optics.ocean import glint_stokes
        constant, scale = surface._parts(wavelength_nm)
        out = scale * glint_stokes(mu0, mu, phi, surface.wind_speed)
        out[..., 0] += constant
        return out
    if not surface.lambertian:
        where = " under the air (the bare sea's glint is: no atmosphere)" if surface.kind == "ocean" else ""
        raise LunarvizError(f"the polarisation of the earth surface {name!r} is not modelled{where}: Stokes vectors "
                            "are for black and lambert:A grounds and the bare sea")
    if not atmosphere:
        return np.stack([np.full(mu0.shape, surface.albedo), np.zeros(mu0.shape), np.zeros(mu0.shape)], -1)
    tau = float(rayleigh.optical_depth(wavelength_nm, p["surface_hpa"]))
    return stokes.lambert_stokes(tau, surface.albedo, mu0, mu, phi) \
        * ozone.transmittance(wavelength_nm, p["ozone_du"], mu0, mu)[..., None]
