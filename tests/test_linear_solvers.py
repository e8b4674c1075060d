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
        match="one of 'auto', 'superlu', 'cholmod', 'superlu-blocks', 'superlu-blocks-mixed', "
        "'pardiso', got 'lu'",
    ):
        make_linear_solver("lu")
    with pytest.raises(ValueError, match="workers must be >= 1"):
        BlockSuperLU(0)


@pytest.mark.parametrize("backend", ["superlu-blocks", "superlu-blocks-mixed", "cholmod"])
def test_block_backend_gives_the_same_motion(backend, monkeypatch):
    # two separate sheets and a box: three independent blocks until the sheets touch; the
    # block factorisation solves the same Newton systems (orderings differ: round-off; the
    # mixed backend refines to a double-precision backward error), so the motion agrees far
    # inside the Newton tolerance (newton_tol * tol_displacement = 1e-6 m)
    from test_checkpoint import _scene

    # The residual test is off here: it vetoes iterates whose residual sits at its bound, and
    # such a veto flips with the round-off of the solve (measured with it on: superlu-blocks
    # 26 steps against 29, 6.2e-6 m apart). This test is about the solves, so it compares
    # runs whose every Newton decision is the same.
    model, s0 = _scene()
    r0 = fp.simulate(model, 0.03, dt_out=0.01, state=s0,
                     options=fp.IntegratorOptions(linear_solver="superlu",
                                                  newton_residual_tol=1e9))  # fmt: skip
    opt = fp.IntegratorOptions(linear_solver=backend, newton_residual_tol=1e9)
    if backend == "cholmod":
        # cholmod solves the friction-coupled (nonsymmetric) matrices by GMRES; solved to
        # near round-off it takes SuperLU's steps (the same Newton decisions; measured 65
        # steps, 2.2e-11 m apart)
        with monkeypatch.context() as m:
            m.setattr(linear, "KRYLOV_RTOL", 1e-12)
            exact = fp.simulate(model, 0.03, dt_out=0.01, state=s0, options=opt)
        assert exact.stats["steps"] == r0.stats["steps"]
        assert np.abs(exact.positions - r0.positions).max() < 1e-8
    r1 = fp.simulate(model, 0.03, dt_out=0.01, state=s0, options=opt)
    if backend != "cholmod":
        assert r1.stats["steps"] == r0.stats["steps"]
        assert np.abs(r1.positions - r0.positions).max() < 1e-9
        return
    # By default GMRES stops at KRYLOV_RTOL (1e-3), an inexact Newton correction: each step's
    # Newton iterate then ends elsewhere within Newton's tolerance (1e-6 m), the step control
    # sees other Newton histories and may take other steps (measured: 65 steps with threaded
    # BLAS, 69 single-threaded, against SuperLU's 65), and the differences carry over the
    # steps (measured 2.2e-6 and 4.6e-6 m at one contact node). Bound: ten Newton tolerances,
    # a tenth of the local error tolerance (1e-4 m per step)
    assert abs(r1.stats["steps"] - r0.stats["steps"]) <= 0.1 * r0.stats["steps"]
    assert np.abs(r1.positions - r0.positions).max() < 1e-5


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


# ---------------------------------------------------------------- CHOLMOD (the ``fast`` extra)

cholmod = pytest.importorskip("cvxopt.cholmod", reason="the cholmod backend needs cvxopt")


