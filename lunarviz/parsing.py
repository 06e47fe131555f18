"""Parsing of number lists shared by the command line and the Python API."""

from __future__ import annotations

import math

from lunarviz.errors import LunarvizError


def parse_float_list(text: str, name: str, lo: float | None = None, hi: float | None = None) -> list[float]:
    """``a,b,c`` and/or ``start:stop[:step]`` (stop inclusive, step 1 by default) → floats,
    each checked in [lo, hi]."""
    out: list[float] = []
    if text is None or not str(text).strip():
        raise LunarvizError(f"empty {name} list")
    for part in str(text).split(","):
        part = part.strip()
        try:
            if ":" in part:
                bits = part.split(":")
                if len(bits) == 2:
                    bits.append("1")
                if len(bits) != 3:
                    raise ValueError
                a, b, s = (float(x) for x in bits)
                if not all(math.isfinite(v) for v in (a, b, s)) or s <= 0 or b < a:
                    raise ValueError
                n = int(math.floor((b - a) / s + 1e-9))
                if n > 100_000:
                    raise ValueError
                out += [a + i * s for i in range(n + 1)]
            else:
                v = float(part)
                if not math.isfinite(v):
                    raise ValueError
                out.append(v)
        except ValueError:
            raise LunarvizError(f"malformed {name} {part!r}: use a,b,c or start:stop[:step] with step > 0") from None
    for v in out:
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            raise LunarvizError(f"{name} {v:g} is out of range [{lo:g}, {hi:g}]")
    return out


def wavelength_label(nm: float) -> str:
    """A wavelength's text in output keys (``bond_albedo``, image planes): 12 significant digits."""
    return format(float(nm), ".12g")
