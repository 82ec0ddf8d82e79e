"""A slider move in the `seatkit serve` page, in headless Chromium: when the design's answer is in the page.

    python benchmarks/bench_serve_browser.py [--moves 8]

Starts `seatkit serve --no-browser` on a free port in a fresh process (as
``bench_serve.py`` does), opens the page in Debian's Chromium (headless,
software WebGL: ``/usr/bin/chromium``, driven by Playwright), waits for the
first design, its figures and its baseline, then moves one joint slider at
a time as a designer does, each move a pose never seen before, and lets
the page rest (the design, its figures and the baseline shown) before the
next. For each move it reads what the page itself records (``app.js``):

- *answer*: from the slider's change to the design's answer parsed in the
  page, before any drawing. This is the timing that does not depend on the
  graphics hardware (no WebGL in it), though on a machine without a GPU
  the software renderer drawing the previews still shares the cores with
  the server;
- *shown*: until the design is drawn (software WebGL here);
- the server's own wall time for the design, the drawing, and the previews
  drawn before the design (what each cost the page).

Prints one line per move and the medians. The server and Chromium run on
the same cores, as on a designer's laptop.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_serve import _free_port, start_serve  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run"]
#: the sliders moved, in turn, and by how much (deg); every round a little further, so every pose is new
SLIDERS = [("knee-right", -6), ("knee-left", 5), ("hip-right", 4), ("hip-left", -4)]
REST = "() => window.seatkit.shownSeq === window.seatkit.clientSeq && document.getElementById('progress').className === 'idle'"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=8)
    args = ap.parse_args()
    if not Path(CHROMIUM).exists():
        sys.exit(f"{CHROMIUM} is missing (Debian's chromium: bash tools/setup-system.sh --test)")
    from playwright.sync_api import sync_playwright

    port = _free_port()
    url = f"http://127.0.0.1:{port}"
    with tempfile.TemporaryDirectory() as tmp:
        proc = start_serve(port, Path(tmp) / "serve")
        try:
            print(f"load average at the start: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                page.goto(url)
                page.wait_for_function("() => window.seatkit && window.seatkit.designsShown > 0", timeout=240_000)
                page.wait_for_function(REST, timeout=240_000)
                keys = page.evaluate("() => Object.keys(window.seatkit.sliders)")
                moved = [(k, d) for k, d in SLIDERS if k in keys] or sys.exit(f"none of the sliders {[k for k, _ in SLIDERS]} on the page ({keys})")
                start = {k: float(page.locator(f"#slider-{k}").input_value()) for k, _ in moved}
                rows = []
                for i in range(args.moves):
                    key, delta = moved[i % len(moved)]
                    value = start[key] + delta * (1 + i // len(moved))
                    n = page.evaluate("() => window.seatkit.designsShown")
                    slider = page.locator(f"#slider-{key}")
                    slider.fill(str(int(round(value))))
                    slider.dispatch_event("change")
                    page.wait_for_function(f"() => window.seatkit.designsShown > {n} && window.seatkit.shownSeq === window.seatkit.clientSeq", timeout=240_000)
                    t = page.evaluate(
                        "() => ({answer: window.seatkit.lastAnswer, shown: window.seatkit.lastRoundTrip, draw: window.seatkit.lastDraw,"
                        " previews: window.seatkit.previewDraws, server: window.seatkit.design.seconds.design})"
                    )
                    rows.append(t)
                    print(
                        f"  move {i} ({key} {value:.0f} deg): answer in the page {t['answer']:.2f} s, shown {t['shown']:.2f} s; "
                        f"server design {t['server']:.2f} s wall, drawing {t['draw']:.2f} s, {len(t['previews'])} previews drawn {sum(t['previews']):.2f} s"
                    )
                    page.wait_for_function(REST, timeout=240_000)  # the figures and the baseline shown: the page at rest
                browser.close()
        finally:
            proc.terminate()
            proc.wait(timeout=30)
    print(f"load average at the end: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")

    def med(key):
        return statistics.median(r[key] for r in rows)

    print(f"slider move in the browser, {len(rows)} moves (medians):")
    print(f"  design's answer in the page (no drawing): {med('answer'):.2f} s (min {min(r['answer'] for r in rows):.2f}, max {max(r['answer'] for r in rows):.2f})")
    print(f"  design shown (software WebGL): {med('shown'):.2f} s; the server's design {med('server'):.2f} s wall; drawing {med('draw'):.2f} s")
    print(f"  previews drawn before the design: {statistics.median(sum(r['previews']) for r in rows):.2f} s of the page's time")


if __name__ == "__main__":
    main()
