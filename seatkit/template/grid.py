"""The fitting state: one block of faces per person, row and column lines, corners.

Rows run from the first declared row (the chair: the feet) to the last (the
upper back); columns run along ``d_side = d_up x n`` (the body's right to
its left). Vertex ``(b, k)`` of a block sits on row boundary ``b`` (0..R)
and column line ``k`` (0..C). Each fitted face estimates its four corners by
intersecting its row lines (its plane cut with the neighbouring row's plane,
when that line lies between the two rows' segments, else the joint line)
with its column lines (``d_up`` offset by the segment's half width along
``d_side``); a vertex is the mean of the estimates of the faces around it
(paper Section 5.2). ``d_up`` comes from :meth:`Block.row_axis`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from seatkit.model import Body
from seatkit.skeleton import PARENTS, SEGMENTS
from seatkit.template.planes import Plane, intersect_planes, cross, unit
from seatkit.template.schema import FaceSpec, TemplateSpec

__all__ = ["FaceState", "Block", "GridMesh", "FitState", "segment_of_vertex"]


#: Parts the chair never holds (hands and forearms): they do not occlude a
#: supported part (``supportability``), and the border's repair keeps the
#: furniture from closing over them (docs/templates.md, "The border lowered
#: beside hanging hands").
NOT_HELD = frozenset(SEGMENTS.index(h) for h in ("RightHand", "LeftHand", "RightForeArm", "LeftForeArm"))


def segment_of_vertex(body: Body) -> np.ndarray:
    """(n,) int64 segment of largest skinning weight of each vertex."""
    return np.asarray(body.weights).argmax(1).astype(np.int64)


@dataclass
class FaceState:
    """A face while it is being fitted.

    Attributes
    ----------
    spec : FaceSpec
    segments : tuple of int
        Segments it supports now (a special case may merge two).
    plane : Plane or None
    d_up, d_side : (3,) float64
        Unit frame on the plane (paper Fig. 3).
    centre : (3,) float64
        Segment centroid projected on the plane, m.
    side_range : (2,) float64
        Column lines at ``centre + s * d_side`` for s in side_range, m.
    supported : (k,) int64
        Body vertices within the support distance of the plane.
    weight : float
        Importance carried by the supported vertices.
    info : dict
        What the fit saw (candidates, rejections).
    """

    spec: FaceSpec
    segments: tuple
    plane: Plane | None = None
    d_up: np.ndarray | None = None
    d_side: np.ndarray | None = None
    centre: np.ndarray | None = None
    side_range: np.ndarray | None = None
    supported: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    weight: float = 0.0
    info: dict = field(default_factory=dict)


@dataclass
class Block:
    """The faces fitted to one person.

    Attributes
    ----------
    person : int
        Index in seat order.
    body : Body
    importance : (n,) float64
        Pressure scaled to [0, 1].
    normal_force : (n,) float64
        Normal reaction of each vertex, N.
    force : (n, 3) float64
        Reaction force on each vertex, N.
    segment : (n,) int64
        Segment of each vertex.
    faces : dict of (int, int) to FaceState
    rows : list of int
        Active rows (contiguous); a special case may drop some.
    estimates : dict of (int, int) to list of (3,) float64
        Corner estimates per vertex (b, k).
    cases : dict
        Special-case facts other steps use (``merged_rows``: rows whose two
        leg faces share one plane).
    members : dict
        Cache of :meth:`vertices_of` by segment tuple.
    """

    person: int
    body: Body
    importance: np.ndarray
    normal_force: np.ndarray
    force: np.ndarray
    segment: np.ndarray
    faces: dict
    rows: list
    n_columns: int
    estimates: dict = field(default_factory=dict)
    cases: dict = field(default_factory=dict)
    members: dict = field(default_factory=dict, repr=False)
    centroids: dict = field(default_factory=dict, repr=False)

    # -- body queries -------------------------------------------------------
    def vertices_of(self, segments) -> np.ndarray:
        """(k,) int64 body vertices whose main segment is in ``segments``."""
        key = tuple(sorted(int(s) for s in segments))
        if key not in self.members:
            self.members[key] = np.flatnonzero(np.isin(self.segment, list(key)))
        return self.members[key]

    def centroid(self, segments) -> np.ndarray:
        """(3,) float64 mean of :meth:`vertices_of` ``segments``, kept per segment set (a new array each call)."""
        key = tuple(sorted(int(s) for s in segments))
        if key not in self.centroids:
            self.centroids[key] = self.body.vertices[self.vertices_of(key)].mean(0)
        return self.centroids[key].copy()

    def neighbours_of(self, segments) -> list:
        """Segments adjacent (parent or child) to ``segments`` but not in them."""
        segs = set(segments)
        out = set()
        for s in segs:
            if PARENTS[s] >= 0:
                out.add(int(PARENTS[s]))
            out.update(int(c) for c in np.flatnonzero(PARENTS == s))
        return sorted(out - segs)

    def joint_between(self, a, b) -> np.ndarray:
        """(3,) float64 mean joint connecting segment sets ``a`` and ``b``, or the midpoint of their centroids."""
        body = self.body
        pts = [body.joints[c] for c in range(len(PARENTS)) if (c in a and PARENTS[c] in b) or (c in b and PARENTS[c] in a)]
        if pts:
            return np.mean(pts, axis=0)
        return (self.centroid(a) + self.centroid(b)) / 2

    def bone(self, segments) -> np.ndarray:
        """(3,) float64 mean bone direction (joint to tip) of ``segments``."""
        body = self.body
        d = sum(unit(body.tips[s] - body.joints[s]) for s in segments)
        return unit(np.asarray(d, dtype=np.float64))

    def lateral(self) -> np.ndarray:
        """(3,) float64 the body's right-to-left axis (hip and shoulder joints)."""
        from seatkit.skeleton import SEGMENT_INDEX as S

        j = self.body.joints
        d = unit(j[S["LeftUpLeg"]] - j[S["RightUpLeg"]]) + unit(j[S["LeftArm"]] - j[S["RightArm"]])
        return unit(d)

    def torso_front(self) -> np.ndarray:
        """(3,) float64 the torso's front direction: lateral axis x (hips to upper back)."""
        from seatkit.skeleton import SEGMENT_INDEX as S

        axis = unit(self.body.tips[S["Spine3"]] - self.body.joints[S["Hips"]])
        return unit(cross(self.lateral(), axis))

    def oriented_bone(self, segments, r: int) -> np.ndarray:
        """(3,) float64 bone direction of ``segments`` pointing along the grid's rows at row ``r``."""
        bone = self.bone(segments)
        return -bone if bone @ self.up_hint(r) < 0 else bone

    def row_axis(self, segments, r: int) -> np.ndarray:
        """(3,) float64 the direction d_up is taken from, for a face of row ``r`` on ``segments``.

        The paper projects the bone d^body onto the plane. A bone nearly
        along the plane's normal (the pelvis over a seat) projects to a short,
        noisy vector, so the unit bone (oriented along the grid's rows) is
        added to the unit direction from the previous row's segments to the
        next row's: projected onto any plane the sum is dominated by
        whichever lies in it.
        """
        return unit(self.oriented_bone(segments, r) + unit(self.up_hint(r)))

    def frame_normal(self, segments, r: int) -> np.ndarray:
        """(3,) float64 the normal a face of row ``r`` would have with d_side along the lateral axis."""
        return unit(cross(self.lateral(), self.row_axis(segments, r)))

    def row_segments(self, r: int) -> tuple:
        """Every segment supported in row ``r``."""
        return tuple(sorted({s for (rr, _), f in self.faces.items() if rr == r for s in f.segments}))

    def up_hint(self, r: int) -> np.ndarray:
        """(3,) float64 direction from the row before ``r`` to the row after it."""
        rows = self.rows
        i = rows.index(r)
        before = rows[i - 1] if i > 0 else r
        after = rows[i + 1] if i + 1 < len(rows) else r
        return self.centroid(self.row_segments(after)) - self.centroid(self.row_segments(before))

    # -- planes and lines ----------------------------------------------------
    def set_frame(self, face: FaceState, plane: Plane, *, side_range=None) -> None:
        """Give ``face`` its plane, its (d_up, d_side) frame and its column lines."""
        n = plane.normal
        axis = self.row_axis(face.segments, face.spec.row)
        up = axis - n * (n @ axis)
        if np.linalg.norm(up) < 1e-6:
            up = cross(n, self.lateral())
        up = unit(up)
        side = cross(up, n)
        idx = self.vertices_of(face.segments)
        pts = self.body.vertices[idx]
        centre = plane.project(self.centroid(face.segments)[None])[0]
        if side_range is None:
            s = (pts - centre) @ side
            half = 0.5 * (s.max() - s.min()) * face.spec.width_fraction
            mid = 0.5 * (s.max() + s.min())
            side_range = np.array([mid - half, mid + half])
        face.plane, face.d_up, face.d_side, face.centre = plane, up, side, centre
        face.side_range = np.asarray(side_range, dtype=np.float64)

    def row_plane(self, r: int) -> Plane | None:
        """Mean plane of the fitted faces of row ``r``, or None."""
        planes = [f.plane for (rr, _), f in self.faces.items() if rr == r and f.plane is not None]
        if not planes:
            return None
        n = unit(np.mean([p.normal for p in planes], axis=0))
        return Plane(np.mean([p.point for p in planes], axis=0), n)

    def neighbour_plane(self, r: int, c: int) -> Plane | None:
        """Plane of face (r, c) if fitted, else the mean plane of row r."""
        f = self.faces.get((r, c))
        if f is not None and f.plane is not None:
            return f.plane
        return self.row_plane(r)

    def row_line(self, face: FaceState, other_row: int, params: dict) -> tuple[np.ndarray, np.ndarray]:
        """Line between ``face`` and row ``other_row`` (its neighbour), in ``face``'s plane.

        The line of intersection of the two planes (paper's l^ir) when they
        meet at a clear angle, near the joint between the two rows, and not
        so skewed that a face would degenerate; otherwise the line through
        the joint (projected on the plane) along ``d_side``.
        """
        P = face.plane
        c = face.spec.column
        Q = self.neighbour_plane(other_row, c)
        segs_other = self.faces[(other_row, c)].segments or self.row_segments(other_row)
        anchor = P.project(self.joint_between(set(face.segments), set(segs_other))[None])[0]
        if Q is not None:
            hit = intersect_planes(P, Q, min_angle=params["min_dihedral"])
            if hit is not None:
                point, d = hit
                point = point + d * ((anchor - point) @ d)
                angle = np.arccos(min(1.0, abs(float(d @ face.d_side))))
                # the line must lie between the two rows' segments along d_up,
                # or the face would fold over its neighbour
                sign = 1.0 if other_row > face.spec.row else -1.0
                other = self.centroid(segs_other)
                t_line = sign * float((point - face.centre) @ face.d_up)
                t_other = sign * float((other - face.centre) @ face.d_up)
                between = 0.0 < t_line < t_other
                if between and angle <= params["max_row_angle"] and np.linalg.norm(point - anchor) <= params["max_line_offset"]:
                    return point, d
        return anchor, face.d_side

    def end_line(self, face: FaceState, sign: float, params: dict) -> tuple[np.ndarray, np.ndarray]:
        """Line closing the first (sign -1) or last (sign +1) row beyond the segment's extent."""
        pts = self.body.vertices[self.vertices_of(face.segments)]
        t = (pts - face.centre) @ face.d_up
        reach = (t.max() if sign > 0 else t.min()) + sign * params["end_margin"]
        return face.centre + reach * face.d_up, face.d_side

    def corners(self, face: FaceState, params: dict) -> np.ndarray:
        """(4, 3) float64 corner estimates (b,k), (b,k+1), (b+1,k+1), (b+1,k) of a fitted face."""
        r = face.spec.row
        i = self.rows.index(r)
        lines = []
        for j, sign in ((i - 1, -1.0), (i + 1, 1.0)):
            if 0 <= j < len(self.rows):
                lines.append(self.row_line(face, self.rows[j], params))
            else:
                lines.append(self.end_line(face, sign, params))
        out = []
        for (q, u), s_pair in zip(lines, (face.side_range, face.side_range[::-1])):
            rel = q - face.centre
            qs, qt = rel @ face.d_side, rel @ face.d_up
            us, ut = u @ face.d_side, u @ face.d_up
            for s in s_pair:
                a = (s - qs) / us
                out.append(face.centre + s * face.d_side + (qt + a * ut) * face.d_up)
        return np.array(out)

    def add_estimates(self, face: FaceState, corners: np.ndarray) -> None:
        """Record the four corner estimates of ``face``."""
        r, c = face.spec.row, face.spec.column
        for key, p in zip(((r, c), (r, c + 1), (r + 1, c + 1), (r + 1, c)), corners):
            self.estimates.setdefault(key, []).append(np.asarray(p))

    def vertex(self, b: int, k: int) -> np.ndarray:
        """(3,) float64 mean of the estimates of vertex (b, k)."""
        return np.mean(self.estimates[(b, k)], axis=0)

    def vertex_grid(self) -> np.ndarray:
        """(R'+1, C+1, 3) float64 vertices of the active rows (NaN where none)."""
        rows = self.rows
        out = np.full((len(rows) + 1, self.n_columns + 1, 3), np.nan)
        for i, b in enumerate(list(rows) + [rows[-1] + 1]):
            for k in range(self.n_columns + 1):
                if (b, k) in self.estimates:
                    out[i, k] = self.vertex(b, k)
        return out


