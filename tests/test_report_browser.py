"""report.html in a real headless browser (Debian's chromium), with no network.

Chromium is driven over the DevTools protocol on a pipe
(``--remote-debugging-pipe``: JSON messages ending in NUL on fds 3 and 4),
so the test sees every console call, uncaught exception, log entry and
network request of the page, not a grep of chromium's log. The network is
blocked twice: a dead proxy and a resolver that maps every host to nothing;
the test also fails on any request that is not ``file:``, ``data:`` or
``blob:``. A negative control page proves the checks catch errors.

Skipped with a reason when chromium is missing, unless the environment
variable ``CI`` is set (then it fails: CI installs chromium with
``tools/setup-system.sh --test``).
"""

from __future__ import annotations

import base64
import io
import json
import os
import queue
import shutil
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from chromium import OFFLINE_FLAGS
from test_report_support import evaluated_result, plain_result

pytestmark = pytest.mark.browser

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "chromium", "chromium-browser")
WINDOW = (1200, 900)


def _chromium() -> str:
    for name in CHROMIUM_CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    if os.environ.get("CI"):
        pytest.fail("chromium is not installed (CI must run tools/setup-system.sh --test)")
    pytest.skip("chromium is not installed (Debian: apt-get install chromium)")


class Browser:
    """A headless chromium page driven over ``--remote-debugging-pipe``."""

    def __init__(self, profile: Path):
        cmd_r, cmd_w = os.pipe()  # we write commands, chromium reads fd 3
        out_r, out_w = os.pipe()  # chromium writes fd 4, we read

        def child_fds():
            # move the pipe ends to fds 3 and 4 (dup first, in case they collide)
            a, b = os.dup(cmd_r), os.dup(out_w)
            os.dup2(a, 3)
            os.dup2(b, 4)

        flags = [
            *OFFLINE_FLAGS,
            f"--user-data-dir={profile}",
            "--host-resolver-rules=MAP * ~NOTFOUND",
            "--remote-debugging-pipe",
            f"--window-size={WINDOW[0]},{WINDOW[1]}",
            "about:blank",
        ]
        self.proc = subprocess.Popen(
            [_chromium(), *flags],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            preexec_fn=child_fds,
            pass_fds=(3, 4),  # kept open after child_fds() put the pipes there
        )
        os.close(cmd_r)
        os.close(out_w)
        self._w = os.fdopen(cmd_w, "wb", buffering=0)
        self._r = os.fdopen(out_r, "rb", buffering=0)
        self._next = 0
        self._replies: dict[int, dict] = {}
        self.events: queue.Queue = queue.Queue()
        self._cond = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()
        target = next(t for t in self.call("Target.getTargets")["targetInfos"] if t["type"] == "page")
        self.session = self.call("Target.attachToTarget", targetId=target["targetId"], flatten=True)["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            self.call(f"{domain}.enable", session=True)
        self.call("Emulation.setDeviceMetricsOverride", session=True, width=WINDOW[0], height=WINDOW[1], deviceScaleFactor=1, mobile=False)

    def _read(self):
        buf = b""
        while True:
            chunk = self._r.read(65536)
            if not chunk:
                return
            buf += chunk
            *messages, buf = buf.split(b"\0")
            for raw in messages:
                msg = json.loads(raw)
                if "id" in msg:
                    with self._cond:
                        self._replies[msg["id"]] = msg
                        self._cond.notify_all()
                else:
                    self.events.put(msg)

    def call(self, method: str, *, session: bool = False, timeout: float = 30.0, **params) -> dict:
        self._next += 1
        msg = {"id": self._next, "method": method, "params": params}
        if session:
            msg["sessionId"] = self.session
        self._w.write(json.dumps(msg).encode() + b"\0")
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._next not in self._replies:
                if not self._cond.wait(timeout=max(0.0, deadline - time.monotonic())):
                    raise TimeoutError(f"no reply to {method} in {timeout} s")
            reply = self._replies.pop(self._next)
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    def evaluate(self, expression: str):
        res = self.call("Runtime.evaluate", session=True, expression=expression, returnByValue=True)
        return res.get("result", {}).get("value")

    def drain(self) -> list[dict]:
        out = []
        while not self.events.empty():
            out.append(self.events.get_nowait())
        return out

    def close(self):
        try:
            self.call("Browser.close", timeout=5.0)
        except (RuntimeError, TimeoutError, OSError):
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


def problems(events: list[dict]) -> list[str]:
    """Console errors, uncaught exceptions, error log entries and network requests."""
    out = []
    for ev in events:
        method, p = ev.get("method"), ev.get("params", {})
        if method == "Runtime.exceptionThrown":
            d = p["exceptionDetails"]
            out.append(f"uncaught: {d.get('exception', {}).get('description') or d.get('text')}")
        elif method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            out.append("console.error: " + " ".join(str(a.get("value", a.get("description"))) for a in p.get("args", [])))
        elif method == "Log.entryAdded" and p["entry"].get("level") == "error":
            out.append(f"log error: {p['entry'].get('text')} {p['entry'].get('url', '')}")
        elif method == "Network.requestWillBeSent":
            url = p["request"]["url"]
            if not url.startswith(("file:", "data:", "blob:", "about:")):
                out.append(f"network request: {url}")
    return out


def open_page(browser: Browser, url: str, *, ready: str, timeout: float = 60.0) -> bool:
    """Navigate and wait until the JavaScript expression ``ready`` is true."""
    browser.call("Page.navigate", session=True, url=url)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if browser.evaluate(ready):
            return True
        time.sleep(0.2)
    return False


#: True once plotly has laid out the figure and the WebGL scene has a canvas.
PLOT_READY = (
    "(() => { const d = document.getElementById('view');"
    " return !!(d && d._fullLayout && d._fullLayout.scene && d.querySelector('.gl-container canvas')); })()"
)


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    b = Browser(tmp_path_factory.mktemp("chromium-profile"))
    yield b
    b.close()


def test_negative_control_errors_and_requests_are_caught(browser, tmp_path):
    page = tmp_path / "bad.html"
    page.write_text(
        "<!DOCTYPE html><html><body><script>console.error('bad-console');</script>"
        "<script>throw new Error('bad-throw');</script>"
        "<img src='http://example.invalid/x.png'></body></html>"
    )
    browser.drain()
    assert open_page(browser, page.as_uri(), ready="document.readyState === 'complete'")
    time.sleep(0.5)
    found = problems(browser.drain())
    text = "\n".join(found)
    assert "bad-console" in text and "bad-throw" in text and "example.invalid" in text, found


def _render(browser, directory: Path, result):
    from seatkit.export.report import write_report_html

    path = write_report_html(result, directory / "report.html")
    browser.drain()
    assert open_page(browser, path.as_uri(), ready=PLOT_READY), "plotly never drew the 3D scene"
    time.sleep(1.5)  # let the software WebGL renderer finish its frame
    shot = base64.b64decode(browser.call("Page.captureScreenshot", session=True, format="png")["data"])
    return path, shot, problems(browser.drain())


def _pixels(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def _view_region(browser, img: np.ndarray) -> np.ndarray:
    box = browser.evaluate(
        "(() => { const r = document.querySelector('#view .gl-container canvas').getBoundingClientRect();"
        " return [r.left, r.top, r.right, r.bottom]; })()"
    )
    left, top, right, bottom = (int(round(v)) for v in box)
    return img[max(top, 0) : min(bottom, img.shape[0]), max(left, 0) : min(right, img.shape[1])]


def test_report_opens_offline_and_draws_the_3d_view(browser, tmp_path):
    result = evaluated_result()
    path, shot, found = _render(browser, tmp_path, result)
    (tmp_path / "screenshot.png").write_bytes(shot)
    assert found == [], found
    assert browser.evaluate("document.querySelectorAll('.no-webgl, .webgl-error').length") == 0
    n_traces = browser.evaluate("document.getElementById('view').data.length")
    assert n_traces == 6  # ours: body, surface, cage; baseline: the same
    view = _view_region(browser, _pixels(shot))
    assert view.shape[0] > 300 and view.shape[1] > 600, view.shape
    flat = view.reshape(-1, 3).astype(np.int64)
    distinct = len(np.unique(flat[:, 0] * 65536 + flat[:, 1] * 256 + flat[:, 2]))
    assert distinct > 2000, f"the 3D view looks blank: {distinct} distinct colours"
    # the shaded body and the blue surface are drawn: many pixels far from white and grey
    saturation = flat.max(axis=1) - flat.min(axis=1)
    assert (saturation > 40).mean() > 0.05
    blue = (flat[:, 2] > flat[:, 0] + 30) & (flat[:, 2] > 120)
    assert blue.mean() > 0.005, "the limit surface (blue) is not visible"
    html = path.read_text()
    assert "Evaluation: the paper's Table 1 quantities and two checks" in html
    assert "cdn.plot.ly/plotly" not in html and "<script src=" not in html


def test_report_without_evaluation_opens_too(browser, tmp_path):
    path, shot, found = _render(browser, tmp_path, plain_result())
    assert found == [], found
    assert browser.evaluate("document.getElementById('view').data.length") == 3  # body, surface, cage
    view = _view_region(browser, _pixels(shot))
    flat = view.reshape(-1, 3).astype(np.int64)
    assert len(np.unique(flat[:, 0] * 65536 + flat[:, 1] * 256 + flat[:, 2])) > 2000
