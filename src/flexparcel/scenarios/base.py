"""The Scenario protocol: what every scenario (swing test, drop tests, conveyor, or one of a
third party) offers to the command line, the benchmarks and the calibration.

A scenario

* has a ``name`` (its registry key, :mod:`flexparcel.scenarios.registry`) and a
  ``description``;
* declares its ``parameters`` (:class:`Parameter`: name, unit, default, allowed range,
  description), in the units a user states them in (the paper's Table 3 units for the
  consignment tests: MPa, s, N/mm, Ns/mm); :meth:`Scenario.resolve` checks given values
  against them, with errors that name the field and the allowed range, and fills in the
  defaults;
* builds its model from resolved parameters and the consignment snapshot(s)
  (:meth:`Scenario.build`; the element size is the snapshot's);
* runs (:meth:`Scenario.run`) into a :class:`ScenarioResult`, which records the wall time;
* reports named scalar responses with units (:meth:`Scenario.responses` ->
  :class:`Response`); a response the run did not reach (no second swing within the
  simulated time, no exit from the belt) has ``value=None`` and a note saying why, never 0
  or NaN;
* writes the files a user opens (:meth:`Scenario.write`: ``responses.json``, the recorded
  results and ParaView files) into a directory; pictures are drawn by a
  :data:`PictureWriter` the caller passes in (``flexparcel.viz.scenario_pictures`` has those
  of the built-ins), because no physics module imports the plotting layer.

Scenario-specific settings that are not parameters (drop height, clamp length, layout,
worker processes) are keyword options of the scenario's factory, see
:func:`flexparcel.scenarios.registry.get_scenario`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from flexparcel.consignments.build import ConsignmentBuild
    from flexparcel.consignments.snapshot import Snapshot
    from flexparcel.simulate import SimulationResult

__all__ = [
    "CHECKPOINT_FILE",
    "Parameter",
    "Response",
    "ScenarioResult",
    "Scenario",
    "ScenarioBase",
    "PictureWriter",
    "T_END",
    "resolve_parameters",
    "split_assignment",
    "single_snapshot",
    "write_json",
]


@dataclass(frozen=True)
class Parameter:
    """A scalar input of a scenario, in the unit ``unit`` a user states it in.

    ``default``: the value when none is given; None means "the consignment's or scene's own"
    (e.g. the packaging's Young's modulus), which the scenario fills in. Allowed: ``low`` to
    ``high`` (``math.inf`` for no upper bound), each end excluded where ``low_open`` /
    ``high_open``; ``integer``: whole numbers only.
    """

    name: str
    unit: str
    default: float | None
    low: float
    high: float
    description: str
    low_open: bool = False
    high_open: bool = False
    integer: bool = False

    def range_text(self) -> str:
        """The allowed range as a phrase, e.g. ``"in (0, 10] s"`` or ``"> 0 MPa"``."""
        unit = f" {self.unit}" if self.unit else ""
        if math.isinf(self.high):
            return f"{'>' if self.low_open else '>='} {self.low:g}{unit}"
        lo = "(" if self.low_open else "["
        hi = ")" if self.high_open else "]"
        return f"in {lo}{self.low:g}, {self.high:g}{hi}{unit}"

    def check(self, value: object, label: str | None = None) -> float:
        """``value`` as a number within the allowed range (an ``int`` for integer
        parameters); else ``ValueError`` naming ``label`` (default: the name) and the range."""
        label = label or self.name
        kind = "an integer " if self.integer else ""
        if isinstance(value, bool):  # True is an int to Python, never a parameter value
            raise ValueError(f"{label} must be {kind}{self.range_text()}, got {value!r}")
        try:
            v = float(value)  # type: ignore[arg-type]
        except (TypeError, ValueError):
            raise ValueError(f"{label}: {value!r} is not a number") from None
        shown = f"{v:g}" if math.isfinite(v) else repr(value)
        ok = math.isfinite(v) and (v > self.low if self.low_open else v >= self.low)
        ok = ok and (v < self.high if self.high_open else v <= self.high)
        if self.integer and ok and v != int(v):
            ok = False
        if not ok:
            raise ValueError(f"{label} must be {kind}{self.range_text()}, got {shown}")
        return int(v) if self.integer else v

    def to_dict(self) -> dict:
        """JSON-ready description (``high`` is None for no upper bound)."""
        return {
            "name": self.name, "unit": self.unit, "default": self.default, "low": self.low,
            "high": None if math.isinf(self.high) else self.high, "low_open": self.low_open,
            "high_open": self.high_open, "integer": self.integer,
            "description": self.description,
        }  # fmt: skip


T_END = Parameter("t_end", "s", None, 0.0, 10.0, "simulated time", low_open=True)
"""The simulated time every scenario's ``run`` takes (its default is the scenario's own)."""

CHECKPOINT_FILE = "checkpoint.npz"
"""Name of the checkpoint a run in a directory (``flexparcel run ... --out DIR``) saves
itself to and resumes from."""


@dataclass(frozen=True)
class Response:
    """A named scalar response of a run: ``value`` in ``unit``, or None where the run did not
    reach it (``note`` then says why; a missing response is never reported as 0 or NaN)."""

    value: float | None
    unit: str
    description: str
    note: str = ""

    def __post_init__(self) -> None:
        if self.value is None:
            if not self.note:
                raise ValueError(f"response {self.description!r}: not reached needs a note why")
            return
        v = float(self.value)
        if not math.isfinite(v):
            raise ValueError(
                f"response {self.description!r} is {v}; use value=None with a note instead"
            )
        object.__setattr__(self, "value", v)

    @property
    def reached(self) -> bool:
        """Whether the run reached this response (``value`` is a number)."""
        return self.value is not None

    def to_dict(self) -> dict:
        """JSON-ready copy."""
        out = {"value": self.value, "unit": self.unit, "description": self.description}
        if self.note:
            out["note"] = self.note
        return out

    def format(self, digits: int = 2) -> str:
        """``"12.34 mm"`` or ``"not reached (why)"``."""
        if self.value is None:
            return f"not reached ({self.note})"
        return f"{self.value:.{digits}f} {self.unit}".rstrip()


@dataclass
class ScenarioResult:
    """A finished scenario run."""

    scenario: str
    """The scenario's name."""
    parameters: dict[str, float | None]
    """The resolved parameters, in their declared units."""
    simulation: SimulationResult
    """The recorded frames (time [s] (k,), positions [m] (k, n, 3), ...)."""
    wall_s: float
    """Wall time of the time integration [s] (model building and files not included)."""
    record: Any = None
    """The scenario's own record of the run (e.g. a TestRun or a ConveyorRun)."""
    settings: dict[str, Any] = field(default_factory=dict)
    """JSON-ready run settings that are not parameters (simulated time, drop height, ...)."""


