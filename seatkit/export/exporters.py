"""The built-in exporters (registered by the ``seatkit_exporters`` plugin).

Each is an :class:`seatkit.interfaces.Exporter`: ``export(result, directory)``
writes files atomically and returns them by role. Those whose time goes
mostly into importing a big library (usd-core, trimesh) also have
``prepare()``, which imports it: a build calls it in its export worker
process while the design is being computed (the export worker of :mod:`seatkit.workers`).

=========  =====================================================================
name       files
=========  =====================================================================
usd        ``cage.usda``: Catmull-Clark cage with creases, corners, per-face
           body segment; posed bodies coloured by pressure
usdc       ``cage.usdc``: the same as a binary crate file
obj        ``cage.obj``: the control mesh as plain OBJ
surface    ``surface.obj/.ply/.stl/.glb``: the limit surface at the recipe's
           ``surface_level``
shell      ``shell.stl``: a watertight solid of the limit surface,
           ``shell_thickness`` m thick (recipe key, default 0.02 m)
body-ply   ``body.ply`` (``body-1.ply`` ...): each posed body, vertex colours
           from its pressure
structure  ``structure.json/.png``: the shell's structural analysis
           (:mod:`seatkit.structure.build`, imported only when it runs)
=========  =====================================================================
"""

from __future__ import annotations

from pathlib import Path

from seatkit.errors import InputError

__all__ = [
    "DEFAULT_SHELL_THICKNESS",
    "BodyPlyExporter",
    "ObjCageExporter",
    "ShellExporter",
    "StructureExporter",
    "SurfaceExporter",
    "UsdExporter",
    "builtin_exporters",
]

#: Thickness of the fabrication shell, m.
DEFAULT_SHELL_THICKNESS = 0.02
#: Surface level used when a result carries no surface, and no recipe level.
DEFAULT_LEVEL = 3


def _cage(result):
    mesh = result.control_mesh if result.control_mesh is not None else result.initial_mesh
    if mesh is None:
        msg = "the build result holds no control mesh to export"
        raise InputError(msg)
    return mesh


def _surface(result):
    if result.surface is not None:
        return result.surface
    from seatkit.subdivision import limit_surface

    level = int((result.recipe or {}).get("surface_level") or DEFAULT_LEVEL)
    return limit_surface(_cage(result), level=level)


class UsdExporter:
    """The cage as an OpenSubdiv Catmull-Clark USD mesh, with the posed bodies."""

    def __init__(self, fmt: str = "usda"):
        if fmt not in ("usda", "usdc"):
            msg = f"USD format must be 'usda' or 'usdc', got {fmt!r}"
            raise ValueError(msg)
        self.fmt = fmt
        self.name = "usd" if fmt == "usda" else "usdc"
        kind = "text" if fmt == "usda" else "binary"
        self.description = f"cage.{fmt} ({kind} USD): Catmull-Clark cage with creases, bodies coloured by pressure"

    prepare_ahead = True
    #: Writes the cage, the bodies and their importance: the design alone.
    design_only = True

    def prepare(self) -> None:
        """Import usd-core (and load its plugins), ahead of :meth:`export`."""
        from seatkit.export.usd import prepare_usd

        prepare_usd()

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.export.usd import write_usd

        path = write_usd(
            Path(directory) / f"cage.{self.fmt}",
            _cage(result),
            bodies=list(result.bodies or []),
            pressures=list(result.pressures or []),
        )
        return {self.name: path}


class ObjCageExporter:
    """The control mesh as a plain OBJ."""

    name = "obj"
    description = "cage.obj: the Catmull-Clark control mesh (creases only in USD)"

    prepare_ahead = False
    design_only = True

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.export.meshes import write_cage_obj

        return {"cage_obj": write_cage_obj(_cage(result), Path(directory) / "cage.obj")}


class SurfaceExporter:
    """The limit surface as OBJ (quads, normals), PLY, STL and GLB."""

    name = "surface"
    description = "surface.obj/.ply/.stl/.glb: the limit surface at surface_level"

    def __init__(self, formats=(".obj", ".ply", ".stl", ".glb")):
        self.formats = tuple(formats)

    prepare_ahead = False
    design_only = True

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.export.meshes import write_surface

        surface = _surface(result)
        return {
            f"surface_{fmt[1:]}": write_surface(surface, Path(directory) / f"surface{fmt}") for fmt in self.formats
        }


class ShellExporter:
    """A watertight solid of the limit surface for fabrication."""

    name = "shell"
    description = "shell.stl: the limit surface thickened along its normals (recipe key shell_thickness, m)"

    def __init__(self, thickness: float = DEFAULT_SHELL_THICKNESS):
        self.thickness = float(thickness)

    prepare_ahead = True

    def prepare(self) -> None:
        """Import trimesh, ahead of :meth:`export`."""
        import trimesh  # noqa: F401

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.export.meshes import write_shell

        # the thickness the structural analysis used or sized, else the recipe's
        thickness = result.shell_thickness_m or (result.recipe or {}).get("shell_thickness")
        thickness = float(thickness or self.thickness)
        return {"shell_stl": write_shell(_surface(result), thickness, Path(directory) / "shell.stl")}


class BodyPlyExporter:
    """Each posed body as a PLY coloured by its pressure."""

    name = "body-ply"
    description = "body.ply: the posed body with vertex colours from pressure (one file per person)"

    prepare_ahead = False

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.export.meshes import write_body_ply

        out = {}
        bodies = list(result.bodies or [])
        pressures = list(result.pressures or [])
        if len(pressures) != len(bodies):
            msg = f"body-ply needs one pressure per body, got {len(pressures)} for {len(bodies)} bodies"
            raise InputError(msg)
        interface = list(getattr(result, "interface_pressures", None) or [None] * len(bodies))
        for i, (body, pressure) in enumerate(zip(bodies, pressures)):
            stem = "body" if i == 0 else f"body-{i}"
            role = "body_ply" if i == 0 else f"body_ply_{i}"
            out[role] = write_body_ply(body, pressure, Path(directory) / f"{stem}.ply", interface=interface[i])
        return out


class StructureExporter:
    """``structure.json`` and ``structure.png``: will the shell hold its people (docs/structure.md)."""

    name = "structure"
    description = "structure.json/.png: stress, safety factor and deflection of the shell under its people (FEM)"
    #: Runs in the build's process: the analysis it may run needs the result's evaluation, not a pickled copy.
    prepare_ahead = False

    def prepare(self) -> None:
        """Nothing to prepare: scikit-fem is imported when an analysis runs."""

    def export(self, result, directory: Path) -> dict[str, Path]:
        from seatkit.structure.build import _title, analyse_result, write_structure

        analysis = result.structure
        if analysis is None:  # listed as an exporter without the build step: analyse now
            analysis = analyse_result(result)
        return write_structure(analysis, directory, title=_title(result))


def builtin_exporters() -> list:
    """One instance of every built-in exporter."""
    return [
        UsdExporter("usda"),
        UsdExporter("usdc"),
        ObjCageExporter(),
        SurfaceExporter(),
        ShellExporter(),
        BodyPlyExporter(),
    ]
