"""Any closed mesh for any body, traced by Embree, checked on shapes that are not spheres.

Every expected value here comes from tests/independent.py (analytic surfaces, numpy only, no
tracer code) or from a closed form; each tolerance says which error it budgets for.
"""

import json

import independent as ind
import numpy as np
import pytest
import trimesh

from lunarviz import constants as C
from lunarviz.bodies import shapes
from lunarviz.bodies.meshes import MeshError, load_user_mesh
from lunarviz.cli import main
from lunarviz.geometry.scene_geometry import SceneGeometry
from lunarviz.methods.tracer.embree_bodies import EmbreeBody
from lunarviz.methods.tracer.estimators import TraceScene, TraceSettings, trace_path

R = C.R_MOON_M
AXES = (1.15 * R, 1.00 * R, 0.85 * R)


def _write(mesh, path):
    shapes.write_mesh(mesh, path)
    return str(path)


#: the module's tests share module fixtures: they run on one worker (pytest-xdist's loadgroup)
pytestmark = pytest.mark.xdist_group("test_meshes")


@pytest.fixture(scope="module")
def lam_dhg():
    from lunarviz.photometry.brdf import make_brdf
    return {"lambert": make_brdf("lambert"), "dhg": make_brdf("dhg")}


def _trace(theta, path, models, **kw):
    ts = TraceScene(SceneGeometry(theta), TraceSettings(moon_mesh=path, **kw))
    return trace_path(ts, "moonshine", models).mean, trace_path(ts, "earthshine", models).mean, ts


@pytest.fixture
def stub_embree(monkeypatch):
    """Embree's query replaced by 'every ray misses, nothing is occluded'."""
    def miss(self, o32, d32, query, dists=None, scene=None):
        return np.full(len(o32), -1, dtype=np.int32)
    monkeypatch.setattr(EmbreeBody, "run_rays", miss)


# ---- a triaxial ellipsoid -----------------------------------------------------------------
@pytest.mark.slow
def test_ellipsoid_converges_to_independent_quadrature(tmp_path, lam_dhg):
    # Reference: parametric Gauss quadrature over the exact ellipsoid (tests/independent.py);
    # its own error at these orders is ≤ 3e-5 (moonshine, n = 480) and ≤ 2e-5 (earthshine,
    # n = 120 with the Earth's lit arc integrated exactly), measured by doubling the orders.
    theta = 60.0
    ms_ref = ind.detector_irradiance(theta, ind.ellipsoid_surface(*AXES, n=480), lam_dhg, earthshine=False)
    es_ref = ind.detector_irradiance(theta, ind.ellipsoid_surface(*AXES, n=120), lam_dhg)
    errs = []
    for level in (4, 5, 6):
        path = _write(shapes.ellipsoid(*AXES, level=level), tmp_path / f"ell{level}.ply")
        ms, es, ts = _trace(theta, path, lam_dhg)
        assert not ts.moon.is_sphere and ts.moon.mode(ts.settings.shading) == "flat"
        e = max(max(abs(ms[k] / ms_ref[k][0] - 1), abs(es[k] / es_ref[k][1] - 1)) for k in lam_dhg)
        errs.append(e)
    # flat facets: second-order convergence (observed order ≥ 1.5 per halving of the facet
    # size), and level 6 (81,920 facets) within 5e-4 (the facets' O(h²) area deficit is 1.1e-4)
    assert errs[1] < errs[0] / 2.8 and errs[2] < errs[1] / 2.8, errs
    assert errs[2] < 5e-4, errs


# ---- a rotated cube: flat faces, closed form ------------------------------------------------
CUBE_ROT = ind.rotation_zyx(25.0, 35.0, 15.0)


@pytest.fixture(scope="module")
def cube_path(tmp_path_factory):
    box = trimesh.creation.box(extents=[2 * R] * 3)
    box = trimesh.Trimesh(np.asarray(box.vertices) @ CUBE_ROT.T, box.faces, process=False)
    return _write(box, tmp_path_factory.mktemp("cube") / "cube.obj")


