"""Parsing of number lists shared by the command line and the Python API."""

from __future__ import annotations

import math
import re

from lunarviz.errors import LunarvizError

#: units a user may write after a number, by quantity: each unit's size in the quantity's own unit
LENGTH_M = {"m": 1.0, "km": 1e3}
TIME_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "min": 60.0}  # (micro sign and Greek mu)
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zµμ]*)\s*$", re.I)


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


def parse_quantity(text, what: str, units: dict[str, float], unit: str) -> tuple[float, bool]:
    """``8ms``, ``2.067km`` or a bare number (in ``unit``) → (the value in ``unit``, whether a unit
    was written). The one-line error names the value and the units accepted."""
    m = _QUANTITY.match(str(text))
    suffix = m.group(2).lower() if m else ""
    if m is None or suffix and suffix not in units:
        raise LunarvizError(f"{what} {str(text)!r} must be a number in {unit}, or a number with one of the units "
                            f"{', '.join(units)} (e.g. 8{list(units)[-1]})")
    v = float(m.group(1)) * units[suffix or unit] / units[unit]
    if not math.isfinite(v):
        raise LunarvizError(f"{what} {str(text)!r} is not finite")
    return v, bool(suffix)


def wavelength_label(nm: float) -> str:
    """A wavelength's text in output keys (``bond_albedo``, image planes): 12 significant digits."""
    return format(float(nm), ".12g")
