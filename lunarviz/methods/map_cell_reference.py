"""An independent reference for the earthlight of a mapped Lambert Earth: the map's own cells.

The ray tracer sums a mapped Earth per facet of its mesh (each facet's area-averaged map value,
:mod:`lunarviz.methods.tracer.mapped_earth`) and gathers the facets into cells of the Earth's disc
seen from the Moon, one beam each. Its error has no closed form (the map's coastlines and cloud
bands cross the facets), so its error model is measured against this reference, which shares
neither the mesh, nor the facet averages, nor the disc's cells:

* the sphere is cut along the **map's own grid** (rows of latitude from +90°, columns of longitude
  from -180°: :func:`lunarviz.surfaces.maps.sample_map`'s cells), where the map is one value a
  cell (a cloud table's latitudes enter linearly: exact for the Gauss points below);
* each cell lit by the Sun and facing the Moon gets ``W_p = ∫_cell v_p(y) L₁(y) dA`` for every map
  ``v_p`` asked for (an Earth of albedo 1, the albedo map, or its components), with
  ``L₁ = E_sun μ_s / π`` the radiance of a white Lambert Earth under a point Sun, by a
  ``sub`` × ``sub`` Gauss rule in (sin lat, lon) (the exact area element);
* each lunar point x receives from a cell ``W_p cos_y(x) / r²`` along the direction of the cell's
  L₁-weighted centre (zero where the cell is behind the Earth's limb or below x's horizon).

The centre rule errs by the second moment of each cell (0.1° on the land mask: 11 km, 3e-5 rad
seen from the Moon) times the curvature of the lunar BRDF and of ``cos_y / r²``; the cells that
the limb, x's horizon or the zero-phase cusp cross hold a small share of the light (docs:
accuracy, "A mapped Earth"). Checked against the exact Lambert-sphere rule of the reference for an
Earth of albedo 1 (``tests/test_mapped_earth_model.py``). Neglected, as in the tracer: the Sun's
extent lighting the Earth, the Moon's shadow on it (dates without an eclipse), the Earth's
oblateness.
"""

from __future__ import annotations

import numpy as np

from lunarviz.geometry.scene_geometry import SceneGeometry, half_angle_sin_cos
from lunarviz.geometry.sphere_quadrature import gauss_legendre

#: cells a chunk (memory: a chunk holds (lunar points × cells) arrays)
CELL_CHUNK = 1 << 14


