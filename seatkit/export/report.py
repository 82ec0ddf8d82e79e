"""The visual report of a build: PNG renders and an offline HTML page.

Two exporters (registered by the ``seatkit_exporters`` plugin):

``report-png``
    ``pressure.png``  the body coloured by its importance pressure (the
    "supported everywhere" solution, kPa), front and back, with a colour bar;
    ``cage.png``  the control mesh over the body: front, side, three-quarter;
    ``surface.png``  the limit surface with the body, the body coloured by its
    contact pressure on that surface when the evaluation computed it;
    ``comparison.png``  our surface beside the flat-patch baseline, both with
    their contact pressure on one colour scale, and the paper's Table 1
    figures (only when the build evaluated a baseline);
    ``interface.png``  the body coloured by its interface pressure on our
    surface from the soft-tissue model (only when the evaluation computed it).
``report-html``
    ``report.html``  an interactive 3D view (plotly ``Mesh3d``: the body with
    pressure colours, the limit surface translucent, the cage as lines, a
    switch to the baseline) and the metrics table. plotly.js is embedded, so
    the file opens with no network.

The pictures are drawn with :mod:`seatkit.picture` (a numpy z-buffer, the
colour scale and bar, the sheet layout, PIL), not matplotlib, to stay within
the build's time budget (see docs/performance.md, "The stages alone"). Both exporters draw what the result holds:
without an evaluation (``metrics`` empty) the contact pressure, the baseline
and the table are left out, never invented.

What they read from a :class:`~seatkit.model.BuildResult`:
``bodies``, ``pressures`` (importance maps), ``control_mesh``, ``surface``,
``metrics["ours"]`` / ``metrics["baseline"]`` (lists of per-person dicts
with the keys of :mod:`seatkit.evaluate`), ``metrics["baseline_template"]``,
``contact_pressures`` (a PressureField per person on our surface) and
``baseline`` (a :class:`~seatkit.model.Baseline`: ``control_mesh``, ``surface``,
``contact_pressures``).
"""

from __future__ import annotations

import base64
import html
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from seatkit import picture as pic
from seatkit.cache import LRUCache, content_key
from seatkit.errors import InputError
from seatkit.geometry.normals import kept_vertex_normals, vertex_normals
from seatkit.io import atomic_write, write_bytes_atomic
from seatkit.picture import draw as pic_draw
from seatkit.picture import raster as rs

__all__ = [
    "PNG_FILES",
    "ReportHtmlExporter",
    "ReportPngExporter",
    "pressure_rgb",
    "render_pngs",
    "report_exporters",
    "write_report_html",
]

#: The PNG files of ``report-png`` by role (comparison only with a baseline).
PNG_FILES = {
    "report_pressure_png": "pressure.png",
    "report_cage_png": "cage.png",
    "report_surface_png": "surface.png",
    "report_comparison_png": "comparison.png",
    "report_interface_png": "interface.png",
}

#: Size of one rendered view, pixels.
PANEL_WIDTH, PANEL_HEIGHT = 360, 440
#: Camera (azimuth, elevation) of each named view, degrees (see :func:`seatkit.picture.raster.view_rotation`).
VIEWS = {
    "front": (0.0, 0.0),
    "back": (180.0, 0.0),
    "side": (-90.0, 0.0),
    "three-quarter": (35.0, 20.0),
    "from below": (160.0, -50.0),
}
BACKGROUND = pic.BACKGROUND
#: What the pictures call the paper's model on the body alone, and on the design (both relative importance, Pa).
IMPORTANCE_TITLE = "Relative importance (the paper's model, supported everywhere; not an interface pressure)"
CONTACT_LABEL = "relative importance on the design (paper's model)"
#: What the report says of a shared design's "own design" column (seatkit.sitters).
SHARING_NOTE = (
    "One seat for all the sitters: each sitter's figures on it (ours), on the flat patch fitted to all of them, "
    "and on the design made for that sitter alone with the same template and seed (own design): the cost of sharing."
)

#: What the report says of the Table 1 figures.
TABLE1_NOTE = (
    "The paper's Table 1 quantities: its model re-solved on the body's contact with each design; "
    "avg. press. and max. press. are relative importance (Pa), not interface pressure."
)
#: What the report says of the soft-tissue figures.
INTERFACE_NOTE = (
    "Soft tissue over the skeleton (an elastic Winkler foundation, E from the literature) on the rigid design, "
    "with Coulomb friction: an interface pressure comparable with a pressure mat on a hard seat. The pressures "
    "above and in the pictures are the paper's model: a relative importance that shares the weight, in Pa but "
    "not a measured pressure (docs/physics.md)."
)

#: Body colour where no pressure is drawn; surface and cage colours.
BODY_RGB = np.array([0.86, 0.79, 0.72])
SURFACE_RGB = np.array([0.42, 0.60, 0.80])
BASELINE_RGB = np.array([0.80, 0.58, 0.40])
CAGE_FACE_RGB = np.array([0.55, 0.70, 0.90])
CAGE_EDGE = (25, 70, 160)
CAGE_EDGE_HIDDEN = (140, 165, 215)
TEXT = pic.TEXT
#: Opacity of the limit surface drawn with the body, of the cage faces.
SURFACE_ALPHA, CAGE_ALPHA = 0.55, 0.22
#: plotly's name of the pressure colour scale, and whether it is reversed:
#: magma reversed, light at zero and dark at the peak, as body.ply.
COLORSCALE, COLORSCALE_REVERSED = "Magma", True
#: Size of the HTML report's meshes: coordinates are rounded to this, m.
HTML_ROUNDING = 1e-3
#: Size of the HTML report's 3D view: as wide as the page up to this, CSS
#: pixels, and this fraction of the window's height (within the bounds), so
#: that the view and the start of the figures fit one screen.
HTML_VIEW_MAX_WIDTH, HTML_VIEW_VH, HTML_VIEW_HEIGHT_PX = 960, 72, (420, 760)
#: Opacity of the limit surfaces in the HTML view: light enough to show the
#: contact pressure on the body through the seat and the back.
HTML_SURFACE_OPACITY = 0.35


# ----------------------------------------------------------------------------- colours


def _colorscale_stops() -> tuple[np.ndarray, np.ndarray]:
    """Positions (s,) and RGB (s, 3) in [0, 1] of the pressure colour scale
    (:data:`seatkit.picture.PRESSURE_SCALE`: plotly's :data:`COLORSCALE`)."""
    return pic.PRESSURE_SCALE.positions, pic.PRESSURE_SCALE.colours


