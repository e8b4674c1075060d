"""Rigid boxes in contact with planes: closed forms of impact, incline and belt."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact.law import REFERENCE_AREA, ContactLaw
from flexparcel.contact.planes import plane_contact_forces
from flexparcel.elements.rotations import rotation_exp
from flexparcel.model.rigid import RoundedBox

G = 9.81


def _box_on_plane(law, *, gravity, z0, surface_velocity=(0.0, 0.0, 0.0), mass=0.1):
    b = fp.ModelBuilder(gravity=gravity)
    node = b.add_rigid_body(RoundedBox(0.1, 0.08, 0.02, 0.002, mass=mass), (0.0, 0.0, z0))
    b.add_contact(node, b.add_plane((0, 0, 0), (0, 0, 1), surface_velocity), law)
    return b.finalize(), node


def _linear_law(mu_s, mu_d, stick_stiffness=None):
    """Linear spring 1e5 N/m per corner with constant damping 20 N s/m (zeta ~ 0.2 per corner;
    resting penetrations are microns, where the STEP option would give almost no damping and
    the box would chatter) and friction mu_s / mu_d. The law is per unit area; a box corner
    carries REFERENCE_AREA (add_contact's default for a rigid body), so these per-point values
    (and k_t [N/m]) are given per point of that area."""
    return ContactLaw.from_point_values(
        REFERENCE_AREA,
        stiffness=1e5,
        stick_stiffness=stick_stiffness,
        damping=20.0,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=mu_s,
        mu_dynamic=mu_d,
    )


@pytest.mark.parametrize("zeta", [0.1, 0.3])
def test_impact_restitution_matches_linear_spring_dashpot(zeta):
    # Linear spring c and constant damping d (indentation option, m_d = 1, m_i = 0), R_df = 0:
    # the force c s + d s' may not pull, so contact ends when it reaches zero, before s = 0.
    # Closed form (Schwager & Poschel 2007, Granular Matter 9:465, eq. 12):
    #   e = exp(-zeta/sqrt(1-zeta^2) (pi - arctan(2 zeta sqrt(1-zeta^2) / (1 - 2 zeta^2)))).
    # The box lands flat on its 4 corners (each c, d, a quarter of the mass), no gravity, at
    # 1 m/s. The integrator only sees contact end at a step end: O(h) error; with the local
    # error tolerance 1e-8 m it is measured 0.25-0.5 %; allowed 1 %.
    m, c = 0.1, 1e5
    d = 2 * zeta * np.sqrt(c * m / 4)
    law = ContactLaw.from_point_values(  # c, d per corner (a corner carries REFERENCE_AREA)
        REFERENCE_AREA,
        stiffness=c,
        damping=d,
        damping_option="indentation",
        damping_exponent=1.0,
        indentation_exponent=0.0,
    )
    model, node = _box_on_plane(law, gravity=(0, 0, 0), z0=0.0101, mass=m)
    s = model.initial_state()
    s.velocities[node, 2] = -1.0
    r = fp.simulate(
        model, 0.004, dt_out=1e-4, state=s, options=fp.IntegratorOptions(tol_displacement=1e-8)
    )
    wd = np.sqrt(1 - zeta**2)
    e_exact = np.exp(-zeta / wd * (np.pi - np.arctan(2 * zeta * wd / (1 - 2 * zeta**2))))
    assert r.velocities[-1, node, 2] == pytest.approx(e_exact, rel=1e-2)
    assert np.abs(r.rotation_vectors[:, node]).max() < 1e-9  # symmetric landing: no tilt


def _incline(theta_deg, mu_s, mu_d, t_end):
    # gravity tilted by theta instead of the plane: the same physics, corners stay in the plane
    th = np.radians(theta_deg)
    law = _linear_law(mu_s, mu_d)
    model, node = _box_on_plane(
        law, gravity=(G * np.sin(th), 0.0, -G * np.cos(th)), z0=0.01 - 0.1 * G * np.cos(th) / 4e5
    )
    r = fp.simulate(model, t_end, dt_out=0.01)
    return r.time, r.positions[:, node, 0], r.velocities[:, node, 0]


def test_incline_sticks_below_and_slides_above_the_friction_angle():
    # tan(theta) < mu_s: the regularised law of eq. (8) holds the box with a slip speed below
    # v_s = 1 mm/s (the law needs |v| ~ v_s tan(theta)/mu_s to produce the holding force).
    t, x, v = _incline(15.0, 0.4, 0.3, 0.5)
    assert np.abs(v[10:]).max() < 1e-3
    # tan(theta) > mu_s: slides with a = g (sin(theta) - mu_d cos(theta)) once |v| > v_d.
    t, x, v = _incline(30.0, 0.4, 0.3, 0.5)
    th = np.radians(30.0)
    a_exact = G * (np.sin(th) - 0.3 * np.cos(th))
    a = np.polyfit(t[20:], v[20:], 1)[0]
    assert a == pytest.approx(a_exact, rel=1e-2)


def test_box_dropped_on_belt_reaches_belt_speed():
    # t = v / (mu g), slip s = v^2 / (2 mu g) (mu_s = mu_d = mu), within 2 %
    mu, vb = 0.5, 1.6
    law = _linear_law(mu, mu)
    model, node = _box_on_plane(
        law, gravity=(0, 0, -G), z0=0.01 - 0.1 * G / 4e5, surface_velocity=(vb, 0.0, 0.0)
    )
    r = fp.simulate(model, 0.6, dt_out=1e-3)
    v = r.velocities[:, node, 0]
    t_exact = vb / (mu * G)
    t_reach = r.time[np.argmax(v >= vb * (1 - 1e-3))]
    assert t_reach == pytest.approx(t_exact, rel=2e-2)
    x_belt = vb * t_exact
    slip = x_belt - np.interp(t_exact, r.time, r.positions[:, node, 0])
    assert slip == pytest.approx(vb**2 / (2 * mu * G), rel=2e-2)


def test_contact_point_tangents_match_finite_differences():
    law = ContactLaw(
        stiffness=1e4,
        stiffness_exponent=1.5,
        damping=5.0,
        damping_option="step",
        damping_depth=2e-3,
        mu_static=0.5,
        mu_dynamic=0.4,
    )
    rng = np.random.default_rng(4)
    pos = np.array([[0.01, -0.02, 0.003]])
    rot = np.array([rotation_exp(np.array([0.1, -0.05, 0.3]))])
    vel = np.array([[0.01, 0.002, -0.05, 0.3, -0.2, 0.5]])
    args = (
        np.array([0]),
        np.array([[0.04, 0.03, -0.008]]),
        np.array([0.002]),
        np.array([0]),
        np.array([0]),
        np.ones(1),
        np.ones(1),  # area 1 m^2: the per-area law acts as this point's law
        np.zeros((1, 3)),
        np.array([[0.0, 0.0, 1.0]]),
        np.array([[0.05, 0.0, 0.0]]),
        np.zeros((1, 3)),
        np.zeros((1, 3)),  # a half-space
        law.packed()[None],
    )

    def run(p, r, v):
        f = np.zeros((1, 6))
        dq = np.zeros((1, 6, 6))
        dv = np.zeros((1, 6, 6))
        n = plane_contact_forces(
            *args,
            p,
            r,
            v,
            f,
            dq,
            dv,
            np.ones(1),
            0.01,
            np.zeros(1),
            np.zeros((1, 3)),
            np.zeros((1, 3)),
            1e-3,
            p,
            r,
        )[0]
        return f[0], dq[0], dv[0], n

    f0, dq, dv, n = run(pos, rot, vel)
    assert n == 1
    eps = 1e-7
    for j in range(6):
        dp, dr, dvv = [np.zeros(3) for _ in range(3)]
        if j < 3:
            dp[j] = eps
        else:
            dr[j - 3] = eps
        fp_ = run(pos + dp, np.array([rotation_exp(dr) @ rot[0]]), vel)[0]
        fm_ = run(pos - dp, np.array([rotation_exp(-dr) @ rot[0]]), vel)[0]
        # the rate's w x (dtheta x rho) term is left out of the tangent by design: compare the
        # position part exactly and the spin part to the size of that term
        tol = 1e-5 * np.abs(dq).max() if j < 3 else 5e-2 * np.abs(dq).max()
        assert np.abs((fp_ - fm_) / (2 * eps) - dq[:, j]).max() <= tol
        vp, vm = vel.copy(), vel.copy()
        vp[0, j] += eps
        vm[0, j] -= eps
        fdv = (run(pos, rot, vp)[0] - run(pos, rot, vm)[0]) / (2 * eps)
        assert np.abs(fdv - dv[:, j]).max() <= 1e-5 * np.abs(dv).max()
    del rng


def test_box_pushed_by_belt_along_a_fence():
    # A belt at speed v_b running at theta = 45 deg into a fixed fence drags a box along it at
    # u = v_b (cos(theta) - mu_f sin(theta)) whatever the belt friction (steady state: the belt
    # friction's components along and into the fence balance the fence's friction mu_f N and
    # its normal force N). The approach is exponential with a time constant ~|v_b - v|/(mu g)
    # ~ 0.25 s: within 2 % after 1.5 s.
    vb, th, mu_f = 1.6, np.radians(45.0), 0.3
    belt_law = _linear_law(0.5, 0.5)
    fence_law = _linear_law(mu_f, mu_f)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    node = b.add_rigid_body(
        RoundedBox(0.1, 0.08, 0.02, 0.002, mass=0.1), (0.0, -0.02, 0.01 - 0.1 * G / 4e5)
    )
    belt = b.add_plane((0, 0, 0), (0, 0, 1), (vb * np.cos(th), -vb * np.sin(th), 0.0))
    fence = b.add_plane((0.0, -0.06, 0.0), (0.0, 1.0, 0.0))
    b.add_contact(node, belt, belt_law)
    b.add_contact(node, fence, fence_law)
    r = fp.simulate(b.finalize(), 1.5, dt_out=0.01)
    u = r.velocities[-10:, node, 0]
    assert np.all(np.abs(u / (vb * (np.cos(th) - mu_f * np.sin(th))) - 1.0) < 2e-2)
    assert np.abs(r.velocities[-10:, node, 1]).max() < 1e-2  # pressed against the fence


@pytest.mark.parametrize("theta_deg", [15.0, 30.0])
def test_stick_model_holds_on_incline_and_lets_slide_above(theta_deg):
    # Stick model (tangential spring k_t with slip limit mu_s F_N): below the friction angle
    # the box comes to rest and then moves less than the creep bound mu_s F_N / k_t per corner
    # (F_N = m g cos/4 here: 1e-5 m with k_t = 1e4 N/m); above it, it slides with
    # g (sin - mu_d cos) (1 %).
    th = np.radians(theta_deg)
    mu_s, mu_d, kt, m = 0.4, 0.3, 1e4, 0.1
    law = _linear_law(mu_s, mu_d, stick_stiffness=kt)
    model, node = _box_on_plane(
        law,
        gravity=(G * np.sin(th), 0.0, -G * np.cos(th)),
        z0=0.01 - m * G * np.cos(th) / 4e5,
        mass=m,
    )
    # the tangential springs (4 k_t on 0.1 kg: period 10 ms) must be resolved by the steps;
    # with h = 20 ms the scheme's high-frequency response alternates the spring force and a
    # corner slips now and then (measured: 31 um in 0.5 s)
    r = fp.simulate(model, 0.5, dt_out=0.01, options=fp.IntegratorOptions(dt_max=2e-3))
    x, v = r.positions[:, node, 0], r.velocities[:, node, 0]
    if np.tan(th) < mu_s:
        # gravity acts suddenly at t = 0: the tangential spring overshoots and the box slips a
        # little while it rocks in; after that it must not creep (regularised friction alone
        # creeps at ~0.7 v_s = 0.7 mm/s here, i.e. 0.3 mm in 0.4 s)
        bound = mu_s * m * G * np.cos(th) / 4 / kt
        assert abs(x[-1] - x[10]) < bound
        assert np.abs(x).max() < 1e-4
    else:
        a = np.polyfit(r.time[20:], v[20:], 1)[0]
        assert a == pytest.approx(G * (np.sin(th) - mu_d * np.cos(th)), rel=1e-2)


def _monitored_box_on_plane(law, *, gravity, z0, mass=0.1, surface_velocity=(0.0, 0.0, 0.0)):
    b = fp.ModelBuilder(gravity=gravity)
    node = b.add_rigid_body(RoundedBox(0.1, 0.08, 0.02, 0.002, mass=mass), (0.0, 0.0, z0))
    plane = b.add_plane((0, 0, 0), (0, 0, 1), surface_velocity)
    with b.monitored_contacts():
        b.add_contact(node, plane, law)
    return b.finalize(), node


@pytest.mark.parametrize("stiffness", [1e5, 1e6])
def test_monitored_impulse_of_an_impact_is_the_momentum_it_reverses(stiffness):
    # Newton's second law over the whole impact: the plane's impulse on a box that meets it at
    # 1 m/s (no gravity) is m (v_after - v_before), whatever the contact's stiffness. The
    # recorded impulse is the contact's share of the scheme's own momentum update
    # (GeneralizedAlpha._monitor_step), so it matches to round-off and the Newton residual
    # (measured 1e-14 and 2e-12 relative; allowed 1e-6). The end-of-step forces times h alone
    # were 6 % off here: the steps change size through the impact.
    m = 0.1
    d = 2 * 0.2 * np.sqrt(stiffness * m / 4)  # zeta = 0.2 per corner
    law = ContactLaw.from_point_values(REFERENCE_AREA, stiffness=stiffness, damping=d,
                                       damping_option="indentation",
                                       indentation_exponent=0.0)  # fmt: skip
    model, node = _monitored_box_on_plane(law, gravity=(0, 0, 0), z0=0.0101, mass=m)
    s = model.initial_state()
    s.velocities[node, 2] = -1.0
    r = fp.simulate(model, 0.03, state=s, dt_out=0.001)
    v_after = r.velocities[-1, node, 2]
    assert 0.1 < v_after < 1.0  # it bounced off, and the dashpot took energy
    impulse = r.monitored_impulses[:, node]
    assert impulse.shape == (r.time.size, 3) and np.all(impulse[0] == 0.0)
    assert impulse[-1, 2] == pytest.approx(m * (v_after + 1.0), rel=1e-6)
    # the interval means add up to the impulse
    mean = r.mean_monitored_forces()
    assert mean.shape == (r.time.size - 1, 3)
    assert np.sum(mean[:, 2] * np.diff(r.time)) == pytest.approx(impulse[-1, 2], rel=1e-12)


@pytest.mark.parametrize("stiffness", [1e5, 1e6])
def test_monitored_mean_force_of_a_box_on_a_belt_is_its_weight_and_friction(stiffness):
    # A box dropped onto a belt that slides under it at 0.5 m/s: over every output interval
    # the belt's impulse is the box's momentum change less gravity's (the shares of the
    # scheme's momentum balance, see GeneralizedAlpha._monitor_step), to the residual Newton
    # leaves (measured 4e-7 of m g; allowed 1e-5). Over
    # 0.05-0.1 s, while it still slips (it reaches belt speed after v / (mu g) = 0.17 s),
    # the mean force is its weight m g up and the dynamic friction mu m g along the belt,
    # for either contact stiffness; the box still rocks on its corners (each interval's mean
    # is within 2 % of m g), so the window's mean is allowed 1 %.
    m, mu = 0.1, 0.3
    law = ContactLaw.from_point_values(REFERENCE_AREA, stiffness=stiffness, damping=20.0,
                                       damping_option="indentation", indentation_exponent=0.0,
                                       mu_static=mu, mu_dynamic=mu)  # fmt: skip
    z0 = 0.01 - m * G / (4 * stiffness)  # the corners at their resting penetration
    model, node = _monitored_box_on_plane(law, gravity=(0, 0, -G), z0=z0, mass=m,
                                          surface_velocity=(0.5, 0.0, 0.0))  # fmt: skip
    r = fp.simulate(model, 0.1, dt_out=0.005)
    mean = r.mean_monitored_forces([node])
    dt = np.diff(r.time)
    dv = np.diff(r.velocities[:, node, :3], axis=0)
    np.testing.assert_allclose(mean, m * dv / dt[:, None] + [0.0, 0.0, m * G], rtol=0,
                               atol=1e-5 * m * G)  # fmt: skip
    late = r.time[1:] > 0.05 + 1e-9
    assert np.all(r.velocities[1:, node, 0][late] < 0.45)  # still slipping
    window = np.sum(mean[late] * dt[late, None], axis=0) / dt[late].sum()
    assert window[2] == pytest.approx(m * G, rel=1e-2)
    assert window[0] == pytest.approx(mu * m * G, rel=1e-2)


def test_a_model_without_monitored_contacts_records_no_impulse():
    law = _linear_law(0.3, 0.3)
    model, _ = _box_on_plane(law, gravity=(0, 0, -G), z0=0.0101)
    r = fp.simulate(model, 0.002, dt_out=0.001)
    assert r.monitored_impulses is None
    with pytest.raises(ValueError, match="monitors no contact"):
        r.mean_monitored_forces()
