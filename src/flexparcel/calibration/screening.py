"""Screening: which parameters matter for a response (paper section 4.2, "Drop tests").

:class:`AnovaScreening` fits a linear model with main effects and two-factor interactions to the
runs of a two-level (full or fractional) factorial in coded units and tests every term with a
multi-factor ANOVA at level ``alpha``, computed with statsmodels (``statsmodels.formula.api.ols``
and ``statsmodels.stats.anova.anova_lm``: F and p per term). Three-factor and higher interactions
are not in the model, so their variation is pooled into the error term, the classical approach
for unreplicated factorials (and, for a deterministic simulator, the only source of an error
estimate besides the numerical noise).

Lenth's method is only for saturated designs: when (almost) no error degrees of freedom are
left (fewer than ``min_error_df``) or the residual vanishes (a noise-free simulator whose
response the model reproduces exactly), the F test is undefined or has no power, and Lenth's
method is used instead: every estimable effect is compared with the margin of error
``t(1 - alpha/2, m/3) * PSE``, where the pseudo standard error ``PSE`` is a robust scale of the
(mostly inert) effects (R. V. Lenth, Technometrics 31 (1989) 469-473).

A parameter is *significant* when its main effect or a two-factor interaction containing it is
significant; the others are frozen at their nominal values for the detailed design. In a
fractional factorial a significant term stands for its alias chain, and the factors of every main
effect and two-factor interaction in that chain are kept (a resolution IV design cannot tell
``a:b`` from ``c:d``; keeping a parameter too many is cheaper than dropping an active one).
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["AnovaScreening", "lenth_pse", "screen_responses"]


def lenth_pse(effects) -> float:
    """Lenth's pseudo standard error of a set of effect estimates [response unit].

    ``s0 = 1.5 median|c|``; ``PSE = 1.5 median(|c_j| : |c_j| < 2.5 s0)``.
    """
    c = np.abs(np.asarray(effects, dtype=float))
    if c.size == 0:
        raise ValueError("Lenth's PSE needs at least one effect")
    s0 = 1.5 * np.median(c)
    trimmed = c[c < 2.5 * s0]
    return float(1.5 * np.median(trimmed)) if trimmed.size else 0.0


class AnovaScreening:
    """Multi-factor ANOVA screening of one response over a two-level factorial.

    Parameters
    ----------
    alpha:
        Significance level of the tests (the paper uses 0.05).
    interactions:
        Include two-factor interactions in the ANOVA model (the default, as the issue asks).
    method:
        ``"anova"`` (F tests, needs residual degrees of freedom), ``"lenth"`` (effects against
        Lenth's margin of error on the saturated model), or ``"auto"``: ANOVA when at least
        ``min_error_df`` residual degrees of freedom remain and the residual is not zero,
        Lenth otherwise.
    min_error_df:
        Smallest number of pooled error degrees of freedom for which ``"auto"`` trusts an F test.

    Attributes
    ----------
    method_ : str
        The method actually used, ``"anova"`` or ``"lenth"``.
    method_reason_ : str
        Why that method ran (for the report).
    factor_names_ : list of str
        Names of the design columns.
    terms_ : list of str
        Estimated model terms (``"a"`` for a main effect, ``"a:b"`` for an interaction).
    aliased_ : dict
        Terms left out because they are aliased with an earlier term, ``{term: alias}``.
    table_ : list of dict
        One row per term plus a ``"Residual"`` row (ANOVA) with keys ``term, df, sum_sq,
        mean_sq, F, p, effect, significant``. ``effect`` is the change of the mean response
        from the low (-1) to the high (+1) level [response unit].
    effects_ : dict
        ``{term: effect}``.
    residual_df_, residual_ms_ : float
        Pooled error degrees of freedom and mean square (ANOVA), or 0 and ``nan`` (Lenth).
    pse_, margin_of_error_ : float
        Lenth's pseudo standard error and margin of error (Lenth), ``nan`` for ANOVA.
    main_effect_means_ : dict
        ``{factor: (mean at -1, mean at +1)}`` for response (main-effects) plots.
    significant_terms_ : list of str
    significant_factors_ : list of str
        Significant parameters, in column order.
    """

    def __init__(
        self,
        alpha: float = 0.05,
        *,
        interactions: bool = True,
        method: str = "auto",
        min_error_df: int = 4,
    ):
        self.alpha = alpha
        self.interactions = interactions
        self.method = method
        self.min_error_df = min_error_df

    def fit(self, X, y, names: Sequence[str] | None = None) -> AnovaScreening:
        """Screen the response ``y``, shape (n,), over the coded design ``X``, shape (n, k)."""
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha must lie in (0, 1), got {self.alpha}")
        if self.method not in ("auto", "anova", "lenth"):
            raise ValueError(f"method must be 'auto', 'anova' or 'lenth', got {self.method!r}")
        X = np.atleast_2d(np.asarray(X, dtype=float))
        y = np.asarray(y, dtype=float).ravel()
        n, k = X.shape
        if y.shape[0] != n:
            raise ValueError(f"X has {n} runs but y has {y.shape[0]} values")
        if not np.all(np.isfinite(y)):
            raise ValueError("the response contains non-finite values")
        if not np.allclose(np.abs(X), 1.0):
            raise ValueError("screening needs a two-level design in coded units (-1/+1)")
        names = list(names) if names is not None else [f"x{j}" for j in range(k)]
        if len(names) != k:
            raise ValueError(f"{len(names)} names for {k} design columns")
        self.factor_names_ = names
        self.main_effect_means_ = {
            name: (float(y[X[:, j] < 0].mean()), float(y[X[:, j] > 0].mean()))
            for j, name in enumerate(names)
        }

        if np.ptp(y) == 0.0:
            raise ValueError(
                f"the response is constant over the design (every run gives {y[0]:g}): no "
                "effect can be estimated and an F ratio is 0/0"
            )
        order = 2 if self.interactions else 1
        terms, columns, aliased = self._model_terms(X, names, order)
        n_terms = len(terms)
        residual_df = n - 1 - n_terms
        model = "main effects and two-factor interactions" if self.interactions else "main effects"
        use_anova = self.method == "anova" or (
            self.method == "auto" and residual_df >= self.min_error_df
        )
        if self.method == "anova" and residual_df < 1:
            raise ValueError(
                f"ANOVA needs residual degrees of freedom: {n} runs, {n_terms} terms; "
                "use method='lenth' or a larger design"
            )
        if self.method == "lenth":
            reason = "Lenth's method requested (method = 'lenth')"
        elif not use_anova:
            reason = (
                f"saturated design: {n} runs and {n_terms} terms ({model}) leave {residual_df} "
                f"error degrees of freedom (an F test needs at least {self.min_error_df} here), "
                "so the effects are judged against Lenth's pseudo standard error"
            )
        else:
            reason = (
                f"multi-factor ANOVA (statsmodels ols + anova_lm) of {model}: {n} runs, "
                f"{n_terms} terms, higher-order interactions pooled into {residual_df} error "
                "degrees of freedom"
            )
        if use_anova:
            fitted = self._anova(X, y, terms, columns)
            if fitted is None:  # residual is zero: F undefined
                use_anova = False
                reason = (
                    f"the {model} model reproduces the response exactly (zero residual, F "
                    "undefined), so the effects are judged against Lenth's pseudo standard error"
                )
        self.method_reason_ = reason
        if not use_anova:
            # Lenth works on the saturated model: all estimable effects up to full order, so
            # that the inert higher-order effects provide the scale estimate.
            terms, columns, aliased = self._model_terms(X, names, k)
            self._lenth(y, terms, columns)
        self.aliased_ = aliased

        sig_terms = [row["term"] for row in self.table_ if row.get("significant")]
        self.significant_terms_ = sig_terms
        # In a fractional factorial a significant term stands for its whole alias chain; the
        # factors of every main effect or two-factor interaction in the chain are kept, since
        # the design cannot tell which of them acts (dropping a real factor is the costly error).
        chains: dict[str, list[str]] = {t: [t] for t in sig_terms}
        for term, alias in aliased.items():
            if alias in chains:
                chains[alias].append(term)
        involved = {
            f for t in sig_terms for a in chains[t] if a.count(":") <= 1 for f in a.split(":")
        }
        self.significant_factors_ = [f for f in names if f in involved]
        return self

    # -- model construction ------------------------------------------------------------------

    @staticmethod
    def _model_terms(X: np.ndarray, names: list[str], order: int):
        """Term names and product columns up to ``order``, aliased duplicates removed."""
        n, k = X.shape
        terms: list[str] = []
        cols: list[np.ndarray] = []
        aliased: dict[str, str] = {}
        for r in range(1, order + 1):
            for combo in itertools.combinations(range(k), r):
                col = np.prod(X[:, combo], axis=1)
                term = ":".join(names[j] for j in combo)
                # Two-level product columns are either identical up to sign (aliased) or
                # orthogonal in a regular fraction; the dot product detects both cases.
                hit = next(
                    (t for t, c in zip(terms, cols, strict=True) if abs(abs(c @ col) - n) < 1e-9),
                    None,
                )
                if np.all(col == col[0]):
                    aliased[term] = "intercept"
                elif hit is not None:
                    aliased[term] = hit
                elif len(terms) < n - 1:
                    terms.append(term)
                    cols.append(col)
                else:
                    aliased[term] = "(no degrees of freedom left)"
        return terms, cols, aliased

    def _anova(self, X, y, terms, columns) -> bool | None:
        """The multi-factor ANOVA of the paper (section 4.2) with statsmodels' formula API.

        ``ols("y ~ x0 + x1 + x0:x1 + ...")`` over the estimable terms (aliased ones left out,
        so the model matrix has full rank) and ``anova_lm`` for F and p per term. Factor names
        become ``x0, x1, ...`` in the formula, so any parameter name works. In the orthogonal
        two-level designs used here type I, II and III sums of squares coincide; type II is
        used. Returns None when the residual vanishes (F undefined).
        """
        import pandas as pd
        from statsmodels.formula.api import ols
        from statsmodels.stats.anova import anova_lm

        code = {name: f"x{j}" for j, name in enumerate(self.factor_names_)}
        data = pd.DataFrame({f"x{j}": X[:, j] for j in range(X.shape[1])})
        data["y"] = y
        coded_terms = [":".join(code[f] for f in t.split(":")) for t in terms]
        res = ols("y ~ " + " + ".join(coded_terms), data=data).fit()
        ss_total = float(((y - y.mean()) ** 2).sum())
        if res.ssr <= 1e-24 * max(ss_total, 1e-300) or res.ssr == 0.0:
            return None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            table = anova_lm(res, typ=2)
        rows = []
        for term, ct in zip(terms, coded_terms, strict=True):
            row = table.loc[ct]
            p = float(row["PR(>F)"])
            rows.append(
                {
                    "term": term,
                    "df": int(row["df"]),
                    "sum_sq": float(row["sum_sq"]),
                    "mean_sq": float(row["sum_sq"] / row["df"]),
                    "F": float(row["F"]),
                    "p": p,
                    # effect: low -> high change of the mean = twice the coded coefficient
                    "effect": float(2.0 * res.params[ct]),
                    "significant": bool(p < self.alpha),
                }
            )
        mse = float(res.ssr / res.df_resid)
        rows.append(
            {
                "term": "Residual",
                "df": int(res.df_resid),
                "sum_sq": float(table.loc["Residual", "sum_sq"]),
                "mean_sq": mse,
                "F": float("nan"),
                "p": float("nan"),
                "effect": float("nan"),
                "significant": False,
            }
        )
        self.method_ = "anova"
        self.terms_ = list(terms)
        self.table_ = rows
        self.effects_ = {r["term"]: r["effect"] for r in rows[:-1]}
        self.residual_df_ = float(res.df_resid)
        self.residual_ms_ = mse
        self.pse_ = float("nan")
        self.margin_of_error_ = float("nan")
        return True

    def _lenth(self, y, terms, columns) -> None:
        from scipy import stats

        M = np.column_stack([np.ones(len(y)), *columns])
        coef, *_ = np.linalg.lstsq(M, y, rcond=None)
        effects = 2.0 * coef[1:]
        m = len(effects)
        if m == 0:
            raise ValueError("no estimable effects")
        pse = lenth_pse(effects)
        d = max(m / 3.0, 1.0)
        tq = float(stats.t.ppf(1.0 - self.alpha / 2.0, d))
        me = tq * pse
        rows = []
        for term, e in zip(terms, effects, strict=True):
            ratio = abs(e) / pse if pse > 0 else (np.inf if abs(e) > 0 else 0.0)
            p = float(2.0 * stats.t.sf(ratio, d)) if np.isfinite(ratio) else 0.0
            # With an exactly zero PSE (noise-free data with sparse effects) every non-zero
            # effect is real: significant iff it is not zero to round-off.
            scale = max(np.max(np.abs(effects)), 1e-300)
            sig = abs(e) > me if pse > 1e-12 * scale else abs(e) > 1e-9 * scale
            rows.append(
                {
                    "term": term,
                    "df": 1,
                    "sum_sq": float(len(y) * (e / 2.0) ** 2),
                    "mean_sq": float(len(y) * (e / 2.0) ** 2),
                    "F": float(ratio**2),
                    "p": p,
                    "effect": float(e),
                    "significant": bool(sig),
                }
            )
        self.method_ = "lenth"
        self.terms_ = list(terms)
        self.table_ = rows
        self.effects_ = {r["term"]: r["effect"] for r in rows}
        self.residual_df_ = 0.0
        self.residual_ms_ = float("nan")
        self.pse_ = pse
        self.margin_of_error_ = me

    def to_dict(self) -> dict:
        """The learned state as plain JSON-serialisable data (for the study store and reports)."""
        return {
            "alpha": self.alpha,
            "method": self.method_,
            "method_reason": self.method_reason_,
            "factor_names": list(self.factor_names_),
            "table": [dict(r) for r in self.table_],
            "aliased": dict(self.aliased_),
            "residual_df": self.residual_df_,
            "residual_ms": self.residual_ms_,
            "pse": self.pse_,
            "margin_of_error": self.margin_of_error_,
            "main_effect_means": {k: list(v) for k, v in self.main_effect_means_.items()},
            "significant_terms": list(self.significant_terms_),
            "significant_factors": list(self.significant_factors_),
        }


def screen_responses(
    X, responses: Mapping[str, np.ndarray], names: Sequence[str], **kwargs
) -> tuple[list[str], dict[str, AnovaScreening]]:
    """Screen several responses of one experiment over the same coded design.

    Returns the union of the significant parameters (in column order) and the fitted
    :class:`AnovaScreening` per response. ``kwargs`` go to :class:`AnovaScreening`.
    """
    fitted = {}
    for r, y in responses.items():
        try:
            fitted[r] = AnovaScreening(**kwargs).fit(X, y, names)
        except ValueError as exc:
            raise ValueError(f"response '{r}': {exc}") from exc
    union = {f for s in fitted.values() for f in s.significant_factors_}
    return [f for f in names if f in union], fitted