@dataclass
class GridMesh:
    """A structured quad grid: the joined blocks, then the border around them.

    Attributes
    ----------
    vertices : (R+1, C+1, 3) float64
    segment : (R, C) int64
        Main supported segment per face, -1 for structural faces.
    person : (R, C) int64
    label : (R, C) object
    plane_point, plane_normal : (R, C, 3) float64
        NaN where a face has no supporting plane.
    face_weight : (R, C) float64
        Importance carried by the face, in [0, 1].
    ground : (R+1, C+1) bool
        Vertices on the ground rectangle.
    fixed : (R+1, C+1) bool, optional
        Vertices the refiners keep where they are (besides the ground ring):
        a dimension a designer set (the ``seat`` step's backrest height).
    """

    vertices: np.ndarray
    segment: np.ndarray
    person: np.ndarray
    label: np.ndarray
    plane_point: np.ndarray
    plane_normal: np.ndarray
    face_weight: np.ndarray
    ground: np.ndarray
    fixed: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        """(R, C) faces."""
        return self.segment.shape


def grid_quads(shape: tuple[int, int]) -> np.ndarray:
    """(R*C, 4) int64 quads of a structured grid of (R, C) faces, as in :func:`seatkit.template.engine.grid_to_mesh`."""
    R, C = shape
    ids = np.arange((R + 1) * (C + 1)).reshape(R + 1, C + 1)
    return np.stack([ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]], axis=-1).reshape(-1, 4)


