"""The finite-element mesh of a shell: quadratic hexahedra through its thickness.

The shell is the solid between the designed limit surface (the side the body
touches) and its offset by ``-thickness`` along the limit normals, exactly
the solid :func:`seatkit.export.meshes.thick_shell` writes. Every quad of the
limit surface tessellated at ``level`` becomes one 27-node (triquadratic)
hexahedron per layer. Its nine in-plane nodes are the quad's corners, edge
midpoints and centre on the *limit surface*: one Catmull-Clark step refines
each level-``level`` quad into four level-``level + 1`` quads whose new
vertices are exactly those points, so the elements are curved like the
surface (quadratic geometry). The corner nodes are the level-``level``
limit points; the edge and centre nodes are the level-``level + 1`` ones,
slid along the surface to the middle of their quad (:func:`_even_nodes`).

Through the thickness, ``layers`` elements stack; their nodes lie on the
offset sheets ``X - s N`` for ``s = 0, t / (2 layers), ..., t``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ShellMesh", "element_normals", "plate_quads9", "quad9_shape", "surface_quads9"]

#: Reference (x, y) of the nine in-plane nodes of a quadratic quad, in the
#: column order of ``quads9``: the corners c0..c3 (counter-clockwise seen
#: from the body side), the midpoints of c0c1, c1c2, c2c3, c3c0, the centre.
_IN_PLANE = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0], [1, 0.5], [0.5, 1], [0, 0.5], [0.5, 0.5]])


def _lagrange(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 1-D quadratic Lagrange basis on nodes 0, 1/2, 1 and its derivative, (k, 3) each."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    values = np.concatenate([2 * (s - 0.5) * (s - 1), -4 * s * (s - 1), 2 * s * (s - 0.5)], axis=1)
    slopes = np.concatenate([4 * s - 3, -8 * s + 4, 4 * s - 1], axis=1)
    return values, slopes


def quad9_shape(x, y) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Values and x, y derivatives (k, 9) of the biquadratic basis at reference points (k,)."""
    col = np.rint(_IN_PLANE * 2).astype(np.int64)  # 0, 1, 2 per direction
    vx, dx = _lagrange(x)
    vy, dy = _lagrange(y)
    return vx[:, col[:, 0]] * vy[:, col[:, 1]], dx[:, col[:, 0]] * vy[:, col[:, 1]], vx[:, col[:, 0]] * dy[:, col[:, 1]]


def element_normals(vertices, quads9) -> np.ndarray:
    """(n, 3) unit normals of the biquadratic surface, averaged over the quads at each node.

    Where the elements resolve the surface this is its limit normal; where
    the limit surface curls tighter than one element (a lip at the floor)
    the limit normal can point against the element's own orientation, and
    an offset along it would turn the element inside out.
    """
    V = np.asarray(vertices, dtype=np.float64)
    q = np.asarray(quads9, dtype=np.int64)
    _, dx, dy = quad9_shape(_IN_PLANE[:, 0], _IN_PLANE[:, 1])  # at the element's own nodes
    tx = np.einsum("kj,qjc->qkc", dx, V[q])
    ty = np.einsum("kj,qjc->qkc", dy, V[q])
    n = np.cross(tx, ty)  # (q, 9, 3), length: the area element
    acc = np.zeros_like(V)
    np.add.at(acc, q.ravel(), n.reshape(-1, 3))
    length = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, length, out=np.zeros_like(acc), where=length > 0)


