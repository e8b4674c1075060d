"""Implicit dynamics: generalized-alpha on the Lie group R^3 x SO(3) of each node.

Scheme (Chung & Hulbert 1993, in the form of Arnold & Bruls 2007, Multibody Syst Dyn 18:185, and
its Lie-group extension, Bruls & Cardona 2010, J Comput Nonlinear Dyn 5:031002):

    M qdd_{n+1} + f_int(q_{n+1}, v_{n+1}) = f_ext(t_{n+1}, q_{n+1})
    (1 - am) a_{n+1} + am a_n = (1 - af) qdd_{n+1} + af qdd_n
    dq = h v_n + h^2 (1/2 - beta) a_n + h^2 beta a_{n+1}
    v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1}

with ``x_{n+1} = x_n + dq_x`` and ``R_{n+1} = exp(dq_rot) R_n`` (spatial increment; the nodal
inertia is isotropic, so the spatial and material forms coincide and there is no gyroscopic term).
Parameters from the spectral radius at infinity ``rho_inf``:
``am = (2 rho - 1)/(rho + 1)``, ``af = rho/(rho + 1)``, ``gamma = 1/2 + af - am``,
``beta = (gamma + 1/2)^2 / 4``: second order accurate, unconditionally stable for linear
problems, and dissipating the (heavily Rayleigh-damped, beta*K) high modes instead of ringing.

Newton works on spatial spin corrections with the element kernels' consistent tangent
``S = c_a M + K_t + c_v C`` with ``c_a = (1 - am)/((1 - af) beta h^2)``, ``c_v = gamma/(beta h)``.
Terms of order |dq_rot| from the SO(3) tangent map in the inertia and damping blocks are left out
(they vanish as h -> 0); the factorisation is reused across iterations and steps while Newton
contracts well (modified Newton), and rebuilt when it does not.

Step size: the local error estimate of Newmark-type schemes (Zienkiewicz & Xie 1991,
Earthquake Eng Struct Dyn 20:871), ``e = h^2 |beta - 1/6| |qdd_{n+1} - qdd_n|`` on translations,
kept below ``tol_displacement``; rejected steps are retried smaller, and a Newton failure halves
the step. Below ``dt_min`` the run stops with :class:`ConvergenceError`.
"""

from __future__ import annotations

import copy
import time as _time
from dataclasses import asdict, dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla

from flexparcel.contact.law import P_SLIP_TANGENT, SLIP_TANGENT_CODES
from flexparcel.elements.rotations import (
    apply_spins,
    relative_rotation_vectors,
    rotation_exp,
)
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.errors import ConvergenceError
from flexparcel.integrate.linear import SingularMatrixError, make_linear_solver
from flexparcel.model.interfaces import ContactContext, ContactOutput
from flexparcel.model.model import Model, State

__all__ = ["IntegratorOptions", "Stats", "GeneralizedAlpha", "WALL_PHASES"]


