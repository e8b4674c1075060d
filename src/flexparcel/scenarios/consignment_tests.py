"""The paper's physical tests on an assembled consignment (section 3.2): swing, vertical and
horizontal drop. Every test starts from the consignment's :class:`Snapshot`.

Parameters are the paper's Table 3 names in the paper's units (MPa, s, N/mm, Ns/mm), converted
to SI here; defaults are the calibrated KP/BW values of Table 6. Young's modulus and the damping
ratio replace the packaging material's; the snapshot's settled shape is kept (the prestress
then follows from the new modulus, as in a RecurDyn model re-run from an exported state).

Responses (all in mm):

- ``first_swing_mm``, ``second_swing_mm``: the free end (the edge opposite the clamp; the
  mean x of its nodes) swings down, under the clamp and past it; the first swing is its peak
  horizontal excursion beyond the vertical through the clamp edge, the second the peak on the
  way back (paper Fig. 25, 27: "displacement in the x-direction" along the ruler).
- ``rebound_mm``: the largest clearance between the plate and the consignment's lowest point
  after the first touch, what a camera beside the plate sees (the paper's Fig. 28 measures
  the rebound this way, against a ruler behind the plate): :func:`camera_clearance`.
- ``com_rise_mm``: how high the consignment's centre of mass rises in its first bounce above
  the height it had when the packaging first touched the plate (the rebound height of a rigid
  body): :func:`com_rise`. A second response, not the paper's: a consignment that tips over
  while its lowest point leaves the plate shows a clearance but no rise, and a box bouncing
  inside a resting envelope shows a rise but no clearance.

Friction: ``stick_model=True`` (the default) uses the stick model with k_t = c on every pair
(see :func:`flexparcel.consignments.build.default_packaging_content_law` for why: 7x fewer
Newton iterations); ``stick_model=False`` the paper's regularised law (eq. 8) exactly.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.consignments.build import (
    Consignment,
    add_air_drag,
    add_consignment,
    add_ground_contact,
)
from flexparcel.consignments.snapshot import Snapshot, place_snapshot
from flexparcel.contact.law import ContactLaw
from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.model.model import Model, State
from flexparcel.scenarios.base import Parameter, resolve_parameters
from flexparcel.scenarios.holding import DropHold, hold_at_rest
from flexparcel.scenarios.swing_jaws import JawClosing, close_jaws
from flexparcel.simulate import SimulationResult, simulate

__all__ = [
    "TABLE3_PARAMETERS",
    "TABLE3",
    "TABLE6_VALUES",
    "FRICTION_PACKAGING_CONTENT",
    "FRICTION_PACKAGING_GROUND",
    "PACKAGING_FRICTION",
    "TEST_PARAMETERS",
    "TestRun",
    "TestModel",
    "parse_assignments",
    "swing_model",
    "drop_model",
    "drop_touch_radius",
    "end_nodes",
    "swing_test",
    "drop_test",
    "swing_peaks",
    "SWING_NOT_REACHED",
    "com_rise_outcome",
    "camera_clearance",
    "lowest_point_gap",
    "clearance_peak",
    "com_rise",
    "consignment_options",
    "drop_options",
    "swing_options",
]

TABLE3_PARAMETERS: dict[str, tuple[str, float]] = {
    "youngs_modulus": ("MPa", 1e6),
    "damping_ratio": ("s", 1.0),
    "contact_stiffness_packaging_content": ("N/mm", 1e3),
    "contact_damping_packaging_content": ("Ns/mm", 1e3),
    "contact_stiffness_packaging_ground": ("N/mm", 1e3),
    "contact_damping_packaging_ground": ("Ns/mm", 1e3),
}
"""Name -> (paper unit, factor to SI) of each settable parameter (paper Table 3)."""

TABLE6_VALUES: dict[str, float] = {
    "youngs_modulus": 926.0,
    "damping_ratio": 1.71e-3,
    "contact_stiffness_packaging_content": 649.0,
    "contact_damping_packaging_content": 0.579,
    "contact_stiffness_packaging_ground": 611.0,
    "contact_damping_packaging_ground": 0.591,
}
"""The calibrated KP/BW parameters (paper Table 6), paper units."""

_TABLE3_TEXT = {
    "youngs_modulus": "Young's modulus of the packaging",
    "damping_ratio": "stiffness-proportional Rayleigh damping beta of the packaging (C = beta K)",
    "contact_stiffness_packaging_content": "contact stiffness c, packaging to content "
    "(per 10 mm node spacing)",
    "contact_damping_packaging_content": "contact damping d, packaging to content",
    "contact_stiffness_packaging_ground": "contact stiffness c, packaging to ground plate",
    "contact_damping_packaging_ground": "contact damping d, packaging to ground plate",
}
TABLE3: tuple[Parameter, ...] = tuple(
    Parameter(name, unit, TABLE6_VALUES[name], 0.0, float("inf"), _TABLE3_TEXT[name],
              low_open=True)
    for name, (unit, _) in TABLE3_PARAMETERS.items()
)  # fmt: skip
"""The paper's Table 3 parameters as declared scenario parameters (paper units, default
Table 6, any positive value)."""

JAWS = JawClosing()
"""The swing clamp's default jaw closing (:class:`~flexparcel.scenarios.swing_jaws.JawClosing`)."""

