"""Generalisation of the chair template: random seated, reclined, crossed-leg and leaning-forward poses.

Draws ``--poses`` plausible poses (seatkit.body.generator; the joint ranges
and their sources are in docs/poses.md) plus ``--unsupported`` poses of the
families the chair cannot hold (sitting sideways, feet tucked, kneeling),
poses them on every ``--bodies`` body, and for each pose and body:

- fits the chair template with every ``--seeds`` seed (only the template
  fit draws on the seed: posing, pressure, refiners and the evaluation do
  not, though they judge the cage it gives), recording success or the
  refusal and its reason;
- checks that a refusal is the pose rule's (the ``pose-rule`` step, decided
  from the skeleton before fitting): any other refusal, of a pose the rule
  calls supportable, is a failure;
- with ``--library-builds``, builds every supported library pose in full
  (``seatkit build``'s default build, no files) with each of the
  ``--library-seeds`` seeds too, not only its template fit;
- with ``--table1`` (default on), runs one full default build (seed of the
  first ``--seeds``, both refiners, the evaluation against the flat patch)
  and records the paper's Table 1 figures, the surface's deepest
  penetration into the body, and the build's time; with
  ``--build-every-seed``, a full build with every ``--seeds`` seed (the
  template's cage depends on the seed, so the refiners' verdict can too):
  success counts every one, Table 1 reports the first seed's.

Prints the success rate on the supportable poses, refusals by reason, the
Table 1 comparison (wins of ours over the flat patch on average distance,
average and maximum pressure, and the means), and the time per template fit
and per build. ``--markdown FILE`` writes the same as a Markdown section
(docs/evaluation.md holds today's).

With ``--captures DIR`` it also runs the real-capture set: every frame
of every BVH file in DIR (benchmarks/captures: seated frames of the CMU
motion-capture database, their sources in DIR/SOURCES.md), turned to each
``--capture-headings`` heading (the root's rotation turned about the file's
up axis, written to a temporary one-frame BVH: no stored copies), on every
``--bodies`` body: whether the pose rule accepts it, whether the full
default build (first ``--seeds`` seed) finishes, the paper's Table 1 wins
over the flat patch, and whether every heading gives the same cage (the
canonical frame, seatkit.body.frame). The real-capture runs of
docs/evaluation.md, the frames picked by eye and those taken from each take
by a fixed rule (benchmarks/captures/sampled; ``--capture-seated`` keeps
the frames with a thigh within 45 deg of level and lists the others):

    nice -n 10 python benchmarks/bench_generalisation.py --poses 0 --unsupported 0 --library-seeds 0 --seeds 0 --captures benchmarks/captures --workers 2 --results captures.jsonl --markdown captures.md
    nice -n 10 python benchmarks/bench_generalisation.py --poses 0 --unsupported 0 --library-seeds 0 --seeds 0 --captures benchmarks/captures/sampled --capture-seated --workers 2 --results sampled.jsonl --markdown sampled.md

Pose-and-body tasks run in ``--workers`` processes (concurrent.futures);
each build runs in one process (``processes=False``) with BLAS on one
thread. Run it niced on a shared machine:

    nice -n 10 python benchmarks/bench_generalisation.py --poses 200 --unsupported 12 --seeds 0 1 2 --build-every-seed --table1-every 1 --workers 2 --library-seeds 10 --library-builds --library-bodies default-male default-female --results gen.jsonl --markdown gen.md

(docs/evaluation.md, "Poses nobody picked": about 30 minutes on 2 cores.)
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import platform
import re
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

WIN_KEYS = ("avg_distance_m", "avg_pressure_pa", "max_pressure_pa")

_STATE: dict = {}


def _init(bodies, folder):
    from threadpoolctl import threadpool_limits

    from seatkit.body import load_rig
    from seatkit.plugins import get_plugin_manager
    from seatkit.resources import template_path
    from seatkit.template import load_template

    _STATE["limits"] = threadpool_limits(limits=1)
    _STATE["rigs"] = {b: load_rig(b) for b in bodies}
    _STATE["rigs"].setdefault("default-male", load_rig("default-male"))
    _STATE["template"] = load_template(template_path("chair.yaml"))
    _STATE["pm"] = get_plugin_manager()
    _STATE["folder"] = Path(folder)


def reason_kind(message: str) -> str:
    """A short category of a refusal message (the pose rule's, or the fit's)."""
    for pattern, kind in (
        (r"lies on its side", "lying on the side"),
        (r"sitting sideways", "sitting sideways"),
        (r"kneeling", "kneeling"),
        (r"a hand on the floor", "a hand on the floor"),
        (r"feet under the body", "feet under the body"),
        (r"crosses the body", "cage crosses the body"),
        (r"intersects itself", "cage intersects itself"),
        (r"cannot support .*important vertices", "occluded support"),
    ):
        if re.search(pattern, message):
            return kind
    return "other: " + message[:60]


def run_library(task):
    """Fit one library pose on one body with seeds 0..n-1; with ``builds``, also build it in full with each seed."""
    from seatkit.body import load_pose, pose_rig
    from seatkit.errors import SeatkitError, UnsupportedPoseError
    from seatkit.pipeline import build
    from seatkit.pressure.qp import solve_pressure

    name, body_name, n, *rest = task
    builds = bool(rest and rest[0])
    body = pose_rig(_STATE["rigs"][body_name], load_pose(name))
    pressure = solve_pressure(body)
    out = {"pose": name, "body": body_name, "ok": 0, "fallback": 0, "refusals": []}
    for seed in range(n):
        try:
            mesh = _STATE["template"].fit([body], [pressure], seed=seed)
            out["ok"] += 1
            out["fallback"] += mesh.meta["fit_attempts"]["attempt"] > 1
        except UnsupportedPoseError as e:
            out["refusals"].append(f"seed {seed}: {e}")
    if builds:
        # the whole default build, as `seatkit build --pose NAME --body BODY --seed S` runs it (no files)
        out["built"], out["build_refusals"] = 0, []
        for seed in range(n):
            recipe = {"template": "chair", "seed": seed, "bodies": [{"model": body_name, "pose": name}]}
            try:
                build(recipe, pm=_STATE["pm"], write=False, processes=False)
                out["built"] += 1
            except SeatkitError as e:
                out["build_refusals"].append(f"seed {seed}: {type(e).__name__}: {e}")
    return out


def run_task(task):
    """Fit every seed (and one full build) for one pose on one body."""
    from seatkit.body import load_pose, pose_rig
    from seatkit.body.generator import draw_pose, pose_yaml
    from seatkit.errors import SeatkitError, UnsupportedPoseError
    from seatkit.pipeline import build
    from seatkit.pressure.qp import solve_pressure
    from seatkit.template.pose_rule import assess_pose, template_rule

    import numpy as np

    index, family, draw_seed, body_name, seeds, table1, *every = task
    build_seeds = list(seeds) if every and every[0] else list(seeds[:1])
    drawn = draw_pose(np.random.default_rng([draw_seed, index]), family, f"{family}-{index:03d}")
    template = _STATE["template"]
    # the template fits and the full build fit the same pose: the one the
    # build reads from the pose file, which is the drawn pose bit for bit
    # (pose_yaml writes every angle at full precision)
    path = _STATE["folder"] / body_name / f"{drawn.name}.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(pose_yaml(drawn))
    pose = load_pose(path)
    if not (np.array_equal(pose.rotations, drawn.pose.rotations) and np.array_equal(pose.translation, drawn.pose.translation)):
        raise AssertionError(f"{drawn.name}: the pose read back from its YAML file is not the drawn pose")
    body = pose_rig(_STATE["rigs"][body_name], pose)
    pressure = solve_pressure(body)
    verdict = assess_pose(body, template_rule(template))
    out = {"pose": drawn.name, "family": family, "body": body_name, "rule_ok": verdict.supportable, "rule_reasons": verdict.reasons, "fits": []}
    fit_seeds = list(seeds)
    for seed in build_seeds if table1 and verdict.supportable else ():
        # a full build's own template fit counts as that seed's fit
        recipe = {"template": "chair", "seed": seed, "bodies": [{"model": body_name, "pose": str(path)}]}
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            r = build(recipe, pm=_STATE["pm"], write=False, processes=False)
            ours, base = r.metrics["ours"][0], r.metrics["baseline"][0]
            out["fits"].append({"seed": seed, "ok": True, "seconds": r.timings["template"], "attempt": r.initial_mesh.meta["fit_attempts"]["attempt"]})
            done = {
                "seed": seed,
                "ok": True,
                "seconds": time.perf_counter() - t0,
                "cpu_seconds": time.process_time() - c0,
                # which candidate of the design search became the design (seatkit.search; absent before it)
                "search": _search_route(r.control_mesh.meta.get("search")),
                "ours": {k: ours[k] for k in (*WIN_KEYS, "max_penetration_m")},
                "flat": {k: base.get(k, float("inf")) for k in WIN_KEYS},
            }
            fit_seeds.remove(seed)
        except SeatkitError as e:
            # the rule accepted the pose: any refusal of the build (the template's too) is a disagreement;
            # the seed's template fit alone is still recorded below
            done = {"seed": seed, "ok": False, "seconds": time.perf_counter() - t0, "cpu_seconds": time.process_time() - c0, "reason": f"{type(e).__name__}: {e}"}
        # "build" is the first seed's (Table 1), "builds" every seed's
        if seed == seeds[0]:
            out["build"] = done
        out.setdefault("builds", []).append(done)
    path.unlink()
    for seed in fit_seeds:
        t0 = time.perf_counter()
        try:
            mesh = template.fit([body], [pressure], seed=seed)
            out["fits"].append({"seed": seed, "ok": True, "seconds": time.perf_counter() - t0, "attempt": mesh.meta["fit_attempts"]["attempt"]})
        except UnsupportedPoseError as e:
            out["fits"].append({"seed": seed, "ok": False, "seconds": time.perf_counter() - t0, "reason": str(e), "rule": bool(getattr(e, "seed_independent", False))})
    if not all(f["ok"] for f in out["fits"]) and verdict.supportable:
        out["yaml"] = pose_yaml(drawn)
    return out


def _search_route(report) -> dict | None:
    """The winner's origin and how many candidates the design search refined (None: no search report)."""
    if not report:
        return None
    return {"origin": report["winner"]["origin"], "candidates": len(report["candidates"])}


