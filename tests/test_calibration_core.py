"""Building blocks of flexparcel.calibration: parameters, designs, screening, error, optimiser."""

from __future__ import annotations

import numpy as np
import pytest

from flexparcel.calibration import (
    AnovaScreening,
    NelderMeadCalibrator,
    Parameter,
    ParameterSpace,
    Target,
    extend_latin_hypercube,
    fractional_factorial,
    full_factorial,
    latin_hypercube,
    lenth_pse,
    range_weights,
    screen_responses,
    weighted_error,
)
from flexparcel.calibration.simulators import ANALYTIC_PARAMETERS, analytic


def analytic_space() -> ParameterSpace:
    return ParameterSpace(
        Parameter(n, lo, hi, unit=u, scale=s) for n, (lo, hi, u, s) in ANALYTIC_PARAMETERS.items()
    )


# -- parameters ----------------------------------------------------------------------------------


def test_unit_and_coded_maps_round_trip_with_log_scale():
    space = analytic_space()
    U = np.array([[0.0] * 6, [1.0] * 6, [0.5] * 6])
    X = space.from_unit(U)
    np.testing.assert_allclose(X[0], space.lower)
    np.testing.assert_allclose(X[1], space.upper)
    # log scale: the midpoint is the geometric mean, 200 MPa .. 2000 MPa -> sqrt(200 * 2000)
    assert X[2, 0] == pytest.approx(np.sqrt(200.0 * 2000.0))
    assert X[2, 2] == pytest.approx(550.0)
    np.testing.assert_allclose(space.to_unit(X), U, atol=1e-12)
    np.testing.assert_allclose(space.from_coded(2 * U - 1), X)
    assert space["youngs_modulus"].nominal_value == pytest.approx(np.sqrt(4e5))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(lower=2.0, upper=1.0), "lower < upper"),
        (dict(lower=0.0, upper=1.0, scale="log"), "lower > 0"),
        (dict(lower=0.0, upper=1.0, scale="cubic"), "scale"),
        (dict(lower=0.0, upper=1.0, nominal=3.0), "outside"),
        (dict(lower=float("nan"), upper=1.0), "finite"),
    ],
)
def test_bad_parameters_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Parameter("p", **kwargs)


def test_space_rejects_duplicates_and_wrong_widths():
    p = Parameter("a", 0, 1)
    with pytest.raises(ValueError, match="duplicate"):
        ParameterSpace([p, p])
    with pytest.raises(ValueError, match="columns"):
        ParameterSpace([p]).to_unit(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="weight"):
        Target("e", "r", 1.0, weight=-1.0)


# -- designs -------------------------------------------------------------------------------------


def test_latin_hypercube_is_latin_and_seeded():
    n, d = 17, 3
    U = latin_hypercube(n, d, random_state=3)
    assert U.shape == (n, d)
    # Latin property: in every column exactly one point per stratum [k/n, (k+1)/n).
    for j in range(d):
        np.testing.assert_array_equal(np.sort(np.floor(U[:, j] * n)), np.arange(n))
    np.testing.assert_array_equal(U, latin_hypercube(n, d, random_state=3))
    assert not np.array_equal(U, latin_hypercube(n, d, random_state=4))


def test_extension_keeps_space_filling():
    from scipy.stats import qmc

    old = latin_hypercube(10, 2, random_state=0)
    new = extend_latin_hypercube(old, 10, random_state=1, n_candidates=16)
    assert new.shape == (10, 2)
    both = np.vstack([old, new])
    # The chosen batch is the best of 16 candidates, so the union is at least as uniform as a
    # blind batch drawn from the same generator would be on average.
    blind = [
        qmc.discrepancy(np.vstack([old, latin_hypercube(10, 2, random_state=100 + s)]))
        for s in range(16)
    ]
    assert qmc.discrepancy(both) <= np.median(blind)


def test_full_factorial_is_balanced_and_orthogonal():
    C = full_factorial(4)
    assert C.shape == (16, 4)
    assert len({tuple(r) for r in C}) == 16
    np.testing.assert_array_equal(C.T @ C, 16 * np.eye(4))
    np.testing.assert_array_equal(C[:4, 0], [-1, 1, -1, 1])  # Yates order


def test_fractional_factorial_generators_define_aliases():
    C = fractional_factorial(5, ["E = ABCD"])
    assert C.shape == (16, 5)
    np.testing.assert_array_equal(C[:, 4], np.prod(C[:, :4], axis=1))
    np.testing.assert_array_equal(C.T @ C, 16 * np.eye(5))  # resolution V: mains clear
    C = fractional_factorial(4, ["D = -AB"])
    np.testing.assert_array_equal(C[:, 3], -C[:, 0] * C[:, 1])
    with pytest.raises(ValueError, match="form"):
        fractional_factorial(4, ["D := AB"])
    with pytest.raises(ValueError, match="basic factors"):
        fractional_factorial(4, ["D = AD"])


# -- screening -----------------------------------------------------------------------------------


def test_anova_recovers_a_known_linear_model():
    C = full_factorial(4)
    names = ["a", "b", "c", "d"]
    a, b, c, d = C.T
    # y = 10 + 3a - 2c + 1.5ab + (a b c) + (a b c d)/2 ; the last two terms are 3- and 4-factor
    # interactions, pooled into the error: SS_error = 16 (1^2 + 0.5^2) = 20 on 5 df.
    y = 10 + 3 * a - 2 * c + 1.5 * a * b + a * b * c + 0.5 * a * b * c * d
    s = AnovaScreening(alpha=0.05).fit(C, y, names)
    assert s.method_ == "anova"
    assert s.residual_df_ == 16 - 1 - 10
    assert s.residual_ms_ == pytest.approx(20.0 / 5)
    assert s.effects_["a"] == pytest.approx(6.0)  # effect = 2 * coefficient
    assert s.effects_["a:b"] == pytest.approx(3.0)
    table = {r["term"]: r for r in s.table_}
    assert table["a"]["sum_sq"] == pytest.approx(16 * 3.0**2)
    assert table["a"]["F"] == pytest.approx(16 * 9 / 4.0)
    assert s.significant_factors_ == ["a", "b", "c"]  # b only through a:b


