"""Build and run the OpenSubdiv reference program; test cages.

Test support only (no pytest import here). ``compile_reference`` compiles
``osd_reference.cpp`` against the system OpenSubdiv (Debian ``libosd-dev``)
into a cache folder keyed by the source's hash; ``run_reference`` feeds it a
cage and parses the refined points, faces, limit positions and tangents.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "osd_reference.cpp"
OSD_HEADER = Path("/usr/include/opensubdiv/far/primvarRefiner.h")


class ReferenceUnavailable(RuntimeError):
    """g++ or the OpenSubdiv headers/library are missing."""


def cache_dir() -> Path:
    """Folder for the compiled program (``$SEATKIT_TEST_CACHE`` or ~/.cache/seatkit-tests)."""
    root = os.environ.get("SEATKIT_TEST_CACHE")
    if root:
        return Path(root)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "seatkit-tests"


def compile_reference(folder: Path | None = None) -> Path:
    """Compile the reference program once per source hash; return its path.

    Raises
    ------
    ReferenceUnavailable
        When g++ or OpenSubdiv's headers are not installed, or linking fails.
    """
    compiler = shutil.which("g++")
    if compiler is None:
        raise ReferenceUnavailable("g++ is not installed (apt-get install g++)")
    if not OSD_HEADER.exists():
        raise ReferenceUnavailable(f"OpenSubdiv headers missing ({OSD_HEADER}); apt-get install libosd-dev")
    source = SOURCE.read_bytes()
    digest = hashlib.sha256(source).hexdigest()[:16]
    folder = Path(folder) if folder is not None else cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    exe = folder / f"osd_reference-{digest}"
    if exe.exists():
        return exe
    fd, tmp = tempfile.mkstemp(prefix=".osd_reference.", dir=folder)
    os.close(fd)
    cmd = [compiler, "-O1", "-std=c++14", str(SOURCE), "-o", tmp, "-losdCPU"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        os.unlink(tmp)
        raise ReferenceUnavailable(f"compiling the OpenSubdiv reference failed:\n{proc.stderr[-2000:]}")
    os.chmod(tmp, 0o755)
    os.replace(tmp, exe)
    return exe


@dataclass
class ReferenceLevel:
    """OpenSubdiv's results at one level."""

    points: np.ndarray  # (p, 3) refined points
    faces: np.ndarray  # (q, 4) faces
    limit: np.ndarray  # (p, 3) limit positions
    tan1: np.ndarray  # (p, 3) first limit tangent
    tan2: np.ndarray  # (p, 3) second limit tangent


def cage_text(case: "CageCase", levels: int) -> str:
    """The reference program's input for ``case``."""
    lines = [f"boundary {0 if case.boundary == 'edge-and-corner' else 1}", f"levels {levels}"]
    lines.append(f"vertices {len(case.vertices)}")
    lines += [" ".join(repr(float(x)) for x in row) for row in case.vertices]
    lines.append(f"faces {len(case.faces)}")
    lines += [" ".join(str(int(i)) for i in [len(f), *f]) for f in case.faces]
    lines.append(f"creases {len(case.crease_edges)}")
    lines += [f"{a} {b} {s!r}" for (a, b), s in zip(case.crease_edges, case.crease_sharpness)]
    lines.append(f"corners {len(case.corners)}")
    lines += [f"{v} {s!r}" for v, s in zip(case.corners, case.corner_sharpness)]
    return "\n".join(lines) + "\n"


