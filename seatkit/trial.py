"""Virtual sitting trial: a person the design was not made for, seated on the fixed design.

``seatkit trial DESIGN_DIR --body B --pose P`` loads a build's design
(``design.npz``: the final cage, its limit surface at the build's level, the
recipe's pressure settings), poses the new person in the canonical frame the
build uses (:func:`seatkit.body.frame.pose_canonical`: facing +Z, feet on the
floor, the hip joints' midpoint above the origin) and then *places* them on
the design by a small optimisation, before solving the pressure on the
design's contact set exactly as the evaluation does
(:func:`seatkit.evaluate.evaluate_person`).

The placement (:func:`place`)
------------------------------
Unknowns ``theta`` (8 numbers): the body's translation ``t`` (m, 3), its
heading ``psi`` about +Y through the hip joints' midpoint (rad), and four
joint changes the support forces (rad, each applied on top of the pose about
the body's left-right axis, both sides alike): ``hip`` flexion (the knees
rise), ``knee`` flexion (the feet go back), the ``ankle`` (the toes rise)
and the ``back``'s recline at the lumbar joint (``Spine``). ``theta = 0`` is
the body exactly as the build would pose it.

With ``v_i(theta)`` the posed and moved skin and, for a point, ``s`` its
signed offset along the surface normal at its closest surface point
(positive on the body side), the placement minimises
(``scipy.optimize.least_squares``)::

    sum_{i in S} w_i [r tanh((s_i - c) / r)]^2           supported skin on the surface
  + k_pen  sum_{i in C} max(0, -s_i - g)^2               no body vertex deeper than g behind it
  + k_pen  sum_{j in P} max(0, d_j - g)^2                no surface point deeper than g in the skin
  + k_floor sum_{feet} max(0, -y_i)^2                    nothing below the floor
  + k_feet  sum_{feet} (height of the sole)^2            feet on the floor (where they reach)
  + k_joint |(psi, hip, knee, ankle, back)|^2            joints change only where forced
  + k_seat  |(t_x, t_z)|^2                               sit where the design's sitters sit

``S`` are the person's supported vertices (importance, "supported
everywhere", at least :data:`~seatkit.pressure.contact.SUPPORTED_FRACTION`
of its peak, on the segments the design supports) whose skin faces the
surface (``n_i . n_surface < -``:data:`MIN_FACING`), ``w_i`` their
importance (normalised); ``c`` = :data:`CLEARANCE` the gap the
Catmull-Clark fit keeps between skin and surface, and ``r`` =
:data:`REACH`: skin much farther than ``r`` from the surface no longer
pulls (it is not in contact). ``C`` are the vertices within :data:`NEAR`
of the surface whose closest point is straight along its normal (not past
a border) and, when behind it, inside the furniture (the evaluation's
test); ``P`` the surface's tessellation points within :data:`NEAR` of the
skin, ``d_j`` their depth below the tangent plane of the nearest skin vertex
(a rim cutting into a thigh, where no body vertex is behind the surface);
``g`` = :data:`GUARANTEE_SLACK`, inside the 5 mm guarantee. The sole's
height is the mean of its :data:`SOLE` lowest vertices less that mean's
offset in the pose as given. The weights are :data:`WEIGHTS`.

The start is the vertical lift (over +-:data:`LIFT_RANGE`, in steps of 4
:data:`LIFT_STEP`, then within 2 of the best) with the least objective
(measured on every :data:`LIFT_STRIDE`-th vertex; a start is measured only when a lower bound of its
objective, its floor, feet and seat terms and its penetration term on a quarter of those vertices, does
not exceed the least so far, so the start chosen is the one measuring every start would choose); then each round takes correspondences on the whole posed body and
measures offsets from the planes of the closest points (point-to-plane, as
in ICP), each unknown moving at most :data:`TRUST` per round, for at most
:data:`ROUNDS` rounds; the round with the least objective (correspondences
taken again there) is kept. The optimiser skins only the vertices it needs
(linear blend skinning, as every built-in body model poses); the kept
placement is posed by the body model. Nothing is measured twice: a round
starts from the correspondences its start was measured with, a translation
reuses the skin normals and the skin's search tree (the surface's points are
moved the other way), and a finite difference in the translation or heading
reuses the skinned vertices of the joint changes it leaves alone. The result is measured, not trusted:
the trial reports the evaluation's ``max_penetration_m`` and
``max_body_depth_m`` of the placed body, and the accommodation criteria
(:mod:`seatkit.population`) judge them.

What is reported (``trial.json``)
---------------------------------
``placement`` (translation m, heading and joint changes in degrees, the
objective, the optimiser's evaluations), ``metrics`` (the paper's Table 1
figures, :func:`seatkit.evaluate.evaluate_person`), ``dimensions`` and
``person_fit`` (seat height vs popliteal height, seat depth vs
buttock-popliteal length, :func:`seatkit.dimensions.person_fit`), and
``design`` (the folder and its build's sitters).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from seatkit.errors import InputError
from seatkit.model import Body, Pose
from seatkit.skeleton import SEGMENT_INDEX as S

__all__ = [
    "CLEARANCE",
    "GUARANTEE_SLACK",
    "Placement",
    "TrialDesign",
    "load_trial_design",
    "place",
    "run_trial",
    "trial_report",
    "write_trial",
]

#: The gap the supported skin is placed at from the surface, m (the Catmull-Clark fit's default clearance).
CLEARANCE = 0.006
#: Skin farther than about this from the surface is not pulled to it (the support term saturates), m.
REACH = 0.005
#: Depth behind the surface the placement lets a vertex reach before it is pushed out, m.
GUARANTEE_SLACK = 0.002
#: Vertices within this of the surface are checked for penetration, m.
NEAR = 0.05
#: A point counts as in front of or behind the surface when its offset along the normal is this share of its distance.
ALONG_NORMAL = 0.9
#: A surface point is judged against its nearest skin vertex's tangent plane when its offset along
#: that vertex's normal is at least this share of its distance (the plane holds near the vertex).
PROBE_ALONG = 0.5
#: A supported vertex is pulled to the surface only where its skin faces it.
MIN_FACING = 0.2
#: Objective weights (see the module docstring); residuals in metres or radians.
WEIGHTS = {"penetration": 30.0, "floor": 30.0, "feet": 0.5, "joint": 0.02, "seat": 3.0}
#: Most correspondence rounds, the optimiser's evaluations per round, and the step
#: (m, rad) under which a round counts as converged.
ROUNDS = 4
MAX_EVALUATIONS = 30
CONVERGED = np.array([2e-4, 2e-4, 2e-4, 2e-3, 2e-3, 2e-3, 2e-3, 2e-3])
#: Largest change of each unknown in one round (m, rad): the plane of a closest point holds only near it.
TRUST = np.array([0.03, 0.03, 0.03, 0.1, 0.1, 0.1, 0.1, 0.1])
#: Vertices of a sole whose mean height is the foot's height above the floor.
SOLE = 20
#: Most supported and near vertices one round keeps (evenly thinned beyond).
MAX_PULL = 600
MAX_NEAR = 1200
#: The start's vertical lift is searched over +-LIFT_RANGE in LIFT_STEP steps, m.
LIFT_RANGE = 0.16
LIFT_STEP = 0.01
LIFT_STRIDE = 4
#: A start is first bounded from below on every BOUND_STRIDE-th vertex (a multiple of LIFT_STRIDE).
BOUND_STRIDE = 16
#: ... and the start's move forward or back over +-DEPTH_RANGE in DEPTH_STEP steps, m.
DEPTH_RANGE = 0.09
DEPTH_STEP = 0.03
#: The most a person's knees extend to keep their feet on the floor on a seat lower than their own (rad), and the
#: extensions scanned up to it (:meth:`_Poser.knee_rises`).
MAX_KNEE_EXTENSION = float(np.radians(60.0))
KNEE_STEPS = 31
#: Hip flexions (the knees raised) a start lowered onto the seat is tried with, rad.
HIP_STARTS = np.radians([0.0, 8.0, 16.0])
#: Bounds of the unknowns: translation (m), heading and joint changes (rad); the knee extends up to
#: :data:`MAX_KNEE_EXTENSION` and 0.2 rad beyond the extension that keeps the feet on the floor.
BOUNDS = (
    np.array([-0.3, -0.3, -0.3, -0.35, -0.6, -MAX_KNEE_EXTENSION - 0.2, -0.6, -0.35]),
    np.array([0.3, 0.3, 0.3, 0.35, 0.6, 0.6, 0.6, 0.35]),
)
#: Names of the unknowns after the translation.
ANGLES = ("heading", "hip_flexion", "knee_flexion", "ankle_dorsiflexion", "back_recline")

_LEGS = ("Right", "Left")
#: The segments the joint changes turn (:meth:`_Poser.pose`): each leg's thigh, shin and foot, then the lumbar joint.
_TURNED = tuple(f"{side}{seg}" for side in _LEGS for seg in ("UpLeg", "Leg", "Foot")) + ("Spine",)


@dataclass
class TrialDesign:
    """A build's design read once for many trials: the surface, its query, the settings."""

    directory: Path
    recipe: dict
    bodies: list
    mesh: Any
    surface: Any
    query: Any
    segments: list

    @property
    def support_distance(self) -> float:
        return float(self.recipe["evaluate"]["support_distance"])


