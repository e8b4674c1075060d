"""Rigid bodies inside the implicit scheme."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.elements.rotations import rotation_exp
from flexparcel.model.rigid import PrescribedMotion, RoundedBox


def test_rounded_box_mass_properties():
    sharp = RoundedBox(0.3, 0.2, 0.05, 0.0, density=500.0)
    assert sharp.volume() == pytest.approx(0.3 * 0.2 * 0.05, rel=1e-14)
    # m (b^2 + c^2) / 12 etc. for a solid cuboid
    m = sharp.total_mass()
    np.testing.assert_allclose(
        np.diag(sharp.inertia()),
        m / 12 * np.array([0.2**2 + 0.05**2, 0.3**2 + 0.05**2, 0.3**2 + 0.2**2]),
        rtol=1e-14,
    )
    # fully rounded to a sphere of radius r: V = 4/3 pi r^3, I = 2/5 m r^2 (numerical quadrature
    # on a 120^3 grid: relative error ~3/120 of the surface layer, allow 1 %)
    ball = RoundedBox(0.1, 0.1, 0.1, 0.05, mass=2.0)
    assert ball.volume() == pytest.approx(4 / 3 * np.pi * 0.05**3, rel=1e-12)
    np.testing.assert_allclose(np.diag(ball.inertia()), 0.4 * 2.0 * 0.05**2, rtol=1e-2)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(length=-0.1, width=0.1, height=0.1, mass=1.0), r"length must be > 0"),
        (
            dict(length=0.1, width=0.1, height=0.1, edge_radius=0.06, mass=1.0),
            r"edge_radius must be in \[0, 0.05\]",
        ),
        (dict(length=0.1, width=0.1, height=0.1), r"exactly one of density"),
        (dict(length=0.1, width=0.1, height=0.1, mass=0.0), r"mass must be > 0"),
    ],
)
def test_rounded_box_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        RoundedBox(**kwargs)


def test_free_fall_is_exact():
    # generalized-alpha integrates a constant acceleration exactly: z = z0 - g t^2 / 2
    b = fp.ModelBuilder()
    node = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.02, 0.005, mass=0.1), (0.0, 0.0, 1.0))
    r = fp.simulate(b.finalize(), 0.3, dt_out=0.05)
    np.testing.assert_allclose(r.positions[:, node, 2], 1.0 - 0.5 * 9.81 * r.time**2, atol=1e-9)


def test_torque_free_rotation_conserves_energy_and_angular_momentum():
    # Euler's equations of a free asymmetric body: kinetic energy and spatial angular momentum
    # J_s w are invariants. With rho_inf = 1 (no numerical dissipation) and h <= 1 ms
    # (|w| h = 5e-3 rad) the O(h^2) errors stay below 1e-4 (energy) and 1e-3 (momentum) in 2 s.
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    node = b.add_rigid_body(RoundedBox(0.3, 0.2, 0.05, 0.01, density=500.0))
    model = b.finalize()
    s = model.initial_state()
    s.velocities[node, 3:] = (0.3, 5.0, 0.2)
    opt = fp.IntegratorOptions(rho_inf=1.0, tol_displacement=1e-7, dt_max=1e-3)
    r = fp.simulate(model, 2.0, state=s, dt_out=0.01, options=opt)
    e = r.energies["kinetic"]
    mom = []
    for k in range(len(r.time)):
        rot = rotation_exp(r.rotation_vectors[k, node])
        mom.append(rot @ model.rigid_inertia[0] @ rot.T @ r.velocities[k, node, 3:])
    mom = np.array(mom)
    assert np.abs(e / e[0] - 1.0).max() < 1e-4
    assert np.abs(mom - mom[0]).max() < 1e-3 * np.linalg.norm(mom[0])


def test_mass_damping_slows_translation_and_spin_alike():
    # Model.mass_damping: -alpha M v on the translations and -alpha J_s w on the spin, so a free
    # body spinning about a principal axis and drifting obeys v' = -alpha v, w' = -alpha w:
    # both decay as exp(-alpha t) (the gyroscopic term vanishes about a principal axis). The
    # trapezoidal-type update is second order: with h <= 1 ms, alpha h = 0.01 and the error over
    # alpha t = 2 is ~ (alpha h)^2 / 12 * alpha t ~ 2e-5 of the amplitude; tolerance 1e-3.
    alpha = 10.0
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0), mass_damping=alpha)
    node = b.add_rigid_body(RoundedBox(0.3, 0.2, 0.05, 0.01, density=500.0))
    model = b.finalize()
    s = model.initial_state()
    s.velocities[node] = (0.4, 0.0, 0.0, 0.0, 0.0, 3.0)
    opt = fp.IntegratorOptions(rho_inf=1.0, tol_displacement=1e-7, dt_max=1e-3)
    r = fp.simulate(model, 0.2, state=s, dt_out=0.05, options=opt)
    decay = np.exp(-alpha * r.time)
    np.testing.assert_allclose(r.velocities[:, node, 0], 0.4 * decay, rtol=1e-3)
    np.testing.assert_allclose(r.velocities[:, node, 5], 3.0 * decay, rtol=1e-3)


def test_prescribed_motion_is_followed():
    b = fp.ModelBuilder()
    w = (0.0, 2.0, 0.0)
    node = b.add_rigid_body(
        RoundedBox(0.1, 0.1, 0.1, 0.05, mass=1.0),
        (0.0, 0.0, 0.5),
        motion=PrescribedMotion(velocity=(1.0, 0.0, 0.0), angular_velocity=w),
    )
    free = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, 0.0, mass=1.0), (1.0, 0.0, 0.5))
    r = fp.simulate(b.finalize(), 0.5, dt_out=0.1)
    np.testing.assert_allclose(r.positions[:, node, 0], r.time, atol=1e-12)
    np.testing.assert_allclose(r.rotation_vectors[-1, node], (0.0, 1.0, 0.0), atol=1e-12)
    assert r.positions[-1, free, 2] < 0.5  # the free one falls


def test_rigid_inertia_tangent_matches_finite_differences():
    # add_rigid_inertia_tangent adds ca dM/dw' + cv dM/dw of the Euler and mass-damping moments
    # M = J_s (w' + alpha w) + w x J_s w (rigid_inertial_moments); central differences of M
    # are exact to round-off for this quadratic in w (step 1e-6, tolerance 1e-7 of the block)
    from flexparcel.integrate import assembly as asm

    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0), mass_damping=30.0)
    node = b.add_rigid_body(RoundedBox(0.3, 0.2, 0.05, 0.01, density=500.0))
    model = b.finalize()
    rot = np.array([rotation_exp(np.array([0.3, -0.5, 0.8]))])
    w = np.array([[0.7, -1.3, 2.1]])
    wd = np.array([[4.0, 1.0, -2.0]])
    slots = model.rigid_rot_slots[0]
    for ca, cv, wrt in ((1.0, 0.0, "acc"), (0.0, 1.0, "vel")):
        data = np.zeros(slots.max() + 1)
        asm.add_rigid_inertia_tangent(model, data, rot, w, ca, cv)
        block = data[slots]
        fd = np.zeros((3, 3))
        for j in range(3):
            d = np.zeros((1, 3))
            d[0, j] = 1e-6
            if wrt == "acc":
                hi = asm.rigid_inertial_moments(model, rot, wd + d, w)
                lo = asm.rigid_inertial_moments(model, rot, wd - d, w)
            else:
                hi = asm.rigid_inertial_moments(model, rot, wd, w + d)
                lo = asm.rigid_inertial_moments(model, rot, wd, w - d)
            fd[:, j] = (hi[node, 3:] - lo[node, 3:]) / 2e-6
        np.testing.assert_allclose(block, fd, atol=1e-7 * np.abs(fd).max())


def test_time_dependent_prescribed_motion_tilts_a_tray():
    # a tray tilting about x: w(t) = 1 rad/s x schedule(t), ramped on over 0.1 s, held 0.2 s,
    # ramped off over 0.1 s. With a fixed axis the angle is exactly the schedule's integral
    # S(t) (PrescribedMotion): 0.05 rad at 0.1 s, 0.25 at 0.3 s, 0.3 from 0.4 s on; the
    # integrator places the body, so the tolerance is round-off.
    from flexparcel.model.schedule import Schedule

    tilt = Schedule((0.0, 0.1, 0.3, 0.4), (0.0, 1.0, 1.0, 0.0))
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    tray = b.add_rigid_body(
        RoundedBox(0.4, 0.3, 0.01, 0.0, mass=2.0),
        motion=PrescribedMotion(angular_velocity=(1.0, 0.0, 0.0), schedule=tilt),
    )
    b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, 0.0, mass=1.0), (1.0, 0.0, 0.5))  # free
    r = fp.simulate(b.finalize(), 0.5, dt_out=0.05)
    angle = np.array([tilt.integral(t) for t in r.time])
    np.testing.assert_allclose(angle[[2, 6, 8, 10]], [0.05, 0.25, 0.3, 0.3], atol=1e-12)
    np.testing.assert_allclose(r.rotation_vectors[:, tray, 0], angle, atol=1e-12)
    np.testing.assert_allclose(r.rotation_vectors[:, tray, 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(r.velocities[:, tray, 3], [tilt(t) for t in r.time], atol=1e-12)


def test_schedule_integral_is_exact_for_the_piecewise_linear_factor():
    # trapezoids between the knots; the factor is constant beyond the ends (1 before 0.1 s and
    # 3 after 0.3 s here), and the integral from 0 to t < 0 is minus that from t to 0
    from flexparcel.model.schedule import Schedule

    s = Schedule((0.1, 0.3), (1.0, 3.0))
    assert s.integral(0.0) == 0.0
    assert s.integral(0.1) == pytest.approx(0.1)
    assert s.integral(0.2) == pytest.approx(0.1 + 0.1 * (1.0 + 2.0) / 2)
    assert s.integral(0.5) == pytest.approx(0.1 + 0.2 * 2.0 + 0.2 * 3.0)
    assert s.integral(-0.2) == pytest.approx(-0.2)
