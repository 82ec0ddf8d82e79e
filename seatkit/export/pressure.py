"""The files of ``seatkit pressure`` for a pressure field on a body: the coloured PLY and the PNG.

(``pressure.npz``, the field's data, is :func:`seatkit.pressure.field.write_npz`.)
The colours are the build's: :func:`seatkit.export.meshes.pressure_colors` for
the PLY, the report's scale and layout for the PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from seatkit.export.meshes import pressure_colors
from seatkit.export.report import write_importance_png
from seatkit.io import atomic_write

__all__ = ["write_ply", "write_pressure_png"]


def write_ply(path, body, field) -> Path:
    """Binary PLY of the body coloured by pressure (with a ``pressure`` vertex property in Pa).

    The colours are the build's ``body.ply`` ones (:func:`seatkit.export.meshes.pressure_colors`:
    magma reversed, 0 Pa light, the peak dark).
    """
    path = Path(path)
    n, m = len(body.vertices), len(body.faces)
    colors = pressure_colors(field.pressure)
    vdtype = np.dtype(
        [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1"), ("pressure", "<f4")]
    )
    vert = np.empty(n, dtype=vdtype)
    vert["x"], vert["y"], vert["z"] = body.vertices.T
    vert["red"], vert["green"], vert["blue"] = colors[:, :3].T
    vert["pressure"] = field.pressure
    fdtype = np.dtype([("count", "u1"), ("v", "<i4", (3,))])
    face = np.empty(m, dtype=fdtype)
    face["count"] = 3
    face["v"] = body.faces
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment seatkit pressure (Pa) on the posed body\n"
        f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float pressure\n"
        f"element face {m}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path, "wb") as fh:
        fh.write(header.encode("ascii"))
        fh.write(vert.tobytes())
        fh.write(face.tobytes())
    return path


def write_pressure_png(path, body, field, *, title: str | None = None) -> Path:
    """Pressure map of the body: the build's ``pressure.png`` (front, back, from below).

    The report's colour scale (light at 0 Pa, dark at the peak) and layout,
    the bar from 0 to the peak (:func:`seatkit.export.report.write_importance_png`).
    """
    return write_importance_png(path, body, field.pressure, title=title)
