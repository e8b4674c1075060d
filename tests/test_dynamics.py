"""Implicit dynamics: energy behaviour, Rayleigh damping, time-step convergence."""

import numpy as np
import pytest
from scipy.signal import find_peaks

import flexparcel as fp
from conftest import strip_model
from flexparcel.scenarios.sheet_swing import SheetSwing, sheet_swing_model
from flexparcel.simulate import ModelStepper

# Strip of Sze case 3.1 with rho chosen so that f1 = 10.00 Hz (omega1 = 62.83 rad/s).
L, B, H, RHO = 10.0, 1.0, 0.1, 3.1314e-4
OMEGA1 = 2.0 * np.pi * 10.0


def _mode_like_state(model, v0):
    """Tip-heavy velocity field v_z = v0 (x/L)^2 with the matching Kirchhoff spin
    omega_y = -dv_z/dx, so no shock is put into the rotations."""
    s = model.initial_state()
    x = model.positions0[:, 0] / L
    s.velocities[:, 2] = v0 * x**2
    s.velocities[:, 4] = -v0 * 2.0 * x / L
    s.velocities[model.fixed] = 0.0
    return s


def _energy_error(dt, v0=60.0, t_end=0.3):
    b, tip, _ = strip_model(L, B, H, 8, rho=RHO)
    model = b.finalize()
    opt = fp.IntegratorOptions(
        rho_inf=1.0,
        adaptive=False,
        dt_initial=dt,
        dt_max=1.0,
        tol_displacement=1e-7,
        reuse_factorization=False,
    )
    r = fp.simulate(model, t_end, dt_out=0.004, options=opt, state=_mode_like_state(model, v0))
    e = r.energies["total"]
    return np.abs(e - e[0]).max() / e[0], np.abs(r.positions[:, tip, 2]).max()


def test_undamped_energy_error_is_second_order_and_does_not_drift():
    # rho_inf = 1 is the trapezoidal rule: it conserves the energy of linear systems exactly;
    # for the nonlinear (tip amplitude ~0.9 m = 9 % of L) co-rotational strip its energy error
    # is O(h^2) and bounded (no secular drift): halving h must cut the error by ~4 (>= 3 here),
    # and at h = 1 ms (omega1 h = 0.06) it stays below 1e-4 over three periods.
    errs = [_energy_error(dt)[0] for dt in (0.004, 0.002, 0.001)]
    amp = _energy_error(0.001)[1]
    assert amp > 0.5  # genuinely nonlinear amplitude
    assert errs[0] / errs[1] >= 3.0 and errs[1] / errs[2] >= 3.0, errs
    assert errs[2] < 1e-4, errs


def test_rayleigh_damping_decay_of_first_mode():
    # C = beta K damps mode i with zeta_i = beta omega_i / 2 (RecurDyn's "damping ratio" is
    # beta [s]). Choose beta for zeta1 = 2 %; release a small tip load (linear regime) and fit
    # the logarithmic decrement of the tip peaks after the higher modes (zeta_i ~ 0.02 i^2)
    # have died out. rho_inf = 1 adds no numerical damping; with omega1 h = 0.06 the
    # trapezoidal rule's period error is 0.03 %. Tolerance 3 % on zeta (peak sampling at 1 ms).
    zeta = 0.02
    beta = 2.0 * zeta / OMEGA1
    b, tip, _ = strip_model(L, B, H, 8, rho=RHO, beta=beta)
    b.add_force(tip, (0.0, 0.0, 1e-3), schedule=fp.Schedule((0.0, 0.02, 0.0201), (1.0, 1.0, 0.0)))
    opt = fp.IntegratorOptions(rho_inf=1.0, adaptive=False, dt_initial=1e-3, dt_max=1.0)
    r = fp.simulate(b.finalize(), 0.8, dt_out=1e-3, options=opt)
    w = r.positions[:, tip, 2].mean(axis=1)
    pk, _ = find_peaks(w)
    pk = pk[r.time[pk] > 0.1][:6]
    slope = np.polyfit(np.arange(len(pk)), np.log(w[pk]), 1)[0]
    zeta_measured = -slope / np.sqrt(4.0 * np.pi**2 + slope**2)
    assert zeta_measured == pytest.approx(zeta, rel=3e-2)