S_MAX_MM = 0.1  # STEP damping ramp of all pairs [mm] (the paper does not print its value)

FRICTION_PACKAGING_CONTENT = Parameter(
    "friction_packaging_content", "-", 0.3, 0.0, 2.0,
    "Coulomb friction coefficient (static = dynamic), packaging to content; the paper does "
    "not give it (default 0.3, uncalibrated)",
)  # fmt: skip
FRICTION_PACKAGING_GROUND = Parameter(
    "friction_packaging_ground", "-", 0.3, 0.0, 2.0,
    "Coulomb friction coefficient (static = dynamic), packaging to ground plate (a metal "
    "sheet); the paper does not give it for the tests (default 0.3, uncalibrated)",
)  # fmt: skip
PACKAGING_FRICTION: tuple[Parameter, ...] = (FRICTION_PACKAGING_CONTENT, FRICTION_PACKAGING_GROUND)
"""The packaging's two friction coefficients, parameters beside Table 3's, named like its
contact pairs: the paper does not print them, and they decide the vertical drop's rebound
(KP/BW at 10 mm, Table 6: 0.0 mm with 0.3 for both, 4.72 mm with 0.1 for both;
docs/scenarios.md), so a calibration must be able to set them."""

TEST_PARAMETERS: tuple[Parameter, ...] = (*TABLE3, *PACKAGING_FRICTION)
"""What the swing and drop tests take: Table 3's six and the two of :data:`PACKAGING_FRICTION`."""


def parse_assignments(items: Sequence[str] | Mapping[str, float] | None) -> dict[str, float]:
    """Table 6 values and the default packaging frictions, overridden by ``name=value``
    strings (or a mapping), paper units. Unknown names and values out of range raise
    ``ValueError`` naming them."""
    return resolve_parameters(TEST_PARAMETERS, items)  # type: ignore[return-value]


def _laws(p: Mapping[str, float], stick_model: bool) -> tuple[ContactLaw, ContactLaw]:
    # Table 6's values are RecurDyn's per-point values of the paper's 10 mm nodes: per unit
    # area they are divided by (10 mm)^2 (the law is per area, see flexparcel.contact.law)
    mu_c = p.get(FRICTION_PACKAGING_CONTENT.name, FRICTION_PACKAGING_CONTENT.default)
    mu_g = p.get(FRICTION_PACKAGING_GROUND.name, FRICTION_PACKAGING_GROUND.default)
    content = ContactLaw.from_paper_units(
        c_N_per_mm=p["contact_stiffness_packaging_content"],
        d_Ns_per_mm=p["contact_damping_packaging_content"],
        s_max_mm=S_MAX_MM, mu_static=mu_c, mu_dynamic=mu_c, reference_spacing_mm=10.0,
    )  # fmt: skip
    ground = ContactLaw.from_paper_units(
        c_N_per_mm=p["contact_stiffness_packaging_ground"],
        d_Ns_per_mm=p["contact_damping_packaging_ground"],
        s_max_mm=S_MAX_MM, mu_static=mu_g, mu_dynamic=mu_g, reference_spacing_mm=10.0,
    )  # fmt: skip
    if stick_model:
        return content.with_stick_model(), ground.with_stick_model()
    return content, ground


