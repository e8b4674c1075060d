"""Gower's general coefficient of dissimilarity for mixed survey data.

Gower, J. C. (1971). A general coefficient of similarity and some of its properties.
Biometrics 27(4), 857-871. doi:10.2307/2528823

For rows i, j and features k with weights w_k >= 0::

    d_ij = sum_k w_k * delta_ijk * d_ijk / sum_k w_k * delta_ijk

* numeric and ordinal k: ``d_ijk = |x_ik - x_jk| / R_k`` with R_k the range of feature k
  (ordinal values enter as their level rank, i.e. ranks treated as interval data);
* categorical and boolean k: ``d_ijk = 0`` if equal else 1 (simple matching). Booleans are
  matched symmetrically (two "false" agree), unlike Gower's asymmetric dichotomous rule, because
  survey booleans such as "content movable" are states, not presence/absence marks;
* ``delta_ijk = 0`` when x_ik or x_jk is missing, so a missing feature is skipped and the weights
  of the remaining features are renormalised; a pair with no feature in common gets NaN.

Distances lie in [0, 1]. With ranges taken from the data (the default) a feature that does not
vary contributes 0 but still counts in the denominator (Gower: all pairs agree on it).

Implementation: one pass per feature over a block of rows against all rows, in float64, so the
temporaries are bounded by ``chunk_elements`` (default 2**21 elements, 16 MB per temporary)
whatever the survey size; for a symmetric matrix only the upper block triangle is computed and
mirrored (the mirrored values are bitwise equal, so HDBSCAN's symmetry check holds). The output
is float32 by default: distances in [0, 1] keep ~1e-7 absolute precision, far below survey
resolution, and 10,000 rows need 400 MB instead of 800 MB.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from flexparcel.selection.survey import Survey

__all__ = ["gower_distances", "gower_from_arrays", "feature_ranges"]

_DEFAULT_CHUNK_ELEMENTS = 1 << 21


def feature_ranges(
    survey: Survey, *, source: str = "data", other: Survey | None = None
) -> dict[str, float]:
    """Gower range R_k per numeric/ordinal column, in the column unit (ordinal: in ranks).

    ``source="data"``: max - min over the non-missing values of ``survey`` (and ``other``);
    ``source="schema"``: ``max - min`` as declared (numeric; both bounds required) and
    ``len(levels) - 1`` (ordinal), so distances do not depend on which rows were sampled.
    """
    specs = survey.schema.numeric_columns
    if source == "schema":
        out = {}
        for c in specs:
            if c.kind == "ordinal":
                out[c.name] = float(len(c.levels) - 1)
            elif c.minimum is None or c.maximum is None:
                raise ValueError(f"column {c.name!r}: schema ranges need both min and max declared")
            else:
                out[c.name] = c.maximum - c.minimum
        return out
    if source != "data":
        raise ValueError(f"ranges source {source!r} is not one of 'data', 'schema'")
    x = survey.numeric if other is None else np.vstack([survey.numeric, other.numeric])
    out = {}
    for j, c in enumerate(specs):
        col = x[:, j]
        col = col[~np.isnan(col)]
        out[c.name] = float(col.max() - col.min()) if col.size else 0.0
    return out


def gower_distances(
    survey: Survey,
    other: Survey | None = None,
    *,
    weights: Mapping[str, float] | None = None,
    ranges: Mapping[str, float] | str = "data",
    dtype: type[np.floating] = np.float32,
    chunk_elements: int = _DEFAULT_CHUNK_ELEMENTS,
) -> np.ndarray:
    """Gower distance matrix between the rows of ``survey`` (and ``other``).

    Parameters
    ----------
    survey, other : encoded surveys with the same schema; ``other=None`` gives the symmetric
        (n, n) matrix of ``survey`` against itself, else shape (len(survey), len(other)).
    weights : per-column weights overriding the schema's ``weight`` (dimensionless, >= 0).
    ranges : ``"data"`` (default; over both surveys), ``"schema"``, or a mapping column -> R_k in
        the column unit (ordinal: ranks). Use the full survey's ranges when comparing centroids.
    dtype : output dtype, float32 (default) or float64.
    chunk_elements : bound on the elements of one temporary block.

    Returns
    -------
    ndarray, shape (len(survey), len(other or survey)), values in [0, 1] (NaN: nothing shared).
    """
    schema = survey.schema
    if other is not None and other.schema.names != schema.names:
        raise ValueError("both surveys must have the same columns in the same order")
    w = {c.name: c.weight for c in schema.columns}
    for name, value in (weights or {}).items():
        if name not in w:
            raise ValueError(f"weight for unknown column {name!r} (columns: {', '.join(w)})")
        w[name] = float(value)
    if isinstance(ranges, str):
        r = feature_ranges(survey, source=ranges, other=other)
    else:
        r = {}
        for c in schema.numeric_columns:
            if c.name not in ranges:
                raise ValueError(f"ranges: no range given for column {c.name!r}")
            r[c.name] = float(ranges[c.name])
        # A given range narrower than the data would give per-feature distances above 1.
        span = feature_ranges(survey, source="data", other=other)
        for name, value in r.items():
            if span[name] > value * (1 + 1e-9):
                raise ValueError(
                    f"ranges: column {name!r} spans {span[name]:g} in the data, more than the "
                    f"given range {value:g}"
                )
    cat_a, cat_b = survey.categorical, None if other is None else other.categorical
    if other is not None:
        # Codes index per-survey level lists; re-code ``other`` into ``survey``'s levels.
        cat_a, cat_b = _common_codes(survey, other)
    return gower_from_arrays(
        survey.numeric,
        cat_a,
        None if other is None else other.numeric,
        cat_b,
        numeric_weights=[w[c.name] for c in schema.numeric_columns],
        categorical_weights=[w[c.name] for c in schema.categorical_columns],
        ranges=[r[c.name] for c in schema.numeric_columns],
        dtype=dtype,
        chunk_elements=chunk_elements,
    )


def _common_codes(a: Survey, b: Survey) -> tuple[np.ndarray, np.ndarray]:
    ca = a.categorical.copy()
    cb = b.categorical.copy()
    for j, (la, lb) in enumerate(zip(a.categorical_levels, b.categorical_levels, strict=True)):
        if la == lb:
            continue
        merged = {v: i for i, v in enumerate(la)}
        for v in lb:
            merged.setdefault(v, len(merged))
        remap = np.array([merged[v] for v in lb], dtype=np.int64)
        col = cb[:, j]
        cb[:, j] = np.where(col >= 0, remap[np.maximum(col, 0)], -1)
    return ca, cb


def gower_from_arrays(
    numeric_a: np.ndarray,
    categorical_a: np.ndarray | None = None,
    numeric_b: np.ndarray | None = None,
    categorical_b: np.ndarray | None = None,
    *,
    numeric_weights: np.ndarray | list[float] | None = None,
    categorical_weights: np.ndarray | list[float] | None = None,
    ranges: np.ndarray | list[float] | None = None,
    dtype: type[np.floating] = np.float32,
    chunk_elements: int = _DEFAULT_CHUNK_ELEMENTS,
) -> np.ndarray:
    """Gower distances from encoded arrays (the kernel behind :func:`gower_distances`).

    Parameters
    ----------
    numeric_a : (n_a, p) float, NaN = missing; numeric values or ordinal ranks.
    categorical_a : (n_a, q) int codes, negative = missing; ``None`` for q = 0.
    numeric_b, categorical_b : the second set; both ``None`` for the symmetric case.
    numeric_weights, categorical_weights : (p,), (q,) weights >= 0 (default 1).
    ranges : (p,) ranges R_k >= 0 in the feature unit; default: from the data (a and b).
    dtype : output dtype.
    chunk_elements : bound on the elements of one temporary block (memory).
    """
    na = np.atleast_2d(np.asarray(numeric_a, dtype=np.float64))
    n_a = na.shape[0]
    ca = (
        np.zeros((n_a, 0), dtype=np.int64)
        if categorical_a is None
        else np.asarray(categorical_a, dtype=np.int64).reshape(n_a, -1)
    )
    symmetric = numeric_b is None and categorical_b is None
    if symmetric:
        nb, cb = na, ca
    else:
        if numeric_b is None:
            raise ValueError("numeric_b is required when categorical_b is given")
        nb = np.atleast_2d(np.asarray(numeric_b, dtype=np.float64))
        cb = (
            np.zeros((nb.shape[0], 0), dtype=np.int64)
            if categorical_b is None
            else np.asarray(categorical_b, dtype=np.int64).reshape(nb.shape[0], -1)
        )
    p, q = na.shape[1], ca.shape[1]
    if nb.shape[1] != p or cb.shape[1] != q:
        raise ValueError(f"feature counts differ: a has ({p}, {q}), b has {nb.shape, cb.shape}")
    n_b = nb.shape[0]
    wn = _weights(numeric_weights, p, "numeric_weights")
    wc = _weights(categorical_weights, q, "categorical_weights")
    total = wn.sum() + wc.sum()
    if total <= 0:
        raise ValueError("all Gower weights are zero")

    if ranges is None:
        both = na if symmetric else np.vstack([na, nb])
        with np.errstate(invalid="ignore"):
            finite = ~np.isnan(both)
            lo = np.where(finite, both, np.inf).min(axis=0)
            hi = np.where(finite, both, -np.inf).max(axis=0)
        r = np.where(np.isfinite(hi - lo), hi - lo, 0.0)
    else:
        r = np.asarray(ranges, dtype=np.float64).reshape(-1)
        if r.shape != (p,) or not np.all(np.isfinite(r)) or np.any(r < 0):
            raise ValueError(f"ranges must be {p} finite values >= 0, got {r}")
    # Pre-scale so that |a' - b'| = w_k |a - b| / R_k. A zero range means every observed value is
    # equal: its differences are 0, and a zero scale avoids 0/0.
    scale = np.divide(wn, r, out=np.zeros(p), where=r > 0)
    sa = na * scale
    sb = sa if symmetric else nb * scale
    miss_na, miss_nb = np.isnan(na), np.isnan(nb)
    miss_ca, miss_cb = ca < 0, cb < 0
    num_has_missing = miss_na.any(axis=0) | miss_nb.any(axis=0)
    cat_has_missing = miss_ca.any(axis=0) | miss_cb.any(axis=0)
    any_missing = bool(num_has_missing.any() or cat_has_missing.any())

    out = np.empty((n_a, n_b), dtype=dtype)
    step = max(1, int(chunk_elements) // max(n_b, 1))
    for s in range(0, n_a, step):
        e = min(n_a, s + step)
        c0 = s if symmetric else 0  # symmetric: columns >= s only, mirrored below
        acc = np.zeros((e - s, n_b - c0))
        tmp = np.empty_like(acc)
        den = np.full_like(acc, total) if any_missing else None
        for k in range(p):
            if wn[k] == 0.0:
                continue
            np.subtract(sa[s:e, k, None], sb[None, c0:, k], out=tmp)
            np.abs(tmp, out=tmp)
            if num_has_missing[k]:
                invalid = miss_na[s:e, k, None] | miss_nb[None, c0:, k]
                np.copyto(tmp, 0.0, where=invalid)
                den -= wn[k] * invalid
            acc += tmp
        for k in range(q):
            if wc[k] == 0.0:
                continue
            differ = np.not_equal(ca[s:e, k, None], cb[None, c0:, k])
            if cat_has_missing[k]:
                invalid = miss_ca[s:e, k, None] | miss_cb[None, c0:, k]
                differ &= ~invalid
                den -= wc[k] * invalid
            np.multiply(differ, wc[k], out=tmp)
            acc += tmp
        if den is None:
            acc /= total
        else:
            # den == 0: no feature observed in both rows -> NaN (0/0), on purpose.
            with np.errstate(invalid="ignore", divide="ignore"):
                np.divide(acc, den, out=acc)
        out[s:e, c0:] = acc
        if symmetric and e < n_b:
            out[e:, s:e] = acc[:, e - s :].T
    return out


def _weights(w: np.ndarray | list[float] | None, n: int, name: str) -> np.ndarray:
    if w is None:
        return np.ones(n)
    arr = np.asarray(w, dtype=np.float64).reshape(-1)
    if arr.shape != (n,) or not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{name} must be {n} finite values >= 0, got {arr}")
    return arr