PictureWriter = Callable[[ScenarioResult, Path], Mapping[str, Path]]
"""Draws the pictures of a result into a directory; returns name -> path."""


@runtime_checkable
class Scenario(Protocol):
    """What a scenario offers (see the module docstring). :class:`ScenarioBase` implements
    :meth:`resolve` from :attr:`parameters`; the rest is the scenario's own."""

    name: str
    description: str
    parameters: tuple[Parameter, ...]

    def resolve(
        self,
        values: Mapping[str, object] | Sequence[str] | None = None,
        build: ConsignmentBuild | None = None,
    ) -> dict[str, float | None]:
        """All parameters: ``values`` (a mapping, or ``"name=value"`` strings) checked, the
        others at their defaults (those that depend on the consignment taken from ``build``
        where given). Unknown names and values out of range raise ``ValueError``."""
        ...

    def build(self, consignment: Snapshot | Mapping[str, Snapshot],
              parameters: Mapping[str, float | None]) -> Any:  # fmt: skip
        """The scenario's model (and what it needs to run it) from resolved ``parameters``
        and the consignment snapshot(s)."""
        ...

    def run(
        self,
        consignment: Snapshot | Mapping[str, Snapshot],
        parameters: Mapping[str, object] | None = None,
        *,
        t_end: float | None = None,
        progress: Any = None,
    ) -> ScenarioResult:
        """Build and simulate for ``t_end`` [s] (None: the scenario's default);
        ``parameters`` are resolved first. ``progress(t, t_end)`` is called as it goes."""
        ...

    def responses(self, result: ScenarioResult) -> dict[str, Response]:
        """Named scalar responses with units."""
        ...

    def write(self, result: ScenarioResult, out_dir: str | Path, *,
              extra: Mapping[str, Any] | None = None,
              pictures: PictureWriter | None = None) -> dict[str, Path]:  # fmt: skip
        """Write ``responses.json`` (with ``extra`` merged in), the scenario's result files
        and, where given, ``pictures(result, out_dir)`` into ``out_dir``; returns name ->
        path, ``"json"`` first. ``responses.json`` is written first (the numbers survive a
        failing picture) and again at the end with the list of files."""
        ...


