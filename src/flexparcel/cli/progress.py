"""Progress bars (tqdm) for the command line's long loops, with an honest ETA.

The ETA comes from this process's own progress in simulated time: the rate is measured over a
moving window of wall time (:class:`RateWindow`), starting at the first step this process
made, so a resumed run does not count the simulated time done before it was interrupted. The
window ends *now*, not at the last step: while one step is stuck (Newton iterations, step
halvings) the rate falls and the ETA grows, and the bar says how long no step has finished. A
background thread redraws the bar every second for that.

:class:`SimulationProgress` is the ``progress(t, t_end)`` callable of
:func:`flexparcel.simulate` and the scenarios; :class:`PhaseProgress` the ``progress(phase,
t)`` callable of :func:`flexparcel.consignments.assembly.assemble`, with an ETA per phase (the
latest end of each phase from the assembly settings). :func:`kernel_cache_is_cold` and
:func:`announce_compilation` tell a user that the first run compiles the numba kernels.

tqdm comes with the ``io`` extra; without it the bars are left out (the runs are the same).
"""

from __future__ import annotations

import math
import os
import re
import sys
import threading
import time
from collections import deque
from pathlib import Path

__all__ = [
    "RateWindow",
    "SimulationProgress",
    "PhaseProgress",
    "ProgressLine",
    "format_duration",
    "kernel_cache_is_cold",
    "cold_kernels",
    "compile_minutes",
    "announce_compilation",
]

WINDOW_S = 30.0
"""Length of the moving window of wall time the rate is measured over [s]."""
STUCK_S = 5.0
"""A step that has not finished after this long [s] is shown as such."""