def pressure_rgb(pressure: np.ndarray, vmax: float) -> np.ndarray:
    """Colours of pressures on the report's colour scale.

    Parameters
    ----------
    pressure : (n,) float64
        Pa.
    vmax : float
        Pressure at the dark end of the scale, Pa (zero at the light end).

    Returns
    -------
    (n, 3) float64
        RGB in [0, 1].
    """
    return pic.PRESSURE_SCALE.rgb(pressure, 0.0, vmax)


def contact_scale(*fields) -> float:
    """Top of the contact-pressure colour scale, Pa (0 with no loaded vertex).

    The highest pressure above :data:`seatkit.evaluate.LOADED_PRESSURE` over
    every given field: a picture that compares designs draws both on one
    scale that reaches both peaks, so no design's peak is clipped (and a
    peak that looks darker is higher).
    """
    from seatkit.evaluate import LOADED_PRESSURE

    loaded = [f[f > LOADED_PRESSURE] for f in fields if f is not None]
    loaded = np.concatenate(loaded) if loaded else np.zeros(0)
    return float(loaded.max()) if loaded.size else 0.0


# ----------------------------------------------------------------------------- the scene


def _tri(quads: np.ndarray) -> np.ndarray:
    from seatkit.export.meshes import quads_to_triangles

    return quads_to_triangles(np.asarray(quads, dtype=np.int64))


@dataclass
class _Mesh:
    vertices: np.ndarray
    faces: np.ndarray  # triangles
    normals: np.ndarray
    closed: bool = False


#: The bodies' rasters in the views framed on them alone, by the bodies' mesh (a digest) and the
#: view: a build's pictures draw the same bodies in the same views in several parts
#: (``pressure.png`` ahead, ``surface.png`` and ``interface.png`` later). About 3 MB each.
_BODY_RASTERS = LRUCache(maxsize=5)


@dataclass
class _Scene:
    """The meshes of a result, merged over people, with cached rasters."""

    body: _Mesh
    importance: np.ndarray  # (n,) Pa, all people
    contact: np.ndarray | None  # (n,) Pa on our surface, or None
    surface: _Mesh | None
    cage: object | None  # ControlMesh
    baseline_surface: _Mesh | None
    baseline_contact: np.ndarray | None
    baseline_cage: object | None
    baseline_name: str
    metrics: dict
    surface_level: int = 0
    interface: np.ndarray | None = None  # (n,) Pa, the soft-tissue model on our surface, or None
    people: list = field(default_factory=list)  # one label per person (pose, body, mass)
    _rasters: dict = field(default_factory=dict)
    _frames: dict = field(default_factory=dict)
    _body_digest: bytes | None = None

    def frame(self, view: str, family: str) -> rs.Frame:
        """The frame of a view that shows the body only or the whole scene."""
        key = (view, family)
        if key not in self._frames:
            rot = rs.view_rotation(*VIEWS[view])
            pts = [self.body.vertices]
            if family == "scene":
                pts += [m.vertices for m in (self.surface, self.baseline_surface) if m is not None]
                pts += [c.vertices for c in (self.cage, self.baseline_cage) if c is not None]
            self._frames[key] = rs.fit_frame(pts, rot, PANEL_WIDTH, PANEL_HEIGHT)
        return self._frames[key]

    def raster(self, name: str, view: str, family: str) -> rs.Raster:
        key = (name, view, family)
        if key not in self._rasters:
            mesh = self.mesh(name)
            draw = lambda: rs.rasterize(self.frame(view, family), mesh.vertices, mesh.faces, cull_back=mesh.closed)  # noqa: E731
            if name == "body" and family == "body":
                # framed on the bodies alone: the same raster for every scene of these bodies in this
                # process (pressure.png, drawn ahead by a build's helper, and the parts it draws later)
                self._rasters[key] = _BODY_RASTERS.get((self._body_key(), view), draw)
            else:
                self._rasters[key] = draw()
        return self._rasters[key]

    def _body_key(self) -> bytes:
        """A digest of the bodies' mesh (vertices and faces): what their views framed on them alone show."""
        if self._body_digest is None:
            self._body_digest = content_key(self.body.vertices, self.body.faces)
        return self._body_digest

    def mesh(self, name: str) -> _Mesh:
        if name == "body":
            return self.body
        if name == "surface":
            return self.surface
        if name == "baseline_surface":
            return self.baseline_surface
        cage = self.cage if name == "cage" else self.baseline_cage
        v = np.asarray(cage.vertices, dtype=np.float64)
        f = _tri(cage.faces)
        return _Mesh(v, f, vertex_normals(v, f))

    def layer(self, name: str, view: str, family: str, rgb: np.ndarray, alpha: float = 1.0):
        """(raster, shaded image, alpha) of a mesh with per-vertex or uniform colours."""
        mesh = self.mesh(name)
        ra = self.raster(name, view, family)
        colors = np.broadcast_to(np.asarray(rgb, dtype=np.float64), mesh.vertices.shape)
        lit = rs.light_vertices(colors, mesh.normals, self.frame(view, family).rotation)
        return ra, ra.shade(lit), alpha


def _body_scene(body: _Mesh, importance: np.ndarray) -> _Scene:
    """A scene of the bodies and their importance pressure alone: no design, no evaluation."""
    return _Scene(
        body=body, importance=importance, contact=None, surface=None, cage=None,
        baseline_surface=None, baseline_contact=None, baseline_cage=None, baseline_name="", metrics={},
    )


def _surface_mesh(surface) -> _Mesh | None:
    if surface is None:
        return None
    faces = _tri(surface.faces)
    v = np.asarray(surface.vertices, dtype=np.float64)
    normals = np.asarray(surface.normals, dtype=np.float64)
    if normals.shape != v.shape:
        normals = vertex_normals(v, faces)
    return _Mesh(v, faces, normals)


def _concat_fields(fields, n_per_body) -> np.ndarray | None:
    """One (n,) pressure array over all people, or None when any is missing."""
    if not fields or len(fields) != len(n_per_body) or any(f is None for f in fields):
        return None
    arrays = [np.asarray(getattr(f, "pressure", f), dtype=np.float64) for f in fields]
    if any(a.shape != (n,) for a, n in zip(arrays, n_per_body)):
        return None
    return np.concatenate(arrays)


