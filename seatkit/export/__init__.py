"""Writers of build results: USD, OBJ cage, limit surface meshes, the
watertight shell and the pressure-coloured body (see :mod:`.exporters`).

Heavy libraries (usd-core, trimesh, matplotlib) are imported when a writer
runs, not when this package is imported.
"""

from __future__ import annotations

from seatkit.export.exporters import (
    BodyPlyExporter,
    ObjCageExporter,
    ShellExporter,
    SurfaceExporter,
    UsdExporter,
    builtin_exporters,
)

__all__ = [
    "BodyPlyExporter",
    "ObjCageExporter",
    "ShellExporter",
    "SurfaceExporter",
    "UsdExporter",
    "builtin_exporters",
]
