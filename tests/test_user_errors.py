"""Errors that help: close matches for misspelt options and choices, units where users write them,
names in any case, a warning for a time without a zone, the API's errors in the API's words."""

from __future__ import annotations

import warnings

import pytest

import lunarviz
from lunarviz.cli import main
from lunarviz.errors import LunarvizError, ZonelessTimeWarning, close_match
from lunarviz.parsing import LENGTH_M, TIME_S, parse_quantity
from lunarviz.sky.observers import parse_observer


def _cli_error(capsys, *argv) -> str:
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_misspelt_option_and_command_get_their_close_match(capsys):
    assert "did you mean --method?" in _cli_error(capsys, "sweep", "--methd", "raytrace")
    both = _cli_error(capsys, "sweep", "--methd", "raytrace", "--phasse", "3")
    assert "--method for --methd" in both and "--phases for --phasse" in both
    assert "did you mean 'sweep'?" in _cli_error(capsys, "swep")
    assert "(did you mean 'dhg'?)" in _cli_error(capsys, "sweep", "--brdf", "dgh", "--out", "x.json")


def test_close_match_ignores_case_and_refuses_strangers():
    assert close_match("SALX", ["salex", "bbso"]) == "salex"
    assert close_match("zzzz", ["salex", "bbso"]) is None


def test_units_where_users_write_them():
    assert parse_quantity("8ms", "exposure", TIME_S, "s") == (pytest.approx(0.008), True)
    assert parse_quantity("500 us", "exposure", TIME_S, "s") == (pytest.approx(5e-4), True)
    assert parse_quantity("0.01", "exposure", TIME_S, "s") == (0.01, False)
    assert parse_observer("site:34.26,-116.92,2.067km").height_m == pytest.approx(2067.0)
    assert parse_observer("site:34.26,-116.92,2067m").height_m == 2067.0
    with pytest.raises(LunarvizError, match=r"'8 parsecs' must be a number in s, or .* ms"):
        parse_quantity("8 parsecs", "exposure", TIME_S, "s")
    with pytest.raises(LunarvizError, match="'2km5'"):
        parse_quantity("2km5", "site height", LENGTH_M, "m")


def test_a_bare_fractional_site_height_is_warned_as_kilometres_by_mistake():
    with pytest.warns(lunarviz.errors.LunarvizWarning, match="write 2.067km for kilometres"):
        assert parse_observer("site:34.26,-116.92,2.067").height_m == 2.067
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parse_observer("site:34.26,-116.92,2067")  # a whole number of metres: no warning


def test_exposure_with_a_unit_on_the_command_line(capsys):
    err = _cli_error(capsys, "image", "--phase", "120", "--instrument", "salex", "--exposure", "8 lightyears",
                     "--out", "x.fits")
    assert "'8 lightyears' must be a number in s" in err


def test_names_in_any_case():
    s = lunarviz.Scene(phases=[90], brdfs=("DHG", "Lambert")).settings("analytic")
    assert s.brdfs == ("dhg", "lambert")
    from lunarviz.instrument.spec import load_instrument
    assert load_instrument("SALEX").name == load_instrument("salex").name
    with pytest.raises(LunarvizError, match=r"instrument 'salx' \(did you mean 'salex'\?\)"):
        load_instrument("salx")


def test_band_and_wavelength_lists_as_python_tuples():
    s = lunarviz.Scene(phases=[90], bands=("V", "B"), wavelengths=None).settings("analytic")
    assert s.bands == "V,B"
    assert lunarviz.Scene(phases=[90], wavelengths=(500, 600.5)).settings("analytic").wavelengths == "500,600.5"


def test_a_time_without_a_zone_is_warned_as_utc():
    from lunarviz.sky.ephemeris import parse_time
    with pytest.warns(ZonelessTimeWarning, match="taken as UTC"):
        zoneless = parse_time("2026-01-15T03:00")
    assert zoneless == parse_time("2026-01-15T03:00Z")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parse_time("2026-01-15T03:00Z")
        parse_time("2026-01-15T03:00-08:00")
        parse_time("2026-01-15")  # a day: no time to be zoned


def test_api_errors_name_keywords_and_the_command_line_names_flags(capsys):
    with pytest.raises(LunarvizError) as exc:
        lunarviz.Scene(observer="site:10,10")
    assert "give time or time_range" in str(exc.value) and "--" not in str(exc.value)
    err = _cli_error(capsys, "sweep", "--observer", "site:10,10", "--out", "x.json")
    assert "give --time or --time-range" in err


def test_double_grazing_brdf_is_zero_not_cos_rounding():
    # i = e = 90°: Eq. 12's 1/(μ0 + μ) is singular and carries no light (μ0 = 0); cos(π/2) = 6e-17
    # used to give 1.5e15. Just off grazing the BRDF keeps its (large, finite) model value: at
    # i = 89.9999°, e = 90° it is w/(4π)·[…]/μ0 with μ0 = 1.7e-6, i.e. ~3e4 (here only > 1e3).
    import numpy as np

    from lunarviz.photometry.brdf import brdf_from_angles, make_brdf
    for name in ("shg", "dhg"):
        model = make_brdf(name)
        assert brdf_from_angles(model, np.pi / 2, np.pi / 2, 0.0) == 0.0
        assert 1e3 < brdf_from_angles(model, np.radians(89.9999), np.pi / 2, 0.0) < 1e6


def test_theta_is_the_same_option_as_phase(capsys):
    from lunarviz.cli import build_parser
    a = build_parser().parse_args(["sweep", "--thetas", "30,60", "--out", "x.json"])
    assert a.phases == "30,60"
    assert "orbital angle" in build_parser()._subparsers._group_actions[0].choices["image"].format_help()


def test_sweep_plot_is_written_beside_the_table(tmp_path, capsys):
    out, png = tmp_path / "s.json", tmp_path / "s.png"
    assert main(["sweep", "--method", "analytic", "--phases", "30,90,150", "--out", str(out), "--plot", str(png),
                 "--quiet"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.is_file()
    # a bad figure name is refused before any work: nothing written
    err = _cli_error(capsys, "sweep", "--method", "analytic", "--phases", "30", "--out", str(tmp_path / "t.json"),
                     "--plot", str(tmp_path / "t.gif"))
    assert "t.gif" in err and not (tmp_path / "t.json").exists()


def test_sweep_rows_as_csv_on_standard_output(capsys):
    import csv
    import io
    assert main(["sweep", "--method", "analytic", "--phases", "30,90", "--brdf", "dhg", "--quiet", "--out", "-"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [float(r["theta_deg"]) for r in rows] == [30.0, 90.0] and float(rows[0]["moonshine_W_m2"]) > 0
