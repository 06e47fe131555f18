"""The explorer's picture of a state: four 3-D panels on the left (the Moon seen from the observer,
its earthshine alone, the light paths, the BRDF map; :data:`~lunarviz.viz.views.EXPLORE_VIEW`), and
on the right the curves of the slider's range with the state marked and the numbers with their
units and error bound.

One :class:`Painter` per thread: it keeps its offscreen plotter and its figure between pictures
(a new render window costs more than a picture). The same painter code makes the window's
pictures and ``lunarviz render --state``'s, so the two agree pixel for pixel.
"""

from __future__ import annotations

import textwrap
from datetime import datetime

import numpy as np

#: the 3-D panels' share of the picture's width
SPLIT = 0.62
#: the figure's resolution [dots per inch]: 10-point text is ~14 pixels high
DPI = 100
#: the numbers' lines are wrapped at this many characters (9-point monospace in the right panel)
TEXT_COLUMNS = 60


def _x(state, keys) -> tuple[np.ndarray, str]:
    """Abscissae of the slider's values: θ [deg], or days since its first date."""
    if state.times is None:
        return np.asarray(keys, dtype=float), "θ [deg] (0: full Moon, 180: new Moon)"
    t = [datetime.fromisoformat(str(k).replace("Z", "+00:00")) for k in keys]
    return np.array([(u - t[0]).total_seconds() / 86400 for u in t]), f"days since {keys[0]}"


def _values(series, name: str) -> np.ndarray:
    """A column of the series' rows; NaN where a row is not computed yet, null, or zero (gaps on log axes)."""
    out = np.full(len(series), np.nan)
    for i, r in enumerate(series):
        v = None if r is None else r.get(name)
        if v is not None and np.isfinite(v) and v > 0:
            out[i] = v
    return out


def numbers_lines(state, quality: str, row: dict) -> list[str]:
    """The numbers panel: the state, the irradiances with units, their ratio, p*, the bound."""
    def f(v, fmt):
        return "n/a" if v is None or not np.isfinite(v) else format(v, fmt)
    row = row or {}
    if quality == "first":
        head = "FIRST PICTURE, converging...\n(the paper's point sources; a coarser Moon)"
    else:
        b = row.get("rtol")
        why = row.get("no_bound_reason") or row.get("skip_reason") or ""
        bound = f"relative error bound {b:.1e}" if b is not None and np.isfinite(b) and b > 0 else \
            ("exact zeros" if b == 0 else f"no error bound: {why or 'no model for this row'}")
        head = f"converged: ray traced ({row.get('estimator', 'deterministic')})\n{bound}"
    where = f"θ = {f(row.get('theta_deg'), '.1f')}°" if state.times is None else \
        f"{row.get('time_utc', state.key)}   observer {state.options.get('observer', 'geocentre')}"
    unit = "W m⁻²"
    lines = [head, where,
             f"phase angle α = {f(row.get('alpha_deg'), '.2f')}°   β = {f(row.get('beta_deg'), '.2f')}°",
             f"BRDF {state.brdf}   Moon {state.option('moon_model')}   "
             f"{'band ' + state.band if state.band else 'grey'}",
             f"Earth {state.option('earth_brdf')}, {state.option('earth_surface')}, "
             f"clouds {state.option('clouds')}",
             f"moonshine  E = {f(row.get('moonshine_W_m2'), '.5e')} {unit}",
             f"earthshine E = {f(row.get('earthshine_W_m2'), '.5e')} {unit}",
             f"earthshine / moonshine = {f(row.get('ratio_earthshine_moonshine'), '.5e')}",
             f"apparent albedo p* = {f(row.get('apparent_albedo'), '.4f')}"]
    if row.get("skip_reason"):
        lines.append(f"nothing computed: {row['skip_reason']}")
    elif row.get("rays"):
        lines.append(f"rays traced: {row['rays']:,}")
    return lines