def format_duration(seconds: float | None) -> str:
    """``75`` -> ``"1:15"``, ``3725`` -> ``"1:02:05"``; None or not finite -> ``"?"``."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0:
        return "?"
    s = int(round(seconds))
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


class RateWindow:
    """Simulated time per wall second over the last ``window_s`` seconds of wall time.

    :meth:`add` records ``(wall, t)`` after each step; :meth:`rate` at wall time ``now`` is
    ``(t_last - t_base) / (now - wall_base)`` with the base the newest sample at least
    ``window_s`` old (else the first one). Ending at ``now`` (not at the last step) makes a
    stuck step lower the rate at once. The first sample is the first step this process made,
    so time simulated before (a resumed checkpoint) never counts.
    """

    def __init__(self, window_s: float = WINDOW_S, min_gap_s: float = 0.1) -> None:
        self.window_s = float(window_s)
        self.min_gap_s = float(min_gap_s)
        self._samples: deque[tuple[float, float]] = deque()
        self.last: tuple[float, float] | None = None
        """The latest ``(wall, t)``."""

    def add(self, wall: float, t: float) -> None:
        self.last = (wall, t)
        if not self._samples or wall - self._samples[-1][0] >= self.min_gap_s:
            self._samples.append((wall, t))
        # keep one sample at or before the window's start as its base
        while len(self._samples) >= 3 and self._samples[1][0] <= wall - self.window_s:
            self._samples.popleft()

    def rate(self, now: float) -> float | None:
        """Simulated seconds per wall second, or None before two samples or without
        progress."""
        if self.last is None:
            return None
        base = self._samples[0]
        for w, t in self._samples:
            if w <= now - self.window_s:
                base = (w, t)
        if base[0] >= self.last[0]:  # the base is the last step: take the one before it
            older = [s for s in self._samples if s[0] < self.last[0]]
            if not older:
                return None
            base = older[-1]
        dt_wall = now - base[0]
        dt_sim = self.last[1] - base[1]
        if dt_wall <= 0 or dt_sim <= 0:
            return None
        return dt_sim / dt_wall

    def eta(self, t_end: float, now: float) -> float | None:
        """Wall seconds to ``t_end`` at :meth:`rate`, or None when unknown."""
        r = self.rate(now)
        if r is None or self.last is None:
            return None
        return max(0.0, t_end - self.last[1]) / r

    def idle(self, now: float) -> float:
        """Wall seconds since the last step (0 before the first)."""
        return 0.0 if self.last is None else max(0.0, now - self.last[0])


def _tqdm():
    try:
        from tqdm import tqdm
    except ModuleNotFoundError:
        return None
    return tqdm


class _Bar:
    """A tqdm bar over simulated time [s] with the ETA of a :class:`RateWindow`, redrawn
    every ``refresh_s`` by a daemon thread while it is open. The bar opens at the first
    update (an unused one prints nothing) and ends when ``t`` reaches ``t_end``; a later
    update (the next segment of a run) opens a new one."""

    _FORMAT = "{desc}: {percentage:3.0f}%|{bar:20}| {postfix}"

    def __init__(self, label: str, *, enabled: bool = True, file=None, refresh_s: float = 1.0,
                 window_s: float = WINDOW_S, clock=time.perf_counter) -> None:  # fmt: skip
        self.label = label
        self.desc = label
        self.clock = clock
        self.window = RateWindow(window_s)
        self.start = clock()
        self.t_end = 0.0
        self.eta_prefix = ""  # "<= " where the end is an upper bound
        self.file = file
        self.refresh_s = float(refresh_s)
        self._tqdm = _tqdm() if enabled else None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._closed = False
        self.bar = None

    @property
    def enabled(self) -> bool:
        """Whether bars are drawn (not with ``enabled=False`` nor without tqdm)."""
        return self._tqdm is not None

    def status(self, now: float | None = None) -> str:
        """The text after the bar: simulated time, wall time, ETA (and a stuck step)."""
        now = self.clock() if now is None else now
        w = self.window
        t = w.last[1] if w.last is not None else 0.0
        eta = w.eta(self.t_end, now)
        if w.last is not None and t >= self.t_end:
            eta = 0.0
        parts = [f"t = {t:.4f}/{self.t_end:.4g} s", f"wall {format_duration(now - self.start)}",
                 f"ETA {self.eta_prefix}{format_duration(eta)}"]  # fmt: skip
        idle = w.idle(now)
        if idle >= STUCK_S and t < self.t_end:
            parts.append(f"step running for {format_duration(idle)}")
        return ", ".join(parts)

    def _open(self) -> None:
        """A new tqdm bar and its redraw thread (the lock held)."""
        self.bar = self._tqdm(total=1.0, desc=self.desc, file=self.file or sys.stderr,
                              bar_format=self._FORMAT, leave=True, dynamic_ncols=True)  # fmt: skip
        self._stop = threading.Event()
        if self.refresh_s > 0:
            threading.Thread(target=self._refresh_loop, args=(self._stop, self.refresh_s),
                             daemon=True).start()  # fmt: skip

    def _end(self) -> None:
        """End the open bar, leaving its last line (the lock held)."""
        self._stop.set()
        if self.bar is not None:
            self.bar.set_postfix_str(self.status(), refresh=False)
            self.bar.close()
            self.bar = None

    def update(self, t: float, t_end: float) -> None:
        with self._lock:
            now = self.clock()
            self.window.add(now, float(t))
            self.t_end = float(t_end)
            if self._tqdm is None or self._closed:
                return
            if self.bar is None:
                self._open()
            self.bar.total = max(self.t_end, 1e-12)
            self.bar.n = min(max(float(t), 0.0), self.bar.total)
            self.bar.set_postfix_str(self.status(now), refresh=False)
            self.bar.refresh()
            if t >= self.t_end - 1e-9 * max(1.0, abs(self.t_end)):
                self._end()

    def _refresh_loop(self, stop: threading.Event, every: float) -> None:
        while not stop.wait(every):
            with self._lock:
                if stop.is_set() or self.bar is None:
                    return
                self.bar.set_postfix_str(self.status(), refresh=False)
                self.bar.refresh()

    def set_description(self, desc: str) -> None:
        """Name the next bar ``desc`` (ends the open one: one line per phase)."""
        with self._lock:
            self._end()
            self.desc = desc

    def close(self) -> None:
        """End the bar for good (idempotent; a run that ends short of ``t_end`` or fails)."""
        with self._lock:
            self._end()
            self._closed = True


class SimulationProgress(_Bar):
    """The ``progress(t, t_end)`` callable of :func:`flexparcel.simulate` and the scenarios:
    a tqdm bar over simulated time with the ETA of this process's own progress. Call
    :meth:`done` (or use it as a context manager) when the run ends or fails."""

    def __call__(self, t: float, t_end: float) -> None:
        self.update(t, t_end)

    def done(self) -> None:
        self.close()

    def __enter__(self) -> SimulationProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


ProgressLine = SimulationProgress
"""The former name (a hand-written line), kept for callers outside the command line."""


class PhaseProgress(_Bar):
    """The ``progress(phase, t)`` callable of
    :func:`flexparcel.consignments.assembly.assemble`: a bar per phase with its ETA.

    The end of a phase is not known in advance (the packaging is open, then at rest, when it
    is), so each bar runs to the phase's latest end from ``settings``
    (:class:`~flexparcel.consignments.assembly.AssemblySettings`) and its ETA reads "<=":
    opening until ``max_opening_time``; settling until ``max_settle_time`` after the closing.
    The closing reports at every step (it is one chunk that took 20 min for KP at 10 mm, with
    no sign of life before); its bar shows the time reached, its end being the assembly's.
    """

    def __init__(self, label: str, *, settings=None, enabled: bool = True, **kwargs) -> None:
        super().__init__(label, enabled=enabled, **kwargs)
        if settings is None:
            from flexparcel.consignments.assembly import AssemblySettings

            settings = AssemblySettings()
        self.settings = settings
        self.phase = None
        self.eta_prefix = "<= "
        self._closed_at = 0.0

    def _phase_end(self, phase: str, t: float) -> float:
        st = self.settings
        if phase == "opening":
            return max(t, float(st.max_opening_time))
        if phase == "settling":
            return max(t, self._closed_at + float(st.max_settle_time))
        return t  # closing: the time reached (its last call is its end)

    def __call__(self, phase: str, t: float) -> None:
        if phase == "closing":
            self._closed_at = float(t)  # the closing's end: the settling's deadline follows
        if phase != self.phase:
            self.phase = phase
            self.set_description(f"{self.label} {phase}")
        self.update(t, self._phase_end(phase, t))

    def done(self) -> None:
        self.close()


# ------------------------------------------------------------------ first run: numba compiles
SECONDS_PER_KERNEL = 6.5
"""Compile time of one cached numba kernel [s]: a first ``flexparcel assemble BW
--element-size 25`` on an empty cache compiled 59 of the 95 kernels in about 6.5 min (one
core shared with other work)."""
USED_FRACTION = 0.6
"""The share of the cold kernels a first run compiles (59 of 95 for an assembly); the others
compile when a later run first needs them."""

_KERNEL_RE = re.compile(r"cache\s*=\s*True[^\n]*\n(?:[ \t]*@[^\n]*\n)*[ \t]*def\s+(\w+)")


def _package_dir() -> Path:
    import flexparcel

    return Path(flexparcel.__file__).resolve().parent


def _index_files(module: Path) -> set[str]:
    """Names of the numba index files (``*.nbi``) of ``module``: in ``__pycache__`` next to
    it, or under ``NUMBA_CACHE_DIR`` when that is set."""
    cache_dir = os.environ.get("NUMBA_CACHE_DIR")
    if cache_dir:
        found = Path(cache_dir).rglob(f"{module.stem}.*.nbi")
    else:
        found = (module.parent / "__pycache__").glob(f"{module.stem}.*.nbi")
    return {p.name for p in found}


def cold_kernels(package: Path | None = None) -> tuple[int, int]:
    """``(uncompiled, total)``: the numba kernels declared with ``cache=True`` in the
    package's modules, and how many of them have no index file (``*.nbi``) in numba's disk
    cache, i.e. compile on their first call."""
    root = package or _package_dir()
    cold = total = 0
    for module in sorted(root.rglob("*.py")):
        try:
            text = module.read_text(encoding="utf-8")
        except OSError:
            continue
        if "cache=True" not in text and "cache = True" not in text:
            continue
        names = _KERNEL_RE.findall(text)
        index = _index_files(module)
        for name in names:
            total += 1
            if not any(n.startswith(f"{module.stem}.{name}-") for n in index):
                cold += 1
    return cold, total


def kernel_cache_is_cold(package: Path | None = None) -> bool:
    """True when at least a quarter of the package's cached kernels are not compiled yet
    (a first run, a new flexparcel version, or a removed cache)."""
    cold, total = cold_kernels(package)
    return total > 0 and cold >= max(1, total // 4)


def compile_minutes(cold: int) -> int:
    """Rough minutes a run spends compiling when ``cold`` kernels are not cached (at least
    1): the share :data:`USED_FRACTION` of them at :data:`SECONDS_PER_KERNEL` each."""
    return max(1, round(cold * USED_FRACTION * SECONDS_PER_KERNEL / 60.0))


def announce_compilation(file=None) -> bool:
    """Print "compiling kernels (first run, about N min) ..." on ``file`` (stdout, with the
    other progress messages: stderr carries a failed command's one error line) when the
    kernel cache is cold; returns whether it did."""
    try:
        cold, total = cold_kernels()
    except OSError:
        return False
    if total == 0 or cold < max(1, total // 4):
        return False
    stream = file or sys.stdout
    stream.write(
        f"compiling kernels (first run, about {compile_minutes(cold)} min; {cold} of {total} "
        "numba kernels are not in the disk cache yet, later runs start at once) ...\n"
    )
    stream.flush()
    return True
