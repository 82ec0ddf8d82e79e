"""The soft-tissue contact model against published seated measurements (the table in docs/physics.md).

Two experiments, each with the paper's model beside it:

1. A rigid flat seat (a plane under the lowest skin of the buttocks and
   thighs) and a rigid floor under the feet, no backrest: the peak interface
   pressure under the buttocks, as measured on a rigid seat (Linder-Ganz et
   al. 2007), and the load shares.
2. The default chair designed for the upright and the reclined pose: load
   shares on seat, back, feet and arms upright and reclined, and the effect
   of recline on the seat's load and on the peak (Nag et al. 2008; Hobson
   1992).

    python benchmarks/validate_interface.py [--body default-male]
    python benchmarks/validate_interface.py --presets
    python benchmarks/validate_interface.py --poses
    python benchmarks/validate_interface.py --bodies

Prints Markdown tables. ``--presets`` runs experiment 1 on every preset
body and both default bodies instead (the rate within the published spread);
``--poses`` builds the default chair for every supportable library pose and
prints the soft-tissue figures on each design; ``--bodies`` does the same
for every body, upright and reclined.
"""

from __future__ import annotations

import argparse

import numpy as np

from seatkit.body import load_pose, load_rig, pose_rig
from seatkit.constants import GRAVITY, TISSUE_THICKNESS_RANGE_M, TISSUE_YOUNGS_MODULUS_PA
from seatkit.pipeline import build
from seatkit.plugins import get_plugin_manager
from seatkit.pressure import solve_pressure
from seatkit.pressure.compliant import (
    SHARE_REGIONS,
    bone_distance,
    contact_with_planes,
    friction_state,
    load_shares,
    solve_compliant,
)
from seatkit.skeleton import SEGMENT_INDEX


#: Every body of the library: the two defaults and the six presets.
BODIES = ["default-male", "default-female"] + [f"p{p}-{s}" for s in ("male", "female") for p in (5, 50, 95)]


def _mask(body, names):
    owner = np.argmax(body.weights, axis=1)
    return np.isin(owner, [SEGMENT_INDEX[s] for s in names])


def _trunk_angle(body) -> float:
    """Trunk recline from vertical, degrees (Spine joint to Neck joint)."""
    d = body.joints[SEGMENT_INDEX["Neck"]] - body.joints[SEGMENT_INDEX["Spine"]]
    return float(np.degrees(np.arctan2(-d[2], d[1])))


def posed(model: str, pose: str, pm):
    """A body as the build makes it (registered body model, posed on the ground)."""
    from seatkit.recipe import parse_body_spec

    spec = parse_body_spec(model)
    component = pm.registry.get("body_model", spec["model"])
    rig = component.make_body(params=spec["params"])
    return component.pose(rig, load_pose(pose, rig=rig, dirs=pm.registry.pose_dirs), ground=True)


def flat_seat(model: str, pm=None) -> dict:
    """Experiment 1: both models on a rigid flat seat and floor."""
    body = posed(model, "upright-sitting", pm) if pm is not None else pose_rig(load_rig(model), load_pose("upright-sitting"))
    seat = _mask(body, SHARE_REGIONS["seat"])
    feet = _mask(body, ("RightFoot", "LeftFoot"))
    top = float(body.vertices[seat, 1].min())
    contact = contact_with_planes(body, [("seat", (0, top, 0), (0, 1, 0), seat), ("floor", (0, 0, 0), (0, 1, 0), feet)])
    soft = solve_compliant(body, contact)
    mask = np.zeros(len(body.vertices), dtype=bool)
    mask[contact.index] = True
    paper = solve_pressure(body, contact=mask)
    peak_at = int(np.argmax(np.where(seat, soft.pressure, 0)))
    hips = body.joints[[SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]]]
    return {
        "soft": soft,
        "paper": paper,
        "body": body,
        "seat_peak": (float(soft.pressure[seat].max()), float(paper.pressure[seat].max())),
        "peak_thickness_m": float(np.clip(bone_distance(body)[peak_at], *TISSUE_THICKNESS_RANGE_M)),
        "peak_compression_m": float(soft.pressure[peak_at] * np.clip(bone_distance(body)[peak_at], *TISSUE_THICKNESS_RANGE_M) / TISSUE_YOUNGS_MODULUS_PA),
        "peak_offset_m": body.vertices[peak_at] - hips[np.argmin(np.linalg.norm(hips - body.vertices[peak_at], axis=1))],
        "shares": (load_shares(body, soft), load_shares(body, paper)),
        "friction": (friction_state(soft, mu=0.5), friction_state(paper, mu=0.5)),
    }


