"""The structural analysis of real designs: loads, supports, sizing, files and bad input."""

import json
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from seatkit.structure import MATERIALS, StructureError, analyse, get_material, size_thickness
from seatkit.constants import GRAVITY

#: A coarse mesh keeps these tests quick; the default resolution is tested once.
QUICK = {"level": 1}


@pytest.fixture(scope="module")
def chair():
    from seatkit.pipeline import build
    from seatkit.recipe import apply_overrides, load_recipe

    recipe = apply_overrides(load_recipe(None)[0], template="chair", baseline="")
    return build(recipe, write=False)


def _run(result, **kw):
    return analyse(result.control_mesh, result.bodies, result.contact_pressures, **kw)


def test_loads_are_the_people_and_the_shell_and_the_floor_carries_them(chair):
    a = _run(chair, material="petg", thickness=0.003)  # the default resolution
    s = a.summary
    weight = sum(b.mass for b in chair.bodies) * GRAVITY
    assert s["people_load_n"] == pytest.approx([weight], rel=1e-9)
    assert s["self_weight_n"] == pytest.approx(s["mass_kg"] * GRAVITY)
    assert s["applied_load_n"] == pytest.approx(weight + s["self_weight_n"], rel=1e-9)
    assert abs(s["floor_reaction_n"] - s["applied_load_n"]) <= 1e-6 * s["applied_load_n"]
    # every component balances, not only the vertical one (friction pushes sideways)
    assert np.allclose(np.add(s["applied_load_vector_n"], s["floor_reaction_vector_n"]), 0, atol=1e-6 * weight)
    assert s["mesh"]["level"] == 2 and s["mesh"]["layers"] == 1
    assert s["safety_factor"] == pytest.approx(MATERIALS["petg"].strength_pa / s["max_von_mises_pa"])
    assert 0 < s["max_deflection_m"] < 0.05
    # the mass is the shell's volume times the density: the surface area times the thickness, near enough
    from seatkit.subdivision import limit_surface

    surf = limit_surface(chair.control_mesh, level=3)
    v, f = surf.vertices, surf.faces
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 2]] - v[f[:, 0]], v[f[:, 3]] - v[f[:, 1]]), axis=1).sum()
    assert s["mass_kg"] == pytest.approx(area * 0.003 * MATERIALS["petg"].density_kg_m3, rel=0.03)


def test_stiffer_material_deflects_less_in_proportion(chair):
    """Same geometry and loads without self-weight: deflection scales as 1/E (nu equal)."""
    a = get_material("birch-plywood")
    b = replace(a, name="stiff", youngs_modulus_pa=2 * a.youngs_modulus_pa)
    da = _run(chair, material=a, thickness=0.01, self_weight=False, **QUICK).summary
    db = _run(chair, material=b, thickness=0.01, self_weight=False, **QUICK).summary
    assert db["max_deflection_m"] == pytest.approx(da["max_deflection_m"] / 2, rel=1e-6)
    assert db["max_von_mises_pa"] == pytest.approx(da["max_von_mises_pa"], rel=1e-6)


def test_size_thickness_is_the_thinnest_that_keeps_both_limits(chair):
    analysis, history = size_thickness(
        chair.control_mesh, chair.bodies, chair.contact_pressures, material="pla", safety_factor=20, max_deflection=0.002, **QUICK
    )
    s = analysis.summary
    t = s["thickness_m"]
    assert s["safety_factor"] >= 20 and s["max_deflection_m"] <= 0.002
    thinner = [h for h in history if abs(h["thickness_m"] - (t - 0.0001)) < 1e-9]
    assert thinner, "the step below the answer was analysed"
    assert thinner[0]["safety_factor"] < 20 or thinner[0]["max_deflection_m"] > 0.002
    assert s["sizing"]["thickness_m"] == t


def test_no_floor_contact_is_one_clear_error(chair):
    up = chair.control_mesh.with_vertices(chair.control_mesh.vertices + [0.0, 0.1, 0.0])
    with pytest.raises(StructureError, match="does not meet the floor"):
        analyse(up, chair.bodies, chair.contact_pressures, **QUICK)


@pytest.mark.parametrize("bad", [0, -0.01, float("nan"), float("inf"), "thick"])
def test_bad_thickness_is_one_clear_error(chair, bad):
    with pytest.raises(StructureError, match="positive number of metres"):
        _run(chair, thickness=bad, **QUICK)


def test_unknown_material_lists_the_names():
    with pytest.raises(Exception, match="expected one of birch-plywood, mdf, pla, petg, aluminium-6061, steel, gfrp"):
        get_material("oak")


def test_every_material_has_a_source_and_sane_values():
    assert set(MATERIALS) == {"birch-plywood", "mdf", "pla", "petg", "aluminium-6061", "steel", "gfrp"}
    for m in MATERIALS.values():
        assert 1e8 < m.youngs_modulus_pa < 3e11 and 0 < m.poisson_ratio < 0.5
        assert 1e6 < m.strength_pa < 1e9 and 500 < m.density_kg_m3 < 9000
        assert len(m.source) > 20


def test_thinner_shells_are_weaker_and_softer(chair):
    """Safety factor and stiffness fall with the thickness (no distorted element decides the maximum)."""
    figures = [_run(chair, material="pla", thickness=t, **QUICK).summary for t in (0.0045, 0.006, 0.0075, 0.01)]
    sf = [f["safety_factor"] for f in figures]
    defl = [f["max_deflection_m"] for f in figures]
    assert sf == sorted(sf) and defl == sorted(defl, reverse=True)


def test_the_structure_package_does_not_use_the_plugin_manager():
    import subprocess
    import sys

    code = (
        "import sys; import seatkit.structure, seatkit.structure.build, seatkit.structure.picture; "
        "print('seatkit.plugins' in sys.modules, 'seatkit.hookspecs' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]  # (pluggy itself comes with `import seatkit`, for its hook markers)


def test_the_bench_of_three_people_is_carried_by_the_floor_to_1e6():
    """Three people on the bench, 2 cm plywood at the default mesh: the floor reaction equals the load to 1e-6.

    Its tight curls fold the 2 cm offset (about 190 distorted elements, whose
    matrices are up to 1e10 times stiffer than a sound one's): the plain
    element product missed the load by 2.5e-6 there, the stable one does not
    (docs/structure.md, "Solve").
    """
    from seatkit.pipeline import build
    from seatkit.recipe import apply_overrides, load_recipe

    poses = ["upright-sitting", "reclined-sitting", "crossed-legs-knees"]
    bench = build(apply_overrides(load_recipe(None)[0], template="bench", poses=poses, baseline=""), write=False)
    s = _run(bench, material="birch-plywood", thickness=0.02).summary
    weight = sum(b.mass for b in bench.bodies) * GRAVITY
    assert s["people_load_n"] == pytest.approx([weight / 3] * 3, rel=1e-9)
    assert s["distorted_elements"] > 50  # the case that needs the stable product
    applied, reaction = np.array(s["applied_load_vector_n"]), np.array(s["floor_reaction_vector_n"])
    assert np.abs(applied + reaction).max() <= 1e-6 * s["applied_load_n"]
