"""Calibration parameters, the parameter space and measured targets.

Three coordinate systems are used throughout :mod:`flexparcel.calibration`:

* **physical** values in the parameter's own unit (e.g. MPa, N/mm, s), what simulators receive;
* **unit** coordinates ``u`` in ``[0, 1]``, linear in the parameter's scale (``log`` parameters
  are mapped through ``log(x)``), used by Latin hypercubes, surrogates and the optimiser;
* **coded** coordinates ``x = 2 u - 1`` in ``[-1, 1]``, used by two-level factorial designs and the
  screening ANOVA (``-1`` = lower bound, ``+1`` = upper bound).

Units are carried as labels only: the calibration layer never converts them, it hands the
physical numbers to the simulator exactly as the study states them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Parameter", "ParameterSpace", "Target"]

_SCALES = ("linear", "log")


@dataclass(frozen=True)
class Parameter:
    """One model parameter to be screened or calibrated.

    Parameters
    ----------
    name:
        Identifier passed to the simulator (a key of its parameter mapping).
    lower, upper:
        Bounds in the physical unit, ``lower < upper`` (and ``lower > 0`` for ``scale="log"``).
    unit:
        Unit label, e.g. ``"MPa"``; informative only.
    scale:
        ``"linear"`` or ``"log"``; a log parameter is sampled and optimised uniformly in
        ``log(value)`` (use it for quantities spanning decades, such as a damping coefficient).
    nominal:
        Value [unit] used when the parameter is frozen (not significant in screening, or not
        calibrated). ``None`` means the midpoint of the range in the parameter's scale.
    description:
        Free text for reports.
    """

    name: str
    lower: float
    upper: float
    unit: str = ""
    scale: str = "linear"
    nominal: float | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if not self.name or not isinstance(self.name, str):
            raise ValueError("parameter name must be a non-empty string")
        for label, value in (("lower", self.lower), ("upper", self.upper)):
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"parameter '{self.name}': {label} bound must be a finite number")
        if not self.lower < self.upper:
            raise ValueError(
                f"parameter '{self.name}': bounds must satisfy lower < upper, "
                f"got [{self.lower}, {self.upper}]"
            )
        if self.scale not in _SCALES:
            raise ValueError(
                f"parameter '{self.name}': scale must be one of {_SCALES}, got {self.scale!r}"
            )
        if self.scale == "log" and self.lower <= 0.0:
            raise ValueError(
                f"parameter '{self.name}': a log-scale parameter needs lower > 0, got {self.lower}"
            )
        if self.nominal is not None and not (self.lower <= self.nominal <= self.upper):
            raise ValueError(
                f"parameter '{self.name}': nominal {self.nominal} lies outside "
                f"[{self.lower}, {self.upper}]"
            )

    @property
    def nominal_value(self) -> float:
        """Frozen value [unit]: ``nominal``, else the range's midpoint in the parameter's scale."""
        if self.nominal is not None:
            return float(self.nominal)
        return float(self.from_unit(0.5))

    def to_unit(self, value):
        """Map physical value(s) [unit] to unit coordinates in ``[0, 1]`` (not clipped)."""
        v = np.asarray(value, dtype=float)
        if self.scale == "log":
            lo, hi = math.log(self.lower), math.log(self.upper)
            return (np.log(v) - lo) / (hi - lo)
        return (v - self.lower) / (self.upper - self.lower)

    def from_unit(self, u):
        """Map unit coordinate(s) in ``[0, 1]`` to physical value(s) [unit]."""
        u = np.asarray(u, dtype=float)
        if self.scale == "log":
            lo, hi = math.log(self.lower), math.log(self.upper)
            return np.exp(lo + u * (hi - lo))
        return self.lower + u * (self.upper - self.lower)


@dataclass(frozen=True)
class ParameterSpace:
    """An ordered set of :class:`Parameter` objects; the columns of every design matrix.

    Arrays of points have shape ``(n_points, n_parameters)`` with columns in :attr:`names` order.
    """

    parameters: tuple[Parameter, ...]

    def __init__(self, parameters: Iterable[Parameter]):
        params = tuple(parameters)
        names = [p.name for p in params]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"duplicate parameter name(s): {', '.join(duplicates)}")
        object.__setattr__(self, "parameters", params)

    @property
    def names(self) -> list[str]:
        """Parameter names in column order."""
        return [p.name for p in self.parameters]

    @property
    def dim(self) -> int:
        """Number of parameters."""
        return len(self.parameters)

    def __len__(self) -> int:
        return len(self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"unknown parameter {name!r}; known: {', '.join(self.names)}")

    def __contains__(self, name: object) -> bool:
        return any(p.name == name for p in self.parameters)

    def subspace(self, names: Sequence[str]) -> ParameterSpace:
        """The parameters called ``names``, in that order."""
        return ParameterSpace(self[n] for n in names)

    @property
    def lower(self) -> np.ndarray:
        """Lower bounds [units], shape (n_parameters,)."""
        return np.array([p.lower for p in self.parameters])

    @property
    def upper(self) -> np.ndarray:
        """Upper bounds [units], shape (n_parameters,)."""
        return np.array([p.upper for p in self.parameters])

    @property
    def nominal(self) -> np.ndarray:
        """Frozen values [units], shape (n_parameters,)."""
        return np.array([p.nominal_value for p in self.parameters])

    def to_unit(self, X) -> np.ndarray:
        """Physical points, shape (n, d), to unit coordinates, shape (n, d)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        self._check_width(X)
        return np.column_stack([p.to_unit(X[:, j]) for j, p in enumerate(self.parameters)])

    def from_unit(self, U) -> np.ndarray:
        """Unit coordinates, shape (n, d), to physical points, shape (n, d)."""
        U = np.atleast_2d(np.asarray(U, dtype=float))
        self._check_width(U)
        return np.column_stack([p.from_unit(U[:, j]) for j, p in enumerate(self.parameters)])

    def from_coded(self, C) -> np.ndarray:
        """Coded points in ``[-1, 1]``, shape (n, d), to physical points, shape (n, d)."""
        return self.from_unit((np.asarray(C, dtype=float) + 1.0) / 2.0)

    def to_coded(self, X) -> np.ndarray:
        """Physical points, shape (n, d), to coded coordinates ``2 u - 1``, shape (n, d)."""
        return 2.0 * self.to_unit(X) - 1.0

    def as_dicts(self, X) -> list[dict[str, float]]:
        """Physical points, shape (n, d), as ``{name: value}`` mappings (what simulators get)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        self._check_width(X)
        return [{n: float(v) for n, v in zip(self.names, row, strict=True)} for row in X]

    def from_dicts(self, rows: Iterable[Mapping[str, float]]) -> np.ndarray:
        """``{name: value}`` mappings to physical points, shape (n, d), in column order."""
        out = [[float(row[n]) for n in self.names] for row in rows]
        return np.asarray(out, dtype=float).reshape(-1, self.dim)

    def _check_width(self, X: np.ndarray) -> None:
        if X.shape[1] != self.dim:
            raise ValueError(
                f"points have {X.shape[1]} columns, the space has {self.dim} parameters "
                f"({', '.join(self.names)})"
            )


@dataclass(frozen=True)
class Target:
    """A measured value of one response of one experiment.

    Parameters
    ----------
    experiment, response:
        Which experiment (e.g. ``"swing"``) and which of its named responses
        (e.g. ``"first_swing_mm"``).
    value:
        The measured value, in the response's unit.
    weight:
        Weight ``w_i`` in ``sum_i (w_i (Z_target,i - Z_pred,i))**2`` [1/unit]. ``None`` means
        the paper's default, ``1 / (max - min)`` of the response over the design runs; 0
        leaves the target out of the objective (still fitted, reported and validated), e.g.
        for a target no run of the design comes near, which 1/range would let set the optimum.
    spread:
        Optional measurement spread (e.g. a standard deviation of repeated tests) [unit]; the
        report flags validation runs that miss the target by more than it.
    unit:
        Unit label of the response; informative only.
    transform, log_offset:
        How the surrogate models the response: ``"none"``, or ``"log"`` for
        ``log(y + log_offset)`` (a response spanning decades or approaching zero). The
        optimisation and the report stay in the response's own units.
    label:
        Name of the response in ``summary.json``. Default: ``response``, or
        ``experiment.response`` where two experiments target the same response (the drops'
        ``rebound_mm``).
    reference:
        A published model's value of the response (the paper's Table 7), reported next to the
        validation run; informative only, never fitted.
    """

    experiment: str
    response: str
    value: float
    weight: float | None = None
    spread: float | None = None
    unit: str = ""
    transform: str = "none"
    log_offset: float = 0.0
    label: str | None = None
    reference: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.value, (int, float)) or not math.isfinite(self.value):
            raise ValueError(
                f"target {self.experiment}.{self.response}: value must be a finite number"
            )
        if self.weight is not None and not (math.isfinite(self.weight) and self.weight >= 0):
            raise ValueError(
                f"target {self.experiment}.{self.response}: weight must be a number >= 0 "
                "(0: reported and validated, not fitted)"
            )
        if self.spread is not None and not (math.isfinite(self.spread) and self.spread >= 0):
            raise ValueError(
                f"target {self.experiment}.{self.response}: spread must be a number >= 0"
            )
        if self.transform not in ("none", "log"):
            raise ValueError(
                f"target {self.experiment}.{self.response}: transform must be 'none' or 'log', "
                f"got {self.transform!r}"
            )
        if not (math.isfinite(self.log_offset) and self.log_offset >= 0):
            raise ValueError(
                f"target {self.experiment}.{self.response}: log_offset must be a number >= 0"
            )
        if self.reference is not None and not math.isfinite(self.reference):
            raise ValueError(
                f"target {self.experiment}.{self.response}: reference must be a finite number"
            )

    @property
    def key(self) -> str:
        """``"experiment.response"``."""
        return f"{self.experiment}.{self.response}"
