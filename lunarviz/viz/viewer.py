"""The desktop viewer: the composite view in a window, with the phase and the BRDF live.

* a slider sets the phase θ (0-180°); keys ``Left``/``Right`` step it by 5°;
* three buttons choose the BRDF (Lambert, SHG, DHG);
* a click on the Moon (top-left panel) picks a facet and shows its per-facet values.

Each change re-traces the phase (about a second) and rebuilds the panels in place.
"""

from __future__ import annotations

import numpy as np

from lunarviz.errors import LunarvizError
from lunarviz.viz.view_data import ComputeView
from lunarviz.viz.views import build_plotter, populate

BRDF_BUTTONS = ("lambert", "shg", "dhg")


class Viewer:
    """The desktop viewer of one scene.

    Parameters
    ----------
    compute : callable
        ``compute(key, brdf)`` → :class:`~lunarviz.viz.view_data.ViewData` of a task.
    theta : float or str
        The task shown first: θ [deg], or one of ``times``.
    brdf : str
        The BRDF shown first.
    times : tuple of str, optional
        The UTC times a dated scene steps through (its slider is then a time index).
    size : (int, int)
        Window size [pixels].
    off_screen : bool
        Render without a window (tests, screenshots).
    """

    def __init__(self, compute: ComputeView, theta, brdf: str, times: tuple | None = None, size=(1600, 900),
                 off_screen=False):
        self.compute = compute
        #: the UTC times of a dated scene (``None``: the θ scene)
        self.times = tuple(times) if times else None
        #: the task key: θ [deg], or a UTC time label of a dated scene
        self.theta = theta if self.times else float(theta)
        self.brdf = brdf
        self.size = size
        self.off_screen = off_screen
        self.data = compute(self.theta, brdf)
        self.plotter = build_plotter(self.data, "composite", size, off_screen=off_screen)
        self.picked: dict | None = None
        self._add_controls()

    # ---- state changes (also driven by tests) -----------------------------------------------
    def set_phase(self, theta: float):
        theta = float(np.clip(theta, 0.0, 360.0))
        if abs(theta - self.theta) < 1e-9:
            return
        self.theta = theta
        self._refresh()

    def set_time_index(self, index: int):
        """Show the ``index``-th of the scene's UTC times (real-sky viewer)."""
        times = self.times
        key = times[int(np.clip(index, 0, len(times) - 1))]
        if key != self.theta:
            self.theta = key
            self._refresh()

    def set_brdf(self, brdf: str):
        if brdf not in BRDF_BUTTONS:
            raise LunarvizError(f"unknown BRDF {brdf!r}")
        if brdf != self.brdf:
            self.brdf = brdf
            self._refresh()

    def pick_facet(self, cell_id: int) -> dict:
        """Per-facet values of lunar facet ``cell_id`` (shown in the window)."""
        cd = self.data.facets.cell_data
        self.picked = {k: float(v[cell_id]) for k, v in cd.items()}
        self.picked["facet"] = int(cell_id)
        lines = [f"facet {cell_id}"] + [f"{k} = {v:.4g}" for k, v in self.picked.items() if k != "facet"]
        self.plotter.subplot(0, 0)
        self.plotter.add_text("\n".join(lines[:12]), position="lower_left", font_size=8, color="yellow",
                              name="picked")
        return self.picked

    # ---- internals ---------------------------------------------------------------------------
    def _refresh(self):
        self.data = self.compute(self.theta, self.brdf)
        pl = self.plotter
        for title in list(pl.scalar_bars.keys()):
            pl.remove_scalar_bar(title, render=False)
        for r in pl.renderers:
            r.clear_actors()
        populate(pl, self.data, "composite")
        self._add_labels()  # cameras follow the new geometry (the Moon seen from the detector)
        # clearing the actors took the widgets' representations with them: put them back, the
        # slider showing the phase (or time index) now drawn
        widgets = getattr(pl, "widgets", pl)
        for widget in list(widgets.slider_widgets):
            value = self.times.index(self.theta) if self.times else self.theta
            widget.GetRepresentation().SetValue(float(value))
        for widget in list(widgets.slider_widgets) + list(widgets.button_widgets):
            widget.Off()
            widget.On()
        pl.render()

    def _add_labels(self):
        pl = self.plotter
        pl.subplot(1, 0)
        for k, name in enumerate(BRDF_BUTTONS):
            pl.add_text(name, position=(52, 18 + 45 * k), font_size=10, color="white", name=f"label_{name}")
        pl.subplot(0, 0)

    def _add_controls(self):
        pl = self.plotter
        pl.subplot(1, 0)
        if self.times:
            n = len(self.times)
            pl.add_slider_widget(lambda v: self.set_time_index(round(v)), [0.0, max(n - 1, 1e-9)],
                                 value=self.times.index(self.theta), title="time index",
                                 pointa=(0.32, 0.11), pointb=(0.95, 0.11), style="modern",
                                 interaction_event="end", color="white")
        else:
            pl.add_slider_widget(lambda v: self.set_phase(round(v)), [0.0, 180.0], value=self.theta,
                                 title="phase theta [deg]", pointa=(0.32, 0.11), pointb=(0.95, 0.11),
                                 style="modern", interaction_event="end", color="white")
        for k, name in enumerate(BRDF_BUTTONS):
            pl.add_checkbox_button_widget(lambda on, n=name: self.set_brdf(n), value=name == self.brdf,
                                          position=(10, 10 + 45 * k), size=35, color_on="orange")
        self._add_labels()
        if not self.off_screen:
            pl.enable_cell_picking(callback=self._on_pick, through=False, show=False, show_message=False,
                                   start=False)
        if self.times:
            times = self.times
            pl.add_key_event("Right", lambda: self.set_time_index(times.index(self.theta) + 1))
            pl.add_key_event("Left", lambda: self.set_time_index(times.index(self.theta) - 1))
        else:
            pl.add_key_event("Right", lambda: self.set_phase(self.theta + 5))
            pl.add_key_event("Left", lambda: self.set_phase(self.theta - 5))

    def _on_pick(self, cells):
        if cells is None or cells.n_cells == 0 or "vtkOriginalCellIds" not in cells.cell_data:
            return
        self.pick_facet(int(cells.cell_data["vtkOriginalCellIds"][0]))

    def show(self, **kw):
        self.plotter.show(title="lunarviz", **kw)


def run_viewer(compute: ComputeView, theta, brdf, times=None, size=(1600, 900)):
    """Open the desktop viewer at phase θ [deg] (or at one of a dated scene's ``times``)."""
    Viewer(compute, theta, brdf, times, size=size).show()
