"""Surfaces: lunar albedo maps, a land/ocean/cloud Earth, and what earthshine sees.

Independent references: ``tests/independent.py::mapped_irradiance``, a numpy double quadrature
in each body's own latitude and longitude (the maps' edges are meridians, so they are integration
limits there), sharing nothing with the tracer but the BRDF formulas; the global-land-mask
package's own 30″ mask for the land fraction.
"""

from __future__ import annotations

import json
import subprocess
import sys

import independent as ind
import numpy as np
import pytest

from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.photometry.brdf import make_brdf
from lunarviz.scene import ResolvedScene
from lunarviz.surfaces.earth_surface import EarthSurface, zonal_cloud_table
from lunarviz.surfaces.maps import map_frame, map_mean
from lunarviz.workflows.sweeps import run_phase

MODELS = {"lambert": make_brdf("lambert"), "dhg": make_brdf("dhg")}
#: each BRDF's albedo parameter in the paper: Lambert albedo 0.10 (Table 5), Hapke w 0.33 (Table 2)
PAPER_ALBEDO = {"lambert": 0.10, "dhg": 0.33}


def _rows(**kw):
    s = ResolvedScene(brdfs=("lambert", "dhg"), method=kw.pop("method", "raytrace"), **kw)
    return {r["brdf"]: r for th in s.tasks() for r in run_phase(s, th)} if len(s.tasks()) == 1 else \
        {(r["theta_deg"], r["brdf"]): r for th in s.tasks() for r in run_phase(s, th)}


def _save(tmp_path, name, a):
    p = tmp_path / name
    np.save(p, np.asarray(a, dtype=float))
    return str(p)


# ---- a uniform map is the scalar ------------------------------------------------------------
@pytest.mark.parametrize("method", ["raytrace", "analytic"])
def test_uniform_maps_equal_the_scalar(tmp_path, method):
    """Bar: a uniform map equal to the scalar gives identical results (≤ 1e-9), both bodies."""
    base = _rows(phases_deg=(120.0,), method=method)
    earth = _rows(phases_deg=(120.0,), method=method, earth_surface=_save(tmp_path, "e.npy", np.full((90, 180), 0.3)))
    moon_rel = _rows(phases_deg=(120.0,), method=method,
                     moon_albedo_map=_save(tmp_path, "m.npy", np.full((90, 180), 0.7)))
    moon_abs = {"lambert": _rows(phases_deg=(120.0,), method=method, moon_albedo_map=f"{tmp_path / 'm.npy'}:0.1")
                ["lambert"]}
    for variant in (earth, moon_rel, moon_abs):
        for k, r in variant.items():
            for f in ("moonshine_W_m2", "earthshine_W_m2", "apparent_albedo"):
                assert r[f] == pytest.approx(base[k][f], rel=1e-9, abs=0), (k, f)


# ---- the Earth --------------------------------------------------------------------------------
def _hemispheric_earth(tmp_path):
    m = np.zeros((180, 360))
    m[:, 180:] = 0.6  # east longitudes [0°, 180°): columns 180-359 (column 0 starts at -180°)
    return _save(tmp_path, "hemi.npy", m)


def _hemi(lat, lon):
    return np.where((lon >= 0) & (lon < 180), 0.6, 0.0)


@pytest.mark.parametrize("shift", [0.0, 25.0, -25.0])
def test_hemispheric_earth_matches_quadrature(tmp_path, shift):
    """Bar: Earth of albedo 0.6 on east longitudes 0–180°, 0 elsewhere. At θ = 120° the lit part
    the Moon sees spans sub-solar longitude λs to λs + 120° ... its middle, λs + 30°, sits on
    the meridian 0° for λs = -30° (half bright, half dark); ±25° turn it. Earthshine within 1e-3 of
    the independent quadrature, Lambert and DHG. The quadrature converges to ~5e-5 (checked
    below by a finer Earth rule), the tracer's mapped Earth is second order in facet size
    (level-6 Earth) and cell size (measured 4e-5 and 9e-5 at shift 0)."""
    lam = -30.0 + shift
    rows = _rows(phases_deg=(120.0,), earth_surface=_hemispheric_earth(tmp_path), earth_rotation_deg=lam)
    ref = ind.mapped_irradiance(120.0, MODELS, earth_albedo=_hemi, earth_lon_sub_solar_deg=lam, earth_cuts=(0, 180),
                                n_moon=(24, 16), n_earth=(32, 24))
    fine = ind.mapped_irradiance(120.0, MODELS, earth_albedo=_hemi, earth_lon_sub_solar_deg=lam, earth_cuts=(0, 180),
                                 n_moon=(40, 24), n_earth=(48, 32))
    for k in MODELS:
        assert fine[k][1] == pytest.approx(ref[k][1], rel=2e-4)  # the reference has converged
        assert rows[k]["earthshine_W_m2"] == pytest.approx(fine[k][1], rel=1e-3), k
        # the same Earth weighted without the map: the earthshine-weighted albedo is the ratio
        assert 0.0 < rows[k]["earth_visible_lit_albedo"] < 0.6


