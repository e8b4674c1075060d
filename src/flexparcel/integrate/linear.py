"""Sparse linear solvers behind one small interface: ``factor(A)`` then ``solve(b)``.

Default: scipy SuperLU with the MMD(A^T+A) ordering and symmetric mode, which the design notes
measured 2-3x faster than the default COLAMD on shell matrices and robust when rows couple many
nodes. ``backend="superlu-blocks"`` (:class:`BlockSuperLU`): the same, one factorisation per
independent block of the matrix (bodies that do not touch, e.g. the consignments on a conveyor)
on worker threads; ``backend="superlu-blocks-mixed"``: the same factorised in single precision,
with iterative refinement in double precision to a double-precision solution.
Optional: Pardiso through ``pypardiso`` if installed (``backend="pardiso"``).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

__all__ = ["LinearSolver", "BlockSuperLU", "make_linear_solver", "SingularMatrixError"]


class SingularMatrixError(RuntimeError):
    """The tangent could not be factorised (singular: an unsupported rigid-body mode?)."""


class LinearSolver:
    """SuperLU backend. ``factor_count`` and ``solve_count`` are kept for the benchmark."""

    name = "superlu"

    def __init__(self) -> None:
        self._lu = None
        self.factor_count = 0
        self.solve_count = 0

    def factor(self, a: sp.csr_matrix) -> None:
        self._lu = _superlu(a)
        self.factor_count += 1

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        return self._lu.solve(b)

    def precondition(self, b: np.ndarray) -> np.ndarray:
        """Apply the held factorisation as a preconditioner (for Krylov reuse)."""
        return self._lu.solve(b)


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

    def solve(self, b: np.ndarray) -> np.ndarray:
        self.solve_count += 1
        return self._solver.solve(self._a, b)

    def precondition(self, b: np.ndarray) -> np.ndarray:
        return self._solver.solve(self._a, b)


BACKENDS = ("superlu", "superlu-blocks", "superlu-blocks-mixed", "pardiso")


def make_linear_solver(backend: str = "superlu") -> LinearSolver:
    """``"superlu"`` (default, always available), ``"superlu-blocks"`` (:class:`BlockSuperLU`),
    ``"superlu-blocks-mixed"`` (:class:`BlockSuperLU` with ``mixed_precision=True``) or
    ``"pardiso"`` (needs pypardiso)."""
    if backend == "superlu":
        return LinearSolver()
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