def _paper_sheet(nx):
    """The benchmark sheet (flexparcel.scenarios.sheet_swing) on a coarse nx-wide mesh."""
    return sheet_swing_model(SheetSwing(element_size=0.275 / nx))


def _swing_tip(dt, nx=6, t_end=0.12):
    # the paper's sheet, coarse: a genuinely nonlinear swing under gravity
    model, tip = _paper_sheet(nx)
    opt = fp.IntegratorOptions(
        adaptive=False, dt_initial=dt, dt_max=1.0, tol_displacement=1e-9, reuse_factorization=False
    )
    r = fp.simulate(model, t_end, dt_out=t_end, options=opt)
    return r.positions[-1, tip].mean(axis=0)


def test_time_step_convergence_second_order():
    # generalized-alpha is second order: the error of the tip position at t = 0.12 s against a
    # h/8 reference shrinks by ~4 per halving (>= 3 accepted: the reference carries its own
    # O(h^2/64) error and the order is asymptotic).
    dts = [4e-3, 2e-3, 1e-3]
    ref = _swing_tip(1.25e-4)
    err = [np.linalg.norm(_swing_tip(dt) - ref) for dt in dts]
    assert err[0] / err[1] >= 3.0 and err[1] / err[2] >= 3.0, err


def test_adaptive_run_matches_fine_fixed_step():
    # the default adaptive controller (local error tol 2e-5 m per step) lands within 1 mm of a
    # fine fixed-step run after 0.12 s of swing (errors accumulate over ~50 steps)
    model, tip = _paper_sheet(6)
    r = fp.simulate(model, 0.12, dt_out=0.12)
    ref = _swing_tip(1.25e-4)
    assert np.linalg.norm(r.positions[-1, tip].mean(axis=0) - ref) < 1e-3
    assert r.stats["rejected_steps"] <= r.stats["steps"]


def test_a_stepper_goes_on_across_simulate_calls_exactly():
    # simulate() called chunk by chunk with one ModelStepper is the single call with frames
    # at the chunk ends, bit for bit: begin() keeps the scheme's accelerations of the state
    # it stopped at (recomputing consistent ones reset the generalised-alpha filter, and the
    # assembly's 5 ms opening chunks took 16x the steps)
    model, _ = _paper_sheet(6)
    one = fp.simulate(model, 0.12, dt_out=0.03)
    stepper = ModelStepper(model, None)
    s = None
    for k in range(1, 5):
        r = fp.simulate(model, 0.03 * k, dt_out=0.03, state=s, stepper=stepper)
        s = r.final_state
    assert r.stats["steps"] == one.stats["steps"]
    for name in ("positions", "rotations", "velocities", "accelerations"):
        assert np.array_equal(getattr(s, name), getattr(one.final_state, name)), name
    # any other state (here the start again) gets consistent accelerations, M a = f - f_int
    start = stepper.begin(model.initial_state())
    fresh = ModelStepper(model, None).begin(model.initial_state())
    assert np.array_equal(start.accelerations, fresh.accelerations)
    assert not np.array_equal(start.accelerations, s.accelerations)


def test_rejected_steps_counted_by_cause():
    # a first step of 20 ms against a 1 um error tolerance is rejected for its error estimate
    model, _ = _paper_sheet(6)
    opt = fp.IntegratorOptions(dt_initial=2e-2, tol_displacement=1e-6)
    r = fp.simulate(model, 0.02, dt_out=0.02, options=opt)
    causes = ("newton", "error", "impact", "penetration")
    assert r.stats["rejected_error"] > 0
    assert sum(r.stats[f"rejected_{c}"] for c in causes) == r.stats["rejected_steps"]


