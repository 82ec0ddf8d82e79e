"""The data that flows through a build.

Every array is SI (metres, kilograms, newtons, pascals, radians), right-handed,
+Y up, the body facing +Z. Shapes and dtypes are in the type slot; ``n`` is the
number of body vertices, ``m`` of body triangles, ``v`` of control-mesh
vertices, ``f`` of control-mesh faces. All types are plain frozen dataclasses
of numpy arrays: picklable, so a build is a pure function of its inputs and
can run on any Dask worker.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np

from seatkit.skeleton import N_SEGMENTS, PARENTS

__all__ = [
    "total_seconds",
    "Pose",
    "RiggedBody",
    "Body",
    "PressureField",
    "ControlMesh",
    "Surface",
    "Baseline",
    "BuildResult",
]


def _f64(a, shape=None, name="array"):
    arr = np.asarray(a, dtype=np.float64)
    if shape is not None:
        want = tuple(s if s is not None else arr.shape[i] for i, s in enumerate(shape))
        if arr.ndim != len(shape) or arr.shape != want:
            msg = f"{name} must have shape {tuple('n' if s is None else s for s in shape)}, got {arr.shape}"
            raise ValueError(msg)
    return arr


@dataclass(frozen=True)
class Pose:
    """A pose: 21 joint rotations plus the root translation (66 numbers).

    Attributes
    ----------
    rotations : (21, 3) float64
        Rotation vector (axis times angle, radians) of each segment relative
        to its parent, in the parent's rest frame, applied about the segment's
        proximal joint. Row 0 is the root (Hips) orientation in the world.
    translation : (3,) float64
        Root translation in metres, added after posing.
    name : str
        Where the pose came from (library name or file), for reports.
    """

    rotations: np.ndarray
    translation: np.ndarray
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "rotations", _f64(self.rotations, (N_SEGMENTS, 3), "rotations"))
        object.__setattr__(self, "translation", _f64(self.translation, (3,), "translation"))

    @classmethod
    def rest(cls, name: str = "rest") -> "Pose":
        """The rest pose (every rotation zero, no translation)."""
        return cls(np.zeros((N_SEGMENTS, 3)), np.zeros(3), name)

    def as_vector(self) -> np.ndarray:
        """The 66 numbers: 63 rotation-vector components then 3 translation."""
        return np.concatenate([self.rotations.ravel(), self.translation])


@dataclass(frozen=True)
class RiggedBody:
    """A body in its rest pose, rigged to the 21-segment skeleton.

    Attributes
    ----------
    vertices : (n, 3) float64
        Rest-pose vertex positions, m.
    faces : (m, 3) int64
        Triangles, counter-clockwise seen from outside.
    weights : (n, 21) float64
        Linear-blend-skinning weights per segment; non-negative, rows sum to 1.
    joints : (21, 3) float64
        Rest position of each segment's proximal joint (row 0: the root, at
        the hip centre), m.
    tips : (21, 3) float64
        Rest position of each segment's distal end (the child joint, or the
        end of the hand, foot, head), m.
    mass : float
        Total body mass, kg.
    segment_mass : (21,) float64
        Mass of each segment, kg (Plagenhoef et al. 1983 fractions of mass).
    com_ratio : (21,) float64
        Position of each segment's centre of mass along joint -> tip, as a
        fraction of the segment length (Plagenhoef et al. 1983).
    name : str
        Which body this is (``default-male``, a file path, ...).
    region_labels : dict of str to (k,) int64
        Named vertex sets (``face``, ``hands`` ...) used for exclusions.
    meta : dict
        Provenance (source data, licence, parameters).
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    joints: np.ndarray
    tips: np.ndarray
    mass: float
    segment_mass: np.ndarray
    com_ratio: np.ndarray
    name: str = ""
    region_labels: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Body:
    """A posed, skinned body: what the pressure solver and templates see.

    Attributes
    ----------
    vertices : (n, 3) float64
        Posed vertex positions, m; by default the lowest rests on y = 0.
    faces : (m, 3) int64
        Triangles.
    weights : (n, 21) float64
        Skinning weights (rows sum to 1).
    joints : (21, 3) float64
        Posed proximal joint of each segment, m. Joint ``j`` of the 20
        joints is ``joints[j + 1]``.
    tips : (21, 3) float64
        Posed distal end of each segment, m; ``tips - joints`` is the bone
        direction ``d^body`` of the paper.
    segment_mass : (21,) float64
        Segment masses, kg; they sum to the body mass.
    segment_com : (21, 3) float64
        Posed centre of mass of each segment, m.
    name : str
        Body and pose, for reports.
    region_labels : dict of str to (k,) int64
        Named vertex sets, as in :class:`RiggedBody`.
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: np.ndarray
    joints: np.ndarray
    tips: np.ndarray
    segment_mass: np.ndarray
    segment_com: np.ndarray
    name: str = ""
    region_labels: dict = field(default_factory=dict)

    @property
    def mass(self) -> float:
        """Total mass, kg."""
        return float(self.segment_mass.sum())

    @property
    def parents(self) -> np.ndarray:
        """(21,) int64 parent segment of each segment (-1 for the root)."""
        return PARENTS

    def translated(self, offset) -> "Body":
        """The same body moved rigidly by ``offset`` (3,), m."""
        d = np.asarray(offset, dtype=np.float64)
        return replace(
            self,
            vertices=self.vertices + d,
            joints=self.joints + d,
            tips=self.tips + d,
            segment_com=self.segment_com + d,
        )


@dataclass(frozen=True)
class PressureField:
    """The reaction of a support on a body (the paper's Section 4 solution).

    Attributes
    ----------
    force : (n, 3) float64
        Reaction force on each vertex in world coordinates, N.
    normal_force : (n,) float64
        Component of ``force`` along the vertex's inward reaction normal, N (>= 0).
    pressure : (n,) float64
        ``normal_force / area``, Pa.
    shear : (n,) float64
        Tangential stress magnitude, Pa.
    area : (n,) float64
        Mixed Voronoi area of each vertex, m^2.
    contact : (n,) bool
        Vertices allowed to carry a reaction.
    joint_force : (20, 3) float64
        Force the parent exerts on the child at each joint, N.
    joint_moment : (20, 3) float64
        Moment the parent exerts on the child at each joint, N m.
    status : str
        Solver status (``optimal`` ...).
    residuals : dict of str to float
        Equilibrium and constraint residuals recomputed after the solve.
    solve_seconds : float
        Wall time of the solve, s.
    params : dict
        lambda, mu, solver and contact settings used.
    """

    force: np.ndarray
    normal_force: np.ndarray
    pressure: np.ndarray
    shear: np.ndarray
    area: np.ndarray
    contact: np.ndarray
    joint_force: np.ndarray
    joint_moment: np.ndarray
    status: str = "optimal"
    residuals: dict = field(default_factory=dict)
    solve_seconds: float = 0.0
    params: dict = field(default_factory=dict)

    @property
    def importance(self) -> np.ndarray:
        """(n,) float64 importance in [0, 1]: pressure scaled by its maximum."""
        peak = float(self.pressure.max()) if self.pressure.size else 0.0
        return self.pressure / peak if peak > 0 else np.zeros_like(self.pressure)


@dataclass(frozen=True)
class ControlMesh:
    """A subdivision-surface cage fitted by a template.

    Attributes
    ----------
    vertices : (v, 3) float64
        Control points, m.
    faces : (f, 4) int64
        Quads, counter-clockwise seen from the body side (normals point at
        the body, i.e. up for a seat).
    face_segments : (f,) int64
        Body segment each face supports, -1 for structural faces (border,
        connectors).
    face_person : (f,) int64
        Which person (0-based, in seat order) a face supports, -1 for shared.
    face_labels : tuple of str
        A human-readable role per face (``thigh.left``, ``border`` ...).
    plane_points : (f, 3) float64
        A point on each face's supporting plane; NaN where a face has none.
    plane_normals : (f, 3) float64
        Unit normal of each face's supporting plane; NaN where none.
    vertex_weights : (v,) float64
        Importance of each control point (data-term weight of ``optimize``).
    fixed : (v,) bool
        Control points that refiners must not move (ground border).
    ground : (v,) bool
        Control points on the ground rectangle (y = 0).
    crease_edges : (k, 2) int64
        Edges with a crease, as vertex pairs.
    crease_sharpness : (k,) float64
        OpenSubdiv sharpness of each crease edge (10 or more = infinitely sharp).
    corners : (c,) int64
        Corner vertices.
    corner_sharpness : (c,) float64
        OpenSubdiv sharpness of each corner.
    meta : dict
        What the template did (special cases taken, rejected planes, ...).
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_segments: np.ndarray
    face_person: np.ndarray = None
    face_labels: tuple = ()
    plane_points: np.ndarray = None
    plane_normals: np.ndarray = None
    vertex_weights: np.ndarray = None
    fixed: np.ndarray = None
    ground: np.ndarray = None
    crease_edges: np.ndarray = None
    crease_sharpness: np.ndarray = None
    corners: np.ndarray = None
    corner_sharpness: np.ndarray = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        v = np.asarray(self.vertices, dtype=np.float64)
        f = np.asarray(self.faces, dtype=np.int64)
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        nf, nv = len(f), len(v)
        defaults = {
            "face_segments": lambda: np.full(nf, -1, np.int64),
            "face_person": lambda: np.full(nf, -1, np.int64),
            "plane_points": lambda: np.full((nf, 3), np.nan),
            "plane_normals": lambda: np.full((nf, 3), np.nan),
            "vertex_weights": lambda: np.ones(nv),
            "fixed": lambda: np.zeros(nv, bool),
            "ground": lambda: np.zeros(nv, bool),
            "crease_edges": lambda: np.zeros((0, 2), np.int64),
            "crease_sharpness": lambda: np.zeros(0),
            "corners": lambda: np.zeros(0, np.int64),
            "corner_sharpness": lambda: np.zeros(0),
        }
        for name, make in defaults.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, make())
        if not self.face_labels:
            object.__setattr__(self, "face_labels", tuple("" for _ in range(nf)))

    def with_vertices(self, vertices) -> "ControlMesh":
        """The same cage with new control points (v, 3)."""
        return replace(self, vertices=np.asarray(vertices, dtype=np.float64))


