"""Calibration studies: the ``study.toml`` format and the pipeline stages.

A study (documented in ``docs/calibration.md``) declares parameters, experiments with their
simulator, fixed setup and measured targets, and options for each stage. :func:`load_study`
parses and validates it; every error names the file and the offending field.

:class:`Study` runs the paper's step 4 as resumable stages, each recording its runs and results
in the study store, so every stage can also be run alone later:

``screen``    two-level factorial of an experiment's parameters, multi-factor ANOVA, significant
              parameters passed on (experiments with a ``[screening]`` table only);
``design``    Latin hypercube over each experiment's active parameters, others frozen at their
              nominal values; extended, not redrawn, when ``runs`` grows;
``fit``       one GPR surrogate per target response, kernel by 5-fold CV on 90 % of the runs,
              RMSE on the untouched 10 %;
``optimise``  weighted error of all targets minimised by multi-start bounded Nelder-Mead;
``validate``  the simulators re-run at the optimum (appended to the store);
``report``    ``results.json`` and a self-contained ``report.html``.

A design study (``purpose = "design"``) has no targets: it runs ``screen`` (ranking, nothing
frozen), ``design`` (over every parameter) and ``report``
(:mod:`flexparcel.calibration.design_report`: maps and contours of its outcomes).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import time
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from flexparcel.calibration.designs import (
    extend_latin_hypercube,
    fractional_factorial,
    full_factorial,
    latin_hypercube,
)
from flexparcel.calibration.execution import CampaignReport, not_retried, run_campaign
from flexparcel.calibration.multifidelity import CoKrigingSurrogate
from flexparcel.calibration.optimise import NelderMeadCalibrator, weighted_error
from flexparcel.calibration.parameters import Parameter, ParameterSpace, Target
from flexparcel.calibration.reach import ReachClassifier
from flexparcel.calibration.screening import screen_responses
from flexparcel.calibration.simulators import get_simulator
from flexparcel.calibration.store import RunSpec, StudyStore, cost_key
from flexparcel.calibration.surrogates import KERNELS, GPRSurrogate

__all__ = [
    "STUDY_FORMAT_VERSION",
    "STAGES",
    "StudyConfigError",
    "StudyConfig",
    "ExperimentConfig",
    "load_study",
    "scale_budget",
    "FIDELITY_LEVELS",
    "Study",
]

#: Fidelity levels a study may declare, cheapest first.
FIDELITY_LEVELS = ("low", "high")

#: Version of the study.toml format read by this module.
STUDY_FORMAT_VERSION = 1

#: Pipeline stages in execution order.
STAGES = ("screen", "design", "fit", "optimise", "validate", "report")
_PLAN_STORE_STAGES = {
    ("screen", "low"): "screening",
    ("design", "low"): "design",
    ("design", "high"): "design-high",
    ("validate", "high"): "validation",
    ("validate", "low"): "validation",
}
"""The store's design name of a plan row (stage, level; a single-fidelity row is "low")."""


class StudyConfigError(ValueError):
    """A study file that cannot be used; the message names the file and the field."""


# -- configuration ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ScreeningConfig:
    design: str = "full-factorial"
    generators: tuple[str, ...] = ()
    alpha: float = 0.05
    method: str = "auto"
    interactions: bool = True


@dataclass(frozen=True)
class ExperimentConfig:
    """One experiment: a simulator with a fixed setup, its parameters and its targets."""

    name: str
    simulator: str
    setup: Mapping
    parameters: tuple[str, ...]
    targets: tuple[Target, ...]
    monitor: tuple[str, ...] = ()
    design_runs: int = 50
    design_seed: int | None = None
    screening: ScreeningConfig | None = None
    description: str = ""
    #: Per-experiment bounds overriding the parameters' own: name -> (lower, upper).
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    #: Latin-hypercube runs at the high fidelity level (multi-fidelity studies only).
    high_runs: int | None = None
    #: Stated wall time of one run [s] for the dry-run plan when the store has none measured:
    #: one number, or by fidelity level (``{"low": 160.0, "high": 3000.0}``).
    estimated_run_s: float | Mapping[str, float] | None = None
    #: Responses a design study analyses; a run may lack one (not reached: a consignment that
    #: never leaves the belt has no exit time), which is recorded as absent, not a failure.
    outcomes: tuple[str, ...] = ()

    @property
    def responses(self) -> tuple[str, ...]:
        """Responses the simulator must return: targets first, then monitored ones."""
        return tuple(t.response for t in self.targets) + tuple(self.monitor)


@dataclass(frozen=True)
class StudyConfig:
    """A parsed and validated study.toml (paths resolved against the file's folder)."""

    path: Path
    name: str
    parameters: ParameterSpace
    experiments: dict[str, ExperimentConfig]
    store: Path
    output: Path
    random_state: int = 0
    description: str = ""
    simulator_modules: tuple[str, ...] = ()
    kernels: tuple[str, ...] = ("matern12", "matern32", "matern52", "rbf")
    cv_folds: int = 5
    holdout_fraction: float = 0.1
    gp_restarts: int = 5
    opt_starts: int = 8
    opt_maxiter: int | None = None
    opt_parameters: tuple[str, ...] | None = None
    #: The optimum's least probability of reaching every experiment's responses, by the
    #: classifier of the runs that did and did not reach them (:mod:`.reach`); 0: unconstrained.
    min_reach_probability: float = 0.5
    workers: int | None = None
    retries: int = 2
    threads: int = 1
    scheduler: str | None = None
    validate: bool = True
    #: What the targets' ``reference`` values are called in ``summary.json`` (e.g. "table7").
    reference_name: str = "reference"
    #: Fidelity levels: ``{"low": setup, "high": setup}``, or None for a single-fidelity study.
    fidelity: Mapping[str, Mapping] | None = None
    #: ``calibration`` or ``design`` (:data:`PURPOSES`).
    purpose: str = "calibration"
    #: A design study's maps: ``{"axes": (p1, p2), "flags": (outcome, ...) or None,
    #: "contours": (outcome, ...) or None}`` (None: chosen by the values, see design_report).
    maps: Mapping | None = None

    @property
    def stages(self) -> tuple[str, ...]:
        """The stages this study runs: :data:`STAGES`, or :data:`DESIGN_STAGES` for a design."""
        return DESIGN_STAGES if self.purpose == "design" else STAGES

    def experiment_space(self, experiment: str, names: Sequence[str] | None = None):
        """The parameters of ``experiment`` (or ``names`` of them) with its own bounds applied."""
        exp = self.experiments[experiment]
        names = exp.parameters if names is None else names
        return ParameterSpace(_bounded(self.parameters[n], exp.bounds.get(n)) for n in names)

    def setup_of(self, experiment: str, level: str | None = None) -> dict:
        """The simulator setup of ``experiment`` at fidelity ``level`` (``None``: the level the
        screen and the design use: ``low`` in a multi-fidelity study)."""
        setup = dict(self.experiments[experiment].setup)
        if self.fidelity is not None:
            setup.update(self.fidelity[level or "low"])
        return setup


def _bounded(p: Parameter, bounds) -> Parameter:
    """``p`` with ``bounds`` (lower, upper) instead of its own; a nominal value outside them
    falls back to the midpoint of the new range."""
    if bounds is None:
        return p
    lo, hi = bounds
    nominal = p.nominal if p.nominal is not None and lo <= p.nominal <= hi else None
    return replace(p, lower=float(lo), upper=float(hi), nominal=nominal)


