"""Where the files that ship inside the package live (data tables, maps, packaged meshes), and
the reader of their two-column spectral tables (also a user's solar spectrum or band)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError

#: the package's data folder: presets, maps, cloud tables, and ``meshes/`` with its manifest
DATA_DIR = Path(__file__).resolve().parent / "data"
#: packaged icosphere meshes and their ``manifest.json`` (sha256 of each file)
MESH_DIR = DATA_DIR / "meshes"
#: a table may hold at most this many rows (a 1 nm table of 200-10,000 nm has 9,800)
MAX_ROWS = 200_000
#: a table's largest value must lie in [TINY_VALUE, 1/TINY_VALUE]: a response of 1e-315 (a
#: subnormal float) loses digits in the band sums, then underflows to 0
TINY_VALUE = 1e-30


def read_table(path, what: str = "solar spectrum", max_rows: int = MAX_ROWS) -> tuple[np.ndarray, np.ndarray, str]:
    """Two columns of a CSV file (``#`` comments, one header line), checked: finite, wavelengths
    increasing and positive, values non-negative; returns them and the comment lines."""
    p = Path(path)
    if not p.is_file():
        raise LunarvizError(f"{what} {str(path)!r} is not a file")
    if p.suffix.lower() not in (".csv", ".txt"):
        raise LunarvizError(f"{what} {str(path)!r}: expected a .csv file (wavelength_nm, value)")
    if p.stat().st_size > 64 * max_rows:
        raise LunarvizError(f"{what} {str(path)!r} is too large ({p.stat().st_size} bytes)")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LunarvizError(f"cannot read {what} {str(path)!r}: {exc}") from None
    notes, rows = [], []
    for n, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            notes.append(s.lstrip("# "))
            continue
        parts = [x.strip() for x in s.split(",")]
        try:
            row = (float(parts[0]), float(parts[1]))
        except (ValueError, IndexError):
            if rows or len(parts) < 2:  # one header line, before the numbers
                raise LunarvizError(f"{what} {str(path)!r} line {n}: expected two numbers, got {s[:60]!r}") from None
            continue
        if len(parts) != 2:
            raise LunarvizError(f"{what} {str(path)!r} line {n}: expected two columns (wavelength_nm, value), got "
                                f"{len(parts)}")
        rows.append(row)
    if len(rows) < 2:
        raise LunarvizError(f"{what} {str(path)!r} has fewer than two rows of numbers")
    a = np.array(rows)
    lam, val = a[:, 0], a[:, 1]
    if not np.all(np.isfinite(a)):
        raise LunarvizError(f"{what} {str(path)!r} has a value that is not finite")
    if lam[0] <= 0 or np.any(np.diff(lam) <= 0):
        raise LunarvizError(f"{what} {str(path)!r}: wavelengths must be positive and increasing")
    if np.any(val < 0):
        raise LunarvizError(f"{what} {str(path)!r} has a negative value ({val[val < 0][0]:g})")
    if 0 < val.max() < TINY_VALUE or val.max() > 1 / TINY_VALUE:
        raise LunarvizError(f"{what} {str(path)!r}: its largest value {val.max():g} is outside [{TINY_VALUE:g}, "
                            f"{1 / TINY_VALUE:g}], where products and sums of it lose digits: scale the column")
    return lam, val, " ".join(notes)