def _case_ok(r) -> bool:
    """Every seed's template fit and every full build of a case succeeded."""
    return all(f["ok"] for f in r["fits"]) and all(b["ok"] for b in r.get("builds", [r["build"]] if "build" in r else []))


def _bvh_up(path):
    """A BVH file read, its joint index for each skeleton segment, and its up axis.

    The up axis is the rest skeleton's hips-to-head direction snapped to the
    nearest file axis.
    """
    import numpy as np

    from seatkit.body.bvh import read_bvh
    from seatkit.body.name_maps import BUILTIN_BVH_MAPS, candidate_maps, choose_map
    from seatkit.skeleton import SEGMENT_INDEX

    motion = read_bvh(path)
    _, index = choose_map(motion.names, candidate_maps(None, BUILTIN_BVH_MAPS))
    rest = motion.rest_positions()
    up = rest[index[SEGMENT_INDEX["Head"]]] - rest[index[0]]
    axis = np.zeros(3)
    axis[int(np.argmax(np.abs(up)))] = np.sign(up[int(np.argmax(np.abs(up)))])
    return motion, index, axis


def turned_bvh(path, frame: int, degrees: float) -> str:
    """One frame of a BVH file as BVH text, its root turned by ``degrees`` about the file's up axis.

    The root's rotation channels (and its horizontal position) are turned,
    every other channel is kept as written.
    """
    import numpy as np
    from scipy.spatial.transform import Rotation

    motion, _, axis = _bvh_up(path)
    turn = Rotation.from_rotvec(np.radians(degrees) * axis)
    row = motion.frames[frame].copy()
    order, cols = motion.rotation_orders[0], motion.rotation_columns[0]
    root = Rotation.from_euler(order, np.where(cols >= 0, row[cols], 0.0), degrees=True)
    row[cols[cols >= 0]] = (turn * root).as_euler(order, degrees=True)[cols >= 0]
    have = motion.position_columns >= 0
    if have.all():
        row[motion.position_columns] = turn.apply(row[motion.position_columns])
    text = Path(path).read_text()
    head = text[: text.upper().index("MOTION")]
    return f"{head}MOTION\nFrames: 1\nFrame Time: {motion.frame_time:g}\n" + " ".join(repr(float(v)) for v in row) + "\n"


