"""The viewer in a browser: the composite view served by trame (PyVista's web backend).

``lunarviz view --web [--port P] [--host H]`` serves on 127.0.0.1 unless asked otherwise. The
picture is rendered on the server (VTK offscreen through EGL) and streamed as images, so the
browser needs no WebGL: it works from a headless server, through an SSH tunnel, or in a
notebook. A slider sets the phase θ (or steps through the given times) and a menu the BRDF;
each change re-traces the scene, as in the desktop viewer.
"""

from __future__ import annotations

import numpy as np

from lunarviz.errors import LunarvizWarning
from lunarviz.viz.view_data import ComputeView
from lunarviz.viz.views import build_plotter, numbers_text, populate

BRDFS = ("lambert", "shg", "dhg")


def _refresh(pl, data) -> None:
    for title in list(pl.scalar_bars.keys()):
        pl.remove_scalar_bar(title, render=False)
    for r in pl.renderers:
        r.clear_actors()
    populate(pl, data, "composite")
    pl.render()


def build_app(compute: ComputeView, key, brdf: str, times: tuple | None = None, size=(1600, 900), server=None):
    """A trame server showing task ``key`` (θ [deg], or one of a dated scene's ``times``) as
    ``compute(key, brdf)`` gives it; returns ``(server, plotter)``. ``server.state.phase`` (θ
    [deg], or the time's index) and ``server.state.brdf`` drive it."""
    from trame.app import get_server
    from trame.ui.vuetify3 import SinglePageLayout
    from trame.widgets import html
    from trame.widgets import vuetify3 as v3
    from trame_pyvista.ui import plotter_ui

    server = server or get_server("lunarviz", client_type="vue3")
    state, ctrl = server.state, server.controller
    times = tuple(times) if times else None
    data = compute(key, brdf)
    pl = build_plotter(data, "composite", size, off_screen=True)
    state.phase = times.index(key) if times else float(key)
    state.brdf = brdf
    state.numbers = numbers_text(data.numbers)
    state.busy = False

    @state.change("phase", "brdf")
    def _update(phase, brdf, **_):
        k = times[int(np.clip(round(float(phase)), 0, len(times) - 1))] if times else float(np.clip(phase, 0, 180))
        state.busy = True
        new = compute(k, brdf)
        _refresh(pl, new)
        state.numbers = numbers_text(new.numbers)
        state.busy = False
        ctrl.view_update()

    with SinglePageLayout(server, full_height=True) as layout:
        layout.title.set_text("lunarviz")
        with layout.toolbar:
            v3.VSpacer()
            if times:
                v3.VSlider(v_model=("phase", state.phase), min=0, max=len(times) - 1, step=1,
                           label="time index", hide_details=True, thumb_label="always", density="compact",
                           style="max-width: 480px")
                html.Span("time index {{ phase }}", style="margin: 0 12px; white-space: nowrap;")
            else:
                v3.VSlider(v_model=("phase", state.phase), min=0, max=180, step=5, label="phase θ [deg]",
                           hide_details=True, thumb_label="always", density="compact", style="max-width: 480px")
                html.Span("θ = {{ phase }}°", style="margin: 0 12px; white-space: nowrap;")
            v3.VSelect(v_model=("brdf", brdf), items=("brdfs", list(BRDFS)), label="BRDF", hide_details=True,
                       density="compact", style="max-width: 160px")
            v3.VProgressCircular(indeterminate=True, v_show=("busy",), size=20)
        with layout.content:
            html.Pre("{{ numbers }}", style="font-size: 11px; margin: 4px 12px; line-height: 1.3;")
            with html.Div(style="position: relative; width: 100%; height: calc(100vh - 190px); min-height: 400px;"):
                view = plotter_ui(pl, mode="server", add_menu=False, server=server)
                ctrl.view_update = view.update
    return server, pl


#: the largest message a viewer client may send [bytes]: its messages are state changes of a few
#: hundred bytes; wslink lets an authenticated client announce 4 GiB, which it allocates at once
MAX_CLIENT_MESSAGE_BYTES = 16 << 20


def cap_client_messages() -> None:
    """In this (server) process, cap what wslink allocates for a client's message: a chunk
    header announcing more than :data:`MAX_CLIENT_MESSAGE_BYTES` is refused, logged in or not."""
    from wslink import chunking

    def capped(self, size):
        self.max_message_size = min(int(size), MAX_CLIENT_MESSAGE_BYTES)
    chunking.UnChunker.set_max_message_size = capped


def serve_app(server, command: str, what: str, host: str = "127.0.0.1", port: int = 0) -> None:
    """Serve a trame ``server`` until interrupted (port 0: a free port, printed at start).

    Each run has its own random secret, printed in the URL it serves (``?secret=...``); a
    client that presents any other, wslink's public default ``wslink-secret`` included, is
    refused. Binding to an interface other than the loopback prints a warning: anyone who can
    reach it and has the URL drives ``what``. ``command`` names the command in what is printed."""
    import secrets
    import warnings

    cap_client_messages()
    secret = secrets.token_urlsafe(24)
    server.cli.set_defaults(authKey=secret, authKeyFile=None)  # trame configures wslink from these
    if host not in ("127.0.0.1", "localhost", "::1"):
        warnings.warn(f"{command} is listening on {host}: anyone who can reach it and has the URL "
                      f"(with its secret) can drive {what}", LunarvizWarning, stacklevel=3)

    def announce(**_):
        print(f"{command}: serving on http://{host}:{server.port}/?secret={secret} (Ctrl-C stops)", flush=True)
    server.controller.on_server_ready.add(announce)
    server.start(host=host, port=port, open_browser=False, show_connection_info=False)


def serve(compute: ComputeView, key, brdf: str, times: tuple | None = None, host: str = "127.0.0.1", port: int = 0,
          size=(1600, 900)):
    """Serve the viewer until interrupted (:func:`serve_app`)."""
    server, _ = build_app(compute, key, brdf, times, size=size)
    serve_app(server, "lunarviz view --web", "the viewer", host, port)
