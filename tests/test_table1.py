"""The paper's Table 1 claim on every supportable library pose (issue 9).

A full default build per pose (chair, both refiners, evaluation against the
flat-patch baseline; nothing written): our surface must have the smaller
average distance, average pressure and maximum pressure, and reach at most
5 mm into the body. ``python benchmarks/table1.py`` prints the same figures.
"""

import numpy as np
import pytest

from seatkit.body import list_poses
from seatkit.constants import GRAVITY
from seatkit.pipeline import build

POSES = [info.name for info in list_poses() if info.supported]


@pytest.fixture(scope="module")
def pm():
    from seatkit.plugins import get_plugin_manager

    return get_plugin_manager(autoload=False)


@pytest.mark.parametrize("pose", POSES)
def test_ours_beats_the_flat_patch_as_in_table1(pm, pose):
    r = build({"template": "chair", "bodies": [{"model": "default-male", "pose": pose}]}, pm=pm, write=False)
    ours, base = r.metrics["ours"][0], r.metrics["baseline"][0]
    assert ours["supported"] and base["supported"]
    for key in ("avg_distance_m", "avg_pressure_pa", "max_pressure_pa"):
        assert ours[key] < base[key], f"{pose}: {key} ours {ours[key]:.4g} >= flat patch {base[key]:.4g}"
    assert ours["max_penetration_m"] <= 0.005
    assert ours["max_body_depth_m"] <= 0.005
    # the pressure recomputed on our surface still carries the whole body
    field = r.contact_pressures[0]
    weight = r.bodies[0].segment_mass.sum() * GRAVITY
    assert field.force.sum(axis=0)[1] == pytest.approx(weight, rel=1e-6)
    # and so does the soft-tissue interface pressure on it, inside the exact Coulomb cone
    soft, figures = r.interface_pressures[0], r.metrics["interface"][0]
    assert figures["supported"] and figures["model"] == "winkler-soft-tissue"
    np.testing.assert_allclose(soft.force.sum(axis=0), [0, weight, 0], atol=1e-6 * weight)
    assert soft.residuals["net_moment"] < 1e-6 * weight
    tangential = np.sqrt(np.maximum((soft.force**2).sum(axis=1) - soft.normal_force**2, 0))
    assert (tangential <= soft.params["mu"] * soft.normal_force + 1e-9).all()
    assert sum(figures["load_share"].values()) == pytest.approx(1.0, abs=1e-6)
    assert figures["friction"]["above_coulomb_share"] == 0.0
