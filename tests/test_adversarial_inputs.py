"""Inputs built to break the commands (an adversarial run's findings), each refused in one line or
handled right: tables of subnormal numbers, PSFs of extreme widths and scales, huge images with a
halo, huge BRDF tables, a plan file, a mesh study at θ where a path vanishes."""

from __future__ import annotations

import numpy as np
import pytest

import lunarviz
from lunarviz.errors import LunarvizError


@pytest.mark.parametrize("peak", [1e-315, 1e-300, 1e31])
def test_a_table_of_subnormal_or_huge_values_is_refused(tmp_path, peak):
    # a band response of 1e-315 gave an earthshine/moonshine ratio 10 % off, of 1e-320 a zero
    from lunarviz.resources import read_table
    f = tmp_path / "band.csv"
    f.write_text(f"wavelength_nm,response\n500,{peak!r}\n600,{peak!r}\n")
    with pytest.raises(LunarvizError, match="scale the column"):
        read_table(f, "spectral response")


def test_a_band_of_any_sane_scale_gives_the_same_ratio(tmp_path):
    # the earthshine/moonshine ratio of a band does not depend on the response's scale
    ratios = []
    for peak in (1e-25, 1.0, 1e25):
        f = tmp_path / f"b{peak:g}.csv"
        f.write_text(f"wavelength_nm,response\n500,{peak!r}\n600,{peak!r}\n")
        res = lunarviz.run(phases=[120], bands=str(f), earth_spectra="grey", method="analytic")
        r = res["rows"][0]
        ratios.append(r["earthshine_W_m2"] / r["moonshine_W_m2"])
    assert ratios[0] == pytest.approx(ratios[1], rel=1e-12) and ratios[2] == pytest.approx(ratios[1], rel=1e-12)


def test_gaussian_psf_of_any_width_and_kernel_of_any_scale():
    # FWHM 1e-170: 2σ² underflowed to 0 and the kernel was 0/0 (an all-NaN image); a .npy
    # kernel of 1e308s summed to inf (an all-zero image)
    from lunarviz.instrument.optics import parse_psf
    k = parse_psf("gaussian:1e-170", 1.0, (32, 32))
    assert np.all(np.isfinite(k)) and k.sum() == pytest.approx(1.0) and k.max() == 1.0


def test_npy_kernel_of_extreme_scale(tmp_path):
    from lunarviz.instrument.optics import parse_psf
    for scale in (1e308, 1e-320):
        f = tmp_path / "k.npy"
        np.save(f, np.full((3, 3), scale))
        k = parse_psf(str(f), 1.0, (32, 32))
        assert np.allclose(k, 1 / 9, rtol=1e-12)


def test_a_halo_on_a_huge_image_is_refused_before_its_kernel():
    from lunarviz.instrument.optics import parse_halo
    with pytest.raises(LunarvizError, match="at most 4194304 pixels"):
        parse_halo("0.01,3", 1.0, (4096, 4096))  # (~7 GB before)
    assert parse_halo("0.01,3", 1.0, (64, 64))[1].shape == (127, 127)


def test_a_brdf_table_of_billions_of_rows_is_refused():
    with pytest.raises(LunarvizError, match="8,100,180,001 rows"):
        lunarviz.brdf(model="dhg", incidence="0:90:0.001", emission="0:90:0.001")


def test_a_brdf_table_evaluated_at_once_equals_row_by_row():
    # the table is evaluated in one call; each row against the model at that row alone
    from lunarviz.photometry.brdf import brdf_from_angles, make_brdf
    rows = lunarviz.brdf(model="dhg", incidence=[0, 30, 89.5], emission=[10, 60], azimuth=[0, 90, 180])
    m = make_brdf("dhg")
    for r in rows:
        one = float(brdf_from_angles(m, *np.radians([r["incidence_deg"], r["emission_deg"], r["azimuth_deg"]])))
        assert r["brdf_per_sr"] == pytest.approx(one, rel=1e-13)


def test_a_mesh_study_where_a_path_vanishes_is_refused():
    # θ = 0: the earthshine is 0 and its relative error divided by zero (a traceback)
    with pytest.raises(LunarvizError, match=r"in \(0, 180\)"):
        lunarviz.study.mesh(levels=[2, 3], phases=[0])


def test_a_mesh_study_at_a_dark_phase_is_refused_before_tracing(monkeypatch):
    # θ = 0.5: the exact earthshine is 0 (ZeroDivisionError after the whole study before)
    from lunarviz.workflows import study
    monkeypatch.setattr(study, "_study_task", lambda *a: pytest.fail("traced before refusing"))
    with pytest.raises(LunarvizError, match=r"θ = 0.5 deg: the exact earthshine"):
        lunarviz.study.mesh(levels=[2, 3], phases=[0.5])


@pytest.mark.parametrize("kw", [dict(phases=10**400), dict(phases=[120], seed=10**400),
                                dict(phases=[120], moon_level=10**400), dict(phases=[120], detector=(10**400, 0, 0)),
                                dict(time_range="2026-01-15T00:00Z,2026-01-15T03:00Z,99999999999d")])
def test_numbers_too_large_for_a_float_are_one_line(kw):
    # OverflowError tracebacks before
    with pytest.raises(LunarvizError):
        lunarviz.Scene(**kw).settings("raytrace")


def test_brdf_names_in_any_case_through_the_api():
    # render(brdf="DHG") raised KeyError: 'moonshine_contribution_DHG'
    from lunarviz.api import _brdf_name
    assert _brdf_name("DHG") == "dhg"
    with pytest.raises(LunarvizError, match="did you mean 'dhg'"):
        _brdf_name("dgh")


def test_rough_hapke_at_double_grazing_is_quiet():
    import warnings

    from lunarviz.photometry.brdf import brdf_from_angles, make_brdf
    model = make_brdf("dhg", params={"theta_bar": 20.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (4 RuntimeWarnings of 0/0 before)
        assert brdf_from_angles(model, np.pi / 2, np.pi / 2, np.pi) == 0.0


def test_choices_and_keywords_in_any_case_on_the_command_line(tmp_path):
    from lunarviz.cli import build_parser
    a = build_parser().parse_args(["sweep", "--shading", "SMOOTH", "--out", "x.json"])
    assert a.shading == "smooth"
    s = lunarviz.Scene(phases=[30], earth_surface="LANDOCEAN", clouds="Zonal").settings("analytic")
    assert (s.earth_surface, s.clouds) == ("landocean", "zonal")
    with pytest.raises(LunarvizError, match="did you mean 'landocean'"):
        lunarviz.Scene(phases=[30], earth_surface="landocen").settings("analytic")
    from lunarviz.spectral.bands import parse_band
    assert parse_band("s2a-b4").name == "S2A-B4"


def test_the_band_term_of_a_traced_mesh_level_run():
    # the band term's analytic sweeps kept --mesh-level ("cannot be used with --method analytic":
    # measure failed for any salex run made with --mesh-level)
    from dataclasses import replace

    from lunarviz.instrument.spec import load_instrument
    from lunarviz.workflows.measurement import band_sigma
    inst = load_instrument("salex")
    settings = replace(lunarviz.Scene([120.0], brdfs="dhg", moon_level=3).settings("raytrace"))
    assert 0 < band_sigma(settings, 120.0, inst) < 0.05


def test_a_mesh_craters_count_is_bounded(capsys):
    from lunarviz.cli import main
    assert main(["mesh", "make", "craters", "--level", "2", "--count", "1000000000", "--out", "c.ply"]) == 2
    assert "more than 100,000" in capsys.readouterr().err