def _shell_like(n=60, seed=0, skew=0.0, couple=()):
    """A symmetric positive definite matrix with the sparsity of a banded FE mesh (a mass
    term on the diagonal, like the Newton matrix c_a M + K), plus an optional one-way
    coupling ``skew`` (friction: the tangential force follows the normal one) and extra
    symmetric couplings ``couple`` (i, j) (a contact pair switching on)."""
    rng = np.random.default_rng(seed)
    g = sp.diags([rng.uniform(0.5, 1.0, n - k) for k in (1, 2, 5)], [1, 2, 5], (n, n))
    for i, j in couple:
        g = g + sp.coo_matrix(([0.3], ([min(i, j)], [max(i, j)])), shape=(n, n))
    k = g + g.T
    a = (k + sp.diags(abs(k).sum(axis=1).A1 + 1.0)).tocsr()
    if skew:
        w = sp.coo_matrix((skew * rng.uniform(size=n - 1), (np.arange(1, n), np.arange(n - 1))),
                          shape=(n, n))  # fmt: skip
        a = (a + w - w.multiply(0) + sp.coo_matrix(w.shape)).tocsr()
        a = (a + 0.0 * a.T).tocsr()  # keep the pattern structurally symmetric
    a.sort_indices()
    return a


def test_backend_auto_takes_cholmod_where_cvxopt_is_installed():
    assert make_linear_solver().name == "cholmod"
    assert make_linear_solver("auto").name == "cholmod"
    assert isinstance(make_linear_solver("cholmod"), linear.CholmodSolver)


@pytest.mark.parametrize("skew", [0.0, 0.05])
def test_cholmod_solves_like_superlu(skew):
    # symmetric: one Cholesky solve; nonsymmetric: GMRES preconditioned by the Cholesky
    # factor of the symmetric part, to KRYLOV_RTOL (1e-3) of the residual
    a = _shell_like(skew=skew)
    assert (abs(a - a.T).max() > 0) == (skew > 0)
    b = np.random.default_rng(3).standard_normal(a.shape[0])
    ref = LinearSolver()
    ref.factor(a)
    s = make_linear_solver("cholmod")
    s.factor(a)
    x = s.solve(b)
    tol = 1e-13 if skew == 0 else linear.KRYLOV_RTOL
    assert np.linalg.norm(a @ x - b) <= tol * np.linalg.norm(b)
    # the condition number of these matrices is ~10: the solutions agree to that factor
    np.testing.assert_allclose(x, ref.solve(b), rtol=0, atol=20 * tol * np.abs(x).max())
    assert (s.krylov_iterations > 0) == (skew > 0)
    assert s.fallbacks == 0 and s.symbolic_count == 1


def test_cholmod_takes_a_one_way_coupling_that_scipy_left_structurally_nonsymmetric():
    # a friction block couples the tangential force to the normal one but not back, and
    # scipy's sparse sums drop the exact zeros of the other side: the pattern is then not
    # structurally symmetric. The solver holds the pattern with its transpose, so the matrix
    # (positive definite symmetric part) goes to Cholesky + GMRES, not to SuperLU
    a = _shell_like()
    n = a.shape[0]
    w = sp.coo_matrix((0.05 * np.ones(n - 10), (np.arange(10, n), np.arange(n - 10))),
                      shape=(n, n))  # fmt: skip
    a = (a + w).tocsr()
    a.sort_indices()
    pattern = (a != 0).astype(int)
    assert (pattern - pattern.T).nnz > 0  # the one-way entries have no partner
    b = np.random.default_rng(6).standard_normal(n)
    s = make_linear_solver("cholmod")
    s.factor(a)
    x = s.solve(b)
    assert s.fallbacks == 0 and s.krylov_iterations > 0
    assert np.linalg.norm(a @ x - b) <= linear.KRYLOV_RTOL * np.linalg.norm(b)


def test_cholmod_reuses_the_symbolic_analysis_while_patterns_stay_within_the_union():
    s = make_linear_solver("cholmod")
    b = np.ones(60)
    # a contact coupling 3-40 switches on, off and on again: the held pattern grows once
    # to the union, and the later matrices (subsets of it) reuse its analysis
    for couple in [(), [(3, 40)], (), [(3, 40)], ()]:
        a = _shell_like(couple=couple)
        s.factor(a)
        assert np.linalg.norm(a @ s.solve(b) - b) <= 1e-13 * np.linalg.norm(b)
    assert s.symbolic_count == 2
    # a pattern far larger than the held one is analysed from scratch (no union)
    big = _shell_like(couple=[(i, (i + 30) % 60) for i in range(0, 60, 2)])
    s.factor(big)
    assert np.linalg.norm(big @ s.solve(b) - b) <= 1e-13 * np.linalg.norm(b)
    assert s.symbolic_count == 3