def designed(model: str, pose: str, pm) -> dict:
    """Experiment 2: a default build; the interface pressure is its evaluation's."""
    r = build({"template": "chair", "bodies": [{"model": model, "pose": pose}], "evaluate": {"baseline": None}}, pm=pm, write=False)
    body, soft, paper = r.bodies[0], r.interface_pressures[0], r.contact_pressures[0]
    seat = _mask(body, SHARE_REGIONS["seat"])
    return {
        "body": body,
        "trunk_deg": _trunk_angle(body),
        "seat_peak": (float(soft.pressure[seat].max()), float(paper.pressure[seat].max())),
        "peak": (float(soft.pressure.max()), float(paper.pressure.max())),
        "shares": (load_shares(body, soft), load_shares(body, paper)),
        "friction": (friction_state(soft, mu=0.5), friction_state(paper, mu=0.5)),
        "importance_friction": friction_state(r.pressures[0], mu=0.5),
        "seconds": r.timings.get("interface pressure", float("nan")),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--body", default="default-male")
    ap.add_argument("--presets", action="store_true", help="experiment 1 on every preset body")
    ap.add_argument("--poses", action="store_true", help="the soft-tissue figures on the chair built for every library pose")
    ap.add_argument("--bodies", action="store_true", help="the soft-tissue figures on the chair built for every body, upright and reclined")
    args = ap.parse_args()
    pm = get_plugin_manager()
    if args.poses or args.bodies:
        from seatkit.body import list_poses

        if args.poses:
            cases = [(args.body, info.name) for info in list_poses() if info.supported]
        else:
            cases = [(b, p) for b in BODIES if b != "default-male" for p in ("upright-sitting", "reclined-sitting")]
        print("| body | pose | supported | peak | peak under the buttocks | seat | back | feet | arms | at the friction limit | max strain |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for body, pose in cases:
            r = build({"template": "chair", "bodies": [{"model": body, "pose": pose}], "evaluate": {"baseline": None}}, pm=pm, write=False)
            m = r.metrics["interface"][0]
            if not m["supported"]:
                print(f"| {body} | {pose} | no: {m['reason'][:120]} |" + " |" * 8)
                continue
            sh = m["load_share"]
            print(
                f"| {body} | {pose} | yes | {m['peak_pa'] / 1e3:.1f} kPa | {m['seat_peak_pa'] / 1e3:.1f} kPa | {sh['seat']:.0%} | {sh['back']:.0%} | "
                f"{sh['feet']:.0%} | {sh['arms']:.0%} | {m['friction']['at_limit_share']:.0%} | {m['max_strain']:.2f} |"
            )
        return
    if args.presets:
        print("| body | mass | peak under the buttocks (soft tissue) | within 17 +/- 4 kPa | paper's model | seat | feet |")
        print("|---|---|---|---|---|---|---|")
        inside = 0
        names = BODIES
        for name in names:
            f = flat_seat(name, pm)
            peak = f["seat_peak"][0]
            ok = 13e3 <= peak <= 21e3
            inside += ok
            print(f"| {name} | {f['body'].mass:.1f} kg | {peak / 1e3:.1f} kPa | {'yes' if ok else 'no'} | {f['seat_peak'][1] / 1e3:.1f} kPa | {f['shares'][0]['seat']:.0%} | {f['shares'][0]['feet']:.0%} |")
        print(f"\n{inside} of {len(names)} within the published spread")
        return
    flat = flat_seat(args.body)
    up = designed(args.body, "upright-sitting", pm)
    rec = designed(args.body, "reclined-sitting", pm)
    weight = flat["body"].segment_mass.sum() * GRAVITY
    print(f"body {args.body}, {weight / GRAVITY:.1f} kg; trunk recline upright {up['trunk_deg']:.0f} deg, reclined {rec['trunk_deg']:.0f} deg")
    print()
    print("| experiment | figure | soft tissue | paper's model |")
    print("|---|---|---|---|")
    print(f"| rigid flat seat | peak under the buttocks | {flat['seat_peak'][0] / 1e3:.1f} kPa | {flat['seat_peak'][1] / 1e3:.1f} kPa |")
    off = flat["peak_offset_m"] * 100
    print(f"| rigid flat seat | where (from the nearer hip joint centre, cm: x, y, z) | {off[0]:.1f}, {off[1]:.1f}, {off[2]:.1f} | |")
    h, c = flat["peak_thickness_m"], flat["peak_compression_m"]
    print(f"| rigid flat seat | tissue under the peak: unloaded, loaded (compression) | {h * 1000:.0f} mm, {(h - c) * 1000:.0f} mm ({c / h:.0%}) | |")
    for name in SHARE_REGIONS:
        print(f"| rigid flat seat | share on {name} | {flat['shares'][0][name]:.0%} | {flat['shares'][1][name]:.0%} |")
    for label, d in (("designed chair, upright", up), ("designed chair, reclined", rec)):
        print(f"| {label} | peak under the buttocks | {d['seat_peak'][0] / 1e3:.1f} kPa | {d['seat_peak'][1] / 1e3:.1f} kPa |")
        print(f"| {label} | peak anywhere | {d['peak'][0] / 1e3:.1f} kPa | {d['peak'][1] / 1e3:.1f} kPa |")
        for name in SHARE_REGIONS:
            print(f"| {label} | share on {name} | {d['shares'][0][name]:.0%} | {d['shares'][1][name]:.0%} |")
    seat_change = [rec["shares"][k]["seat"] - up["shares"][k]["seat"] for k in (0, 1)]
    peak_change = [rec["seat_peak"][k] / up["seat_peak"][k] - 1 for k in (0, 1)]
    print(f"| recline | change of the seat's share (points of body weight) | {seat_change[0] * 100:+.0f} | {seat_change[1] * 100:+.0f} |")
    print(f"| recline | change of the peak under the buttocks | {peak_change[0]:+.0%} | {peak_change[1]:+.0%} |")
    print()
    print("| field | loaded contacts | at the friction limit | above Coulomb (pyramid corners) | normal force at the limit |")
    print("|---|---|---|---|---|")
    rows = [
        ("importance map, upright (paper, pyramid)", up["importance_friction"]),
        ("paper's model on the flat seat", flat["friction"][1]),
        ("soft tissue on the flat seat (exact cone)", flat["friction"][0]),
        ("paper's model on the design, upright", up["friction"][1]),
        ("soft tissue on the design, upright (exact cone)", up["friction"][0]),
        ("paper's model on the design, reclined", rec["friction"][1]),
        ("soft tissue on the design, reclined (exact cone)", rec["friction"][0]),
    ]
    for name, f in rows:
        print(f"| {name} | {f['loaded']} | {f['at_limit_share']:.0%} | {f['above_coulomb_share']:.0%} | {f['force_at_limit_share']:.0%} |")
    print()
    print(f"interface-pressure stage of the build: {up['seconds']:.2f} s upright, {rec['seconds']:.2f} s reclined")


if __name__ == "__main__":
    main()
