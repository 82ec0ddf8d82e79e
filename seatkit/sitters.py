"""Shared designs: one support for several sitters at the same place.

A recipe's ``sitters:`` (instead of ``bodies:``) lists people who will all
use the same seat, one at a time: a small woman and a large man, or one
person who sits upright to work and reclines to rest. They are not placed
side by side (that is a bench); each is brought into the template's frame
(:mod:`seatkit.body.frame`) and then placed where a person sits on a seat:

- **placement** (:func:`align_sitters`): every sitter is moved rigidly so
  that their pelvis meets the seat at one point: the underside of the
  pelvis (the lowest vertex of the ``Hips`` segment) at one height, and the
  centre of the pelvis's load (the importance-weighted mean depth of its
  loaded vertices: the ischial tuberosities upright, towards the sacrum
  reclined) at one depth, the sitters' mean. The canonical frame alone
  keeps each body on the floor with its hip joints above the origin, which
  puts a 5th-percentile woman's buttocks 15 cm below a 95th-percentile
  man's: no seat could hold both. Seated people share a seat pan, not a
  floor position (the seat reference point of seating standards). The
  depth was chosen over the rearmost pelvis vertex (the pelvis against one
  backrest line) by the rate over drawn triples of presets and poses
  (docs/sitters.md).
- **the seat for the shortest legs, the others' legs forward**: as
  seating standards size a fixed seat, the common height is the lowest
  sitter's, so that every sitter's feet can reach the floor. A sitter whose
  own seat is higher is lowered to it and their legs are re-posed through
  the body model (skin, joints and segment masses move together; the
  trial's joint changes, :class:`seatkit.trial._Poser`): the hips flex (the
  knees rise, at most :data:`MAX_HIP_FLEXION`) until the underside of the
  thighs just behind the seat's front (:func:`seat_front`) is as high as
  the thighs of the sitters who were not lowered, so that the seat follows
  the shortest thighs to its front edge instead of the flatter thighs of a
  larger body; then both knees extend by the smallest angle that brings the
  lower foot back to the floor (for a shank of knee-to-sole height ``L``
  hanging straight down, ``L (1 - cos theta)`` = the drop), each ankle
  turned back by the same angles so that the soles stay level. A sitter
  who cannot follow raises the seat instead, to the lowest height they can
  reach: one whose feet do not both rest on the floor (legs crossed, feet
  tucked back: nothing to keep on the floor, or a knee that extending
  lowers the foot) or who would need more than :data:`MAX_KNEE_EXTENSION`.
  The sitters' importance is solved again on the re-posed bodies (the feet
  rest on the floor).
- **the seat as deep as the shortest thighs** (:func:`seat_front`,
  :func:`lifted_importance`): the standards also size a fixed seat's depth
  for the short user (its front edge clears the back of their knees). The
  seat's front is the rearmost of the sitters' knee joints; a longer thigh
  reaches past it, and the thighs and lower legs ahead of it are out of
  every sitter's contact set (importance solved again), so the seat is not
  drawn forward to carry them.
- **lifted off the floor** (:func:`lifted_importance`): a sitter whose own
  seat is lower than the common one (only when another sitter raised it)
  has feet that no longer reach the floor; their importance is solved
  again without the parts that rested on it, so the seat and back carry
  what the feet carried (and the evaluation does not ask the seat to reach
  feet that hang in the air).
- **importance** (:func:`shared_sitter`): each sitter's importance map is
  normalised to its own peak (so a 50 kg sitter counts as much as a 110 kg
  one) and the template is fitted to one *virtual sitter* whose skin is the
  union of the sitters' skins, each vertex keeping its own sitter's
  importance. A template fits each face's plane by an importance-weighted
  vote of the vertices of its segments (RANSAC score and face weight: sums
  of importance), so a plane's score is the **sum over sitters** of the
  importance it supports: a region important for any sitter weighs in the
  combination as much as in that sitter's own map (no averaging dilutes
  it), and a plane that supports several sitters beats one that supports
  one. Reaction forces (the no-backrest and armrest rules read load
  shares) are scaled so that every sitter carries the same total: a share
  is the mean of the sitters' shares. The virtual sitter's skeleton
  (joints, bone ends, segment masses and centres) is the sitters' mean.
- **no sitter cut, every sitter carried** (:class:`SharedTemplate`): the
  template's cages are fitted to the virtual sitter, so its final check
  and clearance see every sitter's skin; their faces then belong to every
  sitter (``face_person = -1``), so the surface fit
  (:mod:`seatkit.refine.ccfit`) pulls the surface to each sitter's
  supported skin (weighted by its normalised importance) and probes it
  against every sitter's skin, and the design search's acceptance check
  (:func:`seatkit.search.judge`) and the evaluation measure each real
  sitter on its own.

One sitter is exactly the single-person design: the virtual sitter is that
body and its importance, and its placement moves and re-poses nothing.

The cost of sharing: a build with sitters also designs each sitter alone
(same template, refiners and seed; :func:`seatkit.pipeline.own_designs`) and report.json's
``metrics.sharing`` gives every sitter's figures on the shared design beside
those on their own.

``sitters: {population: ansur-ii, percentiles: [5, 50, 95], sexes: [f, m],
pose: upright-sitting}`` expands to the survey's boundary manikins, the
preset bodies ``p5-female`` ... ``p95-male`` (:func:`expand_population`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Callable, Iterator, Mapping, Sequence

import numpy as np

from seatkit import trial as _trial
from seatkit.errors import RecipeError
from seatkit.manikins import POPULATIONS, SEXES, expand_population  # noqa: F401  (re-exported: the recipe key is documented here)
from seatkit.metrics import TABLE
from seatkit.model import Body, ControlMesh, PressureField
from seatkit.skeleton import SEGMENT_INDEX

__all__ = [
    "POPULATIONS",
    "SEXES",
    "SharedTemplate",
    "align_sitters",
    "expand_population",
    "lifted_importance",
    "MAX_KNEE_EXTENSION",
    "seat_front",
    "seat_reference",
    "sitter_posers",
    "shared_importance",
    "shared_sitter",
    "sharing_metrics",
]

#: The figures of each sitter that ``metrics.sharing`` puts side by side: the report's Table 1 and checks, and whether the design holds the sitter.
SHARING_FIGURES = tuple(m.key for m in TABLE) + ("supported",)

_HIPS = SEGMENT_INDEX["Hips"]
_KNEES = (SEGMENT_INDEX["RightLeg"], SEGMENT_INDEX["LeftLeg"])  # a lower leg's joint is its knee
_THIGHS = [SEGMENT_INDEX["RightUpLeg"], SEGMENT_INDEX["LeftUpLeg"]]
_LEG_SEGMENTS = [SEGMENT_INDEX[f"{side}{part}"] for side in ("Right", "Left") for part in ("UpLeg", "Leg")]

#: Importance above which a pelvis vertex counts as loaded by the seat (:func:`seat_reference`): the surface fit's threshold.
LOADED = 0.02

#: The most a lowered sitter's knees extend to keep their feet on the floor (rad): a larger drop raises the seat instead.
MAX_KNEE_EXTENSION = _trial.MAX_KNEE_EXTENSION
#: The most a lowered sitter's hips flex (the knees rise) to bring their thighs to the seat's front (rad).
MAX_HIP_FLEXION = float(np.radians(20.0))
#: The seat's front carries the thighs this far behind the shortest sitter's knee joints, m.
FRONT_BAND = 0.04


def seat_reference(body: Body, pressure: PressureField) -> np.ndarray:
    """(2,) float64: where a sitter's pelvis meets the seat: its underside's height and its load's depth, m.

    The height is the lowest vertex of the ``Hips`` segment (the seat
    contact); the depth is the importance-weighted mean depth (z) of the
    ``Hips`` vertices the pressure loads (importance above
    :data:`LOADED`): where the seat carries the pelvis (the ischial
    tuberosities sitting upright, further back towards the sacrum
    reclined). A pelvis that carries nothing keeps its hip joints' depth.
    """
    on = np.argmax(body.weights, axis=1) == _HIPS
    if not on.any():
        on = np.ones(len(body.vertices), bool)
    height = float(body.vertices[on, 1].min())
    importance = np.asarray(pressure.importance, dtype=np.float64)
    loaded = on & (importance > LOADED)
    depth = float(np.average(body.vertices[loaded, 2], weights=importance[loaded])) if loaded.any() else float(body.joints[_HIPS, 2])
    return np.array([height, depth])


def align_sitters(bodies: Sequence[Body], pressures: Sequence[PressureField], posers: Sequence | None = None, *, floor_distance: float = 0.0) -> tuple[list[Body], list[np.ndarray], list[float], list[float]]:
    """The sitters moved to sit on one seat pan (see the module doc): the bodies, each move (3,), m, each knee extension and hip flexion, rad.

    Every sitter's :func:`seat_reference` is moved to one point: the
    sitters' mean load depth, and the lowest seat height every sitter's
    feet can reach the floor from. A sitter whose own seat height is higher
    is lowered to it and their legs re-posed by the body model (``posers``:
    :class:`seatkit.trial._Poser` of each sitter as the build posed them):
    the hips flex (the knees rise) by the smallest angle, up to
    :data:`MAX_HIP_FLEXION`, that brings the underside of the thighs at the
    seat's front (:func:`seat_front`, less :data:`FRONT_BAND`) up to the
    thighs of the sitters who were not lowered, so that the seat follows
    the shortest thighs to its front edge; then both knees extend by the
    smallest angle that keeps the lower foot on the floor, each ankle turned
    back by the same angles so that the soles stay level. A sitter whose
    feet do not both rest on the floor (within ``floor_distance``), or who
    would need more than :data:`MAX_KNEE_EXTENSION`, raises the seat instead
    to as low as they can reach; a sitter whose own seat height is lower
    than the common one is lifted and their feet hang
    (:func:`lifted_importance`). Without ``posers`` no legs are re-posed:
    the seat is the highest sitter's.
    """
    bodies = list(bodies)
    if len(bodies) <= 1:
        return bodies, [np.zeros(3) for _ in bodies], [0.0 for _ in bodies], [0.0 for _ in bodies]
    posers = list(posers or [None] * len(bodies))
    refs = np.array([seat_reference(b, p) for b, p in zip(bodies, pressures)])
    legs = [p.knee_rises(floor_distance, MAX_KNEE_EXTENSION) if p is not None else None for p in posers]
    reach = np.array([0.0 if lg is None else float(lg[1].max()) for lg in legs])  # how far each sitter's seat can be lowered, m
    height = max(refs[:, 0].min(), (refs[:, 0] - reach).max())
    depth = refs[:, 1].mean()
    moves = [np.array([0.0, height - y, depth - z]) for y, z in refs]
    lowered = [lg is not None and y > height for lg, (y, _) in zip(legs, refs)]
    moved = [b.translated(m) for b, m in zip(bodies, moves)]
    front = seat_front(moved) - FRONT_BAND
    bands = [_thigh_band(b, front) for b in moved]
    kept = [b.vertices[i, 1].min() for b, i, low in zip(moved, bands, lowered) if not low and len(i)]
    target = min(kept) if kept else None
    out, knees, hips = [], [], []
    for body, (y, _), move, poser, lg, low, band in zip(moved, refs, moves, posers, legs, lowered, bands):
        knee = hip = 0.0
        if low:
            if target is not None and len(band):
                hip = _hip_for(poser, move, band, target, y - height)
                if hip > 0.0:
                    lg = poser.knee_rises(floor_distance, MAX_KNEE_EXTENSION, hip)
            knee = poser.knee_for(lg, y - height, hip)
        if knee > 0.0 or hip > 0.0:
            theta = np.zeros(8)
            theta[:3], theta[4], theta[5] = move, hip, -knee
            body = poser.body(theta)
        out.append(body)
        knees.append(knee)
        hips.append(hip)
    return out, moves, knees, hips


def _thigh_band(body: Body, front: float) -> np.ndarray:
    """Indices of the thigh skin within :data:`FRONT_BAND` behind ``front`` (z, m): where the seat's front carries the thighs."""
    thighs = np.isin(np.argmax(body.weights, axis=1), _THIGHS)
    z = body.vertices[:, 2]
    return np.flatnonzero(thighs & (z <= front) & (z > front - FRONT_BAND))


