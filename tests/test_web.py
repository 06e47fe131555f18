"""`lunarviz view --web` for real: a server, a headless Chromium, screenshots.

The test starts the command line's server on a free port of 127.0.0.1, loads the page in
headless Chromium (Debian's ``chromium``, installed by ``scripts/install.sh test``), and
checks from the screenshots that the 3D scene is drawn (the Moon panel holds lit pixels on
its black background) and that moving the phase control re-traces and redraws it.
"""

from __future__ import annotations

import asyncio
import io
import os

import numpy as np
import pytest
from web_browser import Browser, chromium_path, lunarviz_server

pytestmark = [pytest.mark.skipif(chromium_path() is None and not os.environ.get("CI"),
                                 reason="no chromium here (CI installs it: scripts/install.sh test)"),
              # one server for the module's tests: they run on one worker (pytest-xdist's loadgroup)
              pytest.mark.xdist_group("web_server")]


@pytest.fixture(scope="module")
def web_server(tmp_path_factory):
    yield from lunarviz_server(["view", "--web", "--phase", "90", "--mesh-level", "3", "--size", "1200x700"],
                               tmp_path_factory.mktemp("web"))


def _moon_panel(png: bytes) -> np.ndarray:
    """The top-left panel of the 3D view (the Moon seen from the detector), as grey levels.

    The view is the black-background block under the numbers: its rows are those where most
    pixels are near black."""
    from PIL import Image
    a = np.asarray(Image.open(io.BytesIO(png)).convert("L")).astype(float)
    dark_rows = np.flatnonzero((a < 40).mean(axis=1) > 0.3)
    assert dark_rows.size > 100, "no 3D view (black panel) in the page"
    top, bottom = dark_rows[0], dark_rows[-1]
    return a[top:top + (bottom - top) // 2, : a.shape[1] // 4]


def test_web_viewer_draws_and_phase_control_redraws(web_server):
    async def run():
        async with Browser(1400, 900) as b:
            await b.goto(web_server)
            await b.wait_for("document.body && document.body.innerText.includes('phase theta = 90.0')", 90)
            await b.wait_for("document.querySelectorAll('img, canvas').length > 0", 30)
            await asyncio.sleep(3)  # the first server-rendered image
            first = await b.screenshot()
            # the phase slider's model: what dragging it sets (trame state "phase")
            await b.evaluate("window.trame.state.set('phase', 150); true")
            await b.wait_for("document.body.innerText.includes('phase theta = 150.0')", 120)
            await asyncio.sleep(3)
            second = await b.screenshot()
            return first, second

    first, second = asyncio.run(run())
    a, b = _moon_panel(first), _moon_panel(second)
    # the Moon is drawn: lit (bright) pixels on the black background; at θ = 90° about half
    # the disc is sunlit, at 150° a thin crescent
    lit_a, lit_b = (a > 150).mean(), (b > 150).mean()
    assert lit_a > 0.03
    assert lit_b < 0.6 * lit_a
    assert np.abs(a - b).mean() > 2.0


def test_web_viewer_refuses_the_default_secret(web_server):
    """wslink's public default secret ('wslink-secret', what a page without ?secret= presents)
    is refused: the page never gets a scene; with the run's own secret it does."""
    without = web_server.split("?", 1)[0]

    async def run():
        async with Browser(1000, 700) as b:
            await b.goto(without)
            # the client gives up on its refused connection within a second or two (it then shows
            # its connect() error); failing that, 15 s is time enough to connect, were it allowed
            try:
                await b.wait_for("document.body && document.body.innerText.includes('connect()')", 15)
            except TimeoutError:
                pass
            await asyncio.sleep(1)
            return await b.evaluate("document.body ? document.body.innerText : ''")

    text = asyncio.run(run())
    assert "phase theta" not in text  # the numbers come from the server: none without the secret
