"""Sparse linear solvers behind one small interface: ``factor(A)`` then ``solve(b)``.

Default: scipy SuperLU with the MMD(A^T+A) ordering and symmetric mode, which the design notes
measured 2-3x faster than the default COLAMD on shell matrices and robust when rows couple many
nodes. ``backend="superlu-blocks"`` (:class:`BlockSuperLU`): the same, one factorisation per
independent block of the matrix (bodies that do not touch, e.g. the consignments on a conveyor)
on worker threads; ``backend="superlu-blocks-mixed"``: the same factorised in single precision,
with iterative refinement in double precision to a double-precision solution.
``backend="cholmod"`` (:class:`CholmodSolver`, needs the ``fast`` extra, cvxopt): CHOLMOD's
supernodal Cholesky of the symmetric part, with the symbolic analysis once per sparsity pattern;
``backend="auto"`` (the integrators' default) takes it when cvxopt is installed, else SuperLU.
Optional: Pardiso through ``pypardiso`` if installed (``backend="pardiso"``).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numba as nb
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

__all__ = [
    "LinearSolver",
    "BlockSuperLU",
    "CholmodSolver",
    "make_linear_solver",
    "SingularMatrixError",
]


class SingularMatrixError(RuntimeError):
    """The tangent could not be factorised (singular: an unsupported rigid-body mode?)."""


class LinearSolver:
    """SuperLU backend. ``factor_count``, ``symbolic_count`` (orderings: SuperLU orders at
    every factorisation) and ``solve_count`` are kept for the benchmark."""

    name = "superlu"

    def __init__(self) -> None:
        self._lu = None
        self.factor_count = 0
        self.symbolic_count = 0
        self.solve_count = 0

    def factor(self, a: sp.csr_matrix) -> None:
        self._lu = _superlu(a)
        self.factor_count += 1
        self.symbolic_count += 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        return self._lu.solve(b)

    def precondition(self, b: np.ndarray) -> np.ndarray:
        """Apply the held factorisation as a preconditioner (for Krylov reuse)."""
        return self._lu.solve(b)

    def history(self) -> dict[str, np.ndarray]:
        """What later factorisations depend on besides the matrices (for checkpoints)."""
        return {}

    def restore_history(self, history: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`history`."""


def _superlu(a: sp.spmatrix):
    try:
        return spla.splu(
            a.tocsc(),
            permc_spec="MMD_AT_PLUS_A",
            diag_pivot_thresh=0.0,
            options=dict(SymmetricMode=True),
        )
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise SingularMatrixError(str(exc)) from exc


