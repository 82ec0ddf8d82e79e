"""Every template start a build runs, and what became of it: the cost of the starts that give no valid cage, and of the surface fits.

For each drawn pose (``FAMILY-INDEX@BODY``, draw seed 2026, as the
generalisation benchmark draws them) it runs the full default build (seed
0) and logs every start the chair template runs, the search's ordinary
starts and its last-resort ones: whether it gave a valid cage, the
template's refusal, and its CPU time; and every surface fit (the first
fit and its refits, guarded or not, with their depths and each iterate's)
and push-out, with their CPU time (the
baseline's fit, the flat patch's, is one of them). Prints one line per case and, with
``--results``, writes every start as JSON lines. docs/templates.md, "What a
rejected candidate costs", gives what it measured:

    python benchmarks/bench_starts.py seated-104@default-male reclined-025@default-female

``--cases-from gen.jsonl`` takes every case a run of
``bench_generalisation.py`` built (its drawn poses); ``--summary`` then
prints, over all the cases, how the guarded refits from a fit ended (within
the surface fit's 5 mm limit or not) beside the depths of the fits they
answer, and how many builds took their first cage from a start after
refused ones. ``--summarise out.jsonl`` prints that summary of a
``--results`` file without building (several runs on parts of the cases
can append to one file):

    python benchmarks/bench_starts.py --cases-from gen.jsonl --results starts.jsonl --summary
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cases", nargs="*", help="FAMILY-INDEX@BODY, e.g. seated-104@default-male")
    ap.add_argument("--cases-from", type=Path, help="also every case a bench_generalisation.py --results file built")
    ap.add_argument("--results", type=Path, help="append one JSON line per case here")
    ap.add_argument("--summary", action="store_true", help="print the summary of every case at the end")
    ap.add_argument("--summarise", type=Path, metavar="RESULTS", help="print the summary of a --results file and build nothing")
    args = ap.parse_args()
    if args.summarise:
        summarise([json.loads(line) for line in args.summarise.read_text().splitlines() if line.strip()])
        return
    cases = list(args.cases) + (built_cases(args.cases_from) if args.cases_from else [])
    if not cases:
        ap.error("name at least one case, or --cases-from a results file")
    rows = []

    from seatkit.body.generator import draw_case, pose_yaml
    from seatkit.errors import SeatkitError, UnsupportedPoseError
    from seatkit.pipeline import build
    from seatkit.template import engine

    log: list = []
    attempt = engine.YamlTemplate._attempt

    def logged(self, bodies, pressures, p, bound, per_step, rng, seed, dropped=frozenset(), last_resort=False, **kw):
        start = time.process_time()
        try:
            out = attempt(self, bodies, pressures, p, bound, per_step, rng, seed, dropped, last_resort, **kw)
        except UnsupportedPoseError as e:
            log.append({"last_resort": last_resort, "valid": False, "reason": str(e), "cpu_s": time.process_time() - start})
            raise
        if out is None:  # the same fit as a refused start of its stream, stopped after the optional step it drops
            log.append({"last_resort": last_resort, "valid": False, "reason": "alike: the same fit as a refused start", "cpu_s": time.process_time() - start})
        else:
            log.append({"last_resort": last_resort, "valid": True, "cpu_s": time.process_time() - start})
        return out

    engine.YamlTemplate._attempt = logged

    from seatkit.refine import ccfit

    fits: list = []
    fit_once, push_out = ccfit._fit_once, ccfit.push_out

    def logged_fit(mesh, bodies, pressures, params, *, guard=False, start_from=None, **more):
        start = time.process_time()
        out = fit_once(mesh, bodies, pressures, params, guard=guard, start_from=start_from, **more)
        report = out.meta["catmull-clark-fit"]
        final = report.get("final_depth") or {}
        fits.append({
            "kind": "fit", "guard": guard, "from_fit": start_from is not None, "iterations": report["iterations"], "cpu_s": time.process_time() - start,
            "depth_m": max(final.values()) if final else None, "body_in_surface_m": final.get("body_in_surface"), "probe_depth_m": report["after"]["max_penetration"],
            "depth_history_m": [round(d, 5) for d in report.get("depth_history", ())],
        })
        return out

    def logged_push(mesh, bodies):
        start = time.process_time()
        out = push_out(mesh, bodies)
        fits.append({"kind": "push-out", "found": out is not None, "cpu_s": time.process_time() - start})
        return out

    ccfit._fit_once, ccfit.push_out = logged_fit, logged_push
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases:
            drawn, body = draw_case(case)
            path = Path(tmp) / f"{drawn.name}.yaml"
            path.write_text(pose_yaml(drawn))
            log.clear()
            fits.clear()
            start = time.process_time()
            try:
                r = build({"template": "chair", "seed": 0, "bodies": [{"model": body, "pose": str(path)}]}, write=False, processes=False)
                row = {"built": True, "search": r.control_mesh.meta["search"]["winner"], "candidates": r.control_mesh.meta["search"]["candidates"]}
            except SeatkitError as e:
                row = {"built": False, "reason": str(e)}
            row.update(case=case, cpu_s=time.process_time() - start, starts=list(log), fits=list(fits))
            refused = [s for s in log if s["last_resort"] and not s["valid"]]
            surface = [f for f in fits if f["kind"] == "fit"]
            pushes = [f for f in fits if f["kind"] == "push-out"]
            print(
                f"{case}: built {row['built']}, {row.get('search')}, build {row['cpu_s']:.1f} s CPU; "
                f"{sum(not s['last_resort'] for s in log)} starts, {sum(s['last_resort'] for s in log)} last-resort starts "
                f"of which {len(refused)} gave no valid cage ({sum(s['cpu_s'] for s in refused):.1f} s; "
                f"{sum(s['reason'].startswith('alike') for s in refused)} of them recognised as a refused start again); "
                f"every start {sum(s['cpu_s'] for s in log):.1f} s; {len(surface)} surface fits ({sum(f['cpu_s'] for f in surface):.1f} s, "
                f"{sum(f['guard'] for f in surface)} guarded: {sum(f['cpu_s'] for f in surface if f['guard']):.1f} s); "
                f"{len(pushes)} push-outs ({sum(f['cpu_s'] for f in pushes):.1f} s)",
                flush=True,
            )
            rows.append(row)
            if args.results:
                with args.results.open("a") as fh:
                    fh.write(json.dumps(row) + "\n")
    if args.summary:
        summarise(rows)


def built_cases(path: Path) -> list[str]:
    """``FAMILY-INDEX@BODY`` of every drawn case a bench_generalisation.py results file built."""
    out = []
    for line in path.read_text().splitlines():
        record = json.loads(line) if line.strip() else {}
        result = record.get("result") or {}
        if record.get("kind") == "case" and (result.get("build") or {}).get("ok") and "pose" in result:
            out.append(f"{result['pose']}@{result['body']}")
    return out


def summarise(rows: list, limit: float = 0.005) -> None:
    """The guarded refits from a fit (within ``limit`` or not, and the fits they answer) and the refused starts before the first cage."""
    import re

    refits = {True: [], False: []}  # within the limit: [(answered fit, refit)]
    for row in rows:
        fits = [f for f in row["fits"] if f["kind"] == "fit"]
        for before, refit in zip(fits, fits[1:]):
            if refit["guard"] and refit["from_fit"] and refit["depth_m"] is not None:
                refits[refit["depth_m"] <= limit].append((before, refit))
    print(f"guarded refits from a fit: {sum(map(len, refits.values()))}; within {limit * 1000:g} mm: {len(refits[True])}, over: {len(refits[False])}")
    for ok, pairs in refits.items():
        if pairs:
            inside = [b["body_in_surface_m"] * 1000 for b, _ in pairs if b.get("body_in_surface_m") is not None]
            probes = [b["probe_depth_m"] * 1000 for b, _ in pairs]
            print(
                f"  {'within' if ok else 'over'}: the fits they answer: a body vertex {min(inside):.1f}-{max(inside):.1f} mm inside the furniture, "
                f"probes {min(probes):.1f}-{max(probes):.1f} mm in the body; the refits' iterations {min(r['iterations'] for _, r in pairs)}-{max(r['iterations'] for _, r in pairs)}"
            )
    late = same = 0
    for row in rows:
        ordinary = [st for st in row["starts"] if not st["last_resort"]]
        first = next((i for i, st in enumerate(ordinary) if st["valid"]), None)
        if not first:
            continue
        late += 1
        # the refusals run to their end (not recognised as a refused start again), without the person's name
        reasons = [re.sub(r"^person \d+ \([^)]*\): ", "", st["reason"]) for st in ordinary[:first] if not st["reason"].startswith("alike")]
        same += len(reasons) >= 2 and len(set(reasons)) == 1
    print(f"builds: {len(rows)}; first cage after refused starts: {late}, after two or more refusals all with the same reason: {same}")


if __name__ == "__main__":
    main()
