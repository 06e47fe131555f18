"""The ``lunarviz`` command line: contract fields and one-line errors."""

import csv
import json
import subprocess
import sys

import pytest

from lunarviz.cli import main


def run(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_sweep_json_contract(tmp_path, capsys):
    out = tmp_path / "s.json"
    code, _, _ = run(["sweep", "--method", "analytic", "--brdf", "lambert,shg,dhg", "--phases", "0:180:5",
                      "--out", str(out), "--quiet"], capsys)
    assert code == 0
    d = json.loads(out.read_text())
    assert set(d) >= {"settings", "rows", "bond_albedo"}
    assert len(d["rows"]) == 37 * 3
    for key in ("theta_deg", "alpha_deg", "beta_deg", "brdf", "method", "moonshine_W_m2",
                "earthshine_W_m2", "apparent_albedo"):
        assert key in d["rows"][0]
    for b in ("lambert", "shg", "dhg"):
        assert d["bond_albedo"][b]["analytic"] == pytest.approx(0.3, abs=3e-4)
    assert d["settings"]["phases_deg"][-1] == 180.0


def test_sweep_csv_and_raytrace_montecarlo(tmp_path, capsys):
    out = tmp_path / "s.csv"
    code, _, _ = run(["sweep", "--method", "raytrace", "--estimator", "montecarlo", "--brdf", "dhg",
                      "--phases", "60,120", "--rays", "3000", "--runs", "3", "--seed", "1",
                      "--workers", "1", "--out", str(out), "--quiet"], capsys)
    assert code == 0
    with out.open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 2 and float(rows[0]["moonshine_std_W_m2"]) > 0
    assert float(rows[1]["earthshine_std_W_m2"]) > 0


def test_brdf_command(tmp_path, capsys):
    out = tmp_path / "b.json"
    code, _, _ = run(["brdf", "--model", "dhg", "--incidence", "75", "--emission", "0:80:20",
                      "--azimuth", "0,180", "--dhg-convention", "hapke2012", "--param", "w=0.4",
                      "--out", str(out)], capsys)
    assert code == 0
    rows = json.loads(out.read_text())["rows"]
    assert len(rows) == 10
    r = rows[0]
    assert set(r) == {"incidence_deg", "emission_deg", "azimuth_deg", "phase_deg", "brdf_per_sr",
                      "reflectance_factor"}
    # azimuth 0 is backscatter (g = |i - e|), 180 the far side (g = i + e)
    g = {(x["emission_deg"], x["azimuth_deg"]): x["phase_deg"] for x in rows}
    assert g[(20.0, 0.0)] == pytest.approx(55.0) and g[(20.0, 180.0)] == pytest.approx(95.0)


@pytest.mark.parametrize("args,needle", [
    (["sweep", "--brdf", "foo"], "unknown BRDF 'foo'"),
    (["sweep", "--method", "magic"], "unknown method 'magic'"),
    (["sweep", "--phases", "0:370:5"], "phase 365 is out of range"),
    (["sweep", "--phases", "5:0:5"], "malformed phase '5:0:5'"),
    (["sweep", "--phases", "a,b"], "malformed phase 'a'"),
    (["sweep", "--param", "w=1.7"], "w=1.7"),
    (["sweep", "--param", "zeta=1"], "no BRDF in this run has a parameter 'zeta'"),
    (["sweep", "--method", "raytrace", "--rays", "-10"], "--rays -10 must be positive"),
    (["sweep", "--method", "raytrace", "--runs", "0"], "--runs 0 must be positive"),
    (["brdf", "--model", "dhg", "--incidence", "95", "--emission", "0"], "incidence 95 is out of range"),
    (["brdf", "--model", "hapke", "--incidence", "5", "--emission", "0"], "unknown BRDF 'hapke'"),
])
def test_bad_input_one_line_no_file(args, needle, tmp_path, capsys):
    out = tmp_path / "x.json"
    code, _, err = run(args + ["--out", str(out)], capsys)
    assert code == 2
    assert needle in err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()
    assert list(tmp_path.iterdir()) == []  # no temporary files left either


def test_unwritable_output(tmp_path, capsys):
    code, _, err = run(["sweep", "--out", str(tmp_path / "nope" / "x.json")], capsys)
    assert code == 2 and "does not exist" in err
    code, _, err = run(["sweep", "--out", str(tmp_path / "x.txt")], capsys)
    assert code == 2 and "must end in .json or .csv" in err


def test_bad_mesh_is_one_line(tmp_path, capsys):
    bad = tmp_path / "m.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code, _, err = run(["sweep", "--method", "raytrace", "--phases", "90", "--moon-mesh", str(bad),
                        "--workers", "1", "--out", str(tmp_path / "x.json")], capsys)
    assert code == 2 and "m.obj" in err and err.count("\n") == 1


def test_trace_writes_vtp(tmp_path):
    pv = pytest.importorskip("pyvista")
    out = tmp_path / "moon.vtp"
    code = main(["trace", "--phase", "100", "--brdf", "shg", "--out", str(out)])
    assert code == 0
    m = pv.read(out)
    info = json.loads(m.field_data["info_json"][0])
    assert m.cell_data["moonshine_contribution_W_m2"].sum() == pytest.approx(info["moonshine_W_m2"], rel=1e-9)
    assert "reflectance_factor" in m.cell_data and "earth_irradiance_W_m2" in m.cell_data


def test_console_script_installed():
    r = subprocess.run([sys.executable, "-m", "lunarviz.cli", "sweep", "--brdf", "nope", "--out", "x.json"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("lunarviz: error: unknown BRDF 'nope'")