def earth_cells(scene: SceneGeometry, values_at, shape: tuple[int, int], frame: np.ndarray, sub: int = 2,
                group: int = 1, split: int = 2, rows_chunk: int = 60):
    """The map grid's cells that the Sun lights and that face the Moon: unit centres (C, 3) in the
    scene frame (each cell's L₁-weighted centre, on the sphere) and weights (C, P) [W sr⁻¹]:
    ``∫_cell v_p L₁ dA`` for ``values_at(dirs)`` → (n, P) at map-frame directions, ``L₁`` the
    radiance of a white Lambert Earth lit by a point Sun (:func:`earth_radiance` of albedo 1).
    ``group``: ``group`` × ``group`` map cells a reference cell (their weights exact, summed; one
    centre: a coarser centre rule, for maps finer than the reference needs). Cells near the
    terminator (where L₁ kinks) or near the Earth's limb seen from some lunar point (where
    ``cos_y`` does) are split ``split`` × ``split`` ways instead, each part its own centre: there
    the centre rule errs most (a thin crescent lies along both)."""
    if rows_chunk % group:
        raise ValueError(f"rows_chunk {rows_chunk} is not a multiple of group {group}")
    h, w = shape
    R = scene.radii["earth"]
    s_hat = (scene.sun - scene.earth) / np.linalg.norm(scene.sun - scene.earth)
    d_moon = np.linalg.norm(scene.moon - scene.earth)
    m_hat = (scene.moon - scene.earth) / d_moon
    lat_edges = np.radians(90.0 - 180.0 * np.arange(h + 1) / h)
    lon_edges = np.radians(-180.0 + 360.0 * np.arange(w + 1) / w)
    cell = 2.0 * np.pi / min(h, w / 2)  # a cell's size [rad], at most
    # the limb seen from any lunar point: m·û within R_M/D of R/D (m·(x - y) = 0 for some x)
    limb, limb_band = R / d_moon, scene.radii["moon"] / d_moon
    centres, weights = [], []
    for r0 in range(0, h, rows_chunk):
        rs = np.arange(r0, min(h, r0 + rows_chunk))
        cl = 0.5 * (lat_edges[rs] + lat_edges[rs + 1])
        cc = 0.5 * (lon_edges[:-1] + lon_edges[1:])
        cdir = np.stack(np.broadcast_arrays(np.cos(cl)[:, None] * np.cos(cc)[None, :],
                                            np.cos(cl)[:, None] * np.sin(cc)[None, :],
                                            np.sin(cl)[:, None] + 0 * cc[None, :]), -1) @ frame.T
        mu_s, mu_m = cdir @ s_hat, cdir @ m_hat
        # within a margin of lit and of facing some lunar point (the exact tests follow, per point)
        keep = (mu_s > -2 * cell) & (mu_m > limb - limb_band - 2 * cell)
        edge = keep & ((np.abs(mu_s) < group * cell) | (np.abs(mu_m - limb) < limb_band + group * cell))
        for cells, q in ((keep & ~edge, 1), (edge, split)):
            ri, ci = np.nonzero(cells)
            if ri.size == 0:
                continue
            d, a, v = _cell_parts(scene, values_at, frame, np.sin(lat_edges[r0 + ri + 1]), np.sin(lat_edges[r0 + ri]),
                                  lon_edges[ci], lon_edges[ci + 1], q, sub)
            wsum = a.sum(1)
            cen = np.einsum("ck,ckj->cj", a, d)
            vw = np.einsum("ck,ckp->cp", a, v)
            if q == 1 and group > 1:  # the map cells of each reference cell, summed
                _, inv = np.unique((ri // group) * (w // group + 1) + ci // group, return_inverse=True)
                wsum = np.bincount(inv, wsum)
                cen = np.stack([np.bincount(inv, cen[:, j]) for j in range(3)], 1)
                vw = np.stack([np.bincount(inv, vw[:, j]) for j in range(vw.shape[1])], 1)
            lit = wsum > 0
            centres.append(cen[lit] / np.linalg.norm(cen[lit], axis=1)[:, None])
            weights.append(vw[lit])
    if not centres:
        return np.zeros((0, 3)), np.zeros((0, 1))
    return np.concatenate(centres), np.concatenate(weights)


def _cell_parts(scene, values_at, frame, s_lo, s_hi, lon_lo, lon_hi, q: int, sub: int):
    """Each cell (sin-lat and longitude edges, (E,) each) split q × q ways, each part with a
    ``sub`` × ``sub`` Gauss rule in (sin lat, lon): unit points (E·q², sub², 3) in the scene frame,
    ``L₁ dA`` there (E·q², sub²) [W sr⁻¹] and the maps' values (E·q², sub², P)."""
    g, gw = gauss_legendre(sub)  # (nodes and weights on [0, 1])
    t = ((np.arange(q)[:, None] + g[None, :]) / q).reshape(-1)  # (q·sub,) composite nodes
    tw = np.tile(gw / q, q)
    E = len(s_lo)
    sin_l = s_lo[:, None] + (s_hi - s_lo)[:, None] * t[None, :]  # (E, q·sub)
    sw = (s_hi - s_lo)[:, None] * tw[None, :]
    lon = lon_lo[:, None] + (lon_hi - lon_lo)[:, None] * t[None, :]
    lw = (lon_hi - lon_lo)[:, None] * tw[None, :]
    # (E, q, sub, q, sub) → parts (E, q, q) × points (sub, sub)
    S = sin_l.reshape(E, q, sub)[:, :, :, None, None] * np.ones((1, 1, 1, q, sub))
    Lo = lon.reshape(E, q, sub)[:, None, None, :, :] * np.ones((1, q, sub, 1, 1))
    W = sw.reshape(E, q, sub)[:, :, :, None, None] * lw.reshape(E, q, sub)[:, None, None, :, :]
    order = (0, 1, 3, 2, 4)
    S, Lo, W = (a.transpose(order).reshape(E * q * q, sub * sub) for a in (S, Lo, W))
    cos_l = np.sqrt(np.clip(1.0 - S**2, 0.0, None))
    dmap = np.stack([cos_l * np.cos(Lo), cos_l * np.sin(Lo), S], -1).reshape(-1, 3)
    d = dmap @ frame.T
    R = scene.radii["earth"]
    vs = scene.sun - (scene.earth + R * d)
    ds = np.linalg.norm(vs, axis=1)
    mu_s = np.clip(np.einsum("ij,ij->i", d, vs) / ds, 0.0, None)
    L1 = (scene.phi / (4 * np.pi * ds**2)) * mu_s / np.pi
    v = np.asarray(values_at(dmap), dtype=float).reshape(len(d), -1)
    n = E * q * q
    return d.reshape(n, sub * sub, 3), (L1 * W.reshape(-1) * R * R).reshape(n, sub * sub), \
        v.reshape(n, sub * sub, -1)


def cell_radiances(scene: SceneGeometry, x, n, o, mu, centres, weights, brdfs: dict, chunk: int = CELL_CHUNK) -> dict:
    """``{brdf: (B, P)}``: the radiance toward the detector [W m⁻² sr⁻¹] at lunar points x (B, 3)
    with normals n, unit directions o to the detector and cosines of emission ``mu`` (B,), from
    every cell of :func:`earth_cells`
    (centres (C, 3), weights (C, P)), for each of its P maps."""
    R = scene.radii["earth"]
    B, P = len(x), weights.shape[1]
    out = {k: np.zeros((B, P)) for k in brdfs}
    for a in range(0, len(centres), chunk):
        m = centres[a:a + chunk]
        y = scene.earth + R * m
        v = y[None, :, :] - x[:, None, :]  # lunar point → cell
        r2 = np.einsum("bkj,bkj->bk", v, v)
        r = np.sqrt(r2)
        om = v / r[..., None]
        cos_y = np.clip(-np.einsum("bkj,kj->bk", om, m), 0.0, None)
        mu0 = np.einsum("bkj,bj->bk", om, n)
        f = np.where(mu0 > 0.0, cos_y / r2, 0.0)  # (x's horizon: the cell's direction above it)
        sh, ch = half_angle_sin_cos(om, o[:, None, :])
        mu0 = np.clip(mu0, 0.0, 1.0)
        wp = weights[a:a + chunk]
        for k, b in brdfs.items():  # (the BRDF once a beam, every map from it)
            rf = b.radiance_factor(mu0, mu[:, None], sh, ch)
            out[k] += (rf * f) @ wp
    return out


def exact_unit_earthshine(scene: SceneGeometry, x, n, o, mu, geom, brdfs: dict, order: int = 24) -> dict:
    """``{brdf: Σ_points geom · L}`` for an Earth of albedo 1 at lunar points x (normals n, unit
    vectors o toward the detector, μ, ``geom`` their weights toward it): the exact reference's
    product rule about the zero-phase point, cut along the kinks
    (:func:`lunarviz.methods.sources.source_sphere_rule`; its own tests: the closed-form area of
    two caps). What this module's cells are checked against: their own error for an Earth of
    albedo 1."""
    from lunarviz.methods.sources import earth_radiance, source_beams, source_sphere_rule, zero_phase_points
    from lunarviz.methods.transport import Transport
    pole = zero_phase_points(scene, x)
    out = dict.fromkeys(brdfs, 0.0)
    for a in range(0, len(x), 8):
        sl = slice(a, a + 8)
        m, w = source_sphere_rule(scene, x[sl], n[sl], "earth", order, pole=pole[sl], roughness_cuts=True)
        y, om, omega = source_beams(scene, x[sl], "earth", m, w)
        sh, ch = half_angle_sin_cos(om, o[sl][:, None, :])
        tr = Transport(mu0=np.clip(np.einsum("bmj,bj->bm", om, n[sl]), 0, 1), sin_hg=sh, cos_hg=ch,
                       e_beam=earth_radiance(scene, y, m, 1.0) * omega, mu=mu[sl], geom=geom[sl])
        for k, b in brdfs.items():
            out[k] += float(tr.radiances(b)[0] @ geom[sl])
    return out
