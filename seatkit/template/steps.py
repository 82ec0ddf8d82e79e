"""The built-in fitting steps a template lists under ``steps:``.

Each step is a :class:`seatkit.interfaces.TemplateStep`: a ``name``, a
``description``, ``options`` (every accepted key as a
:class:`seatkit.template.options.Option`: type, unit, default, range; the
docs tables are generated from them), ``requires`` (steps that must come
before it), ``stage`` (``blocks`` or ``grid``) and ``run(state, *,
options)``, which advances the :class:`FitState` in place. Steps that fit faces run once per person (block); ``join``,
``armrests`` and ``border`` work on the joined grid. A plugin adds a step by
returning an object of this shape from ``seatkit_register_template_steps``.
"""

from __future__ import annotations

import functools

from typing import Any, Mapping

import numpy as np

from seatkit.errors import RecipeError
from seatkit.template.border import add_border, keep_back_behind
from seatkit.template.checks import check_supportability, crossing_faces, enclosed_vertices, free_segments, held_segments, self_intersecting_faces
from seatkit.template.clearance import lift_off_bodies
from seatkit.template.grid import FitState, GridMesh, grid_quads
from seatkit.template.options import Option, options_table
from seatkit.template.planes import Plane, fit_support_plane
from seatkit.template.pose_rule import PoseRuleStep
from seatkit.template.seat import SeatStep
from seatkit.template.special_cases import add_armrests, fit_outer_face, merge_crossed_legs

__all__ = ["BUILTIN_STEPS", "builtin_steps"]


def _rows(state: FitState, options, block) -> list:
    names = options.get("rows", state.spec.rows)
    return [state.spec.rows.index(n) for n in names if state.spec.rows.index(n) in block.rows]


def _columns(state: FitState, options) -> list:
    return [state.spec.columns.index(n) for n in options.get("columns", state.spec.columns)]


