"""Static equilibrium by Newton-Raphson with adaptive load stepping.

Solves ``f_int(q) = lambda f_ext(q)`` for load factors ``lambda`` = 1/k ... 1 (follower loads
depend on q). Rotations are updated multiplicatively, ``R <- exp(dphi) R``, so the consistent
tangent is the spin derivative from the element kernels plus the follower-load stiffness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexparcel.elements.rotations import apply_spins, rotation_vectors
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.errors import ConvergenceError
from flexparcel.integrate.linear import SingularMatrixError, make_linear_solver
from flexparcel.model.model import Model, State

__all__ = ["StaticResult", "solve_static", "apply_increment"]


@dataclass
class StaticResult:
    """Converged equilibrium states at each requested load factor."""

    load_factors: np.ndarray
    """Load factors, shape (k,)."""
    displacements: np.ndarray
    """Node displacements from the reference [m], shape (k, node_count, 3)."""
    rotation_vectors: np.ndarray
    """Nodal rotation vectors [rad], shape (k, node_count, 3) (|.| <= pi; use ``states``
    for rotations beyond pi)."""
    states: list[State]
    newton_iterations: int


def apply_increment(model: Model, state: State, dq_free: np.ndarray) -> None:
    """Add an increment of the unknowns (dof_count,): translations additively, rotations as
    spatial spins; FDR slaves then follow their masters exactly."""
    t = asm.reduction(model, state.rotations)
    dq = asm.nodal_from_ext(model, dq_free if t is None else t @ dq_free)
    state.positions += dq[:, :3]
    apply_spins(state.rotations, np.ascontiguousarray(dq[:, 3:]))
    if t is not None:
        asm.project_slaves(model, state.positions, state.rotations)


def solve_static(
    model: Model,
    load_steps: int = 10,
    *,
    tol: float = 1e-8,
    max_iterations: int = 25,
    max_cuts: int = 8,
    linear_solver: str = "auto",
    time: float = 0.0,
) -> StaticResult:
    """Equilibrium under all loads (gravity, nodal forces/moments at schedule time ``time``)
    scaled by load factors ``i / load_steps``.

    Convergence: the free residual norm below ``tol`` times the norm of the applied load (or of
    the internal force if larger) and the increment norm below ``tol`` times the model size.
    A load increment that does not converge is halved (up to ``max_cuts`` times).
    """
    if int(load_steps) != load_steps or load_steps < 1:
        raise ValueError(f"solve_static: load_steps must be an integer >= 1, got {load_steps!r}")
    solver = make_linear_solver(linear_solver)
    state = model.initial_state()
    span = float(np.ptp(model.positions0, axis=0).max())
    zeros_v = np.zeros((model.node_count, 6))
    targets = np.arange(1, int(load_steps) + 1) / load_steps
    lam = 0.0
    factors, states = [], []
    total_iter = 0
    for target in targets:
        while lam < target - 1e-14:
            dlam = target - lam
            for _cut in range(max_cuts + 1):
                trial = state.copy()
                ok, it = _newton(
                    model, trial, lam + dlam, time, tol, max_iterations, solver, span, zeros_v
                )
                total_iter += it
                if ok:
                    break
                dlam *= 0.5
            else:
                raise ConvergenceError(
                    f"static solve: no convergence at load factor {lam + dlam:.6g} "
                    f"(step from {lam:.6g}) after {max_cuts} cuts; worst node "
                    f"{getattr(trial, '_worst', -1)}"
                )
            state = trial
            lam += dlam
        factors.append(lam)
        states.append(state.copy())
    disp = np.array([s.positions - model.positions0 for s in states])
    rv = np.array([rotation_vectors(s.rotations) for s in states])
    return StaticResult(np.array(factors), disp, rv, states, total_iter)


def _newton(model, state, lam, time, tol, max_iterations, solver, span, zeros_v):
    for it in range(1, max_iterations + 1):
        fint, data, _, _ = asm.internal_forces_and_tangent(
            model, state.positions, state.rotations, zeros_v
        )
        fext = asm.external_forces(model, time, state.rotations, lam)
        asm.add_follower_tangent(model, data, time, state.rotations, lam)
        r = asm.free_vector(model, fint - fext)
        if not np.all(np.isfinite(r)):
            return False, it
        scale = max(
            np.linalg.norm(asm.free_vector(model, fext)),
            np.linalg.norm(asm.free_vector(model, fint)),
            1e-30,
        )
        mat = asm.csr_from_data(model, data)
        t = asm.reduction(model, state.rotations)
        if t is not None:
            kg = asm.link_geometric_stiffness(model, r, state.rotations, t)
            mat, r = (asm.reduced_matrix(model, mat, t) + kg).tocsr(), t.T @ r
        try:
            solver.factor(mat)
        except SingularMatrixError:
            return False, it
        dq = -solver.solve(r)
        if not np.all(np.isfinite(dq)):
            return False, it
        apply_increment(model, state, dq)
        rn = np.linalg.norm(r)
        state._worst = int(np.argmax(np.abs(fint - fext).sum(axis=1)))
        # converged: residual small against the loads, and the correction small against the
        # current displacement (or negligible against the model size)
        umax = np.abs(state.positions - model.positions0).max()
        if rn <= tol * scale and np.abs(dq).max() <= 10 * tol * max(umax, 1e-6 * span):
            return True, it
        if np.abs(dq).max() <= 1e-14 * span:
            return True, it
    return False, max_iterations
