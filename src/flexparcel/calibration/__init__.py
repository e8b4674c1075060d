"""Parameterisation toolkit: designs of experiments, screening, surrogates, optimisation, studies.

The paper's step 4 as a reusable tool that drives any registered simulator (it knows nothing of
the finite-element code):

* :class:`Parameter`, :class:`ParameterSpace`, :class:`Target` - bounds, units, log scale, targets;
* :func:`latin_hypercube`, :func:`extend_latin_hypercube`, :func:`full_factorial`,
  :func:`fractional_factorial` - designs;
* :class:`AnovaScreening` - multi-factor ANOVA / Lenth screening of two-level factorials;
* :class:`GPRSurrogate` - Gaussian-process surrogates with the kernel chosen by cross-validation;
* :class:`CoKrigingSurrogate` - multi-fidelity co-kriging (Kennedy & O'Hagan 2000);
* :func:`weighted_error`, :class:`NelderMeadCalibrator` - the paper's eq. (11) and its minimiser;
* :class:`ReachClassifier` - where a simulator reaches its responses, which bounds the optimum;
* :class:`StudyStore`, :func:`run_campaign` - the resumable SQLite study store and parallel runs;
* :func:`register_simulator` - how simulators make themselves known by name;
* :func:`load_study`, :class:`Study` - study.toml and the pipeline stages behind
  ``flexparcel calibrate``.

scikit-learn, statsmodels, matplotlib and dask are imported only inside the functions that need
them.
"""

from flexparcel.calibration.designs import (
    extend_latin_hypercube,
    fractional_factorial,
    full_factorial,
    latin_hypercube,
)
from flexparcel.calibration.execution import CampaignDrained, CampaignReport, run_campaign
from flexparcel.calibration.multifidelity import CoKrigingSurrogate
from flexparcel.calibration.optimise import NelderMeadCalibrator, range_weights, weighted_error
from flexparcel.calibration.parameters import Parameter, ParameterSpace, Target
from flexparcel.calibration.reach import ReachClassifier
from flexparcel.calibration.screening import AnovaScreening, lenth_pse, screen_responses
from flexparcel.calibration.simulators import (
    available_simulators,
    get_simulator,
    register_simulator,
)
from flexparcel.calibration.store import SCHEMA_VERSION, RunSpec, StudyStore, StudyStoreError
from flexparcel.calibration.study import (
    STAGES,
    STUDY_FORMAT_VERSION,
    Study,
    StudyConfig,
    StudyConfigError,
    load_study,
)
from flexparcel.calibration.surrogates import KERNELS, GPRSurrogate

__all__ = [
    "Parameter",
    "ParameterSpace",
    "Target",
    "latin_hypercube",
    "extend_latin_hypercube",
    "full_factorial",
    "fractional_factorial",
    "AnovaScreening",
    "lenth_pse",
    "screen_responses",
    "KERNELS",
    "GPRSurrogate",
    "CoKrigingSurrogate",
    "weighted_error",
    "range_weights",
    "NelderMeadCalibrator",
    "ReachClassifier",
    "SCHEMA_VERSION",
    "RunSpec",
    "StudyStore",
    "StudyStoreError",
    "CampaignDrained",
    "CampaignReport",
    "run_campaign",
    "register_simulator",
    "get_simulator",
    "available_simulators",
    "STAGES",
    "STUDY_FORMAT_VERSION",
    "Study",
    "StudyConfig",
    "StudyConfigError",
    "load_study",
]
