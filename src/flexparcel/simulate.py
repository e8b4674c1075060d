"""The time loop: one call runs a model from its initial (or a given) state to ``t_end``.

Steps land exactly on output times and on load-schedule breakpoints; a recorder keeps node
positions, rotation vectors, velocities and energies at the output times.
"""

from __future__ import annotations

import json
import time as _time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from flexparcel.elements.rotations import rotation_vectors
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.dynamic import GeneralizedAlpha, IntegratorOptions
from flexparcel.io.checkpoint import (
    CHECKPOINT_FORMAT,
    CHECKPOINT_VERSION,
    MONITORED_FRAME_KEY,
    CheckpointError,
    RunCheckpoint,
    check_same_run,
    load_checkpoint,
    model_fingerprint,
    save_checkpoint,
    state_fingerprint,
)
from flexparcel.model.model import Model, State

__all__ = [
    "SimulationResult",
    "FrameRecorder",
    "Stepper",
    "ModelStepper",
    "simulate",
    "state_energies",
    "output_times",
]


@dataclass
class SimulationResult:
    """Recorded time series of a run (SI units)."""

    time: np.ndarray
    """Output times [s], shape (k,)."""
    positions: np.ndarray
    """Node positions [m], shape (k, node_count, 3)."""
    rotation_vectors: np.ndarray
    """Nodal rotation vectors [rad], shape (k, node_count, 3)."""
    velocities: np.ndarray
    """Node velocities [m/s] and angular velocities [rad/s], shape (k, node_count, 6)."""
    energies: dict[str, np.ndarray]
    """``kinetic``, ``strain``, ``gravity`` (potential, 0 at the reference), ``total`` [J]."""
    final_state: State
    stats: dict = field(default_factory=dict)
    """Step counts, Newton iterations, factorisations and wall time per phase [s]."""
    monitored_impulses: np.ndarray | None = None
    """Impulse [N s] the monitored contact sets
    (:meth:`~flexparcel.builder.model_builder.ModelBuilder.monitored_contacts`) exerted on
    each node from the start of the run to each frame, shape (k, node_count, 3); None when
    the model monitors no contact. Its difference between two frames over their time apart
    is the mean force over that interval (:meth:`mean_monitored_forces`)."""

    @property
    def displacements(self) -> np.ndarray:
        """Displacements from the first recorded frame [m], shape (k, node_count, 3)."""
        return self.positions - self.positions[0]

    def mean_monitored_forces(self, nodes: np.ndarray | None = None) -> np.ndarray:
        """Mean force [N] of the monitored contacts on ``nodes`` (default all) over each
        output interval, summed over those nodes, shape (k - 1, 3): the impulse between
        frames i and i + 1 over their time apart. Unlike a sample of the contact force at
        a frame, it does not depend on when the steps fall or on the contact's stiffness
        spikes: it is the load a force gauge averaging over ``dt_out`` would read."""
        if self.monitored_impulses is None:
            raise ValueError("mean_monitored_forces: the model monitors no contact")
        imp = self.monitored_impulses if nodes is None else self.monitored_impulses[:, nodes]
        total = imp.sum(axis=1)
        return np.diff(total, axis=0) / np.diff(self.time)[:, None]


def state_energies(model: Model, state: State) -> tuple[float, float, float]:
    """(kinetic, strain, gravity potential) energy [J] of ``state``; gravity's is zero in the
    reference configuration."""
    _, strain = asm.internal_forces(
        model, state.positions, state.rotations, np.zeros_like(state.velocities)
    )
    kin = asm.kinetic_energy(model, state.velocities, state.rotations)
    grav = -float(np.sum(model.mass[:, :3] * model.gravity * (state.positions - model.positions0)))
    return kin, strain, grav


def output_times(t0: float, t_end: float, dt_out: float) -> np.ndarray:
    """Output times [s] after ``t0``: every ``dt_out`` and ``t_end`` itself."""
    n_out = int(np.floor((t_end - t0) / dt_out + 1e-9))
    out = t0 + dt_out * np.arange(1, n_out + 1)
    if out.size == 0 or out[-1] < t_end - 1e-12:
        out = np.append(out, t_end)
    return out


