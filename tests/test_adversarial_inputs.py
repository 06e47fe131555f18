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
