"""seatkit's Catmull-Clark operators against OpenSubdiv itself (Far, libosd-dev).

A C++ program (tests/osd_reference/osd_reference.cpp) refines each cage with
Far::TopologyRefiner and Far::PrimvarRefinerReal<double> (Interpolate and
Limit); the refined points, the refined faces, the limit positions and both
limit tangents must agree to 1e-9 at levels 1 to 4.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from seatkit.subdivision import build_operators

_spec = importlib.util.spec_from_file_location(
    "seatkit_tests_osd_fixtures", Path(__file__).parent / "osd_reference" / "fixtures.py"
)
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)
osd_reference = _fixtures.osd_reference
runner = _fixtures.load_runner()

CASES = runner.reference_cases()
TOL = 1e-9


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_matches_opensubdiv(osd_reference, case):
    reference = runner.run_reference(osd_reference, case, 4)
    cage = case.cage()
    P = cage.vertices
    assert len(reference) == 4
    for level, ref in enumerate(reference, start=1):
        ops = build_operators(cage, level)
        assert ops.refine.shape == (len(ref.points), len(P))
        np.testing.assert_array_equal(ops.faces, ref.faces, err_msg=f"{case.name} level {level} faces")
        np.testing.assert_allclose(ops.refine @ P, ref.points, rtol=0, atol=TOL, err_msg=f"level {level} refine")
        np.testing.assert_allclose(ops.limit @ P, ref.limit, rtol=0, atol=TOL, err_msg=f"level {level} limit")
        np.testing.assert_allclose(ops.du @ P, ref.tan1, rtol=0, atol=TOL, err_msg=f"level {level} tangent 1")
        np.testing.assert_allclose(ops.dv @ P, ref.tan2, rtol=0, atol=TOL, err_msg=f"level {level} tangent 2")


def test_cases_cover_the_features():
    """The comparison set holds every feature the issue lists."""
    names = {c.name for c in CASES}
    for wanted in ("grid-eac", "grid-eo", "chair-eac", "chair-eo", "star-eac", "mixed-eac", "cube"):
        assert wanted in names
    sharp = {s for c in CASES for s in c.crease_sharpness}
    assert {0.5, 1.0, 2.3, 10.0} <= sharp
    corner_s = {s for c in CASES for s in c.corner_sharpness}
    assert {0.5, 2.3, 10.0} <= corner_s
    star = next(c for c in CASES if c.name == "star-eac").cage().base_level()
    assert {3, 5} <= set(star.n_vertex_faces[star.n_vertex_faces == star.n_vertex_edges].tolist())
    mixed = next(c for c in CASES if c.name == "mixed-eac").cage()
    assert {3, 4, 5} == set(mixed.face_sizes.tolist())


def test_reference_harness_on_a_single_quad(osd_reference):
    """The program reports refinement of a plain quad (smoke check of the harness itself)."""
    case = runner.CageCase(
        "quad", np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1.0]]), [[0, 3, 2, 1]], [], [], [], []
    )
    ref = runner.run_reference(osd_reference, case, 2)
    assert [len(r.points) for r in ref] == [9, 25]
    # A single quad with sharp corners: its limit surface spans the quad exactly.
    np.testing.assert_allclose(ref[1].limit[:4], case.vertices, atol=1e-15)
