"""A third-party seatkit plugin with a refiner and an exporter.

``relax`` smooths the parts of a cage that hold little of the body with
Taubin's non-shrinking smoothing (SIGGRAPH 1995): each pass moves every free
control point (neither on the ground ring nor fixed) towards the mean of its
neighbours by ``weight`` times one minus its importance
(``ControlMesh.vertex_weights`` scaled to a maximum of 1), then back by a
slightly larger share (plain Laplacian smoothing would shrink the cage
towards the floor). Control points under the body barely move; the ones of
the walls and of the unloaded rim even out, none by more than ``max_move``
(on the coarse chair cage the rim's corners would otherwise move 18 cm).

``profile-svg`` draws the cage's edges seen from the side, the front or
above (``view``) into ``profile-<view>.svg``, ``scale`` pixels per metre,
the floor as a grey line.

See "Writing a refiner or an exporter" in seatkit's docs/plugins.md: both
declare their options (``seatkit.options.Option``); a recipe's ``params``
for them are checked against those before any geometry, and the exporter is
called with its checked options.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

import seatkit
from seatkit.io import atomic_write
from seatkit.options import Option


def cage_edges(faces: np.ndarray) -> np.ndarray:
    """The unique edges ``(e, 2)`` of quads ``faces`` ``(m, 4)``, smaller index first."""
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(pairs, axis=1), axis=0)


#: Taubin's pass-band frequency k_PB = 1/lambda + 1/mu (0.1: his suggested value).
PASS_BAND = 0.1


class RelaxRefiner:
    """Even out the free control points that hold little of the body."""

    name = "relax"
    description = "Laplacian smoothing of the free control points, weighted by how little of the body each holds (example plugin)"
    options = {
        "iterations": Option("count", "smoothing passes", 3, "", 0, 100),
        "weight": Option("number", "Taubin's lambda: share of the way to the neighbours' mean a point with no importance moves per pass", 0.5, "1", 0.0, 0.9),
        "max_move": Option("number", "farthest a control point moves in all", 0.02, "m", 0.0, 0.2),
    }

    def refine(self, mesh, bodies: Sequence[Any], pressures: Sequence[Any], *, params: Mapping[str, Any] | None = None):
        from seatkit.params import refiner_params

        p = refiner_params(self.name, self.options, params)
        vertices = np.array(mesh.vertices, dtype=np.float64)
        n = len(vertices)
        edges = cage_edges(np.asarray(mesh.faces))
        # neighbour counts and the sum of neighbour positions, from the edge list
        degree = np.bincount(edges.ravel(), minlength=n).astype(np.float64)
        importance = np.asarray(mesh.vertex_weights, dtype=np.float64)
        importance = importance / max(float(importance.max()), 1e-12)
        free = ~(np.asarray(mesh.fixed, bool) | np.asarray(mesh.ground, bool))
        share = np.where(free, 1.0 - importance, 0.0)[:, None]
        lam = p["weight"]
        mu = 1.0 / (PASS_BAND - 1.0 / lam) if lam > 0 else 0.0  # Taubin's shrink-free second step (negative)
        for _ in range(p["iterations"]):
            for factor in (lam, mu):
                total = np.zeros_like(vertices)
                np.add.at(total, edges[:, 0], vertices[edges[:, 1]])
                np.add.at(total, edges[:, 1], vertices[edges[:, 0]])
                mean = total / np.maximum(degree, 1.0)[:, None]
                vertices = vertices + factor * share * (mean - vertices)
        # no point farther than max_move from where it was
        shift = vertices - mesh.vertices
        length = np.linalg.norm(shift, axis=1)
        vertices = mesh.vertices + shift * np.minimum(1.0, p["max_move"] / np.maximum(length, 1e-300))[:, None]
        # the floor is an obstacle: no point goes below it (or lower than it was)
        vertices[:, 1] = np.maximum(vertices[:, 1], np.minimum(mesh.vertices[:, 1], 0.0))
        moved = np.linalg.norm(vertices - mesh.vertices, axis=1)
        out = mesh.with_vertices(vertices)
        out.meta["relax"] = {"params": p, "largest_move_m": float(moved.max()), "moved_points": int((moved > 0).sum())}
        return out


#: Plan axes of each view: (horizontal, vertical) coordinate indices.
VIEWS = {"side": (2, 1), "front": (0, 1), "top": (0, 2)}


class ProfileSvgExporter:
    """Draw the cage's edges in one view as an SVG file."""

    name = "profile-svg"
    description = "the cage's edges seen from the side, the front or above, as profile-<view>.svg (example plugin)"
    prepare_ahead = False  # nothing heavy to import
    options = {
        "view": Option("choice", "the direction the cage is seen from", "side", choices=tuple(VIEWS)),
        "scale": Option("number", "drawing scale", 400.0, "px/m", 10.0, 10000.0),
    }

    def prepare(self) -> None:
        """Nothing to get ready."""

    def export(self, result, directory: Path, *, options: Mapping[str, Any]) -> dict[str, Path]:
        h, v = VIEWS[options["view"]]
        scale = options["scale"]
        mesh = result.control_mesh
        points = np.asarray(mesh.vertices)[:, [h, v]] * scale
        points[:, 1] *= -1.0 if options["view"] != "top" else 1.0  # SVG's y grows downwards; up is up
        margin = 10.0
        lo = points.min(axis=0) - margin
        size = points.max(axis=0) + margin - lo
        points -= lo
        lines = [
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{size[0]:.1f}" height="{size[1]:.1f}" viewBox="0 0 {size[0]:.1f} {size[1]:.1f}">',
            f'<title>{mesh.meta.get("template", "cage")}: {options["view"]} view, {scale:g} px/m</title>',
        ]
        if options["view"] != "top":
            floor = -lo[1]  # y = 0 in the drawing
            lines.append(f'<line class="floor" x1="0" y1="{floor:.2f}" x2="{size[0]:.1f}" y2="{floor:.2f}" stroke="#999" stroke-width="1"/>')
        for a, b in cage_edges(np.asarray(mesh.faces)):
            (x1, y1), (x2, y2) = points[a], points[b]
            lines.append(f'<line class="edge" x1="{x1:.2f}" y1="{y1:.2f}" x2="{x2:.2f}" y2="{y2:.2f}" stroke="#1f4e79" stroke-width="1.2"/>')
        lines.append("</svg>")
        path = Path(directory) / f"profile-{options['view']}.svg"
        with atomic_write(path, "w") as fh:
            fh.write("\n".join(lines) + "\n")
        return {"profile": path}


@seatkit.hookimpl
def seatkit_register_refiners():
    return [RelaxRefiner()]


@seatkit.hookimpl
def seatkit_register_exporters():
    return [ProfileSvgExporter()]
