"""Simulator registry, and an analytic test simulator with known truth.

A study names its simulator (``simulator = "analytic"`` in study.toml); the name is resolved in
this registry, in the controlling process and again in every worker process, so no callable is
ever pickled or evaluated from text. A simulator is any function

    simulator(params: dict[str, float], **setup) -> dict[str, float]

taking the physical parameter values (in the units the study states) and the experiment's fixed
``setup`` options, and returning named scalar responses. Simulators register themselves with
:func:`register_simulator` when their module is imported. A name that is not registered yet is
looked up by importing the study's ``simulator_modules`` and then the entry points of the group
``flexparcel.simulators`` (an entry point names a module that registers simulators on import, or
a callable that is registered under the entry point's name). This is how the physics scenarios
plug in without the calibration layer importing any finite-element code.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

__all__ = [
    "SimulatorInfo",
    "register_simulator",
    "get_simulator",
    "available_simulators",
    "analytic",
    "ANALYTIC_PARAMETERS",
    "ANALYTIC_RESPONSES",
]

ENTRY_POINT_GROUP = "flexparcel.simulators"


@dataclass(frozen=True)
class SimulatorInfo:
    """A registered simulator: its function, a version string and the responses it returns."""

    name: str
    func: Callable[..., Mapping[str, float]]
    version: str = "1"
    responses: tuple[str, ...] = ()
    description: str = ""
    #: Parameter name -> unit the simulator takes (empty: not declared, nothing is checked).
    parameters: Mapping[str, str] = field(default_factory=dict)
    #: Setup options it accepts (empty: not declared).
    setup: tuple[str, ...] = ()


_REGISTRY: dict[str, SimulatorInfo] = {}


def register_simulator(
    name: str,
    *,
    version: str = "1",
    responses: Iterable[str] = (),
    description: str = "",
    replace: bool = False,
    parameters: Mapping[str, str] | None = None,
    setup: Iterable[str] = (),
):
    """Decorator registering ``func`` as simulator ``name``.

    ``version`` enters the run hash: bump it when the simulator's results change, so the study
    store does not reuse stale runs. ``parameters`` (name -> unit) and ``setup`` (option names),
    where given, let a study be checked before any run: an unknown parameter, a parameter in
    another unit, or a fidelity level without the element size is refused by name.
    """

    def deco(func):
        if name in _REGISTRY and not replace and _REGISTRY[name].func is not func:
            raise ValueError(f"a simulator named {name!r} is already registered")
        _REGISTRY[name] = SimulatorInfo(
            name,
            func,
            str(version),
            tuple(responses),
            description or (func.__doc__ or ""),
            dict(parameters or {}),
            tuple(setup),
        )
        return func

    return deco


def _register_callable(name: str, obj) -> None:
    """Register a plain callable under ``name``; its ``simulator_version``,
    ``simulator_responses``, ``simulator_parameters`` (name -> unit) and ``simulator_setup``
    attributes, where set, give the version, the responses, the parameters and the setup."""
    if not callable(obj):
        raise ValueError(f"simulator {name!r}: {obj!r} is not callable")
    register_simulator(
        name,
        version=str(getattr(obj, "simulator_version", "1")),
        responses=tuple(getattr(obj, "simulator_responses", ())),
        parameters=dict(getattr(obj, "simulator_parameters", {}) or {}),
        setup=tuple(getattr(obj, "simulator_setup", ()) or ()),
    )(obj)


def _load_entry_points(name: str) -> None:
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        if ep.name != name:
            continue
        obj = ep.load()  # importing a module registers its simulators
        if callable(obj) and name not in _REGISTRY:
            _register_callable(name, obj)


def _load_reference(name: str) -> None:
    """Register ``module:function`` or ``/path/FILE.py:function`` under that very name (a
    study may name its simulator so, without a wrapper module on PYTHONPATH). A file is the
    user's own Python module, imported like one."""
    target, _, attr = name.rpartition(":")
    try:
        if target.endswith(".py"):
            from importlib import util as import_util

            digest = hashlib.sha256(target.encode()).hexdigest()[:12]
            spec = import_util.spec_from_file_location(f"_flexparcel_study_{digest}", target)
            if spec is None or not os.path.isfile(target):
                raise ImportError(f"no file {target}")
            module = import_util.module_from_spec(spec)
            spec.loader.exec_module(module)
        else:
            module = importlib.import_module(target)
    except ImportError as exc:
        raise ValueError(f"simulator {name!r}: cannot import {target!r}: {exc}") from exc
    if not hasattr(module, attr):
        raise ValueError(f"simulator {name!r}: {target!r} has no {attr!r}")
    _register_callable(name, getattr(module, attr))


