"""The examples run: both scripts and the notebook, at smoke size, headless.

``LUNARVIZ_SMOKE=1`` shrinks each example (fewer levels, phases, times); the notebook is
executed by nbclient in a fresh kernel with its default trame 3D backend, as a user would.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _env():
    return {**os.environ, "LUNARVIZ_SMOKE": "1"}


@pytest.mark.parametrize("script, outputs", [("mesh_study.py", ("mesh_study.json", "mesh_study.png")),
                                             ("leo_real_date.py", ("leo.nc", "leo.png"))])
def test_example_script_runs(tmp_path, script, outputs):
    r = subprocess.run([sys.executable, str(EXAMPLES / script)], cwd=tmp_path, env=_env(), capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    for name in outputs:
        assert (tmp_path / name).stat().st_size > 0
    if script == "mesh_study.py":
        res = json.loads((tmp_path / "mesh_study.json").read_text())
        assert [s["level"] for s in res["summary"] if s["path"] == "moonshine"] == [1, 2]
    else:
        import xarray as xr
        with xr.open_dataset(tmp_path / "leo.nc") as ds:
            assert ds.sizes["time"] == 3 and ds.moonshine.attrs["units"] == "W m-2"


def test_notebook_executes_headless(tmp_path, monkeypatch):
    import nbclient
    import nbformat
    for k, v in _env().items():
        monkeypatch.setenv(k, v)
    shutil.copy(EXAMPLES / "lunarviz_tour.ipynb", tmp_path)
    nb = nbformat.read(tmp_path / "lunarviz_tour.ipynb", as_version=4)
    client = nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()  # raises CellExecutionError on any failing cell
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    kinds = {k for o in outputs for k in o.get("data", {})}
    assert "image/png" in kinds  # the matplotlib phase curves
    assert "application/vnd.jupyter.widget-view+json" in kinds  # the trame 3D view