def _scene(result, *, body_only: bool = False) -> _Scene:
    """The scene of a result; ``body_only``: its bodies and importance alone (what :func:`draw_early_pngs` draws)."""
    bodies = list(result.bodies or [])
    if not bodies:
        msg = "the build result holds no body to draw in the report"
        raise InputError(msg)
    sizes = [len(b.vertices) for b in bodies]
    offsets = np.cumsum([0, *sizes[:-1]])
    if len(bodies) == 1:  # the body's own arrays: its normals as the build's stages computed them
        verts, faces = np.asarray(bodies[0].vertices, dtype=np.float64), np.asarray(bodies[0].faces, dtype=np.int64)
        body = _Mesh(verts, faces, kept_vertex_normals(verts, faces), closed=True)
    else:
        verts = np.concatenate([np.asarray(b.vertices, dtype=np.float64) for b in bodies])
        faces = np.concatenate([np.asarray(b.faces, dtype=np.int64) + o for b, o in zip(bodies, offsets)])
        body = _Mesh(verts, faces, vertex_normals(verts, faces), closed=True)
    importance = _concat_fields(list(result.pressures or []), sizes)
    if importance is None:
        msg = f"the report needs one importance pressure per body, got {len(result.pressures or [])} for {len(bodies)} bodies"
        raise InputError(msg)
    if body_only:
        return _body_scene(body, importance)
    base = result.baseline
    metrics = result.metrics or {}
    return _Scene(
        body=body,
        importance=importance,
        contact=_concat_fields(result.contact_pressures, sizes),
        surface=_surface_mesh(result.surface),
        cage=result.control_mesh if result.control_mesh is not None else result.initial_mesh,
        baseline_surface=_surface_mesh(base.surface if base else None),
        baseline_contact=_concat_fields(base.contact_pressures if base else None, sizes),
        baseline_cage=base.control_mesh if base else None,
        baseline_name=str(metrics.get("baseline_template") or "baseline"),
        metrics=metrics,
        surface_level=int(getattr(result.surface, "level", 0) or 0),
        people=person_labels(bodies),
        interface=_concat_fields(getattr(result, "interface_pressures", None), sizes),
    )


def person_labels(bodies) -> list[str]:
    """``person N: POSE, BODY, MASS kg`` for each body, in seat order.

    A body's name is ``BODY:POSE`` (:meth:`seatkit.body.rig.RigModel.pose`);
    one without a colon is shown whole.
    """
    labels = []
    for i, body in enumerate(bodies):
        model, sep, pose = str(getattr(body, "name", "") or "").partition(":")
        what = f"{pose}, {model}" if sep else model
        mass = getattr(body, "mass", None)
        parts = [p for p in (what, f"{float(mass):.0f} kg" if mass else "") if p]
        labels.append(f"person {i + 1}: {', '.join(parts)}" if parts else f"person {i + 1}")
    return labels


# ----------------------------------------------------------------------------- drawing


#: Points tested along each cage edge for visibility, and the depth margin, m
#: (:func:`seatkit.picture.draw.draw_wire`).
CAGE_EDGE_SAMPLES, CAGE_DEPTH_MARGIN = pic_draw.WIRE_SAMPLES, pic_draw.WIRE_DEPTH_MARGIN


def _draw_cage(image, scene: _Scene, name: str, view: str, family: str) -> None:
    """Draw a cage's edges on a PIL image, with the lines its own faces hide removed.

    :func:`seatkit.picture.draw.draw_wire`: edges behind a nearer face of
    the cage are left out, edges behind the body only are drawn light and
    thin (the cage shows through the body), the rest solid; control points
    likewise.
    """
    cage = scene.cage if name == "cage" else scene.baseline_cage
    if cage is None:
        return
    pic_draw.draw_wire(
        image,
        scene.frame(view, family),
        cage.vertices,
        cage.faces,
        scene.raster(name, view, family).depth,
        scene.raster("body", view, family).depth,
        colour=CAGE_EDGE,
        hidden_colour=CAGE_EDGE_HIDDEN,
    )


def _colorbar(height: int, vmax_pa: float, label: str):
    """A vertical colour bar image (PIL) for 0..vmax_pa, ticks in kPa."""
    return pic.colour_bar(height, pic.PRESSURE_SCALE, 0.0, vmax_pa, label, unit=1000.0)


_sheet = pic.sheet
_pil = pic.to_pil


def _write_png(image, path: Path) -> Path:
    return write_bytes_atomic(path, pic.png_bytes(image))


class _PngWriter:
    """Encodes and writes PNGs on a background thread while the next view renders.

    zlib releases the GIL, so on two cores encoding overlaps with rendering.
    :meth:`result` waits for every file and re-raises the first error.
    """

    def __init__(self):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="seatkit-png")
        self._jobs = []

    def __call__(self, image, path: Path) -> Path:
        self._jobs.append(self._pool.submit(_write_png, image, path))
        return path

    def result(self) -> None:
        try:
            for job in self._jobs:
                job.result()
        finally:
            self._pool.shutdown(wait=True)




def _pressure_png(scene: _Scene, path: Path, save=_write_png, title: str | None = None) -> Path:
    vmax = float(scene.importance.max())
    colors = pressure_rgb(scene.importance, vmax)
    panels = []
    for view in ("front", "back", "from below"):
        img = rs.composite(BACKGROUND, [scene.layer("body", view, "body", colors)])
        panels.append((_pil(img), view))
    bar = _colorbar(PANEL_HEIGHT, vmax, "kPa")
    title = f"{title or IMPORTANCE_TITLE}, peak {vmax / 1000:.2f} kPa"
    return save(_sheet(title, panels, colorbar=bar), path)


def write_importance_png(path, body, pressure, *, title: str | None = None) -> Path:
    """The build's ``pressure.png`` for one body and its pressure (Pa), alone.

    What ``seatkit pressure`` writes: front, back and from below, the
    report's colour scale from 0 to the peak, whose value the title prints.
    """
    pressure = np.asarray(getattr(pressure, "pressure", pressure), dtype=np.float64)
    verts, faces = np.asarray(body.vertices, dtype=np.float64), np.asarray(body.faces, dtype=np.int64)
    scene = _body_scene(_Mesh(verts, faces, vertex_normals(verts, faces), closed=True), pressure)
    return _pressure_png(scene, Path(path), title=title)


def _cage_png(scene: _Scene, path: Path, save=_write_png) -> Path:
    panels = []
    for view in ("front", "side", "three-quarter"):
        layers = [scene.layer("body", view, "scene", BODY_RGB)]
        layers.append(scene.layer("cage", view, "scene", CAGE_FACE_RGB, CAGE_ALPHA))
        img = _pil(rs.composite(BACKGROUND, layers))
        _draw_cage(img, scene, "cage", view, "scene")
        panels.append((img, view))
    cage = scene.cage
    title = f"Control mesh over the body: {len(cage.vertices)} control points, {len(cage.faces)} faces"
    return save(_sheet(title, panels), path)


