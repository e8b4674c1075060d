"""The calibration example script runs as a test and recovers the known truth."""

from __future__ import annotations

import runpy
from pathlib import Path

from threadpoolctl import threadpool_limits

from flexparcel.calibration import Parameter, ParameterSpace
from flexparcel.calibration.simulators import ANALYTIC_PARAMETERS

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "calibration_analytic.py"


def test_calibration_analytic_example():
    module = runpy.run_path(str(EXAMPLE))
    with threadpool_limits(1):  # small GP matrices: BLAS threads only cost time here
        result = module["main"](verbose=False)
    assert result["significant"] == ["youngs_modulus", "contact_stiffness", "contact_damping"]
    space = ParameterSpace(
        Parameter(n, lo, hi, scale=s) for n, (lo, hi, _, s) in ANALYTIC_PARAMETERS.items()
    )
    # Same tolerance and argument as the study test: 2 % of the range in unit coordinates.
    for name, truth in module["TRUTH"].items():
        p = space[name]
        err = abs(float(p.to_unit(result["optimum"][name])) - float(p.to_unit(truth)))
        assert err < 0.02, (name, result["optimum"][name], truth)
    for (exp, r), (_, rmse) in result["holdout"].items():
        target = result["targets"][exp][r]
        assert abs(result["validation"][exp][r] - target) < 0.01 * abs(target) + 5 * rmse
