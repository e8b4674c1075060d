"""Every tangent against central finite differences.

Central differences with step eps have truncation error O(eps^2 f''') and round-off
O(u |f| / eps); with eps = 1e-6 (positions ~1) both are ~1e-10 relative, so agreement to 1e-6
relative (of the largest entry) shows the analytic/complex-step tangent is the true derivative.
"""

import numpy as np

from conftest import fd_wrt_nodes, strip_model
from flexparcel.elements import shell
from flexparcel.elements.rotations import rotation_exp, rotation_log, tangent, tangent_inv
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.static import apply_increment

EPS = 1e-6
RTOL = 1e-6
_TF0 = np.zeros((1, 3, 12))  # elastic membrane (no tension-field data)


def _random_triangle_state(seed):
    rng = np.random.default_rng(seed)
    x0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.3, 0.8, 0.0]])
    frames, xloc = shell.reference_frames(x0, np.array([[0, 1, 2]]))
    kl = shell.local_stiffness(xloc[0], 1.0, 0.3, 0.1)[None]
    x = x0 + 0.1 * rng.standard_normal((3, 3))
    rot = np.array([rotation_exp(0.3 * rng.standard_normal(3)) for _ in range(3)])
    vel = rng.standard_normal((3, 6))
    return frames, xloc, kl, x, rot, vel


def _forces(tris, kl, xloc, frames, beta, x, rot, vel):
    out = np.zeros((3, 6))
    shell.element_forces(tris, kl, xloc, frames, beta, _TF0, x, rot, vel, out)
    return out.ravel()


def test_shell_force_is_gradient_of_strain_energy():
    frames, xloc, kl, x, rot, _ = _random_triangle_state(0)
    tris = np.array([[0, 1, 2]])
    zero = np.zeros((3, 6))
    out = np.zeros((3, 6))
    shell.element_forces(tris, kl, xloc, frames, np.zeros(1), _TF0, x, rot, zero, out)

    def energy(xx, rr):
        return shell.element_forces(
            tris, kl, xloc, frames, np.zeros(1), _TF0, xx, rr, zero, np.zeros((3, 6))
        )

    g = fd_wrt_nodes(energy, x, rot, EPS)[0]
    assert np.abs(out.ravel() - g).max() <= RTOL * np.abs(g).max()


def test_shell_stiffness_and_damping_tangents_match_finite_differences():
    frames, xloc, kl, x, rot, vel = _random_triangle_state(1)
    tris = np.array([[0, 1, 2]])
    beta = np.array([0.05])
    emap = np.arange(324).reshape(1, 18, 18)
    dk, dc = np.zeros(325), np.zeros(325)
    shell.element_tangents(
        tris, kl, xloc, frames, beta, _TF0, x, rot, vel, np.zeros((3, 6)), dk, dc, emap
    )
    k = dk[:324].reshape(18, 18)
    c = dc[:324].reshape(18, 18)
    kfd = fd_wrt_nodes(
        lambda xx, rr: _forces(tris, kl, xloc, frames, beta, xx, rr, vel), x, rot, EPS
    )
    cfd = np.zeros((18, 18))
    for j in range(18):
        vp, vm = vel.copy(), vel.copy()
        vp.ravel()[j] += EPS
        vm.ravel()[j] -= EPS
        cfd[:, j] = (
            _forces(tris, kl, xloc, frames, beta, x, rot, vp)
            - _forces(tris, kl, xloc, frames, beta, x, rot, vm)
        ) / (2 * EPS)
    assert np.abs(k - kfd).max() <= RTOL * np.abs(kfd).max()
    assert np.abs(c - cfd).max() <= RTOL * np.abs(cfd).max()


