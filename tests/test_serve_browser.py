"""The ``seatkit serve`` page in headless chromium (Debian's), offline, along a designer's path.

Playwright's Python package drives ``/usr/bin/chromium`` (it never downloads
a browser here: ``executable_path`` is given). The app runs on uvicorn on a
free localhost port. The network is blocked three ways: a dead proxy, a
resolver that maps every host but the loopback to nothing, and a route that
aborts, and records, every request not to the app; the test fails on any.
The path: the first design, a body, its mass and height, rapid slider moves
and one let rest, the switch to the bench, three different people, a
refused pose, the files, a supported pose again; no console error or
warning at any point.

Set ``SEATKIT_SERVE_SCREENSHOTS=FOLDER`` to keep the screenshots
(``serve-chair.png`` is docs/images/serve.png).

Skipped with a reason when chromium or playwright is missing, unless ``CI``
is set (then it fails: CI installs both).
"""

from __future__ import annotations

import os
import shutil
import socket
import threading
import time
from pathlib import Path

import pytest

from chromium import OFFLINE_FLAGS

pytestmark = pytest.mark.browser

CHROMIUM = "/usr/bin/chromium"
FLAGS = [
    *OFFLINE_FLAGS,
    "--use-angle=swiftshader",
    "--proxy-bypass-list=127.0.0.1",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
]


def _need(what: str, ok: bool, hint: str) -> None:
    if ok:
        return
    if os.environ.get("CI"):
        pytest.fail(f"{what} is missing ({hint})")
    pytest.skip(f"{what} is missing ({hint})")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    pytest.importorskip("uvicorn")
    import uvicorn

    from seatkit.serve.app import create_app
    from seatkit.serve.designer import Designer

    designer = Designer(tmp_path_factory.mktemp("serve-browser"))
    port = _free_port()
    srv = uvicorn.Server(uvicorn.Config(create_app(designer), host="127.0.0.1", port=port, log_level="warning", lifespan="off"))
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not srv.started:
        assert time.monotonic() < deadline, "uvicorn did not start"
        time.sleep(0.05)
    yield f"http://127.0.0.1:{port}", designer
    srv.should_exit = True
    thread.join(timeout=10)


def _canvas_stats(page) -> dict:
    """Distinct colours and the share of pixels differing from the background, read back from the WebGL canvas."""
    return page.evaluate(
        """() => {
        const src = document.querySelector('#view canvas');
        const c = document.createElement('canvas');
        c.width = src.width; c.height = src.height;
        const g = c.getContext('2d');
        g.drawImage(src, 0, 0);
        const d = g.getImageData(0, 0, c.width, c.height).data;
        const colours = new Set();
        let differ = 0;
        const bg = [d[0], d[1], d[2]];
        for (let i = 0; i < d.length; i += 16) {
            colours.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]);
            if (Math.abs(d[i] - bg[0]) + Math.abs(d[i + 1] - bg[1]) + Math.abs(d[i + 2] - bg[2]) > 30) differ++;
        }
        return {colours: colours.size, differ: differ / (d.length / 16), width: c.width, height: c.height};
    }"""
    )


def _warm_share(page) -> float:
    """The share of the 3D view's pixels in the pressure colours (yellow to purple: red well above blue), as the screen shows them."""
    import io

    import numpy as np
    from PIL import Image

    shot = np.asarray(Image.open(io.BytesIO(page.locator("#view").screenshot())).convert("RGB")).astype(int)
    r, b = shot[..., 0], shot[..., 2]
    return float(((r > 150) & (r - b > 90)).mean())


def _wait_design(page, before: int, what: str, timeout: int = 240_000) -> dict:
    """The design the page shows after ``before`` designs, once evaluated."""
    page.wait_for_function(f"() => window.seatkit.designsShown > {before} && window.seatkit.design.evaluated === true", timeout=timeout)
    return page.evaluate("() => window.seatkit.design")


