"""The Moon's linear polarisation: the disc-integrated degree of linear polarisation of ESA's
Lunar Irradiance Model (LIME), and the Stokes vector of the moonshine it gives.

Sunlight scattered by the lunar regolith is partly linearly polarised, perpendicular to the plane
of scattering (Sun, Moon, observer) at most phase angles g (the positive branch, largest near
g ≈ 90-110°) and parallel to it near opposition (the negative branch, g ≲ 23°). The signed degree
of polarisation P = (I⊥ − I∥)/(I⊥ + I∥) of the whole disc is LIME's fit to photometer
measurements (CIMEL 1088, coefficient file of 2025-10-10; ``lunarviz/data/lunar_fits/
lime_polarisation.csv`` names it and its licence): a quintic in g per wavelength (440, 500, 675,
870, 1020 and 1640 nm) and branch — waxing (before full Moon) and waning, which differ because the
dark, more polarising maria fill more of the waning disc (Umov's law: darker surfaces polarise more).

* Phase angles: 2° ≤ g ≤ 90°, the range the toolbox validates; elsewhere P is NaN (the quintic
  leaves the data beyond 90°: it falls to −6 % at 120° where the Moon's polarisation still rises).
* Wavelengths: linear between the six nodes, the 440-500 nm segment extended to 350 nm (the
  polarisation grows toward the blue as the Moon darkens; this covers the B band's blue wing, an
  extrapolation of LIME); NaN outside 350-1640 nm. The toolbox itself interpolates along a measured
  spectrum's shape; linear interpolation differs from it between the nodes (not measured here).
* Stokes vector of the moonshine in the scattering plane's frame (e∥ in the plane of the Sun, the
  Moon and the detector, e⊥ normal to it; Q = I∥ − I⊥, U = I(+45°) − I(−45°)): Q = −P I, U = 0.
  A disc-integrated model: every lunar sample takes the disc's P, so the trace sets Q through I
  alone (a map's brighter highlands are not less polarised than its maria here).

* The angle: a disc lit and seen in one plane is mirror-symmetric about it, so its polarisation
  lies across the plane (P > 0) or along it (P < 0) and U = 0. LIME also fits an angle of
  polarisation (``aolp_coeff``, −8° to −23° at 440 nm) whose reference direction its files do not
  state; it is not used. LIME's toolbox calls its polarisation preliminary, and its branch choice
  (the sign of the phase) is checked here against its own ephemeris tests and Lyot's waning Moon
  being the more polarised (``tests/test_moon_polarisation.py``).

Neglected: the polarisation of the earthshine (the Earth's polarised light and the lunar surface's
depolarisation of it are not modelled: earthshine rows stay unpolarised, none is reported), circular
polarisation, the spread of the scattering plane over the Sun's disc (0.27°), the asymmetry of the
maria about the scattering plane (which would give U ≠ 0).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from lunarviz.geometry.scene_geometry import unit
from lunarviz.resources import DATA_DIR

#: the phase angles LIME's polarisation covers [deg] (its toolbox's valid range)
PHASE_RANGE_DEG = (2.0, 90.0)
#: the wavelengths it covers here [nm]: its six nodes, 440-1640 nm, the first segment extended to 350 nm
WAVELENGTH_RANGE_NM = (350.0, 1640.0)
#: which branch of the Moon's phase curve a scene takes: before full Moon, after it, or (the θ
#: scene, whose Moon has no waxing or waning side) the mean of the two
BRANCHES = ("waxing", "waning", "mean")
COEFFICIENTS_FILE = DATA_DIR / "lunar_fits" / "lime_polarisation.csv"


@lru_cache(maxsize=1)
def coefficients() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{branch: (wavelengths (6,) [nm], coefficients (6, 6): row per wavelength, a0..a5)}``."""
    lines = [ln.split(",") for ln in COEFFICIENTS_FILE.read_text(encoding="utf-8").splitlines()
             if ln and not ln.startswith("#")][1:]  # (the header line: branch,wavelength_nm,a0..a5)
    out = {}
    for branch in ("waxing", "waning"):
        sel = np.array([[float(v) for v in ln[1:]] for ln in lines if ln[0] == branch])
        sel = sel[np.argsort(sel[:, 0])]
        out[branch] = (sel[:, 0], sel[:, 1:])
    return out


