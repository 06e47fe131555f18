"""The explorer's worker: a state's numbers and picture, computed off the window's thread.

A control change calls :meth:`Engine.request`, which returns at once. One worker thread then
makes, for the newest request only (a newer one supersedes it between steps):

1. a **first** frame: the numbers of the paper's point-source method (``analytic``: milliseconds)
   and the Moon traced on a mesh two levels coarser, said so on the picture;
2. the **converged** frame: the ray tracer's row (the same :func:`~lunarviz.workflows.sweeps.run_phase`
   call as ``lunarviz sweep``, its ``rtol`` bound shown) and the picture on the scene's own mesh.

Frames already made return at once from a bounded cache (:data:`CACHE_FRAMES`). A second thread,
the **background pass**, has the rows of every slider value (the curves) computed, nearest first,
in a process of its own at the lowest priority, so the worker never waits for it and scrubbing over
a computed range shows its curves at once; the state on show is repainted as they complete. Every
frame goes to the ``on_frame`` callback (from the worker's thread: a window posts it to its own loop).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace

import numpy as np

from lunarviz.caches import BoundedCache
from lunarviz.errors import LunarvizError
from lunarviz.explore.state import ExploreState
from lunarviz.options import DEFAULT_LEVELS

#: frames kept (a frame holds its picture, ~3 MB at 1280×800, and its view: ~8 MB at the Moon's level 4,
#: ×4 a level)
CACHE_FRAMES = 32
#: rows kept (one per slider value, BRDF, band and scene)
CACHE_ROWS = 20_000
#: options of the tracer's meshes, which the point-source method (the first frame's numbers) refuses
MESH_ONLY = ("mesh_units", "moon_level", "earth_level", "sun_level", "shading", "self_shadow")
#: the first frame's Moon mesh: this many levels under the scene's own (at least level 2)
COARSER_LEVELS = 2


@dataclass
class Frame:
    """What the explorer shows for one state at one quality.

    ``quality`` is ``"first"`` (point-source numbers, a coarser Moon) or ``"converged"`` (the ray
    tracer's row and the scene's own mesh); ``row`` the sweep row shown; ``series`` the rows of the
    slider range computed so far (None where a value is not yet); ``image`` the picture (RGB);
    ``seconds`` what it took; ``error`` a one-line message where the state cannot be computed."""

    state: ExploreState
    quality: str
    row: dict | None = None
    series: list = field(default_factory=list)
    image: np.ndarray | None = None
    seconds: float = 0.0
    error: str | None = None
    #: what the 3-D panels drew (:class:`~lunarviz.viz.view_data.ViewData`): picking reads it
    view: object = None


def pick_row(rows: list[dict], state: ExploreState) -> dict:
    """The row of ``rows`` (one task's) for the state's BRDF and band."""
    for r in rows:
        if r.get("brdf") == state.brdf and (state.band is None or r.get("band") == state.band):
            return r
    raise LunarvizError(f"no row for BRDF {state.brdf!r} and band {state.band!r}")


class Engine:
    """Computes frames of states on a worker thread (see the module's text).

    Parameters
    ----------
    on_frame : callable
        ``on_frame(frame)``, called from the worker thread for every frame made.
    painter : object, optional
        A :class:`~lunarviz.explore.picture.Painter` (made on the worker's thread when omitted).
    background : bool
        Run the background pass over the slider's range.
    """

    def __init__(self, on_frame=None, painter=None, background: bool = True, start: bool = True):
        self.on_frame = on_frame or (lambda frame: None)
        self._painters = {} if painter is None else {threading.get_ident(): painter}
        self._frames = BoundedCache(CACHE_FRAMES)
        self._rows = BoundedCache(CACHE_ROWS)
        self._views = BoundedCache(CACHE_FRAMES)
        self._instrument_frames = BoundedCache(8)
        self._seen = BoundedCache(CACHE_FRAMES)  # each state's newest converged frame, its curves as they were
        #: one computation at a time (the worker's and the background pass's): the tracer and VTK
        #: each take both cores, and an OpenGL context is not shared between threads
        self._compute = threading.RLock()
        self._lock = threading.Condition()
        self._wanted: ExploreState | None = None
        self._generation = 0
        self._busy = False
        self._closed = False
        self._shown: ExploreState | None = None
        if start:  # (without: frames made on the caller's thread only, by :meth:`frame`)
            threading.Thread(target=self._work, name="lunarviz-explore", daemon=True).start()
            if background:
                threading.Thread(target=self._background, name="lunarviz-explore-bg", daemon=True).start()

    # ---- the window's side -------------------------------------------------------------------
    def request(self, state: ExploreState) -> None:
        """Ask for ``state``'s frames; returns at once (a newer request supersedes this one)."""
        with self._lock:
            self._wanted = self._shown = state
            self._generation += 1
            self._lock.notify_all()

    def _repaint(self, state: ExploreState) -> bool:
        """Make ``state``'s frames again (its curves now complete), unless a newer state was asked
        for meanwhile (True: done, or no longer wanted) or work is in flight (False: the caller
        tries again): decided under the lock, so it never supersedes a newer request. A state asked
        for again as a new but equal object (the browser's page re-sends its state) is the same
        state: compared by what its frames show (``cache_key``), not by identity, else a frame made
        before its last curve came would stay on show."""
        with self._lock:
            if self._shown is None or self._shown.cache_key() != state.cache_key():
                return True
            state = self._shown
            if self._wanted is None and not self._busy:
                self._wanted = state
                self._generation += 1
                self._lock.notify_all()
                return True
            return False

    def wait_idle(self, timeout: float = 600.0) -> bool:
        """Block until the newest request's converged frame is made (tests, benchmarks, screenshots)."""
        end = time.monotonic() + timeout
        with self._lock:
            while self._wanted is not None or self._busy:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._lock.wait(left)
        return True

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self._lock.notify_all()

    # ---- computing (any thread) --------------------------------------------------------------
    def frame(self, state: ExploreState, quality: str = "converged", full_series: bool = False) -> Frame:
        """The frame of ``state`` at ``quality``, made on the calling thread (cached). With
        ``full_series`` every slider value's row is computed first (the picture ``render --state``
        makes; the window's own converged frame shows the rows computed so far)."""
        key = self._frame_key(state, quality, full_series)
        hit = self._frames.get(key)
        if hit is not None:
            return hit
        with self._compute:
            return self._make_frame(state, quality, full_series, key)

    def _frame_key(self, state: ExploreState, quality: str, full_series: bool) -> tuple:
        """A frame's cache key: its state, quality and, for a converged frame, how many rows its
        curves hold (the background pass adds them: a frame drawn with fewer is made again)."""
        return state.cache_key(), quality, full_series, self.series_done(state) if quality == "converged" else 0

    def _make_frame(self, state: ExploreState, quality: str, full_series: bool, key) -> Frame:
        t0 = time.perf_counter()
        try:
            if full_series:
                for k in state.keys:
                    if (state.task_key(k), "converged") not in self._rows:
                        self.row(state.with_(key=k), "converged")
            row = self.row(state, quality)
            series = [self._rows.get((state.task_key(k), "converged")) for k in state.keys]
            view = self._view(state, quality)
            model = None if state.picked is None or quality != "converged" else \
                state.scene().settings("raytrace").brdf_models()[state.brdf]
            frame = None
            if state.instrument is not None and quality == "converged" and state.picked is None:
                frame = self._instrument_frames.get((state.task_key(band=None), state.instrument))
                if frame is None:
                    frame = instrument_frame(state)
                    self._instrument_frames[(state.task_key(band=None), state.instrument)] = frame
            image = self.painter().paint(state, quality, row, series, view, model, frame)
            out = Frame(state, quality, row, series, image, time.perf_counter() - t0, view=view)
        except Exception as exc:  # noqa: BLE001 (the window's worker must outlive any state: it shows why)
            why = str(exc) if isinstance(exc, LunarvizError) else f"{type(exc).__name__}: {exc}"
            out = Frame(state, quality, error=why, seconds=time.perf_counter() - t0)
            out.image = self.painter().paint_error(state, why)
        if out.error is None and (not full_series or all(r is not None for r in out.series)):
            self._frames[self._frame_key(state, quality, full_series)] = out  # (its own row now counted)
        return out

    def row(self, state: ExploreState, quality: str = "converged") -> dict:
        """The sweep row of ``state``'s task (``analytic`` for the first frame, else ``raytrace``):
        what ``lunarviz sweep --state`` computes for it."""
        key = (state.task_key(), quality)
        hit = self._rows.get(key)
        if hit is not None:
            return hit
        if quality == "first":  # the paper's point sources on exact spheres: the tracer's mesh options dropped
            if any(state.options.get(f"{b}_mesh") for b in ("moon", "earth", "sun")):
                return {}  # (a user's mesh: no sphere stands for it; the converged row only)
            state = state.with_(**{k: None for k in MESH_ONLY})
        row = state_row(state, "analytic" if quality == "first" else "raytrace")
        self._rows[key] = row
        return row

    def series_done(self, state: ExploreState) -> int:
        """How many of the slider's values have their converged row."""
        return sum((state.task_key(k), "converged") in self._rows for k in state.keys)

    def painter(self):
        """This thread's painter (an OpenGL context belongs to the thread that made it)."""
        me = threading.get_ident()
        if me not in self._painters:
            from lunarviz.explore.picture import Painter
            self._painters[me] = Painter()
        return self._painters[me]

    def _view(self, state: ExploreState, quality: str):
        """What the 3-D panels draw: the task traced per facet (grey), on a coarser Moon first."""
        from lunarviz.workflows.tasks import view_data
        key = (state.task_key(band=None), quality)
        hit = self._views.get(key)
        if hit is not None:
            return hit
        sc = state.with_(band=None, picked=None)
        if quality == "first":
            level = state.options.get("moon_level") or DEFAULT_LEVELS["moon"]
            if state.options.get("moon_mesh") is None:
                sc = sc.with_(moon_level=max(2, int(level) - COARSER_LEVELS))
        scene = sc.scene()
        settings = replace(scene.settings("raytrace"), brdfs=(state.brdf,))
        self._views[key] = out = view_data(settings, scene.keys[0], state.brdf,
                                                  quick=True if quality == "first" else "picture")
        return out

    # ---- threads ------------------------------------------------------------------------------
    def _take(self):
        with self._lock:
            while self._wanted is None and not self._closed:
                self._lock.wait()
            if self._closed:
                return None, None
            state, gen = self._wanted, self._generation
            self._wanted = None
            self._busy = True
            return state, gen

    def _current(self, gen: int) -> bool:
        with self._lock:
            return gen == self._generation

    def _work(self) -> None:
        while True:
            state, gen = self._take()
            if state is None:
                return
            try:
                seen = self._seen.get(state.cache_key())
                for quality in ("first", "converged"):
                    if quality == "first" and seen is not None:
                        self.on_frame(seen)  # seen before: its converged frame at once (its curves redrawn next
                        continue             # where rows came since)
                    if not self._current(gen):
                        break
                    frame = self.frame(state, quality)
                    if frame is not seen:
                        self.on_frame(frame)
                    if quality == "converged" and frame.error is None:
                        self._seen[state.cache_key()] = frame
            finally:
                with self._lock:
                    self._busy = False
                    self._lock.notify_all()

    def _background(self) -> None:
        """Rows of every slider value of the state on show, nearest first, computed in a process of
        its own at the lowest priority (:func:`_background_row`): the window's worker never waits
        for it, and the operating system gives it only what the worker leaves; the state on show is
        repainted as its curves fill in."""
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor
        try:  # a band's first use imports speclite (~0.7 s): done here, before a user asks for one
            import speclite.filters  # noqa: F401
        except ImportError:
            pass
        done: set = set()
        pending = None  # a state whose curves filled in while the worker was busy: repainted when it is not
        # (spawned, not forked: this process holds threads and OpenGL contexts)
        spawn = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(1, mp_context=spawn, initializer=_lowest_priority) as pool:
            while True:
                with self._lock:
                    if self._closed:
                        return
                if pending is not None and self._repaint(pending):
                    pending = None
                state = self._shown
                try:
                    todo = None if state is None else self._next_task(state, done)
                except LunarvizError:  # (a state its own checks refuse now, e.g. its instrument file gone)
                    todo = None
                if todo is None:
                    time.sleep(0.05)
                    continue
                done.add(todo.task_key())
                try:
                    row = pool.submit(state_row, todo).result()
                except Exception:  # noqa: BLE001,S112 (a value that fails here fails again, shown, when asked for)
                    continue
                self._rows[(todo.task_key(), "converged")] = row
                if self.series_done(state) == len(state.keys) and not self._repaint(state):
                    pending = state  # its curves complete: painted again once the worker is free

    def _next_task(self, state: ExploreState, done: set):
        """The next slider value of ``state`` whose converged row is not yet known, nearest first."""
        keys = state.keys
        for i in sorted(range(len(keys)), key=lambda i: abs(i - state.index)):
            task = state.task_key(keys[i])
            if (task, "converged") not in self._rows and task not in done:
                return state.with_(key=keys[i], picked=None)
        return None


def _lowest_priority() -> None:
    """The background process's start: the lowest scheduling priority (where the system has one),
    and a watch on its parent: killed, it leaves no orphan waiting on its pipe."""
    import os
    try:
        os.nice(19)
    except (AttributeError, OSError):
        pass
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(0)
    threading.Thread(target=watch, name="lunarviz-explore-parent", daemon=True).start()


def state_picture(state: ExploreState) -> np.ndarray:
    """The converged picture of ``state`` with its curves complete, made on this thread: what
    ``lunarviz render --state`` and ``lunarviz explore --screenshot`` write, and the explorer saves."""
    engine = Engine(background=False, start=False)
    frame = engine.frame(state, "converged", full_series=True)
    engine.painter().close()
    if frame.error is not None:
        raise LunarvizError(frame.error)
    return frame.image


def instrument_frame(state: ExploreState) -> dict:
    """The frame of ``state``'s instrument in counts [ADU] at its default exposure, noise-free (the
    same :func:`~lunarviz.workflows.measurement.observation` as ``lunarviz image --instrument``),
    and the measurement pipeline's patches on it (earthlit, sunlit, sky: ``None`` where the
    pipeline cannot select them, with ``note`` saying why)."""
    from lunarviz.instrument.disc import masked_pixels
    from lunarviz.instrument.observation import instrument_camera
    from lunarviz.instrument.pipeline import select_patches
    from lunarviz.instrument.spec import load_instrument
    from lunarviz.workflows.measurement import instrument_scene, observation
    inst = load_instrument(state.instrument)
    scene = state.with_(band=None, picked=None).scene()
    settings, key = scene.settings("raytrace"), scene.keys[0]
    out = {"name": inst.name, "band": inst.band, "exposure_s": None, "counts": None, "patches": None, "note": "",
           "full_well_adu": inst.bias_adu + inst.full_well_e / inst.gain_e_per_adu, "saturate_adu": inst.saturate_adu}
    try:  # (the pipeline refuses a Moon too full or too thin for its patches before tracing: said, not shown)
        obs = observation(settings, key, inst, None)
    except LunarvizError as exc:
        out["note"] = str(exc)
        return out
    out.update(exposure_s=obs.exposure_s, counts=obs.expected_counts)
    geom, _, masked = masked_pixels(instrument_scene(settings, inst).geometry(key), instrument_camera(inst),
                                    inst.bright_side_nd, inst.margin_px())
    try:
        out["patches"] = select_patches(geom, obs.raw_rates["moonshine"] > 0, inst.margin_px(), masked)
    except LunarvizError as exc:
        out["note"] = str(exc)
    return out


def state_row(state: ExploreState, method: str = "raytrace") -> dict:
    """The sweep row of ``state``'s task by ``method``: :func:`~lunarviz.workflows.sweeps.run_phase` on
    the state's one-task scene, as ``lunarviz sweep --state`` runs it."""
    from lunarviz.workflows.sweeps import run_phase
    scene = state.scene()
    return pick_row(run_phase(scene.settings(method), scene.keys[0]), state)
