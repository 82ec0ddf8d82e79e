"""Fuzz every seatkit file loader with mutated inputs and print the tally.

    nice -n 10 python tools/fuzz_loaders.py                  # 10,000 cases per loader
    python tools/fuzz_loaders.py --cases 500 --loader bvh    # a quick look at one loader
    python tools/fuzz_loaders.py --save-crashes crashes/     # keep an input of each crash class

Each case is one mutated seed (see :mod:`seatkit.fuzzing`), loaded in this
process as the CLI would load it, with a time limit. The input of case ``k``
depends only on ``--seed`` and ``k``, so a crash can be reproduced. Exits 1
if any loader crashed or hung. The figures of a full run are in
docs/robustness.md.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from seatkit.fuzzing import TARGET_BUILDERS, fuzz, make_target


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cases", type=int, default=10_000, help="cases per loader (default 10000)")
    parser.add_argument("--loader", action="append", choices=sorted(TARGET_BUILDERS), help="only these loaders (repeatable)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the mutations")
    parser.add_argument("--timeout", type=float, default=10.0, help="seconds after which a case counts as a hang")
    parser.add_argument("--save-crashes", type=Path, help="write one input of each crash class here")
    args = parser.parse_args(argv)

    names = args.loader or list(TARGET_BUILDERS)
    rows = []
    failed = False
    with tempfile.TemporaryDirectory(prefix="seatkit-fuzz-") as tmp:
        for name in names:
            target = make_target(name, Path(tmp) / f"seeds-{name}")
            t0 = time.perf_counter()

            def progress(k, tally, t0=t0, name=name):
                if k % 500 == 0 or k == args.cases:
                    print(
                        f"  {name}: {k}/{args.cases} cases, {tally.crashes} crashes, {tally.hangs} hangs, "
                        f"{time.perf_counter() - t0:.0f} s",
                        file=sys.stderr,
                        flush=True,
                    )

            tally = fuzz(target, args.cases, Path(tmp) / name, seed=args.seed, timeout=args.timeout, progress=progress)
            wall = time.perf_counter() - t0
            rows.append((tally, wall))
            failed |= bool(tally.crashes or tally.hangs)
            # the row now, so that a long run's finished loaders are on record at once
            print(f"  {name}: {_row(tally, wall)}", file=sys.stderr, flush=True)
            for k, (signature, (count, detail, data)) in enumerate(sorted(tally.signatures.items())):
                print(f"  {name}: {count} x {signature}: {detail[:200]}")
                if args.save_crashes:
                    args.save_crashes.mkdir(parents=True, exist_ok=True)
                    (args.save_crashes / f"{name}-{k}{target.suffix}").write_bytes(data)

    print()
    print("| loader | cases | refused (own error, one line) | accepted (checked) | crashes | hangs | slowest case | time |")
    print("|---|---|---|---|---|---|---|---|")
    for tally, wall in rows:
        print(_row(tally, wall))
    return 1 if failed else 0


def _row(tally, wall: float) -> str:
    return (
        f"| {tally.name} | {tally.cases} | {tally.ok} | {tally.accepted} | {tally.crashes} | {tally.hangs} "
        f"| {tally.slowest:.2f} s | {wall:.0f} s |"
    )


if __name__ == "__main__":
    sys.exit(main())