class _Fields:
    """Typed accessors over one TOML table that report errors as ``file: [table] key: ...``."""

    def __init__(self, path: Path, table: str, data, allowed: Sequence[str]):
        self.path, self.table = path, table
        if not isinstance(data, Mapping):
            self.fail("", f"must be a table, got {type(data).__name__}")
        self.data = data
        unknown = sorted(set(data) - set(allowed))
        if unknown:
            self.fail(
                unknown[0],
                f"unknown key (allowed here: {', '.join(sorted(allowed)) or 'none'})",
            )

    def where(self, key: str) -> str:
        t = f"[{self.table}]" if self.table else "top level"
        return f"{t} {key}".strip() if key else t

    def fail(self, key: str, msg: str):
        raise StudyConfigError(f"{self.path}: {self.where(key)}: {msg}")

    def get(self, key, kind, default=None, required=False):
        if key not in self.data:
            if required:
                self.fail(key, "missing (required)")
            return default
        v = self.data[key]
        ok = {
            "str": isinstance(v, str),
            "int": isinstance(v, int) and not isinstance(v, bool),
            "num": isinstance(v, (int, float)) and not isinstance(v, bool),
            "bool": isinstance(v, bool),
            "list": isinstance(v, list),
            "table": isinstance(v, Mapping),
        }[kind]
        if not ok:
            names = {
                "num": "a number",
                "int": "an integer",
                "str": "a string",
                "bool": "true/false",
            }
            self.fail(key, f"must be {names.get(kind, 'a ' + kind)}, got {v!r}")
        if kind == "num" and not math.isfinite(v):
            self.fail(key, f"must be finite, got {v!r}")
        return v

    def str_list(self, key, default=None, required=False):
        v = self.get(key, "list", default, required)
        if v is not None and not all(isinstance(s, str) for s in v):
            self.fail(key, "must be a list of strings")
        return v


_TOP_KEYS = (
    "version",
    "name",
    "description",
    "store",
    "output",
    "random_state",
    "simulator_modules",
    "parameters",
    "experiments",
    "execution",
    "surrogate",
    "optimisation",
    "validation",
    "fidelity",
    "purpose",
    "maps",
)

#: What a study is for: ``calibration`` fits parameters to measured targets; ``design``
#: explores a design space (screen + Latin hypercube) and maps its outcomes, with no targets.
PURPOSES = ("calibration", "design")

#: Stages of a design study (it has no targets to fit, optimise or validate).
DESIGN_STAGES = ("screen", "design", "report")


def load_study(path: str | Path) -> StudyConfig:
    """Parse and validate a study.toml; raises :class:`StudyConfigError` naming the field."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(f"study file {path} not found") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise StudyConfigError(f"{path}: malformed TOML: {exc}") from exc
    return _parse(path, raw)


def _parse(path: Path, raw: Mapping) -> StudyConfig:
    top = _Fields(path, "", raw, _TOP_KEYS)
    version = top.get("version", "int", required=True)
    if version != STUDY_FORMAT_VERSION:
        top.fail(
            "version",
            f"this flexparcel reads study format version {STUDY_FORMAT_VERSION}, "
            f"the file says {version}",
        )
    base = path.parent
    name = top.get("name", "str", path.stem)
    random_state = top.get("random_state", "int", 0)
    modules = tuple(top.str_list("simulator_modules", []))
    purpose = top.get("purpose", "str", "calibration")
    if purpose not in PURPOSES:
        top.fail("purpose", f"must be one of {', '.join(map(repr, PURPOSES))}, got {purpose!r}")

    # parameters
    ptable = top.get("parameters", "table", required=True)
    if not ptable:
        top.fail("parameters", "no parameters defined")
    params = []
    for pname, pdata in ptable.items():
        f = _Fields(
            path,
            f"parameters.{pname}",
            pdata,
            ("bounds", "unit", "scale", "nominal", "description"),
        )
        bounds = f.get("bounds", "list", required=True)
        if len(bounds) != 2 or not all(
            isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds
        ):
            f.fail("bounds", f"must be [lower, upper] (two numbers), got {bounds!r}")
        lo, hi = float(bounds[0]), float(bounds[1])
        if not lo < hi:
            f.fail("bounds", f"lower bound {bounds[0]} must be below upper bound {bounds[1]}")
        scale = f.get("scale", "str", "linear")
        nominal = f.get("nominal", "num")
        try:
            params.append(
                Parameter(
                    pname,
                    lo,
                    hi,
                    unit=f.get("unit", "str", ""),
                    scale=scale,
                    nominal=None if nominal is None else float(nominal),
                    description=f.get("description", "str", ""),
                )
            )
        except ValueError as exc:
            f.fail("", str(exc))
    space = ParameterSpace(params)

    # experiments
    etable = top.get("experiments", "table", required=True)
    if not etable:
        top.fail("experiments", "no experiments defined")
    experiments = {}
    for ename, edata in etable.items():
        experiments[ename] = _parse_experiment(path, ename, edata, space, purpose)
    used = {p for e in experiments.values() for p in e.parameters}
    unused = [p for p in space.names if p not in used]
    if unused:
        _Fields(path, f"parameters.{unused[0]}", {}, ()).fail(
            "", "not used by any experiment (list it in an experiment's parameters or remove it)"
        )

    ex = _Fields(
        path,
        "execution",
        top.get("execution", "table", {}),
        ("workers", "retries", "threads", "scheduler"),
    )
    workers = ex.get("workers", "int")
    if workers is not None and workers < 0:
        ex.fail("workers", "must be >= 0 (0 runs in this process)")
    retries = ex.get("retries", "int", 2)
    if retries < 0:
        ex.fail("retries", "must be >= 0")
    threads = ex.get("threads", "int", 1)
    if threads < 1:
        ex.fail("threads", "must be >= 1")

    su = _Fields(
        path,
        "surrogate",
        top.get("surrogate", "table", {}),
        ("kernels", "cv_folds", "holdout_fraction", "restarts"),
    )
    kernels = tuple(su.str_list("kernels", list(KERNELS)))
    bad = [k for k in kernels if k not in KERNELS]
    if bad or not kernels:
        su.fail("kernels", f"unknown kernel {bad[0] if bad else ''!r}; choose from {list(KERNELS)}")
    cv_folds = su.get("cv_folds", "int", 5)
    if cv_folds < 2:
        su.fail("cv_folds", "must be >= 2")
    holdout = float(su.get("holdout_fraction", "num", 0.1))
    if not 0.0 <= holdout < 0.5:
        su.fail("holdout_fraction", "must lie in [0, 0.5)")
    restarts = su.get("restarts", "int", 5)
    if restarts < 0:
        su.fail("restarts", "must be >= 0")

    op = _Fields(
        path,
        "optimisation",
        top.get("optimisation", "table", {}),
        ("starts", "maxiter", "parameters", "min_reach_probability"),
    )
    starts = op.get("starts", "int", 8)
    if starts < 1:
        op.fail("starts", "must be >= 1")
    min_reach = float(op.get("min_reach_probability", "num", 0.5))
    if not 0.0 <= min_reach < 1.0:
        op.fail("min_reach_probability", f"must lie in [0, 1), got {min_reach!r}")
    maxiter = op.get("maxiter", "int")
    opt_params = op.str_list("parameters")
    if opt_params is not None:
        for p in opt_params:
            if p not in space:
                op.fail(
                    "parameters", f"unknown parameter {p!r} (defined: {', '.join(space.names)})"
                )
    va = _Fields(
        path, "validation", top.get("validation", "table", {}), ("enabled", "reference_name")
    )
    from flexparcel.calibration.summary import SUMMARY_ROW_KEYS, summary_names

    reference_name = va.get("reference_name", "str", "reference")
    if not reference_name.isidentifier() or reference_name in SUMMARY_ROW_KEYS:
        va.fail(
            "reference_name",
            f"must be a name of letters, digits and '_' other than {', '.join(SUMMARY_ROW_KEYS)},"
            f" got {reference_name!r}",
        )

    try:
        summary_names(experiments.values())
    except ValueError as exc:
        _Fields(path, "experiments", {}, ()).fail("targets", str(exc))
    weights = [t.weight for e in experiments.values() for t in e.targets]
    if weights and all(w == 0 for w in weights):
        _Fields(path, "experiments", {}, ()).fail(
            "targets", "every target has weight = 0: at least one must enter the objective"
        )
    fidelity = _parse_fidelity(path, top, experiments)
    maps = _parse_maps(path, top, space, experiments, purpose)
    # The optimiser searches where every experiment that varies a parameter has data.
    for p in space.names:
        box = [e.bounds.get(p, (space[p].lower, space[p].upper)) for e in experiments.values()]
        box = [b for b, e in zip(box, experiments.values(), strict=True) if p in e.parameters]
        lo, hi = max(b[0] for b in box), min(b[1] for b in box)
        if not lo < hi:
            _Fields(path, f"parameters.{p}", {}, ()).fail(
                "bounds",
                f"the experiments' bounds of {p} do not overlap (common range [{lo:g}, {hi:g}]); "
                "the calibrated value must lie in every experiment's range",
            )

    return StudyConfig(
        path=path,
        name=name,
        description=top.get("description", "str", ""),
        parameters=space,
        experiments=experiments,
        store=(base / top.get("store", "str", f"{path.stem}.sqlite")).resolve(),
        output=(base / top.get("output", "str", f"{path.stem}-report")).resolve(),
        random_state=random_state,
        simulator_modules=modules,
        kernels=kernels,
        cv_folds=cv_folds,
        holdout_fraction=holdout,
        gp_restarts=restarts,
        opt_starts=starts,
        opt_maxiter=maxiter,
        opt_parameters=tuple(opt_params) if opt_params is not None else None,
        min_reach_probability=min_reach,
        workers=workers,
        retries=retries,
        threads=threads,
        scheduler=ex.get("scheduler", "str"),
        validate=va.get("enabled", "bool", True),
        reference_name=reference_name,
        fidelity=fidelity,
        purpose=purpose,
        maps=maps,
    )


def _parse_maps(path: Path, top: _Fields, space: ParameterSpace, experiments, purpose: str):
    """A design study's ``[maps]``: the two parameters its maps are drawn over (default the
    first two), the 0/1 outcomes drawn as maps of the runs (``flags``; default: those whose
    every value is 0 or 1) and the outcomes drawn as contours (default: all others)."""
    if purpose != "design":
        if "maps" in top.data:
            top.fail("maps", "only a design study (purpose = 'design') draws maps")
        return None
    m = _Fields(path, "maps", top.get("maps", "table", {}), ("axes", "flags", "contours"))
    axes = m.str_list("axes", list(space.names[:2]))
    if len(axes) != 2 or len(set(axes)) != 2 or not all(a in space for a in axes):
        m.fail("axes", f"must name two different parameters of {', '.join(space.names)}; "
                       f"got {axes!r}")  # fmt: skip
    known = {o for e in experiments.values() for o in e.outcomes}
    lists = {}
    for key in ("flags", "contours"):
        names = m.str_list(key)
        bad = [o for o in names or () if o not in known]
        if bad:
            m.fail(key, f"{bad[0]!r} is not an outcome of any experiment")
        lists[key] = None if names is None else tuple(names)
    return {"axes": tuple(axes), **lists}


def _parse_fidelity(path: Path, top: _Fields, experiments) -> dict | None:
    """``[fidelity.low]`` and ``[fidelity.high]``, each with its ``setup`` (merged over every
    experiment's own setup; the screen and the design run at ``low``, ``high_runs`` and the
    validation at ``high``)."""
    table = top.get("fidelity", "table")
    if table is None:
        for e in experiments.values():
            if isinstance(e.estimated_run_s, Mapping):
                _Fields(path, f"experiments.{e.name}", {}, ()).fail(
                    "estimated_run_s",
                    "a table by fidelity level needs [fidelity.low] and [fidelity.high]; "
                    "give one number [s]",
                )
            if e.high_runs is not None:
                _Fields(path, f"experiments.{e.name}.design", {}, ()).fail(
                    "high_runs", "only a study with [fidelity.low] and [fidelity.high] takes it"
                )
        return None
    fid = _Fields(path, "fidelity", table, FIDELITY_LEVELS)
    levels = {}
    for level in FIDELITY_LEVELS:
        lf = _Fields(path, f"fidelity.{level}", fid.get(level, "table", required=True), ("setup",))
        setup = lf.get("setup", "table")
        if not setup:
            lf.fail(
                "setup",
                "missing: a fidelity level is its simulator setup, e.g. "
                "setup = { element_size_mm = 25 } (required, not empty)",
            )
        levels[level] = dict(setup)
    if levels["low"] == levels["high"]:
        fid.fail("high", "its setup equals the low level's: the levels would be the same runs")
    for e in experiments.values():
        ef = _Fields(path, f"experiments.{e.name}", {}, ())
        for level, setup in levels.items():
            both = sorted(set(setup) & set(e.setup))
            if both:
                ef.fail(
                    "setup",
                    f"{both[0]!r} is set here and in [fidelity.{level}] setup; set it in one place",
                )
        if e.high_runs is None:
            _Fields(path, f"experiments.{e.name}.design", {}, ()).fail(
                "high_runs",
                "missing: a multi-fidelity study needs the number of high-fidelity runs of "
                "each experiment (the few accurate runs that correct the low level)",
            )
    return levels


def scale_budget(
    config: StudyConfig, factor: float | None = None, runs: Mapping[str, int] | None = None
) -> StudyConfig:
    """A smaller (or larger) campaign: every Latin hypercube's run count times ``factor``
    (at least what the surrogate's hold-out and CV need: ``2 cv_folds + 1``; high-fidelity runs
    at least 3), then ``runs`` = ``{experiment: N}`` setting an experiment's design runs. The
    screening factorials are not scaled: a full factorial is all or nothing (declare a
    fractional one in the study to shrink it). The design stage *extends* a smaller design
    later, so a pilot campaign's runs are kept when the full one follows."""
    if factor is not None and not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"--budget must be a positive factor, got {factor!r}")
    floor = 2 * config.cv_folds + (1 if config.holdout_fraction > 0 else 0)
    experiments = {}
    for name, e in config.experiments.items():
        n, nh = e.design_runs, e.high_runs
        if factor is not None:
            n = max(floor, int(round(n * factor)))
            if nh is not None:
                nh = max(3, int(round(nh * factor)))
        experiments[name] = replace(e, design_runs=n, high_runs=nh)
    for name, n in (runs or {}).items():
        if name not in experiments:
            raise ValueError(
                f"--runs {name}={n}: no experiment {name!r} (experiments: {', '.join(experiments)})"
            )
        if n < 2:
            raise ValueError(f"--runs {name}={n}: at least 2 runs")
        experiments[name] = replace(experiments[name], design_runs=int(n))
    return replace(config, experiments=experiments)


