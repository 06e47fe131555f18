"""The explorer's controls and what each one changes, shared by the desktop window and the browser
app: :data:`CONTROLS` names them and their choices; :class:`Explorer` holds the state on show, turns
a control's new value into a new state, hands it to the engine and keeps the newest frame.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from lunarviz.errors import LunarvizError
from lunarviz.explore.engine import Engine, Frame
from lunarviz.explore.state import OBSERVERS, ExploreState


@dataclass(frozen=True)
class Control:
    """One menu of the explorer: the state field or scene option it sets, its label and choices
    (text shown → value; an ``editable`` one also takes any text, e.g. an ``--observer``)."""

    name: str
    label: str
    choices: tuple
    editable: bool = False


#: the menus, in the order the windows show them (the slider and the play buttons apart)
CONTROLS = (
    Control("observer", "observer", tuple(OBSERVERS.items()), editable=True),
    Control("brdf", "lunar BRDF", (("Lambert", "lambert"), ("Hapke, single HG", "shg"), ("Hapke, double HG", "dhg"))),
    Control("moon_model", "Moon model", (("the paper's", "paper"), ("ROLO fit", "rolo-fit"),
                                         ("ROLO fit with its albedo map", "rolo-fit-map"))),
    Control("earth_brdf", "Earth reflectance", (("Lambert", "lambert"), ("physical (air, ocean glint)", "physical"))),
    Control("earth_surface", "Earth surface", (("uniform", "uniform"), ("land and ocean", "landocean"))),
    Control("clouds", "clouds", (("none", "none"), ("zonal", "zonal"))),
    Control("band", "band", (("grey", None), ("B", "B"), ("V", "V"), ("R", "R"), ("Sentinel-2A B4", "S2A-B4"),
                             ("MODIS Terra B1", "MODIS-TERRA-B1"))),
    Control("panel", "lower right panel", (("the Moon's BRDF map", "brdf"), ("the Earth seen from the Moon", "earth"))),
    Control("instrument", "instrument", (("none", None), ("SALEX-like (LEO)", "salex"), ("BBSO-like (ground)", "bbso")),
            editable=True),
)
BY_CONTROL = {c.name: c for c in CONTROLS}


def choice_value(control: Control, text: str):
    """The value of the choice shown as ``text`` (an editable control takes any other text as is)."""
    for shown, value in control.choices:
        if text == shown or text == value:
            return value
    if control.editable:
        return text.strip()
    raise LunarvizError(f"{control.label}: unknown choice {text!r}")


def choice_text(control: Control, value) -> str:
    """The text shown for ``value``."""
    for shown, v in control.choices:
        if v == value:
            return shown
    return str(value)


def state_value(state: ExploreState, name: str):
    """The current value of control ``name`` in ``state``."""
    if name in ("brdf", "band", "instrument", "panel"):
        return getattr(state, name)
    return state.option(name)


class Explorer:
    """The state on show and its newest frame; every change goes to the engine (see
    :mod:`lunarviz.explore.engine`) and ``on_frame`` hears of each frame made.

    ``set(name, value)`` for a control; ``step(k)`` moves the slider by k; ``show(index)`` puts it at a
    value; ``pick(x, y)`` picks the lunar facet under a pixel of the picture. A change the scene
    refuses (an observer on the ground in the θ scene, a band with a physical Earth out of range...)
    leaves the state as it was and its one-line reason in :attr:`message`."""

    def __init__(self, state: ExploreState, on_frame=None, background: bool = True):
        self.state = state
        self.frame: Frame | None = None
        self.message = ""
        #: what the last save wrote (or why it failed)
        self.saved_note = ""
        self._on_frame = on_frame or (lambda frame: None)
        self._lock = threading.Lock()
        self.engine = Engine(on_frame=self._frame_made, background=background)
        self.engine.request(state)

    def _frame_made(self, frame: Frame) -> None:
        with self._lock:
            if frame.state != self.state:  # an older state's frame, superseded meanwhile
                return
            self.frame = frame
        self._on_frame(frame)

    def _go(self, make) -> bool:
        """Show the state ``make()`` returns, once the scene's own checks pass (else its one line in
        :attr:`message`, the state unchanged)."""
        try:
            state = make()
            state.scene()  # the scene's own checks, before anything is computed
        except LunarvizError as exc:
            self.message = str(exc)
            return False
        self.message = ""
        with self._lock:
            self.state = state
        self.engine.request(state)
        return True

    def set(self, name: str, value) -> bool:
        """Set control ``name`` (a state field or scene option) to ``value``; False (and
        :attr:`message`) where the scene refuses it."""
        if name == "instrument" and value in ("", "none"):
            value = None
        if name == "observer" and self.state.times is None and value != "geocentre":
            self.message = ("an observer other than the geocentre needs dates: start the explorer with --time-range, "
                            "--nights or --lunation")
            return False
        keep_pick = name in ("picked", "instrument", "panel", "band")  # (these leave the facets as they are)
        return self._go(lambda: self.state.with_(**{name: value, **({} if keep_pick else {"picked": None})}))

    def show(self, index: int) -> bool:
        keys = self.state.keys
        index = max(0, min(len(keys) - 1, int(index)))
        return self._go(lambda: self.state.with_(key=keys[index]))

    def step(self, k: int = 1) -> bool:
        return self.show(self.state.index + k)

    def pick(self, x: float, y: float) -> bool:
        """Pick the lunar facet under pixel (x, y) of the picture (its top-left Moon panel; None
        elsewhere: the pick is cleared)."""
        from lunarviz.explore.picture import facet_at
        frame = self.frame
        if frame is None or frame.view is None or frame.quality != "converged" or frame.state != self.state:
            # (a first picture's Moon is a coarser mesh: its facets are not the scene's)
            self.message = "the picture is converging: pick again in a moment"
            return False
        return self.set("picked", facet_at(frame.view, self.state, x, y))

    def save(self, path) -> threading.Thread:
        """Write the state to ``path`` (JSON) and, beside it, its converged picture with its curves
        complete (``.png``: the pixels ``lunarviz render --state`` makes), on a thread of its own."""
        from pathlib import Path

        from lunarviz.explore.engine import state_picture
        from lunarviz.outputs.writers import write_picture
        state = self.state

        def work():
            try:  # the picture first: a state that cannot be drawn leaves nothing behind
                png = Path(path).with_suffix(".png")
                picture = state_picture(state)
                written = state.save(path)
                write_picture(png, picture)
                self.saved_note = f"   saved {written} and {png}"
            except (LunarvizError, OSError) as exc:
                self.saved_note = f"   not saved: {exc}"
        t = threading.Thread(target=work, name="lunarviz-explore-save", daemon=True)
        t.start()
        return t

    def close(self) -> None:
        self.engine.close()