def run_reference(exe: Path, case: "CageCase", levels: int) -> list[ReferenceLevel]:
    """Run OpenSubdiv on ``case`` for levels 1..``levels``."""
    proc = subprocess.run([str(exe)], input=cage_text(case, levels), capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise RuntimeError(f"reference program failed ({proc.returncode}): {proc.stderr}")
    out: list[ReferenceLevel] = []
    pts, faces, lim = [], [], []
    for line in proc.stdout.splitlines():
        tag, *rest = line.split()
        if tag == "level":
            if pts:
                out.append(_level(pts, faces, lim))
            pts, faces, lim = [], [], []
        elif tag == "p":
            pts.append([float(x) for x in rest])
        elif tag == "f":
            faces.append([int(x) for x in rest])
        elif tag == "q":
            lim.append([float(x) for x in rest])
    out.append(_level(pts, faces, lim))
    return out


def _level(pts, faces, lim) -> ReferenceLevel:
    q = np.array(lim, dtype=np.float64)
    return ReferenceLevel(
        points=np.array(pts, dtype=np.float64),
        faces=np.array(faces, dtype=np.int64),
        limit=q[:, 0:3],
        tan1=q[:, 3:6],
        tan2=q[:, 6:9],
    )


# ----------------------------------------------------------------------------- cages


@dataclass
class CageCase:
    """A named test cage."""

    name: str
    vertices: np.ndarray
    faces: list
    crease_edges: list
    crease_sharpness: list
    corners: list
    corner_sharpness: list
    boundary: str = "edge-and-corner"

    def cage(self):
        from seatkit.subdivision import Cage

        return Cage(
            self.vertices,
            self.faces,
            crease_edges=np.array(self.crease_edges, dtype=np.int64).reshape(-1, 2),
            crease_sharpness=np.array(self.crease_sharpness, dtype=np.float64),
            corners=np.array(self.corners, dtype=np.int64),
            corner_sharpness=np.array(self.corner_sharpness, dtype=np.float64),
            boundary=self.boundary,
        )


def grid(nx: int, nz: int, *, seed: int | None = 0, bump: float = 0.15):
    """An nx x nz quad grid in the XZ plane (normals +Y), gently bumped in y."""
    xs, zs = np.meshgrid(np.arange(nx + 1, dtype=float), np.arange(nz + 1, dtype=float))
    v = np.c_[xs.ravel(), np.zeros(xs.size), zs.ravel()]
    if seed is not None:
        v[:, 1] = bump * np.random.default_rng(seed).standard_normal(len(v))
    faces = []
    for i in range(nz):
        for j in range(nx):
            a = i * (nx + 1) + j
            faces.append([a, a + nx + 1, a + nx + 2, a + 1])
    return v, faces


def grid_index(nx: int, i: int, j: int) -> int:
    """Vertex index at row ``i``, column ``j`` of :func:`grid`."""
    return i * (nx + 1) + j


def chair_cage(nx: int = 7, nz: int = 9):
    """A chair-like cage: an nx x nz seat-and-back grid and a border ring of
    quads down to a ground loop (y = 0); the grid's outer loop is creased."""
    # Seat/back profile: flat seat for the first 5 rows, then a back rising.
    rows = []
    for i in range(nz + 1):
        if i <= 5:
            y, z = 0.45, 0.45 * (1 - i / 5)
        else:
            y, z = 0.45 + 0.12 * (i - 5), -0.03 * (i - 5)
        rows.append((y, z))
    v = []
    for i in range(nz + 1):
        y, z = rows[i]
        for j in range(nx + 1):
            x = -0.25 + 0.5 * j / nx
            v.append([x, y + 0.01 * np.sin(3 * j + i), z])
    _, faces = grid(nx, nz, seed=None)
    faces = [list(reversed(f)) for f in faces]  # normals up/forward for this profile
    # Outer loop of the grid, counter-clockwise.
    loop = [grid_index(nx, 0, j) for j in range(nx)]
    loop += [grid_index(nx, i, nx) for i in range(nz)]
    loop += [grid_index(nx, nz, j) for j in range(nx, 0, -1)]
    loop += [grid_index(nx, i, 0) for i in range(nz, 0, -1)]
    base = len(v)
    verts = np.array(v)
    centre = verts.mean(axis=0)
    for k, idx in enumerate(loop):
        p = verts[idx]
        d = p - centre
        d[1] = 0
        d /= np.linalg.norm(d)
        v.append([p[0] + 0.1 * d[0], 0.0, p[2] + 0.1 * d[2]])
    n = len(loop)
    ring = []
    for k in range(n):
        a, b = loop[k], loop[(k + 1) % n]
        ring.append([a, base + k, base + (k + 1) % n, b])
    vv = np.array(v)
    # Orient the ring like the grid: a ring face walks its grid edge b -> a,
    # so the grid face must walk it a -> b.
    grid_dir = {(f[t], f[(t + 1) % 4]) for f in faces for t in range(4)}
    if (ring[0][3], ring[0][0]) in grid_dir:
        ring = [list(reversed(f)) for f in ring]
    crease = [(loop[k], loop[(k + 1) % n]) for k in range(n)]
    return vv, faces + ring, crease


def star_cage():
    """Valence 5 at the centre, valence 3 on a ring: an interior star and an outer ring."""
    c = [0.0, 0.3, 0.0]
    v = [c]
    for i in range(5):
        a = 2 * np.pi * i / 5
        b = 2 * np.pi * (i + 0.5) / 5
        v.append([np.cos(a), 0.1 * np.sin(2 * a), np.sin(a)])  # spoke s_i: 1 + 2i
        v.append([1.3 * np.cos(b), -0.1, 1.3 * np.sin(b)])  # between m_i: 2 + 2i
    inner_loop = list(range(1, 11))
    faces = []
    for i in range(5):
        s, m, s2 = 1 + 2 * i, 2 + 2 * i, 1 + 2 * ((i + 1) % 5)
        faces.append([0, s2, m, s])
    base = len(v)
    for k, idx in enumerate(inner_loop):
        p = np.array(v[idx])
        v.append([2.2 * p[0], 0.2 * np.cos(k), 2.2 * p[2]])
    for k in range(10):
        a, b = inner_loop[k], inner_loop[(k + 1) % 10]
        faces.append([a, b, base + (k + 1) % 10, base + k])
    return np.array(v), faces


def mixed_cage():
    """Quads with a triangle pair and two pentagons (a vertex inserted on an edge)."""
    v, faces = grid(4, 4, seed=3)
    v = list(map(list, v))
    # Split face 5 into two triangles.
    a, b, c, d = faces[5]
    faces[5] = [a, b, c]
    faces.append([a, c, d])
    # Insert a vertex on the edge shared by faces 10 and 11 -> two pentagons.
    f10, f11 = faces[10], faces[11]
    shared = [x for x in f10 if x in f11]
    p = (np.array(v[shared[0]]) + np.array(v[shared[1]])) / 2 + np.array([0.0, 0.2, 0.0])
    v.append(p.tolist())
    m = len(v) - 1
    for fi in (10, 11):
        f = faces[fi]
        for t in range(4):
            if {f[t], f[(t + 1) % 4]} == set(shared):
                faces[fi] = f[: t + 1] + [m] + f[t + 1 :]
                break
    return np.array(v), faces


def cube_cage():
    """A closed cube (valence 3 everywhere), outward normals."""
    v = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
    faces = [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ]
    return v, faces


def reference_cases() -> list[CageCase]:
    """The cages compared with OpenSubdiv."""
    cases = []
    for mode in ("edge-and-corner", "edge-only"):
        tag = "eac" if mode == "edge-and-corner" else "eo"
        v, f = grid(4, 3)
        cases.append(CageCase(f"grid-{tag}", v, f, [], [], [], [], mode))
        v, f, cr = chair_cage()
        cases.append(CageCase(f"chair-{tag}", v, f, cr, [2.3] * len(cr), [], [], mode))
        v, f = star_cage()
        cases.append(CageCase(f"star-{tag}", v, f, [], [], [], [], mode))
        v, f = mixed_cage()
        cases.append(CageCase(f"mixed-{tag}", v, f, [], [], [], [], mode))
    v, f = chair_cage()[:2]
    cases.append(CageCase("chair-smooth", v, f, [], [], [], []))
    # Creases on a 6 x 6 grid: a crease line across, one ending inside (darts),
    # crossing creases (corner rule), in every sharpness flavour.
    nx = 6
    v, f = grid(nx, nx, seed=7)
    row = [(grid_index(nx, 3, j), grid_index(nx, 3, j + 1)) for j in range(nx)]
    col = [(grid_index(nx, i, 3), grid_index(nx, i + 1, 3)) for i in range(1, 5)]
    half = [(grid_index(nx, 2, j), grid_index(nx, 2, j + 1)) for j in range(2, 5)]
    for s in (10.0, 0.5, 1.0, 2.3):
        cases.append(CageCase(f"crease-line-{s}", v, f, row, [s] * len(row), [], []))
        cases.append(CageCase(f"crease-dart-{s}", v, f, half, [s] * len(half), [], []))
        cases.append(CageCase(f"crease-cross-{s}", v, f, row + col, [s] * (len(row) + len(col)), [], []))
    mixed_s = [0.5, 1.0, 2.3, 10.0, 1.7, 0.3]
    cases.append(CageCase("crease-varying", v, f, row, mixed_s, [], []))
    cases.append(
        CageCase("crease-varying-cross", v, f, row + col, mixed_s + [3.2, 0.8, 1.5, 2.0], [], [])
    )
    # Corners: interior sharp and semi-sharp, on a crease, and on the boundary (edge-only).
    corners = [grid_index(nx, 2, 2), grid_index(nx, 4, 4), grid_index(nx, 3, 2), grid_index(nx, 1, 5)]
    for s in (10.0, 0.5, 1.0, 2.3):
        cases.append(CageCase(f"corners-{s}", v, f, row, [1.5] * len(row), corners, [s] * len(corners)))
    bcorners = [grid_index(nx, 0, 0), grid_index(nx, 0, 3), grid_index(nx, nx, nx)]
    cases.append(CageCase("boundary-corners-eo", v, f, [], [], bcorners, [10.0, 1.4, 0.6], "edge-only"))
    v, f = cube_cage()
    cube_edges = [(0, 1), (1, 3), (3, 2), (2, 0)]
    cases.append(CageCase("cube", v, f, [], [], [], []))
    cases.append(CageCase("cube-creased", v, f, cube_edges, [10.0, 2.3, 0.5, 1.0], [7], [1.3]))
    v, f = star_cage()
    spokes = [(0, 1 + 2 * i) for i in range(5)]
    cases.append(CageCase("star-spokes", v, f, spokes[:3], [10.0, 1.5, 0.7], [0], [0.4]))
    v, f = mixed_cage()
    cases.append(CageCase("mixed-creased", v, f, [(f[5][0], f[5][2])], [1.6], [], []))
    return cases