def load_trial_design(directory) -> TrialDesign:
    """Read ``DIRECTORY/design.npz`` (checked as ``seatkit evaluate`` checks it) and its limit surface.

    Raises
    ------
    InputError
        One line when the folder or its design is missing or not a design.
    """
    from seatkit.designs import load_checked_design
    from seatkit.evaluate import design_segments
    from seatkit.geometry.surface import SurfaceQuery
    from seatkit.subdivision import limit_surface

    directory = Path(directory)
    if not directory.is_dir():
        raise InputError(f"{directory}: no such folder; expected a seatkit build folder (it holds design.npz)")
    recipe, bodies, mesh, _ = load_checked_design(directory / "design.npz")
    surface = limit_surface(mesh, level=recipe.get("surface_level", 3))
    return TrialDesign(directory, recipe, bodies, mesh, surface, SurfaceQuery(surface), design_segments(mesh))


@dataclass
class Placement:
    """Where the placement put the person (see the module docstring)."""

    theta: np.ndarray  # (8,): t (3, m), heading, hip, knee, ankle, back (rad)
    cost: float
    evaluations: int
    base_cost: float  # the objective at theta = 0 (the build's own placement)

    def report(self) -> dict:
        t = self.theta
        return {
            "translation_m": [float(x) for x in t[:3]],
            "relative_to": "the person posed as the build poses its sitter, at the chosen sitter's place (hip joints' midpoint above it, feet on the floor)",
            **{f"{name}_deg": float(np.degrees(a)) for name, a in zip(ANGLES, t[3:])},
            "objective": float(self.cost),
            "objective_unmoved": float(self.base_cost),
            "evaluations": int(self.evaluations),
            "unknowns": "translation (3), heading about +Y, hip/knee/ankle flexion and back recline (both sides alike)",
        }


