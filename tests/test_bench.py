"""The bench: one connected cage for several people, each in their own pose."""

import numpy as np
import pytest

from seatkit.errors import SeatkitError, UnsupportedPoseError
from seatkit.pipeline import build
from seatkit.skeleton import SEGMENT_INDEX
from seatkit.template.checks import body_vertex_normals, self_intersecting_faces, topology_problems

THREE = [
    {"model": "default-male", "pose": "upright-sitting"},
    {"model": "default-female", "pose": "reclined-sitting"},
    {"model": "default-male", "pose": "crossed-legs-knees"},
]
QUICK = {"refiners": [], "evaluate": {"enabled": False}}


@pytest.fixture(scope="module")
def bench():
    return build({"template": "bench", "bodies": THREE, **QUICK}, write=False)


def test_three_people_share_one_connected_manifold_cage(bench):
    mesh = bench.control_mesh
    assert mesh.faces.shape[1] == 4
    assert topology_problems(mesh.faces, len(mesh.vertices)) == []  # manifold, connected, one boundary loop
    assert len(self_intersecting_faces(mesh.vertices, mesh.faces)) == 0
    assert set(np.unique(mesh.face_person)) == {-1, 0, 1, 2}
    assert mesh.face_labels.count("connector") >= 2 * 7  # a connector column between each pair of neighbours
    # one ground rectangle: every ground vertex at y = 0
    assert np.allclose(mesh.vertices[mesh.ground, 1], 0.0)


def test_people_are_seated_in_order_without_overlap(bench):
    xs = [b.vertices[:, 0] for b in bench.bodies]
    for left, right in zip(xs, xs[1:]):
        assert left.max() < right.min()
    assert bench.bodies[1].mass == pytest.approx(55.0)  # default-female's default mass (her own shape)
    assert bench.bodies[1].vertices[:, 1].max() < bench.bodies[0].vertices[:, 1].max()  # the female body is smaller


def test_each_persons_supported_parts_are_within_the_support_distance(bench):
    mesh = bench.control_mesh
    checked = {0: 0, 1: 0, 2: 0}
    for face in mesh.meta["faces"]:
        person = face["person"]
        body, pressure = bench.bodies[person], bench.pressures[person]
        seg = body.weights.argmax(1)
        normals = body_vertex_normals(body)
        i = [k for k, lab in enumerate(mesh.face_labels) if lab == face["face"] and mesh.face_person[k] == person][0]
        n, c = mesh.plane_normals[i], mesh.plane_points[i]
        on = np.isin(seg, [SEGMENT_INDEX[s] for s in face["segments"]])
        important = on & (pressure.importance >= 0.05) & (normals @ n < -0.25)
        if important.any():
            assert np.abs((body.vertices[important] - c) @ n).min() <= 0.02, (person, face["face"])
            checked[person] += 1
    assert all(v >= 5 for v in checked.values()), checked


def test_overlapping_people_are_refused_by_name():
    people = [dict(p, offset=[0.0, 0.0, 0.0]) for p in THREE[:2]]
    with pytest.raises(SeatkitError, match=r"person 1 \(default-male:upright-sitting\) and person 2 \(default-female:reclined-sitting\) overlap"):
        build({"template": "bench", "bodies": people, **QUICK}, write=False)


def test_an_unsupportable_person_is_named():
    people = [THREE[0], {"model": "default-female", "pose": "lying-side"}]
    with pytest.raises(UnsupportedPoseError, match=r"person 2 \(default-female:lying-side\)"):
        build({"template": "bench", "bodies": people, **QUICK}, write=False)


def test_bench_needs_two_people():
    with pytest.raises(SeatkitError, match="2"):
        build({"template": "bench", **QUICK}, write=False)