#: A frame is seated (``--capture-seated``) when at least one thigh is within
#: this many degrees of horizontal: standing (both thighs pointing down) and
#: walking frames are left out, sitting on anything (or on nothing) is kept.
SEATED_THIGH_DEG = 45.0


def thigh_down_deg(path, frame: int) -> list[float]:
    """How far each thigh (hip joint to knee) points below horizontal in one frame of a BVH file, degrees (right, left)."""
    import numpy as np

    from seatkit.skeleton import SEGMENT_INDEX

    motion, index, axis = _bvh_up(path)
    _, pos = motion.global_transforms(frame)
    out = []
    for side in ("Right", "Left"):
        thigh = pos[index[SEGMENT_INDEX[side + "Leg"]]] - pos[index[SEGMENT_INDEX[side + "UpLeg"]]]
        out.append(float(np.degrees(np.arcsin(np.clip(-(thigh @ axis) / np.linalg.norm(thigh), -1.0, 1.0)))))
    return out


def capture_frames(args) -> tuple[list, list]:
    """The (file, frame) pairs of the capture set, and those ``--capture-seated`` leaves out (standing) with their thigh angles."""
    from seatkit.body.bvh import read_bvh

    kept, left_out = [], []
    for path in sorted(Path(args.captures).glob("*.bvh")):
        for frame in range(read_bvh(path).n_frames):
            if args.capture_seated:
                down = thigh_down_deg(path, frame)
                if min(down) >= SEATED_THIGH_DEG:
                    left_out.append((str(path), frame, down))
                    continue
            kept.append((str(path), frame))
    return kept, left_out


def capture_tasks(args) -> list:
    """(file, frame, heading, body, seed) for every kept frame of every BVH in ``args.captures``, at every heading, on every body."""
    out = []
    for path, frame in capture_frames(args)[0]:
        for heading in args.capture_headings:
            for body in args.bodies:
                out.append((path, frame, float(heading), body, args.seeds[0]))
    return out


