"""Smoke runs of the benchmark scripts at --quick size, so they cannot rot between
full runs. The figures themselves are benchmarks, kept in benchmarks/ (never asserted here as
times); these tests check that each script runs end to end and writes what the benchmarks
README is generated from, with values in their physical ranges."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_throughput_quick(tmp_path):
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "throughput.py"), "--quick", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    res = json.loads((tmp_path / "throughput.json").read_text())
    for r in res["scenes"]:
        # raw Embree alone on the very same rays cannot be slower than the whole trace around it
        assert 0 < r["ratio_end_to_end_over_raw"] < 1.2, r["scene"]
        assert r["npz_replay_rays"] == r["rays_sent_to_embree"]  # the .npz holds every counted ray
        assert abs(sum(r["stage_shares"].values()) - 1) < 1e-9
        assert r["two_threads"]["end_to_end_seconds"] > 0
    # the quick sweep (5 phases) still meets the accuracy bar against the exact reference
    assert res["paper_sweep"]["max_rel_error_vs_reference_5_175"] < 1e-4
    mc = res["montecarlo_phase"]
    assert mc["earthshine"]["rays"] > 0 and mc["seconds_per_phase"] > 0


def test_scale_quick(tmp_path):
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "scale.py"), "--levels", "3", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    rows = json.loads((tmp_path / "scale.json").read_text())["rows"]
    assert rows[0]["returncode"] == 0, rows[0]
    assert rows[0]["facets"] == 1280 and rows[0]["rays"] > 0 and 0 < rows[0]["peak_rss_GB"] < 4
    assert rows[0]["moonshine_W_m2"] > 0 and rows[0]["earthshine_W_m2"] > 0
    assert (tmp_path / "scale.png").exists()


def test_bench_spectral_quick(tmp_path):
    # the spectral cost benchmark at smoke size: every scene swept grey and with 32 wavelengths
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "bench_spectral.py"), "--quick", "--out",
                        str(tmp_path)], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    res = json.loads((tmp_path / "bench.json").read_text())
    assert set(res["sweeps"]) == {"paper Moon", "rolo-fit-map Moon", "mapped Earth"}
    assert all(r["grey_s"] > 0 and r["spectral_32_s"] > 0 for r in res["sweeps"].values())
    assert (tmp_path / "bench.md").read_text().count("|") > 10


def test_validate_spectral_quick(tmp_path):
    # ROLO against the spectral Moon on two of the twenty dates (the full run is kept in
    # benchmarks/spectral/rolo_spectral.md); the required 5 % bar applies to every row
    import pytest
    pytest.importorskip("rimopy")
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "validate_spectral.py"), "--quick", "--out",
                        str(tmp_path)], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    d = json.loads((tmp_path / "rolo_spectral.json").read_text())
    assert len(d["rows"]) >= 2 * 7 and all(abs(r["ratio"] - 1) < 0.05 for r in d["rows"])
    assert abs(d["solar"]["relative_difference"]) < 0.02


def test_measurement_budget_quick(tmp_path):
    # the error-budget script at smoke size (one salex phase, one bbso date): every term present,
    # the random part near 1/SNR (1 % at SNR 100 on the earthlit patch; the sunlit patch and the
    # halo fit add to it), and the full run's kept results (benchmarks/measurement) are its output
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "measurement_budget.py"), "--quick", "--out",
                        str(tmp_path)], capture_output=True, text=True, cwd=ROOT)
    assert p.returncode == 0, p.stderr[-2000:]
    res = json.loads((tmp_path / "budget.json").read_text())
    rows = [r for rs in res["rows"].values() for r in rs]
    assert len(rows) == 2
    for r in rows:
        assert 0.008 < r["p_star_sigma"] / r["p_star"] < 0.03
        assert r["p_star_U_k2"] == 2 * r["p_star_sigma_total"]
    assert (tmp_path / "budget.png").exists()