class _Poser:
    """The body at ``theta``: the canonical pose with the joint changes, moved rigidly.

    :meth:`points` skins only some vertices (linear blend skinning,
    :mod:`seatkit.body.skinning`, as every built-in body model poses) for the
    optimiser; :meth:`body` poses the whole body with the body model.
    """

    def __init__(self, model, rig, pose: Pose, at=(0.0, 0.0, 0.0)):
        from seatkit.body.frame import canonical_frame, pose_canonical, turned_pose

        self.model, self.rig = model, rig
        self.body0, _ = pose_canonical(model, rig, pose)
        if np.any(at):  # the seat of another sitter of the design (a bench)
            self.body0 = self.body0.translated(np.asarray(at, dtype=np.float64))
        captured = model.pose(rig, pose, ground=True)
        self.pose0 = turned_pose(pose, canonical_frame(captured))
        raw = model.pose(rig, self.pose0, ground=False)
        self.offset = self.body0.vertices[0] - raw.vertices[0]  # grounding and centring of the build
        self.feet = [np.flatnonzero(np.argmax(rig.weights, axis=1) == S[f"{side}Foot"]) for side in _LEGS]
        self._skinned: dict = {}  # (subset, joint changes) -> skinned vertices (:meth:`turned`)
        self._foot_subsets: tuple | None = None
        self._turned = None  # the pose's rotations of the segments :meth:`pose` turns

    def foot_heights(self, knee: float, hip: float = 0.0) -> np.ndarray:
        """(2,) the lowest vertex height of each foot with both knees extended by ``knee`` and the hips flexed by ``hip`` (rad), m.

        The pose's knee flexion changes by ``-knee`` (the feet go forward),
        its hip flexion by ``hip`` (the knees rise); :meth:`pose` turns each
        foot back by both, so the soles keep their tilt.
        """
        if self._foot_subsets is None:  # both feet skinned at once
            self._foot_subsets = self.subset(np.concatenate(self.feet))
        theta = np.zeros(8)
        theta[4], theta[5] = hip, -knee
        y = self.points(theta, self._foot_subsets)[:, 1]
        return np.array([y[: len(self.feet[0])].min(), y[len(self.feet[0]) :].min()])

    def knee_rises(self, floor_distance: float, most: float = MAX_KNEE_EXTENSION, hip: float = 0.0) -> tuple[np.ndarray, np.ndarray] | None:
        """Knee extensions from 0 to ``most`` (rad, :data:`KNEE_STEPS`) and how far each lifts the lower foot (m), the hips flexed by ``hip``.

        None when the feet do not both rest on the floor in the pose
        (within ``floor_distance``: legs crossed, a foot tucked back): there
        is no foot to keep on the floor. The rise is counted from the lower
        foot in the pose and made monotone (the most reached so far): a
        larger extension is never chosen to lift less.
        """
        feet = self.foot_heights(0.0)
        if feet.max() > floor_distance:
            return None
        angles = np.linspace(0.0, most, KNEE_STEPS)
        rise = np.array([self.foot_heights(a, hip).min() for a in angles]) - feet.min()
        return angles, np.maximum.accumulate(rise)

    def knee_for(self, rises: tuple[np.ndarray, np.ndarray], drop: float, hip: float = 0.0) -> float:
        """The smallest knee extension (rad) that keeps the lower foot on the floor when the body comes down by ``drop`` (m).

        ``rises`` is :meth:`knee_rises` with the same ``hip``; a drop beyond
        the largest rise gets the largest extension scanned, a drop the
        hips' flexion alone makes up none.
        """
        from scipy.optimize import brentq

        angles, rise = rises
        if drop <= rise[0]:
            return 0.0
        if rise[-1] < drop:
            return float(angles[-1])
        k = int(np.argmax(rise >= drop))
        base = self.foot_heights(0.0).min()
        f = lambda a: self.foot_heights(a, hip).min() - base - drop  # noqa: E731
        lo, hi = angles[k - 1], angles[k]
        if f(lo) * f(hi) > 0:  # the scan's monotone envelope, not the rise itself, crossed here
            return float(hi)
        return float(brentq(f, lo, hi, xtol=1e-6))

    def pose(self, theta: np.ndarray) -> Pose:
        from scipy.spatial.transform import Rotation

        hip, knee, ankle, back = theta[4:]
        turns = np.zeros((len(_TURNED), 3))  # about the body's left-right axis, in the order of _TURNED
        turns[:, 0] = [-hip, knee, hip - knee - ankle] * len(_LEGS) + [-back]
        idx = [S[seg] for seg in _TURNED]
        rot = np.array(self.pose0.rotations)
        if self._turned is None:
            self._turned = Rotation.from_rotvec(rot[idx])
        rot[idx] = (Rotation.from_rotvec(turns) * self._turned).as_rotvec()
        return Pose(rot, np.zeros(3), self.pose0.name)

    def _moved(self, points: np.ndarray, theta: np.ndarray) -> np.ndarray:
        from seatkit.body.frame import rotation_about_y

        if theta[3]:  # the heading, about the hip joints' midpoint (above the origin)
            points = points @ rotation_about_y(theta[3]).T
        return points + theta[:3]

    def subset(self, idx: np.ndarray) -> tuple:
        """What :meth:`points` needs for the vertices ``idx`` (kept, so that skinning reuses its sparse weights)."""
        idx = np.asarray(idx, dtype=np.int64)
        if len(idx) == len(self.rig.vertices) and np.array_equal(idx, np.arange(len(idx))):
            return idx, self.rig.vertices, self.rig.weights
        return idx, self.rig.vertices[idx], np.ascontiguousarray(self.rig.weights[idx])

    def points(self, theta: np.ndarray, subset: tuple) -> np.ndarray:
        """(k, 3) positions at ``theta`` of the vertices of ``subset`` (:meth:`subset`)."""
        return self.turned(theta, subset) + theta[:3]

    def turned(self, theta: np.ndarray, subset: tuple) -> np.ndarray:
        """:meth:`points` before the translation: the pose's joint changes and the heading only.

        The skinned positions of the last few joint changes are kept: a
        finite-difference Jacobian moves one unknown at a time, and half of
        them (the translation, the heading) leave the skinning as it was.
        """
        from seatkit.body.skinning import segment_transforms, skin_vertices

        idx, rest, weights = subset
        if np.any(theta[4:]):
            key = (id(subset), theta[4:].tobytes())  # the entry holds the subset: its id is not reused
            v = self._skinned.get(key, (None, None))[1]
            if v is None:
                linear, offset = segment_transforms(self.rig.joints, self.pose(theta))
                v = skin_vertices(rest, weights, linear, offset) + self.offset
                if len(self._skinned) >= 4:
                    self._skinned.pop(next(iter(self._skinned)))
                self._skinned[key] = (subset, v)
        else:
            v = self.body0.vertices[idx]
        if theta[3]:  # the heading, about the hip joints' midpoint (above the origin)
            from seatkit.body.frame import rotation_about_y

            v = v @ rotation_about_y(theta[3]).T
        return v

    def body(self, theta: np.ndarray) -> Body:
        body = self.body0
        if np.any(theta[4:]):
            body = self.model.pose(self.rig, self.pose(theta), ground=False).translated(self.offset)
        if theta[3]:
            move = lambda p: self._moved(p, np.r_[0.0, 0.0, 0.0, theta[3:]])  # noqa: E731
            body = replace(body, vertices=move(body.vertices), joints=move(body.joints), tips=move(body.tips), segment_com=move(body.segment_com))
        return body.translated(theta[:3]) if np.any(theta[:3]) else body