def surface_quads9(control_mesh, level: int):
    """The limit surface at ``level + 1`` and its nodes grouped as level-``level`` quadratic quads.

    Returns
    -------
    surface : seatkit.model.Surface
        The tessellation at ``level + 1`` (positions and limit normals of every node).
    quads9 : (q, 9) int64
        For each quad of the level-``level`` tessellation, its nine nodes
        (columns as :data:`_IN_PLANE`), vertex ids of ``surface``.
    """
    from seatkit.subdivision import limit_surface

    coarse = limit_surface(control_mesh, level=level)
    fine = limit_surface(control_mesh, level=level + 1)
    nv, nq = len(coarse.vertices), len(coarse.faces)
    fq = np.asarray(fine.faces, dtype=np.int64)
    # One Catmull-Clark step numbers the child vertices: the parent's
    # vertices, then one per parent face (its centre), then one per edge.
    centre_col = (fq >= nv) & (fq < nv + nq)
    corner_col = fq < nv
    ok = (
        len(fine.vertices) >= nv + nq
        and np.allclose(fine.vertices[:nv], coarse.vertices, atol=1e-9)
        and (centre_col.sum(axis=1) == 1).all()
        and (corner_col.sum(axis=1) == 1).all()
    )
    if not ok:  # pragma: no cover - a change of the subdivision's vertex order
        msg = "the level-(L+1) tessellation does not refine the level-L one as expected (vertex order changed?)"
        raise RuntimeError(msg)
    # rotate every child quad so that its corner comes first: [corner, mid, centre, mid]
    shift = np.argmax(corner_col, axis=1)
    rows = np.arange(len(fq))[:, None]
    child = fq[rows, (shift[:, None] + np.arange(4)) % 4]
    parent = child[:, 2] - nv
    if not (centre_col[rows[:, 0], (shift + 2) % 4]).all():  # pragma: no cover
        msg = "a refined quad's centre vertex is not opposite its corner"
        raise RuntimeError(msg)
    cq = np.asarray(coarse.faces, dtype=np.int64)
    local = np.argmax(cq[parent] == child[:, [0]], axis=1)  # which corner of the parent
    if not (cq[parent, local] == child[:, 0]).all():  # pragma: no cover
        msg = "a refined quad's corner is not a corner of its parent quad"
        raise RuntimeError(msg)
    quads9 = np.empty((nq, 9), np.int64)
    quads9[:, :4] = cq
    quads9[parent, 4 + local] = child[:, 1]  # midpoint of (c_i, c_i+1)
    quads9[:, 8] = nv + np.arange(nq)
    return _even_nodes(fine, quads9), quads9


def _even_nodes(surface, quads9):
    """The surface with its edge-midpoint and centre nodes slid to the middle of their quads.

    Catmull-Clark's parametrisation is uneven near boundaries and unevenly
    sized cage faces: a level-``L + 1`` vertex can sit at a quarter of its
    level-``L`` edge, where a quadratic element's Jacobian vanishes (the
    quarter-point singularity) and beyond which it folds. Each such node
    keeps its height over the chord (the surface's bulge, along its limit
    normal) and moves to the chord's midpoint (the quad's blended centre for
    the centre node): the element stays curved like the surface, with evenly
    spaced nodes. Corners are untouched.
    """
    from dataclasses import replace

    V = np.array(surface.vertices, dtype=np.float64)
    N = np.asarray(surface.normals, dtype=np.float64)
    q = quads9
    corners = V[q[:, :4]]
    for i in range(4):
        m = q[:, 4 + i]
        chord = 0.5 * (corners[:, i] + corners[:, (i + 1) % 4])
        # a mid node is shared by two quads: both compute the same chord
        V[m] = chord + np.einsum("ki,ki->k", V[m] - chord, N[m])[:, None] * N[m]
    c = q[:, 8]
    blend = 0.5 * V[q[:, 4:8]].sum(axis=1) - 0.25 * corners.sum(axis=1)
    V[c] = blend + np.einsum("ki,ki->k", V[c] - blend, N[c])[:, None] * N[c]
    return replace(surface, vertices=V)