@dataclass
class TestRun:
    """A finished test: the recorded run, its responses [mm] and what produced them.
    A response the record does not reach (a run too short, a swing that never passes the
    clamp) is None, never 0, and ``notes`` says why."""

    test: str
    result: SimulationResult
    responses: dict[str, float | None]
    parameters: dict[str, float]
    model: Model
    consignment: Consignment
    wall_s: float
    notes: dict[str, str] = field(default_factory=dict)
    """Why a response is None, by response name."""
    preparation: dict = field(default_factory=dict)
    """:attr:`TestModel.preparation` of the run (jaw closing, hold); its wall time is in
    ``wall_s``."""

    def summary(self) -> dict:
        """``responses.json`` content: responses, ``simulated_s``, ``wall_s``, parameters."""
        return {
            "test": self.test,
            "consignment": self.consignment.build.spec.id,
            **{k: None if v is None else float(v) for k, v in self.responses.items()},
            "notes": dict(self.notes),
            "simulated_s": float(self.result.time[-1] - self.result.time[0]),
            "wall_s": float(self.wall_s),
            "parameters": dict(self.parameters),
            "parameter_units": {
                q.name: q.unit for q in TEST_PARAMETERS if q.name in self.parameters
            },
            "preparation": {k: dict(r) for k, r in self.preparation.items()},
            "steps": int(self.result.stats.get("steps", 0)),
            "newton_iterations": int(self.result.stats.get("newton_iterations", 0)),
        }


def _builder(
    snapshot: Snapshot,
    p: Mapping[str, float],
    stick_model: bool,
    gravity: float = 9.81,
    mass_damping: float = 0.0,
    air_drag: float = 0.0,
) -> tuple[ModelBuilder, Consignment]:
    mat = replace(
        snapshot.build.material,
        youngs_modulus=p["youngs_modulus"] * 1e6,
        damping_ratio=p["damping_ratio"],
    )
    build = replace(snapshot.build, material=mat)
    content_law, _ = _laws(p, stick_model)
    b = ModelBuilder(gravity=(0.0, 0.0, -gravity), mass_damping=mass_damping)
    c = add_consignment(b, build, content_law=content_law)
    if air_drag > 0.0:
        add_air_drag(b, c, air_drag)
    return b, c


def consignment_options() -> IntegratorOptions:
    """Integrator options of the consignment tests (and the envelope-drop benchmark): numerical
    dissipation of the high contact frequencies (rho_inf = 0.5) instead of resolving every
    node's contact oscillation (see IntegratorOptions.impact_limit), the smooth error estimate
    and Newton relaxation for contacts cycling across a kink."""
    return IntegratorOptions(
        rho_inf=0.5, impact_limit="rigid", error_estimate="smooth", newton_relaxation=True
    )


