"""Calibrating the analytic stand-in with the toolkit's building blocks (no study file).

The paper's section 4 in a few lines, on the closed-form `analytic` simulator whose truth is the
paper's Table 6 (E = 926 MPa, beta = 1.71e-3 s, c = 649 N/mm, d = 0.579 Ns/mm):

1. screen the drop test's six parameters with a 2^6 factorial and a multi-factor ANOVA;
2. Latin hypercubes over the significant parameters (swing: E and beta, as in the paper);
3. one GPR surrogate per response, kernel chosen by 5-fold CV, hold-out RMSE reported;
4. minimise eq. (11) with multi-start bounded Nelder-Mead;
5. validate: run the simulator at the optimum.

Run:  python examples/calibration_analytic.py      (a few seconds; prints a summary)

`flexparcel calibrate examples/calibration_study.toml` does the same with a resumable study
store, parallel runs and an HTML report.
"""

from __future__ import annotations

import numpy as np

from flexparcel.calibration import (
    GPRSurrogate,
    NelderMeadCalibrator,
    Parameter,
    ParameterSpace,
    full_factorial,
    latin_hypercube,
    range_weights,
    screen_responses,
)
from flexparcel.calibration.simulators import ANALYTIC_PARAMETERS, analytic

TRUTH = {
    "youngs_modulus": 926.0,  # MPa
    "damping_ratio": 1.71e-3,  # s
    "contact_stiffness": 649.0,  # N/mm
    "contact_damping": 0.579,  # Ns/mm
}
# Parameters each experiment's simulator takes (as in the paper: the swing test sees only the
# packaging's E and beta, the drop test all six).
TAKES = {
    "swing": ["youngs_modulus", "damping_ratio"],
    "drop": list(ANALYTIC_PARAMETERS),
}


def main(verbose: bool = True) -> dict:
    space = ParameterSpace(
        Parameter(name, lo, hi, unit=unit, scale=scale)
        for name, (lo, hi, unit, scale) in ANALYTIC_PARAMETERS.items()
    )
    nominal = {p.name: p.nominal_value for p in space.parameters}

    def at(exp: str, values: dict) -> dict:
        """The experiment's simulator parameters: ``values`` where given, else nominal."""
        return {n: values.get(n, nominal[n]) for n in TAKES[exp]}

    # "Measurements": the model at the truth, without its numerical jitter.
    targets = {exp: analytic(at(exp, TRUTH), mode=exp, noise=0.0) for exp in TAKES}

    # 1. Screening of the drop test: 64 runs, ANOVA with main effects and 2FIs, alpha = 0.05.
    C = full_factorial(space.dim)
    runs = [analytic(p, mode="drop") for p in space.as_dicts(space.from_coded(C))]
    responses = {r: np.array([run[r] for run in runs]) for r in runs[0]}
    significant, _ = screen_responses(C, responses, space.names, alpha=0.05)

    # 2.-3. Designs over the active parameters, surrogates per response.
    active = {"swing": TAKES["swing"], "drop": significant}
    n_runs = {"swing": 30, "drop": 40}
    surrogates, ranges, holdout = {}, {}, {}
    for seed, (exp, names) in enumerate(active.items()):
        sub = space.subspace(names)
        X = sub.from_unit(latin_hypercube(n_runs[exp], sub.dim, random_state=seed))
        # Parameters not significant are frozen at their nominal values.
        Y = [analytic(at(exp, p), mode=exp) for p in sub.as_dicts(X)]
        for r in targets[exp]:
            y = np.array([row[r] for row in Y])
            gp = GPRSurrogate(sub, n_restarts_optimizer=0, random_state=seed).fit(X, y)
            surrogates[(exp, r)] = (gp, names)
            ranges[(exp, r)] = y
            holdout[(exp, r)] = (gp.kernel_name_, gp.holdout_rmse_)

    # 4. Weighted least squares on the surrogates, w_i = 1 / range over the design.
    keys = list(surrogates)
    calibrated = [n for n in space.names if any(n in names for _, names in surrogates.values())]
    cspace = space.subspace(calibrated)
    z_target = np.array([targets[e][r] for e, r in keys])
    weights = np.array([range_weights(ranges[k][:, None])[0] for k in keys])

    def predict(x):
        values = dict(zip(calibrated, x, strict=True))
        out = []
        for key in keys:
            gp, names = surrogates[key]
            out.append(gp.predict(np.array([[values[n] for n in names]]))[0])
        return np.array(out)

    opt = NelderMeadCalibrator(n_starts=6, random_state=1).fit(predict, cspace, z_target, weights)
    optimum = dict(zip(calibrated, opt.x_, strict=True))

    # 5. Validation: the simulator at the optimum.
    validation = {exp: analytic(at(exp, optimum), mode=exp) for exp in TAKES}
    if verbose:
        print(f"screening (drop): significant {', '.join(significant)}")
        for (e, r), (kernel, rmse) in holdout.items():
            print(f"surrogate {e}.{r}: kernel {kernel}, hold-out RMSE {rmse:.3g}")
        print(f"weighted error at the optimum {opt.error_:.3g}")
        for n in calibrated:
            print(f"{n:>18s}: optimum {optimum[n]:.4g}   truth {TRUTH[n]:.4g}")
        for e, r in keys:
            print(
                f"{e}.{r}: target {targets[e][r]:.4g}, simulated at the optimum "
                f"{validation[e][r]:.4g}"
            )
    return {
        "significant": significant,
        "optimum": optimum,
        "holdout": holdout,
        "targets": targets,
        "validation": validation,
        "error": opt.error_,
    }


if __name__ == "__main__":
    main()
