"""Bounded planes (a belt of finite width and length: a slab with rounded edges).

The closed forms: on the top face the slab is the half-space (same penetration and normal);
beside it the surface is a cylinder of the edge radius round the rectangle's edge, beyond a
corner a sphere. Tangents are checked against central finite differences. Dynamics: a film
hanging over the belt's side edge drapes over it (a belt cut off at its edge threw such a
sheet 1.7 m up), and a box carried past the belt's end falls off it.
"""

from __future__ import annotations

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact import ContactLaw
from flexparcel.contact.planes import PlaneBounds, plane_contact_forces, plane_gap
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.rigid import RoundedBox

N = np.array([0.0, 0.0, 1.0])
AXIS = np.array([1.0, 0.0, 0.0])
# a belt 0.4 m long and 0.2 m wide round the origin, its surface at z = 0, edge radius 5 mm
EXTENT = np.array([0.2, 0.1, 0.005])
HALF_SPACE = np.zeros(3)


def _gap(p, radius=0.001, extent=EXTENT):
    return plane_gap(np.asarray(p, float), radius, np.zeros(3), N, AXIS, extent)


def test_top_face_is_the_half_space():
    for p in ([0.0, 0.0, 0.0005], [0.19, -0.09, -0.0003], [-0.1, 0.05, 0.002]):
        s, n, curv = _gap(p)
        s0, n0, _ = _gap(p, extent=HALF_SPACE)
        assert s == pytest.approx(s0, abs=1e-15)
        np.testing.assert_array_equal(n, n0)
        assert not curv.any()


def test_side_edge_is_a_cylinder_and_a_corner_a_sphere():
    rb, r = EXTENT[2], 0.001
    # beside the side edge y = 0.1 at the slab's mid-plane height z = -rb, 2 mm out
    s, n, curv = _gap([0.05, 0.1 + 0.002, -rb])
    assert s == pytest.approx(r + rb - 0.002)
    np.testing.assert_allclose(n, [0.0, 1.0, 0.0], atol=1e-15)
    # the cylinder's curvature: dn/dp = (I - n n^T - e e^T) / dist with e the edge direction
    np.testing.assert_allclose(curv, np.diag([0.0, 0.0, 1.0]) / 0.002, atol=1e-9)
    # 45 degrees round the edge: the normal points out and up
    d = 0.004
    s, n, _ = _gap([0.0, 0.1 + d / np.sqrt(2), -rb + d / np.sqrt(2)])
    assert s == pytest.approx(r + rb - d)
    np.testing.assert_allclose(n, [0.0, 1.0 / np.sqrt(2), 1.0 / np.sqrt(2)], atol=1e-12)
    # beyond the corner (x = 0.2, y = 0.1): a sphere, dn/dp = (I - n n^T) / dist
    p = np.array([0.2, 0.1, -rb]) + 0.003 * np.array([1.0, 1.0, 1.0]) / np.sqrt(3)
    s, n, curv = _gap(p)
    assert s == pytest.approx(r + rb - 0.003)
    np.testing.assert_allclose(curv, (np.eye(3) - np.outer(n, n)) / 0.003, atol=1e-9)
    # below the slab: pushed down, not up through it
    s, n, _ = _gap([0.0, 0.0, -2 * rb - 0.0005])
    assert s == pytest.approx(0.0005) and n[2] == -1.0


def test_penetration_is_continuous_across_the_edge():
    # a node moving sideways over the side edge at a fixed height just under the surface
    ys = np.linspace(0.09, 0.11, 2001)
    s = np.array([_gap([0.0, y, -0.0002])[0] for y in ys])
    # the distance to a convex set is 1-Lipschitz: steps of 10 um change it by 10 um at
    # most, so there is no jump anywhere (a cut-off plane jumps by the full depth)
    assert np.abs(np.diff(s)).max() <= (ys[1] - ys[0]) * (1 + 1e-9)
    assert s[0] == pytest.approx(0.0012) and s[-1] < 0.0


def _forces(pos, vel, law, extent, rot=None):
    rot = np.eye(3)[None] if rot is None else rot
    f = np.zeros((1, 6))
    dq = np.zeros((1, 6, 6))
    dv = np.zeros((1, 6, 6))
    plane_contact_forces(
        np.array([0]), np.zeros((1, 3)), np.array([0.001]), np.array([0]), np.array([0]),
        np.ones(1), np.full(1, 1e-4), np.zeros((1, 3)), N[None], np.array([[0.3, 0.0, 0.0]]),
        AXIS[None], extent[None], law.packed()[None], pos, rot, vel, f, dq, dv, np.ones(1),
        1e9, np.zeros(1), np.zeros((1, 3)), np.zeros((1, 3)), 1e-3, pos, rot,
    )  # fmt: skip
    return f[0], dq[0]