def test_no_two_steps_in_a_row_end_on_their_first_newton_iteration():
    # A step may end after one iteration, judged with the last step's contraction rate; it
    # measures no rate of its own, so the next step must iterate at least twice. Otherwise a
    # stale rate lets steps end unconverged one after another (a chatter on KP's box in the
    # paper's conveyor scene).
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    model, _ = _paper_sheet(6)
    integ = GeneralizedAlpha(model)
    counts = []
    try_step = integ._try_step

    def counting(s0, h, on_progress=None):
        out = try_step(s0, h, on_progress)
        if out is not None:
            counts.append(out[3])
        return out

    integ._try_step = counting
    state = model.initial_state()
    integ.initialize(state)
    while state.time < 0.5 - 1e-12:
        state = integ.step(state, 0.5)
    # without the rule 17 of the 59 steps ended on their first iteration right after one that
    # did (measured); with it 10 steps end so, never two in a row
    ones = np.array(counts) == 1
    assert ones.any()  # the shortcut still works
    assert not (ones[1:] & ones[:-1]).any()
    # a checkpoint history from before the rule (one scalar fewer) restores, rate measured
    history = integ.history()
    history["scalars"] = history["scalars"][:-1]
    integ._rate_fresh = False
    integ.restore_history(history)
    assert integ._rate_fresh is True


def test_divergence_raises_clear_error_not_nan():
    # an absurd load explodes the model: the run must stop with ConvergenceError naming time,
    # step and node, never return non-finite results
    b, tip, _ = strip_model(L, B, H, 2, rho=RHO)
    b.add_force(tip, (0.0, 0.0, 1e12))
    opt = fp.IntegratorOptions(dt_min=1e-5, max_newton=4)
    with pytest.raises(fp.ConvergenceError, match=r"t = .* s \(step \d+\); worst node \d+"):
        fp.simulate(b.finalize(), 0.1, options=opt)


def test_krylov_reuse_option_gives_the_same_motion():
    # GMRES preconditioned with an earlier factorisation solves the same Newton systems to
    # rtol 1e-6: the trajectory agrees with direct solves to well within the step tolerance
    model, tip = _paper_sheet(6)
    r0 = fp.simulate(model, 0.1, dt_out=0.1)
    r1 = fp.simulate(model, 0.1, dt_out=0.1, options=fp.IntegratorOptions(krylov_reuse=True))
    assert r1.stats["krylov_iterations"] > 0
    assert np.abs(r1.positions[-1] - r0.positions[-1]).max() < 1e-4


def test_pardiso_backend_gives_the_same_motion():
    # optional backend (pip install pypardiso): same Newton systems, same trajectory
    pytest.importorskip("pypardiso")
    model, _ = _paper_sheet(6)
    r0 = fp.simulate(model, 0.05, dt_out=0.05)
    r1 = fp.simulate(
        model, 0.05, dt_out=0.05, options=fp.IntegratorOptions(linear_solver="pardiso")
    )
    assert np.abs(r1.positions[-1] - r0.positions[-1]).max() < 1e-8


@pytest.mark.parametrize("growth", [1.05, 1.02])
def test_step_cap_after_a_newton_failure_regrows_by_the_option(growth):
    # after a Newton failure the step is capped; each accepted step lets the cap grow by
    # newton_cap_growth (the conveyor scenes use 1.02: PB's film keeps Newton's reach put)
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    model, _ = _paper_sheet(4)
    integ = GeneralizedAlpha(model, fp.IntegratorOptions(newton_cap_growth=growth))
    s = model.initial_state()
    integ.initialize(s)
    # as left by a failure: the cap just above the step, so that the step controller, which
    # would grow this accurate step by 1.5, is held to the regrown cap
    integ._h_cap = 1.01e-4
    integ.h = 1e-4
    s = integ.step(s, 1.0)
    assert integ._h_cap == pytest.approx(1.01e-4 * growth)
    assert integ.h == pytest.approx(1.01e-4 * growth)  # the next step is the regrown cap


def test_newton_cap_growth_out_of_range_is_refused():
    for bad in (1.0, 0.9, 3.0, float("nan")):
        with pytest.raises(ValueError, match=r"newton_cap_growth must be in \(1, 2\]"):
            fp.IntegratorOptions(newton_cap_growth=bad)


