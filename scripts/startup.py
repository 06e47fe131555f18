"""Start-up cost of a one-phase analytic sweep from the command line: wall time of
``lunarviz sweep --method analytic --phases 90`` (a fresh interpreter each time) and the heavy
packages it imports, optionally against another checkout of lunarviz (``--against DIR``: its
source folder on PYTHONPATH), alternating the two in one run so that machine noise hits both.

``python scripts/startup.py --against DIR --out benchmarks/startup.json``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HEAVY = ("pyvista", "vtkmodules", "trame", "xarray", "astropy", "trimesh", "embreex", "matplotlib", "numba", "scipy")
CODE = ("import sys; from lunarviz.cli import main; main(['sweep', '--method', 'analytic', '--phases', '90', "
        "'--out', sys.argv[1], '--quiet']); "
        f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")


def run_once(src: str | None, out: Path) -> tuple[float, list]:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = src
    t = time.perf_counter()
    # in the output's folder: `python -c` puts the working folder first on sys.path
    r = subprocess.run([sys.executable, "-c", CODE, str(out)], capture_output=True, text=True, env=env, check=True,
                       cwd=out.parent)
    return time.perf_counter() - t, json.loads(r.stdout.strip().splitlines()[-1].replace("'", '"'))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--against", default=None, help="another checkout's root (its lunarviz/ on PYTHONPATH)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=None, help=".json")
    a = ap.parse_args(argv)
    here = str(Path(__file__).resolve().parent.parent)
    who = {"this checkout": here, **({"against": a.against} if a.against else {})}
    times: dict = {k: [] for k in who}
    mods: dict = {}
    with tempfile.TemporaryDirectory() as d:
        for _ in range(a.repeats):
            for k, src in who.items():
                dt, m = run_once(src, Path(d) / "s.json")
                times[k].append(dt)
                mods[k] = m
    res = {k: {"min_s": min(v), "median_s": sorted(v)[len(v) // 2], "heavy_imports": mods[k]} for k, v in times.items()}
    if a.against:
        res["median_ratio"] = res["this checkout"]["median_s"] / res["against"]["median_s"]
    text = json.dumps({"command": "lunarviz sweep --method analytic --phases 90", "repeats": a.repeats, **res},
                      indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")


if __name__ == "__main__":
    main()
