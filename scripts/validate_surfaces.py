"""Surfaces against independent references; writes benchmarks/validation_surfaces.json.

    python scripts/validate_surfaces.py [--out benchmarks/validation_surfaces.json]

* hemispheric Earth (albedo 0.6 on east longitudes 0–180°, 0 elsewhere) at θ = 120° and three
  sub-solar longitudes: ray-traced earthshine against tests/independent.py::mapped_irradiance
  (a lon/lat double quadrature split at the map's edges), Lambert and DHG Moons; and what the
  uniform Earth's Gauss beams (the path a mapped Earth does not take) would have given;
* a Moon bright (×1.5) on the eastern half of its near side: moonshine at θ = 60°, 120° and the
  waning twin 240°, and the waxing/waning ratio, against the same quadrature;
* ``landocean``: the facets' area-weighted mean albedo against the mask's own land fraction;
* timings of one phase (raytrace, both paths, DHG + Lambert) with each surface.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import independent as ind  # noqa: E402

from lunarviz.photometry.brdf import make_brdf  # noqa: E402
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_phase  # noqa: E402

MODELS = {"lambert": make_brdf("lambert"), "dhg": make_brdf("dhg")}


def rows(**kw):
    s = ResolvedScene(brdfs=tuple(MODELS), method="raytrace", **kw)
    t0 = time.perf_counter()
    out = {(th, r["brdf"]): r for th in s.tasks() for r in run_phase(s, th)}
    return out, time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="benchmarks/validation_surfaces.json")
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp())
    res: dict = {"command": "python scripts/validate_surfaces.py"}
    hemi = np.zeros((180, 360))
    hemi[:, 180:] = 0.6
    np.save(tmp / "hemi.npy", hemi)

    def hemi_f(lat, lon):
        return np.where((lon >= 0) & (lon < 180), 0.6, 0.0)
    earth = []
    for lam in (-30.0, -5.0, -55.0):
        r, sec = rows(phases_deg=(120.0,), earth_surface=str(tmp / "hemi.npy"), earth_rotation_deg=lam)
        ref = ind.mapped_irradiance(120.0, MODELS, earth_albedo=hemi_f, earth_lon_sub_solar_deg=lam,
                                    earth_cuts=(0, 180), n_moon=(40, 24), n_earth=(48, 32))
        for k in MODELS:
            earth.append({"sub_solar_lon_deg": lam, "brdf": k, "raytrace_W_m2": r[(120.0, k)]["earthshine_W_m2"],
                          "quadrature_W_m2": ref[k][1],
                          "rel_error": r[(120.0, k)]["earthshine_W_m2"] / ref[k][1] - 1,
                          "earth_visible_lit_albedo": r[(120.0, k)]["earth_visible_lit_albedo"],
                          "seconds_phase": sec})
    res["hemispheric_earth"] = earth
    # the uniform Earth's Gauss beams with each hit facet's albedo (what the facet sum replaces)
    gauss = []
    for order in (6, 12, 24):
        r, sec = rows(phases_deg=(120.0,), earth_surface=str(tmp / "hemi.npy"), earth_rotation_deg=-30.0,
                      earth_order=order, mapped_earth="beams")
        ref = next(e for e in earth if e["sub_solar_lon_deg"] == -30.0 and e["brdf"] == "dhg")["quadrature_W_m2"]
        gauss.append({"earth_order": order, "rel_error_dhg": r[(120.0, "dhg")]["earthshine_W_m2"] / ref - 1,
                      "seconds_phase": sec})
    res["hemispheric_earth_gauss_beams"] = gauss
    moon = np.ones((180, 360))
    moon[:, 180:270] = 1.5
    np.save(tmp / "moon.npy", moon)
    paper_albedo = {"lambert": 0.10, "dhg": 0.33}

    def moon_f(lat, lon):
        f = np.where((lon >= 0) & (lon < 90), 1.5, 1.0) / 1.125
        return {k: paper_albedo[k] * f for k in MODELS}
    r, sec = rows(phases_deg=(60.0, 120.0, 240.0), moon_albedo_map=str(tmp / "moon.npy"))
    mo = []
    refs = {}
    for th in (60.0, 120.0, 240.0):
        refs[th] = ind.mapped_irradiance(th, MODELS, moon_albedo=moon_f, moon_cuts=(0, 90), n_moon=(64, 40),
                                         n_earth=(8, 8))
        for k in MODELS:
            ms = r[(th, k)]["moonshine_W_m2"]
            mo.append({"theta_deg": th, "brdf": k, "raytrace_W_m2": ms, "quadrature_W_m2": refs[th][k][0],
                       "rel_error": ms / refs[th][k][0] - 1})
    res["half_bright_moon"] = mo
    res["waxing_over_waning_120_240"] = {
        k: {"raytrace": r[(120.0, k)]["moonshine_W_m2"] / r[(240.0, k)]["moonshine_W_m2"],
            "quadrature": refs[120.0][k][0] / refs[240.0][k][0]} for k in MODELS}
    res["half_bright_moon_seconds_3_phases"] = sec
    # a latitude-banded Earth (0.6 within 20° of the equator, 0.1 elsewhere): edges along latitude
    lat = 90 - (np.arange(180) + 0.5)
    np.save(tmp / "band.npy", np.where(np.abs(lat)[:, None] < 20, 0.6, 0.1) * np.ones((1, 360)))

    def band_f(la, lo):
        return np.where(np.abs(la) < 20, 0.6, 0.1)
    band = []
    for th in (90.0, 150.0):
        r, _ = rows(phases_deg=(th,), earth_surface=str(tmp / "band.npy"))
        ref = ind.mapped_irradiance(th, MODELS, earth_albedo=band_f, earth_lat_cuts=(-20, 20), n_moon=(32, 20),
                                    n_earth=(48, 32))
        band += [{"theta_deg": th, "brdf": k, "rel_error": r[(th, k)]["earthshine_W_m2"] / ref[k][1] - 1}
                 for k in MODELS]
    res["banded_earth"] = band
    # the half-bright Moon at crescents (its edge at the limb) and a 30° checkerboard Moon
    cres = []
    for th in (150.0, 165.0):
        r, _ = rows(phases_deg=(th,), moon_albedo_map=str(tmp / "moon.npy"))
        ref = ind.mapped_irradiance(th, MODELS, moon_albedo=moon_f, moon_cuts=(0, 90), n_moon=(64, 40), n_earth=(8, 8))
        cres += [{"theta_deg": th, "brdf": k, "rel_error": r[(th, k)]["moonshine_W_m2"] / ref[k][0] - 1}
                 for k in MODELS]
    res["half_bright_moon_crescent"] = cres
    lon = -180 + (np.arange(360) + 0.5)
    chk = np.where((np.floor(lat / 30)[:, None] + np.floor(lon / 30)[None, :]) % 2 == 0, 1.5, 0.5)
    np.save(tmp / "chk.npy", chk)
    from lunarviz.surfaces.maps import map_mean
    mc = map_mean(chk)

    def chk_f(la, lo):
        v = np.where((np.floor(la / 30) + np.floor(lo / 30)) % 2 == 0, 1.5, 0.5) / mc
        return {k: paper_albedo[k] * v for k in MODELS}
    ref = ind.mapped_irradiance(90.0, MODELS, moon_albedo=chk_f, moon_cuts=tuple(range(-180, 181, 30)),
                                moon_lat_cuts=tuple(range(-60, 61, 30)), n_moon=(20, 20), n_earth=(8, 8))
    checker = []
    for level in (4, 5, 6):
        r, _ = rows(phases_deg=(90.0,), moon_albedo_map=str(tmp / "chk.npy"), moon_level=level)
        checker += [{"moon_level": level, "brdf": k, "rel_error": r[(90.0, k)]["moonshine_W_m2"] / ref[k][0] - 1}
                    for k in MODELS]
    res["checkerboard_moon_theta90"] = checker
    from global_land_mask import globe

    from lunarviz.geometry.scene_geometry import SceneGeometry
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    w = np.cos(np.radians(globe._lat.astype(float) - 1 / 240))
    f = float(((~globe._mask).mean(axis=1) * w).sum() / w.sum())
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(earth_surface="landocean"))
    fa = ts.surfaces.earth_facet_albedo()
    mean = float((fa * ts.earth.areas).sum() / ts.earth.areas.sum())
    res["landocean"] = {"mask_land_fraction": f, "expected_mean": 0.25 * f + 0.06 * (1 - f), "facet_mean": mean,
                        "rel_error": mean / (0.25 * f + 0.06 * (1 - f)) - 1}
    timing = {}
    for name, kw in (("uniform", {}), ("moon synthetic map", dict(moon_albedo_map="synthetic")),
                     ("landocean + zonal clouds", dict(earth_surface="landocean", clouds="zonal"))):
        rows(phases_deg=(120.0,), **kw)  # warm caches (land mask, meshes)
        _, sec = rows(phases_deg=(120.0,), **kw)
        timing[name] = sec
    res["seconds_one_phase_theta120_lambert_dhg"] = timing
    Path(a.out).write_text(json.dumps(res, indent=1))
    print(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