class FrameRecorder:
    """The output frames of a run of ``model``: time, positions, rotation vectors,
    velocities and energies (:func:`state_energies`) at each recorded state."""

    def __init__(self, model: Model) -> None:
        self.model = model
        self._t, self._x, self._r, self._v, self._e = [], [], [], [], []
        # impulses of the monitored contacts, or None where the model monitors none
        self._imp = [] if model.has_monitored_contact else None

    def record(self, st: State, impulse: np.ndarray | None = None) -> None:
        """Record ``st``; ``impulse``: the monitored contacts' impulse on each node so far
        (n, 3), required when the model monitors contacts."""
        if self._imp is not None:
            if impulse is None:
                raise ValueError("FrameRecorder: the model monitors contacts, give the impulse")
            self._imp.append(np.array(impulse, dtype=float))
        self._t.append(st.time)
        self._x.append(st.positions.copy())
        self._r.append(rotation_vectors(st.rotations))
        self._v.append(st.velocities.copy())
        self._e.append(state_energies(self.model, st))

    def extend(self, frames: dict[str, np.ndarray]) -> None:
        """Append the frames of a checkpoint (:meth:`frames`'s layout)."""
        if self._imp is not None:
            if MONITORED_FRAME_KEY not in frames:
                raise ValueError(
                    "the checkpoint's frames hold no monitored contact impulses (written "
                    "before they were recorded); remove it to start the run over"
                )
            self._imp.extend(frames[MONITORED_FRAME_KEY])
        self._t.extend(frames["time"].tolist())
        self._x.extend(frames["positions"])
        self._r.extend(frames["rotation_vectors"])
        self._v.extend(frames["velocities"])
        self._e.extend(tuple(e) for e in frames["energies"].tolist())

    def frames(self) -> dict[str, np.ndarray]:
        """The frames as arrays: ``time`` (k,), ``positions`` (k, n, 3), ``rotation_vectors``
        (k, n, 3), ``velocities`` (k, n, 6), ``energies`` (k, 3) [J], and where the model
        monitors contacts ``monitored_impulses`` (k, n, 3) [N s]."""
        out = {
            "time": np.array(self._t), "positions": np.array(self._x),
            "rotation_vectors": np.array(self._r), "velocities": np.array(self._v),
            "energies": np.array(self._e),
        }  # fmt: skip
        if self._imp is not None:
            out[MONITORED_FRAME_KEY] = np.array(self._imp).reshape(-1, self.model.node_count, 3)
        return out

    def result(self, final_state: State, stats: dict) -> SimulationResult:
        f = self.frames()
        e = f["energies"]
        return SimulationResult(
            time=f["time"],
            positions=f["positions"],
            rotation_vectors=f["rotation_vectors"],
            velocities=f["velocities"],
            energies={
                "kinetic": e[:, 0],
                "strain": e[:, 1],
                "gravity": e[:, 2],
                "total": e.sum(axis=1),
            },  # fmt: skip
            final_state=final_state,
            stats=stats,
            monitored_impulses=f.get(MONITORED_FRAME_KEY),
        )


class Stepper(ABC):
    """What :func:`simulate` drives from output frame to output frame. The time loop owns the
    output grid, the recorder, the checkpoint (save and resume) and progress; a stepper owns
    how a state gets from one output time to the next.

    :class:`ModelStepper` steps one model with :class:`GeneralizedAlpha`; the conveyor's
    group-by-group integration (:mod:`flexparcel.scenarios.conveyor_groups`) is another.
    """

    mode: str = "stepper"
    """Name written to the checkpoint header: a checkpoint resumes only with its own mode."""

    @abstractmethod
    def options_header(self) -> dict:
        """JSON-able settings that define the run (written to and checked in checkpoints)."""

    @abstractmethod
    def begin(self, state: State) -> State:
        """Prepare to integrate from ``state`` (consistent accelerations); returns it."""

    @abstractmethod
    def advance(self, state: State, t_out: float, progress) -> State:
        """Integrate ``state`` to ``t_out`` [s], calling ``progress(t, t_out)`` (if given) at
        least once, when ``t_out`` is reached."""

    def after_frame(self, state: State, index: int) -> None:  # noqa: B027 (optional)
        """Called after frame ``index`` (counted from this call of simulate) was recorded."""

    def monitored_impulse(self) -> np.ndarray | None:
        """Impulse [N s] of the model's monitored contacts on each node since the start,
        (n, 3), or None where it monitors none."""
        return None

    @abstractmethod
    def history(self) -> dict[str, np.ndarray]:
        """Arrays that make a resumed run continue exactly (see :meth:`resume`)."""

    @abstractmethod
    def resume(self, state: State, history: dict[str, np.ndarray]) -> State:
        """Continue from a checkpoint's ``state`` and :meth:`history`; returns the state."""

    @abstractmethod
    def statistics(self) -> dict:
        """Step counts, iterations and wall time per phase [s] so far."""

    def close(self) -> None:  # noqa: B027 (optional)
        """Release workers and files; called once, also when the run fails."""


