"""Batch throughput on Dask: items per minute with 1 and 2 workers, and the
per-item overhead of the Dask path against plain builds in one process.

    python benchmarks/bench_batch.py [--items 8] [--template chair]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from seatkit.batch import collect_items, run_batch
from seatkit.pipeline import build

POSES = ["upright-sitting", "reclined-sitting", "armrest-sitting", "crossed-legs-knees", "leaning-forward", "lounger"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--items", type=int, default=8)
    ap.add_argument("--template", default="chair")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "items"
        src.mkdir()
        for i in range(args.items):
            (src / f"{i:02d}.yaml").write_text(f"template: {args.template}\nbodies:\n  - pose: {POSES[i % len(POSES)]}\n")
        # plain: the same builds one after another in this process (imports already warm)
        items = collect_items([src], out=Path(tmp) / "plain")
        build(dict(items[0].recipe, output=str(Path(tmp) / "warm")))
        t0 = time.perf_counter()
        for it in items:
            try:
                build(it.recipe)
            except Exception as e:  # an unsupported pose counts as a finished item, as in a batch
                print(f"  plain {it.name}: {type(e).__name__}")
        plain = time.perf_counter() - t0
        print(f"plain loop: {args.items} items in {plain:.1f} s = {60 * args.items / plain:.1f} items/min")
        for workers in (1, 2):
            out = Path(tmp) / f"dask{workers}"
            items = collect_items([src], out=out)
            t0 = time.perf_counter()
            res = run_batch(items, out, workers=workers)
            wall = time.perf_counter() - t0
            ok = sum(r.status == "ok" for r in res)
            print(
                f"dask, {workers} worker(s): {args.items} items ({ok} ok) in {wall:.1f} s = "
                f"{60 * args.items / wall:.1f} items/min; overhead vs plain "
                f"{(wall * workers - plain) / args.items:+.2f} s/item (cluster start included)"
            )


if __name__ == "__main__":
    main()