def draw_curves(fig, state, series: list) -> dict:
    """The right-hand panels on ``fig``: irradiances and (ratio, p*) against θ or time, and the
    artists that mark a state and print its numbers (animated: :func:`mark` draws them over the
    curves' saved pixels, so a new state costs no redraw of the axes)."""
    keys = state.keys
    x, xlabel = _x(state, keys)
    gs = fig.add_gridspec(3, 1, height_ratios=(0.9, 0.9, 1.45), hspace=0.42, left=0.2, right=0.84, top=0.90,
                          bottom=0.02)
    ax1, ax2 = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    done = sum(r is not None for r in series)
    for name, label, colour in (("moonshine_W_m2", "moonshine", "C1"), ("earthshine_W_m2", "earthshine", "C0")):
        ax1.semilogy(x, _values(series, name), ".-", ms=3, lw=1, color=colour, label=label)
    ax1.set_ylabel("irradiance at the\ndetector [W m⁻²]")
    ax1.legend(fontsize=9, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, frameon=False)
    fig.text(0.5, 0.985, f"ray-traced rows of the slider's {len(keys)} values ({done} computed)", fontsize=10,
             ha="center", va="top")
    ax2.semilogy(x, _values(series, "ratio_earthshine_moonshine"), ".-", ms=3, lw=1, color="C2")
    ax2.set_ylabel("earthshine / moonshine", color="C2")
    ax3 = ax2.twinx()
    p = _values(series, "apparent_albedo")
    ax3.plot(x, p, ".-", ms=3, lw=1, color="C3")
    ax3.set_ylabel("apparent albedo p*", color="C3")
    ax3.ticklabel_format(axis="y", useOffset=False, style="plain")
    if np.isfinite(p).any() and np.nanmax(p) - np.nanmin(p) < 1e-3 * np.nanmax(np.abs(p)):
        mid = float(np.nanmean(p))  # (a constant p*, the Lambert Earth's: an axis about it, not about 1e-13)
        ax3.set_ylim(mid - 0.05 * abs(mid) - 1e-3, mid + 0.05 * abs(mid) + 1e-3)
    ax2.set_xlabel(xlabel)
    for a in (ax1, ax2):
        a.grid(alpha=0.3)
        if len(x) > 1:
            a.set_xlim(x.min() - 0.01 * np.ptp(x), x.max() + 0.01 * np.ptp(x))
    return {"x": x,
            "lines": [a.axvline(x[0], color="0.3", lw=0.9, ls=":", animated=True) for a in (ax1, ax2)],
            "points": [ax1.plot([], [], "o", ms=8, mfc="none", mec="k", animated=True)[0] for _ in range(2)],
            "text": fig.text(0.03, ax2.get_position().y0 - 0.065, "", fontsize=9, family="monospace", va="top",
                             ha="left", animated=True)}


def mark(fig, artists: dict, state, quality: str, row: dict, extra: list = ()) -> None:
    """Draw the state's marker and numbers (and ``extra`` lines) over the curves (after their
    pixels are restored)."""
    here = artists["x"][state.index]
    for line in artists["lines"]:
        line.set_xdata([here, here])
        fig.draw_artist(line)
    for point, name in zip(artists["points"], ("moonshine_W_m2", "earthshine_W_m2")):
        v = (row or {}).get(name)
        point.set_data(([here], [v]) if v is not None and np.isfinite(v) and v > 0 else ([], []))
        fig.draw_artist(point)
    text = artists["text"]
    lines = [w for block in numbers_lines(state, quality, row) + list(extra) for line in block.split("\n")
             for w in textwrap.wrap(line, TEXT_COLUMNS, subsequent_indent="    ") or [""]]
    text.set_text("\n".join(lines))
    text.set_color("darkred" if quality == "first" else "black")
    fig.draw_artist(text)


