"""Executors: a Dask LocalCluster of two workers gives the local rows."""

from __future__ import annotations

import subprocess
import sys

import pytest

from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_sweep

pytest.importorskip("distributed")

# One xdist worker for the clusters: each local cluster's scheduler serves HTTP on port 8787 even
# without its dashboard, and a second cluster started meanwhile on another worker finds it taken
# (a warning, an error under the suite's filterwarnings).
pytestmark = pytest.mark.xdist_group("dask")


def test_dask_local_cluster_gives_identical_rows():
    # the same run_phase tasks, the same numbers bit for bit (each worker builds and caches its
    # own Embree scenes; only settings and keys travel)
    s = ResolvedScene(brdfs=("lambert", "dhg"), method="raytrace", phases_deg=(30.0, 90.0, 150.0), moon_level=3)
    local = run_sweep(s, workers=2)["rows"]
    dask = run_sweep(s, workers=2, executor="dask")["rows"]
    assert [(r["theta_deg"], r["brdf"]) for r in local] == [(r["theta_deg"], r["brdf"]) for r in dask]
    for a, b in zip(local, dask):
        assert a["moonshine_W_m2"] == b["moonshine_W_m2"] and a["earthshine_W_m2"] == b["earthshine_W_m2"]


def test_dask_options_are_checked(tmp_path):
    def cli(*args):
        return subprocess.run([sys.executable, "-m", "lunarviz.cli", "sweep", "--phases", "30", *args,
                               "--out", str(tmp_path / "o.json")], capture_output=True, text=True)
    r = cli("--scheduler", "tcp://127.0.0.1:1")
    assert r.returncode == 2 and "--executor dask" in r.stderr
    r = cli("--executor", "dask", "--scheduler", "tcp://127.0.0.1:1")
    assert r.returncode == 2 and "cannot reach the Dask scheduler" in r.stderr and r.stderr.count("\n") == 1
    assert not (tmp_path / "o.json").exists()


def test_dask_mesh_study_gives_identical_rows():
    from lunarviz.workflows import study
    a = study.mesh((1, 2), (90.0,), ("lambert",))
    b = study.mesh((1, 2), (90.0,), ("lambert",), executor="dask", workers=2)
    assert [r["value_W_m2"] for r in a["rows"]] == [r["value_W_m2"] for r in b["rows"]]


def test_workers_are_capped_by_tasks_and_cores(monkeypatch):
    """`--workers 24` for one phase forks no pool, and `workers=10**6` asks for no more processes
    than the machine has cores (it used to fork them all up front)."""
    import os

    from lunarviz.workflows import sweeps
    assert sweeps.worker_count(24, 1) == 1
    assert sweeps.worker_count(10**6, 37) == min(37, os.cpu_count() or 1)
    assert sweeps.worker_count(None, 5, "analytic") == 1

    def no_pool(*a, **k):
        raise AssertionError("a process pool was started for a single task")
    monkeypatch.setattr(sweeps, "ProcessPoolExecutor", no_pool)
    res = sweeps.run_sweep(sweeps.ResolvedScene(method="analytic", phases_deg=(90.0,), brdfs=("lambert",)), workers=24)
    assert len(res["rows"]) == 1