class ModelStepper(Stepper):
    """One model, one :class:`GeneralizedAlpha`; steps land on the load and gravity schedules'
    breakpoints."""

    mode = "one-model"

    def __init__(self, model: Model, options: IntegratorOptions | None = None) -> None:
        self.integrator = GeneralizedAlpha(model, options)
        self._last: State | None = None  # the state the last advance() returned
        self._breaks = sorted(
            {float(b) for sch in model.schedules for b in sch.breakpoints()}
            | {float(b) for b in model.gravity_schedule.breakpoints()}
        )

    def options_header(self) -> dict:
        return json.loads(json.dumps(asdict(self.integrator.opt)))

    def begin(self, state: State) -> State:
        if self._continues(state):
            # the state this stepper stopped at: go on with the scheme's own accelerations.
            # Consistent ones, M a = f_ext - f_int, would reset the generalised-alpha filter:
            # a film's unresolved membrane modes come back into a, the error estimate sees
            # them as an acceleration jump and the steps collapse (KP's opening at 10 mm in
            # 5 ms simulate() chunks: 132 steps for 15 ms against 8 in one call, the same
            # clearance to 0.01 mm)
            state.accelerations[:] = self._last.accelerations
            return state
        self.integrator.initialize(state)
        return state

    def _continues(self, state: State) -> bool:
        """Whether ``state`` is the one the last :meth:`advance` returned."""
        last = self._last
        return (
            last is not None
            and state.time == last.time
            and np.array_equal(state.positions, last.positions)
            and np.array_equal(state.rotations, last.rotations)
            and np.array_equal(state.velocities, last.velocities)
        )

    def advance(self, state: State, t_out: float, progress) -> State:
        s = state
        while s.time < t_out - 1e-12 * max(1.0, abs(t_out)):
            nxt = [b for b in self._breaks if s.time + 1e-12 < b < t_out]
            s = self.integrator.step(s, nxt[0] if nxt else t_out)
            if progress is not None:
                progress(s.time, t_out)
        self._last = s.copy()
        return s

    def history(self) -> dict[str, np.ndarray]:
        return self.integrator.history()

    def resume(self, state: State, history: dict[str, np.ndarray]) -> State:
        self.integrator.restore_history(history)
        self._last = state.copy()  # a later begin() on it goes on, as after advance()
        return state

    def statistics(self) -> dict:
        return asdict(self.integrator.stats)

    def monitored_impulse(self) -> np.ndarray | None:
        return self.integrator.monitored_impulse


def simulate(
    model: Model,
    t_end: float,
    *,
    dt_out: float | None = None,
    options: IntegratorOptions | None = None,
    state: State | None = None,
    progress: Callable[[float, float], None] | None = None,
    checkpoint: str | Path | None = None,
    checkpoint_interval_s: float = 60.0,
    checkpoint_only: bool = False,
    stepper: Stepper | None = None,
) -> SimulationResult:
    """Integrate ``model`` from ``state`` (default: at rest in the reference configuration)
    to ``t_end`` [s], recording every ``dt_out`` [s] (default ``t_end / 200``).

    ``stepper``: how the state gets from frame to frame (default: :class:`ModelStepper` of
    ``model`` with ``options``); this is the only time loop of flexparcel, the conveyor's
    group-by-group integration is a stepper too. The stepper is closed at the end.

    ``checkpoint``: a ``.npz`` path (:mod:`flexparcel.io.checkpoint`). The run writes it at an
    output frame whenever ``checkpoint_interval_s`` [s] of wall time have passed since the
    last write (0: every frame), and at the end. If the file exists when the call starts, the
    run resumes from it -- after checking that it was written for the same model, initial
    state, times and options -- and a complete checkpoint is returned without stepping.
    ``checkpoint_only``: return what the checkpoint holds so far (frames, state, statistics)
    without stepping, e.g. to look at a run that another process is still computing.

    Raises :class:`flexparcel.ConvergenceError` (naming time, step and worst node) if a step
    cannot be completed even at the minimum step size; nothing non-finite is ever recorded.
    """
    if not (np.isfinite(t_end) and t_end > 0):
        raise ValueError(f"simulate: t_end must be > 0 s, got {t_end!r}")
    s = state.copy() if state is not None else model.initial_state()
    t0 = s.time
    if not t_end > t0:
        raise ValueError(f"simulate: t_end = {t_end} s must be after the state's time {t0} s")
    dt_out = (t_end - t0) / 200.0 if dt_out is None else float(dt_out)
    if not (np.isfinite(dt_out) and dt_out > 0):
        raise ValueError(f"simulate: dt_out must be > 0 s, got {dt_out!r}")
    if not (np.isfinite(checkpoint_interval_s) and checkpoint_interval_s >= 0):
        raise ValueError(
            f"simulate: checkpoint_interval_s must be >= 0 s, got {checkpoint_interval_s!r}"
        )
    if checkpoint_only and checkpoint is None:
        raise ValueError("simulate: checkpoint_only needs a checkpoint path")
    stepper = stepper or ModelStepper(model, options)
    try:
        return _run(model, s, t_end, dt_out, stepper, progress, checkpoint,
                    checkpoint_interval_s, checkpoint_only)  # fmt: skip
    finally:
        stepper.close()


