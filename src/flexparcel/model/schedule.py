"""Time schedules that scale loads: piecewise-linear factor(t)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Schedule"]


@dataclass(frozen=True)
class Schedule:
    """Load factor as a piecewise-linear function of time [s]; constant beyond the ends.

    ``Schedule.constant()`` (the default for every load) is 1 at all times.
    """

    times: tuple[float, ...] = (0.0,)
    factors: tuple[float, ...] = (1.0,)

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        f = np.asarray(self.factors, dtype=float)
        if t.ndim != 1 or t.shape != f.shape or t.size == 0:
            raise ValueError("Schedule.times and Schedule.factors must be 1-D of equal length >= 1")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f))):
            raise ValueError("Schedule.times and Schedule.factors must be finite")
        if np.any(np.diff(t) <= 0):
            raise ValueError("Schedule.times must be strictly increasing")

    @classmethod
    def constant(cls, value: float = 1.0) -> Schedule:
        return cls((0.0,), (float(value),))

    @classmethod
    def ramp_hold_release(
        cls, ramp: float, hold: float = np.inf, release: float = 0.0, start: float = 0.0
    ) -> Schedule:
        """0 at ``start``, ramps linearly to 1 over ``ramp`` s, holds ``hold`` s, then goes back
        to 0 over ``release`` s (a step if 0). Durations [s]."""
        for name, v in (("ramp", ramp), ("hold", hold), ("release", release)):
            if v < 0:
                raise ValueError(f"Schedule.{name} must be >= 0 s, got {v!r}")
        t = [start, start + max(ramp, 1e-12)]
        f = [0.0, 1.0]
        if np.isfinite(hold):
            t += [t[-1] + hold, t[-1] + hold + max(release, 1e-12)]
            f += [1.0, 0.0]
        return cls(tuple(t), tuple(f))

    def __call__(self, t: float) -> float:
        return float(np.interp(t, self.times, self.factors))

    def integral(self, t: float) -> float:
        """Integral of the factor from 0 to ``t`` [s] (exact for the piecewise-linear factor,
        constant beyond the ends, negative for t < 0)."""
        knots = np.asarray(self.times, dtype=float)
        lo, hi = (0.0, float(t)) if t >= 0.0 else (float(t), 0.0)
        inner = knots[(knots > lo) & (knots < hi)]
        x = np.concatenate([[lo], inner, [hi]])
        f = np.interp(x, knots, np.asarray(self.factors, dtype=float))
        area = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))
        return area if t >= 0.0 else -area

    def breakpoints(self) -> np.ndarray:
        """Times [s] where the factor changes slope (the time loop steps onto them)."""
        return np.asarray(self.times, dtype=float)