def _simulator_reference(path: Path, name: str) -> str:
    """A study's ``simulator``: a registered name, ``module:function``, or ``FILE.py:function``
    with FILE relative to the study file (made absolute here, so that every worker finds it)."""
    target, sep, func = name.rpartition(":")
    if sep and target.endswith(".py") and not Path(target).is_absolute():
        return f"{(path.parent / target).resolve()}:{func}"
    return name


def _estimated_run_s(path: Path, t: str, f: _Fields, edata) -> float | dict[str, float] | None:
    """``estimated_run_s``: one number [s], or a table by fidelity level (``{ low = 160,
    high = 3000 }``: a 10 mm run costs ten times a 25 mm one, so one figure cannot serve both
    levels of a multi-fidelity plan)."""
    raw = edata.get("estimated_run_s") if isinstance(edata, Mapping) else None
    if isinstance(raw, Mapping):
        lf = _Fields(path, f"{t}.estimated_run_s", raw, FIDELITY_LEVELS)
        out = {lv: float(lf.get(lv, "num")) for lv in FIDELITY_LEVELS if lv in raw}
        for lv, v in out.items():
            if v <= 0:
                lf.fail(lv, "must be > 0 [s]")
        return out or None
    estimated = f.get("estimated_run_s", "num")
    if estimated is not None and estimated <= 0:
        f.fail("estimated_run_s", "must be > 0 [s]")
    return None if estimated is None else float(estimated)


