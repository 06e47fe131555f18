"""The figure of a sweep's rows (``lunarviz sweep --plot FILE.png``): moonshine, earthshine, their
ratio and the apparent albedo p* against θ or against time, one line per BRDF (and band or
wavelength), rows that computed nothing (the Moon down, hidden or eclipsed) marked at the foot."""

from __future__ import annotations

from datetime import datetime

import numpy as np

from lunarviz.outputs.writers import save_figure

#: the most series a panel draws (a spectral run's wavelengths are thinned to this many)
MAX_SERIES = 6


def _x(rows: list[dict]) -> tuple[np.ndarray, str]:
    """Each row's abscissa: θ [deg], or days since the first date."""
    if rows and rows[0].get("time_utc"):
        t = [datetime.fromisoformat(r["time_utc"].replace("Z", "+00:00")) for r in rows]
        return np.array([(x - t[0]).total_seconds() / 86400 for x in t]), f"days since {rows[0]['time_utc']}"
    return np.array([r["theta_deg"] for r in rows], dtype=float), "θ [deg] (0: full Moon, 180: new Moon)"


def _series(rows: list[dict]) -> dict[tuple, list[dict]]:
    """Rows by (BRDF, method, band or wavelength, and observer where the rows have several), at most
    MAX_SERIES labels per BRDF and method."""
    groups: dict[tuple, list[dict]] = {}
    observers = {r.get("observer") for r in rows}
    for r in rows:
        label = r.get("band") or (f"{r['wavelength_nm']:g} nm" if r.get("wavelength_nm") is not None else "")
        if len(observers) > 1:
            label = f"{label} {r.get('observer')}".strip()
        groups.setdefault((r.get("brdf", ""), r.get("method", ""), label), []).append(r)
    keys = list(groups)
    heads = {k[:2] for k in keys}
    keep = []
    for h in sorted(heads):
        mine = [k for k in keys if k[:2] == h]
        step = max(1, int(np.ceil(len(mine) / MAX_SERIES)))
        keep += mine[::step]
    return {k: groups[k] for k in keep}


def _value(r: dict, name: str) -> float:
    """A row's ``name`` (per nm where the row is a wavelength's), NaN where absent or null."""
    v = r.get(name, r.get(name + "_nm"))
    return float("nan") if v is None else float(v)


def plot_sweep(res: dict, path) -> None:
    """Moonshine, earthshine (log), earthshine/moonshine and p* against θ or time, to ``path``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = res["rows"]
    fig, ax = plt.subplots(4, 1, figsize=(8.5, 10.5), sharex=True)
    xlabel = _x(rows)[1]
    for (brdf, method, label), rs in _series(rows).items():
        x, _ = _x(rs)
        ms = np.array([_value(r, "moonshine_W_m2") for r in rs])
        es = np.array([_value(r, "earthshine_W_m2") for r in rs])
        p = np.array([_value(r, "apparent_albedo") for r in rs])
        dark = np.array([bool(r.get("skip_reason")) or bool(r.get("moon_occulted")) for r in rs])
        live = ~dark & (ms > 0)
        name = " ".join(s for s in (brdf, method, label) if s)
        line, = ax[0].semilogy(x[live], ms[live], ".-", ms=3, lw=0.8, label=name)
        c = line.get_color()
        ax[1].semilogy(x[live & (es > 0)], es[live & (es > 0)], ".-", ms=3, lw=0.8, color=c)
        ok = live & (es > 0)
        ax[2].semilogy(x[ok], es[ok] / ms[ok], ".-", ms=3, lw=0.8, color=c)
        ax[3].plot(x[live], p[live], ".-", ms=3, lw=0.8, color=c)
        # rows that computed nothing (irradiance 0: no place on a log axis) as ticks at the foot
        ax[0].plot(x[dark], np.full(int(dark.sum()), 0.03), "|", color=c, ms=6, transform=ax[0].get_xaxis_transform())
    ax[0].set_ylabel("moonshine [W m⁻²]")
    ax[1].set_ylabel("earthshine [W m⁻²]")
    ax[2].set_ylabel("earthshine / moonshine")
    ax[3].set_ylabel("apparent albedo p*")
    ax[3].set_xlabel(xlabel)
    ax[3].ticklabel_format(axis="y", useOffset=False, style="plain")
    lo, hi = ax[3].get_ylim()
    if hi - lo < 1e-3 * max(abs(hi), abs(lo), 1e-300):  # a constant p* (a Lambert Earth's): an axis about it
        mid = 0.5 * (lo + hi)
        ax[3].set_ylim(mid - 0.05 * abs(mid) - 1e-3, mid + 0.05 * abs(mid) + 1e-3)
    for a in ax:
        a.grid(alpha=0.3, which="both")
    ax[0].legend(fontsize=7, loc="lower left", bbox_to_anchor=(0.0, 1.02), ncol=3, frameon=False)  # (off the data)
    what = "per nm " if any(r.get("wavelength_nm") is not None for r in rows) else ""
    dark = any(r.get("skip_reason") or r.get("moon_occulted") for r in rows)
    fig.suptitle(f"{len(rows)} rows, irradiances {what}at the detector"
                 + ("; | at the foot: the Moon down, hidden or eclipsed" if dark else ""), fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    save_figure(fig, path, dpi=110)
    plt.close(fig)