@dataclass
class FitState:
    """What the steps of one fit share: the view a template step reads and changes.

    The engine makes one per fit and passes it to every step's ``run`` in
    the order of the template's ``steps:``. What a step may do with it
    (docs/plugins.md, "Writing a template step"):

    * read everything;
    * a ``"blocks"`` step changes the faces of each person
      (``blocks[i].faces[(row, column)]``: ``plane``, ``segments``,
      ``supported``, ``weight``, ``info``; :meth:`Block.set_frame` gives a
      plane its frame), the corner estimates (``blocks[i].estimates``, via
      :meth:`Block.add_estimates`) and ``blocks[i].rows`` (the rows kept);
    * a ``"grid"`` step changes ``grid`` (a :class:`GridMesh`: replace it,
      or change ``grid.vertices`` in place; its row ``i`` is template row
      ``blocks[0].rows[i]`` before the border, whose two rings add two rows
      and columns on every side);
    * any step adds facts to ``meta`` (JSON-able; shown in report.json);
      a step decides from the rest of the state and from the special cases
      taken, not from other facts in ``meta`` (the engine recognises a
      start that fits as a refused one did by that state:
      :class:`seatkit.template.engine._AlikeStarts`);
    * random choices use ``rng`` only (same seed, same cage).

    Attributes
    ----------
    spec : TemplateSpec
        The template: ``rows``, ``columns`` (names), ``faces`` (by
        (row, column) index), ``source`` (file, for messages).
    params : dict
        Resolved template parameters (SI; ``*_deg`` also in radians
        without the suffix).
    blocks : list of Block
        One per person, in seat order.
    rng : numpy.random.Generator
    grid : GridMesh or None
        Set by the ``join`` step (or the first ``"grid"`` step).
    meta : dict
        Special cases taken, diagnostics; copied to ``ControlMesh.meta``.
    rebuild_border : callable or None
        Set by the ``border`` step: builds the border again from the grid it
        started from, with the side rings lowered beside hanging hands (the
        clearance step's repair; docs/templates.md, "The border lowered beside
        hanging hands").
    rebuild_walls : callable or None
        Set by the ``border`` step: builds the border again from the grid it
        started from, with its side ring inside the hands hanging beside or
        under the seat that were found inside the furniture (the clearance
        step's ``repair_enclosure``; docs/templates.md, "Walls inside the
        hands").
    keep_border : callable or None
        Set by the ``border`` step: ``keep_border(grid)`` puts the border's
        back ring behind the back rows again after a lift moved them
        (:func:`seatkit.template.border.keep_back_behind`).
    last_resort : bool
        This fit is one of the template's last-resort cages
        (:meth:`seatkit.template.YamlTemplate.last_resort_fits`, asked for
        only when the refiners refused every other cage): steps apply their
        last-resort options (``fit-planes``' ``last_resort_rows``).
    """

    spec: TemplateSpec
    params: dict
    blocks: list
    rng: np.random.Generator
    grid: GridMesh | None = None
    meta: dict = field(default_factory=dict)
    rebuild_border: object = None
    rebuild_walls: object = None
    keep_border: object = None
    last_resort: bool = False

    def supported_segments(self) -> list[int]:
        """Every segment listed by a fitted ('fit' or 'outer') face of a kept row, of any person (``meta["supported_segments"]``)."""
        segs = set()
        for block in self.blocks:
            for (r, _c), f in block.faces.items():
                if r in block.rows and f.plane is not None and f.spec.role in ("fit", "outer"):
                    segs.update(int(s) for s in f.segments)
        return sorted(segs)

    def face_name(self, face: FaceState) -> str:
        """``thigh.right`` style name of a face."""
        return f"{self.spec.rows[face.spec.row]}.{self.spec.columns[face.spec.column]}"

    def segment_names(self, segments) -> list:
        """Names of segment indices."""
        return [SEGMENTS[s] for s in segments]