def run_capture(task):
    """The rule's verdict and the full default build of one capture frame at one heading on one body."""
    import numpy as np

    from seatkit.body.frame import pose_canonical
    from seatkit.body import load_pose
    from seatkit.errors import SeatkitError
    from seatkit.pipeline import build
    from seatkit.plugins import get_plugin_manager  # noqa: F401  (the worker's plugin manager is _STATE["pm"])
    from seatkit.template.pose_rule import assess_pose, template_rule

    path, frame, heading, body_name, seed = task
    name = f"{Path(path).stem}#{frame}"
    tmp = _STATE["folder"] / body_name / f"{Path(path).stem}-{frame}-{heading:g}.bvh"
    tmp.parent.mkdir(exist_ok=True)
    tmp.write_text(turned_bvh(path, frame, heading))
    model = _STATE["pm"].registry.get("body_model", body_name)
    rig = model.make_body(params={})
    body, frame_move = pose_canonical(model, rig, load_pose(tmp, rig=rig))
    verdict = assess_pose(body, template_rule(_STATE["template"]))
    out = {"capture": name, "heading": heading, "body": body_name, "rule_ok": verdict.supportable, "rule_reasons": verdict.reasons,
           "capture_heading_deg": float(np.degrees(frame_move.heading))}
    if verdict.supportable:
        recipe = {"template": "chair", "seed": seed, "bodies": [{"model": body_name, "pose": str(tmp)}]}
        t0 = time.perf_counter()
        try:
            r = build(recipe, pm=_STATE["pm"], write=False, processes=False)
            ours, base = r.metrics["ours"][0], r.metrics["baseline"][0]
            out["build"] = {
                "ok": True,
                "seconds": time.perf_counter() - t0,
                "ours": {k: ours[k] for k in (*WIN_KEYS, "max_penetration_m")},
                "flat": {k: base.get(k, float("inf")) for k in WIN_KEYS},
                "cage": np.round(r.control_mesh.vertices, 9).tolist(),
            }
        except SeatkitError as e:
            out["build"] = {"ok": False, "seconds": time.perf_counter() - t0, "reason": f"{type(e).__name__}: {e}"}
    tmp.unlink()
    return out


def _capture_reason(message: str) -> str:
    """A short category of a refusal of a capture frame (the pose rule's categories, standing and a leg reaching back)."""
    for start in ("standing on its own feet", "a leg reaching back"):
        if message.startswith(start):
            return start
    return reason_kind(message)


def _capture_rows(captures, args) -> str:
    """The real-capture section: per heading, accepted by the rule, built of accepted, Table 1 wins; the same design at every heading."""
    import numpy as np

    if not captures:
        return ""
    frames = sorted({r["capture"] for r in captures})
    rows = ["", "", f"Real captures ({len(frames)} seated frames of {len({f.split('#')[0] for f in frames})} takes, {args.captures}) "
            f"x headings {' '.join(f'{h:g}' for h in args.capture_headings)} deg x bodies {', '.join(args.bodies)}; full default build, seed {args.seeds[0]}:", ""]
    if args.capture_seated:
        left_out = capture_frames(args)[1]
        rows[-1:-1] = [
            f"Left out as not seated (--capture-seated: both thighs more than {SEATED_THIGH_DEG:g} deg below horizontal): {len(left_out)} frames"
            + "".join(f"{'; ' if i else ' ('}{Path(f).stem}#{k} {min(d):.0f} deg" for i, (f, k, d) in enumerate(left_out)) + (")." if left_out else ".")
        ]
    rows += ["| heading | cases | accepted by the rule | built of accepted | Table 1: ours better in all three | deepest penetration (max) |", "|---|---|---|---|---|---|"]
    for heading in args.capture_headings:
        at = [r for r in captures if r["heading"] == float(heading)]
        acc = [r for r in at if r["rule_ok"]]
        built = [r for r in acc if r.get("build", {}).get("ok")]
        wins = sum(all(r["build"]["ours"][k] < r["build"]["flat"][k] for k in WIN_KEYS) for r in built)
        pen = max((r["build"]["ours"]["max_penetration_m"] for r in built), default=float("nan"))
        rows.append(f"| {heading:g} | {len(at)} | {len(acc)} | {len(built)} of {len(acc)} | {wins} of {len(built)} | {1000 * pen:.1f} mm |")
    # the same design at every heading: the largest distance between the cages of one capture and body
    spread = []
    for key in {(r["capture"], r["body"]) for r in captures}:
        cages = [np.array(r["build"]["cage"]) for r in captures if (r["capture"], r["body"]) == key and r.get("build", {}).get("ok")]
        if len(cages) > 1 and all(c.shape == cages[0].shape for c in cages):
            spread.append(max(float(np.abs(c - cages[0]).max()) for c in cages))
    if spread:
        rows += ["", f"Same design at every heading: the cages of one capture and body differ by at most {max(spread):.1e} m over {len(spread)} capture-and-body pairs."]
    verdicts = {(r["capture"], r["body"]): set() for r in captures}
    for r in captures:
        verdicts[(r["capture"], r["body"])].add(r["rule_ok"])
    rows.append(f"Rule verdicts that change with the heading: {sum(len(v) > 1 for v in verdicts.values())} of {len(verdicts)}.")
    refused = collections.Counter(_capture_reason(x) for r in captures if not r["rule_ok"] for x in r["rule_reasons"])
    if refused:
        rows.append("Refused by the rule: " + ", ".join(f"{k} {n}" for k, n in refused.most_common()) + " (cases; a case may give several reasons).")
    for r in captures:
        if r["rule_ok"] and not r["build"]["ok"]:
            rows.append(f"- build failed: {r['capture']} at {r['heading']:g} deg on {r['body']}: {r['build']['reason'][:160]}")
    return "\n".join(rows)