def swing_options() -> IntegratorOptions:
    """Integrator options of the swing test: :func:`consignment_options` with the "balanced"
    error estimate and the "stick" friction tangent (see :class:`IntegratorOptions`). In the
    swing the film hangs taut over its content, so contact jumps at the film nodes under the
    content are balanced by the film's tension and only "balanced" sees that their motion is
    smooth; the friction contacts barely slip, where the consistent slip tangent flips with
    the slip direction and Newton cycles. Measured on KP/BW at 25 mm (Table 6, first 0.1 s):
    722 steps, 3,655 Newton iterations, 37 s with :func:`consignment_options`; 376 steps,
    2,629 iterations, 30 s with "balanced"; 156 steps, 1,335 iterations, 12 s with both. The
    free end's path agrees to 0.03 mm. The drops keep :func:`consignment_options`: there
    "balanced" took as long (25 mm: 145 against 138 s horizontal, 228 s both vertical) and the
    Newton reach, not the error estimate, limits their steps.

    The friction tangent is "symmetric", no longer "stick": since Newton's momentum test
    (``IntegratorOptions.newton_momentum_tol``) the stick tangent's k_t along the slip
    direction held back the box sliding in its envelope, and the test vetoed half of all
    iterations. Measured on KP/BW at 25 mm (Table 6, one numba thread, :func:`swing_test`
    with these options and the one changed), first 0.5 s: "stick" 1,837 steps, 17,302
    iterations (9,729 vetoed), 185 s; "symmetric" 1,261 steps, 10,025 iterations (1,672),
    109 s. First swing 107.72 against 107.83 mm; against a run at a quarter of the step
    tolerance (107.64 mm) every node within 0.32 mm ("stick") and 0.81 mm ("symmetric"):
    the stick tangent's vetoed iterations converge further than ``newton_tol`` asks, the
    symmetric one stops at it (1 um a step). First 0.1 s, time in the Newton phases:
    "stick" 3,862 iterations, 39 s; "consistent" 2,696, 28 s (unsymmetric: 507 symbolic
    analyses); "symmetric" 1,897, 18 s; "stick" without the momentum test 1,354, 11 s."""
    return replace(consignment_options(), error_estimate="balanced", friction_tangent="symmetric")


def drop_options() -> IntegratorOptions:
    """Integrator options of the drop tests: :func:`consignment_options` with the "symmetric"
    friction tangent (see :class:`IntegratorOptions`; the conveyor, the swing's jaws and the
    vertical drop's hold keep :func:`consignment_options`). Measured on KP/BW at 25 mm (Table
    6, one numba thread, 0.3 s): vertical "consistent" 2,246 steps, 12,383 iterations (3,476
    symbolic analyses: its tangent is unsymmetric), 145 s; "symmetric" 1,555 steps, 8,271
    iterations, 90 s; rebound 2.80 against 2.82 mm, 2.82 mm with "consistent" at half the
    step tolerance. Horizontal: "consistent" 1,202 steps, 66 s; "symmetric" 714 steps, 39 s;
    rebound 7.18 against 6.22 mm. The horizontal rebound (the box bouncing in its envelope)
    moves that much with any solver setting: "consistent" at half the step tolerance gave
    7.30 mm in 25 s, a variant with k_t across the slip direction 6.72 mm (7.36 mm)."""
    return replace(consignment_options(), friction_tangent="symmetric")


def _options(options: IntegratorOptions | None) -> IntegratorOptions:
    return options or drop_options()


CHECKPOINT_INTERVAL_S = 60.0
"""Wall time [s] between two saves of a test's checkpoint (at an output frame)."""


def _run(
    model, s0, t_end, dt_out, options, progress, checkpoint=None
) -> tuple[SimulationResult, float]:
    """The test's simulation from ``s0`` and its wall time [s]. ``checkpoint``: a ``.npz``
    the run saves itself to about once a minute and resumes from (:func:`simulate`); the
    wall time then counts the run's earlier parts too."""
    wall = time.perf_counter()
    res = simulate(model, t_end, dt_out=dt_out, options=_options(options), state=s0,
                   progress=progress, checkpoint=checkpoint,
                   checkpoint_interval_s=CHECKPOINT_INTERVAL_S)  # fmt: skip
    if checkpoint is None:
        return res, time.perf_counter() - wall
    return res, float(res.stats["wall_s"]["total"])


