#!/usr/bin/env bash
# Regenerate every kept benchmark result in benchmarks/ (about 20 minutes on 2 cores).
set -euo pipefail
cd "$(dirname "$0")/.."
lunarviz study mesh --levels 2:6 --phases 30,90,150,170 --shading auto --out benchmarks/mesh_study_auto.json --quiet
lunarviz study mesh --levels 2:6 --phases 30,90,150,170 --shading flat --out benchmarks/mesh_study_flat.json --quiet
lunarviz study mesh --shape ellipsoid --levels 3:7 --phases 30,90,150 --brdf lambert,dhg --out benchmarks/mesh_study_ellipsoid.json --quiet
lunarviz study mesh --shape craters --levels 4:7 --phases 60,120 --brdf lambert,dhg --out benchmarks/mesh_study_craters.json --quiet
lunarviz bench --out benchmarks/bench.json --quiet
python3 scripts/bench_spectral.py
python3 scripts/validate_spectral.py
python3 scripts/spectral_figures.py
python3 scripts/bench_summary.py