def _body_layer(scene: _Scene, view: str, family: str, contact: np.ndarray | None, vmax: float):
    rgb = pressure_rgb(contact, vmax) if contact is not None and vmax > 0 else BODY_RGB
    return scene.layer("body", view, family, rgb)


def write_surface_png(result, path, *, title: str | None = None) -> Path:
    """``surface.png`` of ``result`` (the body on the limit surface, coloured by its contact pressure) at ``path``; ``title`` leads its title."""
    return _surface_png(_scene(result), Path(path), heading=title)


def _surface_png(scene: _Scene, path: Path, save=_write_png, heading: str | None = None) -> Path:
    contact = scene.contact
    vmax = contact_scale(contact) if contact is not None else 0.0
    panels = []
    for view in ("three-quarter", "side"):
        layers = [_body_layer(scene, view, "scene", contact, vmax), scene.layer("surface", view, "scene", SURFACE_RGB, SURFACE_ALPHA)]
        panels.append((_pil(rs.composite(BACKGROUND, layers)), view))
    title = f"Limit surface (level {scene.surface_level}, {len(scene.surface.faces)} triangles) with the body"
    if heading:
        title = f"{heading}: {title[0].lower()}{title[1:]}"
    if contact is None or vmax <= 0:
        return save(_sheet(title, panels), path)
    below = rs.composite(BACKGROUND, [_body_layer(scene, "from below", "body", contact, vmax)])
    panels.append((_pil(below), "from below (surface hidden)"))
    title += f"; {CONTACT_LABEL}: peak {vmax / 1000:.1f} kPa (the top of the scale)"
    return save(_sheet(title, panels, colorbar=_colorbar(PANEL_HEIGHT, vmax, "kPa")), path)


