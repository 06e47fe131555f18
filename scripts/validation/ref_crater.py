"""Independent moonshine reference (Sun -> Moon -> detector) for a Moon mesh, flat facets.

Only lunarviz.photometry.brdf.make_brdf(...).brdf and lunarviz.constants are used from lunarviz.

For every facet: K*K sub-triangle centroids (uniform barycentric subdivision), each with weight A/K^2.
Each sample P:
  * detector: o = unit(D - P), d = |D - P|, mu = n.o, cos(delta) = nd.(-o) (nd: detector normal,
    Earth centre -> Moon centre); visibility ray P + 1 m n -> D against the Moon mesh (Embree).
  * Sun: apparent disc of angular radius rho = asin(R_sun/|S - P|) about unit(S - P), quadrature
    Gauss-Legendre (nr nodes) in cos t on [cos rho, 1] x nphi uniform azimuths, each direction
    weighted with dOmega * L_sun, L_sun = PHI/(4 pi^2 R_sun^2); shadow ray P + 1 m n along omega_k.
  * E += (A/K^2) mu cos(delta)/d^2 * vis * sum_k BRDF(mu0_k, mu, g_k) max(mu0_k, 0) L_sun dOmega_k lit_k
Everything in float64 in a Moon-centred frame; rays in float32 in the same frame.
Variants: shadows+occlusion (full), no shadows at all, sun-shadow only, detector-occlusion only.
"""
import argparse
import json
import os as _os
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import trimesh
from embreex import rtcore_scene
from embreex.mesh_construction import TriangleMesh

#: where meshes and reference results go (``LUNARVIZ_VALIDATION_DIR``, default validation_out/)
OUT = _os.environ.get("LUNARVIZ_VALIDATION_DIR", "validation_out")
_os.makedirs(OUT, exist_ok=True)

from lunarviz import constants as C  # noqa: E402
from lunarviz.photometry.brdf import make_brdf  # noqa: E402

OFFSET_M = 1.0
L_SUN = C.PHI_SUN_W / (4 * np.pi**2 * C.R_SUN_M**2)
BRDFS = {"lambert": make_brdf("lambert"), "dhg": make_brdf("dhg")}
VARIANTS = ("full", "none", "sun_only", "det_only")


def sub_bary(K):
    """Barycentric (b1, b2) of the centroids of the K^2 congruent sub-triangles."""
    pts = []
    for i in range(K):
        for j in range(K - i):
            pts.append(((i + 1 / 3) / K, (j + 1 / 3) / K))  # upward
            if i + j <= K - 2:
                pts.append(((i + 2 / 3) / K, (j + 2 / 3) / K))  # downward
    b = np.array(pts)
    assert len(b) == K * K
    return b


