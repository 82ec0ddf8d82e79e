"""The soft-tissue contact model (seatkit.pressure.compliant): analytic cases and invariants."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from seatkit.constants import GRAVITY
from seatkit.errors import InfeasibleSupportError
from seatkit.model import Body
from seatkit.pressure.compliant import contact_with_planes, friction_state, load_shares, solve_compliant

E = 40e3  # Pa
H = 0.03  # m


def _block(com_offset=(0.0, 0.0, 0.0), mass=75.0):
    """A rigid block 0.4 x 0.1 x 0.3 m, its bottom face at y = 0, all mass on one segment."""
    box = trimesh.creation.box(extents=(0.4, 0.1, 0.3))
    for _ in range(4):
        box = box.subdivide()
    v = np.asarray(box.vertices) + [0, 0.05, 0]
    n = len(v)
    weights = np.zeros((n, 21))
    weights[:, 0] = 1.0
    masses = np.zeros(21)
    masses[0] = mass
    com = np.zeros((21, 3))
    com[0] = np.array([0, 0.05, 0]) + com_offset
    return Body(
        vertices=v,
        faces=np.asarray(box.faces, dtype=np.int64),
        weights=weights,
        joints=np.zeros((21, 3)),
        tips=np.zeros((21, 3)),
        segment_mass=masses,
        segment_com=com,
        name="block",
    )


def _solve(body, normal=(0.0, 1.0, 0.0), mu=0.5):
    contact = contact_with_planes(body, [("floor", (0, 0, 0), normal, None)], reach=0.01)
    return solve_compliant(body, contact, youngs_modulus=E, thickness=np.full(len(body.vertices), H), mu=mu)


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_flat_punch_on_an_elastic_foundation_gives_p_equal_k_d(mu):
    body = _block()
    field = _solve(body, mu=mu)
    weight = 75.0 * GRAVITY
    loaded = field.pressure > 1.0
    # a centred rigid punch sinks evenly: the same pressure everywhere, W over the contact area
    area = field.area[loaded].sum()
    np.testing.assert_allclose(field.pressure[loaded], weight / area, rtol=1e-5)
    # and that pressure is the foundation's stiffness times the sink: p = (E / h) d
    d = field.params["max_compression_m"]
    np.testing.assert_allclose(weight / area, E / H * d, rtol=1e-5)
    np.testing.assert_allclose(field.force[:, 1].sum(), weight, rtol=1e-9)
    assert np.abs(field.force[:, [0, 2]].sum(axis=0)).max() < 1e-6 * weight  # no friction needed on a level floor


def test_an_off_centre_load_tilts_the_punch_and_the_pressure_centre_is_under_the_mass():
    body = _block(com_offset=(0.05, 0.0, 0.0))
    field = _solve(body)
    weight = 75.0 * GRAVITY
    cop = (field.force[:, 1] @ body.vertices) / field.force[:, 1].sum()
    assert abs(cop[0] - 0.05) < 1e-6 and abs(cop[2]) < 1e-6
    loaded = field.pressure > 1.0
    x = body.vertices[loaded, 0]
    p = field.pressure[loaded]
    # a rigid tilt: pressure linear in x on the flat bottom (Winkler), higher under the mass
    bottom = loaded & (np.abs(body.vertices[:, 1]) < 1e-9)
    fit = np.polyfit(body.vertices[bottom, 0], field.pressure[bottom], 1, full=True)
    assert fit[0][0] > 0
    assert fit[1][0] / bottom.sum() < (1e-6 * p.mean()) ** 2 + 1e-12
    assert abs(field.force[:, 1].sum() - weight) < 1e-6 * weight
    assert x.size > 0


def test_friction_holds_the_block_on_a_slope_within_the_exact_cone_and_fails_beyond_it():
    body = _block()
    mu = 0.5
    a = np.radians(20.0)  # tan 20 deg = 0.36 < mu
    field = _solve(body, normal=(np.sin(a), np.cos(a), 0.0), mu=mu)
    weight = 75.0 * GRAVITY
    np.testing.assert_allclose(field.force.sum(axis=0), [0, weight, 0], atol=1e-6 * weight)
    tangential = np.sqrt(np.maximum((field.force**2).sum(axis=1) - field.normal_force**2, 0))
    assert (tangential <= mu * field.normal_force + 1e-9).all()  # the circular cone, not a pyramid
    assert field.residuals["friction_excess"] <= 1e-9
    state = friction_state(field, mu=mu)
    assert state["above_coulomb_share"] == 0.0
    steep = np.radians(35.0)  # tan 35 deg = 0.70 > mu
    with pytest.raises(InfeasibleSupportError):
        _solve(body, normal=(np.sin(steep), np.cos(steep), 0.0), mu=mu)


def test_a_seated_body_on_a_rigid_flat_seat_and_floor_is_in_equilibrium_with_a_peak_in_the_published_spread():
    from seatkit.body import load_pose, load_rig, pose_rig
    from seatkit.skeleton import SEGMENT_INDEX

    body = pose_rig(load_rig("default-male"), load_pose("upright-sitting"))
    owner = np.argmax(body.weights, axis=1)
    seat = np.isin(owner, [SEGMENT_INDEX[s] for s in ("Hips", "RightUpLeg", "LeftUpLeg")])
    feet = np.isin(owner, [SEGMENT_INDEX[s] for s in ("RightFoot", "LeftFoot")])
    top = float(body.vertices[seat, 1].min())
    contact = contact_with_planes(body, [("seat", (0, top, 0), (0, 1, 0), seat), ("floor", (0, 0, 0), (0, 1, 0), feet)])
    field = solve_compliant(body, contact)
    weight = body.segment_mass.sum() * GRAVITY
    assert field.residuals["total_force_relative"] < 1e-6
    assert field.residuals["net_moment"] < 1e-6 * weight
    assert field.residuals["friction_excess"] <= 1e-9 and field.residuals["min_normal_force"] >= 0
    shares = load_shares(body, field)
    assert abs(sum(shares.values()) - 1.0) < 1e-6
    # Linder-Ganz et al. 2007: 17 +/- 4 kPa under the ischial tuberosities on a rigid seat
    assert 13e3 <= field.pressure[seat].max() <= 21e3
    assert field.params["max_strain"] < 1.0  # no tissue column is compressed through
