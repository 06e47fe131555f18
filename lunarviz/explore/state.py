"""What the explorer shows: the scene (every option the ``Scene`` takes), the slider's range (θ or
dates), the task on show, its BRDF and band, and the picture's size; saved as JSON.

A state file is what ``lunarviz explore`` saves and what ``lunarviz render --state`` and
``lunarviz sweep --state`` read: the same state gives the same picture and the same numbers,
because all three build the same :class:`lunarviz.Scene` from it (:meth:`ExploreState.scene`)
and compute its task with the same functions.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

from lunarviz.api import SCENE_DEFAULTS, Scene
from lunarviz.errors import LunarvizError, short_repr, unknown_choice
from lunarviz.options import BRDF_NAMES, THETA_MOON_MODEL, default_moon_model

#: the state file's format: ``{"lunarviz": FORMAT, "version": VERSION, ...}``
FORMAT = "explore-state"
VERSION = 2
#: versions read: 1 (before dated runs took the fitted Moon by default: a dated state without a
#: ``moon_model`` meant the paper's, and is read so)
READS = (1, 2)
#: the default slider range of the θ scene [deg] (the sweep's default)
DEFAULT_PHASES = tuple(float(t) for t in range(0, 181, 5))
#: the picture's default size [pixels]: readable at 1280 px wide
DEFAULT_SIZE = (1280, 800)
#: the smallest picture whose panels and numbers keep their layout [pixels]
MIN_SIZE = (960, 600)
#: options the state holds apart (the BRDF and band on show; the slider's range)
OWN = ("brdfs", "bands", "wavelengths")
#: a small list of observatories by name (geodetic latitude, east longitude [deg], height [m]) and a
#: low orbit: the explorer's observer menu (any --observer text works too)
OBSERVERS = {
    "geocentre": "geocentre",
    "Big Bear Solar Observatory": "site:34.2583,-116.9214,2067m",  # BBSO, Goode et al. (2001)
    "Mauna Loa Observatory": "site:19.5362,-155.5763,3397m",  # NOAA MLO
    "Observatorio del Teide": "site:28.3004,-16.5122,2390m",  # IAC
    "Paranal": "site:-24.6272,-70.4042,2635m",  # ESO VLT
    "550 km polar orbit": "orbit:550,97.6,0,0",
}
#: what the lower right panel may show (:attr:`ExploreState.panel`)
PANELS = ("brdf", "earth")
#: the most keys a slider may hold (each is a task the background pass may compute)
MAX_KEYS = 2000


@dataclass(frozen=True)
class ExploreState:
    """One state of the explorer (immutable: a control change makes a new one with :meth:`with_`).

    Parameters
    ----------
    options : dict
        ``Scene`` keywords other than the defaults (not ``brdfs``, ``bands``, ``wavelengths``: the
        state's own ``brdf`` and ``band``).
    phases : tuple of float or None
        The θ slider's values [deg] (the θ scene), or None on dates.
    times : tuple of str or None
        The time slider's UTC labels (a dated scene), or None.
    key : float or str
        The task on show: θ [deg] (one of ``phases``) or a UTC label (one of ``times``).
    brdf : str
        The lunar BRDF on show.
    band : str or None
        A band (``V``, ``S2A-B4``, ``500-600``...): the numbers and curves band-integrated; None: grey.
    size : (int, int)
        The picture's width and height [pixels].
    picked : int or None
        A lunar facet picked on the picture: its paths and numbers are shown.
    instrument : str or None
        An instrument (``salex``, ``bbso`` or a TOML file): its frame in counts, at its default
        exposure, with the measurement pipeline's patches, takes the lower right panel.
    panel : str
        The lower right panel otherwise: ``brdf`` (the Moon's BRDF map) or ``earth`` (the Earth seen
        from the Moon); a picked facet's own BRDF map, then an instrument's frame, take it first.
    """

    options: dict = field(default_factory=dict)
    phases: tuple | None = DEFAULT_PHASES
    times: tuple | None = None
    key: float | str = 90.0
    brdf: str = "dhg"
    band: str | None = None
    size: tuple = DEFAULT_SIZE
    picked: int | None = None
    instrument: str | None = None
    panel: str = "brdf"

    def __post_init__(self):
        extra = sorted(set(self.options) - set(SCENE_DEFAULTS))
        if extra:
            raise unknown_choice("scene option", extra[0], SCENE_DEFAULTS)
        own = sorted(set(self.options) & set(OWN))
        if own:
            raise LunarvizError(f"state option {own[0]!r}: the state's brdf and band say what is shown")
        if self.brdf not in BRDF_NAMES:
            raise unknown_choice("BRDF", self.brdf, BRDF_NAMES)
        if self.band is not None and (not isinstance(self.band, str) or not self.band.strip() or "," in self.band):
            raise LunarvizError(f"band {short_repr(self.band)}: one band (B, V, S2A-B4, 500-600, a file) or none")
        if (self.phases is None) == (self.times is None):
            raise LunarvizError("a state's slider holds phases or times: give one of them")
        keys = self.keys
        if not keys or len(keys) > MAX_KEYS:
            raise LunarvizError(f"the slider holds {len(keys)} values: give 1 to {MAX_KEYS}")
        if self.key not in keys:
            raise LunarvizError(f"key {short_repr(self.key)} is not among the slider's {short_repr(keys)}")
        w, h = self.size
        if not (MIN_SIZE[0] <= w <= 4096 and MIN_SIZE[1] <= h <= 4096):
            raise LunarvizError(f"size {short_repr(self.size)}: width {MIN_SIZE[0]}-4096 and height "
                                f"{MIN_SIZE[1]}-4096 pixels")
        if self.panel not in PANELS:
            raise unknown_choice("panel", self.panel, PANELS)
        if self.instrument is not None:
            from lunarviz.instrument.spec import load_instrument
            if not isinstance(self.instrument, str):
                raise LunarvizError(f"instrument {short_repr(self.instrument)}: a name (salex, bbso) or a TOML file")
            load_instrument(self.instrument)  # (an unknown one refused here, with the names it knows)
        if self.picked is not None and (isinstance(self.picked, bool) or not isinstance(self.picked, int)
                                        or self.picked < 0):
            raise LunarvizError(f"picked facet {short_repr(self.picked)} is not a facet number (0, 1, 2, ...)")

    def option(self, name: str):
        """Scene option ``name`` as this state runs it (its value, or the scene's default; the Moon's
        preset as the scene resolves it: the paper's in the θ scene, the fitted one on dates)."""
        value = self.options.get(name, SCENE_DEFAULTS[name])
        if name == "moon_model" and value is None:  # (the explorer traces: the ray tracer's rule)
            return default_moon_model(self.times is not None, "raytrace", self.option("h_function"), (self.brdf,))
        return value

    @property
    def keys(self) -> tuple:
        """The slider's values: θ [deg] or UTC labels."""
        return tuple(self.times) if self.times is not None else tuple(self.phases or ())

    @property
    def index(self) -> int:
        """The position of :attr:`key` on the slider."""
        return self.keys.index(self.key)

    def with_(self, **changes) -> "ExploreState":
        """A new state with ``changes``: fields of the state, or scene options (``moon_model=...``;
        ``None`` restores an option's default). A new slider range moves the key to its nearest value."""
        opts = dict(self.options)
        for name in [n for n in changes if n in SCENE_DEFAULTS]:
            value = changes.pop(name)
            if value is None or value == SCENE_DEFAULTS[name]:
                opts.pop(name, None)
            else:
                opts[name] = value
        new = {"options": opts, **changes}
        if ("phases" in changes or "times" in changes) and "key" not in changes:
            keys = tuple(changes.get("times") or ()) or tuple(changes.get("phases") or ())
            new["key"] = keys[min(self.index, len(keys) - 1)] if keys else self.key
        if "times" in changes and changes["times"] is not None:
            new.setdefault("phases", None)
        if "phases" in changes and changes["phases"] is not None:
            new.setdefault("times", None)
        return replace(self, **new)

    def scene(self) -> Scene:
        """The :class:`lunarviz.Scene` of the task on show (its one key), with the state's BRDF
        and band: what the numbers, the picture and ``sweep --state`` compute."""
        kw = {**self.options, "brdfs": (self.brdf,), "bands": (self.band,) if self.band else None}
        if self.times is not None:
            return Scene(time=str(self.key), **kw)
        return Scene(phases=[float(self.key)], **kw)

    def range_scene(self) -> Scene:
        """The :class:`lunarviz.Scene` of the whole slider range (the curves' rows)."""
        kw = {**self.options, "brdfs": (self.brdf,), "bands": (self.band,) if self.band else None}
        if self.times is not None:
            return Scene(time=list(self.times), **kw)
        return Scene(phases=list(self.phases), **kw)

    def task_key(self, key=None, band="same") -> str:
        """A text naming one task's computation (options, the key, BRDF and band; not the slider,
        the size or the pick): what its row and its traced view depend on. ``key``: another slider
        value; ``band``: another band (None: grey)."""
        return json.dumps([_plain(self.options), self.key if key is None else key, self.brdf,
                           self.band if band == "same" else band], sort_keys=True)

    def cache_key(self) -> str:
        """A text that two states share exactly when they show the same thing."""
        return json.dumps(self.to_dict(), sort_keys=True)

    def to_dict(self) -> dict:
        return {"lunarviz": FORMAT, "version": VERSION, "options": _plain(self.options),
                "phases": None if self.phases is None else list(self.phases),
                "times": None if self.times is None else list(self.times),
                "key": self.key, "brdf": self.brdf, "band": self.band, "size": list(self.size),
                "picked": self.picked, "instrument": self.instrument, "panel": self.panel}

    def save(self, path) -> Path:
        """Write the state as JSON (atomically)."""
        from lunarviz.outputs.writers import check_output_path, write_bytes_atomic
        path = check_output_path(path, (".json",))
        write_bytes_atomic(path, (json.dumps(self.to_dict(), indent=1, sort_keys=True) + "\n").encode())
        return path

    @classmethod
    def from_dict(cls, d) -> "ExploreState":
        if not isinstance(d, dict) or d.get("lunarviz") != FORMAT:
            raise LunarvizError(f"not an explorer state (no \"lunarviz\": \"{FORMAT}\" entry)")
        if type(d.get("version")) is not int or d.get("version") not in READS:
            raise LunarvizError(f"explorer state version {short_repr(d.get('version'))}: this lunarviz reads "
                                f"{', '.join(map(str, READS))}")
        extra = sorted(set(d) - {"lunarviz", "version", "options", "phases", "times", "key", "brdf", "band", "size",
                            "picked", "instrument", "panel"})
        if extra:
            raise LunarvizError(f"explorer state: unknown entry {extra[0]!r}")
        options = d.get("options") or {}
        if not isinstance(options, dict):
            raise LunarvizError(f"explorer state: options must be an object, got {short_repr(options)}")
        phases, times = d.get("phases"), d.get("times")
        if d["version"] == 1 and times is not None and "moon_model" not in options:
            options = {**options, "moon_model": THETA_MOON_MODEL}  # (version 1's default on dates)
        if phases is not None and times is not None:
            raise LunarvizError("explorer state: give phases (the θ scene) or times (dates), not both")
        for name, v in (("phases", phases), ("times", times), ("size", d.get("size", list(DEFAULT_SIZE)))):
            if v is not None and not isinstance(v, list):
                raise LunarvizError(f"explorer state: {name} must be a list, got {short_repr(v)}")
        if isinstance(d.get("key"), bool) or any(isinstance(v, bool) for v in (phases or []) + list(d.get("size", []))):
            raise LunarvizError("explorer state: key, phases and size are numbers, not true/false")
        try:
            phases = None if phases is None else tuple(float(p) for p in phases)
            times = None if times is None else tuple(str(t) for t in times)
            key = str(d["key"]) if times is not None else float(d["key"])
            size = tuple(int(v) for v in d.get("size", DEFAULT_SIZE))
        except (KeyError, TypeError, ValueError, OverflowError):
            raise LunarvizError("explorer state: phases, times, key or size malformed") from None
        if phases is not None and not all(math.isfinite(p) for p in phases):
            raise LunarvizError("explorer state: phases must be finite numbers")
        if len(size) != 2:
            raise LunarvizError(f"explorer state: size {short_repr(size)} is not [width, height]")
        state = cls(options=options, phases=None if times is not None else phases, times=times, key=key,
                    brdf=str(d.get("brdf", "dhg")), band=d.get("band"), size=size, picked=d.get("picked"),
                    instrument=d.get("instrument"), panel=d.get("panel", "brdf"))
        state.range_scene()  # every option and every slider value checked now, by the Scene itself
        state.scene()
        return state

    @classmethod
    def load(cls, path) -> "ExploreState":
        """Read a state file; a one-line error for anything that is not one."""
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise LunarvizError(f"cannot read state file {str(path)!r}: {exc.__class__.__name__}") from None
        if len(text) > 10_000_000:
            raise LunarvizError(f"state file {str(path)!r} is over 10 MB: not an explorer state")
        try:
            d = json.loads(text)
        except (ValueError, RecursionError):
            raise LunarvizError(f"state file {str(path)!r} is not JSON") from None
        inst = d.get("instrument") if isinstance(d, dict) else None
        if isinstance(inst, str) and inst.lower().endswith(".toml") and not Path(inst).is_absolute() \
                and (p.parent / inst).is_file():
            d["instrument"] = str(p.parent / inst)  # (a file named beside the state: found from anywhere)
        try:
            return cls.from_dict(d)
        except LunarvizError as exc:
            raise LunarvizError(f"state file {str(path)!r}: {exc}") from None


def _plain(v):
    """JSON types: tuples as lists, recursively."""
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


def state_from_scene(sc: Scene, key=None, brdf: str = "dhg", band: str | None = None,
                     size=DEFAULT_SIZE) -> ExploreState:
    """The state of a :class:`lunarviz.Scene` (the command line's options): its non-default options,
    its θ or dates as the slider, ``key`` (default the first) on show."""
    opts = {k: v for k, v in sc.options.items() if k not in OWN and v != SCENE_DEFAULTS[k]
            and not (k == "params" and not v)}
    keys = sc.keys
    if key is None:
        key = keys[0]
    if sc.times is not None:
        return ExploreState(options=_plain(opts), phases=None, times=tuple(keys), key=str(key), brdf=brdf, band=band,
                            size=tuple(size))
    phases = tuple(float(k) for k in keys)
    if len(phases) == 1:  # one θ given: the slider still spans the sweep's default range, through it
        phases = tuple(sorted(set(DEFAULT_PHASES) | set(phases)))
    return ExploreState(options=_plain(opts), phases=phases, times=None, key=float(key), brdf=brdf, band=band,
                        size=tuple(size))
