"""What the paper could not do: one lunation, and a total lunar eclipse, on the real sky.

    python scripts/real_sky.py [--out benchmarks/real_sky] [--quick]

* ``lunation.{json,csv,png}``: moonshine, earthshine and the inverted apparent albedo p*(β)
  through the lunation of June 2026 (new Moon 2026-05-16 and 2026-06-15 are outside; full
  Moon 2026-05-31), every 6 h, for three detectors: the geocentre, a ground site (34.26° N,
  116.92° W, 2067 m) and a 550 km sun-synchronous-like circular orbit. Ray traced (DHG, occlusion
  on): rows where the Earth hides the Moon are 0 and flagged.
* ``eclipse_2025-03-14.{json,csv,png}``: moonshine through the total lunar eclipse of
  2025-03-14 (geocentre, every 5 min), ray traced with occlusion (umbra black: no atmosphere)
  and without (the Moon as if the Earth were transparent).

``--quick`` runs a few points of each with the analytic method (a smoke test for CI).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from lunarviz.outputs.writers import write_results
from lunarviz.sky.ephemeris import time_list
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep

OBSERVERS = {"geocentre": "geocentre", "site 34.26N 116.92W 2067 m": "site:34.26,-116.92,2067",
             "LEO 550 km, i 97.6°": "orbit:550,97.6,0,0"}


def _hours(rows, t0):
    from datetime import datetime
    t0 = datetime.fromisoformat(t0.replace("Z", "+00:00"))
    return np.array([(datetime.fromisoformat(r["time_utc"].replace("Z", "+00:00")) - t0).total_seconds() / 3600
                     for r in rows])


def lunation(out: Path, quick: bool):
    times = time_list(time_range="2026-06-01,2026-06-13,4d" if quick else "2026-06-01,2026-06-30,6h")
    method = "analytic" if quick else "raytrace"
    rows, payload = [], {"observers": OBSERVERS, "runs": []}
    for label, spec in OBSERVERS.items():
        res = run_sweep(ResolvedScene(times=times, observer=spec, brdfs=("dhg",), method=method), progress=False)
        for r in res["rows"]:
            r["observer_label"] = label
        rows += res["rows"]
        payload["runs"].append({"observer": spec, "settings": res["settings"], "wall_seconds": res["wall_seconds"]})
    payload["rows"] = rows
    payload["method"] = method
    write_results(out / "lunation.json", payload)
    write_results(out / "lunation.csv", {"rows": rows})
    plot_lunation(out, payload)


def plot_lunation(out: Path, payload: dict):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, method = payload["rows"], payload.get("method", "raytrace")
    t0 = rows[0]["time_utc"]
    fig, ax = plt.subplots(3, 1, figsize=(10, 10), sharex=True)
    for label in OBSERVERS:
        rs = [r for r in rows if r["observer_label"] == label]
        d = _hours(rs, t0) / 24
        occ = np.array([r["moon_occulted"] for r in rs])
        ms = np.array([r["moonshine_W_m2"] for r in rs])
        es = np.array([r["earthshine_W_m2"] for r in rs])

        def val(r, k):
            return np.nan if r.get(k) is None else r[k]
        p = np.array([val(r, "apparent_albedo") for r in rs], dtype=float)
        pp = np.array([val(r, "apparent_albedo_point_source_inversion") for r in rs], dtype=float)
        line, = ax[0].semilogy(d[~occ], ms[~occ], ".-", ms=3, lw=0.6, label=label)
        # occulted dates (irradiance exactly 0: no place on a log axis) as ticks along the axis's
        # foot, one row per observer
        row = 0.03 + 0.04 * list(OBSERVERS).index(label)
        ax[0].plot(d[occ], np.full(occ.sum(), row), "|", color=line.get_color(), ms=6,
                   transform=ax[0].get_xaxis_transform())
        ax[1].semilogy(d[~occ], es[~occ], ".-", ms=3, lw=0.6, color=line.get_color())
        if np.isfinite(pp).any():
            ax[2].plot(d[~occ], pp[~occ], ".", ms=3, color=line.get_color())
        else:
            ax[2].plot(d[~occ], p[~occ], ".", ms=3, color=line.get_color())
    ax[0].set_ylabel("moonshine [W m$^{-2}$]")
    ax[0].set_title(f"One lunation, {rows[0]['time_utc'][:10]} to {rows[-1]['time_utc'][:10]}, {method}, "
                    "DHG Moon; | at the foot: the Moon occulted by the Earth (irradiance 0)", fontsize=10)
    ax[0].legend(fontsize=8)
    ax[1].set_ylabel("earthshine [W m$^{-2}$]")
    ax[2].set_ylabel("apparent albedo p*(β)")
    ax[2].axhline(0.3, color="k", lw=0.5, ls=":")
    ax[2].ticklabel_format(useOffset=False)
    ax[2].set_title("the paper's point-source inversion of the traced fluxes\n(the consistent inversion returns "
                    "the input 0.3 to 1e-13 for this uniform Lambert Earth)", fontsize=9)
    ax[2].set_xlabel(f"days since {t0}")
    fig.tight_layout()
    fig.savefig(out / "lunation.png", dpi=110)
    plt.close(fig)


def eclipse(out: Path, quick: bool):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    times = time_list(time_range="2025-03-14T03:00,2025-03-14T10:00,1h" if quick
                      else "2025-03-14T02:30,2025-03-14T10:30,5min")
    method = "analytic" if quick else "raytrace"
    runs = {}
    for occ in (True, False):
        res = run_sweep(ResolvedScene(times=times, brdfs=("dhg",), method=method, occlusion=occ), progress=False)
        runs["occlusion" if occ else "no_occlusion"] = res["rows"]
    rows = [{**a, "moonshine_no_occlusion_W_m2": b["moonshine_W_m2"]} for a, b in
            zip(runs["occlusion"], runs["no_occlusion"])]
    write_results(out / "eclipse_2025-03-14.json", {"method": method, "rows": rows})
    write_results(out / "eclipse_2025-03-14.csv", {"rows": rows})
    h = _hours(rows, "2025-03-14T00:00Z")
    fig, ax = plt.subplots(figsize=(9, 4.5))
    ax.plot(h, [r["moonshine_no_occlusion_W_m2"] for r in rows], "--", color="0.5", label="no occlusion")
    ax.plot(h, [r["moonshine_W_m2"] for r in rows], ".-", ms=3, label=f"{method}, occlusion (extended Sun)")
    for t, name in ((3 + 57 / 60, "P1"), (5 + 9 / 60, "U1"), (6 + 26 / 60, "U2"), (7 + 31 / 60, "U3"),
                    (8 + 48 / 60, "U4"), (10, "P4")):  # NASA's contacts (with the atmosphere's 2 % enlargement)
        ax.axvline(t, color="k", lw=0.4, ls=":")
        ax.text(t, ax.get_ylim()[1] * 0.98, name, fontsize=7, ha="center", va="top")
    ax.set_xlabel("hours UTC, 2025-03-14")
    ax.set_ylabel("moonshine at the geocentre [W m$^{-2}$]")
    ax.set_title("Total lunar eclipse of 2025-03-14 (contacts: NASA eclipse catalogue); no atmosphere", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "eclipse_2025-03-14.png", dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmarks/real_sky")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--plot-only", action="store_true", help="redraw lunation.png from lunation.json")
    ap.add_argument("--only", choices=["eclipse", "lunation"], default=None, help="run one of the two")
    a = ap.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.plot_only:
        import json
        plot_lunation(out, json.loads((out / "lunation.json").read_text()))
        return 0
    if a.only != "lunation":
        eclipse(out, a.quick)
    if a.only != "eclipse":
        lunation(out, a.quick)
    print(f"wrote {out}/lunation.* and {out}/eclipse_2025-03-14.*")
    return 0


if __name__ == "__main__":
    sys.exit(main())