def facet_lines(view, picked) -> list[str]:
    """The picked facet's numbers (its light, its angles, its BRDF for sunlight)."""
    if picked is None:
        return []
    cd = view.facets.cell_data

    def v(name, fmt):
        x = cd.get(name)
        return "n/a" if x is None or not np.isfinite(x[picked]) else format(float(x[picked]), fmt)
    return [f"facet {picked}: i = {v('incidence_deg', '.1f')}°  e = {v('emission_deg', '.1f')}°  "
            f"(red: its paths)",
            f"  moonshine  L = {v('moonshine_radiance_W_m2_sr', '.4e')} W m⁻² sr⁻¹",
            f"  earthshine L = {v('earthshine_radiance_W_m2_sr', '.4e')} W m⁻² sr⁻¹",
            f"  π·BRDF for sunlight = {v('reflectance_factor', '.4f')}"]


def instrument_lines(state, frame) -> list[str]:
    """The instrument's frame in words: its exposure, its brightest pixel, its patches."""
    if state.instrument is None:
        return []
    if frame is None:
        return [f"instrument {state.instrument}: its frame comes with the converged picture"]
    c = frame["counts"]
    if c is None:
        return [f"instrument {frame['name']}: no frame: {frame['note']}"]
    lines = [f"instrument {frame['name']} ({frame['band']}): exposure {frame['exposure_s']:g} s",
             f"  counts {c.min():.0f}-{c.max():.0f} ADU (full well {frame['full_well_adu']:.0f})"]
    p = frame["patches"]
    lines.append("  patches: " + (f"earthlit {int(p.earthlit.sum())}, sunlit {int(p.sunlit.sum())}, "
                                  f"sky {int(p.sky.sum())} px" if p is not None else frame["note"]))
    if p is not None:
        full = sum(int((c[getattr(p, n)] >= frame["saturate_adu"]).sum()) for n in ("earthlit", "sunlit", "sky"))
        if full:
            lines.append(f"  {full} patch pixels saturated: the pipeline refuses this exposure")
    return lines