@dataclass
class TestModel:
    """A test's model, ready to run: the model, its consignment, the start state and what
    the responses refer to."""

    model: Model
    consignment: Consignment
    state0: State
    """Start state: the snapshot placed in the test's position (the swing's with its jaws
    closed, at rest)."""
    reference: float
    """Swing: x of the clamp edge [m]; drop: contact radius of the first touch [m]."""
    preparation: dict = field(default_factory=dict)
    """What was done to the snapshot before the start (the swing's ``jaw_closing``, the
    vertical drop's ``hold``: steps, wall time [s], kinetic energy [J] when it ended); empty
    if nothing."""


def end_nodes(snapshot: Snapshot, c: Consignment, length: float) -> np.ndarray:
    """Packaging nodes (ids) within ``length`` [m] of the snapshot's -x end, both layers: the
    swing's clamp, the vertical drop's hold (that end up once on end)."""
    x = snapshot.positions[c.packaging, 0]
    return c.packaging[x <= x.min() + length + 1e-9]


def swing_model(
    snapshot: Snapshot,
    parameters: Mapping[str, float],
    *,
    clamped_length: float = 0.020,
    stick_model: bool = True,
    jaws: JawClosing | None = JAWS,
    air_drag: float = 0.0,
) -> TestModel:
    """The swing test's model: ``clamped_length`` [m] of the length (the -x end, both
    layers) clamped, the rest free under gravity; ``parameters`` as :func:`parse_assignments`
    returns them (paper units). ``jaws``: close the clamp as a pair of flat jaws first
    (:mod:`flexparcel.scenarios.swing_jaws`); None clamps the nodes where they settled.
    ``air_drag``: the envelope's drag coefficient in still air (:func:`add_air_drag`; 0, the
    paper's model: none) while it swings; the jaws close without it."""

    def clamped_model(gravity: float, mass_damping: float = 0.0, drag: float = 0.0):
        b, c = _builder(snapshot, parameters, stick_model, gravity, mass_damping, drag)
        clamped = end_nodes(snapshot, c, clamped_length)
        b.clamp(clamped)
        x_clamp = float(snapshot.positions[c.packaging, 0].min() + clamped_length)
        return b.finalize(), c, clamped, x_clamp

    model, c, clamped, x_clamp = clamped_model(9.81, 0.0, air_drag)
    state0 = place_snapshot(snapshot, model)
    if jaws is None:
        return TestModel(model, c, state0, x_clamp)
    closing_model = clamped_model(0.0, jaws.mass_damping)[0]
    state0, record = close_jaws(closing_model, c, clamped, state0, jaws, consignment_options())
    return TestModel(model, c, state0, x_clamp, {"jaw_closing": record})


def swing_test(
    snapshot: Snapshot,
    parameters: Mapping[str, float] | Sequence[str] | None = None,
    *,
    t_end: float = 1.4,
    clamped_length: float = 0.020,
    dt_out: float = 0.005,
    options: IntegratorOptions | None = None,
    progress: Callable[[float, float], None] | None = None,
    stick_model: bool = True,
    jaws: JawClosing | None = JAWS,
    air_drag: float = 0.0,
    checkpoint: str | Path | None = None,
) -> TestRun:
    """Clamp ``clamped_length`` [m] of the length (the -x end, both layers; closed as flat
    jaws first unless ``jaws`` is None, see :func:`swing_model`), release the horizontal
    consignment under gravity for ``t_end`` [s]. The wall time includes the jaw closing.
    ``air_drag``: drag coefficient of the envelope in still air (0: none, the paper's model).
    ``checkpoint``: see :func:`_run`; the jaws close again on resume (the same closing, so
    the same start state, which the checkpoint's header checks)."""
    p = parse_assignments(parameters)
    tm = swing_model(snapshot, p, clamped_length=clamped_length, stick_model=stick_model,
                     jaws=jaws, air_drag=air_drag)  # fmt: skip
    res, wall = _run(tm.model, tm.state0, t_end, dt_out, options or swing_options(), progress,
                     checkpoint)  # fmt: skip
    wall += tm.preparation.get("jaw_closing", {}).get("wall_s", 0.0)
    free_end = res.positions[:, tm.consignment.edge, 0].mean(axis=1)
    first, second = swing_peaks(free_end - tm.reference)
    responses = {"first_swing_mm": _mm(first), "second_swing_mm": _mm(second)}
    notes = {k: SWING_NOT_REACHED[k] for k, v in responses.items() if v is None}
    return TestRun("swing", res, responses, p, tm.model, tm.consignment, wall, notes,
                   tm.preparation)  # fmt: skip


