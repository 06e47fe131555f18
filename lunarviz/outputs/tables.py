"""Sweep results as an ``xarray.Dataset`` (dims brdf × phase or brdf × time) and NetCDF files.

Variables carry CF-style attributes (``units`` in UDUNITS spelling, ``long_name``); the
values are the JSON rows' values, unrounded (float64). Rows' per-task geometry (angles,
distances, libration, flags) becomes 1-D over phase or time; per-BRDF results are 2-D.
Booleans become int8 flags (NetCDF has no boolean) with ``flag_values``/``flag_meanings``;
undefined values (JSON ``null``) are NaN.
"""

from __future__ import annotations

import json
from datetime import datetime

import numpy as np

from lunarviz.outputs.writers import atomic_path, check_free_space
from lunarviz.parsing import wavelength_label

#: fields that depend on the task (phase or time) only, not on the BRDF
PER_TASK = ("theta_deg", "alpha_deg", "beta_deg", "phase_angle_deg", "observer_moon_distance_m",
            "sun_moon_distance_m", "sub_observer_lat_deg", "sub_observer_lon_deg", "sub_solar_lat_deg",
            "sub_solar_lon_deg", "moon_altitude_deg", "moon_occulted", "observer_in_shadow",
            "observer_x_m", "observer_y_m", "observer_z_m", "tle_epoch_age_days", "skip_reason",
            "scattering_plane_position_angle_deg")
