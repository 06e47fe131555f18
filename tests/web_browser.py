"""A headless Chromium driven through the DevTools protocol (aiohttp's websocket client).

Enough to load a page, run JavaScript in it and take screenshots; no Selenium or Playwright
(no driver downloads). Used by tests/test_web.py against ``lunarviz view --web``.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import shutil
import subprocess
import tempfile
import time


def chromium_path() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        p = shutil.which(name)
        if p:
            return p
    return None


class Browser:
    """``async with Browser() as b: await b.goto(url); png = await b.screenshot()``."""

    def __init__(self, width: int = 1400, height: int = 900):
        self.size = (width, height)
        self._id = 0

    async def __aenter__(self):
        import aiohttp
        self._dir = tempfile.mkdtemp(prefix="lunarviz-chromium-")
        exe = chromium_path()
        self.proc = subprocess.Popen(
            [exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
             "--no-first-run", "--remote-debugging-port=0", f"--user-data-dir={self._dir}",
             f"--window-size={self.size[0]},{self.size[1]}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = os.path.join(self._dir, "DevToolsActivePort")
        t0 = time.time()

        def ready():
            if not os.path.exists(port_file):
                return False
            with open(port_file) as fh:
                return bool(fh.read().strip())
        while not ready():
            if time.time() - t0 > 30 or self.proc.poll() is not None:
                raise RuntimeError("chromium did not start")
            await asyncio.sleep(0.1)
        with open(port_file) as fh:
            port = int(fh.read().split()[0])
        self.session = aiohttp.ClientSession()
        async with self.session.get(f"http://127.0.0.1:{port}/json/list") as r:
            pages = [p for p in await r.json() if p.get("type") == "page"]
        self.ws = await self.session.ws_connect(pages[0]["webSocketDebuggerUrl"], max_msg_size=0)
        await self.send("Page.enable")
        await self.send("Emulation.setDeviceMetricsOverride", width=self.size[0], height=self.size[1],
                        deviceScaleFactor=1, mobile=False)
        return self

    async def __aexit__(self, *exc):
        try:
            await self.ws.close()
            await self.session.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            shutil.rmtree(self._dir, ignore_errors=True)

    async def send(self, method: str, **params):
        self._id += 1
        my = self._id
        await self.ws.send_str(json.dumps({"id": my, "method": method, "params": params}))
        while True:
            msg = json.loads((await self.ws.receive()).data)
            if msg.get("id") == my:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})

    async def goto(self, url: str):
        await self.send("Page.navigate", url=url)

    async def evaluate(self, expression: str):
        res = await self.send("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        return res.get("result", {}).get("value")

    async def wait_for(self, expression: str, timeout: float = 60.0, poll: float = 0.25):
        t0 = time.time()
        while time.time() - t0 < timeout:
            try:
                if await self.evaluate(expression):
                    return True
            except RuntimeError:
                pass
            await asyncio.sleep(poll)
        raise TimeoutError(f"timed out waiting for {expression!r}")

    async def screenshot(self) -> bytes:
        res = await self.send("Page.captureScreenshot", format="png")
        return base64.b64decode(res["data"])


def lunarviz_server(args: list, folder, cwd=None):
    """Start ``python -m lunarviz.cli ARGS --port P`` (a ``--web`` command) on a free port of
    127.0.0.1, its output logged in ``folder``; yield the URL it prints (with its secret) once the
    page answers, and stop it at the end (a generator for a pytest fixture)."""
    import re
    import socket
    import sys
    import urllib.request
    from pathlib import Path

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    log_path = Path(folder) / "server.log"
    log = open(log_path, "w")  # noqa: SIM115 (closed at the end)
    proc = subprocess.Popen([sys.executable, "-m", "lunarviz.cli", *args, "--port", str(port)], stdout=log,
                            stderr=subprocess.STDOUT, text=True, cwd=cwd)
    base = f"http://127.0.0.1:{port}/"
    t0 = time.time()
    while True:
        text = log_path.read_text()
        found = re.search(r"serving on (http://\S+/\?secret=\S+)", text)
        if found:
            try:
                with urllib.request.urlopen(base, timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
        if proc.poll() is not None or time.time() - t0 > 120:
            proc.kill()
            log.close()
            raise RuntimeError(f"lunarviz {args[0]} --web did not serve: {text}")
        time.sleep(0.5)
    url = found.group(1)
    assert url.startswith(base) and "wslink-secret" not in url
    try:
        yield url
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)
        log.close()