def _mm(value_m: float | None) -> float | None:
    return None if value_m is None else value_m * 1e3


SWING_NOT_REACHED = {
    "first_swing_mm": "the free end did not swing past the clamp edge within the run",
    "second_swing_mm": "the free end did not swing back past the clamp edge within the run",
}
"""Why a swing response is not reached, by response name."""


def swing_peaks(x_rel: np.ndarray) -> tuple[float | None, float | None]:
    """First and second swing [same unit as ``x_rel``] from the free end's horizontal
    position relative to the clamp edge over time (positive: on its starting side): the
    peak of the first excursion to the far side, then the peak back on the starting side.
    None where the record does not reach it: no first swing while the free end never passes
    under the clamp, no second swing while it has not come back past the clamp edge."""
    d = -np.asarray(x_rel, float)
    past = np.flatnonzero(d > 0)
    if past.size == 0:
        return None, None
    start = past[0]
    back = np.flatnonzero(d[start:] <= 0)
    end = start + back[0] if back.size else d.size
    first = float(d[start:end].max())
    second = float(max(0.0, (-d[end:]).max())) if end < d.size else None
    return first, second


_VERTICAL = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
# the vertical drop's rotation of the snapshot: +90 deg about y (x -> -z), its +x edge down


def drop_model(
    snapshot: Snapshot,
    orientation: str,
    parameters: Mapping[str, float],
    *,
    drop_height: float = 0.200,
    stick_model: bool = True,
    air_drag: float = 0.0,
    hold: DropHold | None = None,
) -> TestModel:
    """The drop test's model: the consignment at rest with its lowest point ``drop_height``
    [m] above a rigid plate (z = 0), lying flat ("horizontal") or standing on its +x edge
    ("vertical", KP/BW's glued strip, with a line contact of that edge against the plate);
    ``parameters`` in paper units; ``air_drag`` as for :func:`swing_model`. ``hold``: start
    the vertical drop from the consignment held at rest by its top end under gravity
    (:mod:`flexparcel.scenarios.holding`); None (the default) from the snapshot as assembled,
    without gravity. A hold for the horizontal drop raises ``ValueError``."""
    if orientation not in ("horizontal", "vertical"):
        raise ValueError(f"orientation must be 'horizontal' or 'vertical', got {orientation!r}")
    vertical = orientation == "vertical"
    if hold is not None and not vertical:
        raise ValueError("hold applies to the vertical drop only")
    rot = _VERTICAL if vertical else None

    def plate_model(mass_damping: float, drag: float, held_length: float = 0.0):
        b, c = _builder(snapshot, parameters, stick_model, mass_damping=mass_damping,
                        air_drag=drag)  # fmt: skip
        _, ground = _laws(parameters, stick_model)
        plate = b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        add_ground_contact(b, c, plate, ground)  # packaging, and content as a backstop
        if vertical:
            b.add_edge_contact(c.edge, plate, ground, radius=_edge_radius(c))
        if held_length > 0.0:  # the top end once on end
            b.clamp(end_nodes(snapshot, c, held_length))
        return b.finalize(), c

    model, c = plate_model(0.0, air_drag)
    lowest = drop_height + c.contact_radius
    s0 = place_snapshot(snapshot, model, rotation=rot, lowest_z=lowest)
    if hold is None:
        return TestModel(model, c, s0, drop_touch_radius(c, orientation))
    held_model, _ = plate_model(hold.mass_damping, 0.0, hold.held_length)
    s0, record = hold_at_rest(held_model, s0, hold, consignment_options())
    own = slice(0, len(snapshot.positions))  # the snapshot's nodes (place_snapshot)
    s0.positions[own, 2] += lowest - s0.positions[c.packaging, 2].min()
    return TestModel(model, c, s0, drop_touch_radius(c, orientation), {"hold": record})


