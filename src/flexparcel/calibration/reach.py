"""Where a simulator reaches its responses: a Gaussian-process classifier over a design.

A physical test does not always produce its response. A swing whose free end never passes the
clamp has no first swing; a drop that ends while the consignment still rises has no rebound.
Such a run is the simulator's outcome (recorded once, not retried, see
:mod:`flexparcel.calibration.execution`), and it carries information the regression surrogates
cannot use: they are fitted to the runs that reached their responses only, so in the region
of the runs that did not they extrapolate, and an optimiser may put the optimum there, where
the validation run then reaches nothing. In the KP/BW campaign's swing design at 25 mm a point
at E = 1805 MPa, beta = 3.6e-3 s did not swing through while E = 2160 MPa, beta = 1.3e-3 s
swung 127 mm, the target: the boundary passes next to the optimum.

:class:`ReachClassifier` models the probability that a run reaches its responses as a
function of the active parameters: scikit-learn's :class:`GaussianProcessClassifier` (binary
Laplace approximation, Rasmussen & Williams, Gaussian Processes for Machine Learning, 2006,
sec. 3.4) with ``C * Matern(l, nu = 1.5)``, one length scale per input, on the unit cube of
the parameter space (log parameters in log scale) as the regression surrogates are. The study's
optimiser keeps the optimum where that probability is at least ``min_reach_probability``
(:meth:`flexparcel.calibration.study.Study.optimise`).
"""

from __future__ import annotations

import warnings

import numpy as np

from flexparcel.calibration.parameters import ParameterSpace

__all__ = ["ReachClassifier"]


def _kernel(dim: int):
    """``C * Matern(l, 1.5)`` with one length scale per unit-cube input. Bounds: length scales
    0.02 ... 100 (far above 1: the outcome hardly depends on that input), signal variance
    1e-2 ... 1e3 (the latent function's scale sets how sharp the boundary is)."""
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern

    return ConstantKernel(1.0, (1e-2, 1e3)) * Matern(
        length_scale=np.full(dim, 0.3), length_scale_bounds=(0.02, 100.0), nu=1.5
    )


class ReachClassifier:
    """Probability that a run of the simulator reaches its responses, over a design.

    Parameters
    ----------
    space:
        The parameter space of the runs' inputs (the experiment's active parameters).
    random_state:
        Seed of the hyper-parameter optimiser's restarts.

    Attributes
    ----------
    theta_ : ndarray
        Fitted log hyper-parameters of the kernel (scikit-learn's ``kernel_.theta``).
    n_reached_, n_not_reached_ : int
        Runs of each outcome it was fitted on.
    """

    def __init__(self, space: ParameterSpace, *, random_state=None):
        self.space = space
        self.random_state = random_state

    def fit(self, X, reached) -> ReachClassifier:
        """Fit on runs ``X`` (physical units, shape (n, d)) and their outcomes ``reached``
        (bool, shape (n,)). Both outcomes must occur, each at least once."""
        reached = np.asarray(reached, dtype=bool).ravel()
        U = self.space.to_unit(np.atleast_2d(np.asarray(X, dtype=float)))
        if len(U) != len(reached):
            raise ValueError(f"{len(U)} runs but {len(reached)} outcomes")
        if reached.all() or not reached.any():
            raise ValueError("both outcomes (reached and not reached) are needed to classify")
        self._fit(U, reached, _kernel(U.shape[1]), optimise=True)
        return self

    def _fit(self, U, reached, kernel, *, optimise: bool) -> None:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.gaussian_process import GaussianProcessClassifier

        gpc = GaussianProcessClassifier(
            kernel,
            optimizer="fmin_l_bfgs_b" if optimise else None,
            n_restarts_optimizer=4 if optimise else 0,
            random_state=self.random_state,
        )
        with warnings.catch_warnings():
            # Hyper-parameters at their bounds are expected: an inert input's length scale runs
            # to the upper one, and outcomes that a line separates drive the signal variance
            # to its upper bound (the sharpest boundary the kernel allows). The fit is valid.
            warnings.simplefilter("ignore", ConvergenceWarning)
            gpc.fit(U, reached.astype(int))
        self.gpc_ = gpc
        self.theta_ = np.asarray(gpc.kernel_.theta)
        self.n_reached_ = int(reached.sum())
        self.n_not_reached_ = int((~reached).sum())

    def probability(self, X) -> np.ndarray:
        """Probability of reaching the responses at points ``X`` (physical, shape (n, d)),
        shape (n,)."""
        U = self.space.to_unit(np.atleast_2d(np.asarray(X, dtype=float)))
        return self.gpc_.predict_proba(U)[:, 1]

    def to_dict(self) -> dict:
        """Learned state as JSON-serialisable data (the runs themselves excluded)."""
        return {
            "theta": [float(v) for v in self.theta_],
            "kernel_repr": str(self.gpc_.kernel_),
            "n_reached": self.n_reached_,
            "n_not_reached": self.n_not_reached_,
        }

    @classmethod
    def from_dict(cls, data: dict, space: ParameterSpace, X, reached) -> ReachClassifier:
        """Rebuild a fitted classifier from :meth:`to_dict` output and the runs it was fitted
        on (same order); the hyper-parameters are taken as stored, so it predicts as the
        original one did."""
        self = cls(space)
        reached = np.asarray(reached, dtype=bool).ravel()
        U = space.to_unit(np.atleast_2d(np.asarray(X, dtype=float)))
        kernel = _kernel(U.shape[1]).clone_with_theta(np.asarray(data["theta"], dtype=float))
        self._fit(U, reached, kernel, optimise=False)
        return self
