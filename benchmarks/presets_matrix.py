"""Every library pose on every percentile manikin: poses, solves, builds.

For each preset (p5-female ... p95-male) and each library pose: the body is
posed, the pressure solved (the six balance equations checked: vertical
forces sum to the weight), and, for the supported poses, the default chair
build is run (template, both refiners, evaluation; nothing written). Prints
a Markdown table (the one in docs/bodies.md) with the seat dimensions of
each build (seatkit.dimensions) or the reason it failed, and with
``--table1 FILE`` the paper's Table 1 rows (ours vs the flat patch, as
``benchmarks/table1.py`` prints them) of every build.

    python benchmarks/presets_matrix.py [--presets p5-female,p95-male] [--out matrix.md] [--table1 table1.md]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from seatkit.body import list_poses, load_pose, pose_rig
from seatkit.body.presets import make_preset
from seatkit.constants import GRAVITY
from seatkit.errors import SeatkitError
from seatkit.pipeline import build
from seatkit.plugins import get_plugin_manager
from seatkit.pressure import solve_pressure


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="p5-female,p95-male,p50-female,p95-female,p5-male,p50-male")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--table1", type=Path)
    args = ap.parse_args()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from table1 import TABLE_COLUMNS, WIN_KEYS, fmt

    t1 = ["| preset | pose | design | " + " | ".join(label for _, label, _, _ in TABLE_COLUMNS) + " |"]
    t1.append("|" + "---|" * (len(TABLE_COLUMNS) + 3))
    pm = get_plugin_manager()
    lines = [
        "| preset | pose | posed, solved (force balance) | build | seat height | seat depth | seat width | back height | seconds |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    failures = 0
    for preset in args.presets.split(","):
        rig = make_preset(preset)
        for info in list_poses():
            t0 = time.perf_counter()
            body = pose_rig(rig, load_pose(info.name))
            field = solve_pressure(body)
            balance = abs(field.force[:, 1].sum() / (body.mass * GRAVITY) - 1.0)
            solved = f"yes ({balance:.0e})" if balance < 1e-6 else f"NO ({balance:.1e})"
            if not info.supported:
                lines.append(f"| {preset} | {info.name} | {solved} | (not a supported pose) | | | | | |")
                continue
            try:
                r = build({"template": "chair", "bodies": [{"model": preset, "pose": info.name}]}, pm=pm, write=False)
            except SeatkitError as e:
                failures += 1
                lines.append(f"| {preset} | {info.name} | {solved} | FAILED: {str(e)[:140]} | | | | | {time.perf_counter() - t0:.0f} |")
                print(lines[-1], flush=True)
                continue
            ours, base = r.metrics["ours"][0], r.metrics["baseline"][0]
            for design, m in (("ours", ours), ("flat patch", base)):
                if not m.get("supported", True):
                    t1.append(f"| {preset} | {info.name} | {design} | not supported: {m.get('reason', '')[:100]} |" + " |" * (len(TABLE_COLUMNS) - 1))
                    continue
                cells = " | ".join(fmt(k, m[k]) for k, _, _, _ in TABLE_COLUMNS)
                t1.append(f"| {preset} | {info.name} | {design} | {cells} |")
            wins = [k for k in WIN_KEYS if not ours.get(k, float("inf")) < base.get(k, float("inf"))]
            t1.append(f"| {preset} | {info.name} | ours better on | " + ("all three" if not wins else "not on " + ", ".join(wins)) + " |" + " |" * (len(TABLE_COLUMNS) - 1))
            d = r.metrics["dimensions"][0]
            cells = " | ".join("-" if d[k] is None else f"{d[k]:.3f} m" for k in ("seat_height_m", "seat_depth_m", "seat_width_m", "back_height_m"))
            lines.append(f"| {preset} | {info.name} | {solved} | built | {cells} | {time.perf_counter() - t0:.0f} |")
            print(lines[-1], flush=True)
    text = "\n".join(lines)
    print(text)
    print(f"\n{failures} failed builds")
    if args.out:
        args.out.write_text(text + "\n")
    if args.table1:
        args.table1.write_text("\n".join(t1) + "\n")


if __name__ == "__main__":
    main()
