"""Holding a consignment at rest before a test: the vertical drop's hold by its top end.

The paper releases its consignments "from a horizontal and vertical resting position"
(section 3.2, Fig. 26). A snapshot is assembled without gravity
(:mod:`flexparcel.consignments.assembly`), and the drops release it as it is. Standing on
end and at rest, a real envelope's content may have slid down its pouch first; released
mid-pouch, it slides only once the envelope touches the plate, and the slide takes impact
energy (the vertical drop's 0.0 mm at friction 0.3, docs/scenarios.md).

:class:`DropHold` is that resting position as an option of the vertical drop: the snapshot
placed on end, gravity on, ``held_length`` of its top end held fixed (a hand; the swing
clamp's 2 cm), the assembly's mass damping on and ``rho_inf = 0``, for ``hold_time``; then
all velocities are zeroed and the held state is the drop's start, moved down to the drop
height. It is not the default because it changes nothing measurable on the shipped
snapshots while it costs a run: KP/BW at 25 mm, Table 6, friction 0.3 and 0.05, its box
sinks by 0.01 mm in 0.2 s (28 and 36 s wall); the film, wrapped round the box under its
prestress, holds it. The horizontal drop needs no hold: lying flat, gravity moves the
content across the film gap over it (under 1 mm on the shipped snapshots), not along it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.model.model import Model, State
from flexparcel.simulate import ModelStepper, state_energies

__all__ = ["DropHold", "hold_at_rest", "settle_record"]


@dataclass(frozen=True)
class DropHold:
    """How the vertical drop holds the consignment at rest before the release (SI units)."""

    held_length: float = 0.020
    """Length [m] of the top end whose packaging nodes are held (the swing clamp's 2 cm)."""
    hold_time: float = 0.2
    """Time [s] held under gravity before the release, for the content to slide down and
    settle (KP/BW's centred box has 50 mm of pouch below it, a free slide of 0.1 s)."""
    mass_damping: float = 80.0
    """Rayleigh alpha [1/s] while held, the assembly's (time constant 12.5 ms), so the
    consignment is at rest when the hold ends."""

    def __post_init__(self) -> None:
        for name, hi in (("held_length", 0.5), ("hold_time", 2.0)):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 < v <= hi):
                raise ValueError(f"DropHold.{name} must be in (0, {hi:g}] (SI), got {v!r}")
        if not (np.isfinite(self.mass_damping) and self.mass_damping >= 0.0):
            raise ValueError(f"DropHold.mass_damping must be >= 0 1/s, got {self.mass_damping!r}")


def settle_record(stepper: ModelStepper, model: Model, s: State, wall0: float) -> dict:
    """The record (plain JSON numbers) of a held phase that ends in ``s``: ``steps``,
    ``wall_s`` since ``wall0`` (a ``time.perf_counter()`` value), ``kinetic_end_j`` (kinetic
    energy [J] at its end); then ``s`` is set at rest (velocities and accelerations zero,
    time 0) in place."""
    record = {"steps": int(stepper.integrator.stats.steps),
              "wall_s": time.perf_counter() - wall0,
              "kinetic_end_j": float(state_energies(model, s)[0])}  # fmt: skip
    s.velocities[:] = 0.0
    s.accelerations[:] = 0.0
    s.time = 0.0
    return record


def hold_at_rest(
    model: Model, state: State, hold: DropHold, options: IntegratorOptions
) -> tuple[State, dict]:
    """Run ``model`` (its held nodes fixed, gravity and the hold's mass damping in it) from
    ``state`` for ``hold.hold_time``; returns the state at rest and its
    :func:`settle_record`."""
    stepper = ModelStepper(model, replace(options, rho_inf=0.0))
    wall = time.perf_counter()
    s = stepper.advance(stepper.begin(state.copy()), hold.hold_time, None)
    return s, settle_record(stepper, model, s, wall)