def test_friction_tangent_option_is_validated_and_leaves_the_callers_laws():
    match = "friction_tangent must be 'consistent', 'stick' or 'symmetric'"
    with pytest.raises(ValueError, match=match):
        fp.IntegratorOptions(friction_tangent="exact")
    from flexparcel.contact.law import P_SLIP_TANGENT, ContactLaw
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    b = fp.ModelBuilder()
    node = b.add_rigid_body(fp.RoundedBox(0.1, 0.1, 0.1, 0.01, mass=1.0), (0.0, 0.0, 0.05))
    b.add_contact(node, b.add_plane((0, 0, 0), (0, 0, 1)),
                  ContactLaw(stiffness=1e5, mu_static=0.3).with_stick_model())  # fmt: skip
    model = b.finalize()
    integ = GeneralizedAlpha(model, fp.IntegratorOptions(friction_tangent="stick"))
    assert np.all(integ.model.contact_laws[:, P_SLIP_TANGENT] == 1.0)
    integ = GeneralizedAlpha(model, fp.IntegratorOptions(friction_tangent="symmetric"))
    assert np.all(integ.model.contact_laws[:, P_SLIP_TANGENT] == 2.0)
    assert np.all(model.contact_laws[:, P_SLIP_TANGENT] == 0.0)  # the caller's model


def test_initial_accelerations_count_the_contact_forces():
    # a 1 kg box come to rest on a plate: the consistent accelerations of a fresh integrator,
    # M a = f_ext + f_contact - f_int, are those of a body at rest (its contact carries its
    # weight); without the contact forces they were the free fall's g (the first step then
    # had to find the contact's force from a 9.81 m/s^2 start)
    from flexparcel.contact.law import ContactLaw
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    b = fp.ModelBuilder(mass_damping=200.0)
    node = b.add_rigid_body(fp.RoundedBox(0.1, 0.1, 0.1, 0.01, mass=1.0), (0.0, 0.0, 0.04999))
    # 1e8 N/m^3 over the 0.1 m x 0.1 m face: 1e6 N/m, 10 um under the 1 kg box
    b.add_contact(node, b.add_plane((0, 0, 0), (0, 0, 1)), ContactLaw(stiffness=1e8))
    model = b.finalize()
    rest = fp.simulate(model, 0.5, dt_out=0.5).final_state
    assert np.abs(rest.velocities[node]).max() < 1e-6  # at rest
    s = rest.copy()
    GeneralizedAlpha(model).initialize(s)
    # at rest to the residual speed's damping force (mass damping 200/s x 1e-6 m/s) and the
    # integrator's tolerance on the contact's balance, far below g
    assert np.linalg.norm(s.accelerations[node, :3]) < 1e-3 * 9.81


def test_initial_accelerations_of_fdr_slaves_follow_their_master():
    # a stretched strip whose free end is tied to a rigid body by an FDR, no gravity: the
    # slaves move rigidly with the body (a_s = a_m + alpha_m x r at rest), and the body takes
    # the strip's pull on all of them: its acceleration is their summed force over the body's
    # and the slaves' mass. Before, each slave got its own force over its own 1e-4 kg
    # (10^2-10^3 m/s^2 here, 2e6 m/s^2 at KP's glue stripe at 10 mm)
    from flexparcel.integrate import assembly as asm
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    b, tip, pts = strip_model(0.1, 0.02, 1e-3, 8, 2, rho=1000.0)
    body = b.add_rigid_body(fp.RoundedBox(0.02, 0.04, 0.01, 0.002, mass=0.05), (0.11, 0.01, 0.0))
    b.add_fdr(tip, reference=body)
    model = b.finalize()
    s = model.initial_state()
    s.positions[: len(pts), 0] *= 1.01  # the strip 1 % longer: it pulls the body back
    s.positions[body, 0] += 0.01 * 0.1  # (the body and its slaves with the tip)
    asm.project_slaves(model, s.positions, s.rotations)
    GeneralizedAlpha(model).initialize(s)
    a = s.accelerations
    arms = s.positions[tip] - s.positions[body]
    np.testing.assert_allclose(a[tip, :3], a[body, :3] + np.cross(a[body, 3:], arms),
                               rtol=0, atol=1e-9 * np.abs(a[body]).max())  # fmt: skip
    fint, _ = asm.internal_forces(model, s.positions, s.rotations, s.velocities)
    pull = -fint[tip, :3].sum(axis=0)
    assert pull[0] < 0.0  # the stretched strip pulls the body towards it
    total_mass = model.mass[body, 0] + model.mass[tip, 0].sum()
    np.testing.assert_allclose(a[body, :3], pull / total_mass, rtol=1e-12, atol=1e-12)