def _hip_for(poser, move: np.ndarray, band: np.ndarray, target: float, drop: float) -> float:
    """The smallest hip flexion (rad) that brings the lowest thigh skin of ``band`` up to ``target`` (m).

    At most :data:`MAX_HIP_FLEXION`, and no more than lifts the feet by the
    sitter's ``drop`` (m): the knees rise, the feet stay on the floor.
    """
    from scipy.optimize import brentq

    subset = poser.subset(band)
    base = poser.foot_heights(0.0).min()

    def below(hip):
        theta = np.zeros(8)
        theta[:3], theta[4] = move, hip
        return target - float(poser.points(theta, subset)[:, 1].min())

    def lifted(hip):
        return poser.foot_heights(0.0, hip).min() - base - drop

    most = MAX_HIP_FLEXION
    if lifted(most) > 0.0:
        most = 0.0 if lifted(0.0) >= 0.0 else float(brentq(lifted, 0.0, most, xtol=1e-5))
    if below(0.0) <= 0.0 or most == 0.0:
        return 0.0
    if below(most) > 0.0:
        return most
    return float(brentq(below, 0.0, most, xtol=1e-5))


def sitter_posers(recipe, registry) -> list:
    """Each sitter of ``recipe`` as the build poses them (:class:`seatkit.trial._Poser`: the canonical pose, joint changes on top)."""
    from seatkit.body import load_pose
    from seatkit.trial import _Poser

    posers = []
    for entry in recipe["bodies"]:
        model = registry.get("body_model", entry["model"])
        rig = model.make_body(params=entry["params"])
        posers.append(_Poser(model, rig, load_pose(entry["pose"], frame=entry.get("frame", 0), rig=rig, dirs=registry.pose_dirs)))
    return posers


