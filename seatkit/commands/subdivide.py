"""``seatkit subdivide``: refine a Catmull-Clark cage (OBJ or USD) as OpenSubdiv does."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

_OUT_FORMATS = (".obj", ".ply", ".stl", ".glb", ".usda", ".usdc")


def register(app: typer.Typer) -> None:
    @app.command()
    def subdivide(
        cage: Path = typer.Argument(
            ..., metavar="CAGE", help="Cage file: .obj, or .usda/.usdc/.usd (creases and corners read from USD)."
        ),
        levels: int = typer.Option(3, "--levels", "-n", min=1, max=6, help="Uniform refinement levels."),
        out: Path = typer.Option(..., "--out", "-o", help=f"Output mesh, by extension: {', '.join(_OUT_FORMATS)}."),
        limit: bool = typer.Option(
            False, "--limit", help="Write the limit positions of the refined vertices instead of the refined points."
        ),
        boundary: Optional[str] = typer.Option(
            None, "--boundary", metavar="MODE",
            help="edge-and-corner (default for OBJ) or edge-only; a USD file's interpolateBoundary is used otherwise.",
        ),
        prim: Optional[str] = typer.Option(
            None, "--prim", help="USD mesh prim path (default: /seatkit/Cage or the first Catmull-Clark mesh)."
        ),
    ) -> None:
        """Refine CAGE N times with OpenSubdiv's Catmull-Clark rules and write the quads (metres).

        Normals in the output are the limit-surface normals.
        """
        import numpy as np

        from seatkit.errors import InputError
        from seatkit.model import Surface
        from seatkit.subdivision import Cage, build_operators

        suffix = out.suffix.lower()
        if suffix not in _OUT_FORMATS:
            msg = f"--out {out}: unknown format {out.suffix!r}; expected one of {', '.join(_OUT_FORMATS)}"
            raise InputError(msg)
        kind = cage.suffix.lower()
        if not cage.exists():
            msg = f"{cage}: no such cage file"
            raise InputError(msg)
        if kind in (".usda", ".usdc", ".usd"):
            from seatkit.export.usd import read_usd_cage

            c = read_usd_cage(cage, prim_path=prim)
        elif kind == ".obj":
            from seatkit.export.meshes import read_obj_cage

            c = read_obj_cage(cage)
        else:
            msg = f"{cage}: unknown cage format {cage.suffix!r}; expected .obj, .usda, .usdc or .usd"
            raise InputError(msg)
        if boundary is not None:
            c = Cage(c.vertices, c.faces, c.crease_edges, c.crease_sharpness, c.corners, c.corner_sharpness, boundary)
        try:
            ops = build_operators(c, levels)  # refuses a refinement past MAX_REFINED_FACES before any work
        except InputError as e:
            raise InputError(f"{cage}: {e}") from None
        P = c.vertices
        points = ops.limit @ P if limit else ops.refine @ P
        surface = Surface(vertices=points, normals=ops.limit_normals(P), faces=ops.faces, level=levels)
        if suffix in (".usda", ".usdc"):
            _write_usd_mesh(out, surface)
        else:
            from seatkit.export.meshes import write_surface

            write_surface(surface, out)
        what = "limit positions" if limit else "refined points"
        typer.echo(
            f"{out}: level {levels}, {len(points)} {what}, {len(ops.faces)} quads "
            f"(cage: {c.n_vertices} vertices, {c.n_faces} faces, {len(c.crease_edges)} creases, "
            f"{len(c.corners)} corners, boundary {c.boundary}); extent {np.ptp(points, axis=0).round(4).tolist()} m"
        )


def _write_usd_mesh(path: Path, surface) -> None:
    """The refined mesh as a plain (non-subdivided) USD mesh with normals."""
    import numpy as np
    from pxr import Gf, Usd, UsdGeom, Vt

    from seatkit.io import atomic_path

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/seatkit")
    stage.SetDefaultPrim(root.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/seatkit/Refined")
    V = np.asarray(surface.vertices, dtype=np.float32)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(V))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(surface.faces), 4, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(surface.faces, np.int32).reshape(-1)))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(surface.normals, np.float32)))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, V.min(0))), Gf.Vec3f(*map(float, V.max(0)))]))
    with atomic_path(path) as tmp:
        stage.GetRootLayer().Export(str(tmp))
