"""``lunarviz explore --web`` for real: a server, a headless Chromium, screenshots.

The command line's server is started on a free port of 127.0.0.1 on a coarse Moon (level 3, so a
converged picture takes well under a second); the page is loaded in headless Chromium
(``tests/web_browser.py``) and each kind of control is set through the page's state (what
moving a slider or choosing in a menu sets). From the picture the page shows (its ``img``, read
back as PNG) the test checks that the panels a control should change do change and the others
hold, and that a click on the Moon picks a facet (its red paths appear in the schematic).
"""

from __future__ import annotations

import asyncio
import base64
import io
import os
import subprocess
import sys

import numpy as np
import pytest
from web_browser import Browser, chromium_path, lunarviz_server

pytestmark = [pytest.mark.skipif(chromium_path() is None and not os.environ.get("CI"),
                                 reason="no chromium here (CI installs it: scripts/install.sh test)"),
              pytest.mark.xdist_group("web_server")]

SIZE = (1000, 640)
KEYS = (30.0, 60.0, 90.0, 120.0, 150.0)


@pytest.fixture(scope="module")
def explore_server(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("explore")
    for url in lunarviz_server(["explore", "--web", "--phases", "30:150:30", "--mesh-level", "3", "--size",
                                f"{SIZE[0]}x{SIZE[1]}"], tmp, cwd=tmp):
        yield url, tmp


async def _picture(b, condition: str) -> np.ndarray:
    """The page's picture once the state it shows (``shown``, a JavaScript object) meets
    ``condition`` and is converged (grey levels)."""
    from PIL import Image
    await b.wait_for("(() => { const shown = window.trame.state.get('shown') || {};"
                     f" return shown.quality === 'converged' && ({condition}); }})()", 120)
    url = await b.evaluate("window.trame.state.get('picture')")
    img = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("L")
    return np.asarray(img).astype(float)


def _panels(a: np.ndarray) -> dict:
    """The picture's parts: the four 3-D panels (2×2 over 62 % of the width) and the curves."""
    h, w = a.shape
    w3 = int(w * 0.62) // 2 * 2
    return {"moon": a[:h // 2, :w3 // 2], "earthshine": a[:h // 2, w3 // 2:w3], "rays": a[h // 2:, :w3 // 2],
            "brdf_map": a[h // 2:, w3 // 2:w3], "curves": a[:, w3:]}


def _changed(a, b) -> set:
    pa, pb = _panels(a), _panels(b)
    return {k for k in pa if np.abs(pa[k] - pb[k]).mean() > 0.3}


def test_explorer_controls_change_the_right_panels(explore_server):
    url, tmp = explore_server

    async def run():
        async with Browser(1400, 900) as b:
            await b.goto(url)
            await b.wait_for("window.trame && window.trame.state && window.trame.state.get('picture')", 120)
            pics = {"start": await _picture(b, "shown.key === 30")}
            # the curves complete (the background pass), then Save: the state and the page's picture
            saved = await _picture(b, f"shown.key === 30 && shown.rows === {len(KEYS)}")
            await b.evaluate("window.trame.state.set('save_path', 'saved.json'); true")
            await b.evaluate("window.trame.trigger('save'); true")
            await b.wait_for("(window.trame.state.get('status') || '').includes('saved')", 120)
            await b.evaluate("window.trame.state.set('index', 3); true")  # θ: 30° → 120°
            pics["theta"] = await _picture(b, "shown.key === 120")
            await b.evaluate("window.trame.state.set('brdf', 'lambert'); true")
            pics["brdf"] = await _picture(b, "shown.brdf === 'lambert'")
            await b.evaluate("window.trame.state.set('band', 'V'); true")
            pics["band"] = await _picture(b, "shown.band === 'V'")
            await b.evaluate("window.trame.state.set('instrument', 'salex'); true")
            pics["instrument"] = await _picture(b, "shown.instrument === 'salex'")
            await b.evaluate("window.trame.state.set('earth_surface', 'landocean'); true")
            pics["earth"] = await _picture(b, "shown.earth_surface === 'landocean'")
            # a click on the Moon panel, on the disc (its centre is left of the panel's: room for the bar)
            await b.evaluate("(() => { const i = document.querySelector('img.explore_picture');"
                             " const r = i.getBoundingClientRect();"
                             " i.dispatchEvent(new MouseEvent('click', {clientX: r.left + 0.17 * r.width,"
                             " clientY: r.top + 0.25 * r.height, bubbles: true})); return true; })()")
            pics["picked"] = await _picture(b, "shown.picked !== null")
            status = await b.evaluate("window.trame.state.get('status')")
            return pics, status, saved

    pics, status, saved = asyncio.run(run())
    assert "converged" in status
    # render --state makes the page's picture of the saved state, pixel for pixel (rendering noise aside)
    from PIL import Image
    r = subprocess.run([sys.executable, "-m", "lunarviz", "render", "--state", str(tmp / "saved.json"), "--out",
                        str(tmp / "rendered.png")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    rendered = np.asarray(Image.open(tmp / "rendered.png").convert("L")).astype(float)
    assert rendered.shape == saved.shape and np.abs(rendered - saved).max() <= 2
    # θ moves the Sun: every panel changes (the Moon, its earthshine, the paths, the map, the marker)
    assert _changed(pics["start"], pics["theta"]) == {"moon", "earthshine", "rays", "brdf_map", "curves"}
    # the lunar BRDF: the Moon's shading, its earthshine, the map and the numbers; not the geometry's paths
    assert {"moon", "brdf_map", "curves"} <= _changed(pics["theta"], pics["brdf"])
    assert "rays" not in _changed(pics["theta"], pics["brdf"])
    # a band: the numbers and curves only (the 3-D panels are grey, as render)
    assert _changed(pics["brdf"], pics["band"]) == {"curves"}
    # an instrument: its frame in counts with the pipeline's patches (the lower right panel) and its numbers
    assert _changed(pics["band"], pics["instrument"]) == {"brdf_map", "curves"}
    # the Earth's surface: what the Earth sends (the earthshine, the frame's earthlit side, the numbers), not the paths
    changed = _changed(pics["instrument"], pics["earth"])
    assert {"earthshine", "curves"} <= changed and "rays" not in changed  # (the geometry holds)
    # a picked facet: marked on the Moon panels, its red paths in the schematic, its numbers, and its
    # own BRDF map (over view directions) in the BRDF map's place
    pa, pb = _panels(pics["earth"]), _panels(pics["picked"])
    assert np.abs(pa["rays"] - pb["rays"]).mean() > 0.05
    assert {"brdf_map", "curves"} <= _changed(pics["earth"], pics["picked"])