#: text fields (NetCDF variable-length strings, no units): empty where there is nothing to say
TEXT = ("skip_reason", "no_bound_reason")
#: row field → (variable name, units, long name)
DESCRIPTIONS = {
    "moonshine_W_m2": ("moonshine", "W m-2", "irradiance at the detector from sunlight reflected by the Moon"),
    "earthshine_W_m2": ("earthshine", "W m-2", "irradiance at the detector from earthlight reflected by the Moon"),
    "moonshine_std_W_m2": ("moonshine_std", "W m-2", "standard deviation of one Monte Carlo run (pooled), moonshine"),
    "earthshine_std_W_m2": ("earthshine_std", "W m-2", "std. deviation of one Monte Carlo run (pooled), earthshine"),
    "moonshine_sem_W_m2": ("moonshine_sem", "W m-2", "standard deviation of the mean over runs, moonshine"),
    "earthshine_sem_W_m2": ("earthshine_sem", "W m-2", "standard deviation of the mean over runs, earthshine"),
    "earthshine_point_source_W_m2": ("earthshine_point_source", "W m-2",
                                     "earthshine with a point Earth (paper's analytic method)"),
    "ratio_earthshine_moonshine": ("ratio_earthshine_moonshine", "1", "earthshine / moonshine"),
    "geometric_albedo_term": ("geometric_albedo_term", "1", "p_E f_E(beta), paper Eq. 15"),
    "apparent_albedo": ("apparent_albedo", "1", "apparent albedo p*(beta) of the Earth, paper Eq. 16"),
    "apparent_albedo_point_source_inversion": ("apparent_albedo_point_source_inversion", "1",
                                               "p*(beta) inverted with the paper's point-source lunar terms"),
    "extended_over_point_earthshine": ("extended_over_point_earthshine", "1",
                                       "earthshine with an extended Earth over that with a point Earth"),
    "earth_visible_lit_albedo": ("earth_visible_lit_albedo", "1",
                                 "albedo of the Earth's lit face seen from the Moon, as earthshine weights it"),
    "rays": ("rays", "1", "rays submitted to Embree for this row's phase (both paths)"),
    "runs": ("runs", "1", "Monte Carlo runs"),
    "rays_per_run": ("rays_per_run", "1", "Monte Carlo rays per run and path"),
    "seconds": ("seconds", "s", "run time of this row (the task's time shared among its BRDFs)"),
    "theta_deg": ("theta", "degree", "orbital angle theta: 180 deg minus the Sun-Earth-Moon angle (paper Eq. 3)"),
    "alpha_deg": ("alpha", "degree", "lunar phase angle: Sun-Moon-detector angle"),
    "beta_deg": ("beta", "degree", "Earth's phase angle seen from the Moon: Sun-Earth-Moon angle"),
    "phase_angle_deg": ("phase_angle", "degree", "Sun-Moon-observer angle: alpha under the dated rows' name"),
    "observer_moon_distance_m": ("observer_moon_distance", "m", "observer to Moon centre distance"),
    "sun_moon_distance_m": ("sun_moon_distance", "m", "Sun centre to Moon centre distance"),
    "sub_observer_lat_deg": ("sub_observer_lat", "degree", "selenographic lat., sub-observer point (MOON_ME)"),
    "sub_observer_lon_deg": ("sub_observer_lon", "degree", "selenographic lon., sub-observer point (MOON_ME)"),
    "sub_solar_lat_deg": ("sub_solar_lat", "degree", "selenographic latitude of the sub-solar point (MOON_ME)"),
    "sub_solar_lon_deg": ("sub_solar_lon", "degree", "selenographic longitude of the sub-solar point (MOON_ME)"),
    "moon_altitude_deg": ("moon_altitude", "degree", "geometric altitude of the Moon's centre at the site"),
    "moon_occulted": ("moon_occulted", "1", "the Earth hides the Moon's centre from the observer"),
    "observer_in_shadow": ("observer_in_shadow", "1", "the Earth hides the Sun's centre from the observer"),
    "tle_epoch_age_days": ("tle_epoch_age", "day", "time from the TLE's epoch (SGP4 accuracy degrades with it)"),
    "observer_x_m": ("observer_x", "m", "observer position, geocentric ICRF x"),
    "observer_y_m": ("observer_y", "m", "observer position, geocentric ICRF y"),
    "observer_z_m": ("observer_z", "m", "observer position, geocentric ICRF z"),
    "skip_reason": ("skip_reason", "", "why the task was not computed (its rows exact zeros); empty: computed"),
    "no_bound_reason": ("no_bound_reason", "", "why the row carries no error bound (rtol NaN); empty: bounded"),
    "scattering_plane_position_angle_deg": ("scattering_plane_position_angle", "degree",
                                            "position angle on the sky (ICRF north through east) of the direction from "
                                            "the Moon toward the Sun: the scattering plane of the moonshine"),
}
#: spectral rows: fields that depend on the task and the wavelength or band, not on the BRDF
PER_TASK_SPECTRAL = ("solar_irradiance_W_m2_nm", "solar_irradiance_W_m2")
SPECTRAL_DESCRIPTIONS = {
    "moonshine_W_m2_nm": ("moonshine", "W m-2 nm-1", "spectral irradiance at the detector from sunlight reflected "
                                                     "by the Moon"),
    "earthshine_W_m2_nm": ("earthshine", "W m-2 nm-1", "spectral irradiance at the detector from earthlight "
                                                       "reflected by the Moon"),
    "solar_irradiance_W_m2_nm": ("solar_irradiance", "W m-2 nm-1", "solar spectral irradiance at the Moon's "
                                                                   "distance from the Sun"),
    "moonshine_W_m2": ("moonshine", "W m-2", "band-integrated irradiance at the detector, moonshine: "
                                             "integral of E(lambda) S(lambda) dlambda"),
    "earthshine_W_m2": ("earthshine", "W m-2", "band-integrated irradiance at the detector, earthshine: "
                                               "integral of E(lambda) S(lambda) dlambda"),
    "solar_irradiance_W_m2": ("solar_irradiance", "W m-2", "band-integrated solar irradiance at the Moon's "
                                                           "distance from the Sun"),
    "moonshine_Q_W_m2_nm": ("moonshine_Q", "W m-2 nm-1", "Stokes Q of the moonshine, I(parallel) - I(perpendicular) "
                                                         "to the scattering plane"),
    "moonshine_U_W_m2_nm": ("moonshine_U", "W m-2 nm-1", "Stokes U of the moonshine in the scattering plane's frame"),
    "moonshine_Q_W_m2": ("moonshine_Q", "W m-2", "band-integrated Stokes Q of the moonshine, I(parallel) - "
                                                 "I(perpendicular) to the scattering plane"),
    "moonshine_U_W_m2": ("moonshine_U", "W m-2", "band-integrated Stokes U of the moonshine in the scattering "
                                                 "plane's frame"),
    "moonshine_dolp": ("moonshine_dolp", "1", "degree of linear polarisation of the moonshine"),
    "moonshine_aolp_deg": ("moonshine_aolp", "degree", "angle of linear polarisation of the moonshine from the "
                                                       "scattering plane (90: perpendicular to it)"),
}
SKIP = ("brdf", "method", "estimator", "time_utc", "observer", "wavelength_nm", "band")


def _num(v):
    return np.nan if v is None else v


