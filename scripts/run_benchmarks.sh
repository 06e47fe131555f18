#!/usr/bin/env bash
# Regenerate every kept benchmark result in benchmarks/ (about 10 minutes on 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
lunarviz study mesh --levels 2:6 --phases 30,90,150,170 --shading smooth --out benchmarks/mesh_study_smooth.json --quiet
lunarviz study mesh --levels 2:6 --phases 30,90,150,170 --shading flat --out benchmarks/mesh_study_flat.json --quiet
lunarviz bench --out benchmarks/bench.json --quiet
python3 scripts/bench_summary.py
