"""``structure.png``: the von Mises stress on the shell, seen from three sides.

Each element is drawn flat in the colour of its largest stress on the face
shown (the top face: the body side; the bottom face: the underside), on a
scale from zero to the largest stress of the analysis, so no value is
clipped. Elements whose mapping folds (docs/structure.md, "Limits") are grey
(folded or nearly) and left out of the scale. Views are rasterised with :mod:`seatkit.picture.raster`.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from seatkit.geometry.normals import vertex_normals
from seatkit.structure.analysis import Analysis

__all__ = ["face_stress", "write_stress_png"]

#: (azimuth, elevation) in degrees of the three views.
VIEWS = {"front, from above": (35.0, 30.0), "back, from above": (215.0, 25.0), "right side": (90.0, 8.0), "from below (floor removed)": (0.0, -89.0)}
PANEL = (420, 420)
COLORMAP = "viridis"
FOLDED_RGB = (0.62, 0.62, 0.62)

# the four sub-quads of a quadratic quad, as columns of quads9 (corners, mids, centre)
_SUBQUADS = np.array([[0, 4, 8, 7], [4, 1, 5, 8], [8, 5, 2, 6], [7, 8, 6, 3]])


def face_stress(analysis: Analysis) -> tuple[np.ndarray, np.ndarray]:
    """(q,) largest von Mises stress on the top face and on the bottom face of each surface quad, Pa."""
    from seatkit.structure.fem import _full_rule, _stress_rule

    mesh = analysis.mesh
    vm = analysis.solution.von_mises
    q = len(mesh.quads9)
    layers = vm.shape[0] // q
    # the stress points: the 2 x 2 x 3 rule with assumed strains, else the full 3 x 3 x 3 one
    z = (_stress_rule() if vm.shape[1] == 12 else _full_rule())[0][2]
    top = vm[(layers - 1) * q :, :][:, z >= z.max() - 1e-12].max(axis=1)
    bottom = vm[:q, :][:, z <= z.min() + 1e-12].max(axis=1)
    return top, bottom


def _sheet_triangles(mesh, sheet: int, flip: bool):
    """Per-element vertex copies (q, 9, 3) of one node sheet and their triangles (flat colours per element)."""
    nodes = mesh.nodes[mesh.quads9 + sheet * mesh.n_surface]  # (q, 9, 3)
    q = len(nodes)
    quads = (_SUBQUADS[None, :, :] + 9 * np.arange(q)[:, None, None]).reshape(-1, 4)
    if flip:
        quads = quads[:, ::-1]
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    return nodes.reshape(-1, 3), tris


def write_stress_png(analysis: Analysis, path, *, title: str = "") -> Path:
    """Write the picture (atomically) and return its path."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    from seatkit.picture import raster as rs
    from seatkit.io import write_bytes_atomic

    mesh, s = analysis.mesh, analysis.summary
    q = len(mesh.quads9)
    top, bottom = face_stress(analysis)
    layers = analysis.folded.size // q
    folded = analysis.folded.reshape(layers, q)
    vmax = float(s["max_von_mises_pa"])
    vt, tt = _sheet_triangles(mesh, mesh.sheets - 1, flip=False)
    vb, tb = _sheet_triangles(mesh, 0, flip=True)
    vertices = np.concatenate([vt, vb])
    tris = np.concatenate([tt, tb + len(vt)])
    values = np.concatenate([np.repeat(top, 9), np.repeat(bottom, 9)])
    bad = np.concatenate([np.repeat(folded[-1], 9), np.repeat(folded[0], 9)])
    cmap = colormaps[COLORMAP]
    norm = Normalize(0.0, vmax if vmax > 0 else 1.0)
    rgb = cmap(norm(np.where(bad, 0.0, values)))[:, :3]
    rgb[bad] = FOLDED_RGB
    normals = vertex_normals(vertices, tris)
    fig, axes = plt.subplots(1, len(VIEWS) + 1, figsize=(17.0, 4.9), gridspec_kw={"width_ratios": [1] * len(VIEWS) + [0.06]})
    worst = s.get("max_stress_at_m")
    for ax, (name, (az, el)) in zip(axes, VIEWS.items()):
        rot = rs.view_rotation(az, el)
        frame = rs.fit_frame([vertices], rot, *PANEL)
        ra = rs.rasterize(frame, vertices, tris)
        # mostly the flat colour (it is read against the colour bar), some shading for the shape
        lit = 0.7 * rgb + 0.3 * rs.light_vertices(rgb, normals, rot) / (rs.AMBIENT + rs.DIFFUSE)
        image = rs.composite((1.0, 1.0, 1.0), [(ra, ra.shade(lit), 1.0)])
        ax.imshow(image)
        if worst is not None:  # where the largest stress is (seen through the shell when hidden)
            xy, depth = frame.project(np.asarray([worst], dtype=np.float64))
            x, y = xy[0]
            inside = 0 <= int(y) < frame.height and 0 <= int(x) < frame.width
            hidden = inside and ra.depth[int(y), int(x)] > depth[0] + 0.02
            ax.plot([x], [y], marker="o", markersize=14, markerfacecolor="none", markeredgecolor="red", markeredgewidth=1.5, alpha=0.45 if hidden else 1.0)
            ax.plot([x], [y], marker="+", markersize=8, color="red", alpha=0.5 if hidden else 1.0)
        ax.set_title(name, fontsize=10)
        ax.axis("off")
    bar = fig.colorbar(plt.cm.ScalarMappable(norm=Normalize(0.0, vmax / 1e6 if vmax > 0 else 1.0), cmap=cmap), cax=axes[-1])
    bar.set_label("von Mises stress, MPa (0 to the maximum: nothing clipped)")
    head = (
        f"{title + ': ' if title else ''}{s['material']} {s['thickness_m'] * 1000:.1f} mm, "
        f"max von Mises {vmax / 1e6:.2f} MPa (strength {s['strength_pa'] / 1e6:.0f} MPa, safety factor "
        f"{s['safety_factor']:.1f}), max deflection {s['max_deflection_m'] * 1000:.2f} mm, mass {s['mass_kg']:.1f} kg"
    )
    head += "; red ring: where the largest stress is (faint: hidden in that view)"
    if s.get("distorted_elements"):
        head += (f"\n{s['distorted_elements']} distorted elements in grey ({s['distorted_volume_fraction'] * 100:.1f}% of the volume; "
                 "folded or nearly: the surface curls tighter than the thickness there), left out of the maximum")
    fig.suptitle(head, fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return Path(write_bytes_atomic(path, buf.getvalue()))