def _fmt(value, scale: float, unit: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    if isinstance(value, str):
        return value
    return f"{value * scale:.2f} {unit}"


def table_rows(metrics: dict, people=None, *, own: bool = False) -> tuple[list[tuple], list[str]]:
    """The Table 1 figures per person, formatted with units.

    With ``own``, a shared design's rows (``metrics["sharing"]``, one seat
    for several sitters: :mod:`seatkit.sitters`) have a third column: the
    sitter's figures on the design made for that sitter alone.

    ``people`` labels the persons (:func:`person_labels`); default
    ``person N``. The pictures, the HTML report and ``seatkit evaluate``
    all show these rows.

    Returns
    -------
    rows : list of (person, ours, baseline)
        ``ours`` and ``baseline`` list the figures of
        :data:`seatkit.metrics.TABLE`: the paper's Table 1 quantities, then
        the deepest penetration and the deepest body vertex inside the
        furniture (ours, not in the paper);
        a person a design cannot support shows "not supported" (no invented
        figures), a missing value "-".
    labels : list of str
        The quantity names, in the same order.
    """
    from seatkit.metrics import TABLE, columns

    ours = list(metrics.get("ours") or [])
    base = list(metrics.get("baseline") or [])
    cols = columns(TABLE)
    rows = []
    for i in range(max(len(ours), len(base))):
        cells = []
        for person in (ours[i] if i < len(ours) else {}, base[i] if i < len(base) else {}):
            if person and person.get("supported") is False:
                geometric = ("avg_distance_m", "max_penetration_m", "max_body_depth_m")
                cells.append(["not supported" if k not in geometric else _fmt(person.get(k), s, u) for k, _, u, s in cols])
            else:
                cells.append([_fmt(person.get(k), s, u) for k, _, u, s in cols])
        if own and metrics.get("sharing"):
            alone = metrics["sharing"][i] if i < len(metrics["sharing"]) else {}
            figures = alone.get("own") or {}
            cells.append([_fmt(figures.get(k), s, u) if figures else "refused" for k, _, u, s in cols])
        rows.append((people[i] if people and i < len(people) else f"person {i + 1}", *cells))
    return rows, [label for _, label, _, _ in cols]


def _table_head(metrics: dict, baseline: str) -> tuple:
    """Titles of :func:`table_rows`' value columns with ``own``: ours, the baseline, and a shared design's "own design"."""
    return ("ours", baseline, "own design") if metrics.get("sharing") else ("ours", baseline)


def _comparison_png(scene: _Scene, path: Path, save=_write_png) -> Path:
    vmax = contact_scale(scene.contact, scene.baseline_contact)
    designs = (
        ("surface", scene.contact, SURFACE_RGB, "ours"),
        ("baseline_surface", scene.baseline_contact, BASELINE_RGB, scene.baseline_name),
    )
    panels = []
    for name, contact, rgb, label in designs:
        layers = [_body_layer(scene, "three-quarter", "scene", contact, vmax), scene.layer(name, "three-quarter", "scene", rgb, SURFACE_ALPHA)]
        panels.append((_pil(rs.composite(BACKGROUND, layers)), f"{label}: surface"))
    for name, contact, rgb, label in designs:
        if contact is None:
            text = "no contact pressure (the design cannot hold the person)"
            panels.append((_pil(rs.composite(BACKGROUND, [_body_layer(scene, "from below", "body", None, 0.0)])), f"{label}: {text}"))
            continue
        below = rs.composite(BACKGROUND, [_body_layer(scene, "from below", "body", contact, vmax)])
        panels.append((_pil(below), f"{label}: importance, peak {contact.max() / 1000:.1f} kPa"))
    bar = _colorbar(PANEL_HEIGHT, vmax, "kPa") if vmax > 0 else None
    title = f"Ours vs {scene.baseline_name}: importance on one scale (paper's model), up to {vmax / 1000:.1f} kPa"
    return save(_sheet(title, panels, colorbar=bar, table=table_rows(scene.metrics, scene.people, own=True), table_head=_table_head(scene.metrics, scene.baseline_name), columns=2), path)


def _interface_png(scene: _Scene, path: Path, save=_write_png) -> Path:
    """``interface.png``: the body coloured by the soft-tissue model's interface pressure on our surface."""
    vmax = contact_scale(scene.interface)
    panels = []
    for view in ("from below", "back", "side"):
        panels.append((_pil(rs.composite(BACKGROUND, [_body_layer(scene, view, "body", scene.interface, vmax)])), view))
    title = f"Interface pressure on the design (soft tissue over the skeleton; pressure-mat comparable), peak {vmax / 1000:.1f} kPa"
    return save(_sheet(title, panels, colorbar=_colorbar(PANEL_HEIGHT, vmax, "kPa")), path)


#: The report's pictures in parts that share most of their rasters (the same
#: meshes in the same views), drawn each in its own process when a build has
#: idle helper processes (``ReportPngExporter.export_part``). Largest first
#: (CPU of the default build: about 0.27, 0.23 and 0.17 s): a build hands
#: the parts in turn to its idle baseline helper, its export worker (after
#: that worker's own exporters) and its own process (after its own
#: exporters, on the build's critical path), so the last part is the
#: smallest.
PNG_PARTS = (("report_surface_png", "report_comparison_png"), ("report_cage_png",), ("report_pressure_png", "report_interface_png"))


#: The pictures that show only the bodies and their importance pressure: a
#: build with helper processes draws them while it designs
#: (:meth:`ReportPngExporter.export_early`).
EARLY_PNGS = ("report_pressure_png",)


def _importance_key(result) -> str:
    """A digest of what the early pictures show: every body's vertices and faces and its importance pressure."""
    bodies, pressures = list(result.bodies or []), list(result.pressures or [])
    arrays = [a for b in bodies for a in (b.vertices, b.faces)] + [getattr(p, "pressure", p) for p in pressures]
    return f"{len(bodies)} {len(pressures)} {content_key(*arrays).hex()}"


def draw_early_pngs(result) -> dict:
    """The pictures of :data:`EARLY_PNGS`, drawn in memory from the bodies and their importance alone.

    Returns ``{"key": digest of those inputs, "png": {role: PNG bytes}}``;
    :func:`render_pngs` writes the bytes instead of drawing the pictures
    again when the result it is given has the same bodies and importance.
    """
    scene = _scene(result, body_only=True)
    return {"key": _importance_key(result), "png": {"report_pressure_png": _pressure_png(scene, None, lambda image, _: pic.png_bytes(image))}}


def render_pngs(result, directory, roles=None, early=None) -> dict[str, Path]:
    """Write the report's PNG files into ``directory`` and return them by role.

    ``comparison.png`` is written only when the result holds a baseline
    surface; ``cage.png`` and ``surface.png`` only when it holds a cage and a
    surface. ``roles`` (a subset of :data:`PNG_FILES`' keys): only those
    pictures. ``early`` (:func:`draw_early_pngs`): pictures drawn ahead,
    written as they are when they show this result's bodies and importance.
    """
    directory = Path(directory)
    # pictures drawn ahead that this call writes, when they show this result's bodies
    # (the digest only where one is wanted: most parts have none)
    ready = {role: data for role, data in (early or {}).get("png", {}).items() if roles is None or role in roles}
    if ready and early.get("key") != _importance_key(result):
        ready = {}
    if roles is not None and set(roles) <= set(ready):  # nothing left to draw
        return {role: write_bytes_atomic(directory / PNG_FILES[role], ready[role]) for role in PNG_FILES if role in ready}
    scene = _scene(result)
    jobs = [("report_pressure_png", _pressure_png)]
    if scene.cage is not None:
        jobs.append(("report_cage_png", _cage_png))
    if scene.surface is not None:
        jobs.append(("report_surface_png", _surface_png))
        if scene.baseline_surface is not None:
            jobs.append(("report_comparison_png", _comparison_png))
        if scene.interface is not None and contact_scale(scene.interface) > 0:
            jobs.append(("report_interface_png", _interface_png))
    if roles is not None:
        jobs = [job for job in jobs if job[0] in roles]
    return _render(scene, jobs, directory, ready)


def _render(scene: _Scene, jobs, directory: Path, ready=None) -> dict[str, Path]:
    """Draw and write the pictures ``jobs`` lists as ``(role, function)``, in order; those in ``ready`` (role -> PNG bytes) are written as they are."""
    save = _PngWriter()
    out = {}
    try:
        for role, draw in jobs:
            path = directory / PNG_FILES[role]
            out[role] = write_bytes_atomic(path, ready[role]) if ready and role in ready else draw(scene, path, save)
    finally:
        save.result()
    return out


# ----------------------------------------------------------------------------- HTML


def _typed(array: np.ndarray, dtype: str) -> dict:
    """A plotly.js typed-array spec (base64 little-endian), compact in JSON."""
    arr = np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
    code = {"float32": "f4", "float64": "f8", "int32": "i4", "uint32": "u4", "uint16": "u2", "uint8": "u1"}[arr.dtype.name]
    return {"dtype": code, "bdata": base64.b64encode(arr.tobytes()).decode("ascii")}


def _mesh_trace(vertices, faces, *, name: str, visible: bool, **style) -> dict:
    v = np.round(np.asarray(vertices, dtype=np.float64) / HTML_ROUNDING) * HTML_ROUNDING
    f = np.asarray(faces, dtype=np.int64)
    index_type = "uint16" if len(v) < 2**16 else "uint32"
    return {
        "type": "mesh3d",
        "name": name,
        "visible": visible,
        "showlegend": True,
        "x": _typed(v[:, 0], "float32"),
        "y": _typed(v[:, 1], "float32"),
        "z": _typed(v[:, 2], "float32"),
        "i": _typed(f[:, 0], index_type),
        "j": _typed(f[:, 1], index_type),
        "k": _typed(f[:, 2], index_type),
        "hoverinfo": "name",
        **style,
    }


def _pressure_trace(scene: _Scene, pressure: np.ndarray, vmax: float, *, name: str, visible: bool, title: str) -> dict:
    from seatkit.evaluate import LOADED_PRESSURE

    # unloaded vertices (no contact) are exactly 0 and drawn in the body's
    # colour, loaded ones on the pressure scale: the contact patches stand
    # out from the skin instead of a pale scale colour covering the body
    kpa = np.where(pressure > LOADED_PRESSURE, np.round(pressure / 1000.0, 3), 0.0)
    cmax = max(round(vmax / 1000.0, 3), float(kpa.max()))
    return _mesh_trace(
        scene.body.vertices,
        scene.body.faces,
        name=name,
        visible=visible,
        intensity=_typed(kpa, "float32"),
        intensitymode="vertex",
        colorscale=_plotly_colorscale(unloaded=LOADED_PRESSURE / 1000.0 / cmax if cmax > 0 else None),
        cmin=0.0,
        cmax=cmax,
        colorbar={"title": {"text": title}, "len": 0.6},
        hovertemplate="%{intensity:.2f} kPa<extra>" + html.escape(name) + "</extra>",
        lighting={"ambient": 0.6, "diffuse": 0.6, "specular": 0.05},
    )


def _plotly_colorscale(unloaded: float | None = None) -> list:
    """The pressure colour scale as plotly.js stops (the PNGs' scale exactly).

    With ``unloaded`` (a fraction of the scale), 0 is drawn in the body's
    colour and the scale starts at that fraction.
    """
    pos, rgb = _colorscale_stops()

    def css(col):
        return "rgb({},{},{})".format(*(int(round(255 * c)) for c in col))

    if unloaded is None:
        return [[round(float(p), 4), css(col)] for p, col in zip(pos, rgb)]
    # plotly.js samples the scale into 256 colours: the body colour needs one of its own
    start = min(max(float(unloaded), 2.0 / 255.0), 0.02)
    pos = start + (1.0 - start) * pos
    return [[0.0, css(BODY_RGB)], *([float(p), css(col)] for p, col in zip(pos, rgb))]


def _cage_trace(cage, *, name: str, visible: bool, color: str) -> dict:
    quads = np.asarray(cage.faces, dtype=np.int64)
    edges = np.unique(np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1), axis=0)
    v = np.round(np.asarray(cage.vertices, dtype=np.float64), 4)
    # one polyline with a gap (null) after every edge
    pts = np.full((len(edges), 3, 3), np.nan)
    pts[:, :2] = v[edges]
    coords = [[None if math.isnan(x) else x for x in pts[:, :, c].ravel().tolist()] for c in range(3)]
    return {
        "type": "scatter3d",
        "mode": "lines",
        "name": name,
        "visible": visible,
        "x": coords[0],
        "y": coords[1],
        "z": coords[2],
        "line": {"color": color, "width": 3},
        "hoverinfo": "name",
    }