def seat_front(bodies: Sequence[Body]) -> float | None:
    """The depth (z, m) the shared seat's front edge needs to reach: the rearmost of the sitters' knee joints; None for one sitter.

    Seating standards size a fixed seat's depth for the shortest thighs
    (the front edge clears the back of their knees, ANSI/HFES 100-2007
    8.3.3); a longer thigh reaches past that edge, and the part beyond it is
    not a support the seat must reach.
    """
    if len(bodies) <= 1:
        return None
    return float(min(min(b.joints[_KNEES[0], 2], b.joints[_KNEES[1], 2]) for b in bodies))


def lifted_importance(bodies: Sequence[Body], pressures: Sequence[PressureField], solve: Callable, *, floor_distance: float) -> list[PressureField]:
    """Each seated sitter's importance: a sitter lifted off the floor cannot push on it, a long thigh is not carried past the seat's front.

    A sitter whose seat contact is lower than the common one is lifted by
    :func:`align_sitters` (a small woman on the seat of a large man who
    cannot bring his feet down to hers):
    their lowest point is then above the floor, and the parts that rested on
    it (within ``floor_distance`` of that lowest point: the feet) hang in the
    air. The thighs and lower legs ahead of :func:`seat_front` (the
    shortest sitter's knees; a longer thigh reaches past them) are in the
    air too: the seat ends there. That sitter's importance is
    solved again (``solve(body, contact)``) with those parts out of the
    contact set, so the weight they carried goes to the seat, the back and
    the feet, as it does when feet dangle or thighs reach past a short seat.
    A sitter lifted less than ``floor_distance`` and with nothing ahead of
    the front, or whom the rest of the body cannot hold (standing), keeps
    ``pressures``' solve. Reads only the seated bodies, so a design file's
    bodies give the same importance (``seatkit evaluate``).
    """
    from seatkit.errors import InfeasibleSupportError

    front = seat_front(bodies)
    out = []
    for body, pressure in zip(bodies, pressures):
        lift = float(body.vertices[:, 1].min())
        contact = np.ones(len(body.vertices), bool)
        if lift > floor_distance:
            contact &= body.vertices[:, 1] - lift > floor_distance
        if front is not None:
            legs = np.isin(np.argmax(body.weights, axis=1), _LEG_SEGMENTS)
            contact &= ~(legs & (body.vertices[:, 2] > front))
        if contact.all():
            out.append(pressure)
            continue
        try:
            out.append(solve(body, contact))
        except InfeasibleSupportError:
            out.append(pressure)
    return out


