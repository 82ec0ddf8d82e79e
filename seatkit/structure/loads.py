"""The people's loads on the shell: contact pressure and friction shear.

The evaluation (:mod:`seatkit.evaluate`) recomputes each person's reaction
on the designed surface: a force per body vertex (its normal part is the
contact pressure times the vertex's area, its tangential part the friction
shear), summing to the person's weight. By Newton's third law the shell
carries the opposite forces where the body touches it.

A force on one point of a solid would give it an infinite stress, and a
point load's stress depends on the mesh. Each body vertex's force is
therefore spread over the shell's top face around the point nearest to it,
with a smooth bump of radius :data:`SPREAD_RADIUS` (measured along the
surface), and the bump of every vertex integrates exactly to its force: the
traction is a field independent of the mesh, and the loads on the mesh sum
to the people's weight to rounding.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from seatkit.structure.mesh import ShellMesh, quad9_shape

__all__ = ["SPREAD_RADIUS", "TopQuadrature", "contact_loads"]

#: Radius over which each body vertex's force is spread on the shell, m:
#: about twice the spacing of the body's vertices, the scale over which soft
#: tissue spreads a load anyway.
SPREAD_RADIUS = 0.03

#: Gauss points per direction on each top face.
GAUSS_POINTS = 3


class TopQuadrature:
    """Gauss points on the shell's top face (the designed surface).

    Attributes
    ----------
    points : (P, 3) float64
        Positions, m.
    weights : (P,) float64
        Area represented by each point, m^2 (they sum to the top face's area).
    shape : (k, 9) float64
        Biquadratic basis values at the ``k`` points of one face.
    nodes : (q, 9) int64
        Mesh node ids of each top face (point ``f k + j`` lies on face ``f``).
    """

    def __init__(self, mesh: ShellMesh):
        g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        g, w = 0.5 * (g + 1.0), 0.5 * w
        x, y = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
        weight = np.outer(w, w).ravel()
        values, dx, dy = quad9_shape(x, y)
        self.nodes = mesh.quads9 + (mesh.sheets - 1) * mesh.n_surface
        X = mesh.nodes[self.nodes]  # (q, 9, 3)
        self.points = np.einsum("kj,qjc->qkc", values, X).reshape(-1, 3)
        area = np.linalg.norm(np.cross(np.einsum("kj,qjc->qkc", dx, X), np.einsum("kj,qjc->qkc", dy, X)), axis=2)
        self.weights = (area * weight).ravel()
        self.shape = values

    def nodal(self, traction_force: np.ndarray, n_nodes: int) -> np.ndarray:
        """(n_nodes, 3) consistent nodal forces of forces ``(P, 3)`` carried by the Gauss points."""
        k = self.shape.shape[0]
        per = np.einsum("kj,qkc->qjc", self.shape, traction_force.reshape(-1, k, 3))
        out = np.zeros((n_nodes, 3))
        np.add.at(out, self.nodes.ravel(), per.reshape(-1, 3))
        return out


def contact_loads(mesh: ShellMesh, bodies, fields, *, radius: float = SPREAD_RADIUS, quadrature: TopQuadrature | None = None):
    """Nodal forces (N, 3) of every person's contact forces on the shell, and the force per person (k, 3).

    Parameters
    ----------
    mesh : ShellMesh
    bodies : sequence of seatkit.model.Body
    fields : sequence of seatkit.model.PressureField
        Each person's reaction on the designed surface (the evaluation's
        ``contact_pressures``).
    radius : float
        :data:`SPREAD_RADIUS`.
    """
    quad = quadrature or TopQuadrature(mesh)
    tree = cKDTree(quad.points)
    total = np.zeros((len(quad.points), 3))
    per_person = []
    for body, field in zip(bodies, fields):
        force = -np.asarray(field.force, dtype=np.float64)  # what the body does to the shell
        loaded = np.flatnonzero(np.linalg.norm(force, axis=1) > 0)
        per_person.append(force[loaded].sum(axis=0) if loaded.size else np.zeros(3))
        if not loaded.size:
            continue
        p = np.asarray(body.vertices, dtype=np.float64)[loaded]
        height, _ = tree.query(p)  # distance to the top face (to a Gauss point's spacing)
        reach = np.sqrt(height**2 + radius**2)
        near = tree.query_ball_point(p, reach, return_sorted=False)
        cols = np.repeat(np.arange(len(p)), [len(n) for n in near])  # the body vertex of each pair
        rows = np.fromiter((k for n in near for k in n), dtype=np.int64, count=len(cols))  # its Gauss point
        diff = quad.points[rows] - p[cols]
        d2 = np.einsum("kc,kc->k", diff, diff)
        along = np.sqrt(np.maximum(d2 - height[cols] ** 2, 0.0)) / radius  # distance along the surface / radius
        bump = np.clip(1.0 - along**2, 0.0, None) ** 2 * quad.weights[rows]
        vals = bump / np.bincount(cols, weights=bump, minlength=len(p))[cols]  # each vertex's bump integrates to 1
        W = sp.csr_matrix((vals, (rows, cols)), shape=(len(quad.points), len(loaded)))
        total += W @ force[loaded]
    return quad.nodal(total, len(mesh.nodes)), np.array(per_person).reshape(-1, 3)
