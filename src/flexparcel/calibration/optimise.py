"""Weighted least-squares calibration on surrogates (paper eq. 11, section 4.3).

The objective is exactly the paper's

    error(theta) = sum_i ( w_i * (Z_target,i - Z_pred,i(theta)) )**2

over all responses of all experiments, with ``w_i = 1 / (max - min)`` of response ``i`` over its
design runs unless a weight is given. It is minimised by bounded Nelder-Mead
(:func:`scipy.optimize.minimize`) in unit coordinates of the calibrated parameters, from several
starts: the centre of the box plus a seeded Latin hypercube. Nelder-Mead is derivative free and
a single run can stall in a local minimum of a multi-modal surrogate (the paper's vertical drop
has two regions of high rebound), hence the restarts.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from flexparcel.calibration.designs import latin_hypercube
from flexparcel.calibration.parameters import ParameterSpace

__all__ = ["weighted_error", "range_weights", "NelderMeadCalibrator"]


def weighted_error(z_target, z_pred, weights) -> float:
    """``sum_i (w_i (Z_target,i - Z_pred,i))**2`` (dimensionless when ``w_i`` = 1/unit).

    All arguments have shape (n_targets,).
    """
    z_target = np.asarray(z_target, dtype=float)
    z_pred = np.asarray(z_pred, dtype=float)
    w = np.asarray(weights, dtype=float)
    return float(np.sum((w * (z_target - z_pred)) ** 2))


def range_weights(Y) -> np.ndarray:
    """The paper's default weights ``1 / (max - min)`` per column of ``Y``, shape (n_runs, n).

    A response that does not vary over the design cannot be calibrated against; it raises.
    """
    Y = np.atleast_2d(np.asarray(Y, dtype=float))
    span = np.ptp(Y, axis=0)
    if np.any(span <= 0) or not np.all(np.isfinite(span)):
        raise ValueError(
            "a response does not vary over its design; its 1/range weight is undefined"
        )
    return 1.0 / span


class NelderMeadCalibrator:
    """Multi-start bounded Nelder-Mead minimisation of the weighted error.

    Parameters
    ----------
    n_starts:
        Number of starts: the centre of the box and ``n_starts - 1`` Latin-hypercube points.
    maxiter:
        Iteration limit per start (``None``: scipy's default, 200 per parameter).
    xatol, fatol:
        Nelder-Mead convergence tolerances, in unit coordinates and in error units.
    random_state:
        Seed of the start points.

    Attributes
    ----------
    x_ : ndarray, shape (d,)
        Optimum in physical units.
    u_ : ndarray, shape (d,)
        Optimum in unit coordinates.
    error_ : float
        Weighted error at the optimum.
    penalty_ : float
        The penalty at the optimum (0 without one).
    starts_ : list of dict
        Per start: ``u0``, ``u``, ``x``, ``error``, ``nit``, ``nfev``, ``success``, ``message``.
    """

    def __init__(
        self,
        *,
        n_starts: int = 8,
        maxiter: int | None = None,
        xatol: float = 1e-5,
        fatol: float = 1e-12,
        random_state=None,
    ):
        self.n_starts = n_starts
        self.maxiter = maxiter
        self.xatol = xatol
        self.fatol = fatol
        self.random_state = random_state

    def fit(
        self,
        predict: Callable[[np.ndarray], np.ndarray],
        space: ParameterSpace,
        z_target,
        weights,
        penalty: Callable[[np.ndarray], float] | None = None,
    ) -> NelderMeadCalibrator:
        """Minimise ``weighted_error(z_target, predict(x), weights) + penalty(x)`` over
        ``space``.

        ``predict`` maps one physical point, shape (d,), to the predicted responses, shape
        (n_targets,), in the order of ``z_target`` and ``weights``. ``penalty`` (optional,
        >= 0, zero where ``x`` is admissible) keeps the optimum out of a region the surrogates
        cannot see, e.g. where the simulator does not reach its responses; ``error_`` and each
        start's ``error`` are the weighted error alone, ``penalty_`` the penalty at the optimum.
        """
        from scipy.optimize import minimize

        if self.n_starts < 1:
            raise ValueError(f"n_starts must be >= 1, got {self.n_starts}")
        d = space.dim
        z_target = np.asarray(z_target, dtype=float)
        weights = np.asarray(weights, dtype=float)

        def to_x(u: np.ndarray) -> np.ndarray:
            return space.from_unit(np.clip(u, 0.0, 1.0)[None, :])[0]

        def error(u: np.ndarray) -> float:
            return weighted_error(z_target, predict(to_x(u)), weights)

        def objective(u: np.ndarray) -> float:
            return error(u) + (penalty(to_x(u)) if penalty is not None else 0.0)

        starts = [np.full(d, 0.5)]
        if self.n_starts > 1:
            starts += list(latin_hypercube(self.n_starts - 1, d, random_state=self.random_state))
        options = {"xatol": self.xatol, "fatol": self.fatol}
        if self.maxiter is not None:
            options["maxiter"] = self.maxiter
        self.starts_ = []
        for u0 in starts:
            res = minimize(
                objective, u0, method="Nelder-Mead", bounds=[(0.0, 1.0)] * d, options=options
            )
            u = np.clip(res.x, 0.0, 1.0)
            self.starts_.append(
                {
                    "u0": [float(v) for v in u0],
                    "u": [float(v) for v in u],
                    "x": [float(v) for v in to_x(u)],
                    "error": error(u),
                    "penalty": float(penalty(to_x(u))) if penalty is not None else 0.0,
                    "nit": int(res.nit),
                    "nfev": int(res.nfev),
                    "success": bool(res.success),
                    "message": str(res.message),
                }
            )
        best = min(self.starts_, key=lambda s: s["error"] + s["penalty"])
        self.u_ = np.asarray(best["u"])
        self.x_ = np.asarray(best["x"])
        self.error_ = best["error"]
        self.penalty_ = best["penalty"]
        return self