def _edge_radius(c: Consignment) -> float:
    """Radius [m] of the vertical drop's edge line contact: half the strip's thickness, the
    film's doubled by KP/BW's glued strip."""
    return c.contact_radius * (2.0 if c.build.has_glued_strip else 1.0)


def drop_touch_radius(c: Consignment, orientation: str) -> float:
    """Contact radius [m] with which the dropped consignment first touches the plate: its
    nodes' lying flat; standing on the edge, the edge's line contact (:func:`_edge_radius`),
    where larger."""
    if orientation != "vertical":
        return c.contact_radius
    return max(c.contact_radius, _edge_radius(c))


def drop_test(
    snapshot: Snapshot,
    orientation: str = "horizontal",
    parameters: Mapping[str, float] | Sequence[str] | None = None,
    *,
    t_end: float = 0.3,
    drop_height: float = 0.200,
    dt_out: float = 0.001,
    options: IntegratorOptions | None = None,
    progress: Callable[[float, float], None] | None = None,
    stick_model: bool = True,
    air_drag: float = 0.0,
    hold: DropHold | None = None,
    checkpoint: str | Path | None = None,
) -> TestRun:
    """Release the consignment from rest with its lowest point ``drop_height`` [m] above a
    rigid plate (z = 0): lying flat ("horizontal") or standing on its +x edge ("vertical",
    KP/BW's glued strip, with a line contact of that edge against the plate; with ``hold``
    held at rest by its top end first, see :func:`drop_model`). ``air_drag``: drag
    coefficient of the envelope in still air (0: none, the paper's model). The wall time
    includes the hold. ``checkpoint``: see :func:`_run` (a hold runs again on resume)."""
    p = parse_assignments(parameters)
    tm = drop_model(snapshot, orientation, p, drop_height=drop_height, stick_model=stick_model,
                    air_drag=air_drag, hold=hold)  # fmt: skip
    res, wall = _run(tm.model, tm.state0, t_end, dt_out, options, progress, checkpoint)
    wall += tm.preparation.get("hold", {}).get("wall_s", 0.0)
    gap, gap_why = camera_clearance(tm.model, res, tm.consignment, touch_radius=tm.reference)
    rise, rise_why = com_rise_outcome(tm.model, res, tm.consignment, touch_radius=tm.reference)
    responses = {"rebound_mm": _mm(gap), "com_rise_mm": _mm(rise)}
    notes = {k: why for k, why in (("rebound_mm", gap_why), ("com_rise_mm", rise_why)) if why}
    return TestRun(f"drop-{orientation}", res, responses, p, tm.model, tm.consignment, wall,
                   notes, tm.preparation)  # fmt: skip


def com_rise_outcome(
    model: Model, res: SimulationResult, c: Consignment, touch_radius: float | None = None
) -> tuple[float | None, str]:
    """Centre-of-mass rise [m] as :func:`com_rise` defines it, or None and why where the record
    does not reach it: no touch of the plate, no rise after the touch, or still rising at
    the last frame (its peak lies beyond the record)."""
    value, missing = _bounce(model, res, c, touch_radius)
    return (None, missing) if missing else (value, "")


