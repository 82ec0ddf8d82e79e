"""The share of a population sample whom a fixed seat height suits, by popliteal height alone.

    python tools/seat_height_share.py [--n 1000] [--seed 0] [HEIGHT_M ...]

The seat-height criterion of ``seatkit accommodate`` (``seatkit.population.CRITERIA``:
the seat between 88 % and 100 % of popliteal height plus the 25 mm shoe allowance)
applied to the survey figures of the sampled people (``sample_people``: the same
people as a study with that seed), for each given seat height and for the best one.
No trial is run: it says what share any seat of that height can reach on this
criterion.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    from seatkit.dimensions import SHOE_ALLOWANCE
    from seatkit.population import CRITERIA, sample_people

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("heights", nargs="*", type=float, help="seat heights to judge, m")
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    people, _ = sample_people(args.n, seed=args.seed)
    need = np.array([p.figures["popliteal_height"] for p in people]) + SHOE_ALLOWANCE

    def share(h: float) -> float:
        return float(np.mean((CRITERIA.seat_height_low * need <= h) & (h <= CRITERIA.seat_height_high * need)))

    grid = np.arange(0.30, 0.60, 0.005)
    best = max(grid, key=share)
    print(f"best fixed seat height {best:.3f} m: {share(best):.0%} of {args.n}")
    for h in args.heights:
        print(f"{h:.3f} m: {share(h):.0%}")


if __name__ == "__main__":
    main()