def _run(model, s, t_end, dt_out, stepper, progress, checkpoint, interval, checkpoint_only):
    """The loop of :func:`simulate` (its arguments checked)."""
    t0 = s.time
    header = None
    resumed = None
    if checkpoint is not None:
        header = {
            "format": CHECKPOINT_FORMAT,
            "version": CHECKPOINT_VERSION,
            "t0": float(t0),
            "t_end": float(t_end),
            "dt_out": dt_out,
            "node_count": model.node_count,
            "model": model_fingerprint(model),
            "initial_state": state_fingerprint(s),
            "options": stepper.options_header(),
            "mode": stepper.mode,
        }
        if checkpoint_only and not Path(checkpoint).exists():
            raise FileNotFoundError(f"simulate: no checkpoint {checkpoint} to read")
        if Path(checkpoint).exists():
            resumed = load_checkpoint(checkpoint)
            check_same_run(
                checkpoint, resumed.header, {k: v for k, v in header.items() if k != "version"}
            )
    wall0 = _time.perf_counter()
    out_times = output_times(t0, t_end, dt_out)
    rec = FrameRecorder(model)
    wall_before = 0.0  # wall time of the run before it was resumed
    if resumed is None:
        s = stepper.begin(s)
        rec.record(s, stepper.monitored_impulse())
    else:
        try:
            rec.extend(resumed.frames)
            s = stepper.resume(resumed.state, resumed.history)
        except ValueError as exc:  # e.g. written before its monitored contacts were recorded
            raise CheckpointError(f"checkpoint {checkpoint}: {exc}") from None
        wall_before = float(resumed.history.get("wall_total", 0.0))
        out_times = out_times[out_times > s.time + 1e-12 * max(1.0, abs(s.time))]
        if checkpoint_only:
            out_times = out_times[:0]

    def save(complete: bool) -> None:
        hist = stepper.history()
        hist["wall_total"] = np.array(wall_before + _time.perf_counter() - wall0)
        save_checkpoint(
            checkpoint, RunCheckpoint({**header, "complete": complete}, rec.frames(), s, hist)
        )

    step_progress = None if progress is None else (lambda t, _t_out: progress(t, t_end))
    last_save = _time.perf_counter()
    for i, t_out in enumerate(out_times):
        s = stepper.advance(s, t_out, step_progress)
        s.time = float(t_out)  # remove round-off drift so outputs sit on the grid
        rec.record(s, stepper.monitored_impulse())
        stepper.after_frame(s, i)
        if checkpoint is not None and t_out != out_times[-1]:
            if _time.perf_counter() - last_save >= interval:
                save(complete=False)
                last_save = _time.perf_counter()
    if (
        checkpoint is not None
        and not checkpoint_only
        and not (resumed is not None and resumed.header.get("complete"))
    ):
        save(complete=True)
    wall = wall_before + _time.perf_counter() - wall0
    st = stepper.statistics()
    st.setdefault("wall_s", {})["total"] = wall
    st["dof_count"] = model.dof_count
    st["simulated_s"] = float(t_end - t0)
    return rec.result(s, st)