#: unit suffixes of row fields → UDUNITS spelling (for fields without a DESCRIPTIONS entry)
SUFFIX_UNITS = (("_W_m2_sr", "W m-2 sr-1"), ("_W_m2", "W m-2"), ("_deg", "degree"), ("_days", "day"), ("_m", "m"),
                ("_s", "s"))


def _describe(field: str) -> tuple[str, str, str]:
    """(name, units, long name) of a row field with no DESCRIPTIONS entry, from its unit suffix
    (dimensionless otherwise), so that every variable carries both attributes."""
    for suffix, units in SUFFIX_UNITS:
        if field.endswith(suffix):
            return field[: -len(suffix)], units, field[: -len(suffix)].replace("_", " ")
    return field, "1", field.replace("_", " ")


def to_dataset(result: dict):
    """An ``xarray.Dataset`` from :func:`lunarviz.workflows.sweeps.run_sweep`'s result."""
    import xarray as xr
    rows = result["rows"]
    settings = result["settings"]
    brdfs = list(dict.fromkeys(r["brdf"] for r in rows))
    timed = "time_utc" in rows[0]
    keys = list(dict.fromkeys(r["time_utc"] if timed else r["theta_deg"] for r in rows))
    dim = "time" if timed else "phase"
    spec = "wavelength" if "wavelength_nm" in rows[0] else "band" if "band" in rows[0] else None
    if spec is not None:
        return _spectral_dataset(result, rows, brdfs, keys, timed, dim, spec)
    index = {(r["brdf"], r["time_utc"] if timed else r["theta_deg"]): r for r in rows}
    coords = _task_coords(brdfs, keys, timed)
    fields = list(dict.fromkeys(k for r in rows for k in r if k not in SKIP))
    data = {}
    for f in fields:
        name, units, long_name = DESCRIPTIONS.get(f) or _describe(f)
        if f in TEXT:
            values = np.array([[str(index[(b, k)].get(f) or "") for k in keys] for b in brdfs], dtype=object)
            data[name] = ((dim,), values[0], {"long_name": long_name}) if f in PER_TASK else \
                (("brdf", dim), values, {"long_name": long_name})
            continue
        values = np.array([[_num(index[(b, k)].get(f)) for k in keys] for b in brdfs])
        is_bool = values.dtype == bool or all(isinstance(index[(b, k)].get(f), bool) for b in brdfs for k in keys)
        if f in PER_TASK:
            values, dims = values[0], (dim,)
        else:
            dims = ("brdf", dim)
        attrs = {}
        if units:
            attrs["units"] = units
        if long_name:
            attrs["long_name"] = long_name
        if is_bool:
            values = values.astype(np.int8)
            attrs.update({"flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "false true",
                          "units": "1"})
        else:
            values = values.astype(float)
        data[name] = (dims, values, attrs)
    ds = xr.Dataset(data, coords=coords)
    _label_coords(ds, timed)
    bond = result.get("bond_albedo", {})
    method = settings.get("method")
    ds["bond_albedo"] = (("brdf",), np.array([_num(bond.get(b, {}).get(method)) for b in brdfs], dtype=float),
                         BOND_ATTRS)
    _global_attrs(ds, result)
    return ds


BOND_ATTRS = {"units": "1", "long_name": "Bond albedo of the Earth from apparent albedo, corrected Eq. 17"}


def _task_coords(brdfs, keys, timed) -> dict:
    if timed:
        coord = np.array([np.datetime64(datetime.fromisoformat(k.replace("Z", "")), "ns") for k in keys])
        return {"brdf": brdfs, "time": coord}
    return {"brdf": brdfs, "phase": np.asarray(keys, dtype=float)}


def _label_coords(ds, timed) -> None:
    ds["brdf"].attrs.update({"long_name": "lunar BRDF", "units": "1"})
    if timed:
        ds["time"].attrs["long_name"] = "UTC time of the row"
        ds["time"].attrs["standard_name"] = "time"
    else:
        ds["phase"].attrs.update({"units": "degree", "long_name": "orbital angle theta of the paper's scene (Eq. 3)"})


