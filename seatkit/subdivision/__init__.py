"""Catmull-Clark subdivision as sparse operators that match OpenSubdiv.

::

    from seatkit.subdivision import Cage, build_operators, limit_surface
    cage = Cage(vertices, faces, crease_edges=..., crease_sharpness=...)
    ops = build_operators(cage, level=3)     # cached per topology
    refined = ops.refine @ cage.vertices     # OpenSubdiv's refined points
    limit = ops.limit @ cage.vertices        # Far::PrimvarRefiner::Limit
    surface = limit_surface(control_mesh, level=3)

See ``docs/subdivision.md`` for the rules and how they follow OpenSubdiv.
"""

from __future__ import annotations

from seatkit.subdivision.catmull_clark import SubdivisionOperators, build_operators, limit_surface, refine_level
from seatkit.subdivision.limit import limit_masks
from seatkit.subdivision.topology import BOUNDARY_MODES, SHARPNESS_INFINITE, Cage, MeshLevel

__all__ = [
    "BOUNDARY_MODES",
    "SHARPNESS_INFINITE",
    "Cage",
    "MeshLevel",
    "SubdivisionOperators",
    "build_operators",
    "limit_masks",
    "limit_surface",
    "refine_level",
]
