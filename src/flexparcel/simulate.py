"""The time loop: one call runs a model from its initial (or a given) state to ``t_end``.

Steps land exactly on output times and on load-schedule breakpoints; a recorder keeps node
positions, rotation vectors, velocities and energies at the output times.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from flexparcel.elements.rotations import rotation_vectors
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.dynamic import GeneralizedAlpha, IntegratorOptions
from flexparcel.model.builder import Model, State

__all__ = ["SimulationResult", "simulate"]


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

    @property
    def displacements(self) -> np.ndarray:
        """Displacements from the first recorded frame [m], shape (k, node_count, 3)."""
        return self.positions - self.positions[0]


def _energies(model: Model, state: State) -> tuple[float, float, float]:
    _, strain = asm.internal_forces(
        model, state.positions, state.rotations, np.zeros_like(state.velocities)
    )
    kin = asm.kinetic_energy(model, state.velocities, state.rotations)
    grav = -float(np.sum(model.mass[:, :3] * model.gravity * (state.positions - model.positions0)))
    return kin, strain, grav


def simulate(
    model: Model,
    t_end: float,
    *,
    dt_out: float | None = None,
    options: IntegratorOptions | None = None,
    state: State | None = None,
    progress: Callable[[float, float], None] | None = None,
) -> SimulationResult:
    """Integrate ``model`` from ``state`` (default: at rest in the reference configuration)
    to ``t_end`` [s], recording every ``dt_out`` [s] (default ``t_end / 200``).

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
    integ = GeneralizedAlpha(model, options)
    wall0 = _time.perf_counter()
    integ.initialize(s)
    n_out = int(np.floor((t_end - t0) / dt_out + 1e-9))
    out_times = t0 + dt_out * np.arange(1, n_out + 1)
    if out_times.size == 0 or out_times[-1] < t_end - 1e-12:
        out_times = np.append(out_times, t_end)
    breaks = sorted(
        {float(b) for sch in model.schedules for b in sch.breakpoints()}
        | {float(b) for b in model.gravity_schedule.breakpoints()}
    )
    breaks = [b for b in breaks if t0 < b < t_end]
    rec_t, rec_x, rec_r, rec_v, rec_e = [], [], [], [], []

    def record(st: State) -> None:
        rec_t.append(st.time)
        rec_x.append(st.positions.copy())
        rec_r.append(rotation_vectors(st.rotations))
        rec_v.append(st.velocities.copy())
        rec_e.append(_energies(model, st))

    record(s)
    for t_out in out_times:
        while s.time < t_out - 1e-12 * max(1.0, abs(t_out)):
            nxt = [b for b in breaks if s.time + 1e-12 < b < t_out]
            s = integ.step(s, nxt[0] if nxt else t_out)
            if progress is not None:
                progress(s.time, t_end)
        s.time = float(t_out)  # remove round-off drift so outputs sit on the grid
        record(s)
    wall = _time.perf_counter() - wall0
    e = np.array(rec_e)
    st = asdict(integ.stats)
    st["wall_s"]["total"] = wall
    st["dof_count"] = model.dof_count
    st["simulated_s"] = float(t_end - t0)
    return SimulationResult(
        time=np.array(rec_t),
        positions=np.array(rec_x),
        rotation_vectors=np.array(rec_r),
        velocities=np.array(rec_v),
        energies={
            "kinetic": e[:, 0],
            "strain": e[:, 1],
            "gravity": e[:, 2],
            "total": e.sum(axis=1),
        },
        final_state=s,
        stats=st,
    )