def test_lenth_on_a_saturated_design():
    C = full_factorial(3)
    names = ["a", "b", "c"]
    # Saturated: 7 effects from 8 runs. Two large effects, the other five +-0.1 (a fixed
    # pattern): median |c| = 0.2 so PSE = 0.3, margin of error t(0.975, 7/3) * 0.3 ~ 1.1, far
    # below the real effects (8 and 5) and far above the inert ones (0.2).
    M = np.column_stack(
        [
            np.prod(C[:, list(s)], axis=1)
            for s in [(0,), (1,), (2,), (0, 1), (0, 2), (1, 2), (0, 1, 2)]
        ]
    )
    coef = np.array([4.0, 0.1, -2.5, -0.1, 0.1, -0.1, 0.1])
    y = 1.0 + M @ coef
    s = AnovaScreening(alpha=0.05).fit(C, y, names)
    assert s.method_ == "lenth"
    assert s.pse_ == pytest.approx(lenth_pse(2 * coef))
    assert s.significant_terms_ == ["a", "c"]
    assert s.significant_factors_ == ["a", "c"]


def test_aliased_terms_are_reported_and_alias_chains_kept():
    C = fractional_factorial(4, ["D = ABC"])  # resolution IV: 2FIs aliased in pairs
    a, b, c, d = C.T
    # A real c:d interaction; the design estimates it as a:b (the first term of the chain).
    # Inert effects +-0.1 give PSE = 0.15 and a margin of error ~0.6 << 3.
    y = 1 + 2 * a + 1.5 * c * d + 0.05 * (b - c + d) + 0.05 * (-a * c + a * d)
    s = AnovaScreening(alpha=0.05).fit(C, y, list("abcd"))
    assert s.method_ == "lenth"  # 8 runs, 7 terms: saturated
    assert s.aliased_["c:d"] == "a:b"
    assert "c:d" not in s.terms_
    assert s.significant_terms_ == ["a", "a:b"]
    # a:b might be c:d: all four factors are kept rather than dropping an active one.
    assert s.significant_factors_ == ["a", "b", "c", "d"]


def test_screening_finds_exactly_the_active_factors_of_the_analytic_drop():
    """The analytic drop depends on E, c, d only (damping_ratio, friction, label_mass inert).

    Why this is deterministic, not luck: the responses are products of three functions of the
    active factors, so besides main effects and 2FIs they carry a three-factor interaction that
    the ANOVA pools into its error (as for a real deterministic simulation). That error mean
    square is orders of magnitude above the 0.3 % hash "noise", which is all an inert factor's
    terms contain, so their F values are ~1e-2 (p ~ 0.9) whatever the noise pattern, while the
    active main effects have F > 100.
    """
    space = analytic_space()
    C = full_factorial(6)  # the paper's 64-run screening
    rows = [analytic(p, mode="drop") for p in space.as_dicts(space.from_coded(C))]
    responses = {r: np.array([row[r] for row in rows]) for r in rows[0]}
    significant, fitted = screen_responses(C, responses, space.names, alpha=0.05)
    assert significant == ["youngs_modulus", "contact_stiffness", "contact_damping"]
    inert = {"damping_ratio", "friction", "label_mass"}
    for s in fitted.values():
        assert s.method_ == "anova"
        for row in s.table_:
            factors = set(row["term"].split(":"))
            if factors & inert:
                assert row["p"] > 0.5, row
            elif row["term"] in space.names:
                assert row["F"] > 100, row


# -- error and optimiser ---------------------------------------------------------------------


def test_weighted_error_is_the_papers_eq_11():
    t = np.array([127.0, 32.0, 7.0])
    p = np.array([128.0, 27.0, 6.2])
    w = np.array([1 / 100, 1 / 50, 1 / 10])
    expected = (0.01 * -1.0) ** 2 + (0.02 * 5.0) ** 2 + (0.1 * 0.8) ** 2
    assert weighted_error(t, p, w) == pytest.approx(expected, rel=1e-14)
    np.testing.assert_allclose(range_weights([[1.0, 5.0], [3.0, 1.0], [2.0, 9.0]]), [0.5, 0.125])
    with pytest.raises(ValueError, match="does not vary"):
        range_weights([[1.0], [1.0]])


def test_nelder_mead_multistart_finds_the_global_minimum():
    # Two basins in unit coordinates; the global one (depth 0) at u = (0.8, 0.3), a local one
    # (depth 0.5) at u = (0.2, 0.7). Several starts must find the global minimum.
    space = ParameterSpace([Parameter("x", 1.0, 100.0, scale="log"), Parameter("y", -1.0, 1.0)])

    def predict(x):
        u = space.to_unit(x[None, :])[0]
        g = np.sum((u - [0.8, 0.3]) ** 2)
        loc = np.sum((u - [0.2, 0.7]) ** 2)
        return np.array([min(g, 0.5 + loc)])

    opt = NelderMeadCalibrator(n_starts=6, random_state=0).fit(predict, space, [0.0], [1.0])
    np.testing.assert_allclose(opt.u_, [0.8, 0.3], atol=1e-3)
    assert opt.error_ < 1e-10
    assert opt.x_[0] == pytest.approx(10 ** (2 * 0.8), rel=1e-2)
    assert len(opt.starts_) == 6
