"""Gower (1971) distance: hand-computed cases, missing values, weights, ranges, chunking."""

from __future__ import annotations

import numpy as np
import pytest

from flexparcel.selection import (
    ColumnSpec,
    SurveySchema,
    feature_ranges,
    gower_distances,
    gower_from_arrays,
    survey_from_records,
)

SCHEMA = SurveySchema(
    (
        ColumnSpec("x", "numeric", unit="cm"),
        ColumnSpec("o", "ordinal", levels=(1, 2, 3)),
        ColumnSpec("c", "categorical", levels=("a", "b", "c")),
        ColumnSpec("b", "boolean"),
    ),
    id_column="id",
)
ROWS = [
    {"id": "r1", "x": 0.0, "o": 1, "c": "a", "b": True},
    {"id": "r2", "x": 10.0, "o": 3, "c": "a", "b": False},
    {"id": "r3", "x": 5.0, "o": 2, "c": "b", "b": True},
]


def test_hand_computed_mixed_kinds():
    # Ranges from the data: R_x = 10 cm, R_o = 2 ranks. Four features, unit weights:
    # d12 = (|0-10|/10 + |0-2|/2 + [a!=a] + [T!=F]) / 4 = (1 + 1 + 0 + 1) / 4
    # d13 = (0.5 + 0.5 + 1 + 0) / 4 ; d23 = (0.5 + 0.5 + 1 + 1) / 4
    d = gower_distances(survey_from_records(ROWS, SCHEMA), dtype=np.float64)
    expected = np.array([[0, 0.75, 0.5], [0.75, 0, 0.75], [0.5, 0.75, 0]])
    np.testing.assert_allclose(d, expected, atol=1e-15)


def test_missing_values_skip_feature_and_renormalise():
    # r4 lacks x and c: only o and b are compared, denominators 2 (Gower's delta_ijk = 0).
    rows = [*ROWS, {"id": "r4", "x": "", "o": 3, "c": "NA", "b": True}]
    d = gower_distances(survey_from_records(rows, SCHEMA), dtype=np.float64)
    # d14 = (|0-2|/2 + 0) / 2, d24 = (0 + 1) / 2, d34 = (|1-2|/2 + 0) / 2
    np.testing.assert_allclose(d[3, :3], [0.5, 0.5, 0.25], atol=1e-15)
    np.testing.assert_allclose(d[:3, 3], [0.5, 0.5, 0.25], atol=1e-15)
    # Pairs of complete rows are unchanged by r4 (ranges unchanged too).
    np.testing.assert_allclose(d[:3, :3][0, 1], 0.75)
    assert d[3, 3] == 0.0


def test_weights_from_schema_and_override():
    # w_x = 2, w_c = 0.5, others 1; sum of weights 4.5.
    # d12 = (2*1 + 1*1 + 0.5*0 + 1*1) / 4.5 ; d13 = (2*0.5 + 0.5 + 0.5*1 + 0) / 4.5
    d = gower_distances(
        survey_from_records(ROWS, SCHEMA), weights={"x": 2.0, "c": 0.5}, dtype=np.float64
    )
    assert d[0, 1] == pytest.approx(4.0 / 4.5, abs=1e-15)
    assert d[0, 2] == pytest.approx(2.0 / 4.5, abs=1e-15)
    # Weight 0 removes a feature entirely (not counted in the denominator).
    d0 = gower_distances(survey_from_records(ROWS, SCHEMA), weights={"b": 0.0}, dtype=np.float64)
    assert d0[0, 1] == pytest.approx(2.0 / 3.0, abs=1e-15)
    with pytest.raises(ValueError, match="unknown column 'nope'"):
        gower_distances(survey_from_records(ROWS, SCHEMA), weights={"nope": 1.0})


def test_missing_and_weights_together():
    # r4 lacks x: with w_x = 2 its denominator is 1 + 1 + 1 = 3 (o, c, b).
    rows = [*ROWS, {"id": "r4", "x": None, "o": 1, "c": "c", "b": False}]
    d = gower_distances(survey_from_records(rows, SCHEMA), weights={"x": 2.0}, dtype=np.float64)
    # d14 = (0 + 1 + 1) / 3
    assert d[0, 3] == pytest.approx(2.0 / 3.0, abs=1e-15)


