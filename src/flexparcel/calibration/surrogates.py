"""Gaussian-process surrogates of simulator responses (paper section 4.2).

One :class:`GPRSurrogate` models one response as a function of the active parameters. Inputs are
scaled to the unit cube by the parameter space (log parameters in log scale), so length scales
are comparable across parameters. The kernel is chosen among explicit candidates,

* ``"matern12"``, ``"matern32"``, ``"matern52"``: ``C * Matern(l, nu) + White``, nu = 0.5/1.5/2.5,
* ``"rbf"``: ``C * RBF(l) + White``,

each with one length scale per input dimension (automatic relevance determination) and a white
noise term that absorbs the simulator's numerical jitter. The choice follows the paper: the runs
are split once into 90 % for model selection and 10 % that stay untouched; the kernel with the
lowest mean RMSE over a 5-fold cross-validation on the 90 % wins (scikit-learn's
``cross_val_predict`` over fixed ``KFold`` splits, the RMSE of each fold from its out-of-fold
predictions); its RMSE on the untouched 10 % (trained on the 90 %) is the reported accuracy. The
final model is then refitted on all runs, as the paper's contour plots are ("generated with the
whole dataset").

A response may be modelled through a log transform (``transform="log"``: the GP models
``log(y + offset)``), for responses that span decades or approach zero (a rebound near 0, a second
swing from 1 to 100 mm), where a GP in the response itself smears the small values. Everything
visible stays in the response's own units: the CV and hold-out RMSEs are computed from
back-transformed predictions, :meth:`GPRSurrogate.predict` returns ``exp(mu) - offset`` (the
median of the log-normal predictive distribution) and a standard deviation by the delta method,
``exp(mu) * sigma``.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np

from flexparcel.calibration.parameters import ParameterSpace

__all__ = ["KERNELS", "TRANSFORMS", "make_kernel", "GPRSurrogate", "ResponseTransform"]

#: Candidate kernels: name -> Matern smoothness ``nu`` (``None`` for the RBF kernel).
KERNELS: dict[str, float | None] = {
    "matern12": 0.5,
    "matern32": 1.5,
    "matern52": 2.5,
    "rbf": None,
}


def make_kernel(name: str, dim: int):
    """An unfitted scikit-learn kernel ``C * k(l) + White`` for ``dim`` unit-cube inputs.

    Bounds: length scales 0.01 ... 100 (in unit-cube units; a length scale far above 1 means the
    response hardly depends on that input), signal variance 1e-3 ... 1e3 and noise variance
    1e-10 ... 0.1 (both relative to the normalised response, whose variance is 1).
    """
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, Matern, WhiteKernel

    if name not in KERNELS:
        raise ValueError(f"unknown kernel {name!r}; choose from {', '.join(KERNELS)}")
    nu = KERNELS[name]
    ls = np.full(dim, 0.3)
    if nu is None:
        base = RBF(length_scale=ls, length_scale_bounds=(1e-2, 1e2))
    else:
        base = Matern(length_scale=ls, length_scale_bounds=(1e-2, 1e2), nu=nu)
    return ConstantKernel(1.0, (1e-3, 1e3)) * base + WhiteKernel(1e-4, (1e-10, 1e-1))


#: Response transforms a surrogate may model through.
TRANSFORMS = ("none", "log")


class ResponseTransform:
    """``z = log(y + offset)`` (``kind="log"``) or ``z = y`` (``"none"``) and back.

    Module-level and picklable, so that scikit-learn can clone estimators that carry it.
    """

    def __init__(self, kind: str = "none", offset: float = 0.0):
        if kind not in TRANSFORMS:
            raise ValueError(f"transform must be one of {TRANSFORMS}, got {kind!r}")
        if not np.isfinite(offset) or offset < 0:
            raise ValueError(f"the log offset must be a finite number >= 0, got {offset!r}")
        self.kind, self.offset = kind, float(offset)

    def check(self, y) -> None:
        """Raise if ``y`` cannot be transformed (log of a value <= -offset)."""
        if self.kind == "log":
            y = np.asarray(y, dtype=float)
            if np.any(y + self.offset <= 0):
                bad = float(np.min(y))
                raise ValueError(
                    f"a log transform needs y + offset > 0, but the response reaches {bad:g} "
                    f"(offset {self.offset:g}); give a log offset (e.g. the response's resolution)"
                    " or no transform"
                )

    def forward(self, y):
        y = np.asarray(y, dtype=float)
        return np.log(y + self.offset) if self.kind == "log" else y

    def inverse(self, z):
        z = np.asarray(z, dtype=float)
        return np.exp(z) - self.offset if self.kind == "log" else z

    def inverse_std(self, z, sd):
        """Predictive standard deviation in response units (delta method for ``log``)."""
        return np.exp(np.asarray(z)) * np.asarray(sd) if self.kind == "log" else np.asarray(sd)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "offset": self.offset}


def _rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


class GPRSurrogate:
    """A Gaussian-process surrogate of one response with the kernel chosen by cross-validation.

    Parameters
    ----------
    space:
        Parameter space of the inputs (the active parameters); inputs of :meth:`fit` and
        :meth:`predict` are physical values in its column order and are mapped to unit
        coordinates by it.
    kernels:
        Candidate kernel names from :data:`KERNELS`.
    cv_folds:
        Folds of the cross-validation used to choose the kernel (paper: 5).
    holdout_fraction:
        Fraction of runs kept out of model selection and used for the reported RMSE (paper: 0.1).
    n_restarts_optimizer:
        Extra random starts of the marginal-likelihood optimiser per GP fit.
    refit_all:
        Refit the chosen kernel on all runs (hold-out included) after evaluating it.
    random_state:
        Seed of the hold-out split, the CV folds and the optimiser restarts.
    transform, log_offset:
        ``"log"``: model ``log(y + log_offset)`` (see the module text); ``"none"``: ``y``.
    name:
        The response's name, for error messages.

    Attributes
    ----------
    kernel_name_ : str
        The chosen kernel.
    cv_rmse_ : dict
        ``{kernel: mean RMSE over the CV folds}`` [response unit].
    cv_rmse_folds_ : dict
        ``{kernel: [RMSE of each fold]}``.
    holdout_index_, train_index_ : ndarray of int
        Row indices of the untouched hold-out runs and of the model-selection runs.
    holdout_rmse_ : float
        RMSE of the chosen kernel on the hold-out runs, trained on the other runs [response unit].
    holdout_pred_, holdout_std_, holdout_true_ : ndarray
        Its predictions, predictive standard deviations and the simulated values there.
    cv_pred_, cv_true_ : ndarray
        Out-of-fold predictions of the chosen kernel for the model-selection runs, and the
        simulated values there.
    gpr_ : sklearn.gaussian_process.GaussianProcessRegressor
        The final model (inputs in unit coordinates).
    theta_ : list of float
        Log-transformed hyper-parameters of ``gpr_.kernel_``: enough, with the training data, to
        rebuild the model without pickling (:meth:`from_dict`).
    length_scales_ : ndarray
        Fitted length scales per input [unit-cube units].
    y_range_ : float
        ``max(y) - min(y)`` over the training data [response unit].

    The CV, hold-out and predicted values are all in the response's own units, whatever the
    transform.
    """

    def __init__(
        self,
        space: ParameterSpace,
        *,
        kernels: Sequence[str] = ("matern12", "matern32", "matern52", "rbf"),
        cv_folds: int = 5,
        holdout_fraction: float = 0.1,
        n_restarts_optimizer: int = 5,
        refit_all: bool = True,
        random_state=None,
        transform: str = "none",
        log_offset: float = 0.0,
        name: str = "",
    ):
        self.space = space
        self.kernels = kernels
        self.cv_folds = cv_folds
        self.holdout_fraction = holdout_fraction
        self.n_restarts_optimizer = n_restarts_optimizer
        self.refit_all = refit_all
        self.random_state = random_state
        self.transform = transform
        self.log_offset = log_offset
        self.name = name

    def _gpr(self, kernel, seed, optimizer="fmin_l_bfgs_b"):
        from sklearn.gaussian_process import GaussianProcessRegressor

        return GaussianProcessRegressor(
            kernel=kernel,
            normalize_y=True,
            n_restarts_optimizer=self.n_restarts_optimizer if optimizer else 0,
            optimizer=optimizer,
            random_state=seed,
        )

    def _fit_one(self, name: str, U, y, seed):
        from sklearn.exceptions import ConvergenceWarning

        gpr = self._gpr(make_kernel(name, U.shape[1]), seed)
        with warnings.catch_warnings():
            # Hyper-parameters at their bounds are expected (an inert input's length scale
            # runs to the upper bound); the fit is still valid.
            warnings.simplefilter("ignore", ConvergenceWarning)
            gpr.fit(U, self._tf.forward(y))
        return gpr

    def fit(self, X, y) -> GPRSurrogate:
        """Choose the kernel and fit; ``X`` physical, shape (n, d); ``y`` shape (n,)."""
        from sklearn.compose import TransformedTargetRegressor
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.model_selection import KFold, cross_val_predict

        for k in self.kernels:
            if k not in KERNELS:
                raise ValueError(f"unknown kernel {k!r}; choose from {', '.join(KERNELS)}")
        if not self.kernels:
            raise ValueError("at least one candidate kernel is needed")
        self._tf = ResponseTransform(self.transform, self.log_offset)
        U = self.space.to_unit(X)
        y = np.asarray(y, dtype=float).ravel()
        n = len(y)
        what = f"response '{self.name}'" if self.name else "the response"
        if U.shape[0] != n:
            raise ValueError(f"X has {U.shape[0]} runs but y has {n} values")
        if not np.all(np.isfinite(y)):
            raise ValueError(f"{what} contains non-finite values")
        if n and np.ptp(y) == 0.0:
            raise ValueError(
                f"{what} is constant over the design (all {n} runs give {y[0]:g}): a surrogate "
                "of it is a constant and its default weight 1/range is undefined; widen the "
                "parameter bounds, check the simulator's output, or drop it from the targets"
            )
        try:
            self._tf.check(y)
        except ValueError as exc:
            raise ValueError(f"{what}: {exc}") from None
        n_hold = int(round(self.holdout_fraction * n))
        if self.holdout_fraction > 0:
            n_hold = max(n_hold, 1)
        n_sel = n - n_hold
        if n_sel < 2 * self.cv_folds:
            raise ValueError(
                f"{n} runs are too few for a {self.holdout_fraction:.0%} hold-out and "
                f"{self.cv_folds}-fold cross-validation (need at least "
                f"{2 * self.cv_folds} runs for model selection)"
            )
        rng = np.random.default_rng(self.random_state)
        perm = rng.permutation(n)
        self.holdout_index_ = np.sort(perm[:n_hold])
        self.train_index_ = np.sort(perm[n_hold:])
        U_sel, y_sel = U[self.train_index_], y[self.train_index_]
        seed = int(rng.integers(2**31 - 1))

        folds = list(KFold(self.cv_folds, shuffle=True, random_state=seed).split(U_sel))
        self.cv_rmse_folds_, self.cv_rmse_ = {}, {}
        cv_pred = {}
        for name in self.kernels:
            # The GP models the transformed response; the wrapper returns its predictions in
            # the response's own units, so the CV criterion is an RMSE in those units.
            est = TransformedTargetRegressor(
                regressor=self._gpr(make_kernel(name, U.shape[1]), seed),
                func=self._tf.forward,
                inverse_func=self._tf.inverse,
                check_inverse=False,
            )
            with warnings.catch_warnings():
                # Hyper-parameters at their bounds are expected (an inert input's length
                # scale runs to the upper bound); the fit is still valid.
                warnings.simplefilter("ignore", ConvergenceWarning)
                pred = cross_val_predict(est, U_sel, y_sel, cv=folds)
            fold_rmse = [_rmse(pred[te], y_sel[te]) for _, te in folds]
            cv_pred[name] = pred
            self.cv_rmse_folds_[name] = fold_rmse
            # The paper's criterion: the average of the per-fold RMSEs.
            self.cv_rmse_[name] = float(np.mean(fold_rmse))
        self.kernel_name_ = min(self.cv_rmse_, key=self.cv_rmse_.get)
        self.cv_pred_ = cv_pred[self.kernel_name_]
        self.cv_true_ = y_sel

        gpr = self._fit_one(self.kernel_name_, U_sel, y_sel, seed)
        if n_hold:
            mu, sd = self._predict_gpr(gpr, U[self.holdout_index_], True)
            self.holdout_pred_, self.holdout_std_ = mu, sd
            self.holdout_true_ = y[self.holdout_index_]
            self.holdout_rmse_ = _rmse(mu, self.holdout_true_)
        else:
            self.holdout_pred_ = self.holdout_std_ = self.holdout_true_ = np.empty(0)
            self.holdout_rmse_ = float("nan")
        if self.refit_all:
            gpr = self._fit_one(self.kernel_name_, U, y, seed)
        self._set_model(gpr, U if self.refit_all else U_sel, y if self.refit_all else y_sel)
        return self

    def _predict_gpr(self, gpr, U, return_std: bool):
        if not return_std:
            return self._tf.inverse(gpr.predict(U))
        z, sd = gpr.predict(U, return_std=True)
        return self._tf.inverse(z), self._tf.inverse_std(z, sd)

    def _set_model(self, gpr, U, y) -> None:
        self.gpr_ = gpr
        self.theta_ = [float(t) for t in gpr.kernel_.theta]
        self.length_scales_ = np.atleast_1d(
            np.asarray(gpr.kernel_.k1.k2.length_scale, dtype=float)
        ) * np.ones(U.shape[1])
        self.y_range_ = float(np.ptp(y))
        self.n_train_ = int(len(y))

    def predict(self, X, return_std: bool = False):
        """Predicted response at physical points ``X``, shape (n, d) -> (n,) [response unit].

        With ``return_std`` also the predictive standard deviation (GP posterior, white noise
        included) [response unit].
        """
        return self._predict_gpr(self.gpr_, self.space.to_unit(X), return_std)

    def predict_unit(self, U, return_std: bool = False):
        """As :meth:`predict` with inputs in unit coordinates, shape (n, d)."""
        return self._predict_gpr(self.gpr_, np.atleast_2d(U), return_std)

    def to_dict(self) -> dict:
        """Learned state as JSON-serialisable data (training data excluded)."""
        out = {
            "kernel": self.kernel_name_,
            "theta": list(self.theta_),
            "kernel_repr": str(self.gpr_.kernel_),
            "cv_rmse": dict(self.cv_rmse_),
            "cv_rmse_folds": {k: list(v) for k, v in self.cv_rmse_folds_.items()},
            "holdout_index": [int(i) for i in self.holdout_index_],
            "train_index": [int(i) for i in self.train_index_],
            "holdout_rmse": self.holdout_rmse_,
            "holdout_pred": [float(v) for v in self.holdout_pred_],
            "holdout_std": [float(v) for v in self.holdout_std_],
            "holdout_true": [float(v) for v in self.holdout_true_],
            "cv_pred": [float(v) for v in self.cv_pred_],
            "cv_true": [float(v) for v in self.cv_true_],
            "length_scales": [float(v) for v in self.length_scales_],
            "refit_all": self.refit_all,
            "transform": self._tf.to_dict(),
        }
        return out

    @classmethod
    def from_dict(cls, data: dict, space: ParameterSpace, X, y) -> GPRSurrogate:
        """Rebuild a fitted surrogate from :meth:`to_dict` output and its training data.

        ``X`` (physical, shape (n, d)) and ``y`` (shape (n,)) must be the runs it was fitted on,
        in the same order. The hyper-parameters are taken as stored (no optimisation), so the
        rebuilt model predicts exactly as the original one.
        """
        tf = data.get("transform", {"kind": "none", "offset": 0.0})
        self = cls(
            space,
            kernels=(data["kernel"],),
            refit_all=data.get("refit_all", True),
            transform=tf["kind"],
            log_offset=tf["offset"],
        )
        self._tf = ResponseTransform(tf["kind"], tf["offset"])
        U = space.to_unit(X)
        y = np.asarray(y, dtype=float).ravel()
        if not data.get("refit_all", True):
            idx = np.asarray(data["train_index"], dtype=int)
            U, y = U[idx], y[idx]
        kernel = make_kernel(data["kernel"], U.shape[1]).clone_with_theta(
            np.asarray(data["theta"], dtype=float)
        )
        gpr = self._gpr(kernel, None, optimizer=None)
        gpr.fit(U, self._tf.forward(y))
        self.kernel_name_ = data["kernel"]
        self.cv_rmse_ = dict(data["cv_rmse"])
        self.cv_rmse_folds_ = {k: list(v) for k, v in data["cv_rmse_folds"].items()}
        self.holdout_index_ = np.asarray(data["holdout_index"], dtype=int)
        self.train_index_ = np.asarray(data["train_index"], dtype=int)
        self.holdout_rmse_ = float(data["holdout_rmse"])
        self.holdout_pred_ = np.asarray(data["holdout_pred"], dtype=float)
        self.holdout_std_ = np.asarray(data["holdout_std"], dtype=float)
        self.holdout_true_ = np.asarray(data["holdout_true"], dtype=float)
        self.cv_pred_ = np.asarray(data["cv_pred"], dtype=float)
        self.cv_true_ = np.asarray(data.get("cv_true", []), dtype=float)
        self._set_model(gpr, U, y)
        return self
