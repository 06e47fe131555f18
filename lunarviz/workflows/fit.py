"""Fitting a lunar BRDF to disk-integrated reflectance: ROLO (through rimopy) or a table.

Disk reflectance follows ROLO's definition (Kieffer & Stone 2005, Eq. 3; Román et al. 2020):
the Moon's irradiance at the observer is ``E = A Ω E_sun / π`` with Ω = π R_M²/d_OM² the Moon's
solid angle and E_sun the solar irradiance at the Moon, so ``A = π E / (Ω E_sun)``. The model's
E is the analytic disk integral of :mod:`lunarviz.methods.analytic` (point Sun, converged Gauss rule:
exact for a sphere); its geometry-only transport is computed once per phase angle and every
trial parameter set only re-shades it, so a fit takes seconds.

ROLO (``source="rolo"``) is evaluated by the optional ``rimopy`` package (LGPL; nothing of it
is vendored) at zero libration (observer at selenographic 0°, 0°; sub-solar longitude ±g,
positive waxing), at one wavelength, or averaged over a band weighted by the solar spectrum
(Wehrli, rimopy's ESI). The paper's band is 400-750 nm.

The fit minimises the squared log residual ln(A_model/A_target) over phase angles (both
branches) with bounds (scipy's trust-region reflective least squares). Uncertainties are the
square roots of the diagonal of s² (JᵀJ)⁻¹ (s² the residual variance); a parameter counts as
*constrained* when its 1σ is below 10 % of its allowed range and below half its value, it is
not at a bound, and its correlation with every other free parameter is below 0.95 in magnitude.
Hapke parameters are notoriously degenerate
on a phase curve (w against the phase-function asymmetry, B0 against h, θ̄ against both):
the report says which ones the data pin down.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.options import BY_NAME, THETA_MOON_MODEL
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.analytic import AnalyticSettings, moonshine_transport
from lunarviz.outputs.writers import save_figure
from lunarviz.parsing import parse_float_list
from lunarviz.photometry.brdf import FIT_BOUNDS, make_brdf
from lunarviz.photometry.presets import moon_model_params
from lunarviz.surfaces.moon_map import MoonAlbedoMap
from lunarviz.surfaces.point_values import Surfaces

DEFAULT_FREE = {"dhg": ("w", "b", "c", "B0", "h", "theta_bar"), "shg": ("w", "xi", "B0", "h", "theta_bar"),
                "lambert": ("albedo",)}
ROLO_DISTANCE_KM = 384_400.0


def disk_geometry(phase_deg: float, waxing: bool | None = None):
    """A scene with the detector at the Earth's centre, the Moon 384,400 km away and the Sun
    1 au from the Moon at phase angle ``phase_deg`` (the Sun in the detector-Moon plane).

    ``waxing`` (for a lunar albedo map) also orients the Moon at zero libration: its map's
    (0°, 0°) toward the detector, north along +z, and the sub-solar point at longitude +g
    (waxing) or −g (waning), ROLO's convention; ``None`` keeps the unoriented scene (a uniform
    Moon, for which both branches are one)."""
    g = np.radians(phase_deg)
    moon = np.array([ROLO_DISTANCE_KM * 1e3, 0.0, 0.0])
    if waxing is None:
        to_sun = np.array([-np.cos(g), np.sin(g), 0.0])
        return SceneGeometry.from_vectors(moon + 1.495978707e11 * to_sun, moon)
    x_b, z_b = np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    y_b = np.cross(z_b, x_b)  # east
    lon_sun = g if waxing else -g
    to_sun = np.cos(lon_sun) * x_b + np.sin(lon_sun) * y_b
    return SceneGeometry.from_vectors(moon + 1.495978707e11 * to_sun, moon, moon_rotation=np.stack([x_b, y_b, z_b], 1))


class DiskModel:
    """Disk reflectance A(g) of a BRDF model on the analytic sphere, transports cached per g.

    ``moon_map`` (``--moon-albedo-map`` syntax, e.g. ``"synthetic"``) puts a lunar albedo map
    on the sphere (read at the Gauss nodes, order ``order``); the branches then differ and
    ``waxing`` (one flag per phase) says which each phase is."""

    def __init__(self, phases_deg, order: int = 24, waxing=None, moon_map: str | None = None):
        self.phases = np.asarray(phases_deg, dtype=float)
        if moon_map is None:
            self.scenes = [disk_geometry(p) for p in self.phases]
            st = AnalyticSettings(order=order)
        else:
            wax = np.broadcast_to(np.ones(1, bool) if waxing is None else np.asarray(waxing, bool), self.phases.shape)
            self.scenes = [disk_geometry(p, bool(w)) for p, w in zip(self.phases, wax)]
            st = AnalyticSettings(order=order, surfaces=Surfaces(moon_map=MoonAlbedoMap.parse(moon_map)))
        self.transports = [moonshine_transport(sc, st) for sc in self.scenes]

    def reflectance(self, model, map_contrast: float = 1.0) -> np.ndarray:
        """Disk reflectance at each phase; ``map_contrast`` k scales the lunar map's contrast
        (w per node ``w · (1 − k + k · map/⟨map⟩)``, :mod:`lunarviz.spectral.moon`)."""
        out = np.empty(len(self.phases))
        for k, (sc, tr) in enumerate(zip(self.scenes, self.transports)):
            if map_contrast != 1.0 and tr.albedo is not None:
                from dataclasses import replace
                tr = replace(tr, albedo=map_contrast * tr.albedo + (1.0 - map_contrast))
            e = tr.detector_irradiance(model)
            d_om = np.linalg.norm(sc.moon - sc.det)
            omega = np.pi * (sc.radii["moon"] / d_om) ** 2
            e_sun = sc.phi / (4 * np.pi * sc.d_sm**2)
            out[k] = np.pi * e / (omega * e_sun)
        return out


# ---- targets ------------------------------------------------------------------------------------
def _rimopy():
    try:
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # rimopy's deprecation notices about spicedmoon
            import rimopy.elref as elref
            import rimopy.esi as esi
            from rimopy.types import MoonDatas
    except ImportError:
        raise LunarvizError("the ROLO model needs the optional package rimopy (LGPL): pip install rimopy") from None
    return elref, esi, MoonDatas


def parse_band(text: str) -> tuple[float, float]:
    """``"550"`` (one wavelength) or ``"400-750"`` [nm]."""
    try:
        parts = [float(p) for p in str(text).replace("nm", "").split("-")]
    except ValueError:
        raise LunarvizError(f"--band {text!r} is not a wavelength or a range such as 400-750 (nm)") from None
    if len(parts) == 1:
        parts = parts * 2
    lo, hi = parts[0], parts[-1]
    if len(parts) > 2 or not (350 <= lo <= hi <= 2390):
        raise LunarvizError(f"--band {text!r} must lie within ROLO's 350-2390 nm, low to high")
    return lo, hi


def rolo_reflectance(phases_deg, waxing, band=(400.0, 750.0), lat_obs=0.0, lon_obs=0.0, lon_sun=None,
                     dsm_au=1.0, dom_km=ROLO_DISTANCE_KM) -> np.ndarray:
    """ROLO disk reflectance (rimopy, Apollo-adjusted, no RCF) at phase angles [deg].

    ``waxing`` (bool or array) sets the sub-solar longitude's sign at zero libration
    (``lon_sun = +g`` waxing, ``-g`` waning), unless ``lon_sun`` [deg] is given. A band is
    averaged at 5 nm steps weighted by the Wehrli solar spectrum.
    """
    elref, esi, MoonDatas = _rimopy()
    g = np.atleast_1d(np.asarray(phases_deg, dtype=float))
    wax = np.broadcast_to(np.asarray(waxing, dtype=bool), g.shape)
    ls = np.where(wax, g, -g) if lon_sun is None else np.broadcast_to(np.asarray(lon_sun, float), g.shape)
    b = lambda v: np.broadcast_to(np.asarray(v, dtype=float), g.shape)  # noqa: E731
    mds = MoonDatas(b(dsm_au), b(dom_km), np.radians(ls), b(lat_obs), b(lon_obs), np.where(wax, -g, g))
    lo, hi = band
    wl = np.array([lo]) if lo == hi else np.arange(lo, hi + 1e-9, 5.0)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = np.asarray(elref.get_reflectance(wl, mds=mds), dtype=float).reshape(len(g), len(wl))
        if len(wl) == 1:
            return a[:, 0]
        sun = np.asarray(esi.ESICalculatorWehrli().get_esi(wl), dtype=float)
    return (a * sun[None, :]).sum(1) / sun.sum()


#: ROLO's solid angle of the Moon at 384,400 km [sr] (rimopy's constant, Kieffer & Stone 2005)
ROLO_OMEGA = 6.4177e-05
AU_M = 1.495978707e11


def rolo_irradiance(row: dict, band=(400.0, 750.0), phi_sun: float = 1.626e26) -> float:
    """ROLO's irradiance [W m⁻²] for the geometry of a dated sweep row (``phase_angle_deg``,
    sub-observer and sub-solar selenographic points, distances), its reflectance turned into
    irradiance with lunarviz's Sun (the paper's Φ in 400–750 nm, not rimopy's solar spectrum:
    the comparison is of the lunar photometry)."""
    g = row["phase_angle_deg"]
    waxing = row["sub_solar_lon_deg"] > row["sub_observer_lon_deg"]
    a = float(rolo_reflectance([g], [waxing], band=band, lat_obs=row["sub_observer_lat_deg"],
                               lon_obs=row["sub_observer_lon_deg"], lon_sun=row["sub_solar_lon_deg"],
                               dsm_au=row["sun_moon_distance_m"] / AU_M,
                               dom_km=row["observer_moon_distance_m"] / 1e3)[0])
    e_sun = phi_sun / (4 * np.pi * row["sun_moon_distance_m"] ** 2)
    return a * ROLO_OMEGA * (ROLO_DISTANCE_KM * 1e3 / row["observer_moon_distance_m"]) ** 2 * e_sun / np.pi


#: a fit table's most rows (a phase curve binned to 0.01° has 18,000) and smallest reflectance
#: (the fit takes logarithms: subnormal values make its residuals non-finite)
MAX_TABLE_ROWS = 20_000
MIN_REFLECTANCE = 1e-12


def read_table(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A CSV with columns ``phase_deg`` and ``reflectance`` (and optionally ``waxing`` 0/1)."""
    try:
        import stat
        st_ = Path(path).stat()
        if not stat.S_ISREG(st_.st_mode):  # a FIFO or device would block the reader
            raise LunarvizError(f"table {path}: not a regular file")
        size = st_.st_size
        if size > 16 << 20:
            raise LunarvizError(f"table {path}: {size / 2**20:.0f} MiB is more than the 16 MiB a fit table may have")
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise LunarvizError(f"table {path}: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise LunarvizError(f"table {path}: not a UTF-8 CSV ({type(exc).__name__})") from None
    if not rows or not {"phase_deg", "reflectance"} <= set(rows[0]):
        raise LunarvizError(f"table {path}: needs CSV columns phase_deg and reflectance")
    if len(rows) > MAX_TABLE_ROWS:
        raise LunarvizError(f"table {path}: {len(rows):,} rows is more than the {MAX_TABLE_ROWS:,} a fit takes "
                            f"(bin the phase curve first)")
    try:
        g = np.array([float(r["phase_deg"]) for r in rows])
        a = np.array([float(r["reflectance"]) for r in rows])
        w = np.array([float(r.get("waxing") or 1) for r in rows])
    except (ValueError, TypeError):
        raise LunarvizError(f"table {path}: a row has a missing or non-numeric phase_deg/reflectance/waxing") \
            from None
    if not np.all((w == 0) | (w == 1)):
        raise LunarvizError(f"table {path}: waxing must be 0 or 1 (found {float(w[(w != 0) & (w != 1)][0])!r})")
    wax = w == 1
    if not (np.all(np.isfinite(g)) and np.all((g > 0) & (g < 180))):
        raise LunarvizError(f"table {path}: phase_deg must be in (0, 180)")
    if not np.all(np.isfinite(a) & (a >= MIN_REFLECTANCE) & (a <= 10.0)):
        bad = a[~(np.isfinite(a) & (a >= MIN_REFLECTANCE) & (a <= 10.0))][0]
        raise LunarvizError(f"table {path}: reflectance {float(bad)!r} is outside [{MIN_REFLECTANCE:g}, 10] (the fit "
                            f"works on its logarithm)")
    return g, a, wax


# ---- the fit -------------------------------------------------------------------------------------
@dataclass
class FitResult:
    brdf: str
    params: dict
    free: tuple
    sigma: dict
    correlation: np.ndarray
    constrained: dict
    phases_deg: np.ndarray
    waxing: np.ndarray
    target: np.ndarray
    model: np.ndarray
    rms_log_residual: float

    def to_dict(self) -> dict:
        return {"brdf": self.brdf, "params": self.params, "free": list(self.free), "sigma": self.sigma,
                "correlation": {a: {b: float(self.correlation[i, j]) for j, b in enumerate(self.free)}
                                for i, a in enumerate(self.free)},
                "constrained": self.constrained, "rms_log_residual": self.rms_log_residual,
                "rows": [{"phase_deg": float(g), "waxing": bool(w), "target_reflectance": float(t),
                          "model_reflectance": float(m), "relative_residual": float(m / t - 1)}
                         for g, w, t, m in zip(self.phases_deg, self.waxing, self.target, self.model)]}


def fit(brdf: str, phases_deg, target, waxing=None, free=None, start: dict | None = None,
        fixed: dict | None = None, dhg_convention: str = BY_NAME["dhg_convention"].default,
        h_function: str = BY_NAME["h_function"].default,
        moon_map: str | None = None, order: int = 24, disk_model: DiskModel | None = None) -> FitResult:
    """Least-squares fit of ``brdf``'s ``free`` parameters to disk reflectance ``target``
    (on a Moon carrying the albedo map ``moon_map``, if given: then waxing and waning differ).
    ``disk_model``: a :class:`DiskModel` of the same phases, branches, map and order, reused
    (its transports are the costly part; a band-by-band fit shares one)."""
    from scipy.optimize import least_squares

    free = tuple(free or DEFAULT_FREE[brdf])
    if len(set(free)) != len(free):
        raise LunarvizError(f"free parameters {','.join(free)} name one twice")
    if len(np.atleast_1d(phases_deg)) <= len(free):
        raise LunarvizError(f"{len(np.atleast_1d(phases_deg))} data points cannot constrain {len(free)} free "
                            f"parameters: give more phases or fewer --free")
    base = make_brdf(brdf, dhg_convention=dhg_convention, h_function=h_function)
    p0 = {**base.params, "theta_bar": 0.0, "Bc0": 0.0, "hc": 0.05} if brdf != "lambert" else dict(base.params)
    if "map_contrast" in free:  # the map's contrast (a Moon parameter, not the BRDF's): from 1, the map as given
        p0["map_contrast"] = 1.0
    p0.update(start or {})
    p0.update(fixed or {})
    for k in free:
        if k not in FIT_BOUNDS or k not in p0:
            raise LunarvizError(f"cannot fit parameter {k!r} of BRDF {brdf!r}")
    phases = np.asarray(phases_deg, dtype=float)
    target = np.asarray(target, dtype=float)
    waxing = np.ones(len(phases), bool) if waxing is None else np.asarray(waxing, bool)
    dm = disk_model or DiskModel(phases, order=order, waxing=waxing, moon_map=moon_map)
    lo = np.array([FIT_BOUNDS[k][0] for k in free])
    hi = np.array([FIT_BOUNDS[k][1] for k in free])
    x0 = np.clip(np.array([p0[k] for k in free], dtype=float), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))

    def model_of(x):
        return base.with_params(**{k: v for k, v in {**p0, **dict(zip(free, x))}.items() if k in base_keys})

    base_keys = set(p0) - {"map_contrast"}

    def contrast_of(x):
        return dict(zip(free, x)).get("map_contrast", p0.get("map_contrast", 1.0))

    def resid(x):
        return np.log(dm.reflectance(model_of(x), contrast_of(x)) / target)

    sol = least_squares(resid, x0, bounds=(lo, hi), x_scale=hi - lo, diff_step=1e-6)
    J = sol.jac
    dof = max(len(target) - len(free), 1)
    s2 = float(np.sum(sol.fun**2)) / dof
    cov = np.linalg.pinv(J.T @ J) * s2
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sig, sig)
    corr = np.nan_to_num(corr)
    params = {**{k: float(v) for k, v in p0.items()}, **{k: float(v) for k, v in zip(free, sol.x)}}
    constrained = {}
    for n, k in enumerate(free):
        others = np.delete(np.abs(corr[n]), n)
        at_bound = min(sol.x[n] - lo[n], hi[n] - sol.x[n]) < 1e-6 * (hi[n] - lo[n])
        constrained[k] = bool(sig[n] < 0.1 * (hi[n] - lo[n]) and sig[n] < 0.5 * abs(sol.x[n]) and not at_bound
                              and (others.size == 0 or others.max() < 0.95))
    model = dm.reflectance(model_of(sol.x), contrast_of(sol.x))
    return FitResult(brdf, params, free, {k: float(s) for k, s in zip(free, sig)}, corr, constrained, phases,
                     waxing, target, model, float(np.sqrt(np.mean(sol.fun**2))))


