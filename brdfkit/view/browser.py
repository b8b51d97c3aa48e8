"""A page opened in headless Chromium, and its screenshot: how the tests (and anyone
measuring the page) see what a browser draws.

Chromium is driven over the DevTools protocol on a pipe (``--remote-debugging-pipe``:
file descriptors 3 and 4, NUL-separated JSON; no port, no network, no Python package
beyond the standard library). WebGL runs on SwiftShader, Chromium's CPU renderer
(``--use-angle=swiftshader``), so no GPU is needed; the window's device scale factor is
1 and its colour profile sRGB, so that a screenshot's pixels are the canvas's own.

:func:`find_chromium` says where the browser is (``$BRDFKIT_CHROMIUM``, else
``chromium``, ``chromium-browser``, ``google-chrome`` on the ``PATH``);
:func:`screenshot` opens a page at a URL fragment, waits for ``document.title`` to read
``ready`` (or ``error``) and returns the screenshot as an 8-bit RGB array.

Every exchange with Chromium has a deadline: a reply is waited for with ``select`` on the
pipe, so a Chromium that hangs, or never answers, ends in one :class:`BrowserError` line
when the deadline passes (and is killed), never in a wait without end.

Examples
--------
>>> isinstance(INSTALL_ADVICE, str)
True
"""

from __future__ import annotations

import base64
import io
import json
import os
import pathlib
import select
import shutil
import subprocess
import tempfile
import time

import numpy as np

from brdfkit.errors import BrdfkitError

__all__ = ["find_chromium", "screenshot", "Browser", "INSTALL_ADVICE", "BrowserError", "FLAGS", "MIN_WINDOW"]

INSTALL_ADVICE = ("headless Chromium is needed: apt-get install chromium (Debian, Ubuntu), or set "
                  "$BRDFKIT_CHROMIUM to a Chromium or Chrome executable")
FLAGS = ("--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-gpu-sandbox", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", "--no-first-run", "--no-default-browser-check", "--force-color-profile=srgb",
         "--force-device-scale-factor=1", "--hide-scrollbars", "--mute-audio", "--remote-debugging-pipe")
"""Chromium's flags: headless, software WebGL (SwiftShader), no network of its own, an
sRGB screen at scale 1, and the DevTools protocol on a pipe."""
MIN_WINDOW = 128
"""Pixels: the smallest window a :class:`Browser` opens. Headless Chromium (Debian's 156)
never answers ``Page.captureScreenshot`` in a 64-pixel window, while a 64-pixel still in a
128-pixel window is captured in seconds: a smaller still is drawn in a window of this size
and its corner captured."""


class BrowserError(BrdfkitError):
    """Chromium could not be started, or the page reported an error."""


def find_chromium() -> str | None:
    """The Chromium executable (``$BRDFKIT_CHROMIUM`` or the first on the ``PATH``), or ``None``."""
    given = os.environ.get("BRDFKIT_CHROMIUM")
    if given:
        return given if os.access(given, os.X_OK) else None
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


class _Pipe:
    """The DevTools protocol over Chromium's pipe (commands and their replies)."""

    def __init__(self, write_fd: int, read_fd: int):
        self.w, self.r, self.buf, self.n = write_fd, read_fd, b"", 0
        self.stalled = False  # a deadline passed: the browser is not to be asked again

    def call(self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0):
        self.n += 1
        msg = {"id": self.n, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self.w, json.dumps(msg).encode() + b"\0")
        end = time.monotonic() + timeout
        while True:
            while b"\0" not in self.buf:
                left = end - time.monotonic()
                if left <= 0 or not select.select([self.r], [], [], left)[0]:
                    self.stalled = True
                    raise BrowserError(f"Chromium did not answer {method} within {timeout:g} s")
                chunk = os.read(self.r, 1 << 20)
                if not chunk:
                    raise BrowserError("Chromium closed its pipe")
                self.buf += chunk
            raw, self.buf = self.buf.split(b"\0", 1)
            reply = json.loads(raw)
            if reply.get("id") == self.n:
                if "error" in reply:
                    raise BrowserError(f"Chromium: {method}: {reply['error'].get('message')}")
                return reply.get("result", {})


def _start(size: int):
    exe = find_chromium()
    if exe is None:
        raise BrowserError(INSTALL_ADVICE)
    profile = tempfile.mkdtemp(prefix="brdfkit-chromium-")
    to_chrome, from_chrome = os.pipe(), os.pipe()

    def child():
        os.dup2(to_chrome[0], 3)
        os.dup2(from_chrome[1], 4)

    args = [exe, *FLAGS, f"--user-data-dir={profile}", f"--window-size={size},{size}", "about:blank"]
    proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=child, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(to_chrome[0])
    os.close(from_chrome[1])
    return proc, _Pipe(to_chrome[1], from_chrome[0]), profile, (to_chrome[1], from_chrome[0])