def plate_quads9(nx: int, ny: int, size_x: float, size_y: float):
    """A flat rectangular ``nx`` by ``ny`` grid of quadratic quads in the x-z plane (normal +Y).

    Returns
    -------
    vertices : ((2 nx + 1) (2 ny + 1), 3) float64
    normals : same shape, all +Y
    quads9 : (nx ny, 9) int64
    """
    xs = np.linspace(0.0, size_x, 2 * nx + 1)
    zs = np.linspace(0.0, size_y, 2 * ny + 1)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    vertices = np.stack([X.ravel(), np.zeros(X.size), Z.ravel()], axis=1)
    normals = np.tile([0.0, 1.0, 0.0], (len(vertices), 1))
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    i, j = 2 * i.ravel(), 2 * j.ravel()
    # counter-clockwise seen from +Y: x then -z is clockwise, so walk along z first
    node = lambda di, dj: (i + di) * (2 * ny + 1) + (j + dj)  # noqa: E731
    ref = _IN_PLANE * 2
    # a quad's local (x, y) are (z, x) of the plate so that x cross y = +Y
    quads9 = np.stack([node(int(b), int(a)) for a, b in ref], axis=1)
    return vertices, normals, quads9


@dataclass
class ShellMesh:
    """Quadratic hexahedra of a shell and how they relate to its surface.

    Attributes
    ----------
    nodes : (N, 3) float64
        Node positions, m. Node ``k * n_surface + s`` is surface node ``s``
        on sheet ``k`` (``k = 0`` the offset sheet, ``2 layers`` the surface).
    elements : (27, E) int64
        Node ids of each hexahedron in scikit-fem's ElementHex2 order.
    n_surface : int
        Nodes per sheet.
    sheets : int
        Number of node sheets (``2 layers + 1``).
    quads9 : (q, 9) int64
        The surface's quadratic quads (element ``l q + f`` is quad ``f`` in layer ``l``).
    thickness : float
        m.
    """

    nodes: np.ndarray
    elements: np.ndarray
    n_surface: int
    sheets: int
    quads9: np.ndarray
    thickness: float

    @classmethod
    def extrude(cls, vertices, normals, quads9, thickness: float, layers: int = 1) -> "ShellMesh":
        """Hexahedra between ``vertices`` and ``vertices - thickness * normals``."""
        import skfem

        V = np.asarray(vertices, dtype=np.float64)
        N = np.asarray(normals, dtype=np.float64)
        q9 = np.asarray(quads9, dtype=np.int64)
        sheets = 2 * int(layers) + 1
        depth = thickness * (1.0 - np.arange(sheets) / (sheets - 1))  # sheet 0 at -t, last at 0
        nodes = (V[None, :, :] - depth[:, None, None] * N[None, :, :]).reshape(-1, 3)
        ref = skfem.ElementHex2.doflocs  # (27, 3) reference coordinates of the local nodes
        lookup = {tuple(r): c for c, r in enumerate(_IN_PLANE.tolist())}
        col = np.array([lookup[(float(x), float(y))] for x, y, _ in ref])
        dz = np.rint(ref[:, 2] * 2).astype(np.int64)  # 0, 1, 2 sheets up from the element's bottom
        n = len(V)
        per_layer = [q9[:, col].T + (2 * layer + dz)[:, None] * n for layer in range(int(layers))]
        elements = np.concatenate(per_layer, axis=1)
        return cls(nodes, elements, n, sheets, q9, float(thickness))

    @property
    def top(self) -> np.ndarray:
        """Node ids of the designed surface (the sheet the body touches)."""
        return (self.sheets - 1) * self.n_surface + np.arange(self.n_surface)

    @property
    def bottom(self) -> np.ndarray:
        """Node ids of the offset sheet (the underside)."""
        return np.arange(self.n_surface)

    def column(self, surface_nodes) -> np.ndarray:
        """Every node through the thickness under the given surface nodes."""
        s = np.asarray(surface_nodes, dtype=np.int64)
        return (np.arange(self.sheets)[:, None] * self.n_surface + s[None, :]).ravel()

    def skfem_mesh(self):
        """The scikit-fem MeshHex2 (quadratic geometry) of these elements."""
        import skfem

        return skfem.MeshHex2(doflocs=self.nodes.T.copy(), t=self.elements.copy())
