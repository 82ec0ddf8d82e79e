"""Loaders against hostile inputs: how fast they refuse them, and BVH parsing time vs size.

    nice -n 10 python benchmarks/bench_loaders.py
    python benchmarks/bench_loaders.py --old f4bbeb3   # also the BVH parser of that commit, alternating

Prints (figures in docs/robustness.md):

- the time to refuse the issue's hostile inputs (a 100,000-joint BVH chain,
  a YAML alias bomb, 5,000-deep nesting);
- read_bvh on joint chains of growing length with the joint limit lifted,
  to show that parsing is linear in the file size (it was quadratic: the
  100,000-joint chain took 84 s). With ``--old REV`` the parser of that git
  revision runs on the same files, alternating with the current one.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seatkit.errors import SeatkitError
from seatkit.fuzzing import alias_bomb, chain_bvh


def timed(call, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        try:
            call()
        except SeatkitError:
            pass
        best = min(best, time.perf_counter() - t0)
    return best


def old_bvh_module(rev: str, tmp: Path):
    source = subprocess.run(["git", "show", f"{rev}:seatkit/body/bvh.py"], capture_output=True, text=True, check=True).stdout
    path = tmp / "old_bvh.py"
    path.write_text(source)
    spec = importlib.util.spec_from_file_location("old_bvh", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["old_bvh"] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", help="git revision whose read_bvh to compare against")
    parser.add_argument("--sizes", default="2000,5000,10000,20000,40000", help="chain lengths for the linearity table")
    args = parser.parse_args(argv)

    import seatkit.body.bvh as bvh
    from seatkit.recipe import load_recipe

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        chain = tmp / "chain.bvh"
        chain.write_text(chain_bvh(100_000))
        bomb = tmp / "bomb.yaml"
        bomb.write_text(alias_bomb(10, 9))
        deep = tmp / "deep.yaml"
        deep.write_text("template: " + "[" * 5000 + "]" * 5000 + "\n")
        print("| hostile input | size | refused in |")
        print("|---|---|---|")
        for name, path, call in [
            ("BVH chain of 100,000 joints", chain, lambda: bvh.read_bvh(chain)),
            ("YAML alias bomb (10 levels of 9 aliases)", bomb, lambda: load_recipe(bomb)),
            ("YAML nested 5,000 deep", deep, lambda: load_recipe(deep)),
        ]:
            print(f"| {name} | {path.stat().st_size / 1e6:.3f} MB | {timed(call) * 1000:.0f} ms |")

        old = old_bvh_module(args.old, tmp) if args.old else None
        print()
        print("| joints | file | read_bvh (limit lifted) | per joint |" + (f" {args.old} read_bvh | per joint |" if old else ""))
        print("|---|---|---|---|" + ("---|---|" if old else ""))
        limit = bvh.MAX_JOINTS
        try:
            bvh.MAX_JOINTS = 10**7
            for n in [int(s) for s in args.sizes.split(",")]:
                path = tmp / f"chain{n}.bvh"
                path.write_text(chain_bvh(n))
                new_t = old_t = 0.0
                for _ in range(2):  # alternate old and new on the same file
                    new_t += timed(lambda: bvh.read_bvh(path), 1) / 2
                    if old:
                        old_t += timed(lambda: old.read_bvh(path), 1) / 2
                row = f"| {n} | {path.stat().st_size / 1e6:.2f} MB | {new_t:.3f} s | {new_t / n * 1e6:.1f} us |"
                if old:
                    row += f" {old_t:.3f} s | {old_t / n * 1e6:.1f} us |"
                print(row, flush=True)
        finally:
            bvh.MAX_JOINTS = limit
    return 0


if __name__ == "__main__":
    sys.exit(main())
