"""Cratered Moon mesh for the θ = 120° moonshine test (independent of lunarviz, constants only).

Icosphere (subdivisions=7) of radius R_MOON, vertices displaced radially inward inside
N non-overlapping paraboloid bowl craters placed along the terminator, on the Earth-visible side.
Writes validation_out/crater_moon.ply (binary little-endian, float64 vertices) and
validation_out/craters.json (crater list).
"""
import json
import os as _os
import sys

import numpy as np
import trimesh

#: where meshes and reference results go (``LUNARVIZ_VALIDATION_DIR``, default validation_out/)
OUT = _os.environ.get("LUNARVIZ_VALIDATION_DIR", "validation_out")
_os.makedirs(OUT, exist_ok=True)

from lunarviz import constants as C  # noqa: E402

R = C.R_MOON_M
THETA = np.radians(120.0)
N_CRATERS = 40
SEED = 12345


def scene_dirs(theta=THETA):
    moon = C.D_EM_M * np.array([0.0, np.sin(theta), np.cos(theta)])
    sun = np.array([0.0, 0.0, -C.D_SE_M])
    s = (sun - moon) / np.linalg.norm(sun - moon)  # Moon -> Sun
    e = -moon / np.linalg.norm(moon)  # Moon -> Earth
    u = e - (e @ s) * s
    u /= np.linalg.norm(u)  # terminator point nearest the sub-Earth point
    v = np.cross(s, u)
    return s, e, u, v


def place_craters(rng):
    s, e, u, v = scene_dirs()
    craters = []
    tries = 0
    while len(craters) < N_CRATERS:
        tries += 1
        if tries > 200000:
            raise RuntimeError("could not place craters")
        phi = np.radians(rng.uniform(-65.0, 65.0))  # along the terminator
        psi = np.radians(rng.uniform(-5.0, 10.0))  # off the terminator (+: lit side)
        r = rng.uniform(30e3, 120e3)
        c = np.cos(psi) * (np.cos(phi) * u + np.sin(phi) * v) + np.sin(psi) * s
        c /= np.linalg.norm(c)
        if c @ e < 0.25:  # keep well inside the visible disc
            continue
        ok = all(R * np.arccos(np.clip(c @ cc, -1, 1)) > r + rr + 10e3 for cc, rr, _ in craters)
        if ok:
            craters.append((c, r, 0.2 * 2 * r))
    return craters


def write_ply_f64(path, V, F):
    V = np.ascontiguousarray(V, dtype="<f8")
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(V)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode()
    fdt = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    fa = np.empty(len(F), dtype=fdt)
    fa["n"] = 3
    fa["i"] = F
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(V.tobytes())
        fh.write(fa.tobytes())


def main():
    rng = np.random.default_rng(SEED)
    craters = place_craters(rng)
    ico = trimesh.creation.icosphere(subdivisions=7, radius=1.0)
    dirs = ico.vertices / np.linalg.norm(ico.vertices, axis=1)[:, None]
    radius = np.full(len(dirs), R)
    hit = np.zeros(len(dirs), int)
    for c, r, depth in craters:
        rho = R * np.arccos(np.clip(dirs @ c, -1.0, 1.0))
        inside = rho < r
        hit += inside
        radius[inside] -= depth * (1.0 - (rho[inside] / r) ** 2)
    assert hit.max() <= 1
    V = dirs * radius[:, None]
    F = ico.faces.astype(np.int32)
    out = OUT + "/crater_moon.ply"
    write_ply_f64(out, V, F)

    m = trimesh.load(out, process=False)
    print("faces", len(m.faces), "vertices", len(m.vertices), "dtype", m.vertices.dtype)
    print("max |V_loaded - V|", np.abs(m.vertices - V).max())
    print("watertight", m.is_watertight, "winding consistent", m.is_winding_consistent,
          "volume", m.volume, "sphere volume", 4 / 3 * np.pi * R**3)
    fn = m.face_normals
    print("outward facet normals (n.centroid>0):", np.all(np.einsum("ij,ij->i", fn, m.triangles_center) > 0))
    print("vertices inside craters", int(hit.sum()))
    s, e, u, v = scene_dirs()
    rows = []
    for c, r, depth in craters:
        rows.append({"centre_unit": c.tolist(), "r_m": r, "depth_m": depth,
                     "sun_elev_deg": float(np.degrees(np.arcsin(c @ s))),
                     "earth_angle_deg": float(np.degrees(np.arccos(c @ e)))})
    json.dump(rows, open(OUT + "/craters.json", "w"), indent=1)
    el = np.array([x["sun_elev_deg"] for x in rows])
    rr = np.array([x["r_m"] for x in rows])
    print(f"craters: {len(rows)}, r {rr.min()/1e3:.0f}-{rr.max()/1e3:.0f} km, sun elevation of centres "
          f"{el.min():.1f}..{el.max():.1f} deg, {np.sum(el < 0)} centres on the night side")
    print("phase angle (Sun-Moon-Earth) deg:", np.degrees(np.arccos(s @ e)))


if __name__ == "__main__":
    main()