def _cube_lambert_closed_form(theta):
    """Σ over faces of (ρ/π)·E_sun·μ0·μ·cosδ·A/d² at the face centres (Lambert, point Sun):
    exact for flat faces up to the O((R/D)²) ≈ 2e-5 variation of 1/d² across a face."""
    sun, earth, moon = ind.scene(theta)
    det_n = (moon - earth) / np.linalg.norm(moon - earth)
    total = 0.0
    for axis in range(3):
        for sgn in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sgn
            n = CUBE_ROT @ n
            x = moon + R * n
            s = (sun - x) / np.linalg.norm(sun - x)
            v = earth - x
            d = np.linalg.norm(v)
            mu0, mu = max(n @ s, 0), max(n @ v / d, 0)
            E = C.PHI_SUN_W / (4 * np.pi * np.sum((sun - x) ** 2))
            total += 0.1 / np.pi * E * mu0 * mu * (-(v @ det_n) / d) * (2 * R) ** 2 / d**2
    return total


@pytest.mark.parametrize("theta", [40.0, 130.0])
def test_cube_default_shading_matches_closed_form(theta, cube_path, lam_dhg):
    ms, es, ts = _trace(theta, cube_path, lam_dhg)  # default settings: whatever shading they pick
    # the crease limit keeps a cube's normals per face (no 186× smooth-shading blow-up)
    assert np.allclose(ts.moon.corner_normals, ts.moon.normals[:, None, :])
    assert ms["lambert"] == pytest.approx(_cube_lambert_closed_form(theta), rel=2e-4)
    # DHG moonshine and both earthshines against Gauss quadrature over each face (exact on
    # flat faces to 1e-10 at n = 16) with the extended Earth (error ≤ 2e-5)
    ref = ind.detector_irradiance(theta, ind.box_surface(R, CUBE_ROT, n=16), lam_dhg)
    for k in lam_dhg:
        assert ms[k] == pytest.approx(ref[k][0], rel=2e-4)
        assert es[k] == pytest.approx(ref[k][1], rel=5e-4)


# ---- a bowl crater: shadowed fraction (closed form) and moonshine -----------------------------
def _bowl_moon(level, axis, rim_deg, depth_ratio, zoom=4.0):
    """The Moon minus a ball: a spherical bowl crater about ``axis`` of rim angular radius
    ``rim_deg`` and depth/rim-radius ``depth_ratio``; the rim is a planar circle."""
    m = shapes.base_sphere(level, None)
    u = shapes.zoom_toward(np.asarray(m.vertices), axis, zoom)
    r0 = R * np.sin(np.radians(rim_deg))
    H = R * np.cos(np.radians(rim_deg))
    S = r0 * (1 + depth_ratio**2) / (2 * depth_ratio)
    B = axis * (H - depth_ratio * r0 + S)  # ball centre
    ub = u @ B
    disc = ub**2 - B @ B + S * S
    t1 = ub - np.sqrt(np.clip(disc, 0, None))
    rad = np.where((disc > 0) & (ub > 0) & (t1 < R), t1, R)
    return trimesh.Trimesh(u * rad[:, None], m.faces, process=False), (B, S, r0, H)


