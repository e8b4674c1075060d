"""A dependency-free progress line: simulated time, wall time and ETA on stderr."""

from __future__ import annotations

import sys
import time


class ProgressLine:
    """Callable ``(t, t_end)`` for :func:`flexparcel.simulate`; prints at most every 0.5 s."""

    def __init__(self, label: str, stream=None, enabled: bool = True) -> None:
        self.label = label
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.start = time.perf_counter()
        self._last = 0.0

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
        if t >= t_end:
            self.stream.write("\n")
        self.stream.flush()
