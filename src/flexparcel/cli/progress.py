"""A dependency-free progress line: simulated time, wall time and ETA on stderr."""

from __future__ import annotations

import sys
import time

__all__ = ["ProgressLine", "PhaseLine"]


class ProgressLine:
    """Callable ``(t, t_end)`` for :func:`flexparcel.simulate`; prints at most every 0.5 s."""

    def __init__(self, label: str, stream=None, enabled: bool = True) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.start = time.perf_counter()
        self._last = 0.0
        self._open = False  # a line is printed and not yet ended

    def __call__(self, t: float, t_end: float) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < 0.5 and t < t_end:
            return
        self._last = now
        wall = now - self.start
        frac = min(1.0, t / t_end) if t_end > 0 else 1.0
        eta = wall * (1.0 - frac) / frac if frac > 0 else float("nan")
        bar = "#" * int(30 * frac)
        self.stream.write(
            f"\r{self.label} [{bar:<30}] t = {t:.4f}/{t_end:g} s  "
            f"wall {wall:6.1f} s  ETA {eta:6.1f} s"
        )
        self._open = t < t_end
        if not self._open:
            self.stream.write("\n")
        self.stream.flush()

    def done(self) -> None:
        """End the line if the last call did not (the run stopped short of ``t_end`` by
        round-off, or failed)."""
        if self.enabled and self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False


class PhaseLine:
    """Callable ``(phase, t)`` for :func:`flexparcel.consignments.assembly.assemble`: the
    phase, simulated time and wall time on stderr, at most every 0.5 s. No ETA: the assembly
    ends when the packaging is open and then at rest, which is not known in advance."""

    def __init__(self, label: str, stream=None, enabled: bool = True) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.start = time.perf_counter()
        self._last = 0.0
        self._printed = False

    def __call__(self, phase: str, t: float) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < 0.5:
            return
        self._last = now
        self._printed = True
        self.stream.write(
            f"\r{self.label}: {phase:<9} t = {t:.4f} s  wall {now - self.start:6.1f} s   "
        )
        self.stream.flush()

    def done(self) -> None:
        """End the line (after the last call)."""
        if self.enabled and self._printed:
            self.stream.write(f"\n{self.label}: done in {time.perf_counter() - self.start:.1f} s\n")
            self.stream.flush()
