"""The explorer in a desktop window (Tk): the picture, the slider with play and step buttons, the
menus of :data:`~lunarviz.explore.controls.CONTROLS`, Save (the state as JSON and its picture as
PNG) and a status line. The window never waits for the tracer: frames arrive from the engine's
thread through a queue the window reads every 30 ms; a click on the Moon panel picks a facet.
"""

from __future__ import annotations

import queue

from lunarviz.explore.controls import CONTROLS, Explorer, choice_text, choice_value, state_value
from lunarviz.explore.state import ExploreState

#: how often the window looks for new frames and advances a playing slider [ms]
POLL_MS = 30
#: a playing slider's step [ms]
PLAY_MS = 400


class DesktopExplorer:
    """The Tk window over an :class:`~lunarviz.explore.controls.Explorer` (``root``: a ``tk.Tk``)."""

    def __init__(self, root, state: ExploreState, background: bool = True):
        import tkinter as tk
        from tkinter import ttk
        self.tk, self.ttk, self.root = tk, ttk, root
        self.frames: queue.Queue = queue.Queue()
        self.playing = False
        self.explorer = Explorer(state, on_frame=self.frames.put, background=background)
        root.title("lunarviz explore")
        bar = ttk.Frame(root, padding=4)
        bar.pack(side="top", fill="x")
        self.menus = {}
        for c in CONTROLS:
            box = ttk.Frame(bar)
            box.pack(side="left", padx=3)
            ttk.Label(box, text=c.label).pack(anchor="w")
            var = tk.StringVar(value=choice_text(c, state_value(state, c.name)))
            widget = ttk.Combobox(box, textvariable=var, values=[t for t, _ in c.choices], width=max(
                10, min(26, max(len(t) for t, _ in c.choices))), state="normal" if c.editable else "readonly")
            widget.pack()
            widget.bind("<<ComboboxSelected>>", lambda _e, c=c, v=var: self._set(c, v.get()))
            widget.bind("<Return>", lambda _e, c=c, v=var: self._set(c, v.get()))
            self.menus[c.name] = var
        ttk.Button(bar, text="Save", command=self.save).pack(side="right", padx=3)
        slide = ttk.Frame(root, padding=(4, 0))
        slide.pack(side="top", fill="x")
        for text, k in (("◀", -1), ("▶", 1)):
            ttk.Button(slide, text=text, width=3, command=lambda k=k: self.explorer.step(k)).pack(side="left")
        self.play_button = ttk.Button(slide, text="play", width=5, command=self.toggle_play)
        self.play_button.pack(side="left")
        self.slider = tk.Scale(slide, from_=0, to=len(state.keys) - 1, orient="horizontal", showvalue=False,
                               command=lambda v: self.explorer.show(int(float(v))))
        self.slider.set(state.index)
        self.slider.pack(side="left", fill="x", expand=True, padx=4)
        self.key_label = ttk.Label(slide, width=26)
        self.key_label.pack(side="left")
        self.picture = tk.Label(root, bg="black")
        self.picture.pack(side="top")
        self.picture.bind("<Button-1>", lambda e: self.explorer.pick(e.x, e.y))
        self.status = ttk.Label(root, anchor="w", padding=4)
        self.status.pack(side="top", fill="x")
        self._photo = None
        root.after(POLL_MS, self._poll)

    def _set(self, control, text: str) -> None:
        if not self.explorer.set(control.name, choice_value(control, text)):
            self.menus[control.name].set(choice_text(control, state_value(self.explorer.state, control.name)))

    def toggle_play(self) -> None:
        self.playing = not self.playing
        self.play_button.config(text="stop" if self.playing else "play")
        if self.playing:
            self.root.after(PLAY_MS, self._advance)

    def _advance(self) -> None:
        if self.playing:
            st = self.explorer.state
            self.explorer.show((st.index + 1) % len(st.keys))
            self.root.after(PLAY_MS, self._advance)

    def save(self, path: str | None = None) -> None:
        """Save the state (JSON) and its converged picture (PNG, as ``lunarviz render --state`` makes it)."""
        from tkinter import filedialog
        path = path or filedialog.asksaveasfilename(defaultextension=".json", filetypes=[("explorer state", "*.json")])
        if path:
            self.explorer.save(path)
            self.status.config(text=f"saving {path} and its picture ...")

    def _poll(self) -> None:
        frame = None
        while not self.frames.empty():
            frame = self.frames.get_nowait()
        if frame is not None and frame.state != self.explorer.state:
            frame = None  # a superseded state's frame (queued before the newest change): not shown
        if frame is not None:
            from PIL import Image, ImageTk
            self._photo = ImageTk.PhotoImage(Image.fromarray(frame.image))
            self.picture.config(image=self._photo)
            self.slider.set(frame.state.index)
            self.key_label.config(text=str(frame.state.key) + ("" if frame.state.times else " deg"))
            for c in CONTROLS:  # the menus follow the state shown (a refused change put back)
                self.menus[c.name].set(choice_text(c, state_value(self.explorer.state, c.name)))
        st = self.explorer
        shown = st.frame
        self.status.config(text=st.message or ("" if shown is None else
                                               f"{shown.quality} picture in {shown.seconds:.2f} s"
                                               + (f"   {shown.error}" if shown.error else "")) + st.saved_note)
        self.root.after(POLL_MS, self._poll)


def run_desktop(state: ExploreState) -> None:
    """Open the explorer's window on ``state``; returns when it is closed."""
    import tkinter as tk
    root = tk.Tk()
    app = DesktopExplorer(root, state)
    try:
        root.mainloop()
    finally:
        app.explorer.close()