def test_mapped_earth_is_needed(tmp_path):
    """Why the mapped Earth sums facets: the uniform Earth's few Gauss beams per lunar point
    (order 6) get the hemispheric Earth wrong by about 2 % (measured -1.9 %), which the facet
    sum fixes. Checked here on the unit-albedo transport, which must not depend on the map:
    ``earthshine / earth_visible_lit_albedo`` equals the uniform Earth's earthshine / 0.3."""
    rows = _rows(phases_deg=(120.0,), earth_surface=_hemispheric_earth(tmp_path), earth_rotation_deg=-30.0)
    base = _rows(phases_deg=(120.0,))
    for k in MODELS:
        unit = rows[k]["earthshine_W_m2"] / rows[k]["earth_visible_lit_albedo"]
        assert unit == pytest.approx(base[k]["earthshine_W_m2"] / 0.3, rel=2e-4)


def test_landocean_mean_matches_the_mask():
    """Bar: ``landocean`` without clouds: the area-weighted mean facet albedo is within 0.5 % of
    the mask's land fraction f applied to the two albedos, f·0.25 + (1 - f)·0.06. f comes from the
    global-land-mask package's own 30″ mask here (cos-latitude weights per row)."""
    from global_land_mask import globe

    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    land_rows = (~globe._mask).mean(axis=1)
    w = np.cos(np.radians(globe._lat.astype(float) - 1 / 240))  # row centres
    f = float((land_rows * w).sum() / w.sum())
    assert 0.28 < f < 0.30  # the Earth: 29 % land
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(earth_surface="landocean"))
    a = ts.surfaces.earth_facet_albedo()
    mean = float((a * ts.earth.areas).sum() / ts.earth.areas.sum())
    expect = 0.25 * f + 0.06 * (1 - f)
    assert mean == pytest.approx(expect, rel=5e-3)


def test_zonal_clouds_give_the_documented_mean():
    """The defaults' claim (surfaces.py): with zonal clouds (global mean 0.64) and land 0.25,
    ocean 0.06, cloud 0.40, the Earth's mean albedo is 0.30 within 0.01."""
    la, cf = zonal_cloud_table()
    x = np.linspace(-90, 90, 3601)
    mean_cloud = np.trapezoid(np.interp(x, la, cf) * np.cos(np.radians(x)), x) / 2 * np.pi / 180
    assert mean_cloud == pytest.approx(0.64, abs=0.01)
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(earth_surface="landocean", clouds="zonal"))
    a = ts.surfaces.earth_facet_albedo()
    assert float((a * ts.earth.areas).sum() / ts.earth.areas.sum()) == pytest.approx(0.30, abs=0.01)


def test_earth_frame_sub_solar_longitude():
    """--earth-rotation-deg is the sub-solar longitude: a map bright in one cell at longitude
    λ on the equator lights the facet nearest the sub-solar point when λ = λs."""
    sc = SceneGeometry(90.0)
    for lam in (0.0, 75.0, -140.0):
        R = map_frame(sc, "earth", lam)
        sub_solar = R @ np.array([np.cos(np.radians(lam)), np.sin(np.radians(lam)), 0.0])
        assert np.allclose(sub_solar, (sc.sun - sc.earth) / np.linalg.norm(sc.sun - sc.earth), atol=1e-12)
        assert np.allclose(R @ [0, 0, 1.0], [1.0, 0, 0])  # north pole +x (DESIGN.md)


# ---- the Moon -----------------------------------------------------------------------------------
def _half_bright_moon(tmp_path):
    m = np.ones((180, 360))
    m[:, 180:270] = 1.5  # longitudes [0°, 90°): the eastern half of the near side
    return _save(tmp_path, "moon.npy", m)


