"""The block-parallel SuperLU backend against the plain one."""

import numpy as np
import pytest
import scipy.sparse as sp

import flexparcel as fp
from flexparcel.integrate.linear import (
    BlockSuperLU,
    LinearSolver,
    SingularMatrixError,
    make_linear_solver,
)


def _blocks(sizes, seed=0):
    """Nonsymmetric, diagonally dominant sparse blocks, shuffled together so that each
    block's rows are interleaved with the others' (as the bodies of a model are not
    numbered block by block when contacts couple them)."""
    rng = np.random.default_rng(seed)
    mats = []
    for n in sizes:
        m = sp.random(n, n, density=min(1.0, 6.0 / n), random_state=rng, format="csr")
        mats.append(m + sp.eye(n) * (2.0 + abs(m).sum(axis=1).max()))
    a = sp.block_diag(mats, format="csr")
    p = rng.permutation(a.shape[0])
    return a[p][:, p].tocsr()


@pytest.mark.parametrize("workers", [1, 2, 3])
@pytest.mark.parametrize("sizes", [(40,), (40, 7, 1, 25)])
def test_block_superlu_solves_like_superlu(workers, sizes):
    a = _blocks(sizes)
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
    a2 = _blocks(sizes, seed=2)
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
    with pytest.raises(ValueError, match="'superlu', 'superlu-blocks' or 'pardiso', got 'lu'"):
        make_linear_solver("lu")
    with pytest.raises(ValueError, match="workers must be >= 1"):
        BlockSuperLU(0)


def test_block_backend_gives_the_same_motion():
    # two separate sheets and a box: three independent blocks until the sheets touch; the
    # block factorisation solves the same Newton systems (orderings differ: round-off), so
    # the motion agrees far inside the Newton tolerance (newton_tol * tol_displacement =
    # 1e-6 m)
    from test_checkpoint import _scene

    model, s0 = _scene()
    r0 = fp.simulate(model, 0.03, dt_out=0.01, state=s0)
    opt = fp.IntegratorOptions(linear_solver="superlu-blocks")
    r1 = fp.simulate(model, 0.03, dt_out=0.01, state=s0, options=opt)
    assert r1.stats["steps"] == r0.stats["steps"]
    assert np.abs(r1.positions - r0.positions).max() < 1e-9