def test_cholmod_falls_back_to_superlu_where_the_matrix_is_not_positive_definite():
    a = _shell_like().tolil()
    a[7, 7] = -50.0  # indefinite, still regular
    a = a.tocsr()
    b = np.random.default_rng(4).standard_normal(a.shape[0])
    s = make_linear_solver("cholmod")
    s.factor(a)
    x = s.solve(b)
    assert s.fallbacks == 1 and s.symbolic_count == 2  # CHOLMOD's analysis, SuperLU's
    assert np.linalg.norm(a @ x - b) <= 1e-12 * np.linalg.norm(b)
    # the next INDEFINITE_SKIP matrices go straight to SuperLU (the matrices of one step
    # tend to stay indefinite), then a positive definite one is factorised by CHOLMOD again,
    # on the analysis it held (that depends on the pattern only)
    a2 = _shell_like(seed=5)
    for k in range(linear.INDEFINITE_SKIP):
        s.factor(a2)
        assert np.linalg.norm(a2 @ s.solve(b) - b) <= 1e-12 * np.linalg.norm(b)
        assert s.fallbacks == 2 + k
    s.factor(a2)
    assert np.linalg.norm(a2 @ s.solve(b) - b) <= 1e-13 * np.linalg.norm(b)
    assert s.fallbacks == 1 + linear.INDEFINITE_SKIP
    assert s.symbolic_count == 2 + linear.INDEFINITE_SKIP  # SuperLU's orderings only


def test_cholmod_history_restores_the_held_pattern_and_refuses_a_malformed_one():
    # the held pattern sets the ordering, hence the round-off of every later solve: a solver
    # restored from another's history solves bit for bit like it
    s = make_linear_solver("cholmod")
    s.factor(_shell_like(couple=[(3, 40)]))
    s.factor(_shell_like())  # within the held union: no new analysis
    hist = s.history()
    assert set(hist) == {"pattern_indptr", "pattern_indices", "indefinite_left"}
    assert int(hist["indefinite_left"][0]) == 0
    t = make_linear_solver("cholmod")
    t.restore_history(hist)
    a, b = _shell_like(seed=7), np.arange(60.0)
    s.factor(a)
    t.factor(a)
    np.testing.assert_array_equal(s.solve(b), t.solve(b))
    assert t.symbolic_count == 1  # analysed once, on the restored pattern
    bad = {
        "pattern_indptr": hist["pattern_indptr"],
        "pattern_indices": hist["pattern_indices"] + 99,
    }
    with pytest.raises(ValueError, match="held sparsity pattern is malformed"):
        t.restore_history(bad)
    with pytest.raises(ValueError, match="indefinite_left is malformed"):
        t.restore_history({**hist, "indefinite_left": np.array([-1])})
    assert make_linear_solver("superlu").history() == {}


def test_cholmod_history_carries_the_superlu_run_after_an_indefinite_matrix():
    # a solver restored mid-way through the SuperLU run after an indefinite matrix goes on
    # exactly as the original: the same backend for the same matrices, the same solutions
    ind = _shell_like().tolil()
    ind[7, 7] = -50.0
    s = make_linear_solver("cholmod")
    s.factor(ind.tocsr())
    a, b = _shell_like(seed=9), np.arange(60.0)
    s.factor(a)  # one of the skipped ones
    t = make_linear_solver("cholmod")
    t.restore_history(s.history())
    assert int(s.history()["indefinite_left"][0]) == linear.INDEFINITE_SKIP - 1
    for solver in (s, t):
        solver.factor(a)
    np.testing.assert_array_equal(s.solve(b), t.solve(b))
    assert t.fallbacks == 1  # SuperLU, as the original
