"""``lunarviz plot FILE --out F.png``: the figure a user expects from any output, told apart by its content.

* a sweep (``sweep --out`` .json, .csv or .nc): moonshine, earthshine, their ratio and p* against θ
  or time (:func:`lunarviz.outputs.sweep_plot.plot_sweep`);
* a mesh study (``study mesh``): error against facets and against run time
  (:func:`~lunarviz.workflows.study.plot_study`);
* a benchmark (``bench``): run time against error per method (:func:`~lunarviz.workflows.bench.plot_pareto`);
* a measurement (``measure``): p* per measurement with its 1σ and k = 2 bars against the sweep's, and
  its error budget, largest term first (:func:`plot_measurement`);
* an error budget over phases (``scripts/measurement_budget.py``'s ``budget.json``: rows per
  instrument): each term's σ(p*)/p* against the phase angle (:func:`plot_budget`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.outputs.writers import save_figure

#: a NetCDF sweep's variables under the names of the rows they hold (lunarviz.outputs.tables)
NETCDF_NAMES = {"moonshine": "moonshine_W_m2", "earthshine": "earthshine_W_m2", "theta": "theta_deg",
                "alpha": "alpha_deg", "beta": "beta_deg", "time": "time_utc"}
#: the terms of an error budget over phases (σ of p*), as ``measure`` and the budget script write them
BUDGET_ROW_TERMS = ("sigma_photon", "sigma_read_dark", "sigma_halo_fit", "sigma_lunar_model", "sigma_halo_shape",
                    "sigma_nd_filter", "sigma_ephemeris", "sigma_band")
#: the error budget's terms (σ of p*) as ``measure`` writes them, with their names in a figure
BUDGET_TERMS = {"p_star_sigma": "random (photon, read, dark, halo fit)", "sigma_lunar_model": "lunar model",
                "sigma_nd_filter": "ND filter", "sigma_ephemeris": "ephemeris", "sigma_band": "band centre",
                "sigma_halo_shape": "halo shape"}


def read_output(path) -> dict:
    """An output file as a dict (a sweep's CSV or NetCDF as ``{"rows": [...]}``); one line for anything else."""
    p = Path(path)
    suffix = p.suffix.lower()
    try:
        if suffix == ".json":
            return json.loads(p.read_text(encoding="utf-8"))
        if suffix == ".csv":
            import csv
            with p.open(newline="", encoding="utf-8") as f:
                return {"rows": [{k: _cell(v) for k, v in r.items()} for r in csv.DictReader(f)]}
        if suffix == ".nc":
            import xarray as xr
            with xr.open_dataset(p) as ds:
                frame = ds.drop_vars([v for v in ds.data_vars if not set(ds[v].dims) >= {d for d in ds.dims
                                                                                          if d != "brdf"}]
                                     ).to_dataframe().reset_index()
            rows = [{NETCDF_NAMES.get(k, k): _cell(v) for k, v in r.items()} for r in frame.to_dict("records")]
            for r in rows:
                if isinstance(r.get("time_utc"), str) or r.get("time_utc") is None:
                    continue
                r["time_utc"] = str(np.datetime64(r["time_utc"], "s")) + "Z"
            return {"rows": rows}
    except (OSError, UnicodeDecodeError, ValueError, RecursionError, KeyError, TypeError) as exc:
        raise LunarvizError(f"cannot read {str(path)!r}: {exc.__class__.__name__}") from None
    raise LunarvizError(f"{str(path)!r}: lunarviz plot reads .json, .csv or .nc outputs, not {suffix or 'no suffix'!r}")


def _cell(v):
    """A CSV or table cell as a number where it is one (empty: None)."""
    if isinstance(v, (bytes, np.bytes_)):
        v = v.decode()
    if isinstance(v, str):
        if v == "":
            return None
        try:
            return float(v)
        except ValueError:
            return v
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        return v.item()
    return v


def kind_of(res) -> str:
    """What an output is: ``sweep``, ``study``, ``bench``, ``measurement`` or ``budget``."""
    rows = res.get("rows") if isinstance(res, dict) else None
    if isinstance(rows, dict) and rows and all(isinstance(v, list) for v in rows.values()) \
            and any(isinstance(r, dict) and "p_star_sigma_total" in r for v in rows.values() for r in v):
        return "budget"
    if isinstance(res, dict) and isinstance(res.get("summary"), list) and rows is not None:
        return "study"
    if isinstance(rows, list) and rows and isinstance(rows[0], dict):
        first = rows[0]
        if "p_star" in first and "measurement" in first:
            return "measurement"
        if "error_vs_reference" in first and "setting" in first:
            return "bench"
        if any(k.startswith(("moonshine_W_m2", "earthshine_W_m2")) for k in first):
            return "sweep"
    raise LunarvizError("not a lunarviz sweep, study, bench or measurement output (no rows of theirs)")


def plot_file(path, out) -> str:
    """Draw the figure of the output at ``path`` to ``out``; returns what it was."""
    from lunarviz.outputs.sweep_plot import plot_sweep
    from lunarviz.workflows.bench import plot_pareto
    from lunarviz.workflows.study import plot_study
    res = read_output(path)
    kind = kind_of(res)
    draw = {"sweep": plot_sweep, "study": plot_study, "bench": plot_pareto, "measurement": plot_measurement,
            "budget": plot_budget}[kind]
    try:
        draw(res, out)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        raise LunarvizError(f"{str(path)!r} looks like a {kind} output but is not a whole one "
                            f"({exc.__class__.__name__}: {exc})") from None
    return kind


def plot_budget(res: dict, path) -> None:
    """Each term of the error budget, σ(p*)/p*, against the lunar phase angle, one panel per
    instrument or site (``res["rows"]``: name → rows); zeros and infinities as gaps, the phases
    where a term is infinite shaded."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    groups = res["rows"]
    fig, axes = plt.subplots(1, len(groups), figsize=(6.5 * len(groups), 4.6), sharey=True, squeeze=False)
    for ax, (name, rs) in zip(axes[0], groups.items()):
        rs = sorted((r for r in rs if "error" not in r), key=lambda r: r["phase_angle_deg"])
        x = np.array([r["phase_angle_deg"] for r in rs])

        def rel(k, rs=rs):
            v = np.array([(r.get(k) if r.get(k) is not None else np.nan) / r["p_star"] for r in rs], dtype=float)
            return np.where(np.isfinite(v) & (v > 0), v, np.nan)
        for k, style, label, width in (("p_star_sigma_systematic", "r-", "systematic (quadrature sum)", 2.5),
                                       ("p_star_sigma", "b-", "random", 2.0),
                                       ("p_star_sigma_total", "k:", "total (drawn last, dotted)", 2.0)):
            ax.semilogy(x, rel(k), style, lw=width, label=label)
        for k in BUDGET_ROW_TERMS:
            ax.semilogy(x, rel(k), ".--", lw=0.8, label=k.replace("sigma_", "").replace("_", " "))
        inf = [r["phase_angle_deg"] for r in rs if not np.isfinite(r.get("p_star_sigma_total", np.nan))]
        for xi in inf:
            ax.axvline(xi, color="gray", lw=6, alpha=0.25)
        ax.set_xlabel("lunar phase angle [deg]" + ("  (grey: a term infinite there)" if inf else ""))
        ax.set_title(f"{name}: σ(p*)/p*", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("relative standard uncertainty of p*")
    fig.legend(*axes[0][-1].get_legend_handles_labels(), fontsize=7, loc="center right")
    fig.tight_layout(rect=(0, 0, 0.86, 1))
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def plot_measurement(res: dict, path) -> None:
    """p* of each measurement with its random 1σ and total k = 2 bars against the sweep's p*, and
    the mean error budget (σ of p*, relative), largest term first."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = [r for r in res["rows"] if r.get("p_star") is not None]
    if not rows:
        raise LunarvizError("the measurement output holds no p* (every measurement failed)")
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": (1.2, 1.0)})
    n = np.arange(1, len(rows) + 1)
    p = np.array([r["p_star"] for r in rows])
    ax.errorbar(n, p, yerr=[r.get("p_star_U_k2") or 0.0 for r in rows], fmt="none", ecolor="0.7", lw=3,
                label="total, k = 2")
    ax.errorbar(n, p, yerr=[r.get("p_star_sigma") or 0.0 for r in rows], fmt="o", ms=4, color="C0", capsize=2,
                label="random 1σ")
    truth = (res.get("summary") or {}).get("p_star_sweep")
    if truth is not None:
        ax.axhline(truth, color="C3", lw=1, label=f"the sweep's p* = {truth:.4f}")
    ax.set_xlabel("measurement")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_ylabel("apparent albedo p*")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(0.0, -0.18), ncol=3, frameon=False)
    ax.grid(alpha=0.3)
    terms = {label: float(np.mean([(r.get(k) or 0.0) / r["p_star"] for r in rows]))
             for k, label in BUDGET_TERMS.items()}
    shown = dict(sorted(((k, v) for k, v in terms.items() if v > 0), key=lambda t: t[1]))
    zero = [k for k, v in terms.items() if not v > 0]  # (no place on a log axis: named in the title)
    bx.barh(list(shown), list(shown.values()), color="C0")
    bx.set_xscale("log")
    bx.set_xlabel("σ of p* / p* (mean over the measurements)")
    bx.set_title("error budget, largest term on top" + (f"\n(zero: {', '.join(zero)})" if zero else ""), fontsize=9)
    bx.grid(alpha=0.3, axis="x", which="both")
    key = res.get("key")
    try:
        where = f" at θ = {float(key):g}°"
    except (TypeError, ValueError):
        where = f" at {key}" if key else ""
    fig.suptitle(f"{len(rows)} measurements{where}"
                 + (f", {res['instrument']['name']}" if isinstance(res.get("instrument"), dict) else ""), fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
