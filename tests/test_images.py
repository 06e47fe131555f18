"""Synthetic images: consistency with the transport, geometry, files, optics.

Expected values: the sweep's ray-traced irradiance (the image must integrate to it: the same
physics sampled per pixel), the lit fraction of a sphere's disc (1 + cos α)/2 (closed form),
and the Moon's RA/Dec from NAIF's SPICE (tests/sky_reference.py).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import sky_reference as ref

from lunarviz.methods.camera import Camera
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.sweeps import run_phase
from lunarviz.workflows.tasks import image as synthesize


@pytest.mark.slow
@pytest.mark.parametrize("theta", [30.0, 90.0, 150.0])
def test_image_integrates_to_the_sweep(theta):
    # bar 2e-3 at 256 px with the default 4 × 4 supersampling; measured ≤ 4e-4
    # (moonshine: the limb's sub-pixel sampling; earthshine: linear interpolation between the
    # vertices where the transport is evaluated)
    s = ResolvedScene(brdfs=("lambert", "dhg"), method="raytrace", phases_deg=(theta,))
    rows = {r["brdf"]: r for r in run_phase(s, theta)}
    im = synthesize(s, theta, Camera(width=256, height=256))
    for b in ("lambert", "dhg"):
        assert im.integrated("moonshine", b) == pytest.approx(rows[b]["moonshine_W_m2"], rel=2e-3)
        assert im.integrated("earthshine", b) == pytest.approx(rows[b]["earthshine_W_m2"], rel=2e-3)
    # the sunlit share of the disc: (1 + cos α)/2 for a sphere; bar 1 % (sub-pixel counting
    # at the terminator and the limb)
    assert im.lit_fraction == pytest.approx((1 + np.cos(np.radians(im.info["alpha_deg"]))) / 2, rel=1e-2)


def test_image_is_traced_by_embree(monkeypatch):
    # no hits from Embree: no Moon in the picture
    from lunarviz.methods.tracer.embree_bodies import EmbreeBody
    s = ResolvedScene(brdfs=("lambert",), method="raytrace", phases_deg=(90.0,), moon_level=2)
    cam = Camera(width=32, height=32, supersample=1)
    assert synthesize(s, 90.0, cam).integrated("moonshine", "lambert") > 0
    monkeypatch.setattr(EmbreeBody, "run_rays", lambda self, o32, d32, query, dists=None, scene=None:
                        np.full(len(o32), -1, dtype=np.int32))
    assert synthesize(s, 90.0, cam).integrated("moonshine", "lambert") == 0.0


def _cli(tmp_path, *args):
    return subprocess.run([sys.executable, "-m", "lunarviz.cli", "image", *args], capture_output=True, text=True,
                          cwd=tmp_path)


def test_fits_wcs_points_at_the_moon(tmp_path):
    from astropy.io import fits
    from astropy.wcs import WCS
    iso = "2026-06-09T00:00:00Z"
    out = tmp_path / "m.fits"
    r = _cli(tmp_path, "--time", iso, "--brdf", "dhg", "--pixels", "96", "--supersample", "1", "--mesh-level", "3",
             "--out", str(out))
    assert r.returncode == 0, r.stderr
    g = ref.geometry(iso)
    v = g["moon"] / np.linalg.norm(g["moon"])
    ra, dec = np.degrees(np.arctan2(v[1], v[0])) % 360, np.degrees(np.arcsin(v[2]))
    with fits.open(out) as hd:
        assert [h.name for h in hd[1:]] == ["MOONSHINE", "EARTHSHINE"]
        assert hd["MOONSHINE"].header["BUNIT"] == "W m-2 sr-1"
        img = hd["MOONSHINE"].data + hd["EARTHSHINE"].data
        w = WCS(hd["MOONSHINE"].header)
        px, py = w.world_to_pixel_values(ra, dec)
    rows, cols = np.nonzero(img > 0)  # the whole disc: sunlit or earthlit
    cx, cy = (cols.min() + cols.max()) / 2, (rows.min() + rows.max()) / 2
    assert abs(px - cx) < 1.0 and abs(py - cy) < 1.0


def test_psf_conserves_flux(tmp_path):
    from lunarviz.instrument.optics import apply_optics, parse_psf
    s = ResolvedScene(brdfs=("dhg",), method="raytrace", phases_deg=(60.0,), moon_level=3)
    im = synthesize(s, 60.0, Camera(width=128, height=128, supersample=2, fov_deg=1.2))
    plane = im.planes["moonshine"]["dhg"]
    psf = parse_psf("gaussian:20", 1.2 * 3600 / 128, plane.shape)
    blurred = apply_optics(plane, psf, None)
    # a 1.2° frame around a 0.5° Moon: the 20″ Gaussian keeps all light inside (bar 1e-3)
    assert blurred.sum() == pytest.approx(plane.sum(), rel=1e-3)
    assert blurred.max() < plane.max()


@pytest.mark.parametrize("args, word", [
    (["--pixels", "0"], "--pixels"),
    (["--fov-deg", "0"], "--fov-deg"),
    (["--fov-deg", "180"], "--fov-deg"),
    (["--psf", "bad.npy"], "bad.npy"),
    (["--psf", "gaussian:-3"], "FWHM"),
    (["--supersample", "0"], "--supersample"),
    (["--pointing", "10,95"], "declination"),
    (["--halo", "2,3"], "FRACTION"),
    (["--psf", "str.npy"], "str.npy"),
    (["--pixels", "4096", "--supersample", "16"], "rays"),
    (["--gif", "one.gif"], "--gif"),
])
def test_bad_camera_settings_are_one_line(tmp_path, args, word):
    np.save(tmp_path / "bad.npy", np.ones((4, 4)))
    np.save(tmp_path / "str.npy", np.array([["a", "b", "c"]] * 3))
    out = tmp_path / "x.fits"
    r = _cli(tmp_path, "--phase", "90", "--mesh-level", "2", *args, "--out", str(out))
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and word in lines[0], r.stderr
    assert not out.exists()


def test_npy_png_and_frames(tmp_path):
    r = _cli(tmp_path, "--phase", "60,120", "--brdf", "lambert,dhg", "--pixels", "48", "--supersample", "1",
             "--mesh-level", "2", "--out", str(tmp_path / "f.npy"))
    assert r.returncode == 0, r.stderr
    a = np.load(tmp_path / "f_000.npy")
    assert a.shape == (4, 48, 48)
    r = _cli(tmp_path, "--phase", "60", "--pixels", "48", "--supersample", "1", "--mesh-level", "2",
             "--out", str(tmp_path / "f.png"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "f.png").stat().st_size > 0
    meta = json.loads((tmp_path / "f.png.json").read_text()) if (tmp_path / "f.png.json").exists() else {}
    assert isinstance(meta, dict)