def _fd_position_tangent(pos, vel, law, extent, h=1e-8):
    fd = np.zeros((6, 3))
    for j in range(3):
        dp = np.zeros((1, 3))
        dp[0, j] = h
        fd[:, j] = (_forces(pos + dp, vel, law, extent)[0]
                    - _forces(pos - dp, vel, law, extent)[0]) / (2 * h)  # fmt: skip
    return fd


@pytest.mark.parametrize(
    "where",
    [[0.05, 0.0, -0.0003], [0.05, 0.1 + 0.0035, -0.003], [0.2 + 0.002, 0.1 + 0.002, -0.002]],
)
def test_normal_force_tangent_matches_finite_differences(where):
    # top face, side edge (cylinder) and corner (sphere); frictionless, so the tangent is
    # exact: the normal force's magnitude and its turning normal on the rounded edge
    law = ContactLaw(stiffness=6.11e9, damping=5.91e6)
    pos = np.array([where])
    vel = np.zeros((1, 6))
    f, dq = _forces(pos, vel, law, EXTENT)
    assert np.linalg.norm(f[:3]) > 0.0
    fd = _fd_position_tangent(pos, vel, law, EXTENT)
    np.testing.assert_allclose(dq[:3, :3], fd[:3], rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_box_corner_on_the_rounded_edge_tangent_matches_finite_differences():
    # a rounded box's corner (offset b from its node, turned by R) on the side edge: the
    # force's derivative by the node's position and spin, frictionless and at rest in spin
    # (the rate's w x (dtheta x rho) term, left out by design, is then zero), so exact
    from flexparcel.elements.rotations import rotation_exp

    law = ContactLaw(stiffness=6.11e9, damping=5.91e6)
    offset = np.array([[0.02, -0.01, -0.005]])
    r0 = rotation_exp(np.array([0.2, -0.1, 0.4]))
    corner = np.array([0.05, 0.1 + 0.003, -0.003])  # near the edge axis at z = -5 mm
    pos = (corner - r0 @ offset[0])[None]
    vel = np.array([[0.02, -0.01, 0.03, 0.0, 0.0, 0.0]])

    def force(p, r):
        f = np.zeros((1, 6))
        dq = np.zeros((1, 6, 6))
        plane_contact_forces(
            np.array([0]), offset, np.array([0.003]), np.array([0]), np.array([0]),
            np.ones(1), np.full(1, 1e-4), np.zeros((1, 3)), N[None], np.array([[0.3, 0.0, 0.0]]),
            AXIS[None], EXTENT[None], law.packed()[None], p, r[None], vel, f, dq,
            np.zeros((1, 6, 6)), np.ones(1), 1e9, np.zeros(1), np.zeros((1, 3)),
            np.zeros((1, 3)), 1e-3, p, r[None],
        )  # fmt: skip
        return f[0], dq[0]

    f0, dq = force(pos, r0)
    assert np.linalg.norm(f0[:3]) > 0.0
    h = 1e-8
    for j in range(6):
        dp, dr = np.zeros((1, 3)), np.zeros(3)
        if j < 3:
            dp[0, j] = h
        else:
            dr[j - 3] = h
        fd = (force(pos + dp, rotation_exp(dr) @ r0)[0]
              - force(pos - dp, rotation_exp(-dr) @ r0)[0]) / (2 * h)  # fmt: skip
        np.testing.assert_allclose(dq[:3, j], fd[:3], rtol=1e-5, atol=1e-6 * np.abs(dq[:3]).max())


def test_friction_on_the_edge_leaves_out_only_the_turning_slip_direction():
    # with friction the tangent leaves out how the slip direction and the arm turn with the
    # normal on the rounded edge: an error of the order of the friction force over the
    # distance to the edge's axis, |F_T| / dist (module docstring)
    law = ContactLaw(stiffness=6.11e9, damping=5.91e6, mu_static=0.5, mu_dynamic=0.4)
    dist = 0.0045
    pos = np.array([[0.05, 0.1 + dist / np.sqrt(2), -0.005 + dist / np.sqrt(2)]])
    vel = np.array([[0.0, 0.05, 0.0, 0.0, 0.0, 0.0]])  # slipping across the edge
    f, dq = _forces(pos, vel, law, EXTENT)
    _, n, _ = _gap(pos[0])
    ft = f[:3] - (f[:3] @ n) * n
    assert np.linalg.norm(ft) > 0.1 * np.linalg.norm(f[:3])  # friction is acting
    fd = _fd_position_tangent(pos, vel, law, EXTENT)
    err = np.abs(dq[:3, :3] - fd[:3]).max()
    assert err <= 1.5 * np.linalg.norm(ft) / dist
    assert err <= 0.05 * np.abs(fd[:3]).max()  # and small next to the normal stiffness


def _belt(b: fp.ModelBuilder, speed=0.0, length=0.4, width=0.2):
    bounds = PlaneBounds(axis=(1.0, 0.0, 0.0), length=length, width=width, edge_radius=0.005)
    return b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (speed, 0.0, 0.0), bounds=bounds)


