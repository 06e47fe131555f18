"""Mesh-resolution study from Python: how the Moon's icosphere level sets the error.

    python examples/mesh_study.py            # levels 2-5, three phases, three BRDFs (~1 min)
    LUNARVIZ_SMOKE=1 python examples/mesh_study.py   # levels 1-2, one phase (CI)

Writes ``mesh_study.json`` and ``mesh_study.png`` in the working directory.
"""

import os

import lunarviz

smoke = bool(os.environ.get("LUNARVIZ_SMOKE"))
levels = (1, 2) if smoke else (2, 3, 4, 5)
phases = (90.0,) if smoke else (30.0, 90.0, 150.0)

# returns the data; writes and draws only because we ask (out=, plot=)
res = lunarviz.study.mesh(levels, phases, ("lambert", "shg", "dhg"), body="moon",
                          out="mesh_study.json", plot="mesh_study.png")
for row in res["summary"]:
    order = "" if row["observed_order"] is None else f"   observed order {row['observed_order']:.1f}"
    print(f"{row['path']:10s} level {row['level']}  {row['facets']:7d} facets   "
          f"max |error| {row['max_abs_relative_error']:.2e}{order}")
