"""The paper's Table 1 on every supportable pose of the library: ours vs the flat-patch baseline.

For each pose: a full default build (chair template, both refiners), then
the evaluation of seatkit/evaluate.py on our surface and on the flat patch
refined by the same Catmull-Clark fit. Prints a Markdown table (the one in
docs/evaluation.md) and whether ours wins on average distance, average
pressure and maximum pressure.

    python benchmarks/table1.py [--body default-male] [--out table1.md]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from seatkit.body import list_poses
from seatkit.errors import SeatkitError
from seatkit.metrics import TABLE, columns
from seatkit.pipeline import build
from seatkit.plugins import get_plugin_manager

WIN_KEYS = ("avg_distance_m", "avg_pressure_pa", "max_pressure_pa")


#: The columns of the table: the paper's Table 1 quantities, then our two checks (seatkit.metrics).
TABLE_COLUMNS = columns(TABLE)


def fmt(key, value):
    for k, _, unit, scale in TABLE_COLUMNS:
        if k == key:
            return f"{value * scale:.2f} {unit}"
    return f"{value:.3g}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", default="default-male")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    pm = get_plugin_manager()
    head = "| pose | design | " + " | ".join(label for _, label, _, _ in TABLE_COLUMNS) + " |"
    lines = [head, "|" + "---|" * (len(TABLE_COLUMNS) + 2)]
    verdicts = []
    for info in list_poses():
        if not info.supported:
            continue
        try:
            r = build({"template": "chair", "bodies": [{"model": args.body, "pose": info.name}]}, pm=pm, write=False)
        except SeatkitError as e:  # a body the chair cannot fit in this pose: one row, the others go on
            lines.append(f"| {info.name} | (no build) | {str(e)[:160]} |" + " |" * (len(TABLE_COLUMNS) - 1))
            verdicts.append((info.name, {"build": False}))
            continue
        ours, base = r.metrics["ours"][0], r.metrics["baseline"][0]
        for name, m in (("ours", ours), ("flat patch", base)):
            if not m.get("supported", True):
                lines.append(f"| {info.name} | {name} | not supported: {m.get('reason', '')} |" + " |" * (len(TABLE_COLUMNS) - 1))
                continue
            cells = " | ".join(fmt(k, m[k]) for k, _, _, _ in TABLE_COLUMNS)
            lines.append(f"| {info.name} | {name} | {cells} |")
        wins = {k: ours.get(k, float("inf")) < base.get(k, float("inf")) for k in WIN_KEYS}
        verdicts.append((info.name, wins))
    text = "\n".join(lines)
    print(text)
    print()
    for pose, wins in verdicts:
        if "build" in wins:
            status = "no build"
        elif all(wins.values()):
            status = "ours better on all three"
        else:
            status = "NOT better on: " + ", ".join(k for k, w in wins.items() if not w)
        print(f"{pose}: {status}")
    if args.out:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