class Browser:
    """One headless Chromium with one page (a context manager): :meth:`open` a URL and
    wait until the page is drawn, :meth:`capture` its top-left corner (``size`` pixels
    square by default; the window is at least :data:`MIN_WINDOW`). ``timeout``: the
    seconds Chromium has to answer any one command (the start's included)."""

    def __init__(self, size: int = 256, timeout: float = 60.0):
        self.size, self.timeout = int(size), float(timeout)
        self.window = max(self.size, MIN_WINDOW)
        self.proc, self.pipe, self.profile, self.fds = _start(self.window)
        try:
            target = self._call("Target.createTarget", {"url": "about:blank"}, None)
            self.session = self._call("Target.attachToTarget", {"targetId": target["targetId"], "flatten": True},
                                      None)["sessionId"]
            self._call("Emulation.setDeviceMetricsOverride", {"width": self.window, "height": self.window,
                                                              "deviceScaleFactor": 1, "mobile": False})
        except Exception:
            self.close()
            raise

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _call(self, method: str, params: dict | None = None, session: str | None = "page",
              timeout: float | None = None):
        return self.pipe.call(method, params, self.session if session == "page" else session,
                              self.timeout if timeout is None else max(min(timeout, self.timeout), 0.001))

    def evaluate(self, expression: str, await_promise: bool = False, timeout: float | None = None):
        """The value of a JavaScript expression in the page (a promise's, awaited, with
        ``await_promise``), within ``timeout`` seconds (default and at most the browser's)."""
        r = self._call("Runtime.evaluate", {"expression": expression, "returnByValue": True,
                                            "awaitPromise": bool(await_promise)}, timeout=timeout)
        if "exceptionDetails" in r:
            raise BrowserError(f"the page's JavaScript: {r['exceptionDetails'].get('text')}")
        return r.get("result", {}).get("value")

    def open(self, url: str, timeout: float = 120.0) -> float:
        """Load ``url`` and wait until ``document.title`` is ``ready``; seconds taken.
        :class:`BrowserError` with the page's message if it says ``error``."""
        t0 = time.monotonic()
        left = lambda: timeout - (time.monotonic() - t0)  # noqa: E731
        self._call("Page.navigate", {"url": "about:blank"}, timeout=left())
        self._call("Page.navigate", {"url": url}, timeout=left())
        title = None
        while left() > 0:
            title = self.evaluate("document.title", timeout=left())
            if title == "ready":
                return time.monotonic() - t0
            if title == "error":
                error = str(self.evaluate("window.brdfkitError", timeout=max(left(), 5.0))).splitlines()[0]
                raise BrowserError(f"{url}: the page says: {error}")
            time.sleep(0.05)
        raise BrowserError(f"{url}: not drawn within {timeout:g} s (title {title!r})")

    def capture(self, size: int | None = None) -> np.ndarray:
        """uint8 ``(S, S, 3)``: the page's top-left ``S x S`` pixels."""
        from PIL import Image

        s = int(size or self.size)
        shot = self._call("Page.captureScreenshot", {"format": "png", "clip": {"x": 0, "y": 0, "width": s,
                                                                               "height": s, "scale": 1}})
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(shot["data"]))).convert("RGB"))

    def close(self):
        try:
            if self.proc.poll() is None and self.pipe.stalled:
                self.proc.kill()
                self.proc.wait(10)
            elif self.proc.poll() is None:
                try:
                    self._call("Browser.close", session=None, timeout=10)
                except (BrowserError, OSError):
                    pass
                try:
                    self.proc.wait(min(10.0, self.timeout))
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait(10)
        finally:
            for fd in self.fds:
                try:
                    os.close(fd)
                except OSError:
                    pass
            shutil.rmtree(self.profile, ignore_errors=True)


def screenshot(page, fragment: str = "still=reference", size: int = 256, browser: Browser | None = None,
               timeout: float = 120.0) -> np.ndarray:
    """The screenshot of ``page`` (a file) opened at ``#fragment`` with ``size=`` added:
    uint8 ``(size, size, 3)``. ``browser``: one already open (several pages, one start).
    ``timeout``: the seconds the page has to draw, and a new browser to answer each
    command; :class:`BrowserError` once past."""
    url = pathlib.Path(os.path.abspath(os.fspath(page))).as_uri() + f"#{fragment}&size={int(size)}"
    if browser is not None:
        browser.open(url, timeout)
        return browser.capture(size)
    with Browser(size, min(timeout, 60.0)) as b:
        b.open(url, timeout)
        return b.capture(size)
