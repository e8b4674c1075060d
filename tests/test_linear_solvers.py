"""The block-parallel SuperLU backend against the plain one."""

import numpy as np
import pytest
import scipy.sparse as sp

import flexparcel as fp
from flexparcel.integrate import linear
from flexparcel.integrate.linear import (
    BlockSuperLU,
    LinearSolver,
    SingularMatrixError,
    make_linear_solver,
)


def _blocks(sizes, seed=0, interleave=True):
    """Nonsymmetric, diagonally dominant sparse blocks, shuffled together so that each
    block's rows are interleaved with the others' (as the bodies of a model are not
    numbered block by block when contacts couple them), or with ``interleave=False`` one
    after another (the consignments of a conveyor, each numbered together)."""
    rng = np.random.default_rng(seed)
    mats = []
    for n in sizes:
        m = sp.random(n, n, density=min(1.0, 6.0 / n), random_state=rng, format="csr")
        mats.append(m + sp.eye(n) * (2.0 + abs(m).sum(axis=1).max()))
    a = sp.block_diag(mats, format="csr")
    if not interleave:
        return a
    p = rng.permutation(a.shape[0])
    return a[p][:, p].tocsr()


@pytest.mark.parametrize("interleave", [True, False])
@pytest.mark.parametrize("workers", [1, 2, 3])
@pytest.mark.parametrize("sizes", [(40,), (40, 7, 1, 25)])
def test_block_superlu_solves_like_superlu(workers, sizes, interleave):
    a = _blocks(sizes, interleave=interleave)
    b = np.random.default_rng(1).standard_normal(a.shape[0])
    ref = LinearSolver()
    ref.factor(a)
    s = BlockSuperLU(workers)
    s.factor(a)
    x = s.solve(b)
    # both are LU factorisations of the same (well conditioned) matrix: agreement to
    # round-off, and a residual at machine precision
    np.testing.assert_allclose(x, ref.solve(b), rtol=1e-12, atol=1e-14)
    assert np.linalg.norm(a @ x - b) <= 1e-13 * np.linalg.norm(b)
    np.testing.assert_array_equal(s.precondition(b), x)
    # refactoring another matrix replaces the factors
    a2 = _blocks(sizes, seed=2, interleave=interleave)
    s.factor(a2)
    assert np.linalg.norm(a2 @ s.solve(b) - b) <= 1e-13 * np.linalg.norm(b)
    assert s.factor_count == 2 and s.solve_count == 2
    s.close()
    assert s.workers == []


def test_block_superlu_reports_a_singular_block():
    a = _blocks((10, 5)).tolil()
    # a zero row and column make one block singular
    i = 3
    a[i, :] = 0.0
    a[:, i] = 0.0
    s = BlockSuperLU(2)
    with pytest.raises(SingularMatrixError):
        s.factor(a.tocsr())
    s.close()


def test_backend_names():
    assert isinstance(make_linear_solver("superlu-blocks"), BlockSuperLU)
    with pytest.raises(
        ValueError,
        match="one of 'superlu', 'superlu-blocks', 'superlu-blocks-mixed', 'pardiso', got 'lu'",
    ):
        make_linear_solver("lu")
    with pytest.raises(ValueError, match="workers must be >= 1"):
        BlockSuperLU(0)


@pytest.mark.parametrize("backend", ["superlu-blocks", "superlu-blocks-mixed"])
def test_block_backend_gives_the_same_motion(backend):
    # two separate sheets and a box: three independent blocks until the sheets touch; the
    # block factorisation solves the same Newton systems (orderings differ: round-off; the
    # mixed backend refines to a double-precision backward error), so the motion agrees far
    # inside the Newton tolerance (newton_tol * tol_displacement = 1e-6 m)
    from test_checkpoint import _scene

    model, s0 = _scene()
    r0 = fp.simulate(model, 0.03, dt_out=0.01, state=s0)
    opt = fp.IntegratorOptions(linear_solver=backend)
    r1 = fp.simulate(model, 0.03, dt_out=0.01, state=s0, options=opt)
    assert r1.stats["steps"] == r0.stats["steps"]
    assert np.abs(r1.positions - r0.positions).max() < 1e-9


def _backward_error(a, x, b):
    """Componentwise backward error max_i |b - A x|_i / (|A| |x| + |b|)_i (Oettli-Prager)."""
    return float(np.max(np.abs(b - a @ x) / (abs(a) @ np.abs(x) + np.abs(b))))


@pytest.mark.parametrize("sizes", [(40,), (40, 7, 1, 25)])
def test_mixed_precision_refines_to_a_double_precision_solution(sizes):
    a = _blocks(sizes, seed=3)
    b = np.random.default_rng(4).standard_normal(a.shape[0])
    ref = LinearSolver()
    ref.factor(a)
    s = make_linear_solver("superlu-blocks-mixed")
    s.factor(a)
    # the factors alone: single precision (unit round-off 6e-8), far from double's
    assert _backward_error(a, s.precondition(b), b) > 1e-10
    x = s.solve(b)
    assert _backward_error(a, x, b) <= linear.REFINE_TOL
    np.testing.assert_allclose(x, ref.solve(b), rtol=1e-12, atol=1e-14)
    assert s.refinement_steps >= 1 and s.double_fallbacks == 0
    s.close()


def test_mixed_precision_falls_back_to_double_when_refinement_cannot_converge():
    # cond(A) = 1e10: single precision's error cond * 6e-8 >> 1, so refinement cannot
    # contract and the matrix is factorised in double precision
    rng = np.random.default_rng(5)
    n = 30
    u, _ = np.linalg.qr(rng.standard_normal((n, n)))
    v, _ = np.linalg.qr(rng.standard_normal((n, n)))
    a = sp.csr_matrix(u @ np.diag(np.logspace(0, -10, n)) @ v.T)
    b = rng.standard_normal(n)
    s = make_linear_solver("superlu-blocks-mixed")
    s.factor(a)
    x = s.solve(b)
    assert s.double_fallbacks == 1
    ref = LinearSolver()
    ref.factor(a)
    # the same double-precision LU as the plain backend, bit for bit
    np.testing.assert_array_equal(x, ref.solve(b))
    s.close()


def test_mixed_precision_factorises_in_double_where_single_loses_a_pivot():
    # [[1, 1], [1, 1 + 1e-10]]: the second pivot is 1e-10 in double precision and exactly 0
    # once the matrix is rounded to single precision (unit round-off 6e-8)
    a = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0 + 1e-10]]))
    b = np.array([2.0, 2.0 + 1e-10])  # x = (1, 1)
    s = make_linear_solver("superlu-blocks-mixed")
    s.factor(a)
    assert s.double_fallbacks == 1 and s.factor_count == 1
    ref = LinearSolver()
    ref.factor(a)
    np.testing.assert_array_equal(s.solve(b), ref.solve(b))
    assert s.refinement_steps == 0
    s.close()