def _parse_experiment(
    path: Path, ename: str, edata, space: ParameterSpace, purpose: str = "calibration"
) -> ExperimentConfig:
    t = f"experiments.{ename}"
    f = _Fields(
        path,
        t,
        edata,
        (
            "simulator",
            "setup",
            "parameters",
            "targets",
            "monitor",
            "design",
            "screening",
            "description",
            "bounds",
            "estimated_run_s",
            "outcomes",
        ),
    )
    simulator = _simulator_reference(path, f.get("simulator", "str", required=True))
    setup = dict(f.get("setup", "table", {}))
    pnames = f.str_list("parameters", space.names)
    for p in pnames:
        if p not in space:
            f.fail("parameters", f"unknown parameter {p!r} (defined: {', '.join(space.names)})")
    if len(set(pnames)) != len(pnames) or not pnames:
        f.fail("parameters", "must list distinct parameters, at least one")
    bounds = {}
    for p, b in f.get("bounds", "table", {}).items():
        if p not in pnames:
            f.fail("bounds", f"{p!r} is not one of this experiment's parameters")
        if not (
            isinstance(b, list)
            and len(b) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in b)
        ):
            f.fail("bounds", f"{p}: must be [lower, upper] (two numbers), got {b!r}")
        try:
            _bounded(space[p], (float(b[0]), float(b[1])))
        except ValueError as exc:
            f.fail("bounds", f"{p}: {exc}")
        bounds[p] = (float(b[0]), float(b[1]))
    estimated = _estimated_run_s(path, t, f, edata)
    ttable = f.get("targets", "table")
    outcomes = tuple(f.str_list("outcomes", []))
    if purpose == "design":
        if ttable:
            f.fail("targets", "a design study (purpose = 'design') has no targets; list the "
                              "responses to map under outcomes")  # fmt: skip
        if not outcomes:
            f.fail("outcomes", "missing: a design study's experiment lists the responses it maps")
        ttable = {}
    elif outcomes:
        f.fail("outcomes", "only a design study (purpose = 'design') takes outcomes; a "
                           "calibration lists targets and monitor")  # fmt: skip
    elif not ttable:
        f.fail("targets", "missing: every experiment needs at least one target response")
    targets = []
    for rname, tdata in ttable.items():
        if isinstance(tdata, (int, float)) and not isinstance(tdata, bool):
            tdata = {"value": tdata}
        tf = _Fields(
            path,
            f"{t}.targets.{rname}",
            tdata,
            ("value", "weight", "spread", "unit", "transform", "log_offset", "label", "reference"),
        )
        value = tf.get("value", "num", required=True)
        weight = tf.get("weight", "num")
        spread = tf.get("spread", "num")
        if weight is not None and weight < 0:
            tf.fail("weight", "must be >= 0 (0: reported and validated, not fitted)")
        if spread is not None and spread < 0:
            tf.fail("spread", "must be >= 0")
        transform = tf.get("transform", "str", "none")
        if transform not in ("none", "log"):
            tf.fail("transform", f"must be 'none' or 'log', got {transform!r}")
        log_offset = float(tf.get("log_offset", "num", 0.0))
        if log_offset < 0:
            tf.fail("log_offset", "must be >= 0 (log(y + log_offset) is modelled)")
        if "log_offset" in tdata and transform != "log":
            tf.fail("log_offset", "only a transform = 'log' takes a log_offset")
        label = tf.get("label", "str")
        if label is not None and not label.isidentifier():
            tf.fail("label", f"must be a name of letters, digits and '_', got {label!r}")
        reference = tf.get("reference", "num")
        targets.append(
            Target(
                ename,
                rname,
                float(value),
                weight=None if weight is None else float(weight),
                spread=None if spread is None else float(spread),
                unit=tf.get("unit", "str", ""),
                transform=transform,
                log_offset=log_offset,
                label=label,
                reference=None if reference is None else float(reference),
            )
        )
    monitor = tuple(f.str_list("monitor", []))
    d = _Fields(path, f"{t}.design", f.get("design", "table", {}), ("runs", "seed", "high_runs"))
    runs = d.get("runs", "int", 50)
    if runs < 2:
        d.fail("runs", "must be >= 2")
    high_runs = d.get("high_runs", "int")
    if high_runs is not None and high_runs < 2:
        d.fail("high_runs", "must be >= 2 (co-kriging needs at least two high-fidelity runs)")
    screening = None
    if "screening" in edata:
        s = _Fields(
            path,
            f"{t}.screening",
            f.get("screening", "table"),
            ("design", "generators", "alpha", "method", "interactions"),
        )
        design = s.get("design", "str", "full-factorial")
        if design not in ("full-factorial", "fractional-factorial"):
            s.fail("design", "must be 'full-factorial' or 'fractional-factorial'")
        generators = tuple(s.str_list("generators", []))
        if design == "fractional-factorial" and not generators:
            s.fail("generators", "a fractional factorial needs generators, e.g. ['E = ABCD']")
        if design == "full-factorial" and generators:
            s.fail("generators", "only a fractional-factorial design takes generators")
        alpha = float(s.get("alpha", "num", 0.05))
        if not 0 < alpha < 1:
            s.fail("alpha", "must lie in (0, 1)")
        method = s.get("method", "str", "auto")
        if method not in ("auto", "anova", "lenth"):
            s.fail("method", "must be 'auto', 'anova' or 'lenth'")
        if len(pnames) < 2:
            s.fail("", "screening needs at least two parameters")
        try:
            if generators:
                fractional_factorial(len(pnames), generators)
        except ValueError as exc:
            s.fail("generators", str(exc))
        screening = ScreeningConfig(
            design, generators, alpha, method, s.get("interactions", "bool", True)
        )
    return ExperimentConfig(
        name=ename,
        simulator=simulator,
        setup=setup,
        parameters=tuple(pnames),
        targets=tuple(targets),
        monitor=monitor,
        design_runs=runs,
        design_seed=d.get("seed", "int"),
        screening=screening,
        description=f.get("description", "str", ""),
        bounds=bounds,
        high_runs=high_runs,
        estimated_run_s=estimated,
        outcomes=outcomes,
    )


# -- pipeline --------------------------------------------------------------------------------


#: Weight of the optimiser's penalty on a reach probability below ``min_reach_probability``.
REACH_PENALTY = 1e4


def _seed(*parts) -> int:
    """A 32-bit seed derived from the study seed and names (independent of experiment order)."""
    h = hashlib.sha256(json.dumps([str(p) for p in parts]).encode()).digest()
    return int.from_bytes(h[:4], "big")