class ScenarioBase:
    """Shared parts of a scenario: :meth:`resolve` from :attr:`parameters` and
    :meth:`defaults`, and :meth:`parameter` lookup by name."""

    name: str = ""
    description: str = ""
    parameters: tuple[Parameter, ...] = ()

    def defaults(self, build: ConsignmentBuild | None = None) -> dict[str, float | None]:
        """Default values; override where they depend on the consignment ``build``."""
        return {p.name: p.default for p in self.parameters}

    def parameter(self, name: str) -> Parameter:
        """The declared parameter ``name`` (``ValueError`` listing the known ones)."""
        for p in self.parameters:
            if p.name == name:
                return p
        known = ", ".join(p.name for p in self.parameters) or "none"
        raise ValueError(f"unknown parameter {name!r} of {self.name}; settable: {known}")

    def resolve(
        self,
        values: Mapping[str, object] | Sequence[str] | None = None,
        build: ConsignmentBuild | None = None,
    ) -> dict[str, float | None]:
        return resolve_parameters(self.parameters, values, self.defaults(build))


def split_assignment(text: str) -> tuple[str, str]:
    """``"name=value"`` -> ``(name, value)``, stripped; ``ValueError`` without ``=``."""
    if "=" not in text:
        raise ValueError(f"expected name=value, got {text!r}")
    k, v = text.split("=", 1)
    return k.strip(), v.strip()


def resolve_parameters(
    declared: Sequence[Parameter],
    values: Mapping[str, object] | Sequence[str] | None,
    defaults: Mapping[str, float | None] | None = None,
) -> dict[str, float | None]:
    """``defaults`` (else each parameter's own) overridden by ``values`` (a mapping or
    ``"name=value"`` strings), each checked by :meth:`Parameter.check`. A given None keeps the
    default. Unknown names raise ``ValueError`` listing the settable ones."""
    by_name = {p.name: p for p in declared}
    out = {p.name: p.default for p in declared}
    out.update(defaults or {})
    if values is None:
        return out
    items = values.items() if isinstance(values, Mapping) else map(split_assignment, values)
    for name, value in items:
        if name not in by_name:
            raise ValueError(f"unknown parameter {name!r}; settable: {', '.join(by_name)}")
        if value is not None:
            out[name] = by_name[name].check(value)
    return out


def single_snapshot(consignment: Snapshot | Mapping[str, Snapshot], scenario: str) -> Snapshot:
    """The one snapshot of a single-consignment scenario (a mapping must hold exactly one)."""
    if isinstance(consignment, Mapping):
        if len(consignment) != 1:
            raise ValueError(
                f"{scenario} runs on one consignment, got {len(consignment)}: "
                f"{', '.join(consignment)}"
            )
        return next(iter(consignment.values()))
    return consignment


def write_json(path: str | Path, data: Mapping) -> Path:
    """Write ``data`` as indented JSON (numpy scalars as floats), atomically."""
    from flexparcel.io.atomic import write_atomic

    return write_atomic(Path(path), json.dumps(data, indent=2, default=float) + "\n")
