"""What a sweep will do before it does it: its tasks, those it will skip and why, and an estimate of
its time and memory from one task computed now.

The skips are those of the run itself (:func:`lunarviz.workflows.skips.skip_reason`, from each
date's geometry, milliseconds a date). The estimate times one task that is not skipped (the
first; a cold process: Embree scenes, tables and caches built for it, so the later tasks of a
run are as fast or faster) and scales it by the tasks left over the worker processes; the
memory is this process's peak resident size after that task, once per worker.
"""

from __future__ import annotations

import resource
import sys
import time
from collections import Counter

from lunarviz.scene import ResolvedScene
from lunarviz.workflows.skips import skip_reason
from lunarviz.workflows.sweeps import run_phase, worker_count


def dry_run(settings: ResolvedScene, workers: int | None = None, probe: bool = True) -> dict:
    """The plan of :func:`lunarviz.workflows.sweeps.run_sweep` for ``settings``: ``tasks``,
    ``skipped`` ({reason: count}),
    ``to_compute``, ``workers``, and with ``probe`` the one task's ``probe_seconds``, the
    ``estimate_seconds`` of the run and its ``estimate_memory_bytes``."""
    keys = settings.tasks()
    skipped: Counter = Counter()
    computed = []
    for k in keys:
        why = skip_reason(settings, settings.geometry(k))
        if why:
            skipped[why] += 1
        else:
            computed.append(k)
    n_workers = worker_count(workers, max(1, len(computed)), settings.method)
    out = {"tasks": len(keys), "skipped": dict(skipped),
           "to_compute": len(computed), "workers": n_workers}
    if probe and computed:
        t0 = time.perf_counter()
        run_phase(settings, computed[0])
        dt = time.perf_counter() - t0
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * (1 if sys.platform == "darwin" else 1024)
        waves = -(-len(computed) // n_workers)  # tasks per worker, rounded up
        out.update(probe_task=str(computed[0]), probe_seconds=dt, estimate_seconds=dt * waves,
                   estimate_memory_bytes=rss * n_workers)
    return out


def describe(plan: dict) -> list[str]:
    """The plan as lines for the terminal."""
    lines = [f"tasks: {plan['tasks']}"]
    skipped = sum(plan["skipped"].values())
    said = ", ".join(f"{why}: {k}" for why, k in plan["skipped"].items())
    lines.append(f"skipped (no tracing): {skipped}" + (f" ({said})" if said else ""))
    lines.append(f"to compute: {plan['to_compute']} on {plan['workers']} worker process"
                 f"{'' if plan['workers'] == 1 else 'es'}")
    if "estimate_seconds" in plan:
        lines.append(f"estimate: {plan['estimate_seconds']:.0f} s and {plan['estimate_memory_bytes'] / 2**30:.1f} GiB "
                     f"(task {plan['probe_task']} computed now in {plan['probe_seconds']:.1f} s, in a cold process: "
                     "later tasks are as fast or faster)")
    return lines