def _branch_at_nodes(phase_deg: np.ndarray, branch: str) -> tuple[np.ndarray, np.ndarray]:
    """(node wavelengths (6,), P at them (..., 6)) of one branch, the quintic in g."""
    lam, a = coefficients()[branch]
    g = np.asarray(phase_deg, float)[..., None]
    return lam, np.polynomial.polynomial.polyval(g, a.T, tensor=False)


def disc_polarisation(phase_deg, wavelength_nm, branch: str):
    """The signed degree of linear polarisation P of the Moon's disc (positive: perpendicular to the
    scattering plane) at phase angle ``phase_deg`` [deg] and ``wavelength_nm`` (broadcast
    together); NaN outside 2-90° or 350-1640 nm. ``branch``: one of :data:`BRANCHES`."""
    if branch not in BRANCHES:
        raise ValueError(f"branch {branch!r}: one of {', '.join(BRANCHES)}")
    g, lam = np.broadcast_arrays(np.asarray(phase_deg, float), np.asarray(wavelength_nm, float))
    if branch == "mean":
        return 0.5 * (disc_polarisation(g, lam, "waxing") + disc_polarisation(g, lam, "waning"))
    nodes, p_nodes = _branch_at_nodes(g, branch)
    # linear in λ between the nodes; below the first node along the first segment
    j = np.clip(np.searchsorted(nodes, lam, side="right") - 1, 0, len(nodes) - 2)
    t = (lam - nodes[j]) / (nodes[j + 1] - nodes[j])
    lo = np.take_along_axis(p_nodes, j[..., None], -1)[..., 0]
    hi = np.take_along_axis(p_nodes, (j + 1)[..., None], -1)[..., 0]
    p = lo + t * (hi - lo)
    inside = (g >= PHASE_RANGE_DEG[0]) & (g <= PHASE_RANGE_DEG[1]) \
        & (lam >= WAVELENGTH_RANGE_NM[0]) & (lam <= WAVELENGTH_RANGE_NM[1])
    return np.where(inside, p, np.nan)


def scene_branch(fields: dict) -> str:
    """The branch of a task from its row fields: on dates, waxing where the sub-solar point lies
    east of the sub-observer point (selenographic longitudes, ROLO's sign of the phase), else
    waning; the θ scene (no selenographic fields) the mean of the two."""
    if "sub_solar_lon_deg" not in fields:
        return "mean"
    d = (fields["sub_solar_lon_deg"] - fields["sub_observer_lon_deg"] + 180.0) % 360.0 - 180.0
    return "waxing" if d > 0 else "waning"


def scattering_plane_position_angle(sc) -> float:
    """Position angle [deg, 0-360] on the observer's sky of the direction from the Moon's centre
    toward the Sun (the trace of the scattering plane; the bright limb's position angle), from the
    celestial north through east (ICRF, the dated scene's frame)."""
    m, s, pole = unit(sc.moon - sc.det), unit(sc.sun - sc.det), sc.sky_north
    north, east = unit(pole - pole.dot(m) * m), unit(np.cross(pole, m))  # (the Moon never nears the pole)
    s_sky = s - s.dot(m) * m
    return float(np.degrees(np.arctan2(s_sky.dot(east), s_sky.dot(north))) % 360.0)


def stokes_fields(q, intensity, suffix: str, sc) -> dict:
    """The moonshine's Stokes fields of outputs with Stokes Q ``q`` (NaN outside the model) and
    intensities ``intensity`` (the same units, ``suffix``) in the scattering plane's frame: Q, U = 0
    (the plane's mirror symmetry), the degree of linear polarisation ``|P|`` (P = −Q/I) and its angle
    from the scattering plane [deg] (90: perpendicular; NaN without light or polarisation); a dated
    scene ``sc`` adds the plane's position angle on the sky (:func:`scattering_plane_position_angle`)."""
    q, i = np.asarray(q, float), np.asarray(intensity, float)
    p = np.where(i > 0, -q / np.where(i > 0, i, 1.0), np.nan)
    aolp = np.where(np.isnan(p), np.nan, np.where(p > 0, 90.0, 0.0))
    fields = {f"moonshine_Q{suffix}": q, f"moonshine_U{suffix}": np.where(np.isnan(q), np.nan, 0.0),
              "moonshine_dolp": np.abs(p), "moonshine_aolp_deg": aolp}
    if sc.general:
        fields["scattering_plane_position_angle_deg"] = scattering_plane_position_angle(sc)
    return fields
