"""The explorer in a browser or a notebook (trame, ``lunarviz explore --web``): the same menus,
slider, picking and Save as the desktop window (:mod:`lunarviz.explore.desktop`), the picture
streamed as PNG. The page never waits for the tracer: frames arrive from the engine's thread
through a queue that a task on the server's loop reads every 30 ms.
"""

from __future__ import annotations

import asyncio
import base64
import queue

from lunarviz.explore.controls import CONTROLS, Explorer, state_value
from lunarviz.explore.state import ExploreState

#: how often the page's state looks for new frames [s], and a playing slider's step [s]
POLL_S, PLAY_S = 0.03, 0.4
#: the menus' value for "none" (a band of None: grey), as the browser holds it
NONE = "(none)"


def _png_url(img) -> str:
    import io

    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", compress_level=1)  # (fast; lossless: the pixels render --state makes)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


def _items(control) -> list[dict]:
    return [{"title": t, "value": NONE if v is None else v} for t, v in control.choices]


def build_app(state: ExploreState, server=None, background: bool = True):
    """A trame server showing the explorer on ``state``; returns ``(server, explorer)``."""
    from trame.app import get_server

    server = server or get_server("lunarviz-explore", client_type="vue3")
    st, ctrl = server.state, server.controller
    frames: queue.Queue = queue.Queue()
    explorer = Explorer(state, on_frame=frames.put, background=background)
    st.update({"picture": "", "index": state.index, "key_label": "", "status": "computing ...", "playing": False,
               "n_keys": len(state.keys), "save_path": "lunarviz_view.json", "frames_shown": 0, "shown": {}})
    for c in CONTROLS:
        v = state_value(state, c.name)
        st[c.name] = NONE if v is None else v

    def on_control(name):
        def changed(**kw):
            value = kw[name]
            value = None if value == NONE else value
            if value != state_value(explorer.state, name) and not explorer.set(name, value):
                st[name] = NONE if state_value(explorer.state, name) is None else state_value(explorer.state, name)
            st.status = explorer.message or st.status
        return changed
    for c in CONTROLS:
        st.change(c.name)(on_control(c.name))

    @st.change("index")
    def _index(index, **_):
        if int(index) != explorer.state.index:
            explorer.show(int(index))

    @ctrl.trigger("pick")
    def _pick(x, y):
        explorer.pick(float(x), float(y))

    @ctrl.trigger("step")
    def _step(k):
        explorer.step(int(k))

    @ctrl.trigger("save")
    def _save():
        explorer.save(st.save_path)

    async def pump():
        ticks = 0
        while True:
            frame = None
            while not frames.empty():
                frame = frames.get_nowait()
            if frame is not None and frame.state != explorer.state:
                frame = None  # a superseded state's frame (queued before the newest change): not shown
            ticks += 1
            with st:
                if frame is not None:
                    st.picture = _png_url(frame.image)
                    st.index = frame.state.index
                    st.key_label = str(frame.state.key) + ("" if frame.state.times else " deg")
                    st.frames_shown += 1
                    st.shown = {"key": frame.state.key, "brdf": frame.state.brdf, "band": frame.state.band or NONE,
                                "picked": frame.state.picked, "quality": frame.quality,
                                "instrument": frame.state.instrument or NONE, "panel": frame.state.panel,
                                "rows": sum(r is not None for r in frame.series), **frame.state.options}
                    for c in CONTROLS:  # the menus follow the state (a refused change put back)
                        v = state_value(explorer.state, c.name)
                        st[c.name] = NONE if v is None else v

                shown = explorer.frame
                status = (explorer.message or ("computing ..." if shown is None else
                                               f"{shown.quality} picture in {shown.seconds:.2f} s"
                                               + (f"   {shown.error}" if shown.error else ""))) + explorer.saved_note
                if status != st.status:
                    st.status = status
                if st.playing and ticks % round(PLAY_S / POLL_S) == 0:
                    explorer.show((explorer.state.index + 1) % len(explorer.state.keys))
            await asyncio.sleep(POLL_S)
    ctrl.on_server_ready.add(lambda **_: asyncio.ensure_future(pump()))

    _layout(server, state)
    return server, explorer


def _layout(server, state: ExploreState) -> None:
    """The page: the menus in the toolbar; the step and play buttons, the slider, Save; the picture
    (a click picks a facet) and the status line."""
    from trame.ui.vuetify3 import SinglePageLayout
    from trame.widgets import html
    from trame.widgets import vuetify3 as v3

    with SinglePageLayout(server, full_height=True) as layout:
        layout.title.set_text("lunarviz explore")
        with layout.toolbar:
            v3.VSpacer()
            for c in CONTROLS:
                (v3.VCombobox if c.editable else v3.VSelect)(
                    v_model=(c.name,), items=(f"items_{c.name}", _items(c)), label=c.label, hide_details=True,
                    density="compact", style="max-width: 190px; margin: 0 3px;",
                    **({"item_title": "title", "item_value": "value", "return_object": False} if c.editable else {}))
        with layout.content:
            with html.Div(style="display: flex; align-items: center; margin: 4px 8px; gap: 6px;"):
                v3.VBtn("◀", click="trigger('step', [-1])", density="compact", classes="step_back")
                v3.VBtn("▶", click="trigger('step', [1])", density="compact", classes="step_fwd")
                v3.VBtn("{{ playing ? 'stop' : 'play' }}", click="playing = !playing", density="compact",
                        classes="play")
                v3.VSlider(v_model=("index",), min=0, max=("n_keys - 1",), step=1, hide_details=True,
                           density="compact", classes="key_slider")
                html.Span("{{ key_label }}", style="white-space: nowrap; min-width: 210px;")
                v3.VTextField(v_model=("save_path",), hide_details=True, density="compact", label="state file",
                              style="max-width: 220px;")
                v3.VBtn("Save", click="trigger('save')", density="compact", classes="save")
            html.Img(src=("picture",), classes="explore_picture",
                     style=f"display: block; width: {state.size[0]}px; height: {state.size[1]}px; margin: 0 8px;",
                     click="trigger('pick', [$event.offsetX, $event.offsetY])")
            html.Div("{{ status }}", classes="explore_status", style="margin: 4px 8px; font-family: monospace;")


def serve(state: ExploreState, host: str = "127.0.0.1", port: int = 0) -> None:
    """Serve the explorer until interrupted, with a random secret in its URL, as ``lunarviz view
    --web`` (:func:`lunarviz.viz.web.serve_app`)."""
    from lunarviz.viz.web import serve_app
    server, explorer = build_app(state)
    try:
        serve_app(server, "lunarviz explore --web", "the explorer", host, port)
    finally:
        explorer.close()