def place(design: TrialDesign, model, rig, pose: Pose, *, seat: int = 0, importance=None, solver=None, terms: dict | None = None) -> tuple[Body, Placement]:
    """Seat one person on the design: the optimisation of the module docstring.

    Each round takes correspondences on the whole posed body (closest surface
    point and normal of the supported and the near vertices, the vertices
    near the floor); within a round the offset from the surface is measured
    from the plane of that closest point (point-to-plane, as in ICP), so an
    evaluation skins only those vertices.

    Parameters
    ----------
    seat : int
        Which sitter's place of the design (0-based; :func:`seat_position`).
    terms : dict, optional
        Filled with each term of the objective at the result (for tests and
        diagnostics).

    Returns
    -------
    body : Body
        The person as placed (posed by the body model).
    placement : Placement
    """
    from scipy.optimize import least_squares

    from seatkit.geometry.normals import vertex_normals
    from seatkit.pressure.contact import supported_vertices

    poser = _Poser(model, rig, pose, at=seat_position(design, seat))
    body0 = poser.body0
    if importance is None:
        p = design.recipe["pressure"]
        importance = solver.solve(body0, lam=p["lambda"], mu=p["mu"], exclude=p.get("exclude"), options=p.get("options") or {})
    support = np.flatnonzero(supported_vertices(importance, body0, design.segments))
    weight = np.asarray(importance.pressure, dtype=np.float64)[support]
    q = design.query
    k = WEIGHTS
    feet = np.concatenate(poser.feet)
    n_feet = len(poser.feet[0])
    # a sole's height is the mean of its lowest vertices, less their spread above the lowest one in the
    # pose as given: zero when the foot stands on the floor as it stood
    y0 = body0.vertices[:, 1]
    sole = np.array([np.sort(y0[f])[:SOLE].mean() - y0[f].min() for f in poser.feet])

    # on a seat lower than their own, a person comes down with the knees extended so that the feet stay on the
    # floor, and the knees raised where the seat's front meets the thighs (none when the feet do not both rest
    # on the floor): each raise's knee extension for a drop
    rises = [poser.knee_rises(design.support_distance, hip=a) for a in HIP_STARTS]
    if rises[0] is None:  # the feet do not rest on the floor (the same for every raise)
        rises = []
    ref = np.zeros(5)  # the posture the joint changes are counted from: the start's

    def legs_for(drop: float, i: int) -> tuple[float, float]:
        """The hip flexion ``HIP_STARTS[i]`` and the knee change that keeps the feet on the floor when the body comes down by ``drop``."""
        angles, rise = rises[i]
        return HIP_STARTS[i], -float(np.interp(drop, rise, angles)) if drop > rise[0] else 0.0

    every = poser.subset(np.arange(len(body0.vertices)))
    # the start's lift is searched with every LIFT_STRIDE-th vertex (and every supported one)
    coarse = np.union1d(np.arange(0, len(body0.vertices), LIFT_STRIDE), support)
    surface_points = np.asarray(design.surface.vertices, dtype=np.float64)

    shapes: dict = {}  # joint changes and heading -> the turned body, its skin normals and its tree

    def shape(theta):
        """The whole body at ``theta`` before the translation, its skin normals and a tree of it.

        A translation changes neither the normals nor the tree (the surface's points are moved
        the other way instead), so the start's lifts and every round share one.
        """
        from scipy.spatial import cKDTree

        key = theta[3:].tobytes()
        if key not in shapes:
            if len(shapes) >= 2:
                shapes.pop(next(iter(shapes)))
            u = poser.turned(theta, every)
            shapes[key] = (u, vertex_normals(u, body0.faces), cKDTree(u, balanced_tree=False, compact_nodes=False))
        return shapes[key]

    taken: dict = {}  # (theta, thin) -> correspondences: a round starts where the last was measured

    def correspondences(theta, thin=False):
        key = (theta.tobytes(), thin)
        if key not in taken:
            if len(taken) >= 4:
                taken.pop(next(iter(taken)))
            taken[key] = _correspondences(theta, thin)
        return taken[key]

    def _correspondences(theta, thin):
        from seatkit.geometry.surface import inside_furniture

        u, skin_n, tree = shape(theta)
        v = u + theta[:3]
        if thin:  # the others are taken as far from the surface
            d, side, sn = np.full(len(v), np.inf), np.full(len(v), np.nan), np.full((len(v), 3), np.nan)
            d[coarse], side[coarse], sn[coarse] = q.closest_normals(v[coarse], within=NEAR)
        else:
            d, side, sn = q.closest_normals(v, within=NEAR)
        side = np.nan_to_num(side)
        # beyond a border of the surface the offset along the normal says nothing of a side: only
        # points whose closest surface point is straight along the normal (the interior) count, and
        # a point behind the surface only when it is inside the furniture (the evaluation's test)
        along = np.isfinite(d) & (np.abs(side) >= ALONG_NORMAL * d)
        behind = np.flatnonzero(along & (side < 0))
        along[behind[~inside_furniture(design.surface, v[behind])]] = False
        near = _thinned(np.flatnonzero((d <= NEAR) & along), MAX_NEAR)
        facing = along[support] & (np.einsum("ki,ki->k", skin_n[support], np.nan_to_num(sn[support])) < -MIN_FACING)
        keep = _thinned(np.flatnonzero(facing), MAX_PULL)
        w = weight[keep]
        # the surface's own points near the skin (a border or a wing cuts into the body where no
        # body vertex is behind the surface): each against the tangent plane of its nearest skin vertex
        gap, owner = tree.query(surface_points - theta[:3], distance_upper_bound=NEAR)
        close = np.flatnonzero(np.isfinite(gap))
        offset = np.einsum("ki,ki->k", surface_points[close] - v[owner[close]], skin_n[owner[close]])
        probe = _thinned(close[np.abs(offset) >= PROBE_ALONG * gap[close]], MAX_NEAR)
        pull = support[keep]
        return {
            "pull": pull, "w": w / max(w.sum(), 1e-12), "near": near, "near_weight": np.sqrt(LIFT_STRIDE if thin else 1.0),
            "points": v - side[:, None] * np.nan_to_num(sn), "normals": np.nan_to_num(sn),
            "probe": probe, "probe_body": owner[probe], "probe_normals": skin_n[owner[probe]],
            "subset": poser.subset(np.concatenate([pull, near, owner[probe], feet])),
        }

    def split(theta, c):
        v = poser.points(theta, c["subset"])
        a, b, e = len(c["pull"]), len(c["near"]), len(c["probe_body"])
        side = lambda ids, pts: np.einsum("ki,ki->k", pts - c["points"][ids], c["normals"][ids])  # noqa: E731
        inside = -np.einsum("ki,ki->k", surface_points[c["probe"]] - v[a + b : a + b + e], c["probe_normals"])
        y = v[a + b + e :, 1]
        r = {
            "support": np.sqrt(c["w"]) * REACH * np.tanh((side(c["pull"], v[:a]) - CLEARANCE) / REACH),
            "penetration": c["near_weight"] * np.sqrt(k["penetration"]) * np.maximum(0.0, -side(c["near"], v[a : a + b]) - GUARANTEE_SLACK),
            "cut": np.sqrt(k["penetration"]) * np.maximum(0.0, inside - GUARANTEE_SLACK),
            "floor": np.sqrt(k["floor"]) * np.minimum(0.0, y),  # the feet are what reaches the floor
        }
        r["feet"] = np.sqrt(k["feet"]) * (np.array([np.sort(y[:n_feet])[:SOLE].mean(), np.sort(y[n_feet:])[:SOLE].mean()]) - sole)
        r["joints"] = np.sqrt(k["joint"]) * (theta[3:] - ref)
        r["seat"] = np.sqrt(k["seat"]) * theta[[0, 2]]
        return r

    def exact(theta, thin=False):
        """The objective at ``theta`` with correspondences taken there (no linearisation)."""
        c = correspondences(theta, thin)
        parts = split(theta, c)
        return float(sum(np.sum(r**2) for r in parts.values())), parts

    # a start clear of the seat: the move with the least exact objective, found one direction at a time:
    # the depth (a larger person's back clear of a backrest made for a smaller one), then the height
    # coarse and fine (a move down is tried as it is and with the knees extended to keep the feet on
    # the floor)
    def lifted(h, z, legs):
        theta = np.r_[0.0, h, z, 0.0, 0.0, 0.0, 0.0, 0.0]
        if legs is not None:
            theta[4], theta[5] = legs_for(-h, legs)
        return theta

    # a start is measured only when it can be the best so far: the objective is a sum of squares, so the
    # terms of some of its residuals bound it from below (``exceeds``)
    # every BOUND_STRIDE-th vertex and every BOUND_STRIDE / LIFT_STRIDE-th supported one: as many of the start's
    # vertices (every LIFT_STRIDE-th and every supported one) as that share of them, near the surface too
    ratio = BOUND_STRIDE // LIFT_STRIDE
    sparse = poser.subset(np.union1d(np.arange(0, len(body0.vertices), BOUND_STRIDE), support[::ratio]))
    feet_subset = poser.subset(feet)

    def exceeds(theta, best: float) -> bool:
        """Whether a lower bound of ``exact(theta, thin=True)`` exceeds ``best``: its floor, feet and seat terms,
        then its penetration term over a share of its vertices (not when the start's near vertices
        may be thinned, which would make that term no bound)."""
        from seatkit.geometry.surface import inside_furniture

        y = poser.points(theta, feet_subset)[:, 1]
        lower = k["floor"] * np.sum(np.minimum(0.0, y) ** 2) + k["seat"] * (theta[0] ** 2 + theta[2] ** 2)
        lower += k["feet"] * np.sum((np.array([np.sort(y[:n_feet])[:SOLE].mean(), np.sort(y[n_feet:])[:SOLE].mean()]) - sole) ** 2)
        if lower > best:
            return True
        v = poser.points(theta, sparse)
        d, side, _ = q.closest_normals(v, within=NEAR)
        side = np.nan_to_num(side)
        along = np.isfinite(d) & (np.abs(side) >= ALONG_NORMAL * d) & (d <= NEAR)
        if np.count_nonzero(along) * ratio > MAX_NEAR * 3 // 4:  # the start's near vertices might be thinned
            return False
        deep = np.flatnonzero(along & (-side - GUARANTEE_SLACK > 0.0))
        depth = lambda i: LIFT_STRIDE * k["penetration"] * np.sum((-side[i] - GUARANTEE_SLACK) ** 2)  # noqa: E731
        if lower + depth(deep) <= best:  # not even if every point behind the surface were inside the furniture
            return False
        return lower + depth(deep[inside_furniture(design.surface, v[deep])]) > best

    def lift(h, z):
        for legs in (None, *range(len(rises))) if h < 0.0 else (None,):
            key = (round(float(h), 6), round(float(z), 6), legs)
            if key in tried:
                continue
            theta = lifted(*key)
            ref[:] = theta[3:]
            if tried and exceeds(theta, min(tried.values())):
                tried[key] = np.inf  # it cannot be the least
            else:
                tried[key] = exact(theta, thin=True)[0]

    tried: dict = {}
    for z in (0.0, *np.arange(-DEPTH_RANGE, DEPTH_RANGE + 1e-9, DEPTH_STEP)):
        lift(0.0, z)
    depth = min(tried, key=tried.get)[1]
    for h in np.arange(-LIFT_RANGE, LIFT_RANGE + 1e-9, 4 * LIFT_STEP):
        lift(h, depth)
    centre = min(tried, key=tried.get)[0]
    for h in (centre - 2 * LIFT_STEP, centre - LIFT_STEP, centre + LIFT_STEP, centre + 2 * LIFT_STEP):
        lift(h, depth)
    ref[:] = 0.0
    base_cost = exact(lifted(0.0, 0.0, None))[0]
    theta = lifted(*min(tried, key=tried.get))
    ref[:] = theta[3:]
    best, best_cost = theta, exact(theta)[0]
    evaluations = int(np.count_nonzero(np.isfinite(list(tried.values()))))
    scale = np.array([0.01, 0.01, 0.01, 0.05, 0.05, 0.05, 0.05, 0.05])
    for _ in range(ROUNDS):
        c = correspondences(theta)
        fun = lambda x: np.concatenate(list(split(x, c).values()))  # noqa: E731
        lo = np.maximum(BOUNDS[0], theta - TRUST)
        hi = np.minimum(BOUNDS[1], theta + TRUST)
        sol = least_squares(fun, np.clip(theta, lo, hi), bounds=(lo, hi), x_scale=scale, max_nfev=MAX_EVALUATIONS, method="trf")
        evaluations += int(sol.nfev)
        step = np.abs(sol.x - theta)
        theta = sol.x
        cost = exact(theta)[0]
        if cost < best_cost:
            best, best_cost = theta, cost
        if np.all(step <= CONVERGED):
            break
    cost, parts = exact(best)
    if terms is not None:
        terms.update({name: float(np.sum(r**2)) for name, r in parts.items()})
    return poser.body(best), Placement(best, cost, evaluations, base_cost)


