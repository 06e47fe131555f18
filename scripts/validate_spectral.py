"""The spectral Moon against ROLO, wavelength by wavelength, at real dates and two observers.

    python scripts/validate_spectral.py          # ~2 min; needs the optional rimopy
    python scripts/validate_spectral.py --quick --out DIR   # two dates, a smoke run

For each date (20, 2026-2030, phase angles 5-88° waxing and waning; none in the fit, which used
zero libration), observer
(geocentre, a ground site) and method (analytic, ray traced), lunarviz's spectral moonshine with
``--moon-model rolo-fit-map --brdf dhg --wavelengths 440,500,550,650,750,865,1000`` is turned into
disk reflectance with the row's own solar irradiance, ``A = π E / (Ω E_sun(λ))``,
``Ω = π R_M² / d²`` (R_M = 1737.4 km, ROLO's), and compared with ROLO's reflectance (Kieffer &
Stone 2005 through rimopy, independent of lunarviz) for the row's phase angle, libration and
sub-solar point. Rows where the Moon is below the site's horizon or beyond ROLO's 1.5-97° phase
range are skipped. Also checks the solar spectrum's 400-750 nm integral.

Writes ``benchmarks/spectral/rolo_spectral.{json,md}``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "spectral"
WAVELENGTHS = "440,500,550,650,750,865,1000"
#: 20 dates, 2026-2030, none in the fit (zero libration): geocentric phase angles ~5, 12, 20, 30, ...,
#: 88°, each waxing and waning (found by scanning the ephemeris every 7 h)
DATES = ("2029-01-01T03:00Z", "2030-03-19T14:00Z", "2028-01-13T01:00Z", "2028-01-11T07:00Z",
         "2029-01-02T07:00Z", "2028-01-10T17:00Z", "2030-02-20T11:00Z", "2027-01-20T11:00Z",
         "2029-01-03T18:00Z", "2028-01-09T06:00Z", "2026-09-01T07:00Z", "2027-01-19T00:00Z",
         "2029-02-03T16:00Z", "2030-01-14T10:00Z", "2026-09-02T18:00Z", "2030-02-12T07:00Z",
         "2026-09-03T15:00Z", "2027-01-16T16:00Z", "2026-09-04T05:00Z", "2027-01-16T02:00Z")
OBSERVERS = ("geocentre", "site:34.26,-116.92,2067")
R_MOON_ROLO_M = 1737.4e3


def reflectance_rows(dates=DATES) -> list[dict]:
    from lunarviz.workflows.fit import AU_M, rolo_reflectance
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_phase
    out = []
    for obs in OBSERVERS:
        for method in ("analytic", "raytrace"):
            for iso in dates:
                s = ResolvedScene(times=(iso,), brdfs=("dhg",), method=method, observer=obs,
                                  moon_model="rolo-fit-map", wavelengths=WAVELENGTHS)
                for r in run_phase(s, iso):
                    g = r["phase_angle_deg"]
                    if r["moonshine_W_m2_nm"] <= 0 or not 1.5 <= g <= 97:
                        continue
                    d = r["observer_moon_distance_m"]
                    omega = np.pi * R_MOON_ROLO_M**2 / d**2
                    a = np.pi * r["moonshine_W_m2_nm"] / (omega * r["solar_irradiance_W_m2_nm"])
                    lam = r["wavelength_nm"]
                    waxing = r["sub_solar_lon_deg"] > r["sub_observer_lon_deg"]
                    rolo = float(rolo_reflectance([g], [waxing], band=(lam, lam), lat_obs=r["sub_observer_lat_deg"],
                                                  lon_obs=r["sub_observer_lon_deg"], lon_sun=r["sub_solar_lon_deg"],
                                                  dsm_au=r["sun_moon_distance_m"] / AU_M, dom_km=d / 1e3)[0])
                    out.append({"observer": obs, "method": method, "time_utc": iso, "phase_angle_deg": g,
                                "wavelength_nm": lam, "reflectance": float(a), "rolo_reflectance": rolo,
                                "ratio": float(a / rolo)})
    return out


def main() -> int:
    import argparse

    from lunarviz.outputs.writers import write_results
    from lunarviz.spectral.solar import solar_spectrum
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two dates")
    ap.add_argument("--out", default=str(OUT), help="output folder")
    a = ap.parse_args()
    out_dir = Path(a.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = reflectance_rows(DATES[12:14] if a.quick else DATES)
    sun = solar_spectrum()
    solar = {"spectrum": sun.name, "integral_400_750_W_m2": sun.integral(400.0, 750.0),
             "reference_W_m2": 595.0, "relative_difference": sun.integral(400.0, 750.0) / 595.0 - 1}
    write_results(out_dir / "rolo_spectral.json", {"rows": rows, "solar": solar})
    lines = [f"Solar spectrum {sun.name}: 400-750 nm = {solar['integral_400_750_W_m2']:.2f} W m-2 at 1 au "
             f"({100 * solar['relative_difference']:+.2f} % from 595).", "",
             "| observer | method | dates | " + " | ".join(f"{w} nm" for w in WAVELENGTHS.split(",")) + " |",
             "| --- | --- | --- | " + " | ".join("---" for _ in WAVELENGTHS.split(",")) + " |"]
    for obs in OBSERVERS:
        for method in ("analytic", "raytrace"):
            sel = [r for r in rows if r["observer"] == obs and r["method"] == method]
            cells = []
            for w in WAVELENGTHS.split(","):
                e = [abs(r["ratio"] - 1) for r in sel if r["wavelength_nm"] == float(w)]
                cells.append(f"{100 * max(e):.1f} %" if e else "—")
            n = len({r["time_utc"] for r in sel})
            lines.append(f"| {obs} | {method} | {n} | " + " | ".join(cells) + " |")
    lines += ["", "max |A_lunarviz / A_ROLO − 1| over the dates (phase angles "
              f"{min(r['phase_angle_deg'] for r in rows):.0f}-{max(r['phase_angle_deg'] for r in rows):.0f}°), "
              "rolo-fit-map, DHG; `python scripts/validate_spectral.py`"]
    (out_dir / "rolo_spectral.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