#: The page's next design request, when asked (``window.__holdDesign = MS``), sent that much later: a request
#: that reaches the server after a newer one of the same page (the network, or the server's checks, can do that).
HOLD_DESIGN = """
(() => {
  const send = window.fetch.bind(window);
  window.__holdDesign = 0;
  window.fetch = (url, options) => {
    const hold = window.__holdDesign;
    if (hold && String(url).startsWith("/api/design?")) {
      window.__holdDesign = 0;
      return new Promise((done) => setTimeout(done, hold)).then(() => send(url, options));
    }
    return send(url, options);
  };
})();
"""


def _let_go(page, selector: str, value: int) -> None:
    """A slider moved to ``value`` and let go: one change, one request."""
    page.locator(selector).evaluate("(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); el.dispatchEvent(new Event('change')); }", str(value))


def _set(page, selector: str, value: str) -> None:
    page.locator(selector).fill(value)
    page.locator(selector).dispatch_event("change")


def test_the_designers_path_offline(server, tmp_path):
    """Body, mass, height, a pose slider, a template switch, a bench of three different people, a refused pose, downloads."""
    _need("chromium", Path(CHROMIUM).exists() or shutil.which("chromium") is not None, "tools/setup-system.sh --test")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _need("playwright", False, "pip install '.[test]'")
    url, designer = server
    console, page_errors, foreign = [], [], []
    shots = Path(os.environ.get("SEATKIT_SERVE_SCREENSHOTS") or tmp_path)
    with sync_playwright() as p:
        # a fresh profile (--user-data-dir) in the test's folder
        context = p.chromium.launch_persistent_context(
            tmp_path / "profile",
            executable_path=CHROMIUM if Path(CHROMIUM).exists() else shutil.which("chromium"),
            args=FLAGS,
            headless=True,
            viewport={"width": 1400, "height": 880},
        )

        def route(r):
            if r.request.url.startswith(url + "/") or r.request.url.startswith(("data:", "blob:")):
                r.continue_()
            else:
                foreign.append(r.request.url)
                r.abort()

        context.route("**/*", route)
        context.add_init_script(HOLD_DESIGN)
        page = context.new_page()
        # every console error and warning counts, failed resource loads (a non-2xx answer) included
        page.on("console", lambda m: console.append(m.text) if m.type in ("error", "warning") and "GPU stall" not in m.text else None)
        page.on("pageerror", lambda e: page_errors.append(str(e)))
        page.goto(url + "/")
        page.wait_for_function("() => window.seatkit && window.seatkit.designsShown >= 1", timeout=240_000)
        first = page.evaluate("() => window.seatkit.design")
        stats = _canvas_stats(page)
        assert stats["width"] > 300 and stats["height"] > 300
        assert stats["colours"] > 50 and stats["differ"] > 0.05, stats  # a drawn scene, not a cleared canvas
        assert page.locator("#table1 tbody tr").count() == 5  # the five Table 1 columns
        # the fields show what the design used
        assert float(page.locator("#body-mass").input_value()) == pytest.approx(first["people"][0]["mass_kg"])
        assert float(page.locator("#body-height").input_value()) == pytest.approx(first["people"][0]["height_m"])
        # a designer's controls (step options: width, edge, softness, armrests, ...) shown; the algorithm's internals folded away
        shown = page.eval_on_selector_all("#template-params > label.param input", "els => els.map((e) => e.dataset.key)")
        folded = page.eval_on_selector_all("#template-params details.advanced .param input", "els => els.map((e) => e.dataset.key)")
        assert shown and all(k.startswith("steps.") for k in shown), shown
        assert "lambda_r" in folded and "m_alpha_deg" in folded

        # body: the largest preset; its own mass and height in the fields, and in the design
        n = page.evaluate("() => window.seatkit.designsShown")
        page.select_option("#body-select", "p95-male")
        assert float(page.locator("#body-mass").input_value()) == pytest.approx(110.695)
        assert float(page.locator("#body-height").input_value()) == pytest.approx(1.87)
        d = _wait_design(page, n, "p95-male")
        assert d["people"][0]["model"] == "p95-male" and d["people"][0]["mass_kg"] == pytest.approx(110.695)
        # mass, then height (the first design superseded by the second)
        n = page.evaluate("() => window.seatkit.designsShown")
        _set(page, "#body-mass", "95")
        _set(page, "#body-height", "1.8")
        d = _wait_design(page, n, "height")
        assert d["people"][0]["height_m"] == pytest.approx(1.8) and d["people"][0]["mass_kg"] == pytest.approx(95.0)

        # rapid slider moves (each supersedes the last; no console error or warning), then one that is let rest:
        # its design replaces the last
        n = page.evaluate("() => window.seatkit.designsShown")
        left = page.locator("#slider-knee-left")
        start = int(float(left.input_value()))
        for k in range(1, 7):
            left.fill(str(start - 2 * k))
            left.dispatch_event("change")
            page.wait_for_timeout(60)
        left.fill(str(start))
        left.dispatch_event("change")
        # back where it started: the last design again (from the server's memory), once the newest request is shown
        page.wait_for_function(f"() => window.seatkit.shownSeq === window.seatkit.clientSeq && window.seatkit.design.id === '{d['id']}'", timeout=240_000)
        # two moves whose requests reach the server in the other order (the first held back in the page): the
        # server answers the newest 409 (superseded by the older); the page shows the newest all the same
        n = page.evaluate("() => window.seatkit.designsShown")
        page.evaluate("() => { window.__holdDesign = 400; }")
        _let_go(page, "#slider-knee-left", start - 5)
        page.wait_for_timeout(50)
        _let_go(page, "#slider-knee-left", start - 9)
        page.wait_for_function(f"() => window.seatkit.designsShown > {n} && window.seatkit.shownSeq === window.seatkit.clientSeq", timeout=120_000)
        shown = page.evaluate("() => ({id: window.seatkit.design.id, pose: window.seatkit.people[0].made.name})")
        assert designer.get(shown["id"]).recipe["bodies"][0]["pose"].endswith(shown["pose"])  # the pose of the last move
        n = page.evaluate("() => window.seatkit.designsShown")
        slider = page.locator("#slider-knee-right")
        knee = float(slider.input_value())
        slider.fill(str(int(knee) - 15))
        slider.dispatch_event("change")
        moved = _wait_design(page, n, "slider")
        assert moved["id"] != d["id"]
        # the seat beside the person (report.json metrics.person_fit)
        facts = page.locator("#facts").inner_text()
        assert "popliteal height" in facts and "buttock-popliteal length" in facts, facts
        timing = page.evaluate(
            "() => ({roundTrip: window.seatkit.lastRoundTrip, answer: window.seatkit.lastAnswer, draw: window.seatkit.lastDraw, previews: window.seatkit.previewDraws})"
        )
        server = moved["seconds"]["design"]
        # what the page waited for beyond the server's design: the requests, the JSON, the drawing (printed, not asserted);
        # the answer's time has no drawing in it (software WebGL here, a GPU elsewhere)
        print(f"slider move in the browser: design's answer in the page {timing['answer']:.2f} s after the change, shown {timing['roundTrip']:.2f} s "
              f"(server design {server:.2f} s wall, {timing['roundTrip'] - server:.2f} s the rest), drawing {timing['draw']:.2f} s; "
              f"{len(timing['previews'])} previews drawn before it, {sum(timing['previews']):.2f} s")
        assert _canvas_stats(page)["differ"] > 0.05
        # the contact pressure where it is: under the thighs and buttocks, seen from below through the see-through chair
        page.locator('#view-options button:text-is("below")').click()
        page.wait_for_timeout(300)
        page.screenshot(path=str(shots / "serve-below.png"))
        assert _warm_share(page) > 0.001
        page.locator('#view-options button:text-is("back-left")').click()  # the pressure on the back and seat
        page.wait_for_timeout(300)
        page.screenshot(path=str(shots / "serve-chair.png"))

        # a designer's control: the seat height (blank: where the pose puts it), set 8 cm higher; the design's seat is there
        from seatkit.template.seat import seat_point, surface_below

        h0 = float(seat_point(designer.get(moved["id"]).result.bodies[0])[1])
        n = page.evaluate("() => window.seatkit.designsShown")
        field = 'input[data-key="steps.seat.height"]'
        assert page.locator(field).input_value() == "" and page.locator(field).get_attribute("placeholder") == "from the pose"
        _set(page, field, f"{h0 + 0.08:.3f}")
        lifted = _wait_design(page, n, "seat height")
        result = designer.get(lifted["id"]).result
        under = surface_below(result.surface.vertices, result.surface.faces, seat_point(result.bodies[0]), reach=0.04)
        assert under == pytest.approx(round(h0 + 0.08, 3), abs=0.005)  # the seat surface under the pelvis at the height set

        # the template switch: a bench of three different people, each with their own body and pose
        n = page.evaluate("() => window.seatkit.designsShown")
        page.select_option("#template-select", "bench")
        _wait_design(page, n, "bench")
        chair_frame = page.evaluate("() => window.seatkit.frame.size")
        people = [("p5-female", "upright-sitting"), ("default-male", "reclined-sitting"), ("p95-female", "crossed-legs-knees")]
        n = page.evaluate("() => window.seatkit.designsShown")
        _set(page, "#people", "3")
        for i, (model, pose) in enumerate(people):
            page.select_option("#person-select", str(i))
            page.select_option("#body-select", model)
            page.select_option("#pose-select", pose)
        page.wait_for_function(
            "() => window.seatkit.design.people.length === 3 && window.seatkit.design.people[2].model === 'p95-female' "
            "&& window.seatkit.design.people[2].pose === 'crossed-legs-knees' && window.seatkit.design.evaluated === true",
            timeout=360_000,
        )
        bench = page.evaluate("() => window.seatkit.design")
        assert [p["model"] for p in bench["people"]] == [m for m, _ in people]
        assert [p["pose"] for p in bench["people"]][1:] == [q for _, q in people][1:]
        assert len({round(p["mass_kg"], 1) for p in bench["people"]}) == 3
        # Table 1 for every person, each with their own figures
        assert page.locator("#tables table").count() == 3
        columns = [[page.locator(f"#tables table >> nth={k}").locator("tbody tr td").nth(1 + 3 * r).inner_text() for r in range(5)] for k in range(3)]
        assert len({tuple(c) for c in columns}) == 3, columns
        # the camera is framed on the bench, not on the first chair
        frame = page.evaluate("() => window.seatkit.frame")
        lo, hi = frame["bounds"]
        assert hi[0] - lo[0] > 1.0 and frame["size"] > chair_frame, frame
        page.wait_for_timeout(300)
        page.screenshot(path=str(shots / "serve-bench.png"))

        # a refused pose: the reason, the previous design greyed and named, the files for it labelled so
        page.select_option("#person-select", "0")
        page.select_option("#pose-select", "feet-tucked")
        page.wait_for_selector("#refusal:not([hidden])", timeout=240_000)
        refusal = page.locator("#refusal-text").inner_text()
        assert "cannot support" in refusal
        assert page.evaluate("() => document.body.classList.contains('stale')")
        note = page.locator("#design-of").inner_text()
        assert "previous design" in note and "p95-female" in note and "crossed-legs-knees" in note
        assert "previous" in page.locator("#make-files").inner_text()
        page.screenshot(path=str(shots / "serve-refused.png"))
        # downloads: the files of the design named above
        page.locator("#make-files").click()
        page.wait_for_selector("#downloads a", timeout=240_000)
        links = page.locator("#downloads a")
        hrefs = [links.nth(i).get_attribute("href") for i in range(links.count())]
        assert all(f"/files/{bench['id']}/" in h for h in hrefs), hrefs
        for h in hrefs:
            assert page.request.get(url + h).status == 200, h

        # a supported pose again: the new design replaces the greyed one, in its pressure colours (not greyed)
        n = page.evaluate("() => window.seatkit.designsShown")
        page.select_option("#pose-select", "upright-sitting")
        _wait_design(page, n, "after the refusal")
        assert not page.evaluate("() => document.body.classList.contains('stale')")
        assert page.locator("#refusal").is_hidden()
        page.locator('#view-options button:text-is("below")').click()
        page.wait_for_timeout(300)
        assert _warm_share(page) > 0.001
        context.close()
    assert not foreign, f"requests left localhost: {foreign}"
    assert not page_errors, page_errors
    assert not console, console