def _moon_albedo(lat, lon):
    """Each BRDF's albedo parameter × map / ⟨map⟩; ⟨map⟩ = 1.5·1/4 + 1·3/4 = 1.125 exactly."""
    f = np.where((lon >= 0) & (lon < 90), 1.5, 1.0) / 1.125
    return {k: PAPER_ALBEDO[k] * f for k in MODELS}


def test_half_bright_moon_matches_quadrature(tmp_path):
    """Bar: a Moon bright on one half of its near side: moonshine within 1e-3 of the independent
    quadrature at phases θ = 60°, 120° and a crescent, 150° (the map's edge at 90° is then at the
    limb, where the light is: the refined limb facets read the map over their own sub-triangles),
    and the waxing/waning pair of equal phase angle (θ = 120° and 240°) differs as the quadrature
    says (ratio within 1e-3). The quadrature uses a point Sun (extended Sun: 2e-5) and converges
    to 2e-5; the tracer's facets average the map by area (second order)."""
    path = _half_bright_moon(tmp_path)
    assert map_mean(np.load(path)) == pytest.approx(1.125, rel=1e-12)
    phases = (60.0, 120.0, 150.0, 240.0)
    rows = _rows(phases_deg=phases, moon_albedo_map=path)
    ref = {th: ind.mapped_irradiance(th, MODELS, moon_albedo=_moon_albedo, moon_cuts=(0, 90), n_moon=(48, 32),
                                     n_earth=(8, 8)) for th in phases}
    for th in phases:
        for k in MODELS:
            assert rows[(th, k)]["moonshine_W_m2"] == pytest.approx(ref[th][k][0], rel=1e-3), (th, k)
    for k in MODELS:
        ratio = rows[(120.0, k)]["moonshine_W_m2"] / rows[(240.0, k)]["moonshine_W_m2"]
        ratio_ref = ref[120.0][k][0] / ref[240.0][k][0]
        assert abs(ratio_ref - 1) > 0.02  # the map makes waxing and waning differ
        assert ratio == pytest.approx(ratio_ref, rel=1e-3)
        assert rows[(120.0, k)]["alpha_deg"] == pytest.approx(rows[(240.0, k)]["alpha_deg"], abs=1e-9)


def test_moon_map_frame_faces_the_earth(tmp_path):
    """θ scene: the map's (0°, 0°) faces the Earth (tidal lock), its north pole is +x."""
    from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings
    m = np.ones((180, 360))
    m[88:92, 178:182] = 5.0  # a bright spot at (0°, 0°)
    path = _save(tmp_path, "spot.npy", m)
    for th in (30.0, 150.0, 250.0):
        ts = TraceScene(SceneGeometry(th), TraceSettings(moon_albedo_map=path))
        v = ts.surfaces.moon_facet_albedo()
        brightest = ts.moon.centroids[np.argmax(v)] - ts.moon.centre
        to_earth = -ts.scene.moon / np.linalg.norm(ts.scene.moon)
        assert np.degrees(np.arccos(brightest @ to_earth / np.linalg.norm(brightest))) < 4.0


def test_moon_map_follows_libration_on_dates(tmp_path):
    """Dates: the map lives in MOON_ME, so the facet facing the observer carries the map's value
    at the sub-observer point the ephemeris reports (libration)."""
    from lunarviz.methods.tracer.estimators import TraceScene
    lon = -180 + (np.arange(360) + 0.5)
    lat = 90 - (np.arange(180) + 0.5)
    m = np.cos(np.radians(lat))[:, None] * (1.0 + 0.5 * np.sin(np.radians(lon)))[None, :] + 0.1  # smooth
    path = _save(tmp_path, "smooth.npy", m)
    s = ResolvedScene(brdfs=("lambert",), method="raytrace", times=("2026-06-22T00:00Z",), moon_albedo_map=path,
                      moon_level=6)
    sc, fields = s.task(s.tasks()[0])
    ts = TraceScene(sc, s.trace_settings())
    v = ts.surfaces.moon_facet_albedo()
    c = ts.moon.centroids - ts.moon.centre
    facing = np.argmax(c @ (sc.det - sc.moon))
    la, lo = np.radians(fields["sub_observer_lat_deg"]), np.radians(fields["sub_observer_lon_deg"])
    expect = (np.cos(la) * (1 + 0.5 * np.sin(lo)) + 0.1) / map_mean(m)
    assert abs(fields["sub_observer_lon_deg"]) > 1.0  # a date with libration in longitude
    assert v[facing] == pytest.approx(expect, rel=0.02)  # facet-averaged 1° map on a level-6 facet


