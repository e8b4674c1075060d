"""Where a simulator reaches its responses: the classifier, and the optimiser kept out of the
region where the runs did not reach them (flexparcel.calibration.reach)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from flexparcel.calibration import Study, load_study
from flexparcel.calibration.parameters import Parameter, ParameterSpace
from flexparcel.calibration.reach import ReachClassifier
from flexparcel.calibration.simulators import analytic, register_simulator

E_LO, E_HI = 200.0, 2000.0
#: The test simulator's swing does not pass the clamp above this unit coordinate of E (log).
U_STIFF = 0.6


class _NotReached(ValueError):
    retryable = False  # as flexparcel.scenarios.simulators.ResponseNotReached


def _unit_e(E: float) -> float:
    return math.log(E / E_LO) / math.log(E_HI / E_LO)


@register_simulator(
    "test-swing-reach",
    replace=True,
    responses=("first_swing_mm", "second_swing_mm"),
    parameters={"youngs_modulus": "MPa", "damping_ratio": "s"},
)
def _swing_reach(params, **setup):
    """The analytic swing, except that a film stiffer than U_STIFF does not swing through."""
    if _unit_e(params["youngs_modulus"]) > U_STIFF:
        raise _NotReached("first_swing_mm not reached: the free end did not pass the clamp")
    return analytic(params, mode="swing", noise=0.0)


def _space() -> ParameterSpace:
    return ParameterSpace(
        [Parameter("a", 0.0, 1.0), Parameter("b", 1.0, 100.0, unit="s", scale="log")]
    )


def test_classifier_separates_the_outcomes_and_rebuilds_exactly():
    space = _space()
    g = np.linspace(0.05, 0.95, 7)
    U = np.array([(a, b) for a in g for b in g])
    reached = U.sum(axis=1) < 1.0  # the boundary: a diagonal of the unit square
    X = space.from_unit(U)
    clf = ReachClassifier(space, random_state=0).fit(X, reached)
    inside, outside = space.from_unit(np.array([[0.15, 0.2]])), space.from_unit([[0.85, 0.8]])
    assert clf.probability(inside)[0] > 0.8
    assert clf.probability(outside)[0] < 0.2
    # on the boundary it cannot tell (symmetric data)
    assert abs(clf.probability(space.from_unit([[0.5, 0.5]]))[0] - 0.5) < 0.1
    data = json.loads(json.dumps(clf.to_dict()))
    again = ReachClassifier.from_dict(data, space, X, reached)
    probe = space.from_unit(np.random.default_rng(1).random((20, 2)))
    np.testing.assert_allclose(again.probability(probe), clf.probability(probe), rtol=1e-12)
    assert (data["n_reached"], data["n_not_reached"]) == (int(reached.sum()), 49 - reached.sum())


def test_classifier_needs_both_outcomes():
    space = _space()
    X = space.from_unit(np.random.default_rng(0).random((5, 2)))
    with pytest.raises(ValueError, match="both outcomes"):
        ReachClassifier(space).fit(X, np.ones(5, bool))


STUDY = """
version = 1
name = "reach"
store = "reach.sqlite"
output = "report"
random_state = 3

[execution]
workers = 0

[surrogate]
kernels = ["matern52"]
restarts = 0

[optimisation]
starts = 6
{extra}

[parameters.youngs_modulus]
bounds = [200, 2000]
unit = "MPa"
scale = "log"

[parameters.damping_ratio]
bounds = [1e-4, 5e-3]
unit = "s"
scale = "log"

[experiments.swing]
simulator = "test-swing-reach"
parameters = ["youngs_modulus", "damping_ratio"]

[experiments.swing.design]
runs = 24

[experiments.swing.targets]
first_swing_mm = {{ value = {first}, unit = "mm" }}
second_swing_mm = {{ value = {second}, unit = "mm" }}
"""


def _study(tmp_path, extra: str = "") -> Study:
    # targets: the analytic swing's responses at a point the test simulator does not reach
    # (E at unit coordinate 0.85), so the surrogates fitted on the runs that reached them
    # extrapolate towards it
    E = E_LO * (E_HI / E_LO) ** 0.85
    truth = analytic({"youngs_modulus": E, "damping_ratio": 1e-3}, mode="swing", noise=0.0)
    text = STUDY.format(extra=extra, first=truth["first_swing_mm"], second=truth["second_swing_mm"])
    path = tmp_path / "study.toml"
    path.write_text(text)
    return Study(load_study(path), progress=False)


def test_the_optimum_stays_where_the_simulator_reaches_its_responses(tmp_path):
    study = _study(tmp_path)
    out = study.run()
    fit = out["fit"]["swing"]
    assert fit["n_failed"] > 0 and "reach" in fit
    assert fit["reach"]["n_not_reached"] == fit["n_failed"]
    opt = out["optimise"]
    p = opt["reach"]["swing"]["probability"]
    # the quadratic penalty (REACH_PENALTY = 1e4) lets the optimum sit at most a few hundredths
    # below the bound where the weighted error still falls across it
    assert p >= opt["min_reach_probability"] - 0.05, p
    # the classifier's 0.5 line lies between the design runs on either side of U_STIFF: the
    # optimum is within one design spacing (1/24 of the range) of the true boundary or inside
    assert _unit_e(opt["optimum"]["youngs_modulus"]) <= U_STIFF + 1.0 / 24
    rows = out["validate"]["rows"]
    assert {r["status"] for r in rows} == {"done"}, rows
    # the target first swing (87.6 mm) lies below every reached run's (>= 92.8 mm at the
    # stiffest reached E): outside the design's range, which the report says
    first = next(t for t in opt["targets"] if t["response"] == "first_swing_mm")
    assert first["in_design_range"] is False and first["target"] < first["design_range"][0]
    # the report says it, and summary.json carries it
    html = out["report"].read_text()
    assert "Targets outside the range of their design runs" in html
    assert "Probability that a run at the optimum reaches its responses" in html
    assert "may not reach" not in html
    summary = json.loads((out["report"].parent / "summary.json").read_text())
    assert summary["reach"]["swing"]["probability"] == pytest.approx(p)
    assert summary["reach"]["min_reach_probability"] == 0.5


def test_without_the_bound_the_optimum_goes_where_no_run_reached(tmp_path):
    # the same study unconstrained: the surrogates alone lead the optimiser out of the region
    # of the runs that reached their responses, and the validation run reaches nothing
    study = _study(tmp_path, extra="min_reach_probability = 0")
    out = study.run()
    opt = out["optimise"]
    assert opt["reach"]["swing"]["probability"] < 0.5
    assert _unit_e(opt["optimum"]["youngs_modulus"]) > U_STIFF
    assert {r["status"] for r in out["validate"]["rows"]} == {"failed"}
    assert "may not reach its responses" in out["report"].read_text()


def test_min_reach_probability_is_checked(tmp_path):
    from flexparcel.calibration import StudyConfigError

    with pytest.raises(StudyConfigError, match=r"min_reach_probability: must lie in \[0, 1\)"):
        _study(tmp_path, extra="min_reach_probability = 1.5")
