"""Will it hold? The designed shell under its people's loads and its own weight.

:func:`analyse` builds the shell's mesh (:mod:`seatkit.structure.mesh`),
loads it with every person's contact forces (:mod:`seatkit.structure.loads`)
and its weight, holds it where it meets the floor, solves linear elasticity
(:mod:`seatkit.structure.fem`) and reports the figures of ``structure.json``.
:func:`size_thickness` finds the thinnest shell that keeps a safety factor
and a deflection limit. docs/structure.md describes the model and its limits.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from seatkit.constants import GRAVITY
from seatkit.errors import StructureError
from seatkit.structure.fem import Elasticity, Solution
from seatkit.structure.loads import SPREAD_RADIUS, contact_loads
from seatkit.structure.materials import Material, get_material
from seatkit.structure.mesh import ShellMesh, element_normals, surface_quads9

__all__ = [
    "DEFAULT_LAYERS",
    "DEFAULT_LEVEL",
    "DEFAULT_MAX_DEFLECTION",
    "DEFAULT_SAFETY_FACTOR",
    "FLOOR_TOLERANCE",
    "Analysis",
    "StructureError",
    "analyse",
    "check_thickness",
    "size_thickness",
]

#: Tessellation level whose quads become the elements (their nodes are the level + 1 tessellation).
DEFAULT_LEVEL = 2
#: Quadratic elements through the thickness.
DEFAULT_LAYERS = 1
#: Shell surface points this close to the floor (y = 0) or below are held, m.
FLOOR_TOLERANCE = 0.005
#: Elements whose Jacobian ratio (smallest over largest determinant of their
#: mapping at the quadrature points) is below this are "distorted": folded
#: (ratio <= 0) or nearly so, their stresses meaningless (docs/structure.md).
MIN_JACOBIAN_RATIO = 0.2
#: Safety factor and deflection limit (m) :func:`size_thickness` keeps by default.
DEFAULT_SAFETY_FACTOR = 2.0
DEFAULT_MAX_DEFLECTION = 0.010
#: Thicknesses :func:`size_thickness` searches, m, and the step it rounds up to.
THICKNESS_RANGE = (0.0005, 0.10)
THICKNESS_STEP = 0.0001


@dataclass
class Analysis:
    """One solved shell: the figures of ``structure.json`` and the fields behind them.

    Attributes
    ----------
    summary : dict
        ``structure.json``'s figures (see docs/structure.md).
    mesh : ShellMesh
    solution : Solution
    folded : (E,) bool
        Distorted elements: their mapping turns inside out somewhere, or
        nearly (Jacobian ratio below :data:`MIN_JACOBIAN_RATIO`), where the
        offset sheet folds over itself (the surface curls tighter than the
        thickness) or the surface's parametrisation is badly uneven. Left out
        of the stress maximum.
    held : (N,) bool
        Nodes held at the floor.
    """

    summary: dict
    mesh: ShellMesh
    solution: Solution
    folded: np.ndarray
    held: np.ndarray
    material: Material = field(repr=False, default=None)


def check_thickness(thickness) -> float:
    """``thickness`` as a float (m), or a one-line error when it is not a positive number."""
    try:
        t = float(thickness)
    except (TypeError, ValueError):
        t = math.nan
    if not (math.isfinite(t) and t > 0):
        msg = f"shell thickness must be a positive number of metres (e.g. 0.02 for 2 cm), got {thickness!r}"
        raise StructureError(msg)
    return t


def _material(material) -> Material:
    return material if isinstance(material, Material) else get_material(material)


def analyse(
    control_mesh,
    bodies,
    fields,
    *,
    material="birch-plywood",
    thickness: float = 0.02,
    level: int = DEFAULT_LEVEL,
    layers: int = DEFAULT_LAYERS,
    self_weight: bool = True,
    spread_radius: float = SPREAD_RADIUS,
    _geometry=None,
    _people=None,
) -> Analysis:
    """Solve the shell of ``control_mesh``'s limit surface under the people's contact forces.

    Parameters
    ----------
    control_mesh : seatkit.model.ControlMesh
        The designed cage; its limit surface is the shell's top face.
    bodies : sequence of seatkit.model.Body
    fields : sequence of seatkit.model.PressureField or None
        Each person's reaction on the designed surface (the evaluation's
        ``contact_pressures``); None for a person the surface cannot hold.
    material : str or Material
    thickness : float
        m, > 0.
    level, layers : int
        Mesh resolution (:data:`DEFAULT_LEVEL`, :data:`DEFAULT_LAYERS`).
    self_weight : bool
        Load the shell with its own weight too.

    Raises
    ------
    StructureError
        Bad thickness, a person the surface cannot hold, no floor contact.
    """
    start = time.perf_counter()
    mat = _material(material)
    t = check_thickness(thickness)
    bodies, fields = _check_fields(bodies, fields)
    surface, quads9, normals = _geometry if _geometry is not None else _surface_geometry(control_mesh, level)
    mesh = ShellMesh.extrude(surface.vertices, normals, quads9, t, layers)
    on_floor = np.flatnonzero(surface.vertices[:, 1] <= FLOOR_TOLERANCE)
    if not on_floor.size:
        low = float(surface.vertices[:, 1].min())
        msg = (
            f"the design does not meet the floor: its lowest point is {low * 100:.1f} cm above y = 0 "
            f"(within {FLOOR_TOLERANCE * 1000:.0f} mm counts as on the floor); nothing would hold it"
        )
        raise StructureError(msg)
    held = np.zeros(len(mesh.nodes), bool)
    held[mesh.column(on_floor)] = True
    model = Elasticity(mesh, mat)
    # the people's loads sit on the top face, which the thickness does not move (sizing computes them once)
    people, per_person = _people if _people is not None else contact_loads(mesh, bodies, fields, radius=spread_radius)
    load = people + (model.weight_load() if self_weight else 0.0)
    solution = model.solve(load, np.flatnonzero(held))
    det = model.det
    folded = det.min(axis=1) < MIN_JACOBIAN_RATIO * det.max(axis=1)  # folded or nearly folded
    sound = ~folded
    vm = solution.von_mises
    max_vm = float(vm[sound].max()) if sound.any() else float("nan")
    disp = np.linalg.norm(solution.displacement, axis=1)
    worst = int(np.argmax(disp))
    mass = mat.density_kg_m3 * solution.volume
    applied = load.sum(axis=0)
    reaction = solution.reaction.sum(axis=0)
    touches_floor = held[mesh.elements].any(axis=0)
    away = sound & ~touches_floor
    e_worst = np.flatnonzero(sound)[int(np.argmax(vm[sound].max(axis=1)))] if sound.any() else -1
    summary = {
        "material": mat.name,
        "thickness_m": t,
        "max_von_mises_pa": max_vm,
        "max_von_mises_away_from_floor_pa": float(vm[away].max()) if away.any() else float("nan"),
        "strength_pa": mat.strength_pa,
        "safety_factor": mat.strength_pa / max_vm if max_vm > 0 else math.inf,
        "max_deflection_m": float(disp[worst]),
        "max_deflection_at_m": mesh.nodes[worst].tolist(),
        "max_stress_at_m": mesh.nodes[mesh.elements[:, e_worst]].mean(axis=0).tolist() if e_worst >= 0 else None,
        "mass_kg": float(mass),
        "applied_load_n": float(-applied[1]),
        "floor_reaction_n": float(reaction[1]),
        "applied_load_vector_n": applied.tolist(),
        "floor_reaction_vector_n": reaction.tolist(),
        "people_load_n": [float(-f[1]) for f in per_person],
        "self_weight_n": float(mass * GRAVITY) if self_weight else 0.0,
        "held_nodes": int(held.sum()),
        "mesh": {
            "level": int(level),
            "layers": int(layers),
            "elements": int(mesh.elements.shape[1]),
            "nodes": int(len(mesh.nodes)),
            "dofs": int(model.n_dofs),
            "element": "27-node hexahedron (scikit-fem ElementHex2, MeshHex2)",
            "solver": solution.solver,
        },
        "distorted_elements": int(folded.sum()),
        "distorted_volume_fraction": float(model.dx[folded].sum() / model.dx.sum()),
        "spread_radius_m": float(spread_radius),
        "seconds": time.perf_counter() - start,
        "material_data": mat.as_dict(),
    }
    return Analysis(summary, mesh, solution, folded, held, mat)


def _check_fields(bodies, fields) -> tuple[list, list]:
    """The people and their contact forces as lists, or one line naming a person the design cannot hold."""
    bodies, fields = list(bodies), list(fields)
    missing = [i + 1 for i, f in enumerate(fields) if f is None]
    if missing or len(fields) != len(bodies):
        msg = f"no contact forces for person {', '.join(map(str, missing)) or '?'}: the design cannot hold them, so there is no load to analyse"
        raise StructureError(msg)
    return bodies, fields


def _surface_geometry(control_mesh, level: int):
    surface, quads9 = surface_quads9(control_mesh, level)
    return surface, quads9, element_normals(surface.vertices, quads9)


def size_thickness(
    control_mesh,
    bodies,
    fields,
    *,
    material="birch-plywood",
    safety_factor: float = DEFAULT_SAFETY_FACTOR,
    max_deflection: float = DEFAULT_MAX_DEFLECTION,
    start: float = 0.02,
    level: int = DEFAULT_LEVEL,
    layers: int = DEFAULT_LAYERS,
    max_iterations: int = 12,
) -> tuple[Analysis, list[dict]]:
    """The thinnest shell (to :data:`THICKNESS_STEP`) with ``safety_factor`` and ``max_deflection`` kept.

    Each step predicts the thickness from the last two analyses, stress and
    deflection as powers of the thickness fitted in log-log (a thin shell
    in bending: t^-2 and t^-3), then the answer is rounded up to the step
    and analysed once more, so the figures returned are those of the
    thickness returned.

    Returns
    -------
    analysis : Analysis
        Of the chosen thickness (``summary['sizing']`` says what was kept).
    history : list of dict
        Thickness, safety factor and deflection of every analysis made.

    Raises
    ------
    StructureError
        When no thickness in :data:`THICKNESS_RANGE` keeps both limits.
    """
    if not (safety_factor > 0 and math.isfinite(safety_factor)):
        raise StructureError(f"--safety-factor must be a positive number, got {safety_factor!r}")
    if not (max_deflection > 0 and math.isfinite(max_deflection)):
        raise StructureError(f"--max-deflection must be a positive number of metres, got {max_deflection!r}")
    mat = _material(material)
    bodies, fields = _check_fields(bodies, fields)
    geometry = _surface_geometry(control_mesh, level)
    surface, quads9, normals = geometry
    people = contact_loads(ShellMesh.extrude(surface.vertices, normals, quads9, check_thickness(start), layers), bodies, fields)
    lo, hi = THICKNESS_RANGE
    history: list[dict] = []
    cache: dict[float, Analysis] = {}

    def run(t: float) -> Analysis:
        t = round(min(max(t, lo), hi), 7)
        if t not in cache:
            a = analyse(control_mesh, bodies, fields, material=mat, thickness=t, level=level, layers=layers, _geometry=geometry, _people=people)
            cache[t] = a
            s = a.summary
            history.append({"thickness_m": t, "safety_factor": s["safety_factor"], "max_deflection_m": s["max_deflection_m"]})
        return cache[t]

    def need(a: Analysis) -> float:
        """> 1 when too thin: the larger of the two ratios to the limits."""
        s = a.summary
        return max(safety_factor / s["safety_factor"], s["max_deflection_m"] / max_deflection)

    def ok(a: Analysis) -> bool:
        return need(a) <= 1.0

    grid = lambda x: round(math.ceil(round(x / THICKNESS_STEP, 6)) * THICKNESS_STEP, 7)  # noqa: E731
    t = grid(check_thickness(start))
    a = run(t)
    points = [(t, a)]
    # 1. predict the boundary from the scaling of the last two analyses
    for _ in range(max_iterations // 2):
        s = a.summary
        if len(points) >= 2:
            (t0, a0), (t1, a1) = points[-2], points[-1]
            k_s = _slope(t0, t1, a0.summary["safety_factor"], a1.summary["safety_factor"], 2.0)
            k_d = _slope(t0, t1, 1.0 / a0.summary["max_deflection_m"], 1.0 / a1.summary["max_deflection_m"], 3.0)
        else:
            k_s, k_d = 2.0, 3.0
        target = t * max((safety_factor / s["safety_factor"]) ** (1.0 / k_s), (s["max_deflection_m"] / max_deflection) ** (1.0 / k_d))
        target = grid(min(max(target, lo), hi))
        if target == t:
            break
        t = target
        a = run(t)
        points.append((t, a))
    # 2. bracket the answer on the grid between a thickness that fails and one that holds
    def bracket():
        good = [x for x, y in cache.items() if ok(y)]
        bad = [x for x, y in cache.items() if not ok(y)]
        return (max(bad) if bad else None), (min(good) if good else None)

    fail, hold = bracket()
    while hold is None:
        if max(cache) >= hi:
            worst = cache[max(cache)].summary
            msg = (
                f"no {mat.name} shell up to {hi * 100:.0f} cm thick keeps a safety factor of {safety_factor:g} and a deflection "
                f"under {max_deflection * 1000:g} mm (at {hi * 100:.0f} cm: safety factor {worst['safety_factor']:.2f}, "
                f"deflection {worst['max_deflection_m'] * 1000:.1f} mm)"
            )
            raise StructureError(msg)
        run(grid(min(hi, max(cache) * 1.5)))
        fail, hold = bracket()
    while fail is None and min(cache) > lo:
        run(grid(max(lo, min(cache) / 1.5)))
        fail, hold = bracket()
    # 3. bisect to one grid step
    while fail is not None and hold - fail > THICKNESS_STEP * 1.5:
        run(grid(0.5 * (fail + hold)))
        fail, hold = bracket()
    a = cache[hold]
    a.summary["sizing"] = {
        "safety_factor": float(safety_factor),
        "max_deflection_m": float(max_deflection),
        "thickness_m": float(a.summary["thickness_m"]),
        "governed_by": "safety factor" if safety_factor / a.summary["safety_factor"] >= a.summary["max_deflection_m"] / max_deflection else "deflection",
        "analyses": history,
    }
    return a, history


def _slope(t0: float, t1: float, y0: float, y1: float, default: float) -> float:
    """Exponent k of y ~ t^k through two points, or ``default`` when it is not a sane positive number."""
    try:
        k = math.log(y1 / y0) / math.log(t1 / t0)
    except (ValueError, ZeroDivisionError):
        return default
    return k if math.isfinite(k) and 0.5 <= k <= 4.0 else default
