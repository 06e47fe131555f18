"""What colour costs: a 32-wavelength ray-traced sweep against the grey sweep of the same scene, and
the memory of 300 wavelengths.

    python scripts/bench_spectral.py          # ~5 min on 2 cores
    python scripts/bench_spectral.py --quick --out DIR   # a smoke run (tests/test_benchmark_scripts.py)

Each scene is swept grey and with 32 wavelengths (400:1020:20 nm) in the same run, alternating,
twice each (the smaller wall time of each kept): ``lunarviz sweep --method raytrace --phases
0:180:15`` with lambert, shg and dhg, for the paper's Moon (smooth, grey parameters) and for
``--moon-model rolo-fit-map`` (a spectral table, roughness θ̄ = 45°, the synthetic albedo map), and
for a mapped Earth (``--earth-surface landocean --clouds zonal``, five spectral components). Peak
memory (``ru_maxrss`` of a fresh process) is measured for one phase grey, with 32 and with 300
wavelengths.

Writes ``benchmarks/spectral/bench.{json,md}``.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "spectral"
WAVELENGTHS_32 = "400:1020:20"
WAVELENGTHS_300 = "400:1000:2"
SCENES = {
    "paper Moon": {},
    "rolo-fit-map Moon": {"moon_model": "rolo-fit-map"},
    "mapped Earth": {"earth_surface": "landocean", "clouds": "zonal"},
}


def sweep_seconds(opts: dict, wavelengths: str | None, phases=tuple(float(p) for p in range(0, 181, 15))) -> float:
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_sweep
    s = ResolvedScene(phases_deg=phases, method="raytrace", wavelengths=wavelengths, **opts)
    t0 = time.perf_counter()
    run_sweep(s)
    return time.perf_counter() - t0


PEAK = """
import resource, sys
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep
w = sys.argv[1] if sys.argv[1] != "grey" else None
run_sweep(ResolvedScene(phases_deg=(60.0,), method="raytrace", moon_model="rolo-fit-map", wavelengths=w), workers=1)
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""


def peak_mib(wavelengths: str) -> float:
    out = subprocess.run([sys.executable, "-c", PEAK, wavelengths], capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def main() -> int:
    import argparse
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one phase, one run each, no memory runs")
    ap.add_argument("--out", default=str(OUT), help="output folder")
    a = ap.parse_args()
    out_dir = Path(a.out)
    out_dir.mkdir(parents=True, exist_ok=True)
    phases = (90.0,) if a.quick else tuple(float(p) for p in range(0, 181, 15))
    sweep_seconds({}, "500", phases[:1])  # compile / load the kernels once
    res = {}
    for name, opts in SCENES.items():
        grey, spec = [], []
        for _ in range(1 if a.quick else 2):
            grey.append(sweep_seconds(opts, None, phases))
            spec.append(sweep_seconds(opts, WAVELENGTHS_32, phases))
        res[name] = {"grey_s": min(grey), "spectral_32_s": min(spec), "ratio": min(spec) / min(grey),
                     "grey_runs_s": grey, "spectral_runs_s": spec}
        print(name, res[name], flush=True)
    mem = {} if a.quick else {w: peak_mib(w) for w in ("grey", WAVELENGTHS_32, WAVELENGTHS_300)}
    out = {"command": "python scripts/bench_spectral.py", "phases": list(phases), "brdfs": "lambert,shg,dhg",
           "wavelengths_32": WAVELENGTHS_32, "sweeps": res, "peak_rss_MiB_one_phase": mem}
    (out_dir / "bench.json").write_text(json.dumps(out, indent=1) + "\n")
    lines = [f"| scene (raytrace, {len(phases)} phases, 3 BRDFs) | grey [s] | 32 wavelengths [s] | ratio |",
             "| --- | --- | --- | --- |"]
    lines += [f"| {n} | {r['grey_s']:.2f} | {r['spectral_32_s']:.2f} | {r['ratio']:.2f} |" for n, r in res.items()]
    if mem:
        names = {"grey": "grey", WAVELENGTHS_32: "32 wavelengths", WAVELENGTHS_300: "301 wavelengths"}
        lines += ["", "| one phase, rolo-fit-map | peak RSS [MiB] |", "| --- | --- |"]
        lines += [f"| {names[w]} | {m:.0f} |" for w, m in mem.items()]
    lines += ["", "`python scripts/bench_spectral.py` (2-core machine; min of 2 runs each, grey and spectral "
              "alternating in one process)"]
    (out_dir / "bench.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
