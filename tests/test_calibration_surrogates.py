"""GPR surrogates: kernel choice by CV, hold-out accuracy, rebuild without pickling."""

from __future__ import annotations

import numpy as np
import pytest

from flexparcel.calibration import KERNELS, GPRSurrogate, Parameter, ParameterSpace
from flexparcel.calibration.designs import latin_hypercube
from flexparcel.calibration.simulators import analytic

SPACE = ParameterSpace(
    [
        Parameter("youngs_modulus", 200.0, 2000.0, unit="MPa", scale="log"),
        Parameter("damping_ratio", 1e-4, 5e-3, unit="s"),
    ]
)


@pytest.fixture(scope="module")
def swing_data():
    X = SPACE.from_unit(latin_hypercube(40, 2, random_state=11))
    rows = [analytic(p, mode="swing") for p in SPACE.as_dicts(X)]
    Y = {r: np.array([row[r] for row in rows]) for r in rows[0]}
    return X, Y


@pytest.fixture(scope="module")
def fitted(swing_data):
    X, Y = swing_data
    return {
        r: GPRSurrogate(SPACE, n_restarts_optimizer=1, random_state=5).fit(X, y)
        for r, y in Y.items()
    }


def test_holdout_rmse_is_below_two_percent_of_the_response_range(fitted, swing_data):
    """Bound: 2 % of the response range over the design.

    The analytic swing responses are smooth (exponentials of the unit coordinates) with +-0.3 %
    deterministic jitter; 36 runs in 2-D resolve them to about 0.3-0.4 % of the range. 2 % leaves
    a factor of five for the sampling error of a 4-run hold-out, yet it is below what the rough
    Matern-1/2 kernel achieves here (1.7-2.9 % in CV), so a broken kernel choice would fail it.
    """
    _, Y = swing_data
    for r, gp in fitted.items():
        span = np.ptp(Y[r])
        assert gp.holdout_rmse_ < 0.02 * span, (r, gp.holdout_rmse_, span)
        assert len(gp.holdout_index_) == 4  # 10 % of 40 runs, untouched by model selection
        assert set(gp.holdout_index_).isdisjoint(gp.train_index_)
        assert set(gp.cv_rmse_) == set(KERNELS)
        assert gp.kernel_name_ == min(gp.cv_rmse_, key=gp.cv_rmse_.get)
        # The rough Matern 1/2 kernel is the worst model of a smooth function.
        assert gp.cv_rmse_["matern12"] > gp.cv_rmse_[gp.kernel_name_]


def test_predictive_std_covers_holdout_errors(fitted):
    for gp in fitted.values():
        z = np.abs(gp.holdout_pred_ - gp.holdout_true_) / gp.holdout_std_
        assert np.all(z < 4.0), z


def test_rebuild_from_dict_predicts_identically(fitted, swing_data):
    import json

    X, Y = swing_data
    probe = SPACE.from_unit(latin_hypercube(7, 2, random_state=99))
    for r, gp in fitted.items():
        data = json.loads(json.dumps(gp.to_dict()))  # through JSON, as in the study store
        again = GPRSurrogate.from_dict(data, SPACE, X, Y[r])
        m0, s0 = gp.predict(probe, return_std=True)
        m1, s1 = again.predict(probe, return_std=True)
        np.testing.assert_allclose(m1, m0, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(s1, s0, rtol=1e-7, atol=1e-9)
        assert again.kernel_name_ == gp.kernel_name_


def test_too_few_runs_and_bad_kernels_raise():
    X = SPACE.from_unit(latin_hypercube(8, 2, random_state=0))
    y = np.arange(8.0)
    with pytest.raises(ValueError, match="too few"):
        GPRSurrogate(SPACE).fit(X, y)
    X = SPACE.from_unit(latin_hypercube(20, 2, random_state=0))
    with pytest.raises(ValueError, match="unknown kernel"):
        GPRSurrogate(SPACE, kernels=("cubic",)).fit(X, np.arange(20.0))