def shared_importance(pressures: Sequence[PressureField]) -> np.ndarray:
    """The virtual sitter's importance: each sitter's importance (pressure over its own peak), concatenated in sitter order."""
    return np.concatenate([np.asarray(p.importance, dtype=np.float64) for p in pressures])


def shared_sitter(bodies: Sequence[Body], pressures: Sequence[PressureField]) -> tuple[Body, PressureField]:
    """The one virtual sitter a template is fitted to (see the module doc); one sitter is returned as it is."""
    bodies, pressures = list(bodies), list(pressures)
    if len(bodies) == 1:
        return bodies[0], pressures[0]
    offsets = np.cumsum([0] + [len(b.vertices) for b in bodies])
    labels: dict = {}
    for b, o in zip(bodies, offsets):
        for key, idx in b.region_labels.items():
            labels.setdefault(key, []).append(np.asarray(idx, dtype=np.int64) + o)
    body = Body(
        vertices=np.concatenate([b.vertices for b in bodies]),
        faces=np.concatenate([np.asarray(b.faces) + o for b, o in zip(bodies, offsets)]),
        weights=np.concatenate([b.weights for b in bodies]),
        joints=np.mean([b.joints for b in bodies], axis=0),
        tips=np.mean([b.tips for b in bodies], axis=0),
        segment_mass=np.mean([b.segment_mass for b in bodies], axis=0),
        segment_com=np.mean([b.segment_com for b in bodies], axis=0),
        name=" + ".join(b.name for b in bodies),
        region_labels={k: np.concatenate(v) for k, v in labels.items()},
    )
    totals = np.array([max(float(p.normal_force.sum()), 1e-12) for p in pressures])
    scale = totals.mean() / totals  # every sitter carries the mean total: a load share is the mean of the sitters'
    pressure = PressureField(
        force=np.concatenate([p.force * s for p, s in zip(pressures, scale)]),
        normal_force=np.concatenate([p.normal_force * s for p, s in zip(pressures, scale)]),
        pressure=shared_importance(pressures),
        shear=np.concatenate([p.shear for p in pressures]),
        area=np.concatenate([p.area for p in pressures]),
        contact=np.concatenate([p.contact for p in pressures]),
        joint_force=np.mean([p.joint_force for p in pressures], axis=0),
        joint_moment=np.mean([p.joint_moment for p in pressures], axis=0),
        status="optimal" if all(p.status == "optimal" for p in pressures) else "+".join(p.status for p in pressures),
        params={**pressures[0].params, "shared": len(pressures)},
    )
    return body, pressure


