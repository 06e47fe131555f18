"""Write lunarviz/data/synthetic_moon_albedo.npy from lunarviz/data/synthetic_maria.csv.

A synthetic, low-order lunar albedo pattern for tests and demos (no lunar map ships with the
packages lunarviz may use; README "Surfaces" says how to bring a real one): 1 on highlands,
0.5 in maria (spherical caps listed in the CSV), cosine edges 1° wide. 180 × 360 cells (1°),
float32, equirectangular in MOON_ME (row 0 at +90°, column 0 at −180°, cells centred).

    python scripts/make_synthetic_moon_map.py
"""

from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[1] / "lunarviz" / "data"
MARE, HIGHLAND, EDGE_DEG = 0.5, 1.0, 1.0


def synthetic_map(rows: int = 180) -> np.ndarray:
    lines = [ln for ln in (DATA / "synthetic_maria.csv").read_text().splitlines() if ln and not ln.startswith("#")]
    caps = [(float(a), float(b), float(c)) for _, a, b, c in (ln.split(",") for ln in lines[1:])]
    lat = np.radians(90.0 - (np.arange(rows) + 0.5) * 180.0 / rows)[:, None]
    lon = np.radians(-180.0 + (np.arange(2 * rows) + 0.5) * 180.0 / rows)[None, :]
    d = np.stack(np.broadcast_arrays(np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)), -1)
    mare = np.zeros(d.shape[:2])
    for la, lo, r in caps:
        la, lo = np.radians(la), np.radians(lo)
        c = np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])
        dist = np.degrees(np.arccos(np.clip(d @ c, -1, 1)))
        s = np.clip((r + EDGE_DEG / 2 - dist) / EDGE_DEG, 0, 1)  # 1 inside, cosine ramp over the edge
        mare = np.maximum(mare, 0.5 - 0.5 * np.cos(np.pi * s))
    return (HIGHLAND + (MARE - HIGHLAND) * mare).astype(np.float32)


if __name__ == "__main__":
    m = synthetic_map()
    np.save(DATA / "synthetic_moon_albedo.npy", m)
    w = np.cos(np.radians(90.0 - (np.arange(m.shape[0]) + 0.5)))[:, None]
    mean = (m * w).sum() / (w.sum() * m.shape[1])
    print(f"wrote {DATA / 'synthetic_moon_albedo.npy'}: {m.shape}, area-weighted mean {mean:.4f}")
