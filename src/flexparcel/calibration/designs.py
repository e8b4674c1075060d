"""Designs of experiments: Latin hypercubes (unit coordinates) and two-level factorials (coded).

Latin hypercubes return points in unit coordinates ``[0, 1]^d`` and factorials in coded units
``{-1, +1}^k``; :class:`~flexparcel.calibration.parameters.ParameterSpace` maps both to physical
values. All random designs are seeded (``random_state``) so a study regenerates the same runs and
their parameter hashes match the runs already in the store.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Sequence

import numpy as np

__all__ = [
    "FACTOR_LETTERS",
    "latin_hypercube",
    "extend_latin_hypercube",
    "full_factorial",
    "fractional_factorial",
]

# Factor letters of the usual factorial notation; "I" is skipped because it denotes the identity
# column of the defining relation.
FACTOR_LETTERS = "ABCDEFGHJKLMNOPQRSTUVWXYZ"


def _rng(random_state) -> np.random.Generator:
    return np.random.default_rng(random_state)


def latin_hypercube(
    n_runs: int, dim: int, *, random_state=None, optimization: str | None = "random-cd"
) -> np.ndarray:
    """A Latin hypercube sample in unit coordinates, shape (n_runs, dim).

    Uses :class:`scipy.stats.qmc.LatinHypercube`; ``optimization="random-cd"`` permutes
    coordinates to lower the centred discrepancy (better space filling, still a Latin hypercube).
    """
    from scipy.stats import qmc

    if n_runs < 1 or dim < 1:
        raise ValueError(f"a Latin hypercube needs n_runs >= 1 and dim >= 1, got {n_runs}, {dim}")
    sampler = qmc.LatinHypercube(d=dim, optimization=optimization, rng=_rng(random_state))
    return sampler.random(n_runs)


def extend_latin_hypercube(
    existing: np.ndarray,
    n_new: int,
    *,
    random_state=None,
    n_candidates: int = 16,
    optimization: str | None = "random-cd",
) -> np.ndarray:
    """Add ``n_new`` space-filling runs to an existing design, shape (n_new, dim).

    Each candidate batch is itself a Latin hypercube of ``n_new`` runs; the batch whose union
    with ``existing`` has the lowest centred L2 discrepancy is returned. The union is not a Latin
    hypercube any more (the strata of the two parts differ) but it stays space filling, and the
    runs already simulated are kept, which is the point of extending rather than redrawing.
    """
    from scipy.stats import qmc

    existing = np.atleast_2d(np.asarray(existing, dtype=float))
    if n_new < 1:
        raise ValueError(f"n_new must be >= 1, got {n_new}")
    dim = existing.shape[1]
    rng = _rng(random_state)
    best, best_disc = None, np.inf
    for _ in range(max(1, n_candidates)):
        cand = latin_hypercube(n_new, dim, random_state=rng, optimization=optimization)
        disc = qmc.discrepancy(np.clip(np.vstack([existing, cand]), 0.0, 1.0), method="CD")
        if disc < best_disc:
            best, best_disc = cand, disc
    return best


def full_factorial(n_factors: int) -> np.ndarray:
    """The two-level full factorial in coded units, shape (2**n_factors, n_factors).

    Standard (Yates) order: the first factor alternates fastest.
    """
    if not 1 <= n_factors <= 16:
        raise ValueError(f"a full factorial needs 1 <= n_factors <= 16, got {n_factors}")
    levels = itertools.product((-1.0, 1.0), repeat=n_factors)
    # itertools varies the last factor fastest; reverse columns for Yates order.
    return np.array(list(levels))[:, ::-1].copy()


_GENERATOR = re.compile(r"^\s*([A-Z])\s*=\s*([+-]?)\s*([A-Z]+)\s*$")


def fractional_factorial(n_factors: int, generators: Sequence[str]) -> np.ndarray:
    """A two-level fractional factorial ``2**(k-p)`` in coded units, shape (2**(k-p), k).

    ``generators`` define the ``p`` added factors as products of basic ones, in the usual letter
    notation (letters :data:`FACTOR_LETTERS`, the first ``k-p`` being the basic factors of a full
    factorial), e.g. ``["E = ABC", "F = -BCD"]`` for a 2^(6-2) design. Effects aliased by the
    defining relation cannot be separated; :class:`~flexparcel.calibration.screening.AnovaScreening`
    reports them as aliased.
    """
    p = len(generators)
    n_basic = n_factors - p
    if n_basic < 1:
        raise ValueError(f"{p} generators leave no basic factors for {n_factors} factors")
    letters = FACTOR_LETTERS[:n_factors]
    base = full_factorial(n_basic)
    columns = {letters[j]: base[:, j] for j in range(n_basic)}
    for gen in generators:
        m = _GENERATOR.match(gen.upper())
        if m is None:
            raise ValueError(f"generator {gen!r}: expected the form 'E = ABC' or 'E = -ABC'")
        new, sign, word = m.groups()
        expected = letters[len(columns)]
        if new != expected:
            raise ValueError(
                f"generator {gen!r}: generators must define the added factors in order, "
                f"expected {expected!r} next"
            )
        unknown = [c for c in word if c not in letters[:n_basic]]
        if unknown or len(set(word)) != len(word) or len(word) < 2:
            raise ValueError(
                f"generator {gen!r}: the word must be a product of two or more distinct basic "
                f"factors {letters[:n_basic]}"
            )
        col = np.prod([columns[c] for c in word], axis=0)
        columns[new] = -col if sign == "-" else col
    return np.column_stack([columns[c] for c in letters])