def fit_face(state: FitState, block, face, *, direction_penalty: bool, segments=None) -> None:
    """RANSAC-fit the plane of one face and give it its frame (paper Sec. 5.2)."""
    p = state.params
    segs = tuple(segments or face.segments)
    idx = block.vertices_of(segs)
    if len(idx) < 3:
        msg = f"{state.spec.source}: face {state.face_name(face)!r}: segments {state.segment_names(segs)} have {len(idx)} body vertices; at least 3 are needed"
        raise RecipeError(msg)
    pts = block.body.vertices[idx]
    neigh = block.vertices_of(block.neighbours_of(segs))
    # an even subset is enough to tell whether a candidate cuts a neighbour
    neigh = neigh[:: max(1, -(-len(neigh) // 500))]
    prev = None
    i = block.rows.index(face.spec.row)
    if direction_penalty and i > 0:
        q = block.neighbour_plane(block.rows[i - 1], face.spec.column)
        prev = None if q is None else q.normal
    res = fit_support_plane(
        pts,
        block.importance[idx],
        rng=state.rng,
        iterations=p["ransac_iterations"],
        support_distance=p["support_distance"],
        max_penetration=p["max_penetration"],
        body_side=pts.mean(0),
        bone=block.row_axis(segs, face.spec.row),
        reference=block.frame_normal(segs, face.spec.row),
        side_hint=block.lateral(),
        max_side_angle=p["max_side_angle"],
        lambda_r=p["lambda_r"],
        lambda_d=p["lambda_d"] if prev is not None else 0.0,
        m_alpha=p["m_alpha"],
        previous_normal=prev,
        max_row_angle=p["max_row_angle"],
        neighbours=block.body.vertices[neigh],
        max_neighbour_cut=p["max_neighbour_cut"],
        importance_floor=p["importance_floor"],
    )
    face.segments = segs
    block.set_frame(face, res.plane)
    face.supported = idx[res.supported]
    face.weight = float(block.importance[face.supported].sum())
    face.info = {"candidates": res.candidates, "rejected": res.rejected, "quality": res.plane.quality}


class FitPlanesStep:
    """Importance-weighted RANSAC plane per ``fit`` face, row after row.

    ``last_resort_rows``: in the engine's last-resort cages only
    (``state.last_resort``, :meth:`seatkit.template.YamlTemplate.last_resort_fits`),
    each ``fit`` face of these rows then takes the plane of the face of the
    same column in the next row. On the chair the foot faces take their
    shank face's plane: a heel sits in the corner between the shank face
    (under or behind the calf) and the foot face (under or in front of the
    sole), the limit surface rounds that corner, and where it is tight (a
    foot dropped to the floor beside a raised leg) the rounding reaches 3 cm
    into the heel, beyond what the surface fit can pull out. With the leg
    rest running on past the heel there is no corner: the foot rests on it,
    or stands on the floor in front of it (docs/templates.md, "Last-resort
    cages").
    """

    name = "fit-planes"
    description = "RANSAC supporting plane for each 'fit' face of the given rows and columns (paper Sec. 5.2)"
    stage = "blocks"
    requires = ()
    options = {
        "rows": Option("rows", "rows to fit, in order (default: all)"),
        "columns": Option("columns", "columns to fit (default: all)"),
        "direction_penalty": Option("bool", "use p^d against the previous row's plane", False),
        "last_resort_rows": Option("rows", "in the last-resort cages only: these rows' faces take the next row's plane (default: none)"),
    }

    def has_last_resort(self, options: Mapping[str, Any]) -> bool:
        """Whether these options change the last-resort cages (the engine offers those only then)."""
        return bool(options.get("last_resort_rows"))

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        for block in state.blocks:
            for r in _rows(state, options, block):
                for c in _columns(state, options):
                    face = block.faces[(r, c)]
                    if face.spec.role == "fit":
                        fit_face(state, block, face, direction_penalty=bool(options.get("direction_penalty", False)))
        if state.last_resort and options.get("last_resort_rows"):
            _take_next_planes(state, options)


def _take_next_planes(state: FitState, options: Mapping[str, Any]) -> None:
    """Each ``fit`` face of ``last_resort_rows`` (and the step's columns) takes the plane of the same column's face in the next row."""
    sd = state.params["support_distance"]
    names = options["last_resort_rows"]
    for block in state.blocks:
        taken = []
        for r in [state.spec.rows.index(n) for n in names]:
            if r not in block.rows or block.rows.index(r) + 1 >= len(block.rows):
                continue
            after = block.rows[block.rows.index(r) + 1]
            for c in _columns(state, options):
                face, nxt = block.faces[(r, c)], block.faces[(after, c)]
                if face.spec.role != "fit" or face.plane is None or nxt.plane is None:
                    continue
                block.set_frame(face, Plane(nxt.plane.point.copy(), nxt.plane.normal.copy(), nxt.plane.quality))
                idx = block.vertices_of(face.segments)
                near = np.abs(face.plane.signed_distance(block.body.vertices[idx])) <= sd
                face.supported = idx[near]
                face.weight = float(block.importance[face.supported].sum())
                face.info = {**face.info, "plane_of": state.face_name(nxt)}
                taken.append(state.face_name(face))
        state.meta.setdefault("special_cases", []).append({"case": "last-resort-planes", "person": block.person, "taken": bool(taken), "faces": taken})


class BridgeStep:
    """Checks a bridge column has fitted neighbours; its corners are theirs."""

    name = "bridge"
    description = "connect two fitted columns by a bridge column (its corners are its neighbours' inner corners)"
    stage = "blocks"
    requires = ("fit-planes",)
    options = {
        "rows": Option("rows", "rows of the bridge (default: all)"),
        "columns": Option("columns", "bridge columns (default: every bridge face)"),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        C = len(state.spec.columns)
        for block in state.blocks:
            for r in _rows(state, options, block):
                for c in _columns(state, options):
                    face = block.faces[(r, c)]
                    if face.spec.role != "bridge":
                        continue
                    for cc in (c - 1, c + 1):
                        if not 0 <= cc < C or block.faces[(r, cc)].spec.role != "fit":
                            msg = f"{state.spec.source}: bridge face {state.face_name(face)!r} needs a 'fit' face on both sides"
                            raise RecipeError(msg)


class CornersStep:
    """Corner vertices from row and column lines, averaged over adjacent faces."""

    name = "corners"
    description = "intersect row and column lines of every fitted face and average the corner estimates"
    stage = "blocks"
    requires = ("fit-planes",)
    options = {}

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        for block in state.blocks:
            block.estimates = {}
            for (r, c), face in sorted(block.faces.items()):
                if r in block.rows and face.spec.role == "fit" and face.plane is not None:
                    block.add_estimates(face, block.corners(face, state.params))


class OuterColumnsStep:
    """Outer faces through the inner column's fixed vertices (paper Sec. 5.2, step 4)."""

    name = "outer-columns"
    description = "fit the outer column faces with their two inner vertices fixed, then shift them outwards"
    stage = "blocks"
    requires = ("corners",)
    options = {
        "rows": Option("rows", "rows with outer faces (default: all)"),
        "columns": Option("columns", "outer columns (default: first and last)"),
        "min_width": Option("number", "narrowest outer face", 0.06, "m", 0.0, 1.0),
        "margin": Option("number", "width beyond the segment's extent", 0.02, "m", 0.0, 0.5),
        "candidates": Option("count", "body vertices tried as the third point", 400, "", 1, 100000),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        cols = _columns(state, options) if "columns" in options else [0, len(state.spec.columns) - 1]
        for block in state.blocks:
            for r in _rows(state, options, block):
                for c in cols:
                    face = block.faces[(r, c)]
                    if face.spec.role == "outer":
                        fit_outer_face(state, block, face, options)


class CrossedLegsStep:
    """One plane for both legs when their faces come too close (paper Sec. 5.2)."""

    name = "crossed-legs"
    #: when every start's cage with the merged rows is refused (the raised
    #: leg's calf hangs through the shared plane), the engine tries the legs
    #: on their own faces, after dropping the armrests and the backrest's
    #: fallback (docs/templates.md, "The starts")
    optional = True
    description = "merge the two leg faces of a row into one plane when they are closer than min_distance"
    stage = "blocks"
    requires = ("fit-planes",)
    options = {
        "rows": Option("rows", "leg rows (default: all)"),
        "columns": Option("columns", "the two leg columns, right then left", required=True),
        "min_distance": Option("number", "smallest gap between the two faces", 0.02, "m", 0.0, 1.0),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        cols = _columns(state, options)
        if len(cols) != 2:
            msg = f"{state.spec.source}: step crossed-legs: 'columns' must name the two leg columns, got {options.get('columns')!r}"
            raise RecipeError(msg)
        for block in state.blocks:
            merge_crossed_legs(state, block, _rows(state, options, block), cols, float(options.get("min_distance", 0.02)), fit_face)


class NoBackrestStep:
    """Drop the backrest rows when the back carries (almost) no load from behind.

    The load is the reaction force on the rows' segments along the torso's
    front direction (the body's left-right axis crossed with the hips-to-
    upper-back axis), so that a chest resting on the thighs does not count
    as a back needing a backrest.

    Optional (as the armrests): when every cage with the backrest is
    refused, the engine tries again without the optional steps; for this
    step that means going without a backrest whose load is below
    ``optional_below`` (a lightly loaded back a cage cannot reach without
    crossing the body, as the lower back of a large body behind its hips).
    """

    name = "no-backrest"
    optional = True
    description = "remove the given end rows when the load pushing their segments forwards is below min_load_fraction of the total"
    stage = "blocks"
    requires = ()
    options = {
        "rows": Option("rows", "the backrest rows (must be the last or first rows; default: none)"),
        "min_load_fraction": Option("number", "share of the total normal reaction, pushing the back forwards, below which the back needs no support", 0.01, "1", 0.0, 1.0),
        "optional_below": Option("number", "share below which the backrest is dropped too when every cage with it is refused (0: never)", 0.0, "1", 0.0, 1.0),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        self._apply(state, options, float(options.get("min_load_fraction", 0.01)), fallback=False)

    def fallback(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        """What doing without this optional step means: no backrest below ``optional_below`` either."""
        thr = max(float(options.get("min_load_fraction", 0.01)), float(options.get("optional_below", 0.0)))
        self._apply(state, options, thr, fallback=True)

    def _apply(self, state: FitState, options: Mapping[str, Any], thr: float, *, fallback: bool) -> None:
        names = options.get("rows") or []
        for block in state.blocks:
            rows = [state.spec.rows.index(n) for n in names]
            segs = {s for r in rows for s in block.row_segments(r)}
            # load from behind: reaction force along the torso's front direction
            front = block.torso_front()
            on = np.isin(block.segment, list(segs))
            load = float(np.clip(block.force[on] @ front, 0.0, None).sum())
            total = float(block.normal_force.sum()) or 1.0
            share = load / total
            record = {"case": "no-backrest", "person": block.person, "load_fraction": share, "threshold": thr, "taken": share < thr}
            if fallback:
                record["fallback"] = True  # every cage with the backrest was refused
            if share < thr:
                keep = [r for r in block.rows if r not in rows]
                if not keep or keep != list(range(keep[0], keep[-1] + 1)):
                    msg = f"{state.spec.source}: step no-backrest: rows {names} are not at the end of the grid"
                    raise RecipeError(msg)
                block.rows = keep
                record["rows_removed"] = names
            state.meta.setdefault("special_cases", []).append(record)


class SupportabilityStep:
    """Detect poses the topology cannot support (paper Sec. 5.1 and 6)."""

    name = "supportability"
    description = "raise UnsupportedPoseError when important vertices cannot reach their face without crossing the body"
    stage = "blocks"
    requires = ("corners",)
    options = {
        "max_occluded_fraction": Option("number", "share of a segment's importance that may be occluded", 0.2, "1", 0.0, 1.0),
        "max_roll_deg": Option("number", "largest tilt of the body's left-right axis from horizontal", 45.0, "deg", 0.0, 90.0),
        "joint_reach": Option("number", "an adjacent segment crossed within this distance of the joint does not count", 0.1, "m", 0.0, 1.0),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        check_supportability(
            state,
            float(options.get("max_occluded_fraction", 0.2)),
            np.radians(float(options.get("max_roll_deg", 45.0))),
            float(options.get("joint_reach", 0.1)),
        )


class JoinStep:
    """Join the people's blocks into one grid, with connector columns between them."""

    name = "join"
    description = "assemble every person's block into one grid; neighbours are joined by a connector column"
    stage = "grid"
    requires = ("corners",)
    options = {}

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        state.grid = join_blocks(state)


def join_blocks(state: FitState) -> GridMesh:
    """The grid of all blocks side by side (seat order along +d_side)."""
    parts = []
    nrows = {len(b.rows) for b in state.blocks}
    if len(nrows) != 1:
        from seatkit.errors import UnsupportedPoseError
        from seatkit.template.checks import person_label

        full = max(nrows)
        short = [b for b in state.blocks if len(b.rows) < full]
        names = ", ".join(person_label(b.person, b.body) for b in short)
        msg = (
            f"{names}: a special case removed rows ({', '.join(str(len(b.rows)) for b in short)} of {full}, e.g. no backrest "
            "when leaning forward) that the neighbours need; one bench grid joins blocks with the same rows: "
            "seat such people at the end of the bench in a separate design, or choose a pose with back support"
        )
        raise UnsupportedPoseError(msg, parts=[person_label(b.person, b.body) for b in short])
    for block in state.blocks:
        V = block.vertex_grid()
        if np.isnan(V).any():
            miss = [(int(i), int(k)) for i, k in zip(*np.nonzero(np.isnan(V).any(2)))]
            msg = f"{state.spec.source}: template {state.spec.name!r}: vertices {miss} (row boundary, column line) were not placed by any step"
            raise RecipeError(msg)
        R, C = len(block.rows), block.n_columns
        seg = np.full((R, C), -1, np.int64)
        lab = np.empty((R, C), object)
        pp = np.full((R, C, 3), np.nan)
        pn = np.full((R, C, 3), np.nan)
        fw = np.zeros((R, C))
        for i, r in enumerate(block.rows):
            for c in range(C):
                f = block.faces[(r, c)]
                lab[i, c] = f.spec.label
                if f.spec.segments:
                    seg[i, c] = f.spec.segments[0]
                if f.plane is not None:
                    pp[i, c], pn[i, c] = f.plane.point, f.plane.normal
                    fw[i, c] = f.weight
        parts.append((V, seg, lab, pp, pn, fw, np.full((R, C), block.person, np.int64)))
    V, seg, lab, pp, pn, fw, per = parts[0]
    for Vn, sn, ln, ppn, pnn, fwn, pen in parts[1:]:
        R = sn.shape[0]
        # connector column: the faces between the last vertex column and the next block's first
        V = np.concatenate([V, Vn], axis=1)
        seg = np.concatenate([seg, np.full((R, 1), -1), sn], axis=1)
        lab = np.concatenate([lab, np.full((R, 1), "connector", object), ln], axis=1)
        pp = np.concatenate([pp, np.full((R, 1, 3), np.nan), ppn], axis=1)
        pn = np.concatenate([pn, np.full((R, 1, 3), np.nan), pnn], axis=1)
        fw = np.concatenate([fw, np.zeros((R, 1)), fwn], axis=1)
        per = np.concatenate([per, np.full((R, 1), -1), pen], axis=1)
    peak = fw.max() if fw.size and fw.max() > 0 else 1.0
    return GridMesh(V, seg, per, lab, pp, pn, fw / peak, np.zeros(V.shape[:2], bool))


class ArmrestsStep:
    """Armrests: PCA + RANSAC plane and minimal spanning rectangle, two columns per side."""

    name = "armrests"
    #: the armrests are a refinement: when a cage with them is refused, the
    #: engine tries again without them (docs/templates.md, "The starts")
    optional = True
    description = "add an armrest column and a connector column on each side when the arms can rest on one"
    stage = "grid"
    requires = ("corners",)
    options = {
        "right": Option("segments", "segments of the right arm", ["RightArm", "RightForeArm"]),
        "left": Option("segments", "segments of the left arm", ["LeftArm", "LeftForeArm"]),
        "min_load_fraction": Option("number", "share of the load the arm must carry to get an armrest", 0.02, "1", 0.0, 1.0),
        "min_distance": Option("number", "smallest distance between armrest and grid", 0.04, "m", 0.0, 1.0),
        "max_tilt_deg": Option("number", "steepest armrest plane, from horizontal", 30.0, "deg", 0.0, 90.0),
        "reach_below": Option("number", "grid row lines this far below the armrest (and reach_above above it) are spread along it", 0.35, "m", 0.0, 2.0),
        "reach_above": Option("number", "see reach_below", 0.1, "m", 0.0, 2.0),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        if state.grid is None:
            state.grid = join_blocks(state)
        add_armrests(state, options)


class BorderStep:
    """Two rings of border faces; the outer ring on a ground rectangle (Sec. 5.2 refinement)."""

    name = "border"
    description = "extend the grid by two rows/columns on every side down to a ground rectangle at y = 0"
    stage = "grid"
    requires = ("corners",)
    options = {
        "width": Option("number", "how far the first border ring extends the surface", 0.05, "m", 0.0, 1.0),
        "margin": Option("number", "ground rectangle margin around the surface", 0.05, "m", 0.0, 1.0),
        "min_spacing": Option("number", "smallest spacing of ground vertices along the rectangle", 0.02, "m", 0.001, 0.5),
        "clearance": Option("bool", "lift the finished cage off the bodies (the clearance step)", True),
        "front_wall": Option(
            "choice",
            "where the front wall stands: before-feet (in front of everything hanging below the front edge: the chair's "
            "footrest) or behind-calves (under the front edge, behind the lower legs, which hang in front of it: a saddle stool)",
            "before-feet", choices=("before-feet", "behind-calves"),
        ),
        "front_drop": Option("number", "behind-calves: height of the front face, from the surface's front edge down to the first ring", 0.08, "m", 0.01, 1.0),
        "body_clearance": Option("number", "gap between the walls and the bodies (default: min_spacing)", None, "m", 0.0, 0.5),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        if state.grid is None:
            state.grid = join_blocks(state)
        border = functools.partial(
            add_border,
            state.grid,
            width=float(options.get("width", 0.05)),
            margin=float(options.get("margin", 0.05)),
            min_spacing=float(options.get("min_spacing", 0.02)),
            bodies=[b.body for b in state.blocks],
            front_wall=options.get("front_wall", "before-feet"),
            front_drop=float(options.get("front_drop", 0.08)),
            body_clearance=options.get("body_clearance"),
        )
        state.grid = border(meta=state.meta)
        # every lift keeps the back ring behind the back rows it moves (lift_grid)
        state.keep_border = functools.partial(
            keep_back_behind,
            bodies=[b.body for b in state.blocks],
            width=float(options.get("width", 0.05)),
            margin=float(options.get("margin", 0.05)),
            gap=float(options.get("min_spacing", 0.02) if options.get("body_clearance") is None else options["body_clearance"]),
        )
        # the clearance step's repair may rebuild it with the side rings lowered beside a hanging hand
        state.rebuild_border = lambda **kw: border(meta=state.meta, drop_beside=True, **kw)
        # ... or with its side walls inside the hands the cage encloses (the clearance step's repair_enclosure)
        state.rebuild_walls = functools.partial(_border_with_walls, state, border)
        if options.get("clearance", True):
            lift_grid(state, {})


def _free_segments(state: FitState) -> np.ndarray:
    """(s,) bool: the segments the cage does not hold (:func:`seatkit.template.checks.held_segments`), from the fit so far."""
    return free_segments(held_segments({"supported_segments": state.supported_segments(), "special_cases": state.meta.get("special_cases", [])}, state.grid.segment))


def _border_with_walls(state: FitState, border, enclosed, **kw) -> GridMesh:
    """``border(hanging=...)``: the border again, its walls inside the body parts the cage does not hold where ``enclosed`` (per body, vertex indices) were found inside."""
    free = _free_segments(state)
    hanging = []
    for block, found in zip(state.blocks, enclosed):
        trigger = np.zeros(len(block.body.vertices), bool)
        trigger[np.asarray(sorted(found), dtype=np.int64)] = True
        hanging.append((free[block.segment], trigger))
    return border(meta=state.meta, hanging=hanging, **kw)


#: ``facing`` of the first lift: only skin turned towards a face counts
#: (a border wall folded over the feet is left alone).
_FACING = -0.1
#: ``facing`` of a repair: every body vertex over a named face counts,
#: whichever way its skin turns (a dot product never exceeds 1).
_FACING_ANY = 1.01


def lift_grid(state: FitState, options: Mapping[str, Any], *, faces=None) -> dict:
    """Lift the joined grid off the bodies (:func:`seatkit.template.clearance.lift_off_bodies`).

    With ``faces`` (indices into :func:`grid_quads`), a repair: only the
    vertices of those faces move, and every body vertex over them counts,
    whichever way its skin turns (see :meth:`ClearanceStep.repair`).
    Returns what was done (also kept in ``state.meta``).
    """
    grid = state.grid
    p = state.params
    quads = grid_quads(grid.shape)
    V = grid.vertices.reshape(-1, 3)
    movable = ~grid.ground.ravel()
    if faces is not None:
        named = np.zeros(len(V), bool)
        named[quads[np.asarray(faces, dtype=np.int64)].ravel()] = True
        movable &= named
    res = lift_off_bodies(
        V,
        quads,
        [b.body for b in state.blocks],
        movable,
        target=-float(options.get("sink", 0.5 * p["max_penetration"])),
        depth=float(options.get("depth", 0.08)),
        facing=_FACING if faces is None else _FACING_ANY,
        max_move=float(options.get("max_move", 0.3)),
        floor=-float(options.get("below_ground", 0.03)),
        rounds=int(options.get("rounds", 2)),
    )
    grid.vertices = res.vertices.reshape(grid.vertices.shape)
    kept = state.keep_border(grid) if state.keep_border is not None else 0
    report = {
        "moved_vertices": int((res.moves > 1e-6).sum()),
        "max_move": float(res.moves.max()),
        "constraints": res.rows,
        "rounds": res.rounds,
        "feasible": res.feasible,
    }
    if kept:
        report["back_ring_moved"] = kept
    if faces is None:
        state.meta["clearance"] = report
    else:
        report["faces"] = [str(grid.label.ravel()[i]) for i in faces]
        state.meta.setdefault("repairs", []).append(report)
    return report


class ClearanceStep:
    """Lift the cage off the bodies by one linear programme (see :mod:`seatkit.template.clearance`)."""

    name = "clearance"
    description = "move cage vertices along their normals, as little as possible, until no face sinks into a body"
    stage = "grid"
    requires = ("corners",)
    options = {
        "sink": Option("number", "deepest allowed sink of a face into the skin (default: half of max_penetration)", None, "m", 0.0, 0.1),
        "depth": Option("number", "body vertices deeper than this below a face are on its far side", 0.08, "m", 0.0, 1.0),
        "max_move": Option("number", "largest move of one vertex", 0.3, "m", 0.0, 2.0),
        "below_ground": Option("number", "deepest a vertex may end below the ground (y = 0)", 0.03, "m", 0.0, 1.0),
        "rounds": Option("count", "linear programmes solved, each re-linearised at the moved cage", 2, "", 1, 20),
        "repair": Option("bool", "when the final check finds faces crossing a body, lift those faces again counting all the skin over them, then check again", True),
    }

    def run(self, state: FitState, *, options: Mapping[str, Any]) -> None:
        if state.grid is None:
            state.grid = join_blocks(state)
        lift_grid(state, options)

    def repair(self, state: FitState, faces, *, options: Mapping[str, Any]) -> bool:
        """Lift the faces the final check found crossing a body, counting all the skin over them.

        The first lift counts only skin turned towards a face; where a face
        meets a body part from the side (the calf's flank in the fold of a
        raised knee, under the seat's front edge; an arm beside a wall) the
        final check names it. The repair moves only those faces' vertices
        (not the ground ring), with every body vertex over them, up to
        ``depth`` below, required above them. The engine checks the cage
        again; returns whether any vertex moved.
        """
        if not options.get("repair", True) or state.grid is None:
            return False
        rebuild = getattr(state, "rebuild_border", None)
        labels = state.grid.label.ravel()
        named = sorted({str(labels[i]) for i in faces})
        if rebuild is not None and "border" in named:
            # a hand hanging beside the seat pierces the border's side faces:
            # rebuilt with the side ring lowered there (once per start), then lifted as at first
            state.rebuild_border = None
            lifted, border = state.grid, state.meta["border"]
            state.grid = rebuild()
            if state.meta["border"]["dropped_beside"]:
                report = lift_grid(state, options)
                state.meta.setdefault("repairs", []).append({"step": "border", "faces": named, "dropped_beside": state.meta["border"]["dropped_beside"], **report})
                return True
            state.grid, state.meta["border"] = lifted, border
        return lift_grid(state, options, faces=faces)["moved_vertices"] > 0

    def repair_enclosure(self, state: FitState, enclosed, *, options: Mapping[str, Any], every_row: bool = False) -> bool:
        """Put the border's side walls inside the parts the cage does not hold that lie inside the furniture (:func:`_repair_enclosure`).

        ``every_row``: beside the backrest's rows too (the engine's walls
        against a surface the refiners refused, :func:`seatkit.template.engine._walls_against`).
        """
        if not options.get("repair", True) or state.grid is None:
            return False
        return _repair_enclosure(state, enclosed, options, every_row=every_row)


#: Rounds of one enclosure repair: each adds what the last one left inside the furniture.
_WALL_ROUNDS = 3
#: Border rebuilds of one enclosure repair, at most (a wall that crosses the cage or a body is built again without undercut, then left out).
_WALL_BUILDS = 8


def _wall_faces(shape: tuple[int, int], walls: dict) -> dict:
    """{(side, k): indices into :func:`grid_quads` of the four border faces around that wall's ring vertex} (``meta["border"]["walls_inside"]``)."""
    R, C = shape
    out = {}
    for side, ks in walls.items():
        j = 0 if side == "right" else C - 2
        for k in ks:
            out[(side, k)] = [(1 + k + di) * C + j + dj for di in (0, 1) for dj in (0, 1)]
    return out


def _repair_enclosure(state: FitState, enclosed, options: Mapping[str, Any], *, every_row: bool = False) -> bool:
    """The clearance step's ``repair_enclosure`` (docs/templates.md, "Walls inside the hands").

    The border is built again from the grid it started from with walls
    inside the free parts hanging beside or under the seat's sides where
    ``enclosed`` (per body, vertex indices) lie inside the furniture
    (:func:`seatkit.template.border._walls_inside`), and the whole lift runs
    again. A wall whose faces then cross the cage or a body is built again
    straight down from the seat's edge, without undercutting it, and if it
    still crosses, left out (at most ``_WALL_BUILDS`` builds). Up to ``_WALL_ROUNDS`` rounds, each with what the last one still
    left inside added (the limit surface blends neighbouring ring vertices:
    a hand under one wall's neighbour is found next). Once per start.
    ``every_row``: walls beside the backrest's rows too
    (:func:`seatkit.template.border._walls_inside`).
    Returns whether a wall stands (the engine then checks the cage and
    keeps it only if it is valid and encloses less).
    """
    rebuild = state.rebuild_walls
    if rebuild is None:
        return False
    state.rebuild_walls = None
    tolerance = state.params["max_penetration"] + 1e-3
    bodies = [b.body for b in state.blocks]
    found = [set(v) for v in enclosed]
    start, border = state.grid, state.meta["border"]
    # a border the check's repair rebuilt with its side ring lowered beside the hands keeps that too
    lowered = "dropped_beside" in border
    no_wall = {"right": {}, "left": {}}
    best, builds = None, 0
    for _ in range(_WALL_ROUNDS):
        more = False
        while builds < _WALL_BUILDS:
            builds += 1
            state.grid, state.meta["border"] = start, border
            grid = rebuild(found, no_wall=no_wall, drop_beside=lowered, every_row=every_row)
            walls = state.meta["border"]["walls_inside"]
            if not any(walls.values()):
                break
            state.grid = grid
            faces = _wall_faces(grid.shape, walls)
            report = lift_grid(state, options)
            # a wall whose faces cross the cage or a body is left out
            V, quads = state.grid.vertices.reshape(-1, 3), grid_quads(grid.shape)
            bad = {int(f) for pair in self_intersecting_faces(V, quads) for f in pair}
            for body in bodies:
                bad |= {int(f) for f in crossing_faces(V, quads, body, tolerance)}
            crossed = [key for key, fs in faces.items() if bad & set(fs)]
            if not crossed:
                best = (state.grid, state.meta["border"], state.meta["clearance"], {"step": "border", "walls_inside": walls, **report})
                free = _free_segments(state)
                for person, body in enumerate(bodies):
                    index, depth, _ = enclosed_vertices(V, quads, body, free)
                    deep = set(index[depth > tolerance].tolist())
                    more |= bool(deep - found[person])
                    found[person] |= deep
                break
            for side, k in crossed:
                # first without undercutting the seat (straight down from its edge), then none
                no_wall[side][k] = no_wall[side].get(k, 0) + 1
        if not more:
            break
    if best is None:
        state.grid, state.meta["border"] = start, border
        return False
    state.grid, state.meta["border"], state.meta["clearance"], record = best
    state.meta.setdefault("repairs", []).append(record)
    return True


def builtin_steps() -> list:
    """A fresh instance of every built-in step."""
    return [
        FitPlanesStep(),
        BridgeStep(),
        CornersStep(),
        OuterColumnsStep(),
        CrossedLegsStep(),
        NoBackrestStep(),
        SupportabilityStep(),
        JoinStep(),
        ArmrestsStep(),
        BorderStep(),
        ClearanceStep(),
        PoseRuleStep(),
        SeatStep(),
    ]


#: The built-in steps by name.
BUILTIN_STEPS: dict = {s.name: s for s in builtin_steps()}


def update_docs(path) -> bool:
    """Rewrite every ``<!-- options of NAME -->`` block of a Markdown file from the built-in steps' schemas.

    Returns whether the file changed.
    """
    import re
    from pathlib import Path

    path = Path(path)
    text = path.read_text()

    def table(m):
        name = m.group(1)
        return f"<!-- options of {name} -->\n{options_table(BUILTIN_STEPS[name])}\n<!-- end -->"

    new = re.sub(r"<!-- options of ([\w-]+) -->\n.*?\n<!-- end -->", table, text, flags=re.S)
    if new != text:
        path.write_text(new)
    return new != text


if __name__ == "__main__":  # python -m seatkit.template.steps docs/templates.md
    import sys

    for arg in sys.argv[1:]:
        print(f"{arg}: {'updated' if update_docs(arg) else 'up to date'}")
