"""The Python API, NetCDF tables, and the command-line gaps.

Expected values come from the command line itself (the API must give the same numbers: the
CLI is a thin layer over it, and this checks the layering, not the physics, which the other
test files check against independent references).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import lunarviz
from lunarviz.errors import LunarvizError


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "lunarviz.cli", *args], capture_output=True, text=True, cwd=cwd)


# ---- the API --------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["analytic", "raytrace"])
def test_sweep_dataset_equals_cli_json(tmp_path, method):
    out = tmp_path / "s.json"
    r = _cli("sweep", "--method", method, "--phases", "30,90,150", "--brdf", "lambert,dhg", "--mesh-level", "3",
             "--out", str(out), "--quiet") if method == "raytrace" else \
        _cli("sweep", "--method", method, "--phases", "30,90,150", "--brdf", "lambert,dhg", "--out", str(out),
             "--quiet")
    assert r.returncode == 0, r.stderr
    rows = json.loads(out.read_text())["rows"]
    opts = {"moon_level": 3} if method == "raytrace" else {}
    ds = lunarviz.sweep(lunarviz.Scene(phases="30,90,150", brdfs=("lambert", "dhg"), **opts), method=method)
    assert ds.moonshine.dims == ("brdf", "phase")
    for row in rows:
        sel = {"brdf": row["brdf"], "phase": row["theta_deg"]}
        assert float(ds.moonshine.sel(sel)) == row["moonshine_W_m2"]
        assert float(ds.earthshine.sel(sel)) == row["earthshine_W_m2"]
        assert float(ds.apparent_albedo.sel(sel)) == row["apparent_albedo"]
    assert ds.moonshine.attrs["units"] == "W m-2" and ds.earthshine.attrs["units"] == "W m-2"
    assert set(ds.bond_albedo.dims) == {"brdf"}


def test_netcdf_opens_and_equals_json(tmp_path):
    import xarray as xr
    for suffix in ("json", "nc"):
        r = _cli("sweep", "--time-range", "2026-06-03,2026-06-05,1d", "--observer", "site:34.26,-116.92,2067",
                 "--brdf", "lambert,dhg", "--out", str(tmp_path / f"s.{suffix}"), "--quiet")
        assert r.returncode == 0, r.stderr
    rows = json.loads((tmp_path / "s.json").read_text())["rows"]
    with xr.open_dataset(tmp_path / "s.nc") as ds:
        assert ds.moonshine.dims == ("brdf", "time") and ds.sizes["time"] == 3
        assert ds.moonshine.attrs["units"] == "W m-2" and ds.earthshine.attrs["units"] == "W m-2"
        assert ds.attrs["Conventions"].startswith("CF")
        for k, row in enumerate(rows):
            t = k // 2
            assert str(ds.time.values[t])[:19] == row["time_utc"][:19]
            sel = {"brdf": row["brdf"], "time": ds.time.values[t]}
            assert float(ds.moonshine.sel(sel)) == row["moonshine_W_m2"]
            assert float(ds.earthshine.sel(sel)) == row["earthshine_W_m2"]
            assert int(ds.moon_occulted.sel(time=sel["time"])) == int(row["moon_occulted"])
            assert float(ds.moon_altitude.sel(time=sel["time"])) == row["moon_altitude_deg"]
            want = row["apparent_albedo"]
            got = float(ds.apparent_albedo.sel(sel))
            assert (want is None and np.isnan(got)) or got == want
        # every variable read back carries units and a long_name (time: CF units in its encoding; the
        # text columns, strings, a long_name only)
        from lunarviz.outputs.tables import TEXT
        for name, var in list(ds.data_vars.items()) + list(ds.coords.items()):
            units = var.attrs.get("units") or var.encoding.get("units") or (name in TEXT and "text")
            assert units and var.attrs.get("long_name"), (name, var.attrs)


def test_trace_to_pyvista_and_save(tmp_path):
    f = lunarviz.trace(lunarviz.Scene(phases=120.0, brdfs=("dhg", "lambert"), moon_level=2))
    mesh = f.to_pyvista()
    assert mesh.n_cells == f.n_faces == 320
    assert np.isclose(mesh.cell_data["moonshine_contribution_W_m2"].sum(), f.totals["moonshine_W_m2"], rtol=1e-12)
    blocks = f.to_pyvista(bodies=True)
    assert set(blocks.keys()) == {"moon", "earth", "sun"}
    for name in ("moon.vtk", "moon.vtp", "moon.ply"):
        f.save(tmp_path / name)
        assert (tmp_path / name).stat().st_size > 0


def test_render_returns_an_image(tmp_path):
    img = lunarviz.render(lunarviz.Scene(phases=90.0, moon_level=2), brdf="dhg", view="moon", size=(320, 240),
                          out=tmp_path / "m.png")
    assert img.shape == (240, 320, 3) and img.max() > 100
    assert (tmp_path / "m.png").stat().st_size > 0


def test_study_mesh_returns_data_and_draws_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    res = lunarviz.study.mesh((1, 2), (90.0,), ("lambert",))
    assert [s["level"] for s in res["summary"] if s["path"] == "moonshine"] == [1, 2]
    assert list(tmp_path.iterdir()) == []


def test_scene_rejects_bad_options_in_one_line(tmp_path):
    from lunarviz import constants as C
    from lunarviz.bodies import shapes
    mesh = tmp_path / "ell.ply"
    shapes.write_mesh(shapes.ellipsoid(C.R_MOON_M, C.R_MOON_M, 0.9 * C.R_MOON_M, level=2), mesh)
    with pytest.raises(LunarvizError, match="unknown Scene option 'moon_levle'"):
        lunarviz.Scene(moon_levle=3)
    with pytest.raises(LunarvizError, match="phase"):
        lunarviz.Scene(phases=400)
    with pytest.raises(LunarvizError, match="give time or time_range"):
        lunarviz.Scene(observer="site:10,10")
    with pytest.raises(LunarvizError, match="moon_mesh cannot be used with method analytic"):
        lunarviz.sweep(lunarviz.Scene(moon_mesh=str(mesh)), method="analytic")


# ---- the command-line gaps --------------------------------------------------------------------
def test_trace_writes_vtk(tmp_path):
    r = _cli("trace", "--phase", "60", "--mesh-level", "2", "--out", str(tmp_path / "x.vtk"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "x.vtk").stat().st_size > 0


def test_montecarlo_one_ray_has_no_sigma(tmp_path):
    # one sample has no spread: σ is undefined (JSON null), never 0
    out = tmp_path / "mc.json"
    r = _cli("sweep", "--method", "raytrace", "--estimator", "montecarlo", "--rays", "1", "--phases", "90",
             "--brdf", "lambert", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    row = json.loads(out.read_text())["rows"][0]
    assert row["moonshine_std_W_m2"] is None and row["earthshine_std_W_m2"] is None


@pytest.mark.parametrize("detector, body", [("0,0,-1.496e11", "Sun"), ("0,3.8e8,0", "Moon")])
def test_detector_inside_a_body_is_one_line(tmp_path, detector, body):
    out = tmp_path / "d.json"
    r = _cli("sweep", "--phases", "90", "--detector", detector, "--out", str(out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and f"inside the {body}" in lines[0]
    assert not out.exists()


def test_detector_behind_the_moon_has_no_apparent_albedo(tmp_path):
    # θ = 90°: Moon at (0, D_EM, 0); a detector beyond it sees only the far side, which the
    # Earth does not light: earthshine ~1e-16 W m-2 is no measurement, so p* is undefined
    out = tmp_path / "b.json"
    r = _cli("sweep", "--phases", "90", "--detector", "0,7.6e8,0", "--brdf", "dhg", "--out", str(out), "--quiet")
    assert r.returncode == 0, r.stderr
    row = json.loads(out.read_text())["rows"][0]
    assert row["earthshine_W_m2"] < 1e-12
    assert row["apparent_albedo"] is None


def test_main_does_not_disguise_internal_errors(monkeypatch):
    # only lunarviz's own error type becomes a one-line usage error; a ValueError from inside
    # numpy or a bug keeps its traceback
    from lunarviz import cli
    from lunarviz.workflows import sweeps

    def boom(*a, **k):
        raise ValueError("internal numpy-like failure")
    monkeypatch.setattr(sweeps, "run_sweep", boom)
    with pytest.raises(ValueError, match="internal"):
        cli.main(["sweep", "--phases", "90", "--out", "/tmp/never.json", "--quiet"])


def test_core_does_not_import_the_viz_layer():
    code = ("import sys, lunarviz.methods.tracer.facets, lunarviz.workflows.sweeps, lunarviz.api, "
            "lunarviz.outputs.tables; "
            "print(any(m.startswith('lunarviz.viz') or m == 'pyvista' for m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.stdout.strip() == "False", r.stderr


def test_views_and_viewer_do_not_import_each_other():
    code = "import sys, lunarviz.viz.views; print('lunarviz.viz.viewer' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.stdout.strip() == "False", r.stderr


# ---- the API checks what the command line checks -----------------------------------------
_S = dict(phases=30.0, moon_level=2)


@pytest.mark.parametrize("call, word", [
    (lambda: lunarviz.trace(lunarviz.Scene(**_S), 400), "400"),
    (lambda: lunarviz.trace(lunarviz.Scene(**_S), "abc"), "abc"),
    (lambda: lunarviz.render(lunarviz.Scene(**_S), 500), "500"),
    (lambda: lunarviz.render(lunarviz.Scene(**_S), 30.0, out="x.jpg"), "x.jpg"),
    (lambda: lunarviz.render(lunarviz.Scene(**_S), 30.0, size=(0, 0)), "size"),
    (lambda: lunarviz.view(lunarviz.Scene(**_S), web=True, port=70000), "70000"),
    (lambda: lunarviz.study.mesh(levels=(2.7,)), "2.7"),
    (lambda: lunarviz.study.mesh(levels=(2, 1)), "increase"),
    (lambda: lunarviz.study.mesh(levels=(1, 2), phases=(500,)), "500"),
    (lambda: lunarviz.Scene(params={"w": 0.3}), "params"),
    (lambda: lunarviz.Scene(brdfs=("dhg",), params={"shg": {"w": 0.3}}), "shg"),
    (lambda: lunarviz.Scene(params={"dhg": {"w": "x"}}), "'x'"),
    (lambda: lunarviz.Scene(phases=["30", "a"]), "phases"),
    (lambda: lunarviz.Scene(phases=[[30, 60]]), "phases"),
    (lambda: lunarviz.Scene(brdfs=3), "brdfs"),
    (lambda: lunarviz.Scene(detector="1,2,3"), "detector"),
    (lambda: lunarviz.Scene(earth_albedo="x"), "albedo"),
    (lambda: lunarviz.Scene(moon_level=-1), "moon_level"),
    (lambda: lunarviz.Scene(mesh_units="ft"), "ft"),
    (lambda: lunarviz.Scene(earth_law="x"), "'x'"),
    (lambda: lunarviz.Scene(occlusion="no"), "occlusion"),
    (lambda: lunarviz.Scene(phases="30,30"), "twice"),
    (lambda: lunarviz.Scene(phases=30, time="2026-06-01"), "not both"),
    (lambda: lunarviz.sweep(lunarviz.Scene(**_S), workers="2"), "workers"),
])
def test_api_rejects_bad_values_in_one_line(call, word, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(LunarvizError) as exc:
        call()
    assert word in str(exc.value) and "\n" not in str(exc.value)
    assert list(tmp_path.iterdir()) == []


def test_ratios_of_round_off_are_undefined():
    # θ = 0 (full Moon, an eclipse in exact geometry) has no earthlit Moon; θ = 180 no sunlit
    # Moon: ratios of ~1e-16 W m-2 are not measurements
    rows = lunarviz.run(phases="0,180", brdfs="lambert")["rows"]
    by = {r["theta_deg"]: r for r in rows}
    assert np.isnan(by[180.0]["ratio_earthshine_moonshine"])


@pytest.mark.parametrize("where", ["lunarviz.scene.resolved", "lunarviz.api.Scene.settings"])
def test_docstring_examples_run(where):
    """The resolved scene's examples (JSON round trip, its typed inputs) run as written."""
    import doctest
    import importlib
    mod, _, attr = where.partition(".Scene.") if ".Scene." in where else (where, "", "")
    obj = importlib.import_module(mod)
    if attr:
        obj = getattr(obj.Scene, attr)
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    tests = [t for t in finder.find(obj) if t.examples]
    assert tests, f"{where} has no example"
    for t in tests:
        runner.run(t)
    assert runner.failures == 0