def tasks(args):
    from seatkit.body.generator import FAMILIES, UNSUPPORTED_FAMILIES

    out = []
    for i in range(args.poses):
        if args.indices is None or i in args.indices:
            out.append((i, FAMILIES[i % len(FAMILIES)]))
    for j in range(args.unsupported):
        out.append((args.poses + j, UNSUPPORTED_FAMILIES[j % len(UNSUPPORTED_FAMILIES)]))
    cases = [(i, fam, body) for i, fam in out for body in args.bodies]
    every = (True,) if args.build_every_seed else ()
    return [(i, fam, args.draw_seed, body, tuple(args.seeds), args.table1 and n % args.table1_every == 0, *every) for n, (i, fam, body) in enumerate(cases)]


def summarise(results, args, wall) -> str:
    import numpy as np

    lines = []
    supp = [r for r in results if r["rule_ok"]]
    refused = [r for r in results if not r["rule_ok"]]
    fits = [f for r in supp for f in r["fits"]]
    ok_fits = sum(f["ok"] for f in fits)
    ok_all = sum(all(f["ok"] for f in r["fits"]) for r in supp)
    n_poses = len({r["pose"] for r in results})
    lines.append(f"{n_poses} poses ({args.poses} plausible + {args.unsupported} of the unsupported families, draw seed {args.draw_seed}) "
                 f"x {len(args.bodies)} bodies ({', '.join(args.bodies)}) x seeds {' '.join(map(str, args.seeds))}; {wall / 60:.1f} min (this invocation) on {os.cpu_count()} cores, {args.workers} workers")
    lines.append("")
    lines.append("| | count |")
    lines.append("|---|---|")
    lines.append(f"| pose-and-body cases | {len(results)} |")
    lines.append(f"| supportable by the pose rule | {len(supp)} |")
    lines.append(f"| of those, every seed's template fit succeeded | {ok_all} ({100 * ok_all / max(1, len(supp)):.1f}%) |")
    lines.append(f"| template fits of supportable cases that succeeded | {ok_fits} of {len(fits)} ({100 * ok_fits / max(1, len(fits)):.1f}%) |")
    ran = [r for r in supp if "build" in r]
    if ran:
        # a design is built when the whole build finishes (refiners, the 5 mm guarantee, the evaluation), not only its template fit
        done = sum(r["build"]["ok"] for r in ran)
        whole = sum(_case_ok(r) for r in ran)
        lines.append(f"| full builds (refiners, 5 mm guarantee, evaluation; seed {args.seeds[0]}) of supportable cases that finished | {done} of {len(ran)} ({100 * done / len(ran):.1f}%) |")
        lines.append(f"| cases with a full build: every seed's fit and the build succeeded | {whole} of {len(ran)} ({100 * whole / len(ran):.1f}%) |")
        every = [b for r in supp for b in r.get("builds", [])]
        if len(every) > len(ran):
            ok_every = sum(b["ok"] for b in every)
            lines.append(f"| full builds with every seed ({' '.join(map(str, args.seeds))}) of supportable cases that finished | {ok_every} of {len(every)} ({100 * ok_every / len(every):.1f}%) |")
    lines.append(f"| refused by the pose rule (every seed, with its reason) | {len(refused)} |")
    rule_refusals_only = all(not f["ok"] and f.get("rule") for r in refused for f in r["fits"])
    lines.append(f"| every refusal of those is the pose rule's | {'yes' if rule_refusals_only else 'NO'} |")
    lines.append("")
    by_family = collections.defaultdict(lambda: [0, 0])
    for r in results:
        by_family[r["family"]][0] += 1
        by_family[r["family"]][1] += r["rule_ok"]
    lines.append("| family | cases | supportable | refused |")
    lines.append("|---|---|---|---|")
    for fam, (n, s) in by_family.items():
        lines.append(f"| {fam} | {n} | {s} | {n - s} |")
    lines.append("")
    reasons = collections.Counter()
    for r in refused:
        for kind in sorted({reason_kind(x) for x in r["rule_reasons"]}):
            reasons[kind] += 1
    lines.append("| refusal reason (pose rule) | cases |")
    lines.append("|---|---|")
    for kind, n in reasons.most_common():
        lines.append(f"| {kind} | {n} |")
    failures = [(r, f) for r in supp for f in r["fits"] if not f["ok"]]
    if failures:
        lines.append("")
        lines.append("Failures (supportable by the rule, refused by the fit):")
        kinds = collections.Counter(reason_kind(f["reason"]) for _, f in failures)
        for kind, n in kinds.most_common():
            lines.append(f"- {kind}: {n} fits")
        for r, f in failures[:10]:
            lines.append(f"  - {r['pose']} on {r['body']}, seed {f['seed']}: {f['reason'][:160]}")
    builds = [r["build"] for r in supp if "build" in r]
    good = [b for b in builds if b["ok"]]
    if builds:
        lines.append("")
        every = f"every {args.table1_every}th pose-and-body case" if args.table1_every > 1 else "every pose and body"
        lines.append(f"Table 1 on one full default build (seed {args.seeds[0]}) of {every} the rule calls supportable ({len(good)} of {len(builds)} builds finished):")
        lines.append("")
        lines.append("| measure | ours: mean | flat patch: mean | ours better in |")
        lines.append("|---|---|---|---|")
        label = {"avg_distance_m": ("average distance", "cm", 100), "avg_pressure_pa": ("average pressure", "Pa", 1), "max_pressure_pa": ("maximum pressure", "Pa", 1)}
        for k in WIN_KEYS:
            name, unit, scale = label[k]
            wins = sum(b["ours"][k] < b["flat"][k] for b in good)
            finite = [b["flat"][k] for b in good if b["flat"][k] != float("inf")]
            lines.append(
                f"| {name} | {scale * statistics.fmean(b['ours'][k] for b in good):.2f} {unit} | "
                f"{scale * statistics.fmean(finite) if finite else float('nan'):.2f} {unit} | {wins} of {len(good)} ({100 * wins / max(1, len(good)):.1f}%) |"
            )
        all3 = sum(all(b["ours"][k] < b["flat"][k] for k in WIN_KEYS) for b in good)
        lines.append(f"| all three | | | {all3} of {len(good)} ({100 * all3 / max(1, len(good)):.1f}%) |")
        pen = [b["ours"]["max_penetration_m"] for b in good]
        lines.append("")
        lines.append(f"Deepest penetration of our surface into the body: median {1000 * statistics.median(pen):.1f} mm, max {1000 * max(pen):.1f} mm (limit 5 mm).")
        for r in supp:
            for b in r.get("builds", [r["build"]] if "build" in r else []):
                if not b["ok"]:
                    lines.append(f"- build failed: {r['pose']} on {r['body']}, seed {b.get('seed', args.seeds[0])}: {b['reason'][:160]}")
    fit_s = [f["seconds"] for r in supp for f in r["fits"] if f["ok"]]
    rule_s = [f["seconds"] for r in refused for f in r["fits"]]
    retried = sum(f.get("attempt", 1) > 1 for r in supp for f in r["fits"] if f["ok"])
    lines.append("")
    lines.append("Time (loaded shared machine, BLAS on one thread, several workers at once):")
    if fit_s:
        lines.append(f"- template fit: median {statistics.median(fit_s):.2f} s, 90th percentile {float(np.percentile(fit_s, 90)):.2f} s, max {max(fit_s):.2f} s; "
                     f"{retried} of {len(fit_s)} successful fits needed a fallback start")
    if rule_s:
        lines.append(f"- refusal by the pose rule: median {1000 * statistics.median(rule_s):.0f} ms")
    every_good = [b for r in supp for b in r.get("builds", [r["build"]] if "build" in r else []) if b["ok"]]
    if every_good:
        bs = [b["seconds"] for b in every_good]
        lines.append(f"- full build (one process, no export), every finished build: median {statistics.median(bs):.2f} s, max {max(bs):.2f} s ({max(bs) / statistics.median(bs):.1f}x the median)")
        cpu = [b["cpu_seconds"] for b in every_good if "cpu_seconds" in b]
        if cpu:
            lines.append(f"- the same in CPU time (the build's process): median {statistics.median(cpu):.2f} s, max {max(cpu):.2f} s ({max(cpu) / statistics.median(cpu):.1f}x the median)")
        routes = collections.Counter((b["search"]["origin"], b["search"]["candidates"]) for b in every_good if b.get("search"))
        if routes:
            lines.append("- design search, winning candidate (origin, candidates refined): " + ", ".join(f"{o} after {n}: {k}" for (o, n), k in sorted(routes.items())))
    return "\n".join(lines)