class _Worker:
    """One thread that owns the factors it makes. scipy's SuperLU objects must be freed by the
    thread that created them: measured with scipy 1.17, a factor made in a worker thread and
    dropped in the main thread leaks its memory (20 MB per factorisation of a 3,000-DOF
    conveyor matrix; scipy issue 15921). So factors never leave their worker: it factors,
    solves and drops them."""

    def __init__(self) -> None:
        self.pool = ThreadPoolExecutor(1)
        self.factors: list[tuple[np.ndarray, object, np.dtype]] = []  # only on self.pool

    def _factor(self, blocks) -> None:
        self.factors = []  # free the old factors here, on their own thread
        self.factors = [(idx, _superlu(m), m.dtype) for idx, m in blocks]

    def _solve(self, b: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        # a single-precision factor solves in single precision: b is cast to its type
        return [
            (idx, lu.solve(np.ascontiguousarray(b[idx], dtype=dtype)))
            for idx, lu, dtype in self.factors
        ]

    def factor(self, blocks):
        return self.pool.submit(self._factor, blocks)

    def solve(self, b: np.ndarray):
        return self.pool.submit(self._solve, b)

    def close(self) -> None:
        self.pool.submit(self.factors.clear).result()
        self.pool.shutdown()


REFINE_TOL = 1e-13
"""Componentwise backward error max_i |b - A x|_i / (|A| |x| + |b|)_i at which iterative
refinement stops, about 1,000 unit round-offs of double precision (1.1e-16). Measured on a
Newton matrix of the four-consignment conveyor (6,750 DOF): the double-precision LU reaches
1.1e-15; two refinement steps of the single-precision one reach 4.3e-16."""

REFINE_MAX = 6
"""Refinement steps before the mixed-precision backend factorises in double precision."""


class BlockSuperLU(LinearSolver):
    """SuperLU per connected component of the matrix graph, the components shared out over
    ``workers`` threads (default: the CPU count, at most 8), largest first, each to the
    least loaded thread (cost ~ size**1.5). SuperLU releases the GIL, so the blocks factor in
    parallel; their factors together are the factorisation of the whole matrix (its LU has no
    fill between blocks). Call :meth:`close` when done (the garbage collector does it too).

    ``mixed_precision``: factorise in single precision and refine each solution in double
    precision (mixed-precision iterative refinement: x += LU^-1 (b - A x), Higham, Accuracy
    and Stability of Numerical Algorithms, 2nd ed., 2002, ch. 12) until the componentwise
    backward error (Oettli-Prager) is below :data:`REFINE_TOL`, as a double-precision LU
    gives. Each step contracts the error by about cond(A) * 6e-8; where that is not enough
    (no halving per step, or :data:`REFINE_MAX` steps) the matrix is factorised again in
    double precision (counted in ``double_fallbacks``). Measured on PB's block of the
    conveyor's Newton matrix (3,030 DOF): single 25.8 ms against double 39.3 ms, relative
    error 5e-5 before and 3e-10 after one refinement step. :meth:`precondition` applies the
    factors without refinement."""

    name = "superlu-blocks"

    def __init__(self, workers: int | None = None, *, mixed_precision: bool = False) -> None:
        super().__init__()
        n = max(1, min(8, os.cpu_count() or 1)) if workers is None else int(workers)
        if n < 1:
            raise ValueError(f"BlockSuperLU: workers must be >= 1, got {workers!r}")
        self.workers = [_Worker() for _ in range(n)]
        self.mixed_precision = bool(mixed_precision)
        if self.mixed_precision:
            self.name = "superlu-blocks-mixed"
        self.refinement_steps = 0
        self.double_fallbacks = 0
        self._a: sp.csr_matrix | None = None
        self._abs_a: sp.csr_matrix | None = None
        self._single = False  # the held factors are single precision

    def factor(self, a: sp.csr_matrix) -> None:
        a = a.tocsr()
        if not self.mixed_precision:
            self._factor_blocks(a, np.float64)
        else:
            self._a, self._abs_a = a, abs(a)  # for the refinement's residuals
            try:
                self._factor_blocks(a, np.float32)
            except SingularMatrixError:  # a pivot lost in single precision: try double
                self.double_fallbacks += 1
                self._factor_blocks(a, np.float64)
        self.factor_count += 1
        self.symbolic_count += 1

    def _factor_blocks(self, a: sp.csr_matrix, dtype) -> None:
        self._single = dtype == np.float32
        count, labels = connected_components(a, directed=True, connection="weak")
        order = np.argsort(labels, kind="stable")
        bounds = np.searchsorted(labels[order], np.arange(count + 1))
        # the blocks are usually contiguous already (each consignment's DOFs are numbered
        # together): then slice them out directly, sparing the permuted copy of the whole
        # matrix (measured 4.6 ms a factorisation on the paper's four-consignment conveyor)
        permute = count > 1 and bool(np.any(labels[1:] < labels[:-1]))
        ap = a[order][:, order].tocsr() if permute else a
        sizes = np.diff(bounds)
        load = np.zeros(len(self.workers))
        share: list[list] = [[] for _ in self.workers]
        for k in np.argsort(-sizes, kind="stable"):
            w = int(np.argmin(load))
            i, j = bounds[k], bounds[k + 1]
            share[w].append((order[i:j], ap[i:j, i:j].astype(dtype, copy=False)))
            load[w] += float(sizes[k]) ** 1.5
        for f in [w.factor(blocks) for w, blocks in zip(self.workers, share, strict=True)]:
            f.result()  # re-raises SingularMatrixError

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        x = self.precondition(b)
        if not self._single:
            return x
        a, abs_a, abs_b = self._a, self._abs_a, np.abs(b)
        previous = np.inf
        for _ in range(REFINE_MAX):
            r = b - a @ x
            scale = abs_a @ np.abs(x) + abs_b
            with np.errstate(divide="ignore", invalid="ignore"):
                # rows with scale 0 have r = 0 there: no error
                omega = float(np.max(np.where(scale > 0, np.abs(r) / scale, 0.0), initial=0.0))
            if omega <= REFINE_TOL:
                return x
            if not omega < 0.5 * previous:  # not contracting (also NaN): single is not enough
                break
            previous = omega
            x = x + self.precondition(r)
            self.refinement_steps += 1
        self.double_fallbacks += 1
        self._factor_blocks(a, np.float64)
        return self.precondition(b)

    def precondition(self, b: np.ndarray) -> np.ndarray:
        x = np.empty(b.shape, dtype=np.float64)
        for f in [w.solve(b) for w in self.workers]:
            for idx, xi in f.result():
                x[idx] = xi
        return x

    def close(self) -> None:
        """Free the factors (each on its own thread) and stop the threads."""
        for w in self.workers:
            w.close()
        self.workers = []

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown: the threads may be gone already
            pass


SKEW_TOL = 1e-12
"""Relative size max |A - A^T| / max |A| below which a matrix counts as symmetric: round-off of
the element kernels' symmetric tangents is ~1e-16."""

KRYLOV_RTOL = 1e-3
"""Relative residual |b - A x| / |b| to which :class:`CholmodSolver` solves a nonsymmetric
system by GMRES preconditioned with the factor of its symmetric part. The system is a Newton
correction, and Newton's tests judge the iterate by its next correction and its residual, not
by this solve: an inexact solve changes how fast Newton converges, not where it stops (inexact
Newton, Dembo, Eisenstat & Steihaug 1982, SIAM J. Numer. Anal. 19:400, converges while the
forcing term stays below 1). Near convergence a 1e-3 error on a correction of
``newton_tol * tol_displacement`` (1 um) is 1 nm. Measured on the KP/BW swing at 10 mm
(Table 6, first 0.05 s after the jaws, 6,018 DOF): 1e-8 took 185 steps, 1,192 Newton
iterations and 55.9 s; 1e-3 took 132 steps, 883 iterations and 42.1 s, the free end 6 um from
the 1e-8 run (the steps differ as the step control sees other Newton histories)."""

KRYLOV_RESTART = 30
"""GMRES iterations before :class:`CholmodSolver` gives up on the symmetric-part preconditioner
and factorises the nonsymmetric matrix with SuperLU. Measured on Newton matrices of the
envelope drop's impact (6,738 DOF, friction makes them nonsymmetric by 0.3-1 % of the largest
entry): 6-15 iterations to 1e-10."""


INDEFINITE_SKIP = 8
"""After a Newton matrix whose symmetric part is not positive definite, this many following
factorisations go to SuperLU without trying Cholesky first. Where a softer stick spring
lets the steps grow, the mass term no longer outweighs friction's one-way couplings and
most matrices of a step are indefinite: measured on PB alone on the conveyor at 25 mm with
k_t = c / 100 (first 0.02 s), 414 of 438 factorisations fell back, each after a failed
Cholesky (13 ms) and a new symbolic analysis (6 ms) before SuperLU's 45 ms; with the skip,
the analysis kept and the mixed-precision fallback the run took 24.8 s against 33.0 s
(factorisation 16.4 s against 26.6 s)."""

PATTERN_SLACK = 1.3
"""A sparsity pattern held for the symbolic analysis may grow (by the union with each new
matrix's pattern) up to this many times the current matrix's entries before it is rebuilt from
that matrix alone. Contact pairs switching on and off change the Newton matrix's pattern at
most iterations (measured: 301 new patterns in 512 matrices of the envelope drop's impact);
within the union the symbolic analysis is done once."""


@nb.njit(cache=True)
def _embed(indptr_s, indices_s, indptr_a, indices_a):
    """Position in the pattern S of each entry of the pattern A (both CSR, sorted indices, same
    row count), or an array starting with -1 if A has an entry outside S."""
    pos = np.empty(indices_a.size, np.int64)
    for i in range(indptr_a.size - 1):
        k = indptr_s[i]
        end = indptr_s[i + 1]
        for q in range(indptr_a[i], indptr_a[i + 1]):
            j = indices_a[q]
            while k < end and indices_s[k] < j:
                k += 1
            if k == end or indices_s[k] != j:
                pos[0] = -1
                return pos
            pos[q] = k
    return pos


def _pattern_union(a: sp.csr_matrix, b: sp.csr_matrix) -> sp.csr_matrix:
    """The union of two CSR patterns (values 1), sorted."""
    ones = [sp.csr_matrix((np.ones(m.nnz), m.indices, m.indptr), shape=m.shape) for m in (a, b)]
    u = (ones[0] + ones[1]).tocsr()
    u.sort_indices()
    return u


class _SymmetricLower:
    """The CCS lower triangle of the symmetric part (A + A^T) / 2 of CSR matrices that share
    one sparsity pattern, as a cvxopt ``spmatrix`` whose values are refilled per matrix by a
    gather (no triplet sort per factorisation: measured 11 ms for the envelope drop's
    363,276 entries). For a structurally symmetric CSR pattern the CCS lower triangle is the
    CSR upper triangle read column-wise, and each entry's partner (j, i) is found once."""

    def __init__(self, a: sp.csr_matrix, cvxopt) -> None:
        self.indptr, self.indices = a.indptr.copy(), a.indices.copy()
        n = a.shape[0]
        order = sp.csr_matrix((np.arange(1.0, a.nnz + 1.0), a.indices, a.indptr), shape=a.shape)
        t = order.T.tocsr()
        t.sort_indices()
        # FE assembly and the contact blocks give structurally symmetric patterns; any other
        # is left to SuperLU (CholmodSolver falls back)
        self.structural = np.array_equal(t.indptr, a.indptr) and np.array_equal(
            t.indices, a.indices
        )
        if not self.structural:
            return
        rows = np.repeat(np.arange(n), np.diff(a.indptr))
        sel = np.flatnonzero(a.indices >= rows)
        partner = t.data.astype(np.int64) - 1
        slots = cvxopt.matrix(np.arange(1.0, sel.size + 1.0))  # 1-based: no zero to drop
        ii = cvxopt.matrix(a.indices[sel].astype(np.int64))
        jj = cvxopt.matrix(rows[sel].astype(np.int64))
        self.lower = cvxopt.spmatrix(slots, ii, jj, (n, n))
        # the order in which cvxopt keeps the values, as positions in sel
        back = np.asarray(self.lower.V).ravel().astype(np.int64) - 1
        if back.size != sel.size:
            raise RuntimeError("cvxopt dropped entries of the symmetric pattern")
        self.sel, self.partner = sel[back], partner[sel[back]]
        self._matrix = cvxopt.matrix

    def embedding(self, a: sp.csr_matrix) -> np.ndarray | None:
        """Positions of a's entries in this pattern (``slice(None)`` if a has exactly this
        pattern), or None if a has an entry outside it."""
        if np.array_equal(a.indptr, self.indptr) and np.array_equal(a.indices, self.indices):
            return slice(None)
        if a.shape[0] + 1 != self.indptr.size:
            return None
        pos = _embed(self.indptr, self.indices, a.indptr, a.indices)
        return None if pos.size and pos[0] < 0 else pos

    def fill(self, a: sp.csr_matrix, where) -> bool:
        """Load a's symmetric part (a's entries at positions ``where`` of this pattern, zeros
        elsewhere); returns whether a is nonsymmetric (beyond :data:`SKEW_TOL`)."""
        if isinstance(where, slice):
            data = a.data
        else:
            data = np.zeros(self.indices.size)
            data[where] = a.data
        upper, lower = data[self.sel], data[self.partner]
        self.lower.V = self._matrix(0.5 * (upper + lower))
        scale = float(np.abs(a.data).max(initial=0.0))
        return bool(np.abs(upper - lower).max(initial=0.0) > SKEW_TOL * scale)


class CholmodSolver(LinearSolver):
    """CHOLMOD's supernodal Cholesky (through cvxopt, the ``fast`` extra) of the symmetric part
    of the Newton matrix, with the symbolic analysis (fill-reducing ordering, supernodes) done
    once per sparsity pattern and reused until the pattern changes (a contact pair coupling new
    nodes). A symmetric matrix is solved directly; a nonsymmetric one (friction and contact
    damping couple the normal to the tangential directions one way only) by GMRES
    preconditioned with that factor, to :data:`KRYLOV_RTOL`. A matrix that is not positive
    definite, or GMRES that does not converge in :data:`KRYLOV_RESTART` iterations, falls back
    to SuperLU for that matrix (``fallbacks``).

    Measured on Newton matrices (2 cores, scipy 1.17, cvxopt 1.3.3): the 10 mm sheet swing
    (3,276 DOF) 5.0 ms against SuperLU's 28 ms; the 10 mm envelope drop (6,738 DOF) 19 ms
    against 130 ms. Licence: cvxopt and CHOLMOD's supernodal module are GPL; flexparcel (MIT)
    only imports them when installed."""

    name = "cholmod"

    def __init__(self) -> None:
        super().__init__()
        import cvxopt  # noqa: F401 (ImportError: make_linear_solver names the extra)
        import cvxopt.cholmod

        self._cvxopt = cvxopt
        self._cholmod = cvxopt.cholmod
        self._pattern: _SymmetricLower | None = None
        self._symbolic = None
        self._a: sp.csr_matrix | None = None
        self._skew = False
        self._lu = None  # SuperLU factors where Cholesky does not serve
        self.fallbacks = 0
        self.krylov_iterations = 0
        self._indefinite_left = 0  # factorisations still sent straight to SuperLU
        self._superlu_mixed: BlockSuperLU | None = None  # made at the first fallback

    def factor(self, a: sp.csr_matrix) -> None:
        a = a.tocsr()
        if not a.has_sorted_indices:
            a = a.sorted_indices()
        where = None if self._pattern is None else self._pattern.embedding(a)
        if where is None:
            self._new_pattern(a)
            where = self._pattern.embedding(a)
        self._a, self._lu = a, None
        self.factor_count += 1
        if not self._pattern.structural:
            self._fall_back()
            return
        if self._indefinite_left > 0:
            self._indefinite_left -= 1
            self._fall_back()
            return
        self._skew = self._pattern.fill(a, where)
        lower = self._pattern.lower
        if self._symbolic is None:
            self._cholmod.options["supernodal"] = 2  # always supernodal LL^T
            self._symbolic = self._cholmod.symbolic(lower)
            self.symbolic_count += 1
        try:
            self._cholmod.numeric(lower, self._symbolic)
        except ArithmeticError:  # not positive definite: LU of the whole matrix
            # the symbolic analysis depends on the pattern only and stays valid; the next
            # matrices of the step are likely indefinite too, so they skip the attempt
            self._indefinite_left = INDEFINITE_SKIP
            self._fall_back()

    def history(self) -> dict[str, np.ndarray]:
        """The held sparsity pattern: its fill-reducing ordering sets the round-off of every
        later solve, so a resumed run needs it to repeat the uninterrupted one bit for bit;
        and how many factorisations still go to SuperLU after an indefinite matrix."""
        p = self._pattern
        if p is None:
            return {}
        return {"pattern_indptr": p.indptr.copy(), "pattern_indices": p.indices.copy(),
                "indefinite_left": np.array([self._indefinite_left])}  # fmt: skip

    def restore_history(self, history: dict[str, np.ndarray]) -> None:
        left = np.asarray(history.get("indefinite_left", [0])).ravel()
        if left.size != 1 or not 0 <= int(left[0]) <= INDEFINITE_SKIP:
            raise ValueError("linear solver history: indefinite_left is malformed")
        self._indefinite_left = int(left[0])
        if "pattern_indptr" not in history:
            self._pattern, self._symbolic = None, None
            return
        ptr = np.asarray(history["pattern_indptr"], dtype=np.int64)
        idx = np.asarray(history["pattern_indices"], dtype=np.int64)
        n = ptr.size - 1
        if n < 0 or ptr[-1] != idx.size or (idx.size and (idx.min() < 0 or idx.max() >= n)):
            raise ValueError("linear solver history: the held sparsity pattern is malformed")
        held = sp.csr_matrix((np.ones(idx.size), idx, ptr), shape=(n, n))
        self._pattern = _SymmetricLower(held, self._cvxopt)
        self._symbolic = None

    def _new_pattern(self, a: sp.csr_matrix) -> None:
        """Hold the union of the current pattern and a's (a alone if that grew past
        :data:`PATTERN_SLACK` times a's entries); its symbolic analysis is redone."""
        # a contact block with a one-way coupling (friction, the box moment's arm) can hold an
        # exact zero where its transpose does not, and scipy's sparse sums drop such zeros: the
        # held pattern is made structurally symmetric (a's and a^T's entries), else Cholesky
        # would fall back to SuperLU for every such matrix. Measured on the KP/BW swing at
        # 10 mm: all 125 factorisations of its first 20 steps fell back, 6,018 DOF.
        a = _pattern_union(a, a.T.tocsr())
        p = self._pattern
        if p is not None and p.indptr.size == a.shape[0] + 1:
            held = sp.csr_matrix((np.ones(p.indices.size), p.indices, p.indptr), shape=a.shape)
            union = _pattern_union(held, a)
            if union.nnz <= PATTERN_SLACK * a.nnz:
                a = union
        self._pattern = _SymmetricLower(a, self._cvxopt)
        self._symbolic = None

    def _fall_back(self) -> None:
        """LU of the whole matrix: SuperLU in single precision refined to a double-precision
        solution (:class:`BlockSuperLU` with ``mixed_precision``), on one thread. Measured on
        PB's conveyor matrices (3,030 DOF, 1.16 million LU entries): 33 ms against 45 ms in
        double precision."""
        self.fallbacks += 1
        self.symbolic_count += 1  # SuperLU orders anew
        if self._superlu_mixed is None:
            self._superlu_mixed = BlockSuperLU(workers=1, mixed_precision=True)
        self._superlu_mixed.factor(self._a)
        self._lu = self._superlu_mixed

    def precondition(self, b: np.ndarray) -> np.ndarray:
        if self._lu is not None:
            return self._lu.solve(b)
        x = self._cvxopt.matrix(np.array(b, dtype=np.float64).ravel())
        self._cholmod.solve(self._symbolic, x)
        return np.asarray(x).ravel()

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        if self._lu is not None or not self._skew:
            return self.precondition(b)
        # right preconditioning, A P^-1 y = b with x = P^-1 y: GMRES then minimises the true
        # residual (left preconditioning stopped at |b - A x| / |b| ~ 3e-4 on the drop's
        # matrices, where P^-1 weights the rotation rows far above the translations)
        n = b.shape[0]
        a = self._a
        op = spla.LinearOperator((n, n), matvec=lambda y: a @ self.precondition(y))
        its = [0]

        def count(_):
            its[0] += 1

        y, info = spla.gmres(op, b, rtol=KRYLOV_RTOL, restart=KRYLOV_RESTART, maxiter=1,
                             callback=count, callback_type="pr_norm")  # fmt: skip
        x = self.precondition(y)
        self.krylov_iterations += its[0]
        if info != 0 or not np.all(np.isfinite(x)):
            self._fall_back()
            return self._lu.solve(b)
        return x


class PardisoSolver(LinearSolver):
    """Intel MKL Pardiso via pypardiso (real nonsymmetric, mtype 11: the spin tangent is not
    symmetric away from equilibrium)."""

    name = "pardiso"

    def __init__(self) -> None:
        super().__init__()
        import pypardiso

        self._solver = pypardiso.PyPardisoSolver(mtype=11)
        self._a = None

    def factor(self, a: sp.csr_matrix) -> None:
        self._a = a.tocsr()
        self._a.sort_indices()
        self._solver.factorize(self._a)
        self.factor_count += 1
        self.symbolic_count += 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        return self._solver.solve(self._a, b)

    def precondition(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(self._a, b)


BACKENDS = ("auto", "superlu", "cholmod", "superlu-blocks", "superlu-blocks-mixed", "pardiso")


def cholmod_available() -> bool:
    """Whether the ``cholmod`` backend can be used (cvxopt installed: the ``fast`` extra)."""
    try:
        import cvxopt.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def make_linear_solver(backend: str = "auto") -> LinearSolver:
    """``"auto"`` (default: ``"cholmod"`` where cvxopt is installed, else ``"superlu"``),
    ``"superlu"`` (always available), ``"cholmod"`` (:class:`CholmodSolver`),
    ``"superlu-blocks"`` (:class:`BlockSuperLU`), ``"superlu-blocks-mixed"``
    (:class:`BlockSuperLU` with ``mixed_precision=True``) or ``"pardiso"`` (needs
    pypardiso)."""
    if backend == "auto":
        backend = "cholmod" if cholmod_available() else "superlu"
    if backend == "superlu":
        return LinearSolver()
    if backend == "cholmod":
        if not cholmod_available():
            raise ValueError(
                "linear solver backend 'cholmod' needs cvxopt (pip install 'flexparcel[fast]')"
            )
        return CholmodSolver()
    if backend == "superlu-blocks":
        return BlockSuperLU()
    if backend == "superlu-blocks-mixed":
        return BlockSuperLU(mixed_precision=True)
    if backend == "pardiso":
        try:
            return PardisoSolver()
        except ImportError:
            raise ValueError(
                "linear solver backend 'pardiso' needs pypardiso (pip install pypardiso)"
            ) from None
    allowed = ", ".join(f"'{b}'" for b in BACKENDS)
    raise ValueError(f"linear solver backend must be one of {allowed}, got {backend!r}")