def get_simulator(name: str, modules: Iterable[str] = ()) -> SimulatorInfo:
    """The simulator registered as ``name``; imports ``modules`` and entry points if needed."""
    if name in _REGISTRY:
        return _REGISTRY[name]
    for module in modules:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ValueError(f"simulator module {module!r} cannot be imported: {exc}") from exc
        if name in _REGISTRY:
            return _REGISTRY[name]
    if ":" in name:
        _load_reference(name)
        return _REGISTRY[name]
    _load_entry_points(name)
    if name in _REGISTRY:
        return _REGISTRY[name]
    raise ValueError(
        f"unknown simulator {name!r}; registered: {', '.join(sorted(_REGISTRY)) or 'none'} "
        "(a simulator registers itself with flexparcel.calibration.register_simulator when its "
        "module is imported; list that module in the study's simulator_modules, or name it "
        "as 'module:function' or 'FILE.py:function')"
    )


def available_simulators() -> list[str]:
    """Names of the simulators registered so far."""
    return sorted(_REGISTRY)


# -- analytic test simulator -------------------------------------------------------------------

#: Parameters of :func:`analytic`: name -> (lower, upper, unit, scale). The functions are written
#: in unit coordinates of these ranges (the KP/BW ranges of the paper's Table 5, plus two inert
#: parameters).
ANALYTIC_PARAMETERS: dict[str, tuple[float, float, str, str]] = {
    "youngs_modulus": (200.0, 2000.0, "MPa", "log"),
    "damping_ratio": (1e-4, 5e-3, "s", "linear"),
    "contact_stiffness": (100.0, 1000.0, "N/mm", "linear"),
    "contact_damping": (0.1, 1.0, "Ns/mm", "linear"),
    "friction": (0.1, 0.6, "-", "linear"),  # deliberately inert
    "label_mass": (0.0, 20.0, "g", "linear"),  # deliberately inert
}

#: Responses of :func:`analytic` per ``mode``, with the scale of its deterministic noise.
ANALYTIC_RESPONSES: dict[str, dict[str, float]] = {
    "swing": {"first_swing_mm": 70.0, "second_swing_mm": 80.0},
    "drop": {"rebound_mm": 10.0, "peak_force_N": 200.0},
}


def _unit(name: str, value: float) -> float:
    lo, hi, _, scale = ANALYTIC_PARAMETERS[name]
    if scale == "log":
        return math.log(value / lo) / math.log(hi / lo)
    return (value - lo) / (hi - lo)


def _jitter(params: Mapping[str, float], tag: str) -> float:
    """Deterministic pseudo-random number in [-1, 1] from the parameter values and a tag.

    Derived from SHA-256 (not Python's salted ``hash``), so every process and machine agrees.
    """
    text = json.dumps({"p": {k: repr(float(v)) for k, v in sorted(params.items())}, "t": tag})
    h = int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "big")
    return 2.0 * (h / 2.0**64) - 1.0


def _log_line(path: str, text: str) -> None:
    # One O_APPEND write per line: concurrent workers never interleave within a line.
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, (text + "\n").encode())
    finally:
        os.close(fd)


_REQUIRED = {
    "swing": ("youngs_modulus", "damping_ratio"),
    "drop": ("youngs_modulus", "contact_stiffness", "contact_damping"),
}


def _truth(params: Mapping[str, float], mode: str) -> dict[str, float]:
    missing = [p for p in _REQUIRED[mode] if p not in params]
    if missing:
        raise ValueError(f"analytic ({mode}): missing parameter(s) {', '.join(missing)}")
    if mode == "swing":
        uE = _unit("youngs_modulus", params["youngs_modulus"])
        ub = _unit("damping_ratio", params["damping_ratio"])
        first = 60.0 + 90.0 * math.exp(-1.2 * uE) * (1.0 - 0.25 * ub)
        second = first * math.exp(-(0.4 + 2.0 * ub) * (1.3 - 0.5 * uE))
        return {"first_swing_mm": first, "second_swing_mm": second}
    uE = _unit("youngs_modulus", params["youngs_modulus"])
    uk = _unit("contact_stiffness", params["contact_stiffness"])
    uc = _unit("contact_damping", params["contact_damping"])
    # Products of the three active factors: besides main effects and two-factor interactions
    # they carry a three-factor interaction, which a screening ANOVA pools into its error term.
    rebound = 3.0 + 10.0 * (0.3 + 0.7 * uk) * math.exp(-1.5 * uc) * (0.6 + 0.4 * uE)
    force = 40.0 + 200.0 * math.sqrt(0.2 + 0.8 * uk) * (1.0 + 0.6 * uc) * (0.8 + 0.2 * uE)
    return {"rebound_mm": rebound, "peak_force_N": force}