def draw_images(args) -> None:
    """The first draw of every family on the first body, front and side (docs/poses.md)."""
    import numpy as np

    from seatkit.body import load_rig, pose_rig
    from seatkit.body.generator import FAMILIES, UNSUPPORTED_FAMILIES, draw_pose
    from seatkit.body.render import render_body

    rig = load_rig(args.bodies[0])
    args.images.mkdir(parents=True, exist_ok=True)
    for family in FAMILIES + UNSUPPORTED_FAMILIES:
        drawn = draw_pose(np.random.default_rng([args.draw_seed, 0]), family, f"{family} (first draw)")
        path = args.images / f"generated-{family}.png"
        render_body(pose_rig(rig, drawn.pose), path, views=("front", "side"), title=f"{args.bodies[0]}: {drawn.name}", show_skeleton=True)
        print(path)
    if args.cages:
        _draw_cages(args, rig)


def _draw_cages(args, rig) -> None:
    """The chair (seed 0) on the first draw of each supported family that the rule accepts: args.cages/chair-<family>.png."""
    import numpy as np
    from threadpoolctl import threadpool_limits

    from seatkit.body import pose_rig
    from seatkit.body.generator import FAMILIES, draw_pose
    from seatkit.pressure.qp import solve_pressure
    from seatkit.resources import template_path
    from seatkit.template import load_template
    from seatkit.template.pose_rule import assess_pose, template_rule
    from seatkit.template.render import render_cage

    chair = load_template(template_path("chair.yaml"))
    args.cages.mkdir(parents=True, exist_ok=True)
    with threadpool_limits(limits=1):
        for family in FAMILIES:
            # the first draw of the family that the rule accepts, as the benchmark draws it (index i of family[i % 4])
            for i in range(FAMILIES.index(family), 4 * args.poses, len(FAMILIES)):
                drawn = draw_pose(np.random.default_rng([args.draw_seed, i]), family, f"{family}-{i:03d}")
                body = pose_rig(rig, drawn.pose)
                if assess_pose(body, template_rule(chair)).supportable:
                    break
            mesh = chair.fit([body], [solve_pressure(body)], seed=0)
            path = args.cages / f"chair-{family}.png"
            render_cage(mesh, [body], path, title=f"chair on {drawn.name} ({args.bodies[0]}, seed 0)", dpi=70)
            print(path, mesh.meta["fit_attempts"])