def _shared_cage(mesh: ControlMesh | None, n: int) -> ControlMesh | None:
    """A cage fitted to the virtual sitter, its faces every sitter's (``face_person = -1``)."""
    if mesh is None or n <= 1:
        return mesh
    meta = dict(mesh.meta)
    meta["sitters"] = n
    return replace(mesh, face_person=np.full(len(mesh.faces), -1, np.int64), meta=meta)


class SharedTemplate:
    """A template fitted to several sitters at one place: the wrapped template fitted to their virtual sitter (:func:`shared_sitter`).

    Its cages' faces belong to every sitter (``face_person = -1``); the
    bodies and pressures it is given are the real sitters', as the
    refiners, the search and the evaluation see them.
    """

    def __init__(self, template):
        self.template = template
        self.name = template.name
        self.description = template.description
        for attr in ("parameters", "options"):
            if hasattr(template, attr):
                setattr(self, attr, getattr(template, attr))

    def check_params(self, params) -> None:
        """The wrapped template's check."""
        self.template.check_params(params)

    def fit(self, bodies, pressures, *, params=None, seed: int = 0) -> ControlMesh:
        """The first cage (:meth:`fits`)."""
        return next(self.fits(bodies, pressures, params=params, seed=seed))

    def fits(self, bodies, pressures, *, params=None, seed: int = 0) -> Iterator[ControlMesh]:
        """The wrapped template's cages for the virtual sitter, in its order."""
        body, pressure = shared_sitter(bodies, pressures)
        inner = self.template
        cages = inner.fits([body], [pressure], params=params, seed=seed) if hasattr(inner, "fits") else iter([inner.fit([body], [pressure], params=params, seed=seed)])
        for cage in cages:
            yield _shared_cage(cage, len(bodies))

    def walls_against(self, bodies, pressures, cage, refused, *, params=None, seed: int = 0) -> ControlMesh | None:
        """The wrapped template's, for the virtual sitter; None when it has none."""
        if not hasattr(self.template, "walls_against"):
            return None
        body, pressure = shared_sitter(bodies, pressures)
        return _shared_cage(self.template.walls_against([body], [pressure], cage, refused, params=params, seed=seed), len(bodies))

    def last_resort_fits(self, bodies, pressures, *, params=None, seed: int = 0) -> Iterator[ControlMesh]:
        """The wrapped template's last-resort cages for the virtual sitter; none when it has none."""
        if not hasattr(self.template, "last_resort_fits"):
            return
        body, pressure = shared_sitter(bodies, pressures)
        for cage in self.template.last_resort_fits([body], [pressure], params=params, seed=seed):
            yield _shared_cage(cage, len(bodies))