def _thinned(idx: np.ndarray, most: int) -> np.ndarray:
    """``idx`` with at most ``most`` entries, evenly spaced through it."""
    if len(idx) <= most:
        return idx
    return idx[np.linspace(0, len(idx) - 1, most).round().astype(np.int64)]


@dataclass
class TrialResult:
    """One trial: the placed body, its figures and fields (for the picture)."""

    body: Body
    placement: Placement
    importance: Any
    metrics: dict
    field: Any
    dimensions: dict
    fit: dict
    label: dict = field(default_factory=dict)


def seat_position(design: TrialDesign, seat: int) -> np.ndarray:
    """Where sitter ``seat`` (0-based) of the design sat: their hip joints' midpoint, horizontally (m).

    A one-person design's sitter sat at the origin; a bench's people sat side by side.

    Raises
    ------
    InputError
        When the design has no such sitter.
    """
    n = len(design.bodies)
    if not 0 <= seat < n:
        raise InputError(f"--seat: expected a sitter of the design from 1 to {n}, got {seat + 1}")
    j = design.bodies[seat].joints
    centre = 0.5 * (j[S["LeftUpLeg"]] + j[S["RightUpLeg"]])
    return np.array([centre[0], 0.0, centre[2]])


def run_trial(design: TrialDesign, registry, model_name: str, params: dict, pose_spec, *, frame: int = 0, seat: int = 0, label: dict | None = None) -> TrialResult:
    """Seat the person ``model_name`` (with ``params``) in pose ``pose_spec`` on ``design`` and evaluate.

    Parameters
    ----------
    design : TrialDesign
    registry : the plugin registry (body models, the pressure solver)
    model_name, params : the body model and its parameters (as a recipe's ``bodies[]`` entry)
    pose_spec : a library pose name, pose file, or a :class:`~seatkit.model.Pose`
    seat : which sitter's place of the design, 0-based (:func:`seat_position`)
    """
    seat_position(design, seat)  # one line for a seat the design has not, before any work
    from seatkit.body import load_pose
    from seatkit.body.measure import measure_rig
    from seatkit.dimensions import person_fit, support_dimensions
    from seatkit.evaluate import evaluate_person

    model = registry.get("body_model", model_name)
    rig = model.make_body(params=params)
    pose = pose_spec if isinstance(pose_spec, Pose) else load_pose(pose_spec, frame=frame, rig=rig, dirs=registry.pose_dirs)
    p = design.recipe["pressure"]
    solver = registry.get("pressure_solver", p["solver"])
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):  # small dense blocks: threaded BLAS only contends (as in a build)
        return _run_trial(design, rig, model, pose, solver, p, label, seat)