def test_rotation_maps():
    rng = np.random.default_rng(2)
    for scale in (1e-4, 0.3, 2.5):  # series branch, closed form, beyond pi/2
        th = scale * rng.standard_normal(3)
        th *= min(1.0, 3.0 / np.linalg.norm(th))
        r = rotation_exp(th)
        assert np.allclose(r @ r.T, np.eye(3), atol=1e-14)
        assert np.allclose(rotation_log(r), th, atol=1e-12)
        assert np.allclose(tangent(th) @ tangent_inv(th), np.eye(3), atol=1e-12)
        # left Jacobian: exp(th + d) ~ exp(T(th) d) exp(th)
        d = EPS * rng.standard_normal(3)
        lhs = rotation_exp(th + d) @ r.T
        spin = rotation_log(lhs)
        assert np.allclose(spin, tangent(th) @ d, atol=1e-10)


def test_assembled_static_tangent_with_follower_loads():
    # residual r(q) = f_int(q) - f_ext(q) with follower force and moment, derivative along
    # spatial spins: assembled tangent vs central differences on a deformed configuration
    b, tip, _ = strip_model(1.0, 0.5, 0.01, 3, 2, e=1e6, nu=0.3)
    b.add_moment(tip, (0.0, -0.5, 0.2), follower=True)
    b.add_force(tip[0], (0.0, 0.1, 0.3), follower=True)
    model = b.finalize()
    rng = np.random.default_rng(3)
    state = model.initial_state()
    apply_increment(model, state, 0.05 * rng.standard_normal(model.dof_count))
    zeros = np.zeros((model.node_count, 6))

    def residual(st):
        fint, _ = asm.internal_forces(model, st.positions, st.rotations, zeros)
        return asm.free_vector(model, fint - asm.external_forces(model, 0.0, st.rotations))

    _, data, _, _ = asm.internal_forces_and_tangent(model, state.positions, state.rotations, zeros)
    asm.add_follower_tangent(model, data, 0.0, state.rotations)
    k = asm.csr_from_data(model, data).toarray()
    kfd = np.zeros_like(k)
    for j in range(model.dof_count):
        d = np.zeros(model.dof_count)
        d[j] = EPS
        sp, sm = state.copy(), state.copy()
        apply_increment(model, sp, d)
        apply_increment(model, sm, -d)
        kfd[:, j] = (residual(sp) - residual(sm)) / (2 * EPS)
    assert np.abs(k - kfd).max() <= RTOL * np.abs(kfd).max()


def test_reduced_tangent_with_fdr_links_matches_finite_differences():
    # T^T K T plus the links' geometric stiffness is the derivative of the reduced residual
    # T^T r with respect to the unknowns (slaves follow their master exactly)
    b, tip, _ = strip_model(1.0, 0.5, 0.01, 3, 1, e=1e6, nu=0.3)
    ref = b.add_fdr(tip)
    b.add_moment(ref, (0.0, -0.5, 0.2), follower=True)
    model = b.finalize()
    rng = np.random.default_rng(3)
    state = model.initial_state()
    apply_increment(model, state, 0.1 * rng.standard_normal(model.dof_count))
    zeros = np.zeros((model.node_count, 6))

    def residual(st):
        fint, _ = asm.internal_forces(model, st.positions, st.rotations, zeros)
        r = asm.free_vector(model, fint - asm.external_forces(model, 0.0, st.rotations))
        return asm.reduction(model, st.rotations).T @ r, r

    _, data, _, _ = asm.internal_forces_and_tangent(model, state.positions, state.rotations, zeros)
    asm.add_follower_tangent(model, data, 0.0, state.rotations)
    t = asm.reduction(model, state.rotations)
    kext = asm.csr_from_data(model, data)
    k = asm.reduced_matrix(model, kext, t).toarray()
    # the block form T = [I; B] equals the plain product to round-off
    assert np.abs(k - (t.T @ kext @ t).toarray()).max() <= 1e-13 * np.abs(k).max()
    k += asm.link_geometric_stiffness(model, residual(state)[1], state.rotations, t).toarray()
    kfd = np.zeros_like(k)
    for j in range(model.dof_count):
        d = np.zeros(model.dof_count)
        d[j] = EPS
        sp_, sm = state.copy(), state.copy()
        apply_increment(model, sp_, d)
        apply_increment(model, sm, -d)
        kfd[:, j] = (residual(sp_)[0] - residual(sm)[0]) / (2 * EPS)
    assert np.abs(k - kfd).max() <= RTOL * np.abs(kfd).max()