@dataclass
class IntegratorOptions:
    """Settings of the implicit integrator (SI units)."""

    rho_inf: float = 0.8
    """Spectral radius at infinite step (1: no numerical dissipation, trapezoidal rule)."""
    dt_initial: float = 1e-3
    dt_min: float = 1e-7
    dt_max: float = 2e-2
    adaptive: bool = True
    tol_displacement: float = 1e-4
    """Local error tolerance per step on node displacements [m]."""
    newton_tol: float = 1e-2
    """Newton stops when its estimated remaining error is below newton_tol * tol_displacement
    (and the rotation correction times the element size as well)."""
    newton_residual_tol: float = 0.3
    """Newton ends a step only when the correction test passes and the residual
    r = M qdd + f_int - f_ext - f_c of the new iterate balances too: each free DOF's residual
    over its diagonal entry of the Newton matrix, |r_i| / S_ii (the displacement that would
    balance it locally; rotations times the element size), must be below
    ``newton_residual_tol * newton_tol * tol_displacement``. The correction test alone judges
    the iterate before the last correction, and an approximate tangent (no frame-rotation
    terms, a contact kink) can end a step out of balance. Scaling by S_ii and not by the
    force size matters: a film node's weight is 1e-3 N while a micrometre of membrane strain
    error is 0.3 N; a test on |r| / |forces| (tried: 0.1) demands nanometre membrane accuracy
    and cost the sheet swing 47 % more iterations. Costs one element force evaluation per
    step."""
    newton_momentum_tol: float | None = 0.1
    """Newton also ends a step only when no free body is pushed by its residual: for each
    body (nodes joined by elements or rigid ties, none of them with a fixed or prescribed
    translation) the residual summed over its nodes, divided by its mass, must be below this
    acceleration [m/s^2]; None: no such test. The sum is the net force that acts on the body
    in the computed motion but is no physical force (internal forces sum to zero), so it moves
    the body's centre of mass by itself. The per-DOF test above cannot see it: it scales each
    residual by S_ii ~ m / (beta h^2), which lets a 1 g film node carry about 0.1 N at a
    0.1 ms step, and where the residuals share a sign (sliding friction drags every film node
    the same way) they add up. Measured on the pouch sliding along a 75 deg deflector
    (examples/conveyor_jam_scene.toml, deflector friction 0.2): without this test the contacts'
    mean force on it over 0.2-0.4 s was out of balance with its momentum change by 0.040 N,
    10 % of its weight; with it by 4e-6 N. Its cost, measured: that run 483 s against 593 s,
    the paper's conveyor scene (25 mm, 0.07 s) 770 s against 789 s, but the envelope drop
    bench (a box rattling in its envelope) 118 s against 76 s. The default 0.1 m/s^2 (1 % of
    g) bounds a biased drift of a body to 5 cm/s per second; the per-DOF test keeps judging
    the local balance. A body with a held node (a clamped film) is not tested: its reactions
    are unknown. The test also finds contact laws Newton cannot settle: the KP/BW vertical
    drop at 10 mm stopped at its glued edge's impact (2-30 N of net residual on the envelope)
    until that edge's line contact got the stick model instead of the regularised friction's
    1 mm/s sigmoid (:mod:`flexparcel.contact.edges`)."""
    max_newton: int = 12
    newton_cap_growth: float = 1.05
    """After a Newton failure at step h, steps are capped at 0.75 h; the cap then grows by
    this factor per accepted step (Newton's reach, unlike the error estimate, is not
    predicted by the step controller). A failed step costs up to ``max_newton`` iterations,
    so where the reach stays put, a slower regrowth pays: see the conveyor's options
    (:func:`flexparcel.scenarios.conveyor_scene.conveyor_options`)."""
    reuse_factorization: bool = False
    """Keep the factorisation across iterations and steps while Newton contracts well
    (modified Newton). Measured on the sheet swing it forces smaller steps and costs more than
    it saves, so the default rebuilds the tangent every iteration."""
    impact_step_fraction: float = 0.1
    """While a contact closes or opens faster than ``impact_speed``, steps are limited to this
    fraction of its oscillation period 2 pi sqrt(m_node / k_contact)."""
    impact_speed: float = 0.01
    """Normal contact speed [m/s] above which a contact counts as an impact."""
    impact_limit: str = "all"
    """Which contacts the impact step limit applies to: "all", "rigid" (only contact points
    of rigid bodies, whose restitution needs the impact resolved) or "off". Shell and solid
    node contacts oscillate at sqrt(c / m_node), tens of kHz for packaging; resolving them
    costs thousands of steps per impact. Measured on the envelope drop (50 mm, 0.12 s):
    "all" with rho_inf 0.8: 590 steps, box at 15.0 mm at the end; "rigid" with rho_inf 0.5:
    176 steps, 14.8 mm (the same motion); "rigid" with rho_inf 0.8: 198 steps but the box
    bounces to 27.8 mm (the scheme's acceleration memory pumps energy into the unresolved
    contacts). So "rigid" only together with rho_inf <= 0.5, which the consignment tests
    use."""
    error_estimate: str = "full"
    """Local error estimate of the step control: "full" (Zienkiewicz-Xie on all accelerations)
    or "smooth", which leaves out the acceleration jumps caused by contact forces. A node
    resting in a stiff contact has accelerations that jitter with micrometre changes of its
    penetration (c / m_node ~ 1e10 1/s^2 for packaging), and "full" then keeps steps at
    microseconds through a whole free fall of a prestressed consignment; with "smooth" the
    contacts are left to Newton, the impact limit and the numerical dissipation (use it with
    rho_inf <= 0.5).

    "balanced" takes, node by node, the smaller of the two. Where a contact force jump is
    balanced by the node's own internal forces (film pressed between its content and its own
    tension), the node's motion stays smooth and "full" is the right measure, while "smooth"
    counts the contact jump as an acceleration change that never happened. Where a stiff
    contact jitters unbalanced, "smooth" is right. Measured on the KP/BW swing at 25 mm
    (Table 6, first 0.03 s): the "smooth" estimate was 10-70x the "full" one at the film nodes
    under the content (up to 70 um against 1-2 um), so 66 of 285 tries were rejected for an
    error that was not there and steps stayed at 0.14 ms; over 0.1 s "balanced" took 376
    steps against 722 with the free end's path unchanged to 0.01 mm."""
    newton_relaxation: bool = False
    """Under-relax the Newton corrections (halve them while the iteration stagnates at a
    contraction rate near 1, restore them when it contracts) and accept a relaxed iteration
    once Newton's own (unrelaxed) correction is below 0.1 ``tol_displacement``: contacts
    switching across a kink of the law (contact on/off, friction's v_s band) make full Newton
    steps cycle without converging, and such a state is then known to that looser bound, not
    to ``newton_tol``. Measured on the KP/BW horizontal drop (25 mm mesh, Table 6): with it
    the impact passes; judged by ``newton_tol`` alone the step falls below dt_min at
    t = 0.202 s, as without relaxation. Off by default: on a rigid box stalled against a
    deflector it lets the box creep."""
    krylov_reuse: bool = False
    """Solve with GMRES preconditioned by the last LU factorisation (of an earlier Newton
    matrix) and refactor only when GMRES needs more than ``krylov_max_iterations``. Measured
    no gain on the sheet swing and the envelope drop (the step size, hence the mass term
    M / (beta h^2), and the contact set change too fast between factorisations), so off."""
    krylov_rtol: float = 1e-6
    krylov_max_iterations: int = 12
    tangent: str = "material"
    """"material": B^T K_l B + the SO(3) increment map, cheap (no frame-rotation terms, so
    Newton converges linearly; measured 2 iterations per step on the sheet swing) or
    "consistent": exact derivative by complex step (quadratic convergence, ~10x costlier)."""
    linear_solver: str = "auto"
    """Backend of :func:`flexparcel.integrate.linear.make_linear_solver`: "auto" (CHOLMOD where
    the ``fast`` extra is installed, else SuperLU), "cholmod", "superlu",
    "superlu-blocks" (one factorisation per independent block, in parallel),
    "superlu-blocks-mixed" (the same in single precision, refined to a double-precision
    solution) or "pardiso"."""
    friction_tangent: str = "consistent"
    """Newton tangent of a slipping stick-model contact: "consistent" (the return map's exact
    derivative, -mu F_N (I - n n^T)/|a| + the mu(v) term), "stick" (-k_t I as while sticking)
    or "symmetric" (the consistent tangent without its F_N and mu(v) terms, and a smooth
    onset of slip: :func:`flexparcel.contact.law._return_map`). The forces, hence the
    converged solution, are the same. "consistent" converges
    quadratically once the slip directions settle, but a contact that barely slips flips its
    direction n between iterations and the consistent term flips with it, so Newton cycles
    and the step shrinks; "stick" converges linearly instead, so the state is as accurate as
    ``newton_tol`` allows and no better. Measured on the four-consignment conveyor (25 mm,
    from settled snapshots), first 0.01 s: "consistent" 463 steps, 1,263 iterations, 181 s
    with newton_cap_growth 1.05 (406, 781, 116 s with 1.02); "stick" 102 steps, 369
    iterations, 55 s (1.05). But over the first 0.05 s "stick" (1.05) took 776 s (839 steps,
    5,468 iterations) against 703 s for "consistent" (1.02; 2,098 steps, 4,625 iterations).
    On a rigid box sliding along a deflector "stick" needs newton_tol 1e-4 to meet the
    closed-form speed to 0.5 % (tests/test_conveyor.py). With the CHOLMOD backend and the
    residual test, consignment options: the KP/BW swing at 25 mm, first 0.1 s, "stick" 291
    steps, 1,689 iterations, 15.8 s against 729, 3,297, 35.0 s; but the 10 mm envelope drop
    (0.3 s) "stick" 387 steps, 1,621 iterations, 113 s against 225, 847, 60 s. So
    "consistent" stays the default. Since the momentum test (``newton_momentum_tol``) the
    swing's "stick" is slow: along its slide the box in KP/BW's envelope sees a stiffness of
    sum(k_t A) against its inertia, Newton corrects its sliding a little per iteration and
    the momentum test vetoes step after step. "symmetric" drops k_t along the slip direction
    and stays symmetric (Cholesky); measured in :func:`~flexparcel.scenarios.consignment_tests.
    swing_options`."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.rho_inf <= 1.0:
            raise ValueError(f"IntegratorOptions.rho_inf must be in [0, 1], got {self.rho_inf!r}")
        names = ("dt_initial", "dt_min", "dt_max", "tol_displacement", "newton_tol",
                 "newton_residual_tol")  # fmt: skip
        for name in names:
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"IntegratorOptions.{name} must be > 0, got {v!r}")
        tol = self.newton_momentum_tol
        if tol is not None and not (np.isfinite(tol) and tol > 0):
            raise ValueError(
                f"IntegratorOptions.newton_momentum_tol must be > 0 or None, got {tol!r}"
            )
        g = self.newton_cap_growth
        if not (isinstance(g, int | float) and 1.0 < g <= 2.0):
            raise ValueError(f"IntegratorOptions.newton_cap_growth must be in (1, 2], got {g!r}")
        if self.dt_min > self.dt_max:
            raise ValueError("IntegratorOptions.dt_min must be <= dt_max")
        if self.max_newton < 1:
            raise ValueError("IntegratorOptions.max_newton must be >= 1")
        if self.error_estimate not in ("full", "smooth", "balanced"):
            raise ValueError(
                "IntegratorOptions.error_estimate must be 'full', 'smooth' or 'balanced', "
                f"got {self.error_estimate!r}"
            )
        if self.impact_limit not in ("rigid", "all", "off"):
            raise ValueError(
                "IntegratorOptions.impact_limit must be 'rigid', 'all' or 'off', "
                f"got {self.impact_limit!r}"
            )
        if self.friction_tangent not in SLIP_TANGENT_CODES:
            names = [repr(k) for k in SLIP_TANGENT_CODES]
            raise ValueError(
                f"IntegratorOptions.friction_tangent must be {', '.join(names[:-1])} or "
                f"{names[-1]}, got {self.friction_tangent!r}"
            )
        if self.tangent not in ("material", "consistent"):
            raise ValueError(
                "IntegratorOptions.tangent must be 'material' or 'consistent', "
                f"got {self.tangent!r}"
            )


WALL_PHASES = ("elements", "contact", "matrix", "factor", "solve")
"""Phases of :attr:`Stats.wall_s`: element forces and tangents ("elements"), contact detection
and forces with their tangent blocks ("contact"), building the Newton matrix from those
("matrix"), its factorisation ("factor") and the solves, GMRES included ("solve")."""


@dataclass
class Stats:
    steps: int = 0
    rejected_steps: int = 0
    """All rejected tries; by cause in the next four."""
    rejected_newton: int = 0
    """Newton did not converge in ``max_newton`` iterations or diverged."""
    rejected_error: int = 0
    """The local error estimate exceeded ``tol_displacement``."""
    rejected_impact: int = 0
    """An impact needed a shorter step (``impact_step_fraction``)."""
    rejected_penetration: int = 0
    """A contact went deeper than its law's ``max_penetration``."""
    newton_iterations: int = 0
    residual_vetoes: int = 0
    """Iterations whose correction passed Newton's test but whose residual did not."""
    newton_iterations_rejected: int = 0
    """Newton iterations spent in tries that Newton did not converge (part of the above)."""
    factorizations: int = 0
    symbolic_analyses: int = 0
    """Symbolic analyses (orderings) of the linear solver; SuperLU does one per
    factorisation, CHOLMOD one per held sparsity pattern."""
    krylov_solves: int = 0
    krylov_iterations: int = 0
    tangent_assemblies: int = 0
    wall_s: dict = field(default_factory=lambda: dict.fromkeys(WALL_PHASES, 0.0))
    """Wall time [s] per phase of the Newton iterations (see :data:`WALL_PHASES`)."""