def _spectral_dataset(result, rows, brdfs, keys, timed, dim, spec):
    """A spectral run's Dataset: per-row values over (brdf, phase|time, wavelength|band); the
    task's geometry over phase|time; the Sun at the Moon over (phase|time, wavelength|band)."""
    import xarray as xr
    label = "wavelength_nm" if spec == "wavelength" else "band"
    labels = list(dict.fromkeys(r[label] for r in rows))
    task = "time_utc" if timed else "theta_deg"
    index = {(r["brdf"], r[task], r[label]): r for r in rows}
    coords = _task_coords(brdfs, keys, timed)
    coords[spec] = np.asarray(labels, dtype=float) if spec == "wavelength" else labels
    fields = list(dict.fromkeys(k for r in rows for k in r if k not in SKIP))
    data = {}
    for f in fields:
        name, units, long_name = SPECTRAL_DESCRIPTIONS.get(f) or DESCRIPTIONS.get(f) or _describe(f)
        raw = [[[index[(b, k, lab)].get(f) for lab in labels] for k in keys] for b in brdfs]
        if f in TEXT:
            text = np.array([[[str(v or "") for v in bb] for bb in a] for a in raw], dtype=object)
            data[name] = ((dim,), text[0, :, 0], {"long_name": long_name}) if f in PER_TASK else \
                (("brdf", dim, spec), text, {"long_name": long_name})
            continue
        flag = all(isinstance(v, bool) for a in raw for bb in a for v in bb)
        values = np.array([[[_num(v) for v in bb] for bb in a] for a in raw], dtype=float)
        if f in PER_TASK:
            values, dims = values[0, :, 0], (dim,)
        elif f in PER_TASK_SPECTRAL:
            values, dims = values[0], (dim, spec)
        else:
            dims = ("brdf", dim, spec)
        attrs = {"units": units, "long_name": long_name}
        if flag:
            values = values.astype(np.int8)
            attrs.update({"flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "false true", "units": "1"})
        data[name] = (dims, values, attrs)
    ds = xr.Dataset(data, coords=coords)
    _label_coords(ds, timed)
    if spec == "wavelength":
        ds["wavelength"].attrs.update({"units": "nm", "long_name": "wavelength in vacuum",
                                       "standard_name": "radiation_wavelength"})
    else:
        ds["band"].attrs.update({"units": "1", "long_name": "spectral band (response function)"})
    bond = result.get("bond_albedo", {})
    method = result["settings"].get("method")
    key = wavelength_label if spec == "wavelength" else str
    ds["bond_albedo"] = (("brdf", spec), np.array([[_num(bond.get(b, {}).get(method, {}).get(key(lab)))
                                                    for lab in labels] for b in brdfs], dtype=float), BOND_ATTRS)
    _global_attrs(ds, result, [key(lab) for lab in labels])
    return ds


def _global_attrs(ds, result, labels=()) -> None:
    """The run's own attributes; ``labels``: a spectral run's keys in its coordinate's order."""
    settings = result["settings"]
    method = settings.get("method")
    ds.attrs.update({
        "Conventions": "CF-1.10",
        "title": f"lunarviz sweep ({method})",
        "institution": "lunarviz",
        "source": "lunarviz (earthshine and moonshine: analytic, exact reference, or Embree ray tracing)",
        "method": str(method),
        "observer": str(settings.get("observer", "geocentre")),
        "settings_json": json.dumps(settings),
        "wall_seconds": float(result.get("wall_seconds", np.nan)),
    })
    for k in EARTH_OWN_KEYS:  # the model Earth's own (grey: one value; spectral: in the labels' order)
        v = result.get(k)
        if isinstance(v, dict):
            v = np.array([_num(v.get(lab)) for lab in labels], dtype=float)
        if v is not None:
            ds.attrs[k] = v
    if isinstance(result.get("earth_albedo_at"), (str, list)):
        at = result["earth_albedo_at"]
        ds.attrs["earth_albedo_at"] = at if isinstance(at, str) else ",".join(at)
    if isinstance(result.get("earth_parameters"), dict):
        ds.attrs["earth_parameters"] = ", ".join(f"{k}={v:g}" for k, v in result["earth_parameters"].items())


#: the model Earth's own albedos (:mod:`lunarviz.workflows.earth_own_albedos`), global attributes
EARTH_OWN_KEYS = ("earth_spherical_albedo", "earth_geometric_albedo", "earth_phase_integral")


def write_netcdf(path, result: dict) -> None:
    """Write the Dataset of ``result`` as NetCDF-4 (h5netcdf), atomically."""
    ds = to_dataset(result)
    check_free_space(path, ds.nbytes)  # HDF5 crashes the process on a full disk: refuse before writing
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine="h5netcdf")