class Ref:
    def __init__(self, mesh_path, theta_deg=120.0, threads=2):
        m = trimesh.load(mesh_path, process=False)
        self.V = np.asarray(m.vertices, dtype=np.float64)
        self.F = np.asarray(m.faces, dtype=np.int64)
        th = np.radians(theta_deg)
        self.moon = C.D_EM_M * np.array([0.0, np.sin(th), np.cos(th)])
        self.sun_r = np.array([0.0, 0.0, -C.D_SE_M]) - self.moon  # Moon-centred
        self.det_r = np.zeros(3) - self.moon
        self.nd = self.moon / np.linalg.norm(self.moon)  # detector normal (faces the Moon)
        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, self.V.astype(np.float32), self.F.astype(np.int32))
        T = self.V[self.F]
        cr = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
        self.area = 0.5 * np.linalg.norm(cr, axis=1)
        self.n = cr / (2 * self.area[:, None])
        self.T = T
        # candidate facets: can face the detector and some part of the solar disc (generous margins)
        cen = T.mean(axis=1)
        o = self.det_r - cen
        o /= np.linalg.norm(o, axis=1)[:, None]
        s = self.sun_r - cen
        s /= np.linalg.norm(s, axis=1)[:, None]
        mu = np.einsum("ij,ij->i", self.n, o)
        mu0c = np.einsum("ij,ij->i", self.n, s)
        self.cand = np.nonzero((mu > -1e-3) & (mu0c > -0.01))[0]
        self.threads = threads
        self.nrays = 0
        self.perfacet = None

    def occluded(self, org, dirs, tfar):
        r = self.scene.run(org.astype(np.float32), dirs.astype(np.float32), query="OCCLUDED",
                           dists=tfar.astype(np.float32))
        return np.asarray(r) != -1

    def chunk(self, fidx, bary, nr, nphi, nodes):
        K2 = len(bary)
        T = self.T[fidx]
        n = np.repeat(self.n[fidx], K2, axis=0)
        w = np.repeat(self.area[fidx] / K2, K2)
        b0 = 1 - bary[:, 0] - bary[:, 1]
        P = (T[:, None, 0] * b0[None, :, None] + T[:, None, 1] * bary[None, :, 0, None]
             + T[:, None, 2] * bary[None, :, 1, None]).reshape(-1, 3)
        # detector
        ov = self.det_r - P
        d = np.linalg.norm(ov, axis=1)
        o = ov / d[:, None]
        mu = np.einsum("ij,ij->i", n, o)
        keep = mu > 0
        P, n, w, o, d, mu = P[keep], n[keep], w[keep], o[keep], d[keep], mu[keep]
        cosdel = -(o @ self.nd)
        geo = w * mu * cosdel / d**2
        org = P + OFFSET_M * n
        vis = ~self.occluded(org, o, d)
        # sun disc quadrature
        sv = self.sun_r - P
        ds = np.linalg.norm(sv, axis=1)
        c = sv / ds[:, None]
        rho = np.arcsin(C.R_SUN_M / ds)
        h = 2 * np.sin(rho / 2) ** 2  # 1 - cos(rho)
        xi, wx = nodes
        q = h[:, None] * (1 - xi[None, :]) / 2  # 1 - cos t  (Ns, nr)
        sint = np.sqrt(q * (2 - q))
        cost = 1 - q
        dom = (h[:, None] * wx[None, :] / 2) * (2 * np.pi / nphi)  # (Ns, nr)
        phi = 2 * np.pi * (np.arange(nphi) + 0.5) / nphi
        # orthonormal frame about c
        tmp = np.where(np.abs(c[:, 0:1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
        a = np.cross(c, tmp)
        a /= np.linalg.norm(a, axis=1)[:, None]
        bb = np.cross(c, a)
        cp, sp = np.cos(phi), np.sin(phi)
        om = (cost[:, :, None, None] * c[:, None, None, :]
              + sint[:, :, None, None] * (cp[None, None, :, None] * a[:, None, None, :]
                                          + sp[None, None, :, None] * bb[:, None, None, :]))
        Ns = len(P)
        M = nr * nphi
        om = om.reshape(Ns, M, 3)
        dom = np.repeat(dom, nphi, axis=1)  # (Ns, M), order matches om (nr outer, nphi inner)
        mu0 = np.einsum("ikj,ij->ik", om, n)
        pos = mu0 > 0
        lit = np.zeros((Ns, M), bool)
        ii, kk = np.nonzero(pos)
        if len(ii):
            lit[ii, kk] = ~self.occluded(org[ii], om[ii, kk], np.full(len(ii), 1e12))
        self.nrays += Ns + len(ii)
        shg = np.linalg.norm(om - o[:, None, :], axis=2) / 2
        chg = np.linalg.norm(om + o[:, None, :], axis=2) / 2
        mu0c = np.where(pos, mu0, 0.0)
        out = {}
        for name, mdl in BRDFS.items():
            f = mdl.brdf(np.where(pos, mu0, 0.5), np.broadcast_to(mu[:, None], mu0.shape), shg, chg)
            rad = f * mu0c * dom * L_SUN  # (Ns, M) radiance contributions [W m^-2 sr^-1]
            L_all = rad.sum(axis=1)
            L_lit = np.where(lit, rad, 0.0).sum(axis=1)
            if self.perfacet is not None and name == "lambert":
                fid = np.repeat(fidx, K2)[keep]
                np.add.at(self.perfacet, (fid, 0), geo * vis * L_lit)
                np.add.at(self.perfacet, (fid, 1), geo * L_all)
                np.add.at(self.perfacet, (fid, 2), lit.mean(axis=1) * 1.0)
                np.add.at(self.perfacet, (fid, 3), np.ones(len(fid)))
            out[name] = {
                "full": np.sum(geo * vis * L_lit),
                "none": np.sum(geo * L_all),
                "sun_only": np.sum(geo * L_lit),
                "det_only": np.sum(geo * vis * L_all),
            }
        return out

    def compute(self, K, nr, nphi, max_elems=3_000_000):
        bary = sub_bary(K)
        xi, wx = np.polynomial.legendre.leggauss(nr)
        nodes = (xi, wx)
        per = max(1, max_elems // (K * K * nr * nphi))
        chunks = [self.cand[i:i + per] for i in range(0, len(self.cand), per)]
        self.nrays = 0
        t0 = time.time()
        with ThreadPoolExecutor(self.threads) as ex:
            res = list(ex.map(lambda f: self.chunk(f, bary, nr, nphi, nodes), chunks))
        tot = {b: {v: float(sum(r[b][v] for r in res)) for v in VARIANTS} for b in BRDFS}
        return tot, time.time() - t0, self.nrays


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mesh", default=OUT + "/crater_moon.ply")
    ap.add_argument("--configs", default="4:2x8")  # K:nrxnphi,...
    ap.add_argument("--out", default=OUT + "/ref_crater.json")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--perfacet", default="")
    a = ap.parse_args()
    ref = Ref(a.mesh, threads=a.threads)
    print(f"facets {len(ref.F)}, candidates {len(ref.cand)}, L_sun {L_SUN:.6e}")
    rows = []
    if a.perfacet:
        ref.perfacet = np.zeros((len(ref.F), 4))
        ref.threads = 1  # np.add.at on a shared array: keep it single-threaded
    for cfg in a.configs.split(","):
        K, rule = cfg.split(":")
        nr, nphi = (int(x) for x in rule.split("x"))
        tot, dt, nrays = ref.compute(int(K), nr, nphi)
        rows.append({"K": int(K), "nr": nr, "nphi": nphi, "M": nr * nphi, "time_s": dt,
                     "rays": nrays, "E": tot})
        print(f"K={K:>2} M={nr*nphi:>3} ({nr}x{nphi}) {dt:7.1f}s {nrays/1e6:7.1f}M rays  "
              + "  ".join(f"{b}: full {tot[b]['full']:.9e} none {tot[b]['none']:.9e}"
                          f" sun {tot[b]['sun_only']:.9e} det {tot[b]['det_only']:.9e}" for b in tot),
              flush=True)
        json.dump(rows, open(a.out, "w"), indent=1)
    if a.perfacet:
        np.save(a.perfacet, ref.perfacet)


if __name__ == "__main__":
    main()
