"""A slider move in `seatkit serve`: the round trip of a new design on a warm server, and its previews.

Starts `seatkit serve --no-browser` on a free port in a fresh process, warms it
with one design of the default recipe, then moves joints as the page does
(each move a new pose, so nothing comes from the design memory): for each,
POST /api/pose with the new angles and POST /api/design?files=0&baseline=0&evaluate=0&view=1
with the recipe, and times the two requests together (what the page waits for
before it draws the new design, the meshes included); then POST
/api/design/ID/evaluate?view=1, as the page does next (the contact pressure
colours and our Table 1 figures). It reads the server process's CPU time
(psutil) around each move: on a loaded machine the wall time is mostly
waiting for a core, the CPU time is what the move costs. Meanwhile it polls
GET /api/status as the page does (``?since=VERSION``: answered when the
status changes) and fetches each preview the page draws when it appears
(the posed body; then the template's cage and its surface, without the
bodies again), timing when the page could draw it; with --no-previews it
fetches none (the previews' cost is the difference). Prints the medians, the
stages of the design (from the report) and what the server reports as cached.

With --compare, a `seatkit build` of the same pose (what a designer ran before
the web app: a fresh process, every stage, the files) is timed after each move,
alternating, so both see the same machine load.

With --switches N, then N new pose or body choices (a library pose on a
preset body, a combination not designed before), timed the same way.

    python benchmarks/bench_serve.py [--moves 12] [--compare] [--switches 8] [--no-previews]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx
import psutil

#: Joint moves, as the page's sliders make them: (segment index, axis, degrees added).
MOVES = [
    (5, 0, -10.0), (5, 0, 10.0),  # left knee
    (2, 0, -10.0), (2, 0, 10.0),  # right knee
    (1, 0, 8.0), (4, 0, 8.0),  # hips
    (1, 0, -8.0), (4, 0, -8.0),
    (0, 0, -8.0), (0, 0, 8.0),  # trunk recline (root)
    (14, 0, -15.0), (14, 0, 15.0),  # right shoulder
]


#: The previews the page draws (seatkit/serve/static/app.js, PREVIEW_LABEL), in order: their stages.
PREVIEWS = ("posed", "template")

#: New pose or body choices (--switches): each library pose on each body, in turn.
SWITCH_POSES = ["reclined-sitting", "armrest-sitting", "crossed-legs-knees", "lounger", "upright-sitting"]
SWITCH_BODIES = ["p5-female", "p95-male", "default-female", "p50-male"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_serve(port: int, folder: Path) -> subprocess.Popen:
    """`seatkit serve --no-browser` on ``port`` in a fresh process, once it answers; exits with its error if it does not start."""
    seatkit = shutil.which("seatkit") or sys.exit("seatkit is not installed (pip install '.[serve]')")
    proc = subprocess.Popen(
        [seatkit, "serve", "--no-browser", "--port", str(port), "--folder", str(folder)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 60
    while True:
        try:
            httpx.get(f"http://127.0.0.1:{port}/api/status")
            return proc
        except httpx.TransportError:
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                sys.exit(f"seatkit serve did not start: {proc.stderr.read() if proc.stderr else ''}")
            time.sleep(0.1)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--moves", type=int, default=12)
    ap.add_argument("--compare", action="store_true", help="alternate with a seatkit build of the same pose")
    ap.add_argument("--switches", type=int, default=0, help="then this many new pose or body choices (a library pose on a preset body, never seen before)")
    ap.add_argument("--no-previews", action="store_true", help="poll the status but fetch no preview (what the previews cost is the difference)")
    args = ap.parse_args()
    seatkit = shutil.which("seatkit") or sys.exit("seatkit is not installed (pip install '.[serve]')")
    port = _free_port()
    with tempfile.TemporaryDirectory() as tmp:
        proc = start_serve(port, Path(tmp) / "serve")
        try:
            client = httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=120)
            server = psutil.Process(proc.pid)

            def cpu() -> float:
                c = server.cpu_times()
                return c.user + c.system

            print(f"load average at the start: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
            t0 = time.perf_counter()
            first = client.post("/api/design?files=0&baseline=0&view=1", json={})
            first.raise_for_status()
            print(f"first design (cold server: imports, rig, operators): {time.perf_counter() - t0:.2f} s")
            pose = client.get("/api/pose", params={"pose": "upright-sitting"}).json()
            trips, stages, builds, previews = [], [], [], {}
            evaluated, cpu_design, cpu_total = [], [], []
            for i in range(args.moves):
                seg, axis, delta = MOVES[i % len(MOVES)]
                angles = [row[:] for row in pose["angles"]]
                angles[seg][axis] += delta * (1 + 0.15 * (i // len(MOVES)))  # never a pose seen before
                t, c = time.perf_counter(), cpu()
                name = client.post("/api/pose", json={"angles": angles, "translation": pose["translation"]}).json()["pose"]
                request = f"bench-{i}"
                answer = {}

                def post(name=name, request=request, answer=answer):
                    answer["r"] = client.post(
                        "/api/design?files=0&baseline=0&evaluate=0&view=1", json={"bodies": [{"pose": name}]}, headers={"X-Request-Id": request}
                    )
                    answer["t"], answer["cpu"] = time.perf_counter(), cpu()  # the answer is in

                seen: dict = {}
                done = threading.Event()

                def watch(request=request, seen=seen, done=done, t=t):
                    version = ""
                    while not done.is_set():
                        try:
                            st = client.get("/api/status", params={"since": version}).json()  # answered when the status changes
                        except httpx.HTTPError:
                            return  # the server has stopped (the benchmark's end)
                        if "version" not in st:  # a server that answers at once: asked every 50 ms
                            time.sleep(0.05)
                        version = st.get("version", "")
                        stage = st.get("preview")
                        if not args.no_previews and not done.is_set() and st.get("request") == request and stage in PREVIEWS and stage not in seen:
                            # the bodies once: the template's preview of the same request without them
                            p = client.get("/api/preview", params={"request": request, "bodies": 0 if seen else 1})
                            if p.status_code == 200 and not done.is_set():
                                seen[p.json()["stage"]] = time.perf_counter() - t

                worker = threading.Thread(target=post)
                watcher = threading.Thread(target=watch, daemon=True)  # ends at its next answer (a status request may wait up to 5 s)
                worker.start()
                watcher.start()
                worker.join()
                done.set()
                r = answer["r"]
                trips.append(answer["t"] - t)
                cpu_design.append(answer["cpu"] - c)
                for stage, seconds in list(seen.items()):
                    previews.setdefault(stage, []).append(seconds)
                if r.status_code != 200:
                    print(f"  move {i}: {r.status_code} {r.json().get('error')}")
                    continue
                d = r.json()
                e = client.post(f"/api/design/{d['id']}/evaluate", params={"seq": d["request_seq"], "view": 1})
                evaluated.append(time.perf_counter() - t)
                cpu_total.append(cpu() - c)
                e.raise_for_status()
                stages.append({**d["timings_s"], "evaluate (next request)": e.json()["seconds"]["evaluate"], "view payload MB": len(r.content) / 1e6})
                if args.compare:
                    path = Path(tmp) / "serve" / "uploads" / name
                    t = time.perf_counter()
                    done = subprocess.run(
                        [seatkit, "build", "--pose", str(path), "--out", str(Path(tmp) / f"cli{i}"), "--quiet"],
                        capture_output=True,
                        text=True,
                    )
                    builds.append(time.perf_counter() - t)
                    if done.returncode != 0:
                        print(f"  seatkit build failed: {done.stderr.strip()}")
                line = f"  move {i}: design shown {trips[-1]:.2f} s (CPU {cpu_design[-1]:.2f} s), evaluated {evaluated[-1]:.2f} s (CPU {cpu_total[-1]:.2f} s)"
                line += "".join(f", {k} preview {v:.2f} s" for k, v in seen.items())
                if args.compare and builds:
                    line += f", seatkit build {builds[-1]:.2f} s"
                print(line, flush=True)
            switch_trips, switch_cpu = [], []
            combos = [(m, q) for q in SWITCH_POSES for m in SWITCH_BODIES]
            for i in range(args.switches):
                model, pose_name = combos[i % len(combos)]
                t, c = time.perf_counter(), cpu()
                r = client.post("/api/design?files=0&baseline=0&evaluate=0&view=1", json={"bodies": [{"model": model, "pose": pose_name}]})
                switch_trips.append(time.perf_counter() - t)
                switch_cpu.append(cpu() - c)
                print(f"  switch {i} ({model}, {pose_name}): {r.status_code}, design shown {switch_trips[-1]:.2f} s (CPU {switch_cpu[-1]:.2f} s)", flush=True)
            status = client.get("/api/status").json()
        finally:
            proc.terminate()
            proc.wait(timeout=30)
    print(f"designs answered from memory: {status['caches']['design_hits']} (0 expected: every move is a new pose)")
    print(f"load average at the end: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"slider move -> new design shown (POST /api/pose + POST /api/design, meshes included): {len(trips)} moves, previews {'not fetched' if args.no_previews else 'fetched as the page does'}")
    print(f"  round trip: median {statistics.median(trips):.2f} s, min {min(trips):.2f} s, max {max(trips):.2f} s")
    print(f"  server CPU time until the design is shown: median {statistics.median(cpu_design):.2f} s, min {min(cpu_design):.2f} s, max {max(cpu_design):.2f} s")
    if evaluated:
        print(f"  evaluated (contact colours, Table 1): median {statistics.median(evaluated):.2f} s; server CPU time {statistics.median(cpu_total):.2f} s")
    labels = {
        "posed": "preview: the body in its new pose",
        "template": "preview: the template's cage and surface",
    }
    for stage, values in previews.items():
        print(f"  {labels[stage]}: median {statistics.median(values):.2f} s ({len(values)} of {len(trips)} moves)")
    if switch_trips:
        print(f"new pose or body -> new design shown (POST /api/design, meshes included): {len(switch_trips)} choices")
        print(f"  round trip: median {statistics.median(switch_trips):.2f} s; server CPU time median {statistics.median(switch_cpu):.2f} s")
    if builds:
        print(f"  seatkit build of the same pose (fresh process, all stages, files), alternating: median {statistics.median(builds):.2f} s")
    if stages:
        for k in stages[0]:
            values = [s[k] for s in stages if k in s]
            print(f"  {k:<26} {statistics.median(values):.3f}")
    print("cached on the warm server:", json.dumps(status["caches"]))
    print("deferred until asked: the flat-patch baseline (POST /api/design/ID/baseline), the files (POST /api/design/ID/files)")


if __name__ == "__main__":
    main()
