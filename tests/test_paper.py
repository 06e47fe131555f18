"""`lunarviz paper --quick` end to end and the mesh study."""

import json

import pytest

from lunarviz.cli import main


@pytest.mark.slow
def test_paper_quick_meets_targets(tmp_path):
    out = tmp_path / "paper"
    assert main(["paper", "--quick", "--out", str(out), "--quiet"]) == 0
    r = json.loads((out / "results.json").read_text())
    # Table 5: within 0.003 of the input 0.3 for both methods and all BRDFs
    for b in ("lambert", "shg", "dhg"):
        for m in ("analytic", "raytrace"):
            assert r["table5"][b][m] == pytest.approx(0.3, abs=3e-3)
    # the paper-style inversion is biased low for the Hapke Moons: a finding, reported
    for b in ("shg", "dhg"):
        assert r["table5_point_source_inversion"][b]["raytrace"] < 0.29
    # Sec. 3.1 BRDF test within 0.1 % of Eq. 12 averaged over footprint and aperture
    for m in ("shg", "dhg"):
        assert r["brdf_test"][m]["max_relative_error"] <= 1e-3
        row = r["brdf_test"][m]["rows"][0]
        assert {"emission_deg", "azimuth_deg", "brdf_recovered_per_sr", "brdf_expected_per_sr",
                "brdf_eq12_per_sr"} <= set(row)
    for f in ("fig3_reflectance_factor.png", "fig4_brdf_test.png", "fig5_moonshine_earthshine.png",
              "fig6_albedo.png", "report.md"):
        assert (out / f).stat().st_size > 1000
    report = (out / "report.md").read_text()
    for word in ("Eq. 8", "convention", "point Earth", "finite", "Occlusion", "Monte Carlo"):
        assert word.lower() in report.lower()


def test_paper_out_must_be_a_directory(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["paper", "--out", str(f)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_mesh_study_converges(tmp_path):
    from lunarviz.workflows.study import mesh_study
    res = mesh_study([2, 3, 4], [100.0], ["dhg"], tmp_path / "study.json", shading="flat", refine=False)
    s = [r for r in res["summary"] if r["path"] == "moonshine"]
    assert s[2]["max_abs_relative_error"] < s[0]["max_abs_relative_error"] / 4
    assert s[2]["observed_order"] > 1.0  # flat facets: second order expected, > 1 required
    assert (tmp_path / "study.png").stat().st_size > 1000
