"""Real-sky numbers against independent computations; writes benchmarks/validation_real_sky.json.

    python scripts/validate_real_sky.py [--out benchmarks/validation_real_sky.json]

* geometry at six instants 2026-2030 (geocentre) against NAIF's CSPICE on the same DE421 and
  lunar PCK files (tests/sky_reference.py);
* moonshine and earthshine (Lambert and DHG; methods reference and raytrace) at four instants
  against the numpy quadrature of tests/independent.py fed the SPICE positions;
* a site's Moon altitude against astropy/ERFA; a TLE observer against the sgp4 package + astropy.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))

import independent as ind  # noqa: E402
import sky_reference as ref  # noqa: E402
from test_sky import FLUX_TIMES, GEOMETRY_TIMES, SITE_TIMES, TLE, TLE_TIMES  # noqa: E402

from lunarviz import constants as C  # noqa: E402
from lunarviz.outputs.writers import write_results  # noqa: E402
from lunarviz.photometry.brdf import make_brdf  # noqa: E402
from lunarviz.sky.dated_scene import sky_scene  # noqa: E402
from lunarviz.sky.observers import parse_observer  # noqa: E402
from lunarviz.scene import ResolvedScene  # noqa: E402
from lunarviz.workflows.sweeps import run_phase  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(HERE, "..", "benchmarks", "validation_real_sky.json"))
    a = ap.parse_args(argv)
    geo = []
    for iso in GEOMETRY_TIMES:
        g = ref.geometry(iso)
        _, f = sky_scene(iso)
        so, ss = ref.latlon(g["to_me"] @ (-g["moon"])), ref.latlon(g["to_me"] @ (g["sun"] - g["moon"]))
        geo.append({"time_utc": f["time_utc"], "phase_angle_deg": f["phase_angle_deg"],
                    "d_phase_deg": f["phase_angle_deg"] - ref.angle_deg(g["sun"] - g["moon"], -g["moon"]),
                    "d_observer_moon_m": f["observer_moon_distance_m"] - float(np.linalg.norm(g["moon"])),
                    "d_sun_moon_m": f["sun_moon_distance_m"] - float(np.linalg.norm(g["sun"] - g["moon"])),
                    "d_sub_observer_deg": max(abs(f["sub_observer_lat_deg"] - so[0]),
                                              abs(f["sub_observer_lon_deg"] - so[1])),
                    "d_sub_solar_deg": max(abs(f["sub_solar_lat_deg"] - ss[0]), abs(f["sub_solar_lon_deg"] - ss[1]))})
    models = {k: make_brdf(k) for k in ("lambert", "dhg")}
    surf = ind.ellipsoid_surface(C.R_MOON_M, C.R_MOON_M, C.R_MOON_M, n=160)
    flux = []
    for iso in FLUX_TIMES:
        g = ref.geometry(iso)
        want = ind.detector_irradiance(None, surf, models, positions=(g["sun"], g["moon"], np.zeros(3)))
        for method in ("reference", "raytrace"):
            t0 = time.perf_counter()
            rows = run_phase(ResolvedScene(times=(iso,), brdfs=tuple(models), method=method), iso)
            dt = time.perf_counter() - t0
            for r in rows:
                ms, es = want[r["brdf"]]
                flux.append({"time_utc": r["time_utc"], "phase_angle_deg": r["phase_angle_deg"], "method": method,
                             "brdf": r["brdf"], "moonshine_rel_err": r["moonshine_W_m2"] / ms - 1,
                             "earthshine_rel_err": r["earthshine_W_m2"] / es - 1, "seconds_both_brdfs": dt})
    site = []
    for iso in SITE_TIMES:
        p, up = ref.site_gcrs(iso, 34.26, -116.92, 2067.0)
        g = ref.geometry(iso)
        _, f = sky_scene(iso, parse_observer("site:34.26,-116.92,2067"))
        alt = 90.0 - ref.angle_deg(up, g["moon"] - p)
        site.append({"time_utc": iso, "moon_altitude_deg": f["moon_altitude_deg"],
                     "d_altitude_deg": f["moon_altitude_deg"] - alt})
    tle = []
    with open(TLE) as fh:
        lines = fh.read().splitlines()
    for iso in TLE_TIMES:
        d = parse_observer(f"tle:{TLE}").position(iso) - ref.tle_gcrs(iso, lines[1], lines[2])
        tle.append({"time_utc": iso, "d_position_m": float(np.linalg.norm(d))})
    summary = {
        "max_abs_d_phase_deg": max(abs(r["d_phase_deg"]) for r in geo),
        "max_abs_d_distance_m": max(max(abs(r["d_observer_moon_m"]), abs(r["d_sun_moon_m"])) for r in geo),
        "max_abs_d_selenographic_deg": max(max(r["d_sub_observer_deg"], r["d_sub_solar_deg"]) for r in geo),
        "max_abs_flux_rel_err": {m: max(max(abs(r["moonshine_rel_err"]), abs(r["earthshine_rel_err"]))
                                        for r in flux if r["method"] == m) for m in ("reference", "raytrace")},
        "max_abs_d_site_altitude_deg": max(abs(r["d_altitude_deg"]) for r in site),
        "max_d_tle_position_m": max(r["d_position_m"] for r in tle),
    }
    write_results(a.out, {"summary": summary, "geometry": geo, "rows": flux, "site": site, "tle": tle})
    for k, v in summary.items():
        print(f"{k}: {v}")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