def figure_dict(result) -> dict:
    """The plotly figure (a plain dict) of the report's 3D view.

    Traces: the body coloured by its contact pressure on our surface (by its
    importance pressure when the build was not evaluated), our surface and
    cage; with a baseline, the body coloured by its contact pressure on the
    baseline, the baseline's surface and cage, and buttons that switch
    between the two groups. The figure is a plain dict in plotly's JSON schema, so writing
    it needs no ``plotly.graph_objects``; ``plotly.graph_objects.Figure(d)``
    validates it.
    """
    scene = _scene(result)
    traces, groups = [], {}
    has_contact = scene.contact is not None
    vmax_contact = contact_scale(scene.contact, scene.baseline_contact)

    def add(group, trace):
        groups.setdefault(group, []).append(len(traces))
        traces.append(trace)

    # the body is drawn once per group (plotly has no instancing): with an
    # evaluation, coloured by its contact pressure on our surface, and on the
    # baseline's; without, by its importance pressure (pressure.png has both views)
    first = "contact" if has_contact else "importance"
    if has_contact:
        add("contact", _pressure_trace(scene, scene.contact, vmax_contact, name=f"body: {CONTACT_LABEL} (ours)", visible=True, title="importance on<br>the design, kPa"))
    else:
        add("importance", _pressure_trace(scene, scene.importance, float(scene.importance.max()), name="body: relative importance (paper's model)", visible=True, title="importance<br>kPa"))
    for group in (first,):
        if scene.surface is not None:
            add(group, _mesh_trace(scene.surface.vertices, scene.surface.faces, name="limit surface (ours)", visible=group == first, color="rgb(107,153,204)", opacity=HTML_SURFACE_OPACITY, flatshading=False))
        if scene.cage is not None:
            add(group, _cage_trace(scene.cage, name="cage (ours)", visible=group == first, color="rgb(25,70,160)"))
    if scene.baseline_surface is not None:
        name = scene.baseline_name
        if scene.baseline_contact is not None:
            add("baseline", _pressure_trace(scene, scene.baseline_contact, vmax_contact, name=f"body: {CONTACT_LABEL} ({name})", visible=False, title="importance on<br>the design, kPa"))
        else:
            add("baseline", _mesh_trace(scene.body.vertices, scene.body.faces, name="body", visible=False, color="rgb(219,201,184)"))
        add("baseline", _mesh_trace(scene.baseline_surface.vertices, scene.baseline_surface.faces, name=f"limit surface ({name})", visible=False, color="rgb(204,148,102)", opacity=HTML_SURFACE_OPACITY))
        if scene.baseline_cage is not None:
            add("baseline", _cage_trace(scene.baseline_cage, name=f"cage ({name})", visible=False, color="rgb(150,80,30)"))
    labels = {
        "importance": "Ours (relative importance, paper's model)",
        "contact": "Ours (paper's model on the design)",
        "baseline": f"Baseline: {scene.baseline_name} (paper's model on the design)",
    }
    buttons = [
        {
            "label": labels[g],
            "method": "update",
            "args": [{"visible": [i in members for i in range(len(traces))]}],
        }
        for g, members in groups.items()
    ]
    lo, hi = scene.body.vertices.min(axis=0), scene.body.vertices.max(axis=0)
    layout = {
        "margin": {"l": 0, "r": 0, "t": 40, "b": 0},
        "paper_bgcolor": "white",
        "font": {"family": "sans-serif"},
        "legend": {"x": 0.01, "y": 0.99},
        "scene": {
            "aspectmode": "data",
            "xaxis": {"title": {"text": "x (m)"}},
            "yaxis": {"title": {"text": "y (m), up"}},
            "zaxis": {"title": {"text": "z (m), front"}},
            # from behind, to the side and below the seat: the back and the
            # seat, where the body touches, through the translucent surface
            "camera": {
                "up": {"x": 0, "y": 1, "z": 0},
                "eye": {"x": -1.5, "y": -0.35, "z": -1.45},
                "center": {"x": 0, "y": -0.1, "z": 0},
            },
        },
        "meta": {"body_extent_m": (hi - lo).round(3).tolist()},
    }
    if len(buttons) > 1:
        layout["updatemenus"] = [
            {
                "type": "buttons",
                "direction": "right",
                "active": list(groups).index(first),
                "x": 0.0,
                "y": 1.06,
                "xanchor": "left",
                "buttons": buttons,
            }
        ]
    return {"data": traces, "layout": layout}