def _run_trial(design, rig, model, pose, solver, p, label, seat=0) -> TrialResult:
    from seatkit.body.measure import measure_rig
    from seatkit.dimensions import person_fit, support_dimensions
    from seatkit.evaluate import evaluate_person

    body, placement = place(design, model, rig, pose, seat=seat, solver=solver)
    importance = solver.solve(body, lam=p["lambda"], mu=p["mu"], exclude=p.get("exclude"), options=p.get("options") or {})
    metrics, fld = evaluate_person(
        body, importance, design.surface, solver=solver, support_distance=design.support_distance,
        pressure_settings=p, query=design.query, segments=design.segments,
    )
    dims = support_dimensions([body], [fld])[0]
    try:
        measured = measure_rig(rig)
    except (ValueError, IndexError):  # a rig without the legs a measurement reads
        measured = None
    fit = person_fit([measured], [dims])[0]
    return TrialResult(body, placement, importance, metrics, fld, dims, fit, dict(label or {}))


def trial_report(design: TrialDesign, trial: TrialResult) -> dict:
    """What ``trial.json`` holds (see the module docstring)."""
    from seatkit.io import jsonable

    return jsonable({
        "design": {"folder": str(design.directory), "sitters": [b.name for b in design.bodies], "template": design.recipe.get("template")},
        "person": {"body": trial.body.name, **trial.label},
        "placement": trial.placement.report(),
        "support_distance_m": design.support_distance,
        "metrics": trial.metrics,
        "dimensions": trial.dimensions,
        "person_fit": trial.fit,
    })


def write_trial(design: TrialDesign, trial: TrialResult, out) -> dict[str, Path]:
    """Write ``trial.json`` and ``trial.png`` (the body on the surface, coloured by its contact pressure) into ``out``."""
    from seatkit.export.report import write_surface_png
    from seatkit.io import write_text_atomic
    from seatkit.model import BuildResult

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = {"trial_png": out / "trial.png", "trial_json": out / "trial.json"}
    result = BuildResult(
        recipe=design.recipe, bodies=[trial.body], pressures=[trial.importance], control_mesh=design.mesh,
        surface=design.surface, contact_pressures=[trial.field],
    )
    title = f"Trial: {trial.body.name}"
    write_surface_png(result, files["trial_png"], title=title)
    write_text_atomic(files["trial_json"], json.dumps(trial_report(design, trial), indent=1) + "\n")
    return files