# ---- bad maps -----------------------------------------------------------------------------------
def _cli(*args):
    return subprocess.run([sys.executable, "-m", "lunarviz", *args], capture_output=True, text=True)


@pytest.mark.parametrize("kind", ["shape", "nan", "gt1", "unreadable", "missing", "suffix", "w_gt1", "mean_bad"])
def test_bad_maps_end_with_one_line(tmp_path, kind):
    """Bar: a wrong shape, NaN values, albedo > 1, an unreadable file: one line, exit 2, nothing
    written."""
    ok = np.full((10, 20), 0.2)
    if kind == "shape":
        opt = ["--earth-surface", _save(tmp_path, "bad.npy", np.full((10, 10), 0.2))]
        msg = "width = 2 × height"
    elif kind == "nan":
        a = ok.copy()
        a[3, 4] = np.nan
        opt = ["--clouds", _save(tmp_path, "bad.npy", a)]
        msg = "NaN"
    elif kind == "gt1":
        opt = ["--earth-surface", _save(tmp_path, "bad.npy", ok + 1.0)]
        msg = "outside [0, 1]"
    elif kind == "unreadable":
        p = tmp_path / "bad.png"
        p.write_bytes(b"not a png at all")
        opt = ["--moon-albedo-map", str(p)]
        msg = "unreadable"
    elif kind == "missing":
        opt = ["--moon-albedo-map", str(tmp_path / "nope.npy")]
        msg = "file not found"
    elif kind == "suffix":
        p = tmp_path / "map.txt"
        p.write_text("1 2 3")
        opt = ["--earth-surface", str(p)]
        msg = "unknown format"
    elif kind == "w_gt1":
        a = ok.copy()
        a[:, :2] = 10.0  # 8.5 × the mean: w = 0.33 × 8.5 > 1
        opt = ["--moon-albedo-map", _save(tmp_path, "bad.npy", a), "--brdf", "dhg"]
        msg = "> 1"
    else:
        opt = ["--moon-albedo-map", f"{_save(tmp_path, 'm.npy', ok)}:1.5"]
        msg = "mean"
    out = tmp_path / "out.json"
    p = _cli("sweep", "--method", "raytrace", "--phases", "90", *opt, "--out", str(out), "--quiet")
    assert p.returncode == 2, p.stderr
    lines = [ln for ln in p.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and msg in lines[0], p.stderr
    assert not out.exists()


def test_earth_rotation_refused_on_dates():
    from lunarviz.errors import LunarvizError
    with pytest.raises(LunarvizError, match="earth_rotation_deg turns the Earth"):
        ResolvedScene(times=("2026-06-22T00:00Z",), earth_rotation_deg=10.0)


def test_sweep_rows_carry_the_visible_lit_albedo(tmp_path):
    """The CLI writes earth_visible_lit_albedo; for the uniform Earth it is the albedo."""
    out = tmp_path / "s.json"
    p = _cli("sweep", "--method", "analytic", "--phases", "60,120", "--brdf", "lambert", "--out", str(out), "--quiet")
    assert p.returncode == 0, p.stderr
    rows = json.loads(out.read_text())["rows"]
    assert all(r["earth_visible_lit_albedo"] == pytest.approx(0.3, rel=1e-12) for r in rows)


def test_earth_surface_validation():
    from lunarviz.errors import LunarvizError
    with pytest.raises(LunarvizError, match="cloud albedo"):
        EarthSurface(cloud_albedo=1.2)


def test_checkerboard_hapke_moon_second_order(tmp_path):
    """Hapke's reflectance is not linear in w, so a facet's mean w is not its mean reflectance:
    the transport averages the BRDF at w̄ ± σ (σ: the map's spread over the sample's area), exact
    to second order. A 30° checkerboard (w 0.495 / 0.165) at θ = 90°, level-4 Moon: DHG within
    1e-3 of the quadrature (split at every edge in latitude and longitude); with w̄ alone it
    was -1.2 % (measured), Lambert (linear) needs nothing."""
    lat = 90 - (np.arange(180) + 0.5)
    lon = -180 + (np.arange(360) + 0.5)
    chk = np.where((np.floor(lat / 30)[:, None] + np.floor(lon / 30)[None, :]) % 2 == 0, 1.5, 0.5)
    path = _save(tmp_path, "chk.npy", chk)
    mc = map_mean(chk)

    def fc(la, lo):
        v = np.where((np.floor(la / 30) + np.floor(lo / 30)) % 2 == 0, 1.5, 0.5) / mc
        return {k: PAPER_ALBEDO[k] * v for k in MODELS}
    rows = _rows(phases_deg=(90.0,), moon_albedo_map=path)
    ref = ind.mapped_irradiance(90.0, MODELS, moon_albedo=fc, moon_cuts=tuple(range(-180, 181, 30)),
                                moon_lat_cuts=tuple(range(-60, 61, 30)), n_moon=(16, 16), n_earth=(8, 8))
    for k in MODELS:
        assert rows[k]["moonshine_W_m2"] == pytest.approx(ref[k][0], rel=1e-3), k


def test_view_numbers_match_the_sweep(tmp_path):
    """The viewer's numbers invert against the uniform model Earth, as the sweep's rows do."""
    from lunarviz.workflows.tasks import view_data as compute_view_data
    s = ResolvedScene(brdfs=("dhg",), method="raytrace", phases_deg=(120.0,), moon_level=3,
                      earth_surface=_hemispheric_earth(tmp_path), earth_rotation_deg=-30.0)
    r = run_phase(s, 120.0)[0]
    v = compute_view_data(s, 120.0, "dhg").numbers
    assert v["apparent_albedo"] == pytest.approx(r["apparent_albedo"], rel=1e-12)
    assert v["apparent_albedo_point_inversion"] == pytest.approx(r["apparent_albedo_point_source_inversion"],
                                                                  rel=1e-12)
    assert v["earth_visible_lit_albedo"] == pytest.approx(r["earth_visible_lit_albedo"], rel=1e-12)


def test_maps_refused_where_they_would_mislead(tmp_path):
    from lunarviz.errors import LunarvizError
    with pytest.raises(LunarvizError, match="reference"):
        ResolvedScene(method="reference", earth_surface="landocean")
    mesh = tmp_path / "m.ply"
    from lunarviz.bodies import shapes
    shapes.write_mesh(shapes.ellipsoid(1.74e6, 1.73e6, 1.72e6, 2), mesh)
    with pytest.raises(LunarvizError, match="needs a date"):
        ResolvedScene(method="raytrace", moon_mesh=str(mesh), moon_albedo_map="synthetic")


def test_images_read_as_linear_values(tmp_path):
    """Palette images by their colours, 16-bit by 65535; 32-bit integer images refused."""
    from PIL import Image

    from lunarviz.errors import LunarvizError
    from lunarviz.surfaces.maps import read_map
    grey = np.zeros((10, 20), dtype=np.uint8)
    grey[:, 10:] = 200
    im = Image.fromarray(grey).convert("P")
    im.save(tmp_path / "p.png")
    a = read_map(tmp_path / "p.png")
    assert a[0, 15] == pytest.approx(200 / 255, abs=1e-9) and a[0, 0] == 0.0
    Image.fromarray((np.full((10, 20), 40000)).astype(np.uint16)).save(tmp_path / "g16.png")
    assert read_map(tmp_path / "g16.png")[0, 0] == pytest.approx(40000 / 65535, rel=1e-9)
    Image.fromarray(np.full((10, 20), 5, dtype=np.int32)).save(tmp_path / "i32.tif")
    with pytest.raises(LunarvizError, match="32-bit"):
        read_map(tmp_path / "i32.tif")


@pytest.mark.parametrize("rows", [[], [0], [3, 4, 5, 9], [1, 7, 8, 19]])
def test_a_blocks_asked_rows_are_its_whole_draws_rows(rows):
    """The jittered points of the facets a date asks for are drawn by skipping the others' draws
    (maps._random_rows): the same numbers as drawing the whole block and taking the rows, and the
    generator left where that draw leaves it (the next block's draws unchanged), a block asked
    nothing included (passed without drawing)."""
    from lunarviz.surfaces.maps import _random_rows
    whole, skipped = np.random.default_rng(7), np.random.default_rng(7)
    want = whole.random((20, 6))[rows]
    got = _random_rows(skipped, 20, 6, np.asarray(rows, dtype=np.int64))
    assert got.shape == (len(rows), 6) and np.array_equal(got, want)
    assert np.array_equal(skipped.random(5), whole.random(5))


def test_facet_fields_keep_a_linear_map_and_the_compiled_fits_agree():
    """A linear function of position is its own least-squares fit over each facet: value at the
    centroid and gradient in the facet's plane to rounding (1e-12). The compiled fits of the
    packaged Earth maps (lunarviz.surfaces.earth_field_kernels) equal numpy's to rounding."""
    from lunarviz.methods.tracer.estimators import TraceScene
    from lunarviz.surfaces.earth_field_kernels import available
    from lunarviz.surfaces.earth_spectra import _compiled_fits, weights_at
    from lunarviz.surfaces.maps import facet_field_at, facet_linear_fit
    s = ResolvedScene(phases_deg=(60.0,), earth_surface="landocean", clouds="zonal", method="raytrace", earth_level=4)
    body = TraceScene(s.geometry(60.0), s.trace_settings(threads=1)).bodies.earth
    V, F = body.vertices, body.faces
    only = np.arange(0, len(F), 7)
    a, R = np.array([0.3, -0.2, 0.5]) / 6.371e6, 6.371e6
    value, grad = facet_linear_fit(lambda d: np.stack([1 + d @ a, np.full(len(d), 2.0)], 1), V, F, 8, only=only)
    tri = V[F[only]]
    c = tri.mean(1)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    assert np.allclose(value[:, 0], 1 + c @ a, rtol=0, atol=1e-12)
    assert np.allclose(grad[:, 0] * R, (a - (nrm @ a)[:, None] * nrm) * R, rtol=0, atol=1e-12)
    assert np.allclose(value[:, 1], 2.0, rtol=0, atol=1e-12) and np.abs(grad[:, 1]).max() * R < 1e-12
    # at a point of the sphere above the facet: the field at its radial projection onto the facet
    y = c / np.linalg.norm(c, axis=1)[:, None] * R
    flat = y * ((nrm * c).sum(1) / (nrm * y).sum(1))[:, None]
    assert np.allclose(facet_field_at(value, grad, V, F[only], y, radial=True)[:, 0], 1 + flat @ a, rtol=0, atol=1e-12)
    if not available():
        pytest.skip("numba not available: the numpy fits are the only ones")
    frame = map_frame(s.geometry(60.0), "earth", 30.0)
    for surface, clouds in (("landocean", "zonal"), ("uniform", "zonal"), ("landocean", "none")):
        surf = ResolvedScene(phases_deg=(60.0,), earth_surface=surface, clouds=clouds).earth_model()
        slow = facet_linear_fit(lambda d: weights_at(surf, d @ frame), V, F, 12, only=only)
        fast = facet_linear_fit(None, V, F, 12, only=only, fit=_compiled_fits(surf, frame))
        assert np.allclose(fast[0], slow[0], rtol=0, atol=1e-12)
        assert np.allclose(fast[1] * R, slow[1] * R, rtol=0, atol=1e-10)


def test_mapped_earth_fields_at_full_moon_and_on_a_facet_through_the_centre():
    """At θ = 0 no Earth facet is both lit and seen from the Moon: the mapped Earth's earthshine is
    0 (the fields of no facet asked for first). A user mesh's facet whose plane holds the body's
    centre (a notch) takes its field at the element itself, on the facet: finite, as the field's
    own linear value; the radial projection is for the exact sphere's points only."""
    from lunarviz.surfaces.maps import facet_field_at
    r = _rows(phases_deg=(0.0,), earth_surface="landocean", clouds="zonal", earth_level=3, moon_level=3)
    assert all(v["earthshine_W_m2"] == 0.0 for v in r.values())
    V = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # a plane through the centre
    p = np.array([[0.3, 0.0, 0.1]])
    got = facet_field_at(np.array([[2.0]]), np.array([[[1.0, 0.0, 0.5]]]), V, np.array([[0, 1, 2]]), p)
    assert got[0, 0] == pytest.approx(2.0 + (0.3 - 1 / 3) + 0.5 * 0.1, rel=1e-14)