@register_simulator(
    "analytic",
    version="1",
    responses=[r for rs in ANALYTIC_RESPONSES.values() for r in rs],
    description="closed-form toy consignment with known truth (tests and examples)",
    parameters={n: v[2] for n, v in ANALYTIC_PARAMETERS.items()},
    setup=(
        "mode",
        "noise",
        "element_size_mm",
        "delay_s",
        "log_file",
        "fail_first_dir",
        "crash_first_dir",
    ),
)
def analytic(
    params: Mapping[str, float],
    *,
    mode: str = "swing",
    noise: float = 0.003,
    element_size_mm: float | None = None,
    delay_s: float = 0.0,
    log_file: str | None = None,
    fail_first_dir: str | None = None,
    crash_first_dir: str | None = None,
) -> dict[str, float]:
    """Closed-form stand-in for the paper's KP/BW tests, with known truth.

    ``mode="swing"``: ``first_swing_mm``, ``second_swing_mm`` depend on ``youngs_modulus`` and
    ``damping_ratio`` only. ``mode="drop"``: ``rebound_mm`` and ``peak_force_N`` depend on
    ``youngs_modulus``, ``contact_stiffness`` and ``contact_damping`` only. ``friction`` and
    ``label_mass`` (and, for the drop, ``damping_ratio``) are accepted but inert: a screening
    must find them insignificant. Parameters are in the units of :data:`ANALYTIC_PARAMETERS`.

    ``element_size_mm`` mimics a discretisation with a known bias (the low-fidelity level of a
    multi-fidelity study): at 10 mm, or when not given, the responses are the ones above; at
    ``h`` mm each response ``y`` becomes ``y * (1 - 0.05 e) * (1 + 0.1 e (u - 0.5))`` with
    ``e = (h - 10) / 10`` and ``u`` the unit coordinate of ``youngs_modulus`` (a coarser mesh
    is stiffer, the more so the stiffer the material). Signs are kept, and the levels are
    related as ``y_high = y_low * g(u)``: in log scale exactly the autoregressive structure of
    Kennedy & O'Hagan (2000) with rho = 1 and a smooth discrepancy.

    Each response gets deterministic "noise" ``noise * scale * z`` with ``z`` in [-1, 1] a hash
    of all parameter values and ``scale`` from :data:`ANALYTIC_RESPONSES` (it mimics the
    discretisation jitter of a real simulation: same inputs, same output).

    Test hooks: ``delay_s`` sleeps that long [s]; ``log_file`` gets a ``start`` and an ``end``
    line per call (parameter digest and time); with ``fail_first_dir`` the first call at each
    parameter point raises (a marker file in that directory records it), later ones succeed;
    ``crash_first_dir`` likewise, but the first call kills its process (``os._exit``), as a
    segfaulting solver would.
    """
    if mode not in ANALYTIC_RESPONSES:
        raise ValueError(f"analytic: mode must be one of {sorted(ANALYTIC_RESPONSES)}, got {mode}")
    unknown = sorted(set(params) - set(ANALYTIC_PARAMETERS))
    if unknown:
        raise ValueError(f"analytic: unknown parameter(s) {', '.join(unknown)}")
    digest = hashlib.sha256(
        json.dumps({k: repr(float(v)) for k, v in sorted(params.items())}).encode()
    ).hexdigest()[:16]
    if log_file:
        _log_line(log_file, f"start {digest} {time.time():.6f}")
    if fail_first_dir:
        marker = os.path.join(fail_first_dir, f"{mode}-{digest}")
        if not os.path.exists(marker):
            open(marker, "w").close()
            raise RuntimeError(f"analytic: deliberate first-attempt failure at {digest}")
    if crash_first_dir:
        marker = os.path.join(crash_first_dir, f"{mode}-{digest}")
        if not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(70)
    if delay_s > 0:
        time.sleep(delay_s)
    truth = _truth(params, mode)
    if element_size_mm is not None and float(element_size_mm) != 10.0:
        e = (float(element_size_mm) - 10.0) / 10.0
        uE = _unit("youngs_modulus", params["youngs_modulus"])
        factor = (1.0 - 0.05 * e) * (1.0 + 0.1 * e * (uE - 0.5))
        truth = {r: v * factor for r, v in truth.items()}
    out = {
        r: v + noise * ANALYTIC_RESPONSES[mode][r] * _jitter(params, f"{mode}.{r}")
        for r, v in truth.items()
    }
    if log_file:
        _log_line(log_file, f"end {digest} {time.time():.6f}")
    return out
