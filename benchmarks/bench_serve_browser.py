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

Around each move (from the slider's change until the design is drawn) it
also reads what does not depend on the machine's load: the CPU time of the
server process and of Chromium's processes (its GPU process, where the
software renderer draws, and the page's renderer, where the script runs;
psutil), the page's main thread busy in tasks of 50 ms or more (the
browser's Long Tasks API), how long the design's answer sat in the page
between its last byte arriving and the script having it parsed (the
browser's Resource Timing), and the bytes the previews and the design took
on the wire.

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

import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_serve import _free_port, start_serve  # noqa: E402

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--no-first-run"]
#: the sliders moved, in turn, and by how much (deg); every round a little further, so every pose is new
SLIDERS = [("knee-right", -6), ("knee-left", 5), ("hip-right", 4), ("hip-left", -4)]
#: the page's main thread: every task of 50 ms or more (Long Tasks API), from before the page's script runs
LONG_TASKS = """
performance.setResourceTimingBufferSize(100000);  // every request of every move (the default keeps 250)
window.__longTasks = [];
new PerformanceObserver((list) => { for (const e of list.getEntries()) window.__longTasks.push([e.startTime, e.duration]); })
  .observe({type: "longtask", buffered: true});
"""
#: what the page's clock says about the last move: the design request's and the previews' resource timing, the long tasks
MOVE_TIMES = """() => {
  // the move's start and its answer parsed, on the page's clock (a page that does not record them: from the move's pose request)
  const a = window.seatkit.lastAnswerTimes || (() => {
    const pose = performance.getEntriesByType("resource").filter((e) => e.name.includes("/api/pose")).pop();
    return {started: pose.startTime, parsed: pose.startTime + 1000 * window.seatkit.lastAnswer};
  })();
  const entries = performance.getEntriesByType("resource").filter((e) => e.startTime >= a.started - 1);
  const design = entries.filter((e) => e.name.includes("/api/design?")).pop();
  const previews = entries.filter((e) => e.name.includes("/api/preview"));
  const polls = entries.filter((e) => e.name.includes("/api/status") && e.startTime <= a.parsed);
  const busy = window.__longTasks.filter(([t, d]) => t + d > a.started && t < a.parsed).reduce((s, [t, d]) => s + Math.min(t + d, a.parsed) - Math.max(t, a.started), 0);
  return {
    sat: design ? (a.parsed - design.responseEnd) / 1000 : null,
    server_to_page: design ? (design.responseEnd - design.requestStart) / 1000 : null,
    design_bytes: design ? design.encodedBodySize : null,
    preview_bytes: previews.reduce((s, e) => s + e.encodedBodySize, 0),
    previews_fetched: previews.length,
    polls: polls.length,
    busy: busy / 1000,
  };
}"""
STUCK = "() => ({clientSeq: window.seatkit.clientSeq, shownSeq: window.seatkit.shownSeq, progress: document.getElementById('progress').textContent})"
REST = "() => window.seatkit.shownSeq === window.seatkit.clientSeq && document.getElementById('progress').className === 'idle'"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=8)
    args = ap.parse_args()
    if not Path(CHROMIUM).exists():
        sys.exit(f"{CHROMIUM} is missing (Debian's chromium: bash tools/setup-system.sh --test)")
    from playwright.sync_api import TimeoutError as PlaywrightTimeout
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
                page.add_init_script(LONG_TASKS)
                server = psutil.Process(proc.pid)
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
                    before = _cpu(server), _chromium_cpu()
                    # one change, as a slider let go (fill() would send its own change event, a second request)
                    slider.evaluate("(el, v) => { el.value = v; el.dispatchEvent(new Event('input')); el.dispatchEvent(new Event('change')); }", str(int(round(value))))
                    try:
                        page.wait_for_function(f"() => window.seatkit.designsShown > {n} && window.seatkit.shownSeq === window.seatkit.clientSeq", timeout=240_000)
                    except PlaywrightTimeout:
                        seen = page.evaluate(STUCK)
                        sys.exit(f"move {i}: no design shown after 240 s; the page: {seen}")
                    after = _cpu(server), _chromium_cpu()
                    t = page.evaluate(
                        "() => ({answer: window.seatkit.lastAnswer, shown: window.seatkit.lastRoundTrip, draw: window.seatkit.lastDraw,"
                        " previews: window.seatkit.previewDraws, server: window.seatkit.design.seconds.design})"
                    )
                    t.update(page.evaluate(MOVE_TIMES))
                    t["server_cpu"] = after[0] - before[0]
                    t["gpu_cpu"] = after[1]["gpu"] - before[1]["gpu"]
                    t["renderer_cpu"] = after[1]["renderer"] - before[1]["renderer"]
                    rows.append(t)
                    print(
                        f"  move {i} ({key} {value:.0f} deg): answer in the page {t['answer']:.2f} s, shown {t['shown']:.2f} s; "
                        f"server design {t['server']:.2f} s wall, drawing {t['draw']:.2f} s, {len(t['previews'])} previews drawn {sum(t['previews']):.2f} s; "
                        f"CPU: server {t['server_cpu']:.2f} s, Chromium GPU {t['gpu_cpu']:.2f} s, page {t['renderer_cpu']:.2f} s; "
                        f"answer sat {t['sat']:.3f} s, main thread busy {t['busy']:.2f} s, "
                        f"{t['previews_fetched']} previews {t['preview_bytes'] / 1e6:.2f} MB, design {t['design_bytes'] / 1e6:.2f} MB, {t['polls']} polls",
                        flush=True,
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
    print(
        f"  CPU time until shown: server {med('server_cpu'):.2f} s, Chromium's GPU process {med('gpu_cpu'):.2f} s, the page's renderer {med('renderer_cpu'):.2f} s"
    )
    print(
        f"  the page: main thread busy (tasks >= 50 ms) {med('busy'):.2f} s before the answer was parsed; the answer's last byte to parsed {med('sat'):.3f} s; "
        f"on the wire: previews {med('preview_bytes') / 1e6:.2f} MB, the design {med('design_bytes') / 1e6:.2f} MB, {med('polls'):.0f} status polls"
    )


def _cpu(process) -> float:
    c = process.cpu_times()
    return c.user + c.system


def _chromium_cpu() -> dict:
    """CPU seconds of this script's Chromium processes: the GPU process (software WebGL draws there), the renderers (the page's script), the rest."""
    out = {"gpu": 0.0, "renderer": 0.0, "other": 0.0}
    for child in psutil.Process().children(recursive=True):
        try:
            if "chrom" not in child.name():
                continue
            cmd = " ".join(child.cmdline())
            kind = "gpu" if "--type=gpu-process" in cmd else "renderer" if "--type=renderer" in cmd else "other"
            out[kind] += _cpu(child)
        except psutil.Error:
            continue
    return out


if __name__ == "__main__":
    main()