def _hanging_film(bounded: bool):
    """A 60 x 60 mm film (10 mm mesh, 0.05 mm, 100 MPa) lying across the belt's side edge at
    y = 0.1 m with 20 mm over it, released at rest; returns the result and initial y."""
    mat = ShellMaterial(youngs_modulus=100e6, poisson_ratio=0.3, thickness=5e-5,
                        density=950.0, damping_ratio=1e-3)  # fmt: skip
    nx = ny = 7
    x, y = np.meshgrid(np.linspace(-0.03, 0.03, nx), np.linspace(0.06, 0.12, ny), indexing="ij")
    r = 2.5e-5
    pts = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, r)])
    q = np.array([[i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1]
                  for i in range(nx - 1) for j in range(ny - 1)])  # fmt: skip
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(pts, q, material=mat)
    law = ContactLaw.from_paper_units(c_N_per_mm=611, d_Ns_per_mm=0.591, s_max_mm=0.1,
                                      mu_static=0.3, mu_dynamic=0.25)  # fmt: skip
    plane = _belt(b) if bounded else b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    b.add_contact(ids, plane, law.with_stick_model(), radius=r)
    res = fp.simulate(b.finalize(), 0.15, dt_out=0.005,
                      options=fp.IntegratorOptions(rho_inf=0.5, impact_limit="rigid",
                                                   error_estimate="smooth"))  # fmt: skip
    return res.positions[:, ids], pts[:, 1]


def test_film_hanging_over_the_side_edge_drapes_over_it():
    # its centre of mass lies on the belt: the 20 mm overhang swings down round the rounded
    # edge like a flap (measured: its free edge 19 mm below the belt at 0.09 s, then back to
    # 15 mm), the film behind the edge bulges by its bending stiffness (2 mm), and the far
    # part stays on the belt. Nothing is thrown up (a belt cut off at its edge threw such a
    # film 1.7 m up)
    pos, y0 = _hanging_film(bounded=True)
    z = pos[:, :, 2]
    assert z.max() < 5e-3
    assert z[-1, y0 > 0.115].max() < -8e-3  # the free edge hangs
    assert np.abs(z[:, y0 < 0.075]).max() < 1e-3  # the far part stays on the belt
    # on an unbounded plane the same film lies flat: the bound is what lets it hang
    pos, _ = _hanging_film(bounded=False)
    assert np.abs(pos[-1, :, 2]).max() < 1e-3


def test_box_carried_past_the_belt_end_falls_off():
    law = ContactLaw.from_paper_units(c_N_per_mm=611, d_Ns_per_mm=0.591, s_max_mm=0.1,
                                      mu_static=0.5, mu_dynamic=0.4)  # fmt: skip
    b = fp.ModelBuilder()
    box = b.add_rigid_body(RoundedBox(0.06, 0.04, 0.02, edge_radius=0.003, mass=0.1),
                           position=(0.14, 0.0, 0.0101))  # fmt: skip
    b.add_contact(box, _belt(b, speed=1.0), law)
    model = b.finalize()
    # a local error of 0.01 mm per step, as in examples/box_on_belt.py: with the default the
    # box bounces on its stiff corner contacts
    res = fp.simulate(model, 0.4, dt_out=0.01, options=fp.IntegratorOptions(tol_displacement=1e-5))
    x, z = res.positions[:, box, 0], res.positions[:, box, 2]
    on_belt = x < 0.2 - 0.03
    assert np.abs(z[on_belt] - 0.0101).max() < 1e-3  # carried flat while on the belt
    assert x[-1] > 0.2 and z[-1] < -0.1  # past the end and falling
