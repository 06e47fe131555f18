"""Earthshine-side contrast with and without scattered light, kept in benchmarks/images/.

    python scripts/image_contrast.py

At θ = 120° (DHG, 256 px over 0.75°, default supersampling) the image is made once; the
earthshine side is measured in a 9 × 9-pixel box centred 80 % of the way from the disc's
centre to its dark limb. Reported: the true earthshine there, and the moonshine that a
Gaussian core (FWHM 2″: a good telescope) and power-law halos ((1 + (r/1″)²)^(-INDEX/2) wings
carrying 1 % or 5 % of the light, INDEX 3 or 2) throw onto it, as a fraction of the earthshine.
Pictures (one stretch for all): ``theta120.png`` (no optics), ``theta120_halo1pc.png`` and
``theta120_halo.png`` (2″ core with a 1 % or 5 % r^-2 halo).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from lunarviz.methods.camera import Camera
from lunarviz.instrument.optics import apply_optics, parse_halo, parse_psf
from lunarviz.outputs.images import write_png
from lunarviz.scene import ResolvedScene
from lunarviz.workflows.tasks import image as synthesize

OUT = Path(__file__).resolve().parent.parent / "benchmarks" / "images"


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    theta = 120.0
    cam = Camera(width=256, height=256)
    s = ResolvedScene(brdfs=("dhg",), method="raytrace", phases_deg=(theta,))
    im = synthesize(s, theta, cam)
    ms, es = im.planes["moonshine"]["dhg"], im.planes["earthshine"]["dhg"]
    disc = (ms + es) > 0
    rows, cols = np.nonzero(disc)
    cy, cx = (rows.min() + rows.max()) / 2, (cols.min() + cols.max()) / 2
    r = (cols.max() - cols.min()) / 2
    # the dark side: opposite the sunlit centroid
    lit = ms > 0
    ly, lx = np.mean(np.nonzero(lit), axis=1)
    u = np.array([cy - ly, cx - lx])
    u /= np.linalg.norm(u)
    py, px = int(round(cy + 0.8 * r * u[0])), int(round(cx + 0.8 * r * u[1]))
    box = (slice(py - 4, py + 5), slice(px - 4, px + 5))
    true_es = float(es[box].mean())
    assert float(ms[box].max()) == 0.0, "the box must lie on the earthshine side"
    pix_arcsec = float(np.degrees(cam.scale_rad)) * 3600
    tot = ms + es  # one stretch for every picture (the no-optics image's): their halos compare by eye
    stretch = (float(np.percentile(tot[tot > 0], 5)), float(tot.max()))
    pictures = {"0.05,2,1": ("theta120_halo.png", "2″ Gaussian + 5 % r^-2 halo"),
                "0.01,2,1": ("theta120_halo1pc.png", "2″ Gaussian + 1 % r^-2 halo")}
    rows_out = []
    for label, psf, halo in (("no optics", None, None), ("Gaussian 2″", "gaussian:2", None),
                             ("Gaussian 2″ + 1 % halo r^-3", "gaussian:2", "0.01,3,1"),
                             ("Gaussian 2″ + 1 % halo r^-2", "gaussian:2", "0.01,2,1"),
                             ("Gaussian 2″ + 5 % halo r^-2", "gaussian:2", "0.05,2,1")):
        kp = parse_psf(psf, pix_arcsec, ms.shape)
        kh = parse_halo(halo, pix_arcsec, ms.shape)
        obs = apply_optics(ms, kp, kh) + apply_optics(es, kp, kh)
        rows_out.append({"optics": label, "psf": psf, "halo": halo,
                         "observed_over_true_earthshine": float(obs[box].mean()) / true_es,
                         "scattered_moonshine_over_earthshine": float(apply_optics(ms, kp, kh)[box].mean()) / true_es})
        if halo in pictures:
            name, words = pictures[halo]
            planes = {"moonshine": {"dhg": apply_optics(ms, kp, kh)}, "earthshine": {"dhg": apply_optics(es, kp, kh)}}
            write_png(OUT / name, im, planes, title=f"θ = 120°, DHG, {words}", stretch=stretch)
    write_png(OUT / "theta120.png", im, im.planes, title="θ = 120°, DHG, no optics", stretch=stretch)
    res = {"theta_deg": theta, "alpha_deg": im.info["alpha_deg"], "box_centre_px": [px, py], "box_px": 9,
           "true_earthshine_W_m2_sr": true_es, "rows": rows_out}
    (OUT / "contrast.json").write_text(json.dumps(res, indent=2) + "\n")
    for q in rows_out:
        print(f"{q['optics']:30s} observed/true earthshine {q['observed_over_true_earthshine']:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