def interface_html(figures: list) -> str:
    """The report's "Interface pressure" block: the soft-tissue model's figures per person (``metrics['interface']``)."""
    if not figures:
        return ""
    parts = [
        "<h2>Interface pressure (soft-tissue model)</h2>",
        f"<p>{html.escape(INTERFACE_NOTE)}</p>",
    ]
    for i, fig in enumerate(figures):
        parts.append(f"<h3>Person {i + 1}</h3><table>")
        if not fig.get("supported", True):
            parts.append(f"<tr><td>not supported</td><td>{html.escape(str(fig.get('reason', '')))}</td></tr></table>")
            continue
        rows = [
            ("peak interface pressure", f"{fig['peak_pa'] / 1000:.1f} kPa"),
            ("peak under the buttocks and thighs", f"{fig['seat_peak_pa'] / 1000:.1f} kPa"),
            ("mean over the loaded skin", f"{fig['mean_loaded_pa'] / 1000:.1f} kPa"),
            ("loaded skin area", f"{fig['contact_area_m2'] * 1e4:.0f} cm^2"),
            *((f"share of the weight under the {k}", f"{v:.0%}") for k, v in fig["load_share"].items()),
            ("contacts at the friction limit", f"{fig['friction']['at_limit_share']:.0%}"),
            ("largest tissue compression", f"{fig['max_compression_m'] * 1000:.1f} mm ({fig['max_strain']:.0%} of its thickness)"),
        ]
        parts += [f"<tr><td>{html.escape(k)}</td><td>{html.escape(v)}</td></tr>" for k, v in rows] + ["</table>"]
    return "\n".join(parts)


def _metrics_html(result) -> str:
    from seatkit.metrics import CHECKS_NOTE

    metrics = result.metrics or {}
    parts = []
    if metrics.get("ours") or metrics.get("baseline"):
        rows, labels = table_rows(metrics, person_labels(result.bodies), own=True)
        heads = "".join(f"<th>{html.escape(str(h))}</th>" for h in _table_head(metrics, str(metrics.get("baseline_template") or "baseline")))
        parts.append(f"<p>{html.escape(TABLE1_NOTE)} {html.escape(CHECKS_NOTE)}</p>")
        if metrics.get("sharing"):
            parts.append(f"<p>{html.escape(SHARING_NOTE)}</p>")
        for person, *columns in rows:
            parts.append(f"<h3>{html.escape(person)}</h3><table><tr><th>quantity</th>{heads}</tr>")
            parts += ["<tr><td>" + html.escape(lab) + "</td>" + "".join(f"<td>{html.escape(c[k])}</td>" for c in columns) + "</tr>" for k, lab in enumerate(labels)]
            parts.append("</table>")
    else:
        parts.append("<p>No evaluation in this build (built with evaluation switched off): no metrics.</p>")
    st = metrics.get("structure")
    if st:  # seatkit build --structure (docs/structure.md); the picture is structure.png
        parts.append(f"<h2>Will it hold? {html.escape(str(st['material']))}, {st['thickness_m'] * 1000:.1f} mm (structure.png)</h2><table>")
        rows = [("max von Mises stress", f"{st['max_von_mises_pa'] / 1e6:.3f} MPa"), ("safety factor", f"{st['safety_factor']:.2f}"),
                ("max deflection", f"{st['max_deflection_m'] * 1000:.3f} mm"), ("mass", f"{st['mass_kg']:.2f} kg"),
                ("applied load", f"{st['applied_load_n']:.1f} N"), ("floor reaction", f"{st['floor_reaction_n']:.1f} N")]
        parts += [f"<tr><td>{k}</td><td>{v}</td></tr>" for k, v in rows] + ["</table>"]
    parts.append(interface_html(metrics.get("interface") or []))
    for i, dims in enumerate(metrics.get("dimensions") or []):  # seatkit.dimensions
        cells = "".join(f"<tr><td>{html.escape(k[:-2].replace('_', ' '))}</td><td>{'-' if v is None else f'{v:.3f} m'}</td></tr>" for k, v in dims.items())
        parts.append(f"<h3>Seat dimensions where it carries person {i + 1}</h3><table>{cells}</table>")
    parts += person_fit_html(metrics.get("person_fit") or [])
    parts.append(timings_html(result.timings or {}))
    return "\n".join(parts)


def person_fit_html(fits: list[dict]) -> list[str]:
    """The seat beside the person (seatkit.dimensions.person_fit): one table per measured person."""
    parts = []
    for i, fit in enumerate(fits):
        if "popliteal_height_m" not in fit:
            continue

        def mm(v):
            return "-" if v is None else f"{v * 1000:+.0f} mm"

        def m(v):
            return "-" if v is None else f"{v:.3f} m"

        rows = [
            ("seat height (front edge)", m(fit["seat_height_m"]),
             f"popliteal height {m(fit['popliteal_height_m'])} + {fit['shoe_allowance_m'] * 1000:.0f} mm shoe allowance = "
             f"{m(fit['seat_height_for_shoes_m'])}", mm(fit["seat_height_difference_m"])),
            ("seat depth (loaded)", m(fit["seat_depth_m"]), f"buttock-popliteal length {m(fit['buttock_popliteal_length_m'])}",
             mm(fit["seat_depth_difference_m"])),
            ("seat width (loaded)", m(fit["seat_width_m"]), f"hip breadth, sitting {m(fit['hip_breadth_sitting_m'])}",
             mm(fit["seat_width_difference_m"])),
        ]
        cells = "".join(f"<tr><td>{a}</td><td>{b}</td><td>{html.escape(c)}</td><td>{d}</td></tr>" for a, b, c, d in rows)
        measured = fit.get("measurements") or {}
        person = ", ".join(
            f"{k.replace('_', ' ')} {v:.3f} m" for k, v in measured.items() if k not in ("mass", "volume")
        )
        parts.append(
            f"<h3>The seat beside person {i + 1}</h3><p>{html.escape(fit['standard'])}. The person, measured on the "
            f"bare-skin body as ANSUR II measures (docs/bodies.md): {html.escape(person)}; mass "
            f"{measured.get('mass', float('nan')):.1f} kg.</p><table><tr><th>seat</th><th>designed</th>"
            f"<th>the person, as the standard relates them</th><th>difference</th></tr>{cells}</table>"
        )
    return parts


_TIMINGS_START, _TIMINGS_END = "<!-- seatkit:timings -->", "<!-- /seatkit:timings -->"