def camera_clearance(
    model: Model, res: SimulationResult, c: Consignment, touch_radius: float | None = None
) -> tuple[float | None, str]:
    """What a camera beside the plate sees (the paper's Fig. 28): the largest clearance [m]
    between the plate and the consignment's lowest point (its lowest packaging node's
    surface, ``touch_radius`` [m] below the node, default the contact radius) after the first
    touch; or None and why where the record does not reach it (no touch, or the gap still
    growing at the last frame). This is the drop tests' ``rebound_mm``. Unlike
    :func:`com_rise` it does not follow the centre
    of mass: a consignment that tips over while its lowest point leaves the plate by 3 mm
    shows 3 mm here, and a box bouncing inside a resting envelope shows none."""
    gap = lowest_point_gap(res, c, touch_radius)
    peak, why = clearance_peak(gap)
    return (None, why) if peak is None else (max(0.0, float(gap[peak])), "")


def lowest_point_gap(
    res: SimulationResult, c: Consignment, touch_radius: float | None = None
) -> np.ndarray:
    """Gap [m] (k,) between the plate (z = 0) and the consignment's lowest point in every
    frame: the lowest packaging node's height minus ``touch_radius`` [m] (default the contact
    radius); negative while the contact is compressed."""
    radius = c.contact_radius if touch_radius is None else touch_radius
    return res.positions[:, c.packaging, 2].min(axis=1) - radius


def clearance_peak(gap: np.ndarray) -> tuple[int | None, str]:
    """Frame of the largest clearance after the first touch in a :func:`lowest_point_gap`
    curve (the rebound's frame; a touch with no clearance after it: the last frame at the
    largest value, 0), or None and why where the record does not reach it."""
    touch = np.flatnonzero(gap <= 0.0)
    if touch.size == 0:
        return None, "the consignment did not touch the plate within the run"
    after = np.maximum(gap[touch[0] :], 0.0)
    peak = int(np.argmax(after))
    if peak == after.size - 1 and after[-1] > 0.0:
        return None, "the gap was still growing at the end of the run: its peak lies beyond it"
    return int(touch[0]) + peak, ""


def com_rise(
    model: Model, res: SimulationResult, c: Consignment, touch_radius: float | None = None
) -> float:
    """Centre-of-mass rise [m] (the drop tests' ``com_rise_mm``): the rise of the centre of
    mass in the first bounce above its height at the
    first touch (the lowest packaging node reaching ``touch_radius`` [m], default the contact
    radius); 0 without a touch. The bounce runs from the first minimum of the centre height
    after the touch until the centre falls back below that minimum (a consignment that bounces
    and then tips over, as in the vertical drop, keeps sinking afterwards: its global minimum
    comes after the bounce)."""
    return _bounce(model, res, c, touch_radius)[0]


def _bounce(
    model: Model, res: SimulationResult, c: Consignment, touch_radius: float | None
) -> tuple[float, str]:
    """:func:`com_rise`'s value [m] and, where the record does not reach the rise,
    why (else "")."""
    ids = c.node_ids
    m = model.mass[ids, 0]
    zc = res.positions[:, ids, 2] @ m / m.sum()
    radius = c.contact_radius if touch_radius is None else touch_radius
    low = res.positions[:, c.packaging, 2].min(axis=1) - radius
    touch = np.flatnonzero(low <= 0.0)
    if touch.size == 0:
        return 0.0, "the consignment did not touch the plate within the run"
    k = touch[0]
    if k > 0:  # interpolate the centre height at the touch between the two frames
        w = low[k - 1] / (low[k - 1] - low[k])
        z_touch = zc[k - 1] + w * (zc[k] - zc[k - 1])
    else:
        z_touch = zc[0]
    rising = np.flatnonzero(np.diff(zc[k:]) > 0.0)
    if rising.size == 0:
        return 0.0, "still sinking at the end of the run: no bounce within it"
    kmin = k + int(rising[0])
    below = np.flatnonzero(zc[kmin + 1 :] < zc[kmin])
    end = kmin + 1 + int(below[0]) if below.size else zc.size
    value = float(max(0.0, zc[kmin:end].max() - z_touch))
    if end == zc.size and zc[-1] > zc[-2]:  # the peak may lie beyond the last frame
        return value, "still rising at the end of the run: the peak lies beyond it"
    return value, ""