def sharing_metrics(shared: Sequence[Mapping], own: Sequence[Mapping], names: Sequence[str], moves: Sequence[np.ndarray], knees: Sequence[float] | None = None, hips: Sequence[float] | None = None) -> list[dict]:
    """``metrics.sharing``: per sitter, the move onto the shared seat (m, after the canonical frame), the knee extension that keeps a lowered sitter's feet on the floor and the hip flexion that brings their thighs to the seat's front (degrees), the figures on the shared design, on their own design, and the cost (shared minus own)."""
    rows = []
    knees = [0.0] * len(names) if knees is None else knees
    hips = [0.0] * len(names) if hips is None else hips
    for name, ours, alone, move, knee, hip in zip(names, shared, own, moves, knees, hips):
        row: dict[str, Any] = {
            "sitter": name, "seat_move_m": [float(x) for x in move], "knee_extension_deg": float(np.degrees(knee)), "hip_flexion_deg": float(np.degrees(hip)),
            "shared": {k: ours.get(k) for k in SHARING_FIGURES if k in ours},
        }
        if "ours" in alone:
            row["own"] = {k: alone["ours"].get(k) for k in SHARING_FIGURES if k in alone["ours"]}
            a, b = ours.get("avg_distance_m"), alone["ours"].get("avg_distance_m")
            if isinstance(a, float) and isinstance(b, float):
                row["avg_distance_cost_m"] = a - b
        else:
            row["own_refused"] = alone.get("refused")
        rows.append(row)
    return rows