def _about_axis(axis, ct, phi, sign=1.0):
    """Unit vectors at polar cosines ``ct`` (about ``sign``·axis) and azimuths ``phi`` (grid
    ct × phi, flattened): the polar quadrature grids of the bowl tests."""
    CT, PH = np.meshgrid(ct, phi, indexing="ij")
    e1 = np.cross(axis, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    ring = np.cos(PH)[..., None] * e1 + np.sin(PH)[..., None] * e2
    return (sign * CT[..., None] * axis + np.sqrt(1 - CT**2)[..., None] * ring).reshape(-1, 3)


def _bowl_axis_for(theta, elevation_deg):
    """A crater axis on the Moon whose rim plane sees the Sun at ``elevation_deg`` and faces
    the detector (at the Earth's centre) as much as that allows."""
    sun, earth, moon = ind.scene(theta)
    s = (sun - moon) / np.linalg.norm(sun - moon)
    o = (earth - moon) / np.linalg.norm(earth - moon)
    t = o - (o @ s) * s
    t /= np.linalg.norm(t)
    e = np.radians(elevation_deg)
    return np.sin(e) * s + np.cos(e) * t


@pytest.mark.parametrize("elevation", [8.0, 20.0, 40.0])
def test_bowl_shadow_fraction_closed_form(elevation):
    # Buhl, Welch & Rea (1968) geometry: in a spherical bowl the shadow is the intersection of
    # two equal caps (tests/independent.py); Embree answers the shadow rays on the mesh.
    theta = 90.0
    axis = _bowl_axis_for(theta, elevation)
    mesh, (B, S, r0, H) = _bowl_moon(6, axis, 8.0, 0.4)
    body = EmbreeBody(mesh, np.zeros(3))
    sun, _, moon = ind.scene(theta)
    s = (sun - moon) / np.linalg.norm(sun - moon)
    # stratified points on the exact bowl (the cap of the ball about −axis below the rim plane)
    a = np.arccos((S - 0.4 * r0) / S)
    n = 200
    ct = 1 - (1 - np.cos(a)) * (np.arange(n) + 0.5) / n
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    u = _about_axis(axis, ct, phi, sign=-1.0)
    # each point moved onto the mesh along the ball's radius (a chord of the concave bowl lies
    # up to ~20 m above it), and shaded as the tracer shades flat facets: facet normal, origin
    # 1 m above the facet
    hit = body.intersect(np.broadcast_to(B, u.shape), u)
    assert hit.hit.all()
    nrm = body.normals[hit.prim]
    facing = nrm @ s > 0
    occ = body.occluded(hit.point + nrm * 1.0, np.broadcast_to(s, u.shape))
    lit = np.mean(facing & ~occ)  # equal-area points
    expected = 1 - ind.bowl_shadow_fraction(0.4, elevation)
    # budget: the rim polygon of a level-6 mesh zoomed 4× (facets ~7 km on a 240 km rim)
    assert lit == pytest.approx(expected, abs=0.015)


def test_bowl_crater_moonshine_and_self_shadow(tmp_path, lam_dhg):
    theta, elev = 90.0, 12.0
    axis = _bowl_axis_for(theta, elev)
    mesh, (B, S, r0, H) = _bowl_moon(6, axis, 12.0, 0.4)
    path = _write(mesh, tmp_path / "bowl.ply")
    lam = {"lambert": lam_dhg["lambert"]}
    ms, _, ts = _trace(theta, path, lam, shading="flat")
    assert not ts.moon.convex
    a = np.arccos((S - 0.4 * r0) / S)

    def lit(xb, s, o):
        """Analytic self-shadowing and hiding: a bowl point is dark (hidden) when the cap
        condition of tests/independent.py holds for the Sun (detector) direction."""
        u = (xb - B) / S
        in_bowl = np.abs(np.linalg.norm(xb - B, axis=1) - S) < 1e-6 * S
        ok = np.ones(len(xb), dtype=bool)
        for d in (s, o):
            m = axis - 2 * (d @ axis)[:, None] * d  # Hm ẑ with ẑ = axis (rim plane normal)
            ok &= ~(in_bowl & (np.einsum("ij,ij->i", u, -m) > np.cos(a)))
        return ok

    # reference surface: the sphere outside the rim cap + the bowl, polar rules about the axis
    def polar(t0, t1, n, centre, radius, sign):
        xg, wg = np.polynomial.legendre.leggauss(n)
        ct = 0.5 * (np.cos(t0) + np.cos(t1)) + 0.5 * (np.cos(t1) - np.cos(t0)) * xg
        w = 0.5 * abs(np.cos(t1) - np.cos(t0)) * wg
        ph = (np.arange(2 * n) + 0.5) * np.pi / n
        u = _about_axis(axis, ct, ph, sign)
        return centre + radius * u, u, np.repeat(w, len(ph)) * (np.pi / n) * radius**2

    x1, n1, w1 = polar(np.radians(12.0), np.pi, 600, np.zeros(3), R, 1.0)
    x2, u2, w2 = polar(0.0, a, 400, B, S, -1.0)
    surf = (np.concatenate([x1, x2]), np.concatenate([n1, -u2]), np.concatenate([w1, w2]))  # bowl normal −u
    ref = ind.detector_irradiance(theta, surf, lam, earthshine=False, lit=lit)["lambert"][0]
    # budget: flat facets (level 6 zoomed ×4: O(h²) ≈ 1e-4 on the sphere part) and the
    # reference's O(1/n) error at the bowl's shadow edge (the bowl is ~1 % of the signal)
    assert ms["lambert"] == pytest.approx(ref, rel=1e-3)
    # the crater's self-shadowing is ray traced and independent of --no-occlusion
    no_occ, _, _ = _trace(theta, path, lam, shading="flat", occlusion=False)
    no_self, _, _ = _trace(theta, path, lam, shading="flat", self_shadow=False)
    assert no_occ["lambert"] == pytest.approx(ms["lambert"], rel=1e-12)
    assert no_self["lambert"] > ms["lambert"] * (1 + 1e-3)


def test_embree_stub_changes_non_spherical_results(tmp_path, cube_path, lam_dhg, monkeypatch):
    lam = {"lambert": lam_dhg["lambert"]}
    crater = _write(shapes.craters(R, 4, 12, 150e3, 400e3, seed=1, region=(0.0, 60.0, 50.0)),
                    tmp_path / "craters.ply")
    ell = _write(shapes.ellipsoid(*AXES, level=4), tmp_path / "ell.ply")
    before = {p: _trace(120.0, p, lam, shading="flat")[:2] for p in (crater, ell, cube_path)}

    def miss(self, o32, d32, query, dists=None, scene=None):
        return np.full(len(o32), -1, dtype=np.int32)
    monkeypatch.setattr(EmbreeBody, "run_rays", miss)
    from lunarviz.caches import release_caches
    release_caches()  # no Embree scene or geometry built before the stub is reused
    for p, (ms0, es0) in before.items():
        ms1, es1, _ = _trace(120.0, p, lam, shading="flat")
        assert abs(ms1["lambert"] / ms0["lambert"] - 1) > 0.01, p
        assert abs(es1["lambert"] / es0["lambert"] - 1) > 0.01, p


def test_moon_only_stub_changes_a_cratered_moon(tmp_path):
    # Stubbing only the Moon's Embree queries (the Sun and Earth still traced) must change a
    # non-convex Moon: its self-shadowing and self-hiding are Embree's answers. (A convex Moon
    # mesh sends no rays to its own scene, by design: its horizon decides exactly.)
    from lunarviz.photometry.brdf import make_brdf
    lam = {"lambert": make_brdf("lambert")}
    p = _write(shapes.craters(R, 5, 25, 80e3, 250e3, seed=3, region=(0.0, -90.0, 25.0)), tmp_path / "c.ply")
    ts = TraceScene(SceneGeometry(120.0), TraceSettings(moon_mesh=p))
    a = trace_path(ts, "moonshine", lam).mean["lambert"]
    ts2 = TraceScene(SceneGeometry(120.0), TraceSettings(moon_mesh=p))
    ts2.moon.run_rays = lambda o32, d32, query, dists=None, scene=None: np.full(len(o32), -1, dtype=np.int32)
    b = trace_path(ts2, "moonshine", lam).mean["lambert"]
    assert b > a * 1.01  # no shadows at all: brighter by the craters' shadowed share


def test_sun_mesh_conserves_power(tmp_path):
    # The Sun is a Lambertian emitter of power Φ: a Sun mesh twice the size has a quarter of
    # the radiance and four times the solid angle, so the moonshine is unchanged (to the level-3
    # mesh's ~1e-3 beam/facet error) and the earthshine (point Sun of power Φ) is identical.
    from lunarviz.photometry.brdf import make_brdf
    lam = {"lambert": make_brdf("lambert")}
    sun2 = _write(shapes.base_sphere(3).apply_scale(2 * C.R_SUN_M), tmp_path / "sun2.ply")
    base = TraceScene(SceneGeometry(60.0), TraceSettings(moon_level=3))
    big = TraceScene(SceneGeometry(60.0), TraceSettings(moon_level=3, sun_mesh=sun2))
    assert trace_path(big, "moonshine", lam).mean["lambert"] == pytest.approx(
        trace_path(base, "moonshine", lam).mean["lambert"], rel=3e-3)


# ---- formats, units, refusals ------------------------------------------------------------
def test_same_numbers_from_ply_obj_stl(tmp_path, lam_dhg):
    m = shapes.craters(R, 3, 6, 200e3, 500e3, seed=2)
    vals = []
    for suffix in (".ply", ".obj", ".stl"):
        path = _write(m, tmp_path / f"moon{suffix}")
        ms, es, _ = _trace(100.0, path, lam_dhg)
        vals.append([ms["dhg"], es["dhg"]])
    # OBJ/STL store ~7-9 significant digits (float32 in STL): 1e-6 relative budget
    assert np.allclose(vals, vals[0], rtol=1e-6, atol=0)


def test_units_and_implausible_sizes(tmp_path):
    m = shapes.ellipsoid(*AXES, level=2)
    km = trimesh.Trimesh(np.asarray(m.vertices) / 1e3, m.faces, process=False)
    p = _write(km, tmp_path / "moon_km.ply")
    with pytest.raises(MeshError, match="kilometres: pass mesh_units km"):
        load_user_mesh(p, "moon")
    got = load_user_mesh(p, "moon", units="km")
    assert np.allclose(got.vertices, m.vertices, rtol=1e-12)  # taken as given, not rescaled
    unit = trimesh.Trimesh(np.asarray(m.vertices) / R, m.faces, process=False)
    p2 = _write(unit, tmp_path / "moon_r.ply")
    assert np.allclose(load_user_mesh(p2, "moon", units="radius").vertices, m.vertices, rtol=1e-12)
    off = trimesh.Trimesh(np.asarray(m.vertices) + [0.05 * R, 0, 0], m.faces, process=False)
    with pytest.raises(MeshError, match="centre of mass"):  # 87 km off: more than 2 %
        load_user_mesh(_write(off, tmp_path / "off.ply"), "moon")
    two = trimesh.util.concatenate([trimesh.Trimesh(np.asarray(m.vertices) * 0.4 + [d * R, 0, 0], m.faces)
                                    for d in (-0.5, 0.5)])
    with pytest.raises(MeshError, match="2 disconnected parts"):
        load_user_mesh(_write(two, tmp_path / "two.ply"), "moon")


def test_cli_refuses_meshes_it_cannot_use(tmp_path, capsys):
    m = shapes.ellipsoid(*AXES, level=2)
    p = _write(m, tmp_path / "ell.ply")
    km = _write(trimesh.Trimesh(np.asarray(m.vertices) / 1e3, m.faces, process=False), tmp_path / "km.ply")
    for argv in (["sweep", "--method", "analytic", "--moon-mesh", p],
                 ["sweep", "--method", "analytic", "--mesh-units", "km"],
                 ["trace", "--phase", "60", "--mesh-level", "2", "--out", str(tmp_path / "keep.vtm")],
                 ["sweep", "--method", "reference", "--earth-mesh", p],
                 ["sweep", "--method", "raytrace", "--moon-mesh", km],
                 ["sweep", "--method", "raytrace", "--moon-mesh", str(tmp_path / "missing.ply")]):
        out = tmp_path / "s.json"
        (tmp_path / "keep").mkdir(exist_ok=True)
        (tmp_path / "keep" / "notes.txt").write_text("a user's file beside the .vtm name")
        extra = [] if argv[0] == "trace" else ["--phases", "60", "--out", str(out), "--quiet"]
        assert main([*argv, *extra]) == 2
        assert (tmp_path / "keep" / "notes.txt").exists()
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("lunarviz: error:")
        assert not out.exists()


def test_cli_mesh_make_and_sweep(tmp_path):
    out = tmp_path / "ell.ply"
    assert main(["mesh", "make", "ellipsoid", "--level", "3", "--out", str(out)]) == 0
    s = tmp_path / "s.json"
    assert main(["sweep", "--method", "raytrace", "--moon-mesh", str(out), "--phases", "90",
                 "--brdf", "lambert", "--out", str(s), "--quiet"]) == 0
    row = json.loads(s.read_text())["rows"][0]
    assert row["moonshine_W_m2"] > 0 and row["earthshine_W_m2"] > 0


def test_earth_and_sun_meshes_are_traced(tmp_path, lam_dhg):
    # An oblate Earth mesh (flattening 0.2 along x, ⟂ to the Sun and the Moon at θ = 90°)
    # and a faceted Sun, both traced on their facets. Expected earthshine ratio: the far-field
    # Lambert phase integral ∫ max(0, n·s) max(0, n·v) dA of the ellipsoid over the sphere's,
    # 0.7615 by parametric quadrature (tests/independent.py, n = 300, converged to 1e-5).
    lam = {"lambert": lam_dhg["lambert"]}
    x, n, w = ind.ellipsoid_surface(0.8, 1.0, 1.0, n=300)
    xs, ns, ws = ind.ellipsoid_surface(1.0, 1.0, 1.0, n=300)
    far = lambda n, w: np.sum(np.clip(n @ [0, 0, -1.0], 0, None) * np.clip(n @ [0, 1.0, 0], 0, None) * w)
    expected = far(n, w) / far(ns, ws)
    Re = C.R_EARTH_M
    earth = _write(shapes.ellipsoid(0.8 * Re, Re, Re, level=5), tmp_path / "earth.ply")
    sphere = _write(shapes.ellipsoid(Re, Re, Re, level=5), tmp_path / "earth_s.ply")
    sun = _write(shapes.base_sphere(4).apply_scale(C.R_SUN_M), tmp_path / "sun.ply")
    kw = dict(moon_level=3, earth_order=24, occlusion=False)
    base = TraceScene(SceneGeometry(90.0), TraceSettings(**kw))
    ms0, es0 = trace_path(base, "moonshine", lam).mean, trace_path(base, "earthshine", lam).mean
    ts = TraceScene(SceneGeometry(90.0), TraceSettings(earth_mesh=earth, sun_mesh=sun, **kw))
    ms1, es1 = trace_path(ts, "moonshine", lam).mean, trace_path(ts, "earthshine", lam).mean
    es_s = trace_path(TraceScene(SceneGeometry(90.0), TraceSettings(earth_mesh=sphere, **kw)), "earthshine", lam).mean
    # a faceted Sun of level 4 (inscribed: projected-area deficit 0.4 %) within 1 %
    assert ms1["lambert"] == pytest.approx(ms0["lambert"], rel=1e-2)
    # beams over the bounding cone (order 24: silhouette and terminator resolved to ~0.3 %)
    assert es_s["lambert"] == pytest.approx(es0["lambert"], rel=5e-3)
    assert es1["lambert"] / es_s["lambert"] == pytest.approx(expected, rel=1e-2)
    assert ts.source_hits["earth"].sum() > 0 and ts.source_hits["sun"].sum() > 0


def test_out_of_range_face_index_is_one_line_error(tmp_path):
    """A PLY whose face names vertex 9 of 4 (trimesh reads it without complaint) is refused
    with one line naming the index, not an IndexError traceback."""
    path = tmp_path / "bad.ply"
    lines = ["ply", "format ascii 1.0", "element vertex 4", "property float x", "property float y",
             "property float z", "element face 4", "property list uchar int vertex_indices", "end_header",
             "0 0 0", "1.7e6 0 0", "0 1.7e6 0", "0 0 1.7e6", "3 0 2 1", "3 0 1 3", "3 0 3 2", "3 1 2 9"]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeshError, match="face index 9 out of range for 4 vertices"):
        load_user_mesh(path, "moon")