def facet_at(view, state, x: float, y: float):
    """The lunar facet under pixel (x, y) of the picture's top-left panel (the Moon seen from the
    observer), or None: the panel's camera (:func:`lunarviz.viz.views.panel_camera`) inverted, and
    of the facets facing the observer the one whose centre projects nearest."""
    from lunarviz.viz.views import EXPLORE_ZOOM, facet_centroids, panel_camera
    W, H = state.size
    pw, ph = (int(W * SPLIT) // 2 * 2) / 2.0, H / 2.0
    if not (0 <= x < pw and 0 <= y < ph):
        return None
    fr = view.facets
    focal, look, up, scale = panel_camera(fr, EXPLORE_ZOOM)
    right = np.cross(look, up)  # the image's right (look: from the observer toward the Moon)
    u, w = (x - pw / 2) * 2 * scale / ph, (ph / 2 - y) * 2 * scale / ph
    c = facet_centroids(fr)
    front = c @ -look > 0
    d = (c - focal) @ right - u, (c - focal) @ up - w
    dist = np.where(front, d[0] ** 2 + d[1] ** 2, np.inf)
    i = int(np.argmin(dist))
    R = float(np.max(np.linalg.norm(c, axis=1)))
    spacing = R * np.sqrt(4 * np.pi / len(c))  # (the facets' mean spacing: off the disc, none is that near)
    return i if dist[i] < spacing ** 2 else None


class Painter:
    """Makes pictures of states; keeps one offscreen plotter and one figure (use from one thread)."""

    def __init__(self):
        self._plotter = None
        self._size = None
        self._curves_sig = None
        self._curves_fig = None
        self._left, self._left_of = None, None

    def _plot3d(self, view, size, picked=None, model=None, frame=None, lower="brdf") -> np.ndarray:
        from lunarviz.viz import views
        if self._plotter is None or self._size != size:
            if self._plotter is not None:
                self._plotter.close()
            self._plotter = views.build_plotter(view, views.EXPLORE_VIEW, size, off_screen=True, picked=picked,
                                                brdf_model=model, frame=frame, lower=lower)
            self._size = size
        else:
            pl = self._plotter
            pl.suppress_rendering = True  # (else every actor added renders the window: ~30 ms each)
            try:
                for title in list(pl.scalar_bars.keys()):
                    pl.remove_scalar_bar(title, render=False)
                for r in pl.renderers:
                    r.clear_actors()
                views.populate(pl, view, views.EXPLORE_VIEW, picked, model, frame, lower)
                for r in pl.renderers:  # (a panel's new scene may lie far from its last: a dome of radius 1
                    r.reset_camera_clipping_range()  # where the Moon was, in metres, would be clipped away)
            finally:
                pl.suppress_rendering = False
        self._plotter.render()
        return np.asarray(self._plotter.screenshot(return_img=True))[..., :3]

    @staticmethod
    def _figure(size):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        fig = Figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)
        FigureCanvasAgg(fig)
        return fig

    @staticmethod
    def _pixels(fig) -> np.ndarray:
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()

    def _curves(self, state, series: list, size, quick: bool = False):
        """The figure of the curves, drawn once per slider range and set of rows (its pixels kept);
        ``quick`` (a first picture): the range's last drawn curves, though rows came since."""
        scene = (state.with_(key=state.keys[0], picked=None).cache_key(), size)
        sig = (*scene, tuple(None if r is None else (r.get("moonshine_W_m2"), r.get("earthshine_W_m2"),
                                                     r.get("apparent_albedo")) for r in series))
        if self._curves_sig != sig and not (quick and self._curves_sig is not None and self._curves_sig[:2] == scene):
            fig = self._curves_fig[0] if self._curves_fig is not None and self._curves_sig[1] == size else None
            if fig is None:
                fig = self._figure(size)
            fig.clear()
            artists = draw_curves(fig, state, series)
            fig.canvas.draw()
            self._curves_fig = (fig, artists, fig.canvas.copy_from_bbox(fig.bbox))
            self._curves_sig = sig
        return self._curves_fig

    def paint(self, state, quality: str, row: dict, series: list, view, model=None, frame=None) -> np.ndarray:
        """The picture (RGB, height × width × 3, uint8) of ``state`` (``model``: its lunar BRDF, for
        a picked facet's own map; ``frame``: its instrument's, :func:`~lunarviz.explore.engine.instrument_frame`)."""
        W, H = state.size
        w3 = int(W * SPLIT) // 2 * 2
        picked = state.picked if quality == "converged" else None  # (a first picture's Moon is coarser)
        if picked is not None and picked >= view.facets.n_faces:
            from lunarviz.errors import LunarvizError
            raise LunarvizError(f"picked facet {picked} is not on the Moon's mesh of {view.facets.n_faces} facets")
        last = self._left_of
        if last is None or last[0] is not view or last[1] is not frame or last[2:] != (picked, state.panel, (w3, H)):
            self._left = self._plot3d(view, (w3, H), picked, model, frame, state.panel)  # (else a band's: kept)
            self._left_of = (view, frame, picked, state.panel, (w3, H))
        left = self._left
        fig, artists, background = self._curves(state, series, (W - w3, H), quick=quality == "first")
        fig.canvas.restore_region(background)
        mark(fig, artists, state, quality, row, facet_lines(view, picked) + instrument_lines(state, frame))
        right = np.asarray(fig.canvas.buffer_rgba())[..., :3]
        return np.concatenate([left, right[:H, :W - w3]], axis=1)

    def paint_error(self, state, message: str) -> np.ndarray:
        """A picture that says why ``state`` cannot be shown."""
        fig = self._figure(state.size)
        fig.text(0.05, 0.5, "cannot show this state:\n" + message, fontsize=12, va="center", wrap=True,
                 color="darkred")
        return self._pixels(fig)

    def close(self) -> None:
        if self._plotter is not None:
            self._plotter.close()
            self._plotter = None