def test_ordinal_uses_ranks_not_values():
    schema = SurveySchema((ColumnSpec("o", "ordinal", levels=(1, 2, 10)),))
    s = survey_from_records([{"o": 1}, {"o": 2}, {"o": 10}], schema)
    # Ranks 0, 1, 2 -> range 2: d(1, 2) = 1/2, although the values differ by 1 of 9.
    np.testing.assert_allclose(gower_distances(s, dtype=np.float64)[0], [0, 0.5, 1])


def test_schema_and_explicit_ranges():
    x = ColumnSpec("x", "numeric", minimum=0, maximum=40)
    schema = SurveySchema((x, ColumnSpec("o", "ordinal", levels=(1, 2, 3, 4, 5))))
    s = survey_from_records([{"x": 10, "o": 2}, {"x": 20, "o": 3}], schema)
    assert feature_ranges(s, source="schema") == {"x": 40.0, "o": 4.0}
    # (10/40 + 1/4) / 2
    assert gower_distances(s, ranges="schema")[0, 1] == pytest.approx(0.25)
    assert gower_distances(s, ranges={"x": 20.0, "o": 2.0})[0, 1] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="column 'x' spans 10 .* more than the given range 5"):
        gower_distances(s, ranges={"x": 5.0, "o": 2.0})


def test_constant_feature_contributes_zero_but_counts():
    schema = SurveySchema((ColumnSpec("x", "numeric"), ColumnSpec("k", "numeric")))
    s = survey_from_records([{"x": 0, "k": 7}, {"x": 1, "k": 7}], schema)
    # R_k = 0: all agree on k; d = (1 + 0) / 2.
    assert gower_distances(s)[0, 1] == pytest.approx(0.5)


def test_cross_distances_match_the_symmetric_block():
    s = survey_from_records(ROWS, SCHEMA)
    full = gower_distances(s, dtype=np.float64)
    ranges = feature_ranges(s)
    cross = gower_distances(s.subset([0, 1]), s.subset([2]), ranges=ranges, dtype=np.float64)
    np.testing.assert_allclose(cross, full[:2, 2:], atol=1e-15)


def _reference_gower(num, cat, wn, wc):
    """Pair-by-pair Gower, written straight from the 1971 formula (test oracle)."""
    n = num.shape[0]
    r = np.nanmax(num, axis=0) - np.nanmin(num, axis=0)
    out = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = w = 0.0
            for k in range(num.shape[1]):
                if not (np.isnan(num[i, k]) or np.isnan(num[j, k])):
                    s += wn[k] * (abs(num[i, k] - num[j, k]) / r[k] if r[k] > 0 else 0.0)
                    w += wn[k]
            for k in range(cat.shape[1]):
                if cat[i, k] >= 0 and cat[j, k] >= 0:
                    s += wc[k] * (cat[i, k] != cat[j, k])
                    w += wc[k]
            out[i, j] = s / w if w > 0 else np.nan
    return out


def test_vectorised_chunked_kernel_matches_pairwise_formula():
    rng = np.random.default_rng(7)
    n = 37
    num = rng.normal(size=(n, 3)) * [1.0, 10.0, 100.0]
    num[rng.random(num.shape) < 0.15] = np.nan
    cat = rng.integers(0, 3, size=(n, 2))
    cat[rng.random(cat.shape) < 0.15] = -1
    wn, wc = np.array([1.0, 2.0, 0.5]), np.array([1.5, 1.0])
    ref = _reference_gower(num, cat, wn, wc)
    for chunk in (1, 50, 1 << 21):  # one row, a few rows, everything at once
        d = gower_from_arrays(
            num, cat, numeric_weights=wn, categorical_weights=wc, dtype=np.float64,
            chunk_elements=chunk,
        )  # fmt: skip
        np.testing.assert_allclose(d, ref, atol=1e-12, equal_nan=True)
        # Exact symmetry (HDBSCAN checks it) and exact zeros on the diagonal.
        assert np.array_equal(d, d.T, equal_nan=True)
    d32 = gower_from_arrays(num, cat, numeric_weights=wn, categorical_weights=wc)
    assert d32.dtype == np.float32
    np.testing.assert_allclose(d32, ref, atol=1e-6, equal_nan=True)


def test_no_shared_feature_gives_nan():
    schema = SurveySchema((ColumnSpec("x", "numeric"), ColumnSpec("c", "categorical")))
    s = survey_from_records([{"x": 1, "c": ""}, {"x": "", "c": "a"}, {"x": 2, "c": "a"}], schema)
    d = gower_distances(s)
    assert np.isnan(d[0, 1]) and np.isnan(d[1, 0])
    assert d[0, 2] == pytest.approx(1.0) and d[1, 2] == pytest.approx(0.0)