def plot_fit(res: FitResult, path, title: str = "") -> None:
    """Reflectance against phase (target and model) and the relative residual, per branch."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for wax, mk, name, col in ((True, "o", "waxing", "C0"), (False, "s", "waning", "C3")):  # (a colour a branch)
        k = res.waxing == wax
        if not k.any():
            continue
        ax[0].semilogy(res.phases_deg[k], res.target[k], mk, ms=3, mfc="none", color=col, label=f"target, {name}")
        ax[0].semilogy(res.phases_deg[k], res.model[k], "-", lw=1, color=col, label=f"{res.brdf} fit, {name}")
        ax[1].plot(res.phases_deg[k], 100 * (res.model[k] / res.target[k] - 1), mk + "-", ms=3, lw=0.7, color=col,
                   mfc="none", label=name)
    ax[0].set_ylabel("disk reflectance A")
    ax[0].legend(fontsize=7)
    ax[1].legend(fontsize=7, title="branch", title_fontsize=7)
    ax[0].set_title(title or f"{res.brdf} fitted: rms log residual {res.rms_log_residual:.3f}", fontsize=9)
    ax[1].axhline(0, color="k", lw=0.5)
    for y in (-5, 5):
        ax[1].axhline(y, color="k", lw=0.4, ls=":")
    ax[1].set_ylabel("model / target - 1 [%]")
    ax[1].set_xlabel("phase angle [deg]")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def run_fit(brdf: str, source: str = "rolo", band: str = "400-750", phases: str = "2:96:2", free=None,
            start_model: str = THETA_MOON_MODEL,
            dhg_convention: str = BY_NAME["dhg_convention"].default, h_function: str = BY_NAME["h_function"].default,
            moon_map: str | None = None, order: int = 24) -> FitResult:
    """The ``lunarviz fit`` pipeline: target from ROLO (both branches) or a CSV table."""
    if source == "rolo":
        g = np.asarray(parse_float_list(phases, "phase", 0.5, 120.0))
        G = np.concatenate([g, g])
        W = np.concatenate([np.ones(len(g), bool), np.zeros(len(g), bool)])
        A = rolo_reflectance(G, W, band=parse_band(band))
    else:
        G, A, W = read_table(source)
    start = moon_model_params(start_model, brdf) if start_model != "paper" else {}
    if brdf != "lambert" and "theta_bar" in (free or DEFAULT_FREE[brdf]):
        start = {"theta_bar": 20.0, **start}
    return fit(brdf, G, A, W, free=free, start=start, dhg_convention=dhg_convention, h_function=h_function,
               moon_map=moon_map, order=order)
