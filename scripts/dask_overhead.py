"""What a Dask sweep costs per task: 10^4 analytic phase tasks on a local cluster of two workers.

    python scripts/dask_overhead.py        # ~1-2 min; writes benchmarks/dask_overhead.json

Overhead per task = (wall time on the cluster × workers − the tasks' own compute time) / tasks,
the tasks' compute time being the sum of their rows' ``seconds`` (measured inside each task).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep

OUT = Path(__file__).resolve().parent.parent / "benchmarks" / "dask_overhead.json"


def main() -> int:
    n = 10_000
    phases = tuple(float(p) for p in np.linspace(1.0, 179.0, n))
    s = ResolvedScene(brdfs=("dhg",), method="analytic", phases_deg=phases, order=8)
    workers = 2
    t0 = time.perf_counter()
    res = run_sweep(s, workers=workers, executor="dask")
    wall = time.perf_counter() - t0
    compute = float(sum(r["seconds"] for r in res["rows"]))
    t1 = time.perf_counter()
    local = run_sweep(s, workers=1)
    serial = time.perf_counter() - t1
    same = all(a["moonshine_W_m2"] == b["moonshine_W_m2"] for a, b in zip(res["rows"], local["rows"]))
    out = {"tasks": n, "workers": workers, "method": "analytic (order 8)", "dask_wall_seconds": wall,
           "tasks_compute_seconds": compute, "serial_local_wall_seconds": serial,
           "overhead_per_task_ms": 1e3 * (wall * workers - compute) / n,
           "rows_identical_to_local": same}
    OUT.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
