"""How often a shared chair works for sitters nobody picked: triples drawn from the presets and the library's seated poses.

Draws ``--n`` triples (``numpy.random.default_rng(--seed)``: three presets of the six ANSUR II
manikins and three poses, with repetition), builds a shared chair for each (``sitters:``, the
chair template, seed 0, nothing written) and prints, per triple, whether it was built, whether
every sitter is held within 5 mm (surface in the body and body in the furniture), each sitter's
average distance beside the flat patch's, the seat moves and knee extensions; then the counts
of docs/sitters.md ("How often it works").

    python benchmarks/bench_sitters.py --n 8 --seed 0 [--poses upright-sitting,reclined-sitting,...] [--json out.json]

Each build also designs every sitter alone (``metrics.sharing``), about two minutes a triple on
2 cores.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

PRESETS = ("p5-female", "p50-female", "p95-female", "p5-male", "p50-male", "p95-male")
POSES = ("upright-sitting", "reclined-sitting", "armrest-sitting", "crossed-legs-ankles", "leaning-forward", "feet-tucked", "crossed-legs-knees")
LIMIT = 0.005


def draw(n: int, seed: int, poses=POSES) -> list[list[dict]]:
    """``n`` triples of sitters, each a preset and a pose drawn with repetition."""
    rng = np.random.default_rng(seed)
    return [[{"model": PRESETS[rng.integers(len(PRESETS))], "pose": poses[rng.integers(len(poses))]} for _ in range(3)] for _ in range(n)]


def run(sitters: list[dict]) -> dict:
    """One shared chair's outcome (see the module docstring)."""
    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build

    try:
        result = build({"template": "chair", "sitters": sitters, "seed": 0}, write=False, processes=False)
    except SeatkitError as e:
        return {"sitters": sitters, "built": False, "reason": str(e).splitlines()[0]}
    ours, flat, sharing = result.metrics["ours"], result.metrics["baseline"], result.metrics["sharing"]
    held = [bool(o["supported"] and o["max_penetration_m"] <= LIMIT and o["max_body_depth_m"] <= LIMIT) for o in ours]
    ahead = [o["avg_distance_m"] < b["avg_distance_m"] for o, b in zip(ours, flat)]
    return {
        "sitters": sitters, "built": True, "held": held, "ahead": ahead,
        "avg_distance_m": [o["avg_distance_m"] for o in ours], "flat_avg_distance_m": [b["avg_distance_m"] for b in flat],
        "seat_move_m": [r["seat_move_m"][1] for r in sharing], "knee_extension_deg": [r.get("knee_extension_deg", 0.0) for r in sharing],
        "hip_flexion_deg": [r.get("hip_flexion_deg", 0.0) for r in sharing],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--poses", default=",".join(POSES))
    parser.add_argument("--json")
    args = parser.parse_args()
    rows = []
    for sitters in draw(args.n, args.seed, tuple(args.poses.split(","))):
        row = run(sitters)
        rows.append(row)
        who = ", ".join(f"{s['model']}:{s['pose']}" for s in sitters)
        if not row["built"]:
            print(f"refused  {who}: {row['reason']}", flush=True)
            continue
        dist = "  ".join(f"{a * 100:.2f}/{b * 100:.2f} cm" for a, b in zip(row["avg_distance_m"], row["flat_avg_distance_m"]))
        knees = " ".join(f"{k:.0f}" for k in row["knee_extension_deg"])
        hips = " ".join(f"{h:.0f}" for h in row["hip_flexion_deg"])
        print(f"{'held' if all(row['held']) else 'not held':8} {who}: ours/flat {dist}; knees extended {knees}, hips flexed {hips} deg", flush=True)
    built = [r for r in rows if r["built"]]
    held = [r for r in built if all(r["held"])]
    print(
        f"{len(held)} of {len(rows)} built and held every sitter; {sum(all(r['ahead']) for r in held)} of them ahead of the flat patch "
        f"for every sitter; {sum(sum(r['ahead']) for r in held)} of their {3 * len(held)} sitters ahead"
    )
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    main()
