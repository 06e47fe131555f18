"""The model Earth's own albedos (spherical, geometric, phase integral), the clouds' optical depth,
the dated runs' default Moon and the Earth options that a physical Earth refuses."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.surfaces.earth_albedos import earth_albedos
from lunarviz.surfaces.earth_surface import EarthSurface
from lunarviz.surfaces.maps import map_frame
from lunarviz.workflows.earth_own_albedos import run_earth_albedos


def _scene():
    sc = SceneGeometry(90.0)
    return sc, map_frame(sc, "earth", 0.0)


def test_a_lambert_sphere_has_its_closed_form_albedos():
    # a Lambert sphere of albedo A: A_s = A, p = 2A/3, q = 3/2 (Russell 1916), for any lighting;
    # the place grid and its weights are what is checked (a 1° grid: ~1e-5 of the closed form)
    sc, frame = _scene()
    got = earth_albedos(EarthSurface(earth_albedo=0.37), sc, frame)
    assert got["spherical"][0] == pytest.approx(0.37, rel=1e-4)
    assert got["geometric"][0] == pytest.approx(2 * 0.37 / 3, rel=1e-4)
    assert got["phase_integral"][0] == pytest.approx(1.5, rel=1e-4)


def test_the_physical_earth_conserves_energy():
    # a white ground under the conservative Rayleigh layer returns all the light (A_s = 1) and a
    # black one the layer's spherical albedo S, from the tables' own flux solution (a different
    # quantity than the reflectance factors integrated here): 1e-4 (the μ, φ and incidence rules)
    from lunarviz.earth_optics import rayleigh
    from lunarviz.earth_optics.atmosphere import spherical_albedo
    sc, frame = _scene()
    def ground(a):  # no ozone: it absorbs (the next test)
        return EarthSurface(earth_brdf="physical", earth_params=(("ground_albedo", a), ("ozone_du", 0.0)))
    white = earth_albedos(ground(1.0), sc, frame)["spherical"][0]
    black = earth_albedos(ground(0.0), sc, frame)["spherical"][0]
    assert white == pytest.approx(1.0, abs=1e-4)
    assert black == pytest.approx(spherical_albedo(float(rayleigh.optical_depth(550.0))), rel=1e-3)


def test_the_ozone_layer_absorbs_along_its_slant_paths():
    # a white ground under 300 DU of ozone with (almost) no air above it (100 hPa: Rayleigh optical
    # depth 0.007 at 600 nm): every photon crosses the ozone down at μ₀ and up at a Lambert angle,
    # so A_s = (2 ∫₀¹ μ e^{−τ m(μ)} dμ)² over the sphere (the lit hemisphere's μ₀ weight is the
    # ground's own 2μ dμ), with τ = σ N and the Dobson shell's air mass m, written here from
    # Komhyr (1980) apart from the package. σ(600 nm): Serdyuchenko et al. (2014) at 233 K, the
    # package's 10 nm bin means (5.02e-21 cm² for 600-610 nm, the Chappuis band's peak) read
    # between their centres, 4.857e-21 at 600 nm; the bar, 1e-3, holds the air's 0.007 (scattering
    # moves the photons' angles, not their number: ~τ_R τ_O3 ≈ 3e-4) and the 12-node μ rule
    # (measured 2e-6)
    from scipy.integrate import quad
    sc, frame = _scene()
    tau = 300 * 2.687e16 * 4.857e-21  # the table's 600 nm value, between its 595 and 605 nm bins
    k = 6.378e6 / (6.378e6 + 22e3)
    def m(mu):
        return 1.0 / np.sqrt(1.0 - k * k * (1.0 - mu * mu))
    expected = (2.0 * quad(lambda mu: mu * np.exp(-tau * m(mu)), 0.0, 1.0)[0]) ** 2
    s = EarthSurface(earth_brdf="physical", earth_params=(("ground_albedo", 1.0), ("surface_hpa", 100.0),
                                                            ("wavelength_nm", 600.0)))
    got = earth_albedos(s, sc, frame)["spherical"][0]
    assert expected == pytest.approx(0.867, abs=0.005)  # two crossings of τ ≈ 0.039 at a mean m ≈ 1.8
    assert got == pytest.approx(expected, rel=1e-3)
    none = EarthSurface(earth_brdf="physical", earth_params=(("ground_albedo", 1.0), ("wavelength_nm", 600.0),
                                                               ("ozone_du", 0.0)))
    assert earth_albedos(none, sc, frame)["spherical"][0] == pytest.approx(1.0, abs=1e-4)


@pytest.mark.slow
def test_the_spherical_albedo_is_the_same_by_places_and_by_directions():
    # two routes to the same power: per place, ρ_h(μ₀) integrated over the lit hemisphere (here),
    # against the disc's reflectance toward 16 × 8 directions integrated over the sphere of
    # directions (physical_earth.bond_albedo, on a 1° disc grid): land and sea at 550 nm, bar 5e-4
    # (measured 8e-5). With the zonal clouds the direction rule needs 24 × 12 directions for the
    # glory and the forward peak (0.4137, 0.4076, 0.4095 at 12 × 6, 16 × 8, 24 × 12; this rule
    # 0.4094): measured within 2e-4 there, 20 s, not run here. Geometric albedo, with the clouds:
    # the glory (exact backscatter) sets its last per cents and the tables resolve it only at their
    # nodes: this rule takes the backscatter at the nodes (0.330), the disc toward a distant viewer
    # interpolates the table between them (0.325 at β = 0), and at β = 0.5° the glory is mostly
    # gone (0.320). Bars: within 2 % of the first, above the second by 0-4 %
    from lunarviz.surfaces.physical_earth import apparent_albedo, bond_albedo
    sc, frame = _scene()
    clear = EarthSurface(earth_brdf="physical", earth_surface="landocean")
    bond, _ = bond_albedo(clear, sc, frame, 550.0, order=16, azimuths=8, rows=90)
    assert earth_albedos(clear, sc, frame)["spherical"][0] == pytest.approx(bond, rel=5e-4)
    s = EarthSurface(earth_brdf="physical", earth_surface="landocean", clouds="zonal")
    mine = earth_albedos(s, sc, frame)
    full = 2.0 / 3.0 * apparent_albedo(s, sc, frame, 0.0, 0.0, 550.0)
    near = 2.0 / 3.0 * apparent_albedo(s, sc, frame, 0.5, 0.0, 550.0)
    assert mine["geometric"][0] == pytest.approx(full, rel=0.02)
    assert 0.0 < mine["geometric"][0] / near - 1.0 < 0.04


def test_thicker_clouds_reflect_more_and_the_range_is_refused_beyond_the_tables():
    from lunarviz.earth_optics.classes import surface_from_name
    from lunarviz.errors import LunarvizError
    from lunarviz.surfaces.earth_albedos import hemispherical_reflectance
    rho = [hemispherical_reflectance(surface_from_name("cloud", cloud_optical_depth=t), 550.0, 0.6)[0]
           for t in (0.5, 2.0, 7.0, 10.0, 40.0, 150.0)]
    assert np.all(np.diff(rho) > 0) and 0.0 < rho[0] and rho[-1] < 1.0
    with pytest.raises(LunarvizError, match="cloud_optical_depth=200"):
        EarthSurface(earth_brdf="physical", earth_params=(("cloud_optical_depth", 200.0),))


@pytest.mark.parametrize("name, value", [("ozone_du", -1.0), ("ozone_du", 1e9), ("chlorophyll", 0.0),
                                         ("chlorophyll", float("nan"))])
def test_the_air_and_sea_parameters_are_refused_outside_their_range(name, value):
    from lunarviz.errors import LunarvizError
    with pytest.raises(LunarvizError, match=f"earth.{name}="):
        EarthSurface(earth_brdf="physical", earth_params=((name, value),))


def test_the_seas_chlorophyll_and_the_ozone_reach_the_earthshine_and_the_reflectance_table():
    # each parameter through each door: the traced sweep (its class models) and the Earth's
    # reflectance table (brdf --body earth). A greener sea (3 mg m⁻³) is darker in the blue (the
    # pigments absorb) and brighter in the green (the particles scatter): at 443 nm its water
    # reflects 0.011 against clear water's 0.027; ozone takes light from the V band, not the B
    import lunarviz
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_phase
    def earthshine(**params):
        s = ResolvedScene(brdfs=("lambert",), phases_deg=(90.0,), earth_brdf="physical", earth_surface="landocean",
                          params={"earth": {"wavelength_nm": 443.0, **params}})
        return run_phase(s, 90.0)[0]["earthshine_W_m2"]
    assert earthshine(chlorophyll=3.0) < earthshine(chlorophyll=0.03)
    assert earthshine(ozone_du=0.0) > earthshine()
    def table(**params):
        rows = lunarviz.brdf(body="earth", surface="ocean", wavelengths=[443.0, 600.0], incidence=30,
                             emission=[10], azimuth=[90], params=params)
        return np.array([r["reflectance_factor"] for r in rows])
    green, clear = table(chlorophyll=3.0), table(chlorophyll=0.03)
    assert green[0] < clear[0] and green[1] > clear[1]
    no_ozone = table(ozone_du=0.0)
    assert table()[1] / no_ozone[1] < 0.95  # 600 nm: the Chappuis band's peak, two crossings


def test_a_physical_run_records_every_earth_parameter_it_ran_with():
    # the settings hold only the parameters given; a default changed between versions (the ozone
    # column, the sea's chlorophyll) must still be readable from the output: all of them, defaults
    # included, in the result and in the NetCDF attributes
    import lunarviz
    from lunarviz.options import EARTH_PARAMETER_DEFAULTS
    from lunarviz.outputs.tables import to_dataset
    with pytest.warns(lunarviz.errors.UnboundedRowsWarning):
        res = lunarviz.run(phases=[90], brdfs=("lambert",), earth_brdf="physical", earth_surface="landocean",
                           params={"earth": {"ozone_du": 250}})
    assert res["earth_parameters"] == {**EARTH_PARAMETER_DEFAULTS, "ozone_du": 250.0}
    attrs = to_dataset(res).attrs["earth_parameters"]
    assert "ozone_du=250" in attrs and "chlorophyll=0.1" in attrs
    assert "earth_parameters" not in lunarviz.run(phases=[90], brdfs=("lambert",))


def test_a_sweep_reports_the_earths_own_albedos_beside_eq17(tmp_path):
    out = tmp_path / "s.json"
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--phases", "30,90,150", "--brdf", "lambert",
                        "--earth-albedo", "0.25", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    res = json.loads(out.read_text())
    assert res["earth_spherical_albedo"] == pytest.approx(0.25, rel=1e-4)
    assert res["earth_geometric_albedo"] == pytest.approx(0.25 * 2 / 3, rel=1e-4)
    assert res["earth_phase_integral"] == pytest.approx(1.5, rel=1e-4)
    assert "Eq. 17 over the sampled phases" in r.stdout and "the model Earth's own" in r.stdout


def test_a_dated_spectral_run_reports_them_per_band_and_in_netcdf(tmp_path):
    import xarray as xr
    out = tmp_path / "s.nc"
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--time-range",
                        "2026-03-01T00:00Z,2026-03-02T00:00Z,12h", "--brdf", "lambert", "--band", "B,V",
                        "--earth-surface", "landocean", "--clouds", "zonal", "--quiet", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    ds = xr.open_dataset(out)
    assert list(ds["band"].values) == ["B", "V"]
    a = np.asarray(ds.attrs["earth_spherical_albedo"])
    assert a.shape == (2,) and np.all((a > 0.2) & (a < 0.5))
    assert ds.attrs["earth_albedo_at"].count("2026-03-0") == 3  # the run's three dates
    # in the band coordinate's order: each band's own value, computed apart for it alone
    from lunarviz.scene import ResolvedScene
    settings = json.loads(ds.attrs["settings_json"])
    for k, band in enumerate(("B", "V")):
        alone = run_earth_albedos(ResolvedScene.from_dict({**settings, "bands": [band]}))
        assert a[k] == pytest.approx(alone["earth_spherical_albedo"][band], rel=1e-12)


def test_dated_runs_default_to_the_observed_moon():
    from lunarviz.scene import ResolvedScene
    assert ResolvedScene(phases_deg=(90.0,)).moon_model == "paper"
    dated = ResolvedScene(times=("2026-03-01T00:00Z",), method="raytrace")
    assert dated.moon_model == "rolo-fit-map" and dated.moon_albedo_map is not None
    assert ResolvedScene(times=("2026-03-01T00:00Z",), method="reference").moon_model == "rolo-fit"
    assert ResolvedScene(times=("2026-03-01T00:00Z",), moon_model="paper").moon_model == "paper"


def test_a_physical_earth_refuses_the_lambert_earths_albedo(tmp_path):
    r = subprocess.run([sys.executable, "-m", "lunarviz", "sweep", "--earth-brdf", "physical", "--earth-albedo", "0.2",
                        "--phases", "90", "--out", str(tmp_path / "x.json")], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "--earth-albedo 0.2" in r.stderr and "earth.ground_albedo" in r.stderr and "--earth-surface" in r.stderr
    assert not (tmp_path / "x.json").exists()
    # the uniform ground under the air is the physical Earth's own parameter, and it is load-bearing
    from lunarviz.scene import ResolvedScene
    own = {a: run_earth_albedos(ResolvedScene(phases_deg=(90.0,), earth_brdf="physical",
                                              params={"earth": {"ground_albedo": a}}))["earth_spherical_albedo"]
           for a in (0.1, 0.3)}
    assert own[0.3] > own[0.1] + 0.1


def test_the_printed_eq8_reports_its_own_brighter_earth():
    # the paper's printed Eq. 8 (analytic method): 3/2 a Lambert sphere's intensity at every phase,
    # so the run's Earth has p = A and A_s = 3A/2, which Eq. 17 over a full θ sweep recovers
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.sweeps import run_sweep
    res = run_sweep(ResolvedScene(phases_deg=tuple(range(0, 181, 5)), brdfs=("lambert",), earth_law="paper_eq8"))
    assert res["earth_geometric_albedo"] == pytest.approx(0.3, rel=1e-4)
    assert res["earth_spherical_albedo"] == pytest.approx(0.45, rel=1e-4)
    assert res["bond_albedo"]["lambert"]["analytic"] == pytest.approx(0.45, rel=1e-3)


def test_an_old_dated_explorer_state_keeps_the_papers_moon():
    # version 1 of the state file was written when dated runs took the paper's Moon by default:
    # a dated state without moon_model meant it, and is read so; version 2 takes the new default
    from lunarviz.explore.state import ExploreState
    d = {"lunarviz": "explore-state", "version": 1, "options": {}, "times": ["2026-03-05T00:00:00Z"],
         "key": "2026-03-05T00:00:00Z", "brdf": "dhg"}
    assert ExploreState.from_dict(d).option("moon_model") == "paper"
    assert ExploreState.from_dict({**d, "version": 2}).option("moon_model") == "rolo-fit-map"


def test_an_apparent_albedo_no_lambert_sphere_gives_warns():
    from lunarviz.errors import ApparentAlbedoWarning
    from lunarviz.photometry.albedo_inversion import warn_non_lambert_apparent_albedo
    rows = [{"theta_deg": 20.0, "beta_deg": 160.0, "apparent_albedo": 3.2},
            {"theta_deg": 90.0, "beta_deg": 90.0, "apparent_albedo": 0.31}]
    with pytest.warns(ApparentAlbedoWarning, match=r"1 of 2 rows .* p\* = 3\.2 at θ = 20°"):
        warn_non_lambert_apparent_albedo(rows)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_non_lambert_apparent_albedo(rows[1:])  # within 0-1: silent


def test_a_clear_sky_map_of_one_value_is_the_uniform_ground(tmp_path):
    # a map FILE's ground takes the exact Lambert form under the layer, R = ρ_R + T T A / (1 − S A)
    # integrated in closed form over the view hemisphere; the uniform ground takes the numerical
    # hemispherical rule over the same coupling: a map holding 0.3 everywhere is the uniform
    # Earth of 0.3 (A_s to 1e-6), with and without clouds, at two wavelengths; p: the map's
    # backscatter per place against the uniform ground's, cubic between 2° nodes (measured 7e-5)
    path = tmp_path / "ground.npy"
    np.save(path, np.full((90, 180), 0.3))
    sc, frame = _scene()
    for clouds in ("none", "zonal"):
        mapped = earth_albedos(EarthSurface(earth_brdf="physical", earth_surface=str(path), clouds=clouds), sc,
                               frame, [450.0, 650.0])
        uniform = earth_albedos(EarthSurface(earth_brdf="physical", clouds=clouds,
                                             earth_params=(("ground_albedo", 0.3),)), sc, frame, [450.0, 650.0])
        assert np.allclose(mapped["spherical"], uniform["spherical"], rtol=1e-6)
        assert np.allclose(mapped["geometric"], uniform["geometric"], rtol=2e-4)


def test_the_ground_albedo_is_the_uniform_earths_alone_and_exact_h_takes_a_uniform_moon_only_where_it_must():
    from lunarviz.errors import LunarvizError
    from lunarviz.scene import ResolvedScene
    from lunarviz.workflows.brdf_tables import earth_rows
    with pytest.raises(LunarvizError, match="ground_albedo is the uniform Earth's ground: earth_surface landocean"):
        ResolvedScene(phases_deg=(90.0,), earth_brdf="physical", earth_surface="landocean",
                      params={"earth": {"ground_albedo": 0.5}})
    with pytest.raises(LunarvizError, match="surface lambert:A"):
        earth_rows("lambert:0.3", [550.0], [30.0], [30.0], [0.0], params={"ground_albedo": 0.5})
    # --h-function exact takes one w: a Hapke run on dates gets the uniform fit, a Lambert one keeps the map
    t = ("2026-03-05T00:00Z",)
    assert ResolvedScene(times=t, brdfs=("dhg",), h_function="exact").moon_model == "rolo-fit"
    assert ResolvedScene(times=t, brdfs=("lambert",), h_function="exact").moon_model == "rolo-fit-map"