CONTACT_HISTORY = "contact"
"""Prefix of the contact sets' arrays in :meth:`GeneralizedAlpha.history`."""

SOLVER_HISTORY = "solver"
"""Prefix of the linear solver's arrays (its held sparsity pattern) in the history."""


def _adjacent_keys(model: Model) -> np.ndarray:
    """Sorted keys ``a * n + b`` (both orders) of node pairs joined by an element edge, for
    the filter that keeps a point off the faces next to it in its own mesh."""
    pairs = [g.node_pairs() for g in model.element_groups]
    pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
    if not (model.contact_sets and pairs.size):
        return np.zeros(0, np.int64)
    n = model.node_count
    return np.unique(np.concatenate([pairs[:, 0] * n + pairs[:, 1], pairs[:, 1] * n + pairs[:, 0]]))


def _free_bodies(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """Each node's free body and each body's mass [kg]: the connected parts of the mesh
    (element edges, FDR ties) that have mass and no node with a fixed or prescribed
    translation. Returns (body of each node or -1, shape (n,); masses, shape (b,))."""
    n = model.node_count
    pairs = [np.column_stack([model.slave_nodes, model.slave_master])]
    for g in model.element_groups:
        nodes = g.element_dofs() // 6  # (m, w): every element ties its nodes to its first
        pairs.append(np.column_stack([np.repeat(nodes[:, 0], nodes.shape[1]), nodes.ravel()]))
    pairs = np.concatenate(pairs).astype(np.int64)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, labels = csgraph.connected_components(graph, directed=False)
    held = np.asarray(model.fixed)[:, :3].any(axis=1)
    held[model.prescribed_nodes] = True
    mass = np.bincount(labels, weights=model.mass[:, 0], minlength=count)
    ok = (mass > 0.0) & (np.bincount(labels, weights=held, minlength=count) == 0)
    index = np.full(count, -1, np.int64)
    index[ok] = np.arange(int(ok.sum()))
    return index[labels], mass[ok]


class GeneralizedAlpha:
    """Steps a :class:`State` of a :class:`Model` in time. ``step`` advances one accepted step."""

    def __init__(self, model: Model, options: IntegratorOptions | None = None) -> None:
        self.opt = options or IntegratorOptions()
        # the friction tangent is a solver choice carried by the packed laws (the kernels read
        # it per pair): work on a copy so that the caller's model keeps its own laws
        model = copy.copy(model)
        model.contact_laws = model.contact_laws.copy()
        self.model = model
        if self.opt.friction_tangent != "consistent" and model.contact_laws.size:
            model.contact_laws[:, P_SLIP_TANGENT] = SLIP_TANGENT_CODES[self.opt.friction_tangent]
        rho = self.opt.rho_inf
        self.am = (2.0 * rho - 1.0) / (rho + 1.0)
        self.af = rho / (rho + 1.0)
        self.gamma = 0.5 + self.af - self.am
        self.beta = 0.25 * (self.gamma + 0.5) ** 2
        self.solver = make_linear_solver(self.opt.linear_solver)
        self._symbolic_seen = 0  # the solver's symbolic_count already in the statistics
        self.stats = Stats()
        self.h = self.opt.dt_initial
        self._factor_h = None  # step size the current matrix was built with
        self._mat = None  # the current Newton matrix (CSR)
        self._factored_mat = None  # the matrix whose LU factors the solver holds
        self._has_factor = False
        self._cooldown = 0
        self._tangent = None  # (K data, C data) of the last tangent assembly
        self._refresh_next = False
        self._h_cap = np.inf
        self._last_rate = 1.0  # Newton contraction rate seen in the last step
        # whether _last_rate was measured since a step last ended on its first iteration
        self._rate_fresh = True
        self._contact_info = (0, 0.0, -1, 0.0)
        self._coupled_blocks = []
        # the contact sets carry this run's history (stick springs, anchors, candidates): each
        # integrator works on its own copies, so two runs of one model never share it
        model.contact_sets = [copy.deepcopy(cs) for cs in model.contact_sets]
        self._adjacent_keys = _adjacent_keys(model)
        self._impact_w2 = 0.0
        self._fc_trial = None  # translational contact forces of the last converged trial
        self._fc_prev = np.zeros((model.node_count, 3))
        # impulse [N s] of the monitored contact sets on every node since the start (None:
        # the model monitors no contact), their forces at the last accepted step's end and
        # its algorithmic counterpart (see _monitor_step), and at the last converged trial;
        # each monitored set's nodes (its forces act on no others)
        self.monitored_impulse = self._fmon = self._gmon = self._fmon_trial = None
        self._monitored_nodes = {}
        if model.has_monitored_contact:
            self.monitored_impulse = np.zeros((model.node_count, 3))
            self._fmon = np.zeros((model.node_count, 3))
            self._gmon = np.zeros((model.node_count, 3))
            self._monitored_nodes = {
                i: cs.nodes() for i, cs in enumerate(model.contact_sets) if cs.monitored
            }
        mt = model.mass[:, :1]
        self._inv_mass = np.divide(1.0, mt, out=np.zeros_like(mt), where=mt > 0)
        self._h_now = self.opt.dt_initial
        self._reach = 0.0
        # node masses as the impact step limit sees them: an infinite mass never limits
        self._node_mass = np.ascontiguousarray(model.mass[:, 0]).copy()
        if self.opt.impact_limit == "off":
            self._node_mass[:] = np.inf
        elif self.opt.impact_limit == "rigid":
            keep = self._node_mass[model.rigid_nodes].copy()
            self._node_mass[:] = np.inf
            self._node_mass[model.rigid_nodes] = keep
        mask = model.free_index >= 0
        # DOF number of each assembled (unknown or FDR slave) index, in that index order
        self._ext_dofs = np.empty(model.ext_count, dtype=np.int64)
        self._ext_dofs[model.free_index[mask]] = np.flatnonzero(mask)
        self._ext_rotation = self._ext_dofs % 6 >= 3  # which assembled DOFs are rotations
        self._mfree = asm.free_vector(model, model.mass)
        # length that converts rotation corrections to displacements in the Newton test
        sizes = [g.characteristic_length() for g in model.element_groups]
        sizes = [x for x in sizes if x is not None]
        if sizes:
            self.elem_size = sizes[0]
        elif model.rigid_half_inner.size:
            self.elem_size = float(np.max(model.rigid_half_inner + model.rigid_radius[:, None]))
        else:
            self.elem_size = 1.0
        self._body, self._body_mass = _free_bodies(model)
        self._body_nodes = np.flatnonzero(self._body >= 0)
        # corrections below this are round-off in the positions, not Newton error
        self._floor = 1e-13 * max(1.0, float(np.abs(model.positions0).max()))

    # ---------------------------------------------------------------- helpers
    def initialize(self, state: State) -> None:
        """Consistent initial accelerations: M qdd_0 = f_ext + f_contact - f_int(q_0, v_0).

        The contact forces belong in it: a film pressed on its content (every settled
        snapshot) carries a membrane prestress that only its contacts balance. Without them
        its nodes started with the prestress's acceleration, 1e7 m/s^2 at the gusset corners
        of KP at 10 mm (134 N on 12 mg), and the settling's first step halved from 1e-3 s
        to 5e-7 s and left the bag with 22 J of kinetic energy from 0.003 J."""
        m = self.model
        fint, _ = asm.internal_forces(m, state.positions, state.rotations, state.velocities)
        fext = asm.external_forces(m, state.time, state.rotations)
        rhs = fext - fint - m.mass_damping * m.mass * state.velocities
        if m.contact_sets:
            rhs += self._contact_forces_at(state)
        mass = m.mass
        if m.slave_nodes.size:  # FDR slaves move with their masters: lump them onto them
            rhs, mass = asm.lump_slaves(m, state.rotations, rhs)
        qdd = np.zeros((m.node_count, 6))
        has_mass = mass > 0.0
        qdd[has_mass] = rhs[has_mass] / mass[has_mass]
        if m.rigid_nodes.size:
            # Euler's gyroscopic and mass-damping moments at zero angular acceleration
            rhs -= asm.rigid_inertial_moments(
                m, state.rotations, np.zeros_like(state.velocities[:, 3:]), state.velocities[:, 3:]
            )
        for k, node in enumerate(m.rigid_nodes):
            r = state.rotations[node]
            qdd[node, 3:] = np.linalg.solve(r @ m.rigid_inertia[k] @ r.T, rhs[node, 3:])
        if m.slave_nodes.size:
            qdd[m.slave_nodes] = asm.slave_accelerations(m, state.rotations, state.velocities, qdd)
        qdd[m.fixed] = 0.0
        state.accelerations[:] = qdd
        self._alg = state.accelerations.copy()

    def _contact_forces_at(self, state: State) -> np.ndarray:
        """Contact forces (n, 6) at ``state`` as a step from it sees them before it moves
        (broad phase for the next step size); the sets' committed history is untouched."""
        self._h_now, self._s0 = self.h, state
        self._prepare_contacts(state, self.h)
        fc = self._contact(state, state.time, monitor=True)[0]
        if self.monitored_impulse is not None:
            # the monitored share of M a0 (see _monitor_step) starts as their own force
            self._fmon = self._fmon_trial.copy()
            self._gmon = self._fmon_trial.copy()
        for cs in self.model.contact_sets:
            cs.begin_step()  # drop the trial history of this evaluation
        return fc

    def _kinematics(self, s0: State, a0_alg, dq: np.ndarray, h: float):
        """From the increment dq (n, 6) return (a_{n+1}, qdd_{n+1}, v_{n+1})."""
        b, g, am, af = self.beta, self.gamma, self.am, self.af
        a1 = (dq / h - s0.velocities - h * (0.5 - b) * a0_alg) / (h * b)
        qdd = ((1.0 - am) * a1 + am * a0_alg - af * s0.accelerations) / (1.0 - af)
        v1 = s0.velocities + h * (1.0 - g) * a0_alg + h * g * a1
        fixed = self.model.fixed
        a1[fixed] = 0.0
        qdd[fixed] = 0.0
        v1[fixed] = 0.0
        if self.model.prescribed_nodes.size:
            v1[self.model.prescribed_nodes] = self.model.prescribed_motion(s0.time + h)[0]
        return a1, qdd, v1

    def _nodal_residual(self, s1, qdd, v1, fint, fc, t1):
        """M qdd + f_int - f_ext - f_contact per node (n, 6)."""
        m = self.model
        inertia = m.mass * qdd
        if m.mass_damping:
            inertia += m.mass_damping * m.mass * v1
        if m.rigid_nodes.size:
            inertia += asm.rigid_inertial_moments(m, s1.rotations, qdd[:, 3:], v1[:, 3:])
        return inertia + fint - asm.external_forces(m, t1, s1.rotations) - fc

    def _contact_context(self, t: float) -> ContactContext:
        m = self.model
        return ContactContext(
            model=m,
            laws=m.contact_laws,
            factors=np.array([sch(t) for sch in m.contact_schedules]),
            node_mass=self._node_mass,
            impact_speed=self.opt.impact_speed,
            start=self._s0,
            step=self._h_now,
            box_half=m.box_half_at(t),
            reach=self._reach,
            adjacent_keys=self._adjacent_keys,
        )

    def _contact(self, s: State, t: float, monitor: bool = False):
        """Contact forces (n, 6) on the nodes of every contact set at state ``s``, time ``t``,
        the blocks of contacts acting on single nodes (for :meth:`_add_contact_tangent`) and
        the contact info (count, deepest penetration, its node, worst ratio); the blocks of
        contacts coupling several nodes are kept for :meth:`_box_contact_matrix`. With
        ``monitor`` the monitored sets' own forces (n, 3) are kept in ``_fmon_trial``."""
        t0 = _time.perf_counter()
        ctx = self._contact_context(t)
        out = ContactOutput(np.zeros((self.model.node_count, 6)))
        monitor = monitor and self.monitored_impulse is not None
        fmon = np.zeros((self.model.node_count, 3)) if monitor else None
        for i, cs in enumerate(self.model.contact_sets):
            nodes = self._monitored_nodes.get(i) if monitor else None
            if nodes is None:
                cs.evaluate(ctx, s, out)
                continue
            # the set's share, on its own nodes, without changing the order of summation
            before = out.forces[nodes, :3]
            cs.evaluate(ctx, s, out)
            fmon[nodes] += out.forces[nodes, :3] - before
        if monitor:
            self._fmon_trial = fmon
        self.stats.wall_s["contact"] += _time.perf_counter() - t0
        self._coupled_blocks = out.coupled_blocks
        self._impact_w2 = float(ctx.w2[0])
        return out.forces, out.node_blocks, (out.count, out.depth, out.worst_node, out.ratio)

    def _box_contact_matrix(self, cv: float):
        """-(dF/dq + cv dF/dv) of the contact pairs that couple several nodes (node-box,
        node-face, line contacts), (ext x ext) sparse; None if none is in contact."""
        mats = []
        n = self.model.ext_count
        for bk, bc, dofs in self._coupled_blocks:
            live = dofs[:, 0] >= 0
            if not np.any(live):
                continue
            w = dofs.shape[1]
            blocks = -(bk[live] + cv * bc[live])
            idx = self.model.free_index[dofs[live]]  # ext numbers, -1 where held
            rows = np.repeat(idx, w, axis=1).reshape(-1, w, w)
            cols = np.tile(idx, (1, w)).reshape(-1, w, w)
            ok = (rows >= 0) & (cols >= 0)
            mats.append(sp.csr_matrix((blocks[ok], (rows[ok], cols[ok])), shape=(n, n)))
        return sum(mats[1:], mats[0]) if mats else None

    def _prepare_contacts(self, s0: State, h: float) -> None:
        """Broad phase once per step, at its start: each contact set finds its candidates
        within its contact distance plus twice the distance any node can travel in the
        step."""
        if not self.model.contact_sets:
            return
        t0 = _time.perf_counter()
        vmax = float(np.sqrt((s0.velocities[:, :3] ** 2).sum(axis=1)).max())
        self._reach = 2.0 * h * (vmax + 9.81 * h) + 1e-9
        ctx = self._contact_context(s0.time + h)
        for cs in self.model.contact_sets:
            cs.prepare(ctx, s0, h)
            cs.begin_step()
        self.stats.wall_s["contact"] += _time.perf_counter() - t0

    def _add_contact_tangent(self, data, node_blocks, cv):
        """Residual r = ... - f_contact: add -(dF/dq + cv dF/dv) of the contacts acting on
        single nodes into each node's block."""
        slots = self.model.node_block_slots
        for nodes, dq, dv in node_blocks:
            if nodes.size:
                np.add.at(data, slots[nodes].ravel(), -(dq + cv * dv).ravel())

    def _factor(self, mat) -> bool:
        t0 = _time.perf_counter()
        try:
            self.solver.factor(mat)
        except SingularMatrixError:
            self.stats.wall_s["factor"] += _time.perf_counter() - t0
            self._tangent = None
            self._has_factor = False
            return False
        self.stats.wall_s["factor"] += _time.perf_counter() - t0
        self.stats.symbolic_analyses += self.solver.symbolic_count - self._symbolic_seen
        self._symbolic_seen = self.solver.symbolic_count
        self._factored_mat = mat
        self._has_factor = True
        self.stats.factorizations += 1
        return True

    def _krylov_solve(self, mat, r):
        """Newton correction -mat^-1 r by GMRES preconditioned with the last factorisation (of
        an earlier tangent); None if it needs more than ``krylov_max_iterations``."""
        n = mat.shape[0]
        prec = spla.LinearOperator((n, n), matvec=self.solver.precondition)
        its = [0]

        def count(_):
            its[0] += 1

        x, info = spla.gmres(mat, -r, rtol=self.opt.krylov_rtol,
                             restart=self.opt.krylov_max_iterations, maxiter=1, M=prec,
                             callback=count, callback_type="pr_norm")  # fmt: skip
        self.stats.krylov_iterations += its[0]
        if info != 0 or not np.all(np.isfinite(x)):
            # the old factors no longer fit: factor directly for the next few matrices
            self._cooldown = 8
            return None
        self.stats.krylov_solves += 1
        return x

    def _drive_prescribed(self, s: State) -> None:
        """Place the prescribed bodies at time ``s.time``: x = x0 + v S(t), R = exp(w S(t))
        with S the integral of their schedules (see PrescribedMotion)."""
        m = self.model
        if not m.prescribed_nodes.size:
            return
        vel, area = m.prescribed_motion(s.time)
        for k, node in enumerate(m.prescribed_nodes):
            s.positions[node] = m.positions0[node] + m.prescribed_velocity[k, :3] * area[k]
            s.rotations[node] = rotation_exp(m.prescribed_velocity[k, 3:] * area[k])
            s.velocities[node] = vel[k]

    def _increment_map(self, theta: np.ndarray) -> sp.csr_matrix:
        """Block-diagonal d(increment)/d(spin correction) over the free DOFs: identity for
        translations, the inverse left Jacobian T^-1(Theta) (3, 3) for each node's rotation."""
        n = self.model.node_count
        w = np.zeros((n, 3, 3))
        w[:, 0, 1], w[:, 0, 2], w[:, 1, 2] = -theta[:, 2], theta[:, 1], -theta[:, 0]
        w -= np.transpose(w, (0, 2, 1))
        t2 = np.sum(theta * theta, axis=1)
        small = t2 < 1e-4
        tt = np.sqrt(np.where(small, 1.0, t2))
        c = np.where(
            small,
            1.0 / 12.0 + t2 / 720.0,
            (1.0 - 0.5 * tt / np.tan(0.5 * np.where(small, 1.0, tt))) / np.where(small, 1.0, t2),
        )
        blocks = np.zeros((n, 6, 6))
        blocks[:, :3, :3] = np.eye(3)
        blocks[:, 3:, 3:] = np.eye(3) - 0.5 * w + c[:, None, None] * (w @ w)
        full = sp.block_diag(list(blocks), format="csr")
        ext = self._ext_dofs
        return full[ext][:, ext]

    def _try_step(self, s0: State, h: float, on_progress=None):
        """One step of size h from s0. Returns (state, qdd, a_alg, iterations) or None."""
        m = self.model
        b, am, af = self.beta, self.am, self.af
        ca = (1.0 - am) / ((1.0 - af) * b * h * h)
        cv = self.gamma / (b * h)
        t1 = s0.time + h
        for group in m.element_groups:
            group.at_time(t1)
        # predictor: translations with qdd_{n+1} = qdd_n; rotations at constant angular velocity,
        # because the nodal rotary inertia of a thin shell is tiny (rho t^3/12) and its
        # accelerations carry no useful trend (they are set by small moment imbalances)
        a_pred = ((1.0 - af) * s0.accelerations + af * s0.accelerations - am * self._alg) / (1 - am)
        dq = h * s0.velocities + h * h * ((0.5 - b) * self._alg + b * a_pred)
        dq[:, 3:] = h * s0.velocities[:, 3:]
        dq[m.fixed] = 0.0
        s1 = s0.copy()
        s1.time = t1
        s1.positions = s0.positions + dq[:, :3]
        theta = dq[:, 3:].copy()
        apply_spins(s1.rotations, theta)
        self._drive_prescribed(s1)
        if m.slave_nodes.size:
            asm.project_slaves(m, s1.positions, s1.rotations)
            theta = relative_rotation_vectors(s1.rotations, s0.rotations)
        self._h_now = h
        self._s0 = s0
        self._prepare_contacts(s0, h)
        tol = self.opt.newton_tol * self.opt.tol_displacement
        prev = None
        tangent_iter = None  # iteration (of this step) whose state the tangent was built at
        diverging = 0
        relax = 1.0  # under-relaxation of the Newton corrections (see below)
        # a step that had to rebuild its tangent suggests the next one will too: do it upfront
        refresh = (not self.opt.reuse_factorization) or self._refresh_next
        self._refresh_next = False
        for it in range(1, self.opt.max_newton + 1):
            a1, qdd, v1 = self._kinematics(
                s0, self._alg, np.hstack([s1.positions - s0.positions, theta]), h
            )
            s1.velocities = v1
            fc, node_blocks, self._contact_info = self._contact(s1, t1)
            t_red = asm.reduction(m, s1.rotations)  # None without FDRs
            t0 = _time.perf_counter()
            if refresh or self._tangent is None or not self.opt.reuse_factorization:
                tangent_iter = it
                fint, dk, dc, _ = asm.internal_forces_and_tangent(
                    m, s1.positions, s1.rotations, v1, self.opt.tangent == "consistent"
                )
                self._tangent = (dk, dc)
                self._factor_h = None
                refresh = False
                self.stats.tangent_assemblies += 1
            else:
                fint, _ = asm.internal_forces(m, s1.positions, s1.rotations, v1)
            self.stats.wall_s["elements"] += _time.perf_counter() - t0
            res_nodal = self._nodal_residual(s1, qdd, v1, fint, fc, t1)
            if self._factor_h != h:
                t0 = _time.perf_counter()
                dk, dc = self._tangent
                data = dk.copy()
                asm.add_follower_tangent(m, data, t1, s1.rotations)
                # velocities and accelerations depend on the rotation increment Theta through
                # dTheta = T^-1(Theta) dphi: right-multiply C and M by that block map
                if self.opt.tangent == "consistent":
                    tmap = self._increment_map(theta)
                    asm.add_rigid_inertia_tangent(m, data, s1.rotations, v1[:, 3:], ca, cv)
                    self._add_contact_tangent(data, node_blocks, cv)
                    mat = (
                        asm.csr_from_data(m, data)
                        + (
                            cv * asm.csr_from_data(m, dc)
                            + sp.diags((ca + cv * m.mass_damping) * self._mfree)
                        )
                        @ tmap
                    )
                    box_mat = self._box_contact_matrix(cv)
                    if box_mat is not None:
                        mat = mat + box_mat
                else:
                    # the material tangent is approximate anyway; without the O(|Theta|)
                    # increment map it stays symmetric and is assembled in place
                    data += cv * dc
                    data[m.diag_slots] += (ca + cv * m.mass_damping) * self._mfree
                    asm.add_rigid_inertia_tangent(m, data, s1.rotations, v1[:, 3:], ca, cv)
                    self._add_contact_tangent(data, node_blocks, cv)
                    mat = asm.csr_from_data(m, data)
                    box_mat = self._box_contact_matrix(cv)
                    if box_mat is not None:
                        mat = mat + box_mat
                if t_red is not None:
                    r_link = asm.free_vector(m, res_nodal)
                    mat = asm.reduced_matrix(m, mat.tocsr(), t_red) + asm.link_geometric_stiffness(
                        m, r_link, s1.rotations, t_red
                    )
                self._mat = mat.tocsr()
                self._factor_h = h
                self.stats.wall_s["matrix"] += _time.perf_counter() - t0
                # an older factorisation may still precondition GMRES on this matrix well
                # enough (Krylov reuse); otherwise factor now
                krylov = self.opt.krylov_reuse and self._has_factor and self._cooldown == 0
                self._cooldown = max(0, self._cooldown - 1)
                if not krylov and not self._factor(self._mat):
                    return None
            r = asm.free_vector(m, res_nodal)
            if t_red is not None:
                r = t_red.T @ r
            if not np.all(np.isfinite(r)):
                return None
            t0 = _time.perf_counter()
            factor_before = self.stats.wall_s["factor"]  # a refactorisation below is its own
            dx = None
            if self._factored_mat is not self._mat:
                dx = self._krylov_solve(self._mat, r)
                if dx is None:  # GMRES did not converge fast: factor the current matrix
                    if not self._factor(self._mat):
                        return None
            if dx is None:
                dx = -self.solver.solve(r)
            self.stats.wall_s["solve"] += (
                _time.perf_counter() - t0 - (self.stats.wall_s["factor"] - factor_before)
            )
            self.stats.newton_iterations += 1
            if not np.all(np.isfinite(dx)):
                return None
            applied = relax
            if applied < 1.0:
                dx = applied * dx
            full = asm.nodal_from_ext(m, dx if t_red is None else t_red @ dx)
            s1.positions += full[:, :3]
            apply_spins(s1.rotations, np.ascontiguousarray(full[:, 3:]))
            if t_red is not None:
                asm.project_slaves(m, s1.positions, s1.rotations)
            theta = relative_rotation_vectors(s1.rotations, s0.rotations)
            # the convergence test judges Newton's own correction, not the under-relaxed part
            # of it that was applied: halving a cycling correction must not read as contraction
            norm = max(np.abs(full[:, :3]).max(), self.elem_size * np.abs(full[:, 3:]).max())
            norm /= applied

            rate = 0.0 if prev is None or prev == 0 else norm / prev
            # contacts switching between their pushing and their released branch (F_N =
            # max(F_NC + F_ND, R_df F_NC) has a kink) make full Newton steps cycle with
            # corrections of constant size: under-relax the next corrections until the
            # iteration contracts again
            if self.opt.newton_relaxation and it >= 2 and 0.85 < rate < 1.5:
                relax = max(0.125, 0.5 * relax)
            elif rate < 0.5:
                relax = min(1.0, 2.0 * relax)
            self._worst = int(np.argmax(np.abs(full).sum(axis=1)))
            # Newton's remaining error ~ norm * rate / (1 - rate) for a contracting iteration
            err_est = norm * rate / (1.0 - rate) if 0.0 < rate < 1.0 else norm
            if prev is None and self._last_rate < 0.5 and self._rate_fresh:
                # first iteration: estimate Newton's error with the previous step's contraction
                # rate (Hairer & Wanner, Solving ODEs II, sec. IV.8) so a step can end after one
                # tangent and one solve. A step that ends so measures no rate, so the next one
                # must iterate twice: otherwise a stale rate lets step after step end
                # unconverged. Measured on the paper's conveyor from 0.93 s: steps ending on
                # their first iteration with a rate of 0.076 made KP's film nodes on its box
                # alternate their velocity (-0.44 / -0.04 m/s) from step to step, and the
                # error estimate held the steps at 7.5 us (266 steps over 2 ms, 32.8 s);
                # with a second iteration at least every other step 36 steps, 9.5 s.
                err_est = norm * self._last_rate / (1.0 - self._last_rate)
                accept_first = err_est <= tol
            else:
                accept_first = False
            if rate > 0.0:
                self._last_rate = min(0.99, max(rate, 0.5 * self._last_rate))
            converged = accept_first or (prev is not None and err_est <= tol)
            # under relaxation a correction that keeps its size is a contact cycling across its
            # kink: accept once Newton's own correction is below a tenth of the step's error
            # tolerance (the state is then known to that bound, not to tol)
            settled = (applied < 1.0 and norm <= 0.1 * self.opt.tol_displacement) or norm <= max(
                1e-3 * tol, self._floor
            )
            if converged or settled:
                done = self._finish_iterate(s0, s1, theta, h, t1, check_balance=not settled)
                if done is not None:
                    self._rate_fresh = not accept_first
                    return (s1, *done, it)
                self.stats.residual_vetoes += 1
            prev = norm
            diverging = diverging + 1 if rate > 1.0 else 0
            if diverging >= 2 and it >= 4:
                return None  # Newton diverges: cut the step
            if rate > 0.3 and (tangent_iter is None or it - tangent_iter >= 1):
                # the tangent in use contracts too slowly: rebuild it at the current iterate
                refresh = True
                if tangent_iter is None:
                    self._refresh_next = True
        return None

    def _unbalanced(self, r: np.ndarray) -> bool:
        """Whether the free residual ``r`` fails the residual test (see
        ``IntegratorOptions.newton_residual_tol``)."""
        diag = np.abs(self._mat.diagonal())
        scaled = np.divide(np.abs(r), diag, out=np.full(r.shape, np.inf), where=diag > 0)
        if r.size == self._ext_dofs.size:  # no FDR reduction: rotations in radians
            scaled[self._ext_rotation] *= self.elem_size
        limit = self.opt.newton_residual_tol * self.opt.newton_tol * self.opt.tol_displacement
        return not float(scaled.max(initial=0.0)) <= max(limit, self._floor)

    def _pushes_a_body(self, res: np.ndarray) -> bool:
        """Whether the nodal residual ``res`` (n, 6) accelerates a free body's centre of
        mass by more than ``newton_momentum_tol`` (see there)."""
        tol = self.opt.newton_momentum_tol
        if tol is None or not self._body_mass.size:
            return False
        b, nodes, k = self._body, self._body_nodes, self._body_mass.size
        net = np.stack([np.bincount(b[nodes], res[nodes, i], k) for i in range(3)], axis=1)
        return bool((np.linalg.norm(net, axis=1) > tol * self._body_mass).any())

    def _finish_iterate(self, s0, s1, theta, h, t1, check_balance: bool):
        """Velocities, accelerations and contact forces of the iterate ``s1`` that passed
        Newton's correction test; with ``check_balance`` also its residual test
        (:meth:`_unbalanced`). Returns (qdd, a_alg), or None if the residual is out of balance
        (Newton iterates on)."""
        m = self.model
        a1, qdd, v1 = self._kinematics(
            s0, self._alg, np.hstack([s1.positions - s0.positions, theta]), h
        )
        s1.velocities = v1
        s1.accelerations = qdd
        fc = None
        if m.has_contact:
            # contact history (stick springs) and contact info of the converged state
            fc = self._contact(s1, t1, monitor=True)[0]
            self._fc_trial = fc[:, :3]
        if check_balance:
            t0 = _time.perf_counter()
            fint, _ = asm.internal_forces(m, s1.positions, s1.rotations, v1)
            self.stats.wall_s["elements"] += _time.perf_counter() - t0
            res = self._nodal_residual(s1, qdd, v1, fint, 0.0 if fc is None else fc, t1)
            r = asm.free_vector(m, res)
            t_red = asm.reduction(m, s1.rotations)
            if t_red is not None:
                r = t_red.T @ r
            if self._unbalanced(r) or self._pushes_a_body(res):
                return None
        return qdd, a1

    # ---------------------------------------------------------------------- checkpoints

    _HISTORY_SCALARS = (
        "h", "_h_cap", "_last_rate", "_impact_w2", "_cooldown", "_refresh_next", "_rate_fresh",
    )  # fmt: skip

    def history(self) -> dict[str, np.ndarray]:
        """What the next step depends on besides the :class:`State`: the algorithmic
        accelerations, the step controller (step, Newton cap, contraction rate), the stick-model
        history of every contact set (as ``"contact.<set key>.<name>"``), the last contact
        forces of the error estimate, and the statistics so far. With :meth:`restore_history`
        a run continues exactly as if uninterrupted (bit for bit unless
        ``reuse_factorization`` or ``krylov_reuse`` carry a factorisation across steps, which
        is not saved)."""
        out = {
            "alg": self._alg,
            "fc_prev": self._fc_prev,
            "scalars": np.array([float(getattr(self, k)) for k in self._HISTORY_SCALARS]),
        }
        if self.monitored_impulse is not None:
            out["monitored_impulse"] = self.monitored_impulse
            out["monitored_force"] = self._fmon
            out["monitored_alg"] = self._gmon
        for cs in self.model.contact_sets:
            for name, arr in cs.history().items():
                out[f"{CONTACT_HISTORY}.{cs.key}.{name}"] = arr
        for name, arr in self.solver.history().items():
            out[f"{SOLVER_HISTORY}.{name}"] = arr
        counts = {k: v for k, v in asdict(self.stats).items() if k != "wall_s"}
        out["stat_counts"] = np.array(list(counts.values()), dtype=np.int64)
        out["stat_wall"] = np.array([self.stats.wall_s[k] for k in WALL_PHASES])
        return {k: np.array(v, copy=True) for k, v in out.items()}

    def restore_history(self, history: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`history`, for this integrator's model; shapes are checked."""

        def take(key: str, like: np.ndarray) -> np.ndarray:
            if key not in history:
                raise ValueError(f"integrator history: missing {key!r}")
            v = np.asarray(history[key])
            if v.shape != np.shape(like):
                raise ValueError(
                    f"integrator history: {key!r} has shape {v.shape}, this model needs "
                    f"{np.shape(like)}"
                )
            return v.astype(np.asarray(like).dtype, copy=True)

        self._alg = take("alg", np.zeros((self.model.node_count, 6)))
        self._fc_prev = take("fc_prev", self._fc_prev)
        if self.monitored_impulse is not None:
            if "monitored_impulse" not in history:
                raise ValueError(
                    "integrator history: no 'monitored_impulse' (written before monitored "
                    "contacts recorded their impulse); start the run over"
                )
            self.monitored_impulse = take("monitored_impulse", self.monitored_impulse)
            self._fmon = take("monitored_force", self._fmon)
            self._gmon = take("monitored_alg", self._gmon)
        for cs in self.model.contact_sets:
            prefix = f"{CONTACT_HISTORY}.{cs.key}."
            own = {k[len(prefix) :]: v for k, v in history.items() if k.startswith(prefix)}
            try:
                cs.restore_history(own)
            except ValueError as exc:
                raise ValueError(f"integrator history of contact set {cs.key!r}: {exc}") from None
        prefix = f"{SOLVER_HISTORY}."
        try:
            self.solver.restore_history(
                {k[len(prefix) :]: v for k, v in history.items() if k.startswith(prefix)}
            )
        except ValueError as exc:
            raise ValueError(f"integrator history: {exc}") from None
        if "scalars" in history and len(history["scalars"]) == len(self._HISTORY_SCALARS) - 1:
            # a history from before _rate_fresh was saved: its rate counts as measured
            history = {**history, "scalars": np.append(history["scalars"], 1.0)}
        scalars = take("scalars", np.zeros(len(self._HISTORY_SCALARS)))
        for k, v in zip(self._HISTORY_SCALARS, scalars, strict=True):
            cur = getattr(self, k)
            setattr(self, k, type(cur)(v))
        names = [k for k in asdict(self.stats) if k != "wall_s"]
        counts = np.asarray(history.get("stat_counts", ()), dtype=np.int64)
        if counts.shape == (len(names),):  # else an older version's: count from here
            for k, v in zip(names, counts, strict=True):
                setattr(self.stats, k, int(v))
        wall = np.asarray(history.get("stat_wall", ()), dtype=float)
        if wall.shape == (len(WALL_PHASES),):
            self.stats.wall_s = dict(zip(WALL_PHASES, map(float, wall), strict=True))
        # a history from before the phases were split carries other wall times: the phases
        # then count from the resumption (the run's total wall time is kept by simulate)

    def _acceleration_jump(self, s0: State, qdd: np.ndarray) -> float:
        """Largest nodal acceleration change [m/s^2] of the step, as the error estimate
        (``IntegratorOptions.error_estimate``) counts it."""
        dqdd = qdd[:, :3] - s0.accelerations[:, :3]
        full = np.sqrt((dqdd**2).sum(axis=1))
        if self.opt.error_estimate == "full" or self._fc_trial is None:
            return float(full.max())
        # leave the jumps of the contact forces out: see IntegratorOptions
        smooth = np.sqrt(((dqdd - (self._fc_trial - self._fc_prev) * self._inv_mass) ** 2).sum(1))
        if self.opt.error_estimate == "smooth":
            return float(smooth.max())
        return float(np.minimum(full, smooth).max())

    def _monitor_step(self, h: float) -> None:
        """Add the monitored contacts' impulse of the accepted step ``h``: the share of the
        momentum change M (v_{n+1} - v_n) = h ((1 - gamma) M a_n + gamma M a_{n+1}) that their
        forces make. M a, the algorithmic acceleration times the mass, follows
        (1 - alpha_m) M a_{n+1} + alpha_m M a_n = (1 - alpha_f) F_{n+1} + alpha_f F_n (Chung &
        Hulbert 1993), which is linear in the forces, so each force has its own share and the
        shares add up to the momentum change exactly. (The end-of-step forces times h alone
        were 6 % off a box's momentum change in an impact, the steps varying through it.)"""
        am, af, g = self.am, self.af, self.gamma
        f1 = self._fmon_trial
        g1 = ((1.0 - af) * f1 + af * self._fmon - am * self._gmon) / (1.0 - am)
        self.monitored_impulse += h * ((1.0 - g) * self._gmon + g * g1)
        self._fmon, self._gmon = f1, g1

    def _reject(self, cause: str) -> None:
        """Count a rejected try and its cause (a ``Stats.rejected_<cause>`` field)."""
        self.stats.rejected_steps += 1
        name = f"rejected_{cause}"
        setattr(self.stats, name, getattr(self.stats, name) + 1)

    def step(self, state: State, t_limit: float) -> State:
        """Advance ``state`` by one accepted step not past ``t_limit``; returns the new state."""
        opt = self.opt
        while True:
            h = min(self.h, opt.dt_max, t_limit - state.time)
            if h < opt.dt_min and t_limit - state.time > opt.dt_min:
                worst = getattr(self, "_worst", -1)
                pos = state.positions[worst] if worst >= 0 else None
                raise ConvergenceError(
                    f"time step fell below dt_min = {opt.dt_min:g} s at t = {state.time:.6g} s "
                    f"(step {self.stats.steps + 1}); worst node {worst} at {pos} m"
                )
            its_before = self.stats.newton_iterations
            out = self._try_step(state, h)
            if out is None:
                self._reject("newton")
                self.stats.newton_iterations_rejected += self.stats.newton_iterations - its_before
                self.h = 0.5 * h
                # Newton's reach, unlike the error estimate, is not predicted by the controller:
                # remember where it failed and let the cap relax slowly afterwards
                self._h_cap = 0.75 * h
                self._tangent = None  # retry from a fresh tangent
                continue
            self._h_cap *= self.opt.newton_cap_growth
            s1, qdd, a1, _ = out
            if self._impact_w2 > 0.0:
                # resolve impacts: a contact that closes or opens faster than impact_speed must
                # be integrated with steps short against its oscillation period, otherwise the
                # scheme's acceleration memory carries the contact impulse past the release and
                # the rebound gains energy
                h_lim = opt.impact_step_fraction * 2.0 * np.pi / np.sqrt(self._impact_w2)
                if h > 1.5 * h_lim and h_lim >= opt.dt_min:
                    self._reject("impact")
                    self.h = h_lim
                    continue
                self.h = min(self.h, max(h_lim, opt.dt_min))
            n_contact, depth, node, ratio = self._contact_info
            if ratio > 1.0:
                # a contact went deeper than its law's max_penetration: retry smaller
                self._reject("penetration")
                if h <= opt.dt_min * 1.0001:
                    where = f"a contact at node {node}" if node >= 0 else "a contact"
                    raise ConvergenceError(
                        f"{where} penetrates {depth:.3g} m, beyond its max_penetration, at "
                        f"t = {s1.time:.6g} s (step {self.stats.steps + 1}) even at dt_min"
                    )
                self.h = max(0.5 * h, opt.dt_min)
                continue
            if opt.adaptive:
                err = h * h * abs(self.beta - 1.0 / 6.0) * self._acceleration_jump(state, qdd)
                ratio = err / opt.tol_displacement
                grow = 1.5 if ratio == 0 else min(1.5, max(0.3, 0.85 * ratio ** (-1.0 / 3.0)))
                if ratio > 1.0:
                    self._reject("error")
                    self.h = h * grow
                    continue
                # a new h costs a refactorisation: change it only for a clear gain, and never
                # grow from a step that was shortened to land on t_limit
                if grow < 1.0 or (grow > 1.2 and h >= 0.999 * self.h):
                    self.h = min(h * grow, opt.dt_max, max(self._h_cap, h))
            elif h < opt.dt_initial:
                # fixed-step mode: after a Newton failure forced sub-steps, return to the step
                self.h = min(opt.dt_initial, 2.0 * h)
            if self._fc_trial is not None:
                self._fc_prev = self._fc_trial
            if self.monitored_impulse is not None and self._fmon_trial is not None:
                self._monitor_step(h)
            for cs in self.model.contact_sets:
                cs.commit()  # the stick-model history of the accepted step
            self._alg = a1
            self.stats.steps += 1
            return s1