@dataclass(frozen=True)
class Surface:
    """A tessellated limit surface of a cage.

    Attributes
    ----------
    vertices : (p, 3) float64
        Limit positions, m.
    normals : (p, 3) float64
        Unit limit normals.
    faces : (q, 4) int64
        Quads of the refined mesh.
    level : int
        Subdivision level it was refined to.
    """

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    level: int


@dataclass(frozen=True)
class Baseline:
    """The baseline design a build compares ours with (default the flat patch, Sit & Relax).

    Attributes
    ----------
    template : str
        The baseline template's registered name.
    control_mesh : ControlMesh
        Its cage after the baseline's refiners.
    surface : Surface
        Its limit surface.
    metrics : list of dict
        The evaluation figures per person (keys of :mod:`seatkit.evaluate`).
    contact_pressures : list of PressureField or None
        Each person's contact pressure on its surface (None where it cannot
        hold the person).
    seconds : float
        Wall time of the fit and evaluation.
    """

    template: str
    control_mesh: ControlMesh
    surface: Surface
    metrics: list
    contact_pressures: list
    seconds: float = 0.0


@dataclass
class BuildResult:
    """Everything one build produced.

    Attributes
    ----------
    recipe : seatkit.recipe.Recipe or mapping
        The recipe the build ran (after command-line overrides): a
        :class:`~seatkit.recipe.Recipe` from :func:`seatkit.build`; a plain
        mapping where a caller assembles a result itself (``seatkit
        evaluate`` from design.npz).
    bodies : list of Body
        The posed bodies, in seat order.
    pressures : list of PressureField
        The "supported everywhere" pressure of each body (importance maps).
    initial_mesh : ControlMesh
        The template's cage before refiners.
    control_mesh : ControlMesh
        The cage after every refiner.
    surface : Surface or None
        The limit surface of ``control_mesh``.
    metrics : dict
        Evaluation figures (the paper's Table 1 quantities).
    timings : dict of str to float
        Seconds per stage.
    files : dict of str to str
        Output files written, by role.
    contact_pressures : list of PressureField or None
        Each person's contact pressure on ``surface`` (set by the evaluation;
        None for a person the surface cannot hold): the paper's model, a
        relative importance.
    interface_pressures : list of PressureField or None
        Each person's interface pressure on ``surface`` from the soft-tissue
        contact model (:mod:`seatkit.pressure.compliant`; None for a person
        it cannot hold), when the evaluation computed it.
    baseline : Baseline or None
        The baseline design, when the evaluation fitted one.
    output : str or None
        The output folder, once the files are written.
    structure : seatkit.structure.analysis.Analysis or None
        The structural analysis, when the recipe asks for one.
    shell_thickness_m : float or None
        The shell thickness the structural analysis chose (the ``shell``
        exporter uses it), m.
    frames : list of seatkit.body.frame.CanonicalFrame or None
        Per person, the rigid move from the capture's frame into the
        template's (canonical) frame the design is fitted in; None where a
        caller assembled the result from bodies already placed.
    """

    recipe: Any
    bodies: list
    pressures: list
    initial_mesh: ControlMesh | None = None
    control_mesh: ControlMesh | None = None
    surface: Surface | None = None
    metrics: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)
    contact_pressures: list | None = None
    interface_pressures: list | None = None
    baseline: Baseline | None = None
    output: str | None = None
    structure: Any = None
    shell_thickness_m: float | None = None
    frames: list | None = None


def total_seconds(timings: Mapping[str, float]) -> float:
    """A build's wall time from its stage timings.

    Stages marked ``(parallel)`` ran on another process or thread during
    the others and are left out.
    """
    return float(sum(v for k, v in timings.items() if not str(k).endswith("(parallel)")))
