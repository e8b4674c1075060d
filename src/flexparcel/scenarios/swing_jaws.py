"""The swing test's clamp closed as a pair of flat jaws before the release.

The paper fixes 2 cm of the consignment's length (section 3.2, Fig. 25); the real clamp presses
both layers together there. A settled envelope at 10 mm has its layers apart by up to 5 mm
within those 2 cm (the film runs straight from the seam to the content's edges). Clamping those
nodes where they are makes a truss: the consignment cannot turn about the clamp edge without
stretching a layer, and KP/BW at 10 mm vibrated as a cantilever (free end down 15.6 mm and
back, 7 Hz) instead of swinging. Clamping them flat at once put 1.5 J of strain into the free
elements next to the clamp (the film cannot slide over its content in an instant).

So the jaws close in a phase before the release, as in the real test: gravity off, the clamped
nodes moved in ``increments`` equal steps over ``close_time`` onto the jaws' faces (the top
layer half a film thickness above the seam's mean height, the bottom layer as far below, the
seam on it; nodal rotations to the flat reference, R = I), then held for ``hold_time`` while
the film and the content settle against the closed jaws (rho_inf = 0 and mass-proportional
damping, as in the assembly). The swing starts from that state at rest. Friction stays on
while the jaws close: without it the content box, held by nothing, drifted off at 0.25 m/s
(KP/BW at 10 mm).

Measured on KP/BW at 10 mm (61 clamped nodes spanning 5.0 mm in height; Table 6; 1.4 s,
1,270 s wall with the closing): the consignment swings as a pendulum, its free end falling
248 mm to 22 mm short of the vertical through the clamp edge and back to 227 mm, where with
the open clamp it dropped 15.6 mm and sprang back (docs/scenarios.md, "The clamp").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from flexparcel.consignments.build import Consignment
from flexparcel.elements.rotations import apply_spins, rotation_vectors
from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.model.model import Model, State
from flexparcel.scenarios.holding import settle_record
from flexparcel.simulate import ModelStepper

__all__ = ["JawClosing", "close_jaws", "jaw_targets"]


@dataclass(frozen=True)
class JawClosing:
    """How the swing clamp's jaws close before the release (SI units)."""

    close_time: float = 0.02
    """Time [s] over which the clamped nodes move onto the jaws."""
    hold_time: float = 0.1
    """Time [s] the closed jaws hold before the release, for the film to settle."""
    increments: int = 50
    """Equal position increments of the closing (each 1/increments of the way, 0.1 mm for
    KP/BW's 5 mm spread at the default)."""
    mass_damping: float = 80.0
    """Rayleigh alpha [1/s] of the closing model, as the assembly's settling
    (:class:`~flexparcel.consignments.assembly.AssemblySettings`): without it the consignment
    still rocked about the clamp when the hold ended (the 20 mm example: its free end then
    swung +-2 mm at 25 Hz after the release, up or down with the hold time)."""

    def __post_init__(self) -> None:
        for name in ("close_time", "hold_time"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 < v <= 1.0):
                raise ValueError(f"JawClosing.{name} must be in (0, 1] s, got {v!r}")
        if not (np.isfinite(self.mass_damping) and self.mass_damping >= 0.0):
            raise ValueError(f"JawClosing.mass_damping must be >= 0 1/s, got {self.mass_damping!r}")
        if not (isinstance(self.increments, int) and 1 <= self.increments <= 10_000):
            raise ValueError(
                f"JawClosing.increments must be an integer in [1, 10000], got {self.increments!r}"
            )


def jaw_targets(
    c: Consignment, clamped: np.ndarray, positions: np.ndarray
) -> tuple[np.ndarray, float]:
    """Positions [m] (k, 3) of the ``clamped`` nodes on the closed jaws and the jaws' mid
    height [m]: x and y kept; the seam (the border shared by both layers) at the mid height,
    the mean height of the clamped seam nodes; the top layer half a film thickness above it,
    the bottom layer as far below, so the two layers touch at the self contact's thickness."""
    seam = np.isin(clamped, c.border)
    top = np.isin(clamped, c.top) & ~seam
    z = positions[clamped, 2]
    z_mid = float(z[seam].mean()) if seam.any() else float(z.mean())
    half = c.contact_radius  # half the film thickness
    out = positions[clamped].copy()
    out[:, 2] = z_mid + np.where(seam, 0.0, np.where(top, half, -half))
    return out, z_mid


def close_jaws(
    model: Model,
    c: Consignment,
    clamped: np.ndarray,
    state: State,
    closing: JawClosing | None = None,
    options: IntegratorOptions | None = None,
) -> tuple[State, dict]:
    """Close the jaws on ``model`` (gravity off, ``clamped`` nodes fixed) from ``state``;
    returns the closed state at rest (velocities and accelerations zero, time 0) and a
    record: ``steps``, ``wall_s``, ``kinetic_end_j`` (kinetic energy when the hold ends)."""
    closing = closing or JawClosing()
    stepper = ModelStepper(model, replace(options or IntegratorOptions(), rho_inf=0.0))
    s = stepper.begin(state.copy())
    p0 = s.positions[clamped].copy()
    target, _ = jaw_targets(c, clamped, s.positions)
    n = closing.increments
    # each node turns about its own fixed axis to R = I: 1/n of its rotation vector a time
    turn = -rotation_vectors(np.ascontiguousarray(s.rotations[clamped])) / n
    wall = time.perf_counter()
    for k in range(1, n + 1):
        # the fixed nodes keep whatever the state holds: move them one increment, then step
        s.positions[clamped] = p0 + (k / n) * (target - p0)
        rot = np.ascontiguousarray(s.rotations[clamped])
        apply_spins(rot, turn)
        s.rotations[clamped] = rot
        s.velocities[clamped] = 0.0
        s = stepper.advance(s, k * closing.close_time / n, None)
    s = stepper.advance(s, closing.close_time + closing.hold_time, None)
    return s, settle_record(stepper, model, s, wall)
