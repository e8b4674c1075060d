"""Multi-fidelity surrogates: many cheap low-fidelity runs corrected by a few accurate ones.

A coarse mesh (say 25 mm elements) runs many times faster than the 10 mm mesh the paper uses,
and its responses are biased but strongly correlated with the fine ones. The autoregressive
co-kriging of Kennedy & O'Hagan (2000),

    y_high(x) = rho * y_low(x) + delta(x),

with independent Gaussian processes for ``y_low`` and the discrepancy ``delta``, turns this into
a surrogate of ``y_high`` that needs only a few high-fidelity runs. It is fitted recursively as
proposed by Le Gratiet (2013, "Bayesian analysis of hierarchical multifidelity codes", SIAM/ASA
J. UQ 1, 244-269): first the low-fidelity GP on the low runs alone (the kernel by 5-fold CV as
for :class:`~flexparcel.calibration.surrogates.GPRSurrogate`), then ``rho`` and ``delta`` from the
high runs, with the low GP's posterior mean ``m_low`` standing in for ``y_low`` at the high
points (so the designs need not be nested). ``rho`` maximises the marginal likelihood of the
high runs' discrepancy ``z_high - rho * m_low`` with ``delta``'s kernel (same family as the low
GP's) refitted for each ``rho`` (a profile likelihood; see ``_fit_delta`` for why not least
squares). Prediction:

    mean = rho * m_low(x) + m_delta(x),    variance = rho^2 * s_low(x)^2 + s_delta(x)^2

(Le Gratiet's recursive formula; the estimation uncertainty of ``rho`` is not propagated).

Why not SMT's ``MFK``: it installs here (``smt`` 2.15, a compiled wheel and ten more packages),
but it brings its own kernel family and hyper-parameter optimiser, and a trained model is
restored by pickling or by retraining; this module reuses the scikit-learn kernels chosen by CV
and, like ``GPRSurrogate``, is rebuilt exactly from stored hyper-parameters and the stored runs.

A log transform (``transform="log"``) applies to both levels: the recursion then holds for
``log(y + offset)``, i.e. a multiplicative correction, and all reported numbers are back in the
response's units.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from flexparcel.calibration.parameters import ParameterSpace
from flexparcel.calibration.surrogates import (
    GPRSurrogate,
    ResponseTransform,
    _rmse,
    make_kernel,
)

__all__ = ["CoKrigingSurrogate", "FixedKernelGP"]


def _gpr(kernel, seed, restarts: int, optimizer="fmin_l_bfgs_b"):
    from sklearn.gaussian_process import GaussianProcessRegressor

    return GaussianProcessRegressor(
        kernel=kernel,
        normalize_y=True,
        n_restarts_optimizer=restarts if optimizer else 0,
        optimizer=optimizer,
        random_state=seed,
    )


def _fit(gpr, U, z):
    from sklearn.exceptions import ConvergenceWarning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        gpr.fit(U, z)
    return gpr


class FixedKernelGP:
    """A GP of one kernel family fitted by marginal likelihood alone (no kernel CV).

    What the high runs alone support: a handful of runs is too few for a 5-fold CV, so the
    kernel family is given (in a study: the one the low-fidelity CV chose). Used as the
    high-only reference against which the fused surrogate is judged.
    """

    def __init__(
        self,
        space: ParameterSpace,
        kernel: str,
        *,
        n_restarts_optimizer: int = 5,
        random_state=None,
        transform: str = "none",
        log_offset: float = 0.0,
    ):
        self.space, self.kernel = space, kernel
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state
        self.transform, self.log_offset = transform, log_offset

    def fit(self, X, y) -> FixedKernelGP:
        self._tf = ResponseTransform(self.transform, self.log_offset)
        U = self.space.to_unit(X)
        y = np.asarray(y, dtype=float).ravel()
        self._tf.check(y)
        kernel = make_kernel(self.kernel, U.shape[1])
        self.gpr_ = _fit(
            _gpr(kernel, self.random_state, self.n_restarts_optimizer), U, self._tf.forward(y)
        )
        return self

    def predict(self, X, return_std: bool = False):
        U = self.space.to_unit(X)
        if not return_std:
            return self._tf.inverse(self.gpr_.predict(U))
        z, sd = self.gpr_.predict(U, return_std=True)
        return self._tf.inverse(z), self._tf.inverse_std(z, sd)


class CoKrigingSurrogate:
    """Autoregressive co-kriging of a high-fidelity response (Kennedy & O'Hagan 2000).

    Parameters
    ----------
    space:
        Parameter space of the inputs (physical values in its column order).
    kernels, cv_folds, holdout_fraction, n_restarts_optimizer, random_state, transform,
    log_offset, name:
        As for :class:`~flexparcel.calibration.surrogates.GPRSurrogate`. ``kernels`` and
        ``cv_folds`` choose the low-fidelity kernel; ``holdout_fraction`` is applied to the
        low runs (the low GP's own hold-out) and to the high runs (at least one high run is
        held out while there are four or more).
    rho_grid:
        Points of the grid on which ``rho``'s profile likelihood is searched first.

    Attributes
    ----------
    low_ : GPRSurrogate
        The low-fidelity surrogate (its CV table and hold-out RMSE are the low level's).
    kernel_name_ : str
        Kernel family of the low GP and of ``delta``.
    rho_ : float
        Scale factor between the levels (in the transformed response when a transform is set).
    delta_gpr_ : sklearn.gaussian_process.GaussianProcessRegressor
        The discrepancy GP (inputs in unit coordinates).
    high_holdout_index_, high_train_index_ : ndarray of int
        High runs held out for the comparison, and those used for training.
    holdout_rmse_ : float
        RMSE of the fused surrogate on the held-out high runs, trained on all low runs and the
        other high runs [response unit] (``nan`` without a high hold-out).
    high_only_holdout_rmse_ : float
        RMSE on the same held-out high runs of a :class:`FixedKernelGP` of the same kernel family
        trained on the same high runs only [response unit]: what the high runs alone give.
    holdout_pred_, holdout_std_, holdout_true_ : ndarray
        The fused surrogate's hold-out predictions, standard deviations and simulated values.
    high_only_holdout_pred_ : ndarray
    loo_rmse_, high_only_loo_rmse_ : float
        Leave-one-out RMSE over all high runs [response unit]: each high run predicted by the
        fused surrogate (all low runs, the other high runs) and by the high-only GP (the other
        high runs); ``nan`` with fewer than three high runs.
    loo_pred_, high_only_loo_pred_ : ndarray
        Their predictions, one per high run in the order given to :meth:`fit`.
    """

    def __init__(
        self,
        space: ParameterSpace,
        *,
        kernels: Sequence[str] = ("matern12", "matern32", "matern52", "rbf"),
        cv_folds: int = 5,
        holdout_fraction: float = 0.1,
        n_restarts_optimizer: int = 5,
        random_state=None,
        transform: str = "none",
        log_offset: float = 0.0,
        name: str = "",
        rho_grid: int = 13,
    ):
        self.space = space
        self.kernels = kernels
        self.cv_folds = cv_folds
        self.holdout_fraction = holdout_fraction
        self.n_restarts_optimizer = n_restarts_optimizer
        self.random_state = random_state
        self.transform = transform
        self.log_offset = log_offset
        self.name = name
        self.rho_grid = rho_grid

    # -- fitting -------------------------------------------------------------------------------

    def _seed(self) -> int:
        rng = np.random.default_rng(self.random_state)
        return int(rng.integers(2**31 - 1))

    def _delta_fit(self, U_h, r, seed, restarts: int | None = None):
        """The discrepancy GP fitted to ``r`` and its log marginal likelihood of ``r`` itself
        (sklearn's is that of the normalised ``r``; ``- n log std(r)`` is the Jacobian that
        makes values for different ``rho`` comparable)."""
        kernel = make_kernel(self.kernel_name_, U_h.shape[1])
        n_restarts = self.n_restarts_optimizer if restarts is None else restarts
        gpr = _fit(_gpr(kernel, seed, n_restarts), U_h, r)
        scale = float(np.std(r))
        lml = gpr.log_marginal_likelihood_value_ - len(r) * np.log(scale if scale > 0 else 1.0)
        return gpr, float(lml)

    def _fit_delta(self, U_h, z_h, m_low, seed) -> float:
        """``rho`` by maximum likelihood: the discrepancy GP's marginal likelihood of
        ``z_h - rho * m_low``, its kernel refitted for every ``rho`` (profile likelihood).

        A least-squares ``rho`` is biased whenever the discrepancy has a trend that correlates
        with ``y_low`` over a few high points (the Forrester pair: least squares gives 0.75 for
        a true 2 from 8 points), and a flexible discrepancy GP then absorbs the rest; the joint
        likelihood prefers the ``rho`` that leaves the smoothest discrepancy. Searched on a grid
        over +-3 ``std(z_high) / std(m_low)`` (plus the least-squares value), then refined by
        bounded Brent between the grid neighbours of the best point.
        """
        from scipy.optimize import minimize_scalar

        F = np.column_stack([m_low, np.ones_like(m_low)])
        rho_ls = float(np.linalg.lstsq(F, z_h, rcond=None)[0][0])
        sm = float(np.std(m_low))
        s = float(np.std(z_h)) / sm if sm > 0 else 1.0
        grid = np.unique(np.append(np.linspace(-3.0 * s, 3.0 * s, self.rho_grid), rho_ls))
        cache: dict[float, float] = {}

        def nll(rho: float) -> float:
            if rho not in cache:
                # one optimiser start per point (the restarts go to the final fit only)
                cache[rho] = -self._delta_fit(U_h, z_h - rho * m_low, seed, restarts=0)[1]
            return cache[rho]

        values = [nll(float(r)) for r in grid]
        k = int(np.argmin(values))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        if hi > lo:
            res = minimize_scalar(
                nll, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3 * s}
            )
            best = float(res.x) if res.fun <= values[k] else float(grid[k])
        else:
            best = float(grid[k])
        return best

    def _train(self, U_h, z_h, seed, theta=None, rho=None):
        m_low = self.low_.gpr_.predict(U_h)
        if theta is None:
            rho = self._fit_delta(U_h, z_h, m_low, seed)
            gpr, _ = self._delta_fit(U_h, z_h - rho * m_low, seed)
            return rho, gpr
        kernel = make_kernel(self.kernel_name_, U_h.shape[1]).clone_with_theta(
            np.asarray(theta, dtype=float)
        )
        return rho, _gpr(kernel, None, 0, optimizer=None).fit(U_h, z_h - rho * m_low)

    def fit(self, X_low, y_low, X_high, y_high) -> CoKrigingSurrogate:
        """Fit on low runs ``(X_low, y_low)`` and high runs ``(X_high, y_high)`` (physical
        inputs, shape (n, d); responses, shape (n,))."""
        self._tf = ResponseTransform(self.transform, self.log_offset)
        what = f"response '{self.name}'" if self.name else "the response"
        y_high = np.asarray(y_high, dtype=float).ravel()
        U_h = self.space.to_unit(X_high)
        n_h = len(y_high)
        if U_h.shape[0] != n_h:
            raise ValueError(f"X_high has {U_h.shape[0]} runs but y_high has {n_h} values")
        if n_h < 2:
            raise ValueError(f"{what}: co-kriging needs at least 2 high-fidelity runs, got {n_h}")
        if not np.all(np.isfinite(y_high)):
            raise ValueError(f"{what}: the high-fidelity runs contain non-finite values")
        try:
            self._tf.check(y_high)
        except ValueError as exc:
            raise ValueError(f"{what} (high fidelity): {exc}") from None
        self.low_ = GPRSurrogate(
            self.space,
            kernels=self.kernels,
            cv_folds=self.cv_folds,
            holdout_fraction=self.holdout_fraction,
            n_restarts_optimizer=self.n_restarts_optimizer,
            random_state=self.random_state,
            transform=self.transform,
            log_offset=self.log_offset,
            name=f"{self.name} (low fidelity)" if self.name else "low fidelity",
        ).fit(X_low, y_low)
        self.kernel_name_ = self.low_.kernel_name_
        seed = self._seed()
        z_h = self._tf.forward(y_high)

        # Hold-out of high runs: the fused surrogate and a high-only GP, trained on the same
        # remaining high runs, predict them.
        n_hold = int(round(self.holdout_fraction * n_h)) if self.holdout_fraction > 0 else 0
        if self.holdout_fraction > 0 and n_h >= 4:
            n_hold = max(n_hold, 1)
        n_hold = min(n_hold, n_h - 3) if n_h >= 4 else 0
        perm = np.random.default_rng(seed).permutation(n_h)
        self.high_holdout_index_ = np.sort(perm[:n_hold])
        self.high_train_index_ = np.sort(perm[n_hold:])
        if n_hold:
            te = self.high_holdout_index_
            mu, sd, ref = self._compare(self.high_train_index_, te, U_h, z_h, X_high, y_high, seed)
            self.holdout_pred_, self.holdout_std_ = mu, sd
            self.holdout_true_ = y_high[te]
            self.holdout_rmse_ = _rmse(mu, y_high[te])
            self.high_only_holdout_pred_ = ref
            self.high_only_holdout_rmse_ = _rmse(ref, y_high[te])
        else:
            self.holdout_pred_ = self.holdout_std_ = self.holdout_true_ = np.empty(0)
            self.high_only_holdout_pred_ = np.empty(0)
            self.holdout_rmse_ = self.high_only_holdout_rmse_ = float("nan")
        self._leave_one_out(U_h, z_h, X_high, y_high, seed)
        # The final model on all high runs.
        self.rho_, self.delta_gpr_ = self._train(U_h, z_h, seed)
        self.n_high_ = n_h
        return self

    def _compare(self, tr, te, U_h, z_h, X_high, y_high, seed):
        """The fused surrogate trained on all low runs and the high runs ``tr``, and a
        high-only :class:`FixedKernelGP` trained on the same high runs, at the high runs
        ``te``: fused mean and standard deviation, high-only mean [response unit]."""
        rho, gpr = self._train(U_h[tr], z_h[tr], seed)
        mu, sd = self._predict(U_h[te], rho, gpr)
        ref = FixedKernelGP(
            self.space,
            self.kernel_name_,
            n_restarts_optimizer=self.n_restarts_optimizer,
            random_state=seed,
            transform=self.transform,
            log_offset=self.log_offset,
        ).fit(np.asarray(X_high)[tr], y_high[tr])
        return mu, sd, ref.predict(np.asarray(X_high)[te])

    def _leave_one_out(self, U_h, z_h, X_high, y_high, seed) -> None:
        """Each high run predicted from all low runs and the other high runs, by the fused
        surrogate and by the high-only GP: with the four high runs of a campaign a hold-out
        of 10 % is one run, a figure of one point; leaving each out once compares the two on
        all of them (Hastie, Tibshirani & Friedman, The Elements of Statistical Learning,
        2nd ed., 7.10). Needs three high runs (two to train on); ``nan`` below."""
        n_h = len(y_high)
        self.loo_pred_ = np.full(n_h, np.nan)
        self.high_only_loo_pred_ = np.full(n_h, np.nan)
        self.loo_rmse_ = self.high_only_loo_rmse_ = float("nan")
        if n_h < 3:
            return
        for i in range(n_h):
            tr = np.delete(np.arange(n_h), i)
            mu, _, ref = self._compare(tr, [i], U_h, z_h, X_high, y_high, seed)
            self.loo_pred_[i], self.high_only_loo_pred_[i] = mu[0], ref[0]
        self.loo_rmse_ = _rmse(self.loo_pred_, y_high)
        self.high_only_loo_rmse_ = _rmse(self.high_only_loo_pred_, y_high)

    # -- prediction ----------------------------------------------------------------------------

    def _predict(self, U, rho, gpr, return_std: bool = True):
        U = np.atleast_2d(U)
        if not return_std:
            z = rho * self.low_.gpr_.predict(U) + gpr.predict(U)
            return self._tf.inverse(z)
        ml, sl = self.low_.gpr_.predict(U, return_std=True)
        md, sdd = gpr.predict(U, return_std=True)
        z = rho * ml + md
        sd = np.sqrt((rho * sl) ** 2 + sdd**2)
        return self._tf.inverse(z), self._tf.inverse_std(z, sd)

    def predict(self, X, return_std: bool = False):
        """Predicted high-fidelity response at physical points ``X``, shape (n, d) -> (n,)
        [response unit]; with ``return_std`` also the predictive standard deviation."""
        return self._predict(self.space.to_unit(X), self.rho_, self.delta_gpr_, return_std)

    def predict_unit(self, U, return_std: bool = False):
        """As :meth:`predict` with inputs in unit coordinates."""
        return self._predict(U, self.rho_, self.delta_gpr_, return_std)

    @property
    def length_scales_(self) -> np.ndarray:
        """Length scales of the low GP [unit-cube units] (it carries the response's shape)."""
        return self.low_.length_scales_

    # -- persistence ---------------------------------------------------------------------------

    def to_dict(self) -> dict:
        """Learned state as JSON-serialisable data (training data excluded)."""
        low = self.low_.to_dict()
        return {
            "multifidelity": "co-kriging",
            "kernel": self.kernel_name_,
            "low": low,
            "rho": float(self.rho_),
            "delta_theta": [float(t) for t in self.delta_gpr_.kernel_.theta],
            "delta_kernel_repr": str(self.delta_gpr_.kernel_),
            "n_high": int(self.n_high_),
            "high_holdout_index": [int(i) for i in self.high_holdout_index_],
            "high_train_index": [int(i) for i in self.high_train_index_],
            "holdout_rmse": self.holdout_rmse_,
            "high_only_holdout_rmse": self.high_only_holdout_rmse_,
            "holdout_pred": [float(v) for v in self.holdout_pred_],
            "holdout_std": [float(v) for v in self.holdout_std_],
            "holdout_true": [float(v) for v in self.holdout_true_],
            "high_only_holdout_pred": [float(v) for v in self.high_only_holdout_pred_],
            "loo_rmse": self.loo_rmse_,
            "high_only_loo_rmse": self.high_only_loo_rmse_,
            "loo_pred": [float(v) for v in self.loo_pred_],
            "high_only_loo_pred": [float(v) for v in self.high_only_loo_pred_],
            "transform": self._tf.to_dict(),
            # for the report's CV table and residual plot (the low level's model selection)
            "cv_rmse": low["cv_rmse"],
            "cv_rmse_folds": low["cv_rmse_folds"],
            "cv_pred": low["cv_pred"],
            "cv_true": low["cv_true"],
            "kernel_repr": low["kernel_repr"],
            "holdout_index": low["holdout_index"],
            "length_scales": low["length_scales"],
            "low_holdout_rmse": low["holdout_rmse"],
        }

    @classmethod
    def from_dict(
        cls, data: dict, space: ParameterSpace, X_low, y_low, X_high, y_high
    ) -> CoKrigingSurrogate:
        """Rebuild from :meth:`to_dict` output and the runs it was fitted on (same order);
        no hyper-parameter is re-optimised, so it predicts exactly as the original."""
        tf = data["transform"]
        self = cls(space, kernels=(data["kernel"],), transform=tf["kind"], log_offset=tf["offset"])
        self._tf = ResponseTransform(tf["kind"], tf["offset"])
        self.low_ = GPRSurrogate.from_dict(data["low"], space, X_low, y_low)
        self.kernel_name_ = data["kernel"]
        y_high = np.asarray(y_high, dtype=float).ravel()
        self.rho_, self.delta_gpr_ = self._train(
            space.to_unit(X_high),
            self._tf.forward(y_high),
            None,
            theta=data["delta_theta"],
            rho=data["rho"],
        )
        self.n_high_ = int(data["n_high"])
        self.high_holdout_index_ = np.asarray(data["high_holdout_index"], dtype=int)
        self.high_train_index_ = np.asarray(data["high_train_index"], dtype=int)
        self.holdout_rmse_ = float(data["holdout_rmse"])
        self.high_only_holdout_rmse_ = float(data["high_only_holdout_rmse"])
        for k in ("holdout_pred", "holdout_std", "holdout_true", "high_only_holdout_pred"):
            setattr(self, k + "_", np.asarray(data[k], dtype=float))
        # fits stored before the leave-one-out comparison have none
        self.loo_rmse_ = float(data.get("loo_rmse", float("nan")))
        self.high_only_loo_rmse_ = float(data.get("high_only_loo_rmse", float("nan")))
        for k in ("loo_pred", "high_only_loo_pred"):
            setattr(self, k + "_", np.asarray(data.get(k, [np.nan] * self.n_high_), dtype=float))
        return self