def _library_rows(library, args) -> str:
    if not library:
        return ""
    builds = all("built" in r for r in library)
    what = "template fit and full build" if builds else "template fit"
    rows = ["", "", f"Library poses marked supported, {what} with seeds 0-{args.library_seeds - 1}:", ""]
    rows += ["| pose | body | fitted | needed a fallback start | full builds that finished |", "|---|---|---|---|---|"] if builds else ["| pose | body | built | needed a fallback start |", "|---|---|---|---|"]
    for r in library:
        cells = [r["pose"], r["body"], f"{r['ok']} of {args.library_seeds}", str(r["fallback"])]
        if builds:
            cells.append(f"{r['built']} of {args.library_seeds}")
        rows.append("| " + " | ".join(cells) + " |")
        rows += [f"| | | {x[:120]} | |" for x in r["refusals"] + r.get("build_refusals", [])]
    if builds:
        total = sum(r["built"] for r in library)
        rows += ["", f"Full builds of the library poses: {total} of {args.library_seeds * len(library)}."]
    return "\n".join(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=200, help="plausible poses drawn (families in turn)")
    ap.add_argument("--unsupported", type=int, default=12, help="poses drawn from the unsupported families (sideways, feet tucked, kneeling)")
    ap.add_argument("--bodies", nargs="+", default=["default-male", "default-female"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--draw-seed", type=int, default=2026)
    ap.add_argument("--indices", nargs="+", type=int, help="only these draw indices of the plausible poses (0 .. --poses - 1)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-table1", dest="table1", action="store_false", help="template fits only, no full builds")
    ap.add_argument("--table1-every", type=int, default=1, help="full build (Table 1) for every K-th pose-and-body case only")
    ap.add_argument("--markdown", type=Path, help="write the summary (Markdown) here")
    ap.add_argument("--failures", type=Path, help="folder for the pose YAML of every failing supportable pose")
    ap.add_argument("--results", type=Path, help="append every result to this JSON-lines file and skip the cases it already holds (resume)")
    ap.add_argument("--summarise-only", action="store_true", help="run nothing: print the summary of what --results holds (marked partial when cases are missing)")
    ap.add_argument("--build-every-seed", action="store_true", help="with Table 1: build in full with every --seeds seed, not only the first")
    ap.add_argument("--library-seeds", type=int, default=10, help="also fit every supported library pose with seeds 0..N-1 (0: skip)")
    ap.add_argument("--library-bodies", nargs="+", help="bodies for the library poses (default: the first of --bodies, the build's default)")
    ap.add_argument("--library-builds", action="store_true", help="also build every supported library pose in full with each of those seeds")
    ap.add_argument("--captures", type=Path, help="also run the real-capture set: every frame of every BVH in this folder (benchmarks/captures)")
    ap.add_argument("--capture-headings", nargs="+", type=float, default=[0.0, 90.0, 180.0, 270.0], help="headings (deg) each capture is turned to")
    ap.add_argument(
        "--capture-seated", action="store_true",
        help=f"keep only the seated capture frames: at least one thigh within {SEATED_THIGH_DEG:g} deg of horizontal (for frames sampled by a fixed rule, benchmarks/captures/sampled)",
    )
    ap.add_argument("--images", type=Path, help="only draw DIR/generated-<family>.png (the first draw of each family) and stop")
    ap.add_argument("--cages", type=Path, help="with --images: also draw the chair on a supportable draw of each family, DIR/chair-<family>.png")
    args = ap.parse_args()
    if args.images:
        draw_images(args)
        return
    print(f"python {platform.python_version()}, {os.cpu_count()} cores, {platform.machine()}", flush=True)
    from seatkit.body import list_poses

    todo = [("case", t) for t in tasks(args)]
    if args.library_seeds:
        extra = (True,) if args.library_builds else ()
        todo += [("library", (i.name, b, args.library_seeds, *extra)) for i in list_poses() if i.supported for b in (args.library_bodies or args.bodies[:1])]
    if args.captures:
        todo += [("capture", t) for t in capture_tasks(args)]
    done = {}
    if args.results and args.results.exists():
        for line in args.results.read_text().splitlines():
            if line.strip():
                rec = json.loads(line)
                done[(rec["kind"], rec["key"])] = rec["result"]
    key = {"case": lambda t: f"{t[0]}:{t[1]}:{t[2]}:{t[3]}:{','.join(map(str, t[4]))}:{t[5]}" + (":every-seed" if t[6:] else ""), "library": lambda t: f"{t[0]}:{t[1]}:{t[2]}" + (":builds" if t[3:] else ""), "capture": lambda t: ":".join(map(str, t))}
    results = [done[("case", key["case"](t))] for kind, t in todo if kind == "case" and ("case", key["case"](t)) in done]
    library = [done[("library", key["library"](t))] for kind, t in todo if kind == "library" and ("library", key["library"](t)) in done]
    captures = [done[("capture", key["capture"](t))] for kind, t in todo if kind == "capture" and ("capture", key["capture"](t)) in done]
    todo = [(kind, t) for kind, t in todo if (kind, key[kind](t)) not in done]
    if args.summarise_only:
        missing = sum(kind == "case" for kind, _ in todo)
        missing_lib = sum(kind == "library" for kind, _ in todo)
        text = summarise(results, args, 0.0)
        if missing or missing_lib:
            text = f"PARTIAL: {missing} pose-and-body cases and {missing_lib} library poses not run yet\n\n" + text
        text += _library_rows(sorted(library, key=lambda r: (r["pose"], r["body"])), args)
        text += _capture_rows(captures, args)
        print(text)
        if args.markdown:
            args.markdown.write_text(text + "\n")
        return
    if done:
        print(f"resuming: {len(results) + len(library)} results read from {args.results}, {len(todo)} to go", flush=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder, ProcessPoolExecutor(args.workers, initializer=_init, initargs=(args.bodies, folder)) as pool:
        workers = {"case": run_task, "library": run_library, "capture": run_capture}
        futures = {pool.submit(workers[kind], t): (kind, t) for kind, t in todo}
        for n, fut in enumerate(as_completed(futures), 1):
            kind, t = futures[fut]
            r = fut.result()
            if args.results:
                with args.results.open("a") as fh:
                    fh.write(json.dumps({"kind": kind, "key": key[kind](t), "result": r}) + "\n")
            if kind == "library":
                library.append(r)
                status = f"library, {r['ok']} of {t[2]} seeds fitted" + (f", {r['built']} built in full" if "built" in r else "")
            elif kind == "capture":
                captures.append(r)
                r = {**r, "pose": f"{r['capture']} at {r['heading']:g} deg"}
                status = "refused (rule)" if not r["rule_ok"] else ("built" if r["build"]["ok"] else "BUILD FAILED: " + r["build"]["reason"][:100])
            else:
                results.append(r)
                ok = _case_ok(r)
                status = "refused (rule)" if not r["rule_ok"] else ("ok" if ok else "FAILED")
                if args.failures and "yaml" in r:
                    args.failures.mkdir(parents=True, exist_ok=True)
                    (args.failures / f"{r['pose']}-{r['body']}.yaml").write_text(r["yaml"])
            print(f"[{n}/{len(todo)} {(time.perf_counter() - t0) / 60:.1f} min] {r['pose']} on {r['body']}: {status}", flush=True)
    library.sort(key=lambda r: (r["pose"], r["body"]))
    results.sort(key=lambda r: (r["pose"], r["body"]))
    text = summarise(results, args, time.perf_counter() - t0)
    text += _library_rows(library, args)
    text += _capture_rows(captures, args)
    bad_library = [r for r in library if r["refusals"] or r.get("build_refusals")]
    print()
    print(text)
    if args.markdown:
        args.markdown.write_text(text + "\n")
    # a failure: a supportable case whose fit (any seed) or full build was refused
    bad = [r for r in results if r["rule_ok"] and not _case_ok(r)]
    bad_captures = [r for r in captures if r["rule_ok"] and not r["build"]["ok"]]
    sys.exit(1 if bad or bad_library or bad_captures else 0)


if __name__ == "__main__":
    main()
