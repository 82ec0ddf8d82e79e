"""The bottom geometry layer: questions about meshes that the templates, refiners and evaluation share.

- :mod:`~seatkit.geometry.closest`: closest points on triangles (Ericson's
  regions) and the triangles around each vertex
- :mod:`~seatkit.geometry.skin`: :class:`SkinDistance`, the signed distance to
  a body's closed skin (pseudo-normal sign, winding numbers)
- :mod:`~seatkit.geometry.surface`: :class:`SurfaceQuery`, closest points on
  a tessellated limit surface, and how deep a surface and a body reach into
  each other
- :mod:`~seatkit.geometry.normals`: triangle and vertex normals of triangle
  meshes, vertex normals of quad cages

Only numpy, scipy and :mod:`seatkit.model` below it (tests/test_import_graph.py).
"""

from seatkit.geometry.closest import closest_point_on_triangles, vertex_triangle_rings
from seatkit.geometry.normals import face_normals, quad_vertex_normals, vertex_normals
from seatkit.geometry.skin import SkinDistance
from seatkit.geometry.surface import SurfaceQuery, body_depth_in_surface, surface_depth_in_body

__all__ = [
    "SkinDistance",
    "SurfaceQuery",
    "body_depth_in_surface",
    "closest_point_on_triangles",
    "face_normals",
    "quad_vertex_normals",
    "surface_depth_in_body",
    "vertex_normals",
    "vertex_triangle_rings",
]
