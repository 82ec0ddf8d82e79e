"""Per-trial CPU of the virtual sitting trial, and its outcomes, side by side with another version of seatkit/trial.py.

Seats the first N people of the accommodation sample (``seatkit.population.sample_people``,
seed 0) on a built design, one after another in this process, and prints each trial's CPU
time (``time.process_time``, so that other work on the machine changes it little), its
placement and its accommodation verdict. With ``--baseline FILE`` (another trial.py, e.g.
``git show REV:seatkit/trial.py > /tmp/trial_old.py``) every person is also seated by that
version, alternately with this one (both see the same machine load), and the differences
in placement, figures and verdicts are listed.

    seatkit build --body p50-male --pose upright-sitting --out p50m-chair --quiet
    python benchmarks/bench_trial.py p50m-chair --n 40 [--baseline /tmp/trial_old.py] [--json out.json]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np


def _load(path: str):
    spec = importlib.util.spec_from_file_location("trial_baseline", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["trial_baseline"] = mod
    spec.loader.exec_module(mod)
    return mod


def _one(mod, design, registry, person, reference, pose) -> dict:
    from seatkit.errors import SeatkitError
    from seatkit.population import judge, person_params

    model, params = person_params(person)
    start = time.process_time()
    try:
        t = mod.run_trial(design, registry, model, params, pose)
    except SeatkitError as e:
        return {"cpu_s": time.process_time() - start, "error": str(e).splitlines()[0]}
    cpu = time.process_time() - start
    fit = {k: v for k, v in t.fit.items() if k != "measurements"}
    return {
        "cpu_s": cpu,
        "theta": [float(x) for x in t.placement.theta],
        "evaluations": t.placement.evaluations,
        "metrics": {k: t.metrics.get(k) for k in ("supported", "avg_distance_m", "max_penetration_m", "max_body_depth_m", "max_pressure_pa", "max_moment_nm")},
        "seat_height_m": fit.get("seat_height_m"),
        "reasons": judge(t.metrics, t.fit, reference),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("design", help="a build folder (design.npz, report.json)")
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--pose", default="upright-sitting")
    ap.add_argument("--baseline", help="another trial.py to run side by side")
    ap.add_argument("--json", help="write every trial's figures here")
    args = ap.parse_args()

    import seatkit.trial as current
    from seatkit.plugins import get_plugin_manager
    from seatkit.population import design_reference, sample_people

    registry = get_plugin_manager().registry
    reference = design_reference(Path(args.design))
    versions = {"current": current}
    if args.baseline:
        versions["baseline"] = _load(args.baseline)
    designs = {name: mod.load_trial_design(args.design) for name, mod in versions.items()}
    people, _ = sample_people(args.n)
    for name, mod in versions.items():  # warm the imports and caches
        _one(mod, designs[name], registry, people[0], reference, args.pose)
    rows = []
    for p in people:
        row = {"person": p.name}
        for name, mod in versions.items():
            row[name] = _one(mod, designs[name], registry, p, reference, args.pose)
        rows.append(row)
        parts = []
        for name in versions:
            r = row[name]
            verdict = "error" if "error" in r else ("yes" if not r["reasons"] else "no")
            parts.append(f"{name} {r['cpu_s']:.2f} s {verdict}")
        line = f"{p.name}: " + ", ".join(parts)
        if "baseline" in row and "theta" in row["current"] and "theta" in row["baseline"]:
            d = np.subtract(row["current"]["theta"], row["baseline"]["theta"])
            line += f"; placement moved {1000 * np.abs(d[:3]).max():.1f} mm, {np.degrees(np.abs(d[3:])).max():.1f} deg"
        print(line, flush=True)
    for name in versions:
        cpu = np.array([r[name]["cpu_s"] for r in rows])
        ok = sum(1 for r in rows if "error" not in r[name] and not r[name]["reasons"])
        print(f"{name}: CPU per trial mean {cpu.mean():.2f} s, median {np.median(cpu):.2f} s, range {cpu.min():.2f}-{cpu.max():.2f} s; accommodated {ok} of {len(rows)}")
    if "baseline" in versions:
        changed = [
            r["person"] for r in rows
            if ("error" in r["current"]) != ("error" in r["baseline"])
            or sorted(x.split(":")[0] for x in r["current"].get("reasons", [])) != sorted(x.split(":")[0] for x in r["baseline"].get("reasons", []))
        ]
        verdict = [r["person"] for r in rows if (not r["current"].get("reasons", [1])) != (not r["baseline"].get("reasons", [1]))]
        print(f"verdict (accommodated or not) changed for {len(verdict)} of {len(rows)}: {', '.join(verdict) or 'none'}")
        print(f"set of reasons changed for {len(changed)} of {len(rows)}: {', '.join(changed) or 'none'}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