def timings_html(timings: dict) -> str:
    """The report's "Time per stage" table: every stage and the total.

    Stages marked ``(parallel)`` ran beside the others and are not added to
    the total (:func:`seatkit.model.total_seconds`). The table sits between
    markers so that the build can put in the export stage once it has ended
    (:func:`finish_report_html`).
    """
    from seatkit.model import total_seconds

    if not timings:
        return f"{_TIMINGS_START}{_TIMINGS_END}"
    rows = [f"<tr><td>{html.escape(str(k))}</td><td>{float(v):.3f}</td></tr>" for k, v in timings.items()]
    rows.append(f"<tr><th>total</th><th>{total_seconds(timings):.3f}</th></tr>")
    note = "<p>Stages marked (parallel) ran beside the others and are not part of the total.</p>"
    return f"{_TIMINGS_START}<h2>Time per stage</h2><table><tr><th>stage</th><th>seconds</th></tr>{''.join(rows)}</table>{note}{_TIMINGS_END}"


def finish_report_html(path, timings: dict) -> bool:
    """Replace the time table of a written ``report.html`` with the build's final one, in place.

    ``report.html`` is written during the export stage, before that stage's
    time is known; the build calls this once it is (with ``export`` and the
    total), on the file in its staging folder (moved into place only once
    every file is written: :func:`seatkit.output.staging_folder`). The table
    is near the end of the page: only the bytes from it on are written again,
    not the page's several megabytes of plotly. Returns whether the file held
    a table to replace.
    """
    start_mark, end_mark = _TIMINGS_START.encode(), _TIMINGS_END.encode()
    with open(path, "r+b") as fh:
        data = fh.read()
        start, end = data.find(start_mark), data.find(end_mark)
        if start < 0 or end < start:
            return False
        fh.seek(start)
        fh.write(timings_html(timings).encode("utf-8") + data[end + len(end_mark) :])
        fh.truncate()
        fh.flush()
        os.fsync(fh.fileno())
    return True


_PAGE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>{title}</title>
<style>
body {{ font-family: sans-serif; margin: 1em 2em; color: #222; }}
table {{ border-collapse: collapse; margin: 0.5em 0 1em; }}
td, th {{ border: 1px solid #bbb; padding: 0.25em 0.8em; text-align: right; }}
td:first-child, th:first-child {{ text-align: left; }}
#view-box {{ width: 100%; max-width: {max_width}px; height: clamp({min_h}px, {vh}vh, {max_h}px); }}
</style></head>
<body>
<h1>{title}</h1>
<p>{summary}</p>
{plot}
<h2>Evaluation: the paper's Table 1 quantities and two checks</h2>
{metrics}
</body></html>
"""


def write_report_html(result, path) -> Path:
    """Write ``report.html``: the 3D view and the metrics, with plotly.js inline.

    The page makes no network request: plotly.js is embedded
    (``include_plotlyjs=True``), MathJax is off and the fonts are the
    browser's own ``sans-serif``.
    """
    import plotly.io as pio

    fig = figure_dict(result)
    plot = pio.to_html(
        fig,
        include_plotlyjs=True,
        include_mathjax=False,
        full_html=False,
        validate=False,
        div_id="view",
        default_width="100%",
        default_height="100%",
        config={"displaylogo": False, "responsive": True},
    )
    recipe = result.recipe or {}
    people = "; ".join(person_labels(result.bodies))
    summary = html.escape(f"template: {recipe.get('template', '?')}; {people}")
    title = html.escape(f"seatkit build: {recipe.get('template', '')}")
    low, high = HTML_VIEW_HEIGHT_PX
    # the page around the plot, formatted without it: the plot (plotly.js
    # inline, 6 MB) is encoded once and written between, not copied into
    # the page first
    fields = {
        "max_width": HTML_VIEW_MAX_WIDTH, "vh": HTML_VIEW_VH, "min_h": low, "max_h": high,
        "title": title, "summary": summary, "metrics": _metrics_html(result),
    }
    head, tail = (text.format(**fields) for text in _PAGE.split("{plot}"))
    with atomic_write(Path(path), "wb") as fh:
        for piece in (head, '<div id="view-box">', plot, "</div>", tail):
            fh.write(piece.encode("utf-8"))
    return Path(path)


# ----------------------------------------------------------------------------- exporters


class ReportPngExporter:
    """PNG renders of the build: pressure, cage, surface, comparison with the baseline."""

    name = "report-png"
    description = "pressure.png, cage.png, surface.png, comparison.png: renders of the body, cage, surface and baseline"

    prepare_ahead = False
    #: Costly (0.3-0.5 s of drawing) with nothing big to import: a build with
    #: idle helper processes draws its parts (:data:`PNG_PARTS`) there and in
    #: its own process, beside the other exporters.
    runs_apart = True
    parts = len(PNG_PARTS)
    #: ``cage.png`` shows the body and the cage alone: drawn beside the evaluation,
    #: once the baseline is fitted (the views frame both designs).
    design_parts = (PNG_PARTS.index(("report_cage_png",)),)
    reads_baseline = True

    def prepare(self) -> None:
        """Nothing to prepare: this exporter imports nothing big."""

    def export_early(self, result) -> dict:
        """``pressure.png`` drawn from the bodies and their importance alone (:func:`draw_early_pngs`), before the design exists."""
        return draw_early_pngs(result)

    def export(self, result, directory: Path, early=None) -> dict[str, Path]:
        return render_pngs(result, directory, early=early)

    def export_part(self, result, directory: Path, part: int, early=None) -> dict[str, Path]:
        """The pictures of one part (:data:`PNG_PARTS`) only; the parts together write what :meth:`export` writes."""
        return render_pngs(result, directory, roles=PNG_PARTS[part], early=early)

    def join_parts(self, written: list) -> dict[str, Path]:
        """The parts' files by role, in the order :meth:`export` gives them."""
        merged = {role: path for files in written for role, path in files.items()}
        return {role: merged[role] for role in PNG_FILES if role in merged}


class ReportHtmlExporter:
    """An interactive 3D report that opens offline."""

    name = "report-html"
    description = "report.html: interactive 3D view (plotly, embedded, offline) and the metrics table"

    prepare_ahead = True

    def prepare(self) -> None:
        """Import plotly's HTML writer (it imports more on first use), ahead of :meth:`export`."""
        import plotly.io as pio

        pio.to_html({"data": [], "layout": {}}, include_plotlyjs=False, full_html=False, validate=False)

    def export(self, result, directory: Path) -> dict[str, Path]:
        return {"report_html": write_report_html(result, Path(directory) / "report.html")}


def report_exporters() -> list:
    """One instance of each report exporter."""
    return [ReportPngExporter(), ReportHtmlExporter()]

