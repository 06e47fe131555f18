"""``lunarviz plot FILE --out F.png``: the figure a user expects from any output, told apart by its content.

* a sweep (``sweep --out`` .json, .csv or .nc): moonshine, earthshine, their ratio and p* against θ
  or time (:func:`lunarviz.outputs.sweep_plot.plot_sweep`);
* a mesh study (``study mesh``): error against facets and against run time
  (:func:`~lunarviz.workflows.study.plot_study`);
* a benchmark (``bench``): run time against error per method (:func:`~lunarviz.workflows.bench.plot_pareto`);
* a measurement (``measure``): p* per measurement with its 1σ and k = 2 bars against the sweep's, and
  its error budget, largest term first (:func:`plot_measurement`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.outputs.writers import save_figure

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
                frame = ds.to_dataframe().reset_index()
            return {"rows": [{k: _cell(v) for k, v in r.items()} for r in frame.to_dict("records")]}
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
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
    """What an output is: ``sweep``, ``study``, ``bench`` or ``measurement``."""
    rows = res.get("rows") if isinstance(res, dict) else None
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
    {"sweep": plot_sweep, "study": plot_study, "bench": plot_pareto, "measurement": plot_measurement}[kind](res, out)
    return kind


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
    fig.suptitle(f"{len(rows)} measurements" + (f" of task {key}" if key else "")
                 + (f", {res['instrument']['name']}" if isinstance(res.get("instrument"), dict) else ""), fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
