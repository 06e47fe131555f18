"""Run a fixed set of lunarviz commands on a checkout and compare every number two such runs wrote.

    python scripts/compare_outputs.py run  --root CHECKOUT --out DIR   # the commands, into DIR
    python scripts/compare_outputs.py diff DIR_A DIR_B                  # every number, A against B

``run`` executes each command with ``python -m lunarviz`` from ``CHECKOUT`` (its ``lunarviz`` first on
``PYTHONPATH``), one output file or folder per command. ``diff`` reads what both runs wrote (JSON, CSV,
NetCDF, FITS, VTK multiblocks and polydata, PNG, NPY, PLY) and reports the largest relative
difference of every file's numbers; run times and the settings' own key order are not compared. A
refactoring that keeps the numbers shows 0 everywhere (or round-off where a summation order changed).

Commands that spell a flag differently in two checkouts are listed with each spelling; the first
that the checkout accepts runs.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

#: (name, output file, command alternatives): each alternative is the argument list after ``lunarviz``
COMMANDS = [
    ("analytic", "analytic.json", [["sweep", "--method", "analytic", "--phases", "0:180:15"]]),
    ("raytrace", "raytrace.json", [["sweep", "--method", "raytrace", "--phases", "0:180:30"]]),
    ("montecarlo", "montecarlo.json", [["sweep", "--method", "raytrace", "--estimator", "montecarlo", "--rays", "5000",
                                        "--runs", "2", "--seed", "3", "--phases", "30,90"]]),
    ("reference", "reference.json", [["sweep", "--method", "reference", "--phases", "30,90,150"]]),
    ("maps", "maps.json", [["sweep", "--method", "raytrace", "--moon-albedo-map", "synthetic", "--earth-surface",
                            "landocean", "--clouds", "zonal", "--phases", "60,120"]]),
    ("maps_analytic", "maps_analytic.json", [["sweep", "--method", "analytic", "--moon-albedo-map", "synthetic",
                                              "--earth-surface", "landocean", "--clouds", "zonal",
                                              "--land-albedo", "0.3", "--phases", "60,120"]]),
    ("dates", "dates.json", [["sweep", "--method", "raytrace", "--time", "2026-02-16T03:00Z,2026-03-01T00:00Z"]]),
    ("site", "site.csv", [["sweep", "--method", "raytrace", "--time", "2026-02-16T03:00Z", "--observer",
                           "site:34.26,-116.92,2067"]]),
    ("netcdf", "netcdf.nc", [["sweep", "--method", "analytic", "--phases", "30,90", "--brdf", "lambert,dhg"]]),
    ("rtol", "rtol.json", [["sweep", "--method", "raytrace", "--rtol", "1e-5", "--phases", "30,90,150"]]),
    ("orbit", "orbit.json", [["sweep", "--method", "raytrace", "--moon-model", "rolo-fit-map", "--brdf", "dhg",
                              "--time-range", "2026-06-01,2026-06-01T06:00,3h", "--observer", "orbit:550,97.6,0,0",
                              "--rtol", "1e-4"]]),
    ("misc_analytic", "misc_analytic.json", [["sweep", "--method", "analytic", "--h-function", "exact",
                                              "--dhg-convention", "hapke2012", "--grid", "paper",
                                              "--phases", "30,90"]]),
    ("detector", "detector.json", [["sweep", "--method", "raytrace", "--detector", "3e6,1e6,-2e6",
                                    "--earth-rotation-deg", "30", "--shading", "flat", "--mesh-level", "3",
                                    "--phases", "60"]]),
    ("rolo_params", "rolo_params.json", [["sweep", "--method", "raytrace", "--moon-model", "rolo-fit", "--brdf",
                                          "dhg", "--param", "dhg.theta_bar=15", "--phases", "45"]]),
    ("spectral", "spectral.json", [["sweep", "--method", "analytic", "--moon-model", "rolo-fit-map", "--brdf", "dhg",
                                    "--wavelengths", "400:1000:200", "--phases", "30,90"]]),
    ("spectral_traced", "spectral_traced.json", [["sweep", "--method", "raytrace", "--earth-surface", "landocean",
                                                  "--clouds", "zonal", "--wavelengths", "500,800", "--phases", "90"]]),
    ("band", "band.json", [["sweep", "--method", "raytrace", "--band", "B,V", "--phases", "30,90"]]),
    ("physical", "physical.json", [["sweep", "--method", "raytrace", "--earth-brdf", "physical", "--earth-surface",
                                    "landocean", "--clouds", "zonal", "--param", "earth.wind_speed=5",
                                    "--phases", "90"]]),
    ("physical_band", "physical_band.json", [["sweep", "--method", "analytic", "--earth-brdf", "physical",
                                              "--earth-surface", "landocean", "--band", "V", "--phases", "100"]]),
    ("trace", "trace.vtm", [["trace", "--phase", "60", "--brdf", "dhg,lambert", "--quiet"]]),
    ("trace_date", "trace_date.vtp", [["trace", "--time", "2026-02-16T03:00Z", "--moon-albedo-map", "synthetic",
                                       "--quiet"]]),
    ("image", "image.fits", [["image", "--phase", "90", "--pixels", "64", "--quiet"]]),
    ("image_band", "image_band.fits", [["image", "--phase", "120", "--band", "B,V", "--pixels", "48",
                                        "--psf", "gaussian:20", "--quiet"]]),
    ("image_instrument", "image_instrument.fits", [["image", "--phase", "120", "--instrument", "salex", "--frames",
                                                    "2", "--seed", "1", "--quiet"]]),
    ("measure", "measure.json", [["measure", "--simulate", "3", "--instrument", "salex", "--phase", "120",
                                  "--seed", "1", "--quiet"]]),
    ("plan", "plan.json", [["plan", "--instrument", "salex", "--snr", "100", "--phase", "120", "--quiet"]]),
    ("brdf_moon", "brdf_moon.csv", [["brdf", "--model", "dhg", "--incidence", "30,60", "--emission", "0:80:20",
                                     "--azimuth", "0,180"]]),
    ("brdf_earth", "brdf_earth.csv", [["brdf", "--body", "earth", "--surface", "ocean", "--wavelengths", "450,865",
                                       "--incidence", "30", "--emission", "0:70:10", "--param",
                                       "earth.wind_speed=7"]]),
    ("study", "study.json", [["study", "mesh", "--levels", "2:3", "--phases", "90", "--quiet"]]),
    ("mesh", "craters.ply", [["mesh", "make", "craters", "--level", "4", "--count", "5", "--crater-seed", "2"],
                             ["mesh", "make", "craters", "--level", "4", "--count", "5", "--seed", "2"]]),
    ("user_mesh", "user_mesh.json", [["sweep", "--method", "raytrace", "--moon-mesh", "{out}/craters.ply",
                                      "--sun-order", "2", "--earth-order", "4", "--phases", "90"]]),
    ("fit", "fit.json", [["fit", "--model", "lambert", "--source", "{data}/fit_table.csv"],
                         ["fit", "--brdf", "lambert", "--source", "{data}/fit_table.csv"]]),
    ("render", "render.png", [["render", "--phase", "90", "--view", "moon", "--size", "320x240", "--quiet"]]),
]
#: keys whose values are run times or machine facts, not results
SKIP_KEYS = {"seconds", "wall_seconds", "elapsed_s", "time_s", "run_seconds", "DATE", "CHECKSUM", "DATASUM"}


def _fit_table(folder: Path) -> Path:
    """A small disk-integrated reflectance table for ``fit`` (a Lambert-like phase law, made up)."""
    path = folder / "fit_table.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["phase_deg", "reflectance"])
        for g in range(10, 100, 10):
            w.writerow([g, 0.1 * (math.sin(math.radians(g)) + (math.pi - math.radians(g)) * math.cos(math.radians(g)))
                        / math.pi])
    return path


def run(root: Path, out: Path, only: list[str] | None) -> int:
    out.mkdir(parents=True, exist_ok=True)
    data = out / "_inputs"
    data.mkdir(exist_ok=True)
    (data / "root.txt").write_text(str(root))
    _fit_table(data)
    env = {**os.environ, "PYTHONPATH": str(root)}
    failed = 0
    for name, target, alternatives in COMMANDS:
        if only and name not in only:
            continue
        for n, args in enumerate(alternatives):
            args = [a.format(out=out, data=data) for a in args]
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "lunarviz", *args, "--out", str(out / target)], env=env,
                               cwd=out, capture_output=True, text=True)
            dt = time.perf_counter() - t0
            if r.returncode == 2 and "unrecognized arguments" in r.stderr and n + 1 < len(alternatives):
                continue
            status = "ok" if r.returncode == 0 else f"rc {r.returncode}: {r.stderr.strip().splitlines()[-1:]}"
            print(f"{name:18s} {dt:6.1f} s  {status}", flush=True)
            failed += r.returncode != 0
            break
    return failed


# ---- reading every number of an output -----------------------------------------------------
def _timing(key: str) -> bool:
    return key in SKIP_KEYS or "seconds" in key


def _flatten(value, prefix: str, out: dict) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            if not _timing(k):
                _flatten(v, f"{prefix}.{k}", out)
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _flatten(v, f"{prefix}[{i}]", out)
    else:
        out[prefix] = value


def _json(path: Path) -> dict:
    d = json.loads(path.read_text())
    out: dict = {}
    _flatten(d, "", out)
    return out


def _csv(path: Path) -> dict:
    out = {}
    with open(path, newline="") as f:
        for i, row in enumerate(csv.DictReader(f)):
            for k, v in row.items():
                if _timing(k):
                    continue
                try:
                    out[f"[{i}].{k}"] = float(v)
                except (TypeError, ValueError):
                    out[f"[{i}].{k}"] = v
    return out


def _netcdf(path: Path) -> dict:
    import xarray as xr
    out = {}
    with xr.open_dataset(path) as ds:
        for name, var in {**ds.data_vars, **ds.coords}.items():
            if not _timing(name):
                out[f"var.{name}"] = np.asarray(var.values)
        for k, v in ds.attrs.items():
            if k == "settings_json":
                _flatten(json.loads(v), "attrs.settings", out)
            elif k not in SKIP_KEYS:
                out[f"attrs.{k}"] = v
    return out


def _fits(path: Path) -> dict:
    from astropy.io import fits
    out = {}
    with fits.open(path) as hdul:
        for i, h in enumerate(hdul):
            label = h.name or str(i)
            if h.data is not None:
                out[f"{label}.data"] = np.asarray(h.data, dtype=float)
            for k, v in h.header.items():
                if k in SKIP_KEYS or k in ("COMMENT", "HISTORY"):
                    continue
                if k == "SETTINGS" or (isinstance(v, str) and v.startswith("{")):
                    try:
                        _flatten(json.loads(v), f"{label}.{k}", out)
                        continue
                    except ValueError:
                        pass
                out[f"{label}.{k}"] = v
    return out


def _vtk(path: Path) -> dict:
    import pyvista as pv  # noqa: TID251 (reads the VTK files lunarviz wrote)
    out = {}
    obj = pv.read(path)
    blocks = [(obj.get_block_name(i), obj[i]) for i in range(obj.n_blocks)] if isinstance(obj, pv.MultiBlock) \
        else [("", obj)]
    for name, mesh in blocks:
        out[f"{name}.points"] = np.asarray(mesh.points, dtype=float)
        for k in mesh.cell_data:
            out[f"{name}.cell.{k}"] = np.asarray(mesh.cell_data[k])
        for k in mesh.point_data:
            out[f"{name}.point.{k}"] = np.asarray(mesh.point_data[k])
        for k in mesh.field_data:
            v = np.asarray(mesh.field_data[k])
            if k.endswith("_json"):
                _flatten(json.loads(str(v.ravel()[0])), f"{name}.field.{k}", out)
            else:
                out[f"{name}.field.{k}"] = v
    return out


def _png(path: Path) -> dict:
    from PIL import Image
    with Image.open(path) as im:
        return {"pixels": np.asarray(im, dtype=float)}


def _ply(path: Path) -> dict:
    import trimesh
    m = trimesh.load(path, process=False)
    return {"vertices": np.asarray(m.vertices), "faces": np.asarray(m.faces, dtype=float)}


READERS = {".json": _json, ".csv": _csv, ".nc": _netcdf, ".fits": _fits, ".vtm": _vtk, ".vtp": _vtk,
           ".png": _png, ".npy": lambda p: {"array": np.load(p)}, ".ply": _ply}


def _rel(a, b) -> float:
    """Largest relative difference of two values (arrays, numbers, strings: 0 or inf)."""
    if isinstance(a, str) or isinstance(b, str) or a is None or b is None or isinstance(a, bool):
        return 0.0 if a == b else math.inf
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind not in "biuf" or b.dtype.kind not in "biuf":
        return 0.0 if a.shape == b.shape and bool(np.all(a == b)) else math.inf
    a, b = a.astype(float), b.astype(float)
    if a.shape != b.shape:
        return math.inf
    both_nan = np.isnan(a) & np.isnan(b)
    same = (a == b) | both_nan
    if same.all():
        return 0.0
    d = np.abs(a - b)[~same]
    scale = np.maximum(np.abs(a), np.abs(b))[~same]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(scale > 0, d / scale, math.inf)
    return float(np.nanmax(np.where(np.isnan(r), math.inf, r)))


def _relative_paths(values: dict, folder: Path) -> dict:
    """Paths inside a run's folder and its checkout written as ``{out}/…`` and ``{root}/…`` (two runs
    write to two folders, from two checkouts)."""
    marker = folder / "_inputs" / "root.txt"
    root = marker.read_text() if marker.is_file() else None

    def plain(v):
        v = v.replace(str(folder.resolve()), "{out}")
        return v.replace(root, "{root}") if root else v
    return {k: plain(v) if isinstance(v, str) else v for k, v in values.items()}


def diff(a_dir: Path, b_dir: Path, verbose: bool) -> float:
    worst = 0.0
    for name, target, _ in COMMANDS:
        pa, pb = a_dir / target, b_dir / target
        if not pa.exists() or not pb.exists():
            print(f"{name:18s} missing in {'A' if not pa.exists() else 'B'}")
            worst = math.inf
            continue
        read = READERS[pa.suffix.lower()]
        va, vb = _relative_paths(read(pa), a_dir), _relative_paths(read(pb), b_dir)
        keys = sorted(set(va) | set(vb))
        numbers = settings = 0.0
        only = [k for k in keys if (k in va) != (k in vb)]
        bad = []
        for k in keys:
            if k not in va or k not in vb:
                continue
            r = _rel(va[k], vb[k])
            if "settings" in k.lower():
                settings = max(settings, r)
            else:
                numbers = max(numbers, r)
            if r > 0:
                bad.append((r, k))
        worst = max(worst, numbers)
        note = "" if not only else f"; keys in one only: {only[:4]}{' …' if len(only) > 4 else ''}"
        print(f"{name:18s} numbers {numbers:.3g}  settings {settings:.3g}  ({len(keys)} keys{note})")
        if verbose:
            for r, k in sorted(bad, reverse=True)[:8]:
                shown = [v[k] if np.ndim(v[k]) == 0 else "…" for v in (va, vb)]
                print(f"    {r:.3g}  {k}: {shown[0]} / {shown[1]}")
    print(f"largest relative difference of any result: {worst:.3g}")
    return worst


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="what", required=True)
    p = sub.add_parser("run")
    p.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--only", default=None, help="comma-separated command names")
    p = sub.add_parser("diff")
    p.add_argument("a", type=Path)
    p.add_argument("b", type=Path)
    p.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args(argv)
    if a.what == "run":
        return 1 if run(a.root.resolve(), a.out.resolve(), a.only.split(",") if a.only else None) else 0
    return 0 if diff(a.a, a.b, a.verbose) == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