@contextlib.contextmanager
def _blas_threads(n: int):
    """Limit BLAS/OpenMP threads in this process while fitting and predicting surrogates.

    GP matrices are at most a few hundred rows: threading them gains nothing, and on a loaded
    machine idle-spinning BLAS threads slow a fit down several times (measured: 13 s -> 61 s
    for the example study's fit stage with one other busy process on 2 cores).
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl ships with scikit-learn
        yield
        return
    with threadpool_limits(n):
        yield


def _fingerprint(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True).encode()).hexdigest()[:16]


def _stated_cost(exp: ExperimentConfig, level: str | None) -> float | None:
    """The experiment's ``estimated_run_s`` [s] at fidelity ``level`` (one number for all
    levels, or a table by level), or None."""
    stated = exp.estimated_run_s
    if isinstance(stated, Mapping):
        stated = stated.get(level)
    return None if stated is None else float(stated)


class Study:
    """The calibration pipeline of one study file over its store.

    Parameters
    ----------
    config:
        A :class:`StudyConfig` (see :func:`load_study`) or the path of a study.toml.
    store, output:
        Override the store file and the report folder of the configuration.
    workers, scheduler, retries:
        Override the ``[execution]`` options (``scheduler``: a Dask scheduler address).
    retry_failed:
        Give runs that failed in earlier campaigns a fresh retry budget.
    progress:
        Show progress bars.
    time_limit_s:
        Wall time [s] from now within which every run this study starts must end: a
        campaign starts no run whose measured cost would take it past, and raises
        :class:`~flexparcel.calibration.execution.CampaignDrained` with the rest pending.
    """

    def __init__(
        self,
        config: StudyConfig | str | Path,
        *,
        store: str | Path | None = None,
        output: str | Path | None = None,
        workers: int | None = None,
        scheduler=None,
        retries: int | None = None,
        retry_failed: bool = False,
        progress: bool = True,
        time_limit_s: float | None = None,
    ):
        if time_limit_s is not None and not (math.isfinite(time_limit_s) and time_limit_s > 0):
            raise ValueError(f"time_limit_s must be > 0 s, got {time_limit_s!r}")
        self.deadline = None if time_limit_s is None else time.time() + float(time_limit_s)
        self.config = config if isinstance(config, StudyConfig) else load_study(config)
        c = self.config
        self.store_path = Path(store) if store is not None else c.store
        self.output = Path(output) if output is not None else c.output
        self.workers = workers if workers is not None else c.workers
        self.scheduler = scheduler if scheduler is not None else c.scheduler
        self.retries = retries if retries is not None else c.retries
        self.retry_failed = retry_failed
        self.progress = progress
        self.campaigns: dict[str, CampaignReport] = {}
        self._store: StudyStore | None = None

    # -- plumbing ----------------------------------------------------------------------------

    @property
    def store(self) -> StudyStore:
        if self._store is None:
            self._store = StudyStore(self.store_path)
            if self._store.get_meta("study_name") is None:
                self._store.set_meta("study_name", self.config.name)
        return self._store

    def close(self) -> None:
        if self._store is not None:
            self._store.close()
            self._store = None

    def __enter__(self) -> Study:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _spec(
        self, exp: ExperimentConfig, params: Mapping[str, float], level: str | None = None
    ) -> RunSpec:
        info = get_simulator(exp.simulator, self.config.simulator_modules)
        return RunSpec(exp.simulator, info.version, self.config.setup_of(exp.name, level), params)

    def _campaign(self, label: str, batches: list[tuple[ExperimentConfig, list[str]]]):
        keys, expect = [], {}
        for exp, ks in batches:
            keys += ks
            for k in ks:
                expect[k] = tuple(dict.fromkeys(expect.get(k, ()) + exp.responses))
        rep = run_campaign(
            self.store,
            keys,
            workers=self.workers,
            scheduler=self.scheduler,
            retries=self.retries,
            retry_failed=self.retry_failed,
            expect=expect,
            modules=self.config.simulator_modules,
            threads=self.config.threads,
            progress=self.progress,
            desc=label,
            deadline=self.deadline,
            stated_costs=self._stated_costs(),
        )
        self.campaigns[label] = rep
        return rep

    def _stated_costs(self) -> dict[tuple[str, str], float]:
        """The experiments' ``estimated_run_s`` [s] by :func:`cost_key` of each level's setup:
        the cost of a kind of run not finished yet, for the time limit."""
        c = self.config
        out = {}
        for exp in c.experiments.values():
            for level in ("low", "high") if c.fidelity is not None else (None,):
                stated = _stated_cost(exp, level)
                if stated is not None:
                    run = {"simulator": exp.simulator, "setup": c.setup_of(exp.name, level)}
                    out[cost_key(run)] = float(stated)
        return out

    def _done_rows(self, stage: str, exp: ExperimentConfig, limit: int | None = None):
        keys = self.store.design_keys(stage, exp.name)
        if limit is not None:
            keys = keys[:limit]
        rows = self.store.get_runs(keys)
        return rows, [r for r in rows if r["status"] == "done"]

    def _require(self, stage: str, experiment: str, needed_by: str, hint: str):
        res = self.store.get_result(stage, experiment)
        if res is None:
            where = f" of experiment '{experiment}'" if experiment else ""
            raise StudyConfigError(
                f"stage '{needed_by}'{where} needs the results of stage '{hint}': "
                f"run `flexparcel calibrate {self.config.path.name} --stage {hint}` first"
            )
        return res

    def active_parameters(self, exp: ExperimentConfig) -> list[str]:
        """Parameters varied in the experiment's design: the screening result, or all (always
        all in a design study: its screen ranks the parameters, the map needs every one)."""
        if exp.screening is None or self.config.purpose == "design":
            return list(exp.parameters)
        res = self._require("screening", exp.name, "design", "screen")
        return list(res["significant"])

    # -- stages ------------------------------------------------------------------------------

    def screen(self) -> dict:
        """Run and analyse the screening factorials; returns ``{experiment: result}``."""
        batches, designs = [], {}
        for exp in self.config.experiments.values():
            if exp.screening is None:
                continue
            sub = self.config.experiment_space(exp.name)
            if exp.screening.design == "full-factorial":
                C = full_factorial(sub.dim)
            else:
                C = fractional_factorial(sub.dim, exp.screening.generators)
            X = sub.from_coded(C)
            keys = self.store.add_design(
                "screening", exp.name, [self._spec(exp, p) for p in sub.as_dicts(X)]
            )
            batches.append((exp, keys))
            designs[exp.name] = (C, keys)
        if not batches:
            return {}
        self._campaign("screening", batches)
        out = {}
        for exp, _ in batches:
            C, keys = designs[exp.name]
            rows = self.store.get_runs(keys)
            failed = [r["run_key"] for r in rows if r["status"] != "done"]
            if failed:
                raise RuntimeError(
                    f"screening of '{exp.name}': {len(failed)} of {len(rows)} factorial runs "
                    "failed; an ANOVA needs the complete design (see the store's error texts, "
                    "then rerun with --retry-failed)"
                )
            responses, skipped = self._screened_responses(exp, rows)
            design = self.config.purpose == "design"
            sc = exp.screening
            try:
                significant, fitted = screen_responses(
                    C,
                    responses,
                    list(exp.parameters),
                    alpha=sc.alpha,
                    interactions=sc.interactions,
                    method=sc.method,
                )
            except ValueError as exc:
                raise StudyConfigError(f"stage 'screen', experiment '{exp.name}': {exc}") from exc
            result = {
                "design": sc.design,
                "generators": list(sc.generators),
                "coded": C.tolist(),
                "run_keys": keys,
                "parameters": list(exp.parameters),
                "responses": {r: v.tolist() for r, v in responses.items()},
                "anova": {r: s.to_dict() for r, s in fitted.items()},
                "significant": significant,
                # a design study's hypercube varies every parameter: it freezes none
                "frozen": {}
                if design
                else {p: sub[p].nominal_value for p in exp.parameters if p not in significant},
                "not_analysed": skipped,
            }
            if not (design or significant):
                raise RuntimeError(
                    f"screening of '{exp.name}' found no significant parameter at alpha = "
                    f"{sc.alpha}; nothing to calibrate against its targets"
                )
            self.store.put_result("screening", exp.name, result)
            out[exp.name] = result
        return out

    def _screened_responses(self, exp: ExperimentConfig, rows: list[dict]):
        """The responses the screen analyses, ``{name: values}``, and those it leaves out with
        the reason, ``{name: reason}``. A calibration analyses its targets and monitored
        responses (every run has them); a design study its outcomes that every factorial run
        reached and that vary over the design."""
        if self.config.purpose != "design":
            return {r: np.array([row["responses"][r] for row in rows]) for r in exp.responses}, {}
        out, skipped = {}, {}
        for r in exp.outcomes:
            values = [(row["responses"] or {}).get(r) for row in rows]
            if any(v is None for v in values):
                n = sum(v is None for v in values)
                skipped[r] = f"not reached in {n} of {len(values)} factorial runs"
            elif np.ptp(values) == 0.0:
                skipped[r] = f"the same in every factorial run ({values[0]:g})"
            else:
                out[r] = np.array(values, dtype=float)
        if not out:
            raise StudyConfigError(
                f"stage 'screen', experiment '{exp.name}': no outcome can be analysed ("
                + "; ".join(f"{k}: {v}" for k, v in skipped.items())
                + ")"
            )
        return out, skipped

    def design(self) -> dict:
        """Run the Latin-hypercube designs (extending earlier ones); returns info per experiment."""
        batches, out = [], {}
        for exp in self.config.experiments.values():
            active = self.active_parameters(exp)
            full = self.config.experiment_space(exp.name)
            sub = full.subspace(active)
            frozen = {p: full[p].nominal_value for p in exp.parameters if p not in active}
            seed = (
                exp.design_seed
                if exp.design_seed is not None
                else _seed(self.config.random_state, exp.name, "design")
            )
            info = get_simulator(exp.simulator, self.config.simulator_modules)
            fp = _fingerprint(
                {
                    "active": [[p.name, p.lower, p.upper, p.scale] for p in sub.parameters],
                    "frozen": frozen,
                    "simulator": [exp.simulator, info.version],
                    "setup": self.config.setup_of(exp.name),
                    "seed": seed,
                }
            )
            if self.config.fidelity is not None:
                fp = _fingerprint([fp, self.config.setup_of(exp.name, "high")])
            prev = self.store.get_result("design", exp.name)
            if prev is not None and prev["fingerprint"] != fp:
                raise StudyConfigError(
                    f"the design of experiment '{exp.name}' in {self.store_path} was made for "
                    f"other parameters, bounds, setup or seed (active then: "
                    f"{', '.join(prev['active'])}; now: {', '.join(active)}); run "
                    "`flexparcel calibrate ... --reset design` to redo it (runs already "
                    "simulated are kept and reused where they match)"
                )
            n_prev = len(self.store.design_keys("design", exp.name)) if prev else 0
            if n_prev == 0:
                U = latin_hypercube(exp.design_runs, sub.dim, random_state=seed)
            elif exp.design_runs > n_prev:
                old = self.store.get_runs(self.store.design_keys("design", exp.name))
                U_old = sub.to_unit(sub.from_dicts(r["params"] for r in old))
                U_new = extend_latin_hypercube(
                    U_old, exp.design_runs - n_prev, random_state=_seed(seed, n_prev)
                )
                U = np.vstack([U_old, U_new])
            else:
                U = None
            if U is not None:
                points = [dict(p, **frozen) for p in sub.as_dicts(sub.from_unit(U))]
                if n_prev:
                    # Keep the stored parameter values of the old runs bit for bit.
                    old_params = [r["params"] for r in old]
                    points[:n_prev] = old_params
                keys = self.store.add_design(
                    "design", exp.name, [self._spec(exp, p) for p in points]
                )
            keys = self.store.design_keys("design", exp.name)[: exp.design_runs]
            self.store.put_result(
                "design",
                exp.name,
                {
                    "fingerprint": fp,
                    "active": active,
                    "frozen": frozen,
                    "seed": seed,
                    "runs": exp.design_runs,
                    "stored_runs": len(self.store.design_keys("design", exp.name)),
                },
            )
            batches.append((exp, keys))
            out[exp.name] = {"active": active, "frozen": frozen, "runs": len(keys)}
            if self.config.fidelity is not None:
                # A few high-fidelity runs: their own seeded Latin hypercube over the same
                # active parameters (the co-kriging needs no nesting in the low design).
                U = latin_hypercube(exp.high_runs, sub.dim, random_state=_seed(seed, "high"))
                points = [dict(p, **frozen) for p in sub.as_dicts(sub.from_unit(U))]
                self.store.delete_design("design-high", exp.name)
                hkeys = self.store.add_design(
                    "design-high", exp.name, [self._spec(exp, p, "high") for p in points]
                )
                batches.append((exp, hkeys))
                out[exp.name]["high_runs"] = len(hkeys)
        self._campaign("design", batches)
        for exp, keys in batches:
            counts = self.store.status_counts(keys)
            key = "status" if "status" not in out[exp.name] else "high_status"
            out[exp.name][key] = counts
        return out

    def _surrogates(self, exp: ExperimentConfig, fit: dict) -> dict:
        """The fitted surrogates of ``exp``, rebuilt from the store: ``{response: model}``
        (:class:`GPRSurrogate`, or :class:`CoKrigingSurrogate` in a multi-fidelity study)."""
        sub = self.config.experiment_space(exp.name, fit["active"])
        rows = self.store.get_runs(fit["run_keys"])
        X = sub.from_dicts(r["params"] for r in rows)
        if "high_run_keys" not in fit:
            return {
                r: GPRSurrogate.from_dict(
                    fit["responses"][r], sub, X, [row["responses"][r] for row in rows]
                )
                for r in fit["responses"]
            }
        high = self.store.get_runs(fit["high_run_keys"])
        Xh = sub.from_dicts(r["params"] for r in high)
        return {
            r: CoKrigingSurrogate.from_dict(
                fit["responses"][r],
                sub,
                X,
                [row["responses"][r] for row in rows],
                Xh,
                [row["responses"][r] for row in high],
            )
            for r in fit["responses"]
        }

    def fit(self) -> dict:
        """Fit one GPR surrogate per target response; returns ``{experiment: result}``."""
        self.check_stages(["fit"])
        with _blas_threads(self.config.threads):
            return self._fit()

    def _fit(self) -> dict:
        c = self.config
        out = {}
        jobs = [(e, t) for e in c.experiments.values() for t in e.targets]
        bar = None
        if self.progress:
            try:
                from tqdm.auto import tqdm

                bar = tqdm(total=len(jobs), desc="fit", unit="model", leave=False)
            except ImportError:  # pragma: no cover
                bar = None
        for exp in c.experiments.values():
            design = self._require("design", exp.name, "fit", "design")
            active = design["active"]
            sub = c.experiment_space(exp.name, active)
            rows, done = self._done_rows("design", exp, exp.design_runs)
            if not rows:
                raise StudyConfigError(
                    f"stage 'fit' of experiment '{exp.name}' found no design runs: run "
                    "--stage design first"
                )
            n_failed = len(rows) - len(done)
            pending = [r for r in rows if r["status"] in ("pending", "running")]
            if pending:
                raise RuntimeError(
                    f"stage 'fit' of experiment '{exp.name}': {len(pending)} design runs have "
                    "not been executed yet; run --stage design (it resumes) first"
                )
            X = sub.from_dicts(r["params"] for r in done)
            result = {
                "active": active,
                "run_keys": [r["run_key"] for r in done],
                "n_failed": n_failed,
                "responses": {},
                "range": {},
            }
            high, hrows = [], []
            if c.fidelity is not None:
                hrows = self.store.get_runs(self.store.design_keys("design-high", exp.name))
                high = [r for r in hrows if r["status"] == "done"]
                result["high_run_keys"] = [r["run_key"] for r in high]
                result["n_high_failed"] = len(hrows) - len(high)
                Xh = sub.from_dicts(r["params"] for r in high)
            reach = self._fit_reach(exp, sub, rows + hrows)
            if reach is not None:
                result["reach"] = reach
            for t in exp.targets:
                y = np.array([r["responses"][t.response] for r in done])
                common = dict(
                    kernels=c.kernels,
                    cv_folds=c.cv_folds,
                    holdout_fraction=c.holdout_fraction,
                    n_restarts_optimizer=c.gp_restarts,
                    random_state=_seed(c.random_state, exp.name, t.response, "gpr"),
                    transform=t.transform,
                    log_offset=t.log_offset,
                    name=t.response,
                )
                try:
                    if c.fidelity is None:
                        gp = GPRSurrogate(sub, **common).fit(X, y)
                    else:
                        yh = np.array([r["responses"][t.response] for r in high])
                        gp = CoKrigingSurrogate(sub, **common).fit(X, y, Xh, yh)
                        # the weights 1/range come from the high level (the calibrated one)
                        y = yh
                except ValueError as exc:
                    raise StudyConfigError(
                        f"stage 'fit', experiment '{exp.name}', response '{t.response}': {exc} "
                        f"({len(done)} usable runs of {len(rows)}; see "
                        f"[experiments.{exp.name}.design] runs and [surrogate])"
                    ) from exc
                result["responses"][t.response] = gp.to_dict()
                result["range"][t.response] = [float(y.min()), float(y.max())]
                if bar is not None:
                    bar.update(1)
            self.store.put_result("fit", exp.name, result)
            out[exp.name] = result
        if bar is not None:
            bar.close()
        return out

    def _fit_reach(self, exp: ExperimentConfig, sub: ParameterSpace, rows: list) -> dict | None:
        """The classifier of where ``exp``'s simulator reaches its responses (:mod:`.reach`),
        from its design runs of every level (a point not reached at either level counts as
        not reached there), as stored data; None where every run reached them, or fewer than
        two did. Runs that failed otherwise (a crash) say nothing about the model and are
        left out."""
        known = [r for r in rows if r["status"] == "done" or not_retried(r["error"])]
        reached = [r["status"] == "done" for r in known]
        if all(reached) or sum(reached) < 2:
            return None
        X = sub.from_dicts(r["params"] for r in known)
        seed = _seed(self.config.random_state, exp.name, "reach")
        clf = ReachClassifier(sub, random_state=seed).fit(X, reached)
        return {**clf.to_dict(), "run_keys": [r["run_key"] for r in known], "reached": reached}

    def reach_classifiers(self, fits: Mapping[str, dict]) -> dict:
        """``{experiment: ReachClassifier}`` rebuilt from the fit results ``fits`` of the
        experiments whose design has runs that did not reach their responses."""
        out = {}
        for e, fit in fits.items():
            if "reach" not in fit:
                continue
            sub = self.config.experiment_space(e, fit["active"])
            rows = self.store.get_runs(fit["reach"]["run_keys"])
            X = sub.from_dicts(r["params"] for r in rows)
            out[e] = ReachClassifier.from_dict(fit["reach"], sub, X, fit["reach"]["reached"])
        return out

    def optimisation_space(self, names: Sequence[str]) -> ParameterSpace:
        """The optimiser's box: per parameter the intersection of the bounds of every
        experiment that takes it (each surrogate is only trusted inside its own design)."""
        c = self.config
        params = []
        for n in names:
            boxes = [
                c.experiment_space(e.name, [n])[n]
                for e in c.experiments.values()
                if n in e.parameters
            ]
            lo, hi = max(p.lower for p in boxes), min(p.upper for p in boxes)
            params.append(_bounded(c.parameters[n], (lo, hi)))
        return ParameterSpace(params)

    def check(self) -> None:
        """Check the study against its simulators before any run; raises
        :class:`StudyConfigError` naming the field.

        Each experiment's simulator must resolve; where it declares its parameters (name ->
        unit) every listed parameter must be one of them, in the same unit; where it declares
        its setup options and takes ``element_size_mm``, every fidelity level must set it.
        Resolving a simulator may import it (an entry point): this runs in the controlling
        process at run time, never when :mod:`flexparcel.calibration` is imported.
        """
        c = self.config
        for exp in c.experiments.values():
            where = f"{c.path}: [experiments.{exp.name}]"
            try:
                info = get_simulator(exp.simulator, c.simulator_modules)
            except ValueError as exc:
                raise StudyConfigError(f"{where} simulator: {exc}") from None
            if info.parameters:
                for p in exp.parameters:
                    if p not in info.parameters:
                        raise StudyConfigError(
                            f"{where} parameters: {p!r} is not a parameter of simulator "
                            f"'{exp.simulator}' (it takes: "
                            + ", ".join(f"{k} [{u}]" for k, u in info.parameters.items())
                            + ")"
                        )
                    unit, want = c.parameters[p].unit, info.parameters[p]
                    if unit != want:
                        stated = f"'{unit}'" if unit else "not stated"
                        raise StudyConfigError(
                            f"{c.path}: [parameters.{p}] unit: {stated}, but simulator "
                            f"'{exp.simulator}' (experiment '{exp.name}') takes {p} in "
                            f"'{want}'; values are handed over unconverted, so state the "
                            f'bounds in {want} and set unit = "{want}"'
                        )
            if c.fidelity is not None and "element_size_mm" in info.setup:
                for level, setup in c.fidelity.items():
                    if "element_size_mm" not in setup:
                        raise StudyConfigError(
                            f"{c.path}: [fidelity.{level}] setup: element_size_mm missing; "
                            f"simulator '{exp.simulator}' (experiment '{exp.name}') is a "
                            "discretised model and its fidelity levels are its element sizes"
                        )

    def plan(self) -> dict:
        """What a full run of the study would simulate, and what it would cost.

        Per stage and experiment: the runs, the fidelity level, and the cost of one run: the
        median wall time of the store's finished runs of that simulator and setup
        (``"measured"``), else the experiment's ``estimated_run_s`` (``"stated"``), else unknown;
        and how far a campaign has come: ``done`` and ``failed`` among the row's stored design
        points, ``left`` the runs a resume would still make (a design not generated yet is all
        left), with ``left_runs`` and ``left_known_s`` over all rows. Reads the store only if
        it exists (a dry run creates nothing).
        """
        c = self.config
        walls: dict[tuple, list[float]] = {}
        stored: dict[tuple[str, str], list[str]] = {}  # (store stage, experiment) -> statuses
        if self.store_path.exists():
            with StudyStore(self.store_path) as store:
                status = {r["run_key"]: r["status"] for r in store.all_runs()}
                walls = store.wall_times()
                for exp in c.experiments:
                    for st in set(_PLAN_STORE_STAGES.values()):
                        keys = store.design_keys(st, exp)
                        stored[(st, exp)] = [status[k] for k in keys if k in status]

        def progress(stage, exp, level, n):
            """(done, failed) of the row's first ``n`` stored design points."""
            st = _PLAN_STORE_STAGES[(stage, "high" if level == "high" else "low")]
            statuses = stored.get((st, exp.name), [])[:n]
            return statuses.count("done"), statuses.count("failed")

        def cost(exp, level):
            run = {"simulator": exp.simulator, "setup": c.setup_of(exp.name, level)}
            w = walls.get(cost_key(run))
            if w:
                return float(np.median(w)), f"measured ({len(w)} runs in the store)"
            stated = _stated_cost(exp, level)
            if stated is not None:
                return stated, "stated in the study (estimated_run_s)"
            return None, "unknown \u2014 run one"

        low = "low" if c.fidelity is not None else None
        high = "high" if c.fidelity is not None else None
        rows = []
        for exp in c.experiments.values():
            if exp.screening is not None:
                k = len(exp.parameters)
                n = 2**k
                if exp.screening.design == "fractional-factorial":
                    n = 2 ** (k - len(exp.screening.generators))
                what = f"2^{k} full factorial" if n == 2**k else f"2^({k}-"
                if n != 2**k:
                    what += f"{len(exp.screening.generators)}) fractional factorial"
                what += f", ANOVA at alpha = {exp.screening.alpha}"
                rows.append(("screen", exp, low, n, what))
            k_act = str(len(exp.parameters))
            if exp.screening is not None and c.purpose != "design":
                k_act = "screened"
            rows.append(
                ("design", exp, low, exp.design_runs, f"Latin hypercube over {k_act} parameters")
            )
            if c.fidelity is not None:
                rows.append(("design", exp, high, exp.high_runs, "high-fidelity Latin hypercube"))
        if c.validate and "validate" in c.stages:
            for exp in c.experiments.values():
                rows.append(("validate", exp, high, 1, "the simulator at the optimum"))
        out_rows, total, unknown = [], 0.0, 0
        rows.sort(key=lambda r: STAGES.index(r[0]))  # stable: experiments stay in file order
        left_runs, left_s, left_unknown = 0, 0.0, 0
        for stage, exp, level, n, what in rows:
            each, source = cost(exp, level)
            done, failed = progress(stage, exp, level, n)
            left = n - done - failed
            left_runs += left
            if each is None:
                unknown += n
                left_unknown += left
            else:
                total += n * each
                left_s += left * each
            out_rows.append(
                {
                    "stage": stage,
                    "experiment": exp.name,
                    "simulator": exp.simulator,
                    "level": level,
                    "setup": c.setup_of(exp.name, level),
                    "runs": n,
                    "what": what,
                    "run_s": each,
                    "cost_source": source,
                    "total_s": None if each is None else n * each,
                    "done": done,
                    "failed": failed,
                    "left": left,
                }
            )
        workers = self.workers if self.workers else (os.cpu_count() or 1)
        return {
            "study": c.name,
            "rows": out_rows,
            "runs": sum(r["runs"] for r in out_rows),
            "known_s": total,
            "unknown_runs": unknown,
            "left_runs": left_runs,
            "left_known_s": left_s,
            "left_unknown_runs": left_unknown,
            "workers": workers,
            "surrogate": (
                f"GPR, kernel by {c.cv_folds}-fold CV among {', '.join(c.kernels)}, "
                f"{c.holdout_fraction:.0%} hold-out"
                + ("; co-kriging of the low and high levels" if c.fidelity else "")
            )
            if c.purpose != "design"
            else (
                f"GPR contours of each outcome over {' and '.join(c.maps['axes'])} (kernel by "
                "CV over all runs, no hold-out); 0/1 outcomes as maps of the runs"
            ),
            "optimiser": f"Nelder-Mead from {c.opt_starts} starts, weights 1/range (eq. 11)"
            if c.purpose != "design"
            else "none (a design study has no targets)",
        }

    def calibrated_parameters(self) -> list[str]:
        """Parameters the optimiser varies: ``[optimisation].parameters`` or all active ones."""
        c = self.config
        if c.opt_parameters is not None:
            return list(c.opt_parameters)
        names: list[str] = []
        for exp in c.experiments.values():
            fit = self._require("fit", exp.name, "optimise", "fit")
            names += [p for p in fit["active"] if p not in names]
        return [p for p in c.parameters.names if p in names]

    def optimise(self) -> dict:
        """Minimise the weighted error on the surrogates; returns the optimum and predictions."""
        self.check_stages(["optimise"])
        with _blas_threads(self.config.threads):
            return self._optimise()

    def _optimise(self) -> dict:
        c = self.config
        fits = {e: self._require("fit", e, "optimise", "fit") for e in c.experiments}
        surrogates = {e: self._surrogates(c.experiments[e], fits[e]) for e in c.experiments}
        names = self.calibrated_parameters()
        space = self.optimisation_space(names)
        nominal = {p.name: p.nominal_value for p in c.parameters.parameters}
        targets = [t for e in c.experiments.values() for t in e.targets]
        z_target = np.array([t.value for t in targets])
        weights = np.array(
            [
                t.weight
                if t.weight is not None
                else 1.0 / _span(fits[t.experiment]["range"][t.response], t.key)
                for t in targets
            ]
        )
        # Per experiment: columns of its active parameters in the calibrated vector (or the
        # nominal value for an active parameter the user excluded from the optimisation).
        plan = []
        for e, fit in fits.items():
            cols = [names.index(p) if p in names else None for p in fit["active"]]
            own = c.experiment_space(e)
            fixed = np.array([own[p].nominal_value for p in fit["active"]])
            rs = [t.response for t in c.experiments[e].targets]
            plan.append((e, cols, fixed, rs))

        def experiment_point(x, cols, fixed):
            xe = fixed.copy()
            for j, col in enumerate(cols):
                if col is not None:
                    xe[j] = x[col]
            return xe

        reach = self.reach_classifiers(fits)
        p_min = c.min_reach_probability

        def reach_probability(x) -> dict:
            return {
                e: float(reach[e].probability(experiment_point(x, cols, fixed)[None, :])[0])
                for e, cols, fixed, _ in plan
                if e in reach
            }

        def reach_penalty(x) -> float:
            # A quadratic penalty on the shortfall: at REACH_PENALTY = 1e4 a shortfall of
            # 0.01 costs 1, as much as one target missed by its whole design range.
            return REACH_PENALTY * sum(
                max(0.0, p_min - p) ** 2 for p in reach_probability(x).values()
            )

        def predict_all(x, return_std=False):
            preds, stds = [], []
            for e, cols, fixed, rs in plan:
                xe = experiment_point(x, cols, fixed)
                for r in rs:
                    if return_std:
                        m, s = surrogates[e][r].predict(xe[None, :], return_std=True)
                        preds.append(float(m[0]))
                        stds.append(float(s[0]))
                    else:
                        preds.append(float(surrogates[e][r].predict(xe[None, :])[0]))
            return (np.array(preds), np.array(stds)) if return_std else np.array(preds)

        opt = NelderMeadCalibrator(
            n_starts=c.opt_starts,
            maxiter=c.opt_maxiter,
            random_state=_seed(c.random_state, "optimise"),
        ).fit(
            predict_all,
            space,
            z_target,
            weights,
            penalty=reach_penalty if reach and p_min > 0 else None,
        )
        pred, std = predict_all(opt.x_, return_std=True)
        optimum = dict(nominal)
        optimum.update({n: float(v) for n, v in zip(names, opt.x_, strict=True)})
        result = {
            "calibrated": names,
            "optimum": optimum,
            "optimum_unit": {n: float(v) for n, v in zip(names, opt.u_, strict=True)},
            "error": opt.error_,
            "error_check": weighted_error(z_target, pred, weights),
            "min_reach_probability": p_min,
            "reach": {
                e: {
                    "probability": p,
                    "n_reached": reach[e].n_reached_,
                    "n_not_reached": reach[e].n_not_reached_,
                }
                for e, p in reach_probability(opt.x_).items()
            },
            "targets": [
                {
                    "experiment": t.experiment,
                    "response": t.response,
                    "unit": t.unit,
                    "target": t.value,
                    "weight": float(w),
                    "weight_source": "given" if t.weight is not None else "1/range",
                    "predicted": float(p),
                    "std": float(s),
                    "spread": t.spread,
                    # the response's range over the design runs (the high level's with
                    # fidelity levels): a target outside it no parameter set of the design
                    # reached, and the optimum trades it against the others
                    "design_range": fits[t.experiment]["range"][t.response],
                    "in_design_range": _within(t.value, fits[t.experiment]["range"][t.response]),
                }
                for t, w, p, s in zip(targets, weights, pred, std, strict=True)
            ],
            "starts": opt.starts_,
        }
        self.store.put_result("optimise", "", result)
        return result

    def validate(self) -> dict:
        """Re-run every experiment's simulator at the optimum; returns the comparison."""
        self.check_stages(["validate"])
        c = self.config
        opt = self._require("optimise", "", "validate", "optimise")
        batches = []
        for exp in c.experiments.values():
            params = {p: opt["optimum"][p] for p in exp.parameters}
            level = "high" if c.fidelity is not None else None
            keys = self.store.add_design("validation", exp.name, [self._spec(exp, params, level)])
            batches.append((exp, keys))
        self._campaign("validation", batches)
        pred = {(t["experiment"], t["response"]): t for t in opt["targets"]}
        rows_out = []
        for exp, keys in batches:
            run = self.store.get_runs(keys)[0]
            for t in exp.targets:
                p = pred[(exp.name, t.response)]
                sim = run["responses"][t.response] if run["status"] == "done" else None
                rows_out.append(
                    {
                        "experiment": exp.name,
                        "response": t.response,
                        "unit": t.unit,
                        "target": t.value,
                        "predicted": p["predicted"],
                        "std": p["std"],
                        "simulated": sim,
                        "status": run["status"],
                        "error": run["error"] if run["status"] != "done" else None,
                        "wall_s": run["wall_s"],
                        "run_key": run["run_key"],
                        "within_spread": (
                            None
                            if t.spread is None or sim is None
                            else bool(abs(sim - t.value) <= t.spread)
                        ),
                    }
                )
        result = {"rows": rows_out, "optimum": opt["optimum"]}
        self.store.put_result("validation", "", result)
        return result

    def report(self) -> Path:
        """Write ``results.json``, ``summary.json`` and ``report.html`` into the output
        folder; returns the HTML."""
        from flexparcel.calibration.report import write_report
        from flexparcel.calibration.summary import write_summary

        with _blas_threads(self.config.threads):
            if self.config.purpose == "design":
                from flexparcel.calibration.design_report import write_design_report

                return write_design_report(self)
            write_summary(self)
            return write_report(self)

    def reset(self, stage: str) -> None:
        """Forget a stage's design points and results and those of all later stages.

        Simulated runs stay in the store and are reused where a redone design hits them again.
        """
        if stage not in STAGES:
            raise ValueError(f"unknown stage {stage!r}; stages: {', '.join(STAGES)}")
        names = {
            "screen": ("screening", "screening"),
            "design": ("design", "design"),
            "fit": (None, "fit"),
            "optimise": (None, "optimise"),
            "validate": ("validation", "validation"),
            "report": (None, None),
        }
        for s in STAGES[STAGES.index(stage) :]:
            design, result = names[s]
            if design:
                self.store.delete_design(design)
                if design == "design":
                    self.store.delete_design("design-high")
            if result:
                self.store.delete_results(result)

    def run(self, stages: Sequence[str] | None = None) -> dict:
        """Run ``stages`` (default: all of the study's, :attr:`StudyConfig.stages`) in pipeline
        order; returns ``{stage: result}``."""
        own = self.config.stages
        stages = own if stages is None else stages
        unknown = [s for s in stages if s not in STAGES]
        if unknown:
            raise ValueError(f"unknown stage {unknown[0]!r}; stages: {', '.join(STAGES)}")
        self.check_stages(stages)
        self.check()
        out = {}
        for s in own:
            if s not in stages:
                continue
            if s == "validate" and not self.config.validate:
                continue
            out[s] = getattr(self, s)()
        return out

    def check_stages(self, stages: Sequence[str]) -> None:
        """Refuse, naming the study's purpose, a stage that does not apply to it (a design
        study has no targets to fit, optimise or validate)."""
        foreign = [s for s in stages if s not in self.config.stages]
        if foreign:
            raise StudyConfigError(
                f"{self.config.path}: stage '{foreign[0]}' does not apply to a "
                f"{self.config.purpose} study (purpose = '{self.config.purpose}'); its stages "
                f"are {', '.join(self.config.stages)}"
            )


def _within(value: float, rng: Sequence[float]) -> bool:
    return float(rng[0]) <= value <= float(rng[1])


def _span(rng: Sequence[float], key: str) -> float:
    span = float(rng[1]) - float(rng[0])
    if not span > 0:
        raise ValueError(
            f"target {key}: the response does not vary over its design, so its default weight "
            "1/range is undefined; give a weight in the study file"
        )
    return span
