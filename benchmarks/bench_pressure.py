"""Benchmark of the pressure QP (paper Section 4) on the default seated body.

Run:  python benchmarks/bench_pressure.py [--repeat 7]

Prints, for the default male body in the upright-sitting pose with every
vertex a contact (the paper's "supported everywhere", no exclusions) and with
the default exclusions:

- the full solve (areas, weights, assembly, dual Newton, residual recheck),
- its assembly part alone,
- the equality-only lower bound measured in the same run: assembly plus the
  single r x r (66 x 66) dual solve that ignores the pyramid,
- PIQP on the paper's unreduced formulation (for comparison),
- the rigid body (lambda = inf),
- the exact friction cone (``friction="cone"``, Clarabel) with the default
  exclusions,
- the soft-tissue interface pressure on a rigid flat seat and floor
  (:mod:`seatkit.pressure.compliant`, Clarabel), with its CPU time.

Best of ``--repeat`` wall-clock times, in seconds.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

from seatkit.body import load_pose, load_rig, pose_rig
from seatkit.pressure import solve_pressure
from seatkit.pressure.assembly import assemble, body_geometry
from seatkit.pressure.compliant import contact_with_planes, friction_state, solve_compliant
from seatkit.pressure.solve import solve_equality_only
from seatkit.skeleton import SEGMENT_INDEX


def flat_seat_contact(body):
    """A rigid flat seat under the buttocks and thighs and a floor under the feet."""
    owner = np.argmax(body.weights, axis=1)
    seat = np.isin(owner, [SEGMENT_INDEX[s] for s in ("Hips", "RightUpLeg", "LeftUpLeg")])
    feet = np.isin(owner, [SEGMENT_INDEX[s] for s in ("RightFoot", "LeftFoot")])
    top = float(body.vertices[seat, 1].min())
    return contact_with_planes(body, [("seat", (0, top, 0), (0, 1, 0), seat), ("floor", (0, 0, 0), (0, 1, 0), feet)])


def best(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), out


def equality_only(body):
    geo = body_geometry(body.vertices, body.faces)
    prob = assemble(body, contact=np.ones(len(body.vertices), bool), lam=0.013, mu=0.5, geometry=geo)
    return solve_equality_only(prob)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    body = pose_rig(load_rig("default-male"), load_pose("upright-sitting"))
    n = len(body.vertices)
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}")
    print(f"body: default-male upright-sitting, {n} vertices")
    solve_pressure(body, exclude=[])  # warm-up (imports, caches)
    t_full, field = best(lambda: solve_pressure(body, exclude=[]), args.repeat)
    t_eq, _ = best(lambda: equality_only(body), args.repeat)
    t_def, field_def = best(lambda: solve_pressure(body), args.repeat)
    t_rigid, field_rigid = best(lambda: solve_pressure(body, exclude=[], lam=np.inf), args.repeat)
    t_piqp, field_piqp = best(lambda: solve_pressure(body, exclude=[], backend="piqp"), max(1, args.repeat // 3))
    t_cone, field_cone = best(lambda: solve_pressure(body, friction="cone"), max(1, args.repeat // 3))
    flat = flat_seat_contact(body)
    cpu0 = time.process_time()
    t_soft, field_soft = best(lambda: solve_compliant(body, flat), args.repeat)
    cpu_soft = (time.process_time() - cpu0) / args.repeat
    rows = [
        ("every vertex, dual Newton (full solve)", t_full, f"{field.params['iterations']} iterations, assembly {field.params['assembly_seconds']:.3f} s"),
        ("every vertex, equality-only lower bound", t_eq, "assembly + one 66 x 66 dual solve"),
        ("ratio full / lower bound", t_full / t_eq, ""),
        ("default exclusions, dual Newton", t_def, f"{field_def.params['n_contact']} contacts, {field_def.params['iterations']} iterations"),
        ("every vertex, rigid (lambda = inf)", t_rigid, f"{field_rigid.params['iterations']} iterations"),
        ("every vertex, PIQP on the paper's formulation", t_piqp, f"max |force difference| {np.abs(field_piqp.force - field.force).max():.1e} N"),
        ("default exclusions, exact cone (Clarabel)", t_cone, f"{friction_state(field_cone, mu=0.5)['at_limit_share']:.0%} at the friction limit"),
        ("soft tissue on a flat seat and floor (Clarabel)", t_soft, f"{field_soft.params['n_contact']} candidates, CPU {cpu_soft:.3f} s per solve"),
    ]
    for name, value, note in rows:
        unit = "" if name.startswith("ratio") else " s"
        print(f"{name:48s} {value:8.3f}{unit}  {note}")


if __name__ == "__main__":
    main()
