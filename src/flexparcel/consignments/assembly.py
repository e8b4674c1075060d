"""Assembly of a consignment as in the paper (section 3.1.3), ending in a snapshot.

1. Opening: equal and opposite uniform forces pull the top layer up and the bottom layer down
   (growing geometrically in time, from 1 Pa) while the packaging-content contact is off; the
   content sits in the almost flat packaging. Gravity is off during the whole assembly (the
   paper's assembly does not rest on anything either), so the content does not move. A
   content that nearly fills its packaging is opened round at ``content_scale`` of its size.
2. Closing: as soon as the opening clears the content by ``margin`` on both sides (checked
   every ``check_every`` s), the contact is switched on (frictionless) and the forces are
   released over ``release_time``: the packaging closes around the content. A shrunk content
   then grows back to full size over ``growth_time`` while a small pressure holds the layers
   on it. Each layer is held in the plane at two nodes (``hold_film_centre``).
3. Settling: with friction (``AssemblySettings.friction``), mass-proportional damping (an
   assembly aid, :attr:`Model.mass_damping`) and the integrator's full high-frequency
   dissipation (``settle_rho_inf``) the consignment comes to rest; the run stops when the
   kinetic energy is below ``kinetic_tolerance`` or after ``max_settle_time``.

The three phases are three models of the same mesh (node numbering is identical by
construction); the state carries over. The result is a :class:`Snapshot` at rest, its shape
checked (:mod:`flexparcel.consignments.shape`: outer size against Table 2, the film on its
content, no content outside).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.consignments.assembly_checkpoint import AssemblyCheckpoint, AssemblyPosition
from flexparcel.consignments.build import (
    Consignment,
    ConsignmentBuild,
    add_consignment,
    default_packaging_content_law,
)
from flexparcel.consignments.shape import check_shape, content_outside_packaging
from flexparcel.consignments.snapshot import Snapshot
from flexparcel.contact.law import ContactLaw
from flexparcel.elements.solid import SolidGroup
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.dynamic import IntegratorOptions
from flexparcel.io.checkpoint import model_fingerprint
from flexparcel.model.model import BoxGrowth, Model, State
from flexparcel.model.schedule import Schedule
from flexparcel.simulate import ModelStepper, simulate

__all__ = [
    "AssemblySettings",
    "AssemblyError",
    "assemble",
    "content_scale_for",
    "content_outside_packaging",
    "opening_clearance",
]


ASSEMBLY_FRICTION = ("none", "regularised", "stick")
CLOSING_FRAMES = 20
"""Output frames of the closing: where its run checkpoint can be written (KP at 10 mm closes
in some 35 min of wall time)."""
FINE_OPENING_SIZE = 0.015
"""Shells finer than this [m] open round a shrunk content (:func:`content_scale_for`)."""


def _assembly_law(friction: str) -> ContactLaw:
    """The packaging-content law of the assembly: Table 6's normal law with ``friction``
    ("none": mu = 0; "regularised": eq. 8; "stick": the stick model)."""
    law = default_packaging_content_law(stick_model=friction == "stick")
    if friction == "none":
        law = replace(law, mu_static=0.0, mu_dynamic=0.0)
    return law


class AssemblyError(RuntimeError):
    """The packaging could not be opened, did not come to rest or came to rest in a wrong
    shape (:func:`flexparcel.consignments.shape.check_shape`). ``unsettled``: the state at
    the end of the settling (a :class:`Snapshot`; its ``info["shape"]`` holds the shape's
    figures) in the last two cases, else None."""

    def __init__(self, message: str, unsettled: Snapshot | None = None) -> None:
        super().__init__(message)
        self.unsettled = unsettled


@dataclass(frozen=True)
class AssemblySettings:
    """Settings of :func:`assemble` (SI units)."""

    opening_pressure: float = 5000.0
    """Largest opening force per layer divided by the flat packaging area [Pa], spread
    equally over the layer's nodes. The force grows geometrically from
    ``opening_start_pressure``, doubling every ``opening_doubling_time``, up to this value,
    and stops growing as soon as the packaging is open (a flat envelope only opens by bending
    at its border and stretching, so the force needed depends strongly on the material and
    the mesh; the ramp finds it: 5.0 kPa for KP/BW's bubble wrap at 25 mm, 0.5 kPa for KP's
    kraft paper). The linear ramp used before (25 kPa/s) had reached 250 Pa when PB's
    55 g/m^2 film opened, by then moving at some 20 m/s (impulse over areal density), and the
    film ended ballooned to +-48 mm; the slow start avoids throwing a light film open. (An
    experiment with 100x film mass also ballooned; the balloon went only with the wrap-round
    contact fix of :func:`flexparcel.contact.geometry.side_used`.)"""
    opening_start_pressure: float = 1.0
    opening_doubling_time: float = 0.01
    check_every: float = 0.005
    max_opening_time: float = 0.2
    margin: float = 1.5e-3
    """Clearance [m] between content and packaging required before the contact goes on."""
    release_time: float = 0.03
    max_settle_time: float = 0.4
    settle_chunk: float = 0.05
    kinetic_tolerance: float = 2e-6
    """Kinetic energy [J] below which the consignment counts as at rest: a mean speed of
    5 mm/s for PB's 180 g (the lightest paper consignment, BW's 80 g: 7 mm/s). PB's film at
    25 mm kept 1.1e-6 to 1.1e-5 J through 0.3 s of settling (its stick contacts on the
    flexible content let go and catch again), where the other three came below 1e-7 J; the
    bound was 1e-6 J before."""
    mass_damping: float = 80.0
    """Rayleigh alpha [1/s] during the assembly (critical for modes near 40 rad/s)."""
    settle_rho_inf: float = 0.0
    """Spectral radius at infinite step of the integrator while settling, in [0, 1] (the
    opening and closing use the assembly's options, rho_inf 0.5). 0 annihilates unresolved
    high-frequency motion within a step (Chung & Hulbert 1993). A film node resting on its
    content has a local mode of some 4,000 rad/s (34 mg against the film's tension, PB at
    25 mm) that bounces on the stiff contact (649 N/mm, unresolved at ~80 us steps): with
    rho_inf 0.5 the scheme's acceleration memory fed each bounce (a node bounced off at
    64 mm/s and fell back at 96 mm/s), and PB's film kept 1e-6 to 1e-5 J through 0.35 s,
    with mass damping 500 1/s still 1e-7 to 1e-6 J; with 0 it came to 3e-8 J within 0.01 s.
    The settling is a means to the static state, so its numerical dissipation costs no
    physics."""
    tol_displacement: float = 2e-4
    content_scale: float | None = None
    """Size of the content (all three dimensions), as a fraction of its real size, while the
    packaging is opened; it grows back to full size over ``growth_time`` once the contact is on. A
    content that nearly fills its packaging (PB, KP, BW: the flat envelope is only a few mm
    longer than the content's length + height) cannot be cleared by opening forces, since an
    opened envelope's section is a lens, not a rectangle; growing it inside the closed
    packaging pushes the film into shape instead (for KP it also lifts the content's lower
    face off the bottom layer, which the glue stripe keeps close to it while the border is
    pulled up). ``None``: :func:`content_scale_for`."""
    growth_time: float = 0.1
    closing_pressure: float = 50.0
    """While a shrunk content grows back, the layers are pressed onto it with this pressure
    [Pa] (the opening force reversed), released over ``release_time`` before the growth
    ends: in the assembly's zero gravity nothing else closes a limp film left open."""
    hold_film_centre: bool = True
    """Hold the top and bottom layers' centre nodes in x and y, and one more node of each on
    its centre line in y, during the closing; they are released for the settling (the
    opening pulls them straight up, so they have not moved in the plane). In the
    frictionless closing nothing else holds a film in the plane on its growing content: PB's
    film at 25 mm slid 35 mm and turned by 10 degrees, and the content came out through a
    seam; held at its centre node only, it still turned by 10 degrees about it."""
    friction: str = "stick"
    """Friction of the packaging-content and layer-on-layer contacts while the consignment
    settles: "stick" (the stick model, as in the tests; default), "regularised" (the paper's
    eq. 8) or "none". BW at 25 mm settled with the stick model in 0.05 s simulated (57 s
    wall for the whole assembly); with eq. 8 its Newton iterations cycled at 30-70 us steps
    (see :func:`flexparcel.consignments.build.default_packaging_content_law`).
    The closing before it (release and content growth) is always frictionless: the growth is
    an assembly device, not physics, and a growing content's faces, expanding under the film,
    would drag it along so that it cannot slide round the corners (KP at 25 mm with the
    regularised law throughout was pressed 1.9 mm into its content, at 6.7 us steps, halfway
    through the growth). Friction while settling keeps the film from sliding off-centre along
    its content (frictionless throughout, BW's film ended 19 mm off-centre). The tests after
    the assembly use their own friction."""

    def __post_init__(self) -> None:
        if self.friction not in ASSEMBLY_FRICTION:
            raise ValueError(
                f"AssemblySettings.friction must be one of {', '.join(ASSEMBLY_FRICTION)}, "
                f"got {self.friction!r}"
            )
        # every field is a positive number except these, checked below
        special = ("friction", "content_scale", "settle_rho_inf", "hold_film_centre")
        for k, v in asdict(self).items():
            if k not in special and not (np.isfinite(v) and v > 0):
                raise ValueError(f"AssemblySettings.{k} must be > 0, got {v!r}")
        if not isinstance(self.hold_film_centre, bool):
            raise ValueError(
                f"AssemblySettings.hold_film_centre must be true or false, "
                f"got {self.hold_film_centre!r}"
            )
        r = self.settle_rho_inf
        if isinstance(r, bool) or not (isinstance(r, int | float) and 0.0 <= r <= 1.0):
            raise ValueError(f"AssemblySettings.settle_rho_inf must be in [0, 1], got {r!r}")
        if self.content_scale is not None and not 0.3 <= self.content_scale <= 1.0:
            raise ValueError(
                f"AssemblySettings.content_scale must be in [0.3, 1], got {self.content_scale!r}"
            )


def _model(build: ConsignmentBuild, settings: AssemblySettings, contact: bool,
           forces: Schedule | None, friction: str,
           hold: tuple[np.ndarray, np.ndarray] | None = None
           ) -> tuple[Model, Consignment]:  # fmt: skip
    """The assembly model: no gravity, mass damping, the content contact on or off with
    ``friction`` (see :func:`_assembly_law`), opening forces on the layers by ``forces``
    (None: none), nodes ``hold[0]`` held in x and y and ``hold[1]`` in y (None: none)."""
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0), mass_damping=settings.mass_damping)
    c = add_consignment(
        b,
        build,
        content_law=_assembly_law(friction),
        content_contact=Schedule.constant(1.0 if contact else 0.0),
    )
    if forces is not None:
        length, width = build.flat_size
        total = settings.opening_pressure * length * width
        b.add_force(c.top, (0.0, 0.0, total / len(c.top)), schedule=forces)
        b.add_force(c.bottom, (0.0, 0.0, -total / len(c.bottom)), schedule=forces)
    if hold is not None:
        b.fix(hold[0], ["x", "y"])
        b.fix(hold[1], ["y"])
    return b.finalize(), c


def _held_nodes(model: Model, c: Consignment) -> tuple[np.ndarray, np.ndarray]:
    """The top and the bottom layer's node nearest the packaging's centre (to be held in x and
    y), and each layer's node nearest the point 40 % of the layer's length further along x
    (held in y: with the first, it keeps the layer from turning about z)."""
    centre, along = [], []
    for ids in (c.top, c.bottom):
        p = model.positions0[ids, :2]
        mid = p.mean(axis=0)
        centre.append(ids[np.argmin(np.sum((p - mid) ** 2, axis=1))])
        far = mid + (0.4 * np.ptp(p[:, 0]), 0.0)
        along.append(ids[np.argmin(np.sum((p - far) ** 2, axis=1))])
    return np.array(centre), np.array(along)


def _opening_schedule(st: AssemblySettings) -> Schedule:
    """Opening force factor (of ``opening_pressure``) in time: p_start 2^(t / t_double),
    capped at 1, sampled every quarter doubling time (piecewise linear in between)."""
    p0 = st.opening_start_pressure / st.opening_pressure
    if p0 >= 1.0:
        return Schedule.constant(1.0)
    t_full = st.opening_doubling_time * np.log2(1.0 / p0)
    dt = st.opening_doubling_time / 4.0
    times = np.arange(0.0, t_full, dt)
    values = p0 * 2.0 ** (times / st.opening_doubling_time)
    return Schedule(tuple(times) + (t_full + dt,), tuple(values) + (1.0,))


def content_scale_for(build: ConsignmentBuild) -> float:
    """The automatic :attr:`AssemblySettings.content_scale` of ``build``: 0.6 when a flat
    envelope side is shorter than the content side + 3 x its height (PB, KP, BW), or when
    the shells are finer than :data:`FINE_OPENING_SIZE`; else 1 (no growth).

    Why the mesh matters: opening forces on a flat envelope make a pillow, whose film must
    shorten along its border. A fine film does that in wrinkles and stays flat over the
    content's footprint; a coarse one cannot wrinkle and bulges. KP/BW (75 mm of slack round
    a 20 mm content) opened at 25 mm, but at 10 mm its top layer still cut 10.9 mm into the
    content after 0.2 s at 5 kPa, and 12.6 mm after 0.3 s at 20 kPa; opened round a content
    at 0.6 of its size and grown back, it assembled in 388 s (shape within Table 2)."""
    spec = build.spec
    length, width = build.flat_size
    hc = spec.content_height_mm * 1e-3
    slack = min(length - spec.content_length_mm * 1e-3, width - spec.content_width_mm * 1e-3)
    return 0.6 if slack < 3.0 * hc or build.element_size < FINE_OPENING_SIZE else 1.0


def _solid_groups(model: Model) -> list[SolidGroup]:
    """The model's solid element groups (a flexible content), in the order they were added."""
    return [g for g in model.element_groups if isinstance(g, SolidGroup)]


def _scale_content(
    model: Model, c: Consignment, s: State | None, f: float | Schedule, xref_full: list
) -> None:
    """Give the content ``f`` times its size (a number or a Schedule of it): a rigid content
    through ``Model.box_growth``, a flexible one through its solid groups' ``growth`` (their
    full-size reference geometry ``xref_full``, one array per solid group, scaled at every
    step: a jump would shock the elements and their contacts) and, if ``s`` is given, its
    nodes about the content centre (by ``f`` at ``s.time``)."""
    sched = f if isinstance(f, Schedule) else Schedule.constant(f)
    if c.content_body is not None:
        outer = np.asarray(c.content_box, dtype=float) / 2
        model.box_growth[:] = [BoxGrowth(c.content_body, outer, sched)]
        return
    t = 0.0 if s is None else s.time
    for g, xref0 in zip(_solid_groups(model), xref_full, strict=True):
        g.growth = (xref0, sched)
        g.at_time(t)
    if s is not None:
        p = s.positions[c.content_nodes]
        centre = 0.5 * (p.min(axis=0) + p.max(axis=0))
        s.positions[c.content_nodes] = centre + (p - centre) * sched(t)


def _content_extent(c: Consignment, s: State, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi) of the content [m] in state ``s`` (a rigid content with
    ``scale`` times its size)."""
    if c.content_body is not None:
        half = np.asarray(c.content_box) / 2 * scale
        r = s.rotations[c.content_body]
        ext = np.abs(r) @ half
        p = s.positions[c.content_body]
        return p - ext, p + ext
    p = s.positions[c.content_nodes]
    return p.min(axis=0), p.max(axis=0)


def opening_clearance(c: Consignment, s: State, scale: float = 1.0) -> float:
    """Smallest gap [m] between the content's top/bottom faces and the packaging layers over
    the content's footprint (negative while a layer still cuts through the content); a rigid
    content counted with ``scale`` times its size."""
    lo, hi = _content_extent(c, s, scale)
    gaps = [np.inf]
    for ids, sign in ((c.top, 1.0), (c.bottom, -1.0)):
        p = s.positions[ids]
        over = np.all((p[:, :2] >= lo[:2]) & (p[:, :2] <= hi[:2]), axis=1)
        if np.any(over):
            z = p[over, 2]
            gaps.append(float(np.min(z - hi[2])) if sign > 0 else float(np.min(lo[2] - z)))
    return min(gaps) - c.contact_radius


def _settle_deadline(st: AssemblySettings, t_open: float, f0: float) -> float:
    """Latest end [s] of the settling: release, growth (if any) and ``max_settle_time``."""
    return t_open + st.release_time + (st.growth_time if f0 < 1.0 else 0.0) + st.max_settle_time


def _default_options(st: AssemblySettings) -> IntegratorOptions:
    # Newton relaxation: in PB's closing (25 mm) the film's many light nodes switching on
    # and off its content's faces made full Newton steps cycle; with it 49 Newton failures
    # up to t = 0.16 s instead of 290
    return IntegratorOptions(
        rho_inf=0.5,
        tol_displacement=st.tol_displacement,
        impact_limit="rigid",
        error_estimate="smooth",
        newton_relaxation=True,
    )


class _Assembly:
    """One run of :func:`assemble`: its three phases, the step count and wall time, and the
    checkpoint (None: none) that each chunk's end is saved to and a resumed run starts from."""

    def __init__(self, build: ConsignmentBuild, st: AssemblySettings, opt: IntegratorOptions,
                 progress: Callable[[str, float], None] | None,
                 checkpoint: str | Path | None) -> None:  # fmt: skip
        self.build, self.st, self.opt, self.progress = build, st, opt, progress
        self.wall0, self.steps = time.perf_counter(), 0
        self.f0 = content_scale_for(build) if st.content_scale is None else st.content_scale
        self.opening = _opening_schedule(st)
        self.model_a, self.c = _model(build, st, False, self.opening, "none")
        self.xref_full = [g.xref.copy() for g in _solid_groups(self.model_a)]
        self.t_open: float | None = None
        self.ck = None
        self.saved: AssemblyPosition | None = None
        if checkpoint is not None:
            header = {
                "consignment": build.spec.id,
                "element_size": float(build.element_size),
                "settings": asdict(st),
                "options": asdict(opt),
                "model": model_fingerprint(self.model_a),
            }
            self.ck = AssemblyCheckpoint(checkpoint, header)
            self.saved = self.ck.load()
        self.wall_before = 0.0 if self.saved is None else self.saved.wall_s

    def wall(self) -> float:
        """Wall time [s] of the assembly so far, over all its runs."""
        return self.wall_before + time.perf_counter() - self.wall0

    def save(self, phase: str, s: State, history: dict[str, np.ndarray]) -> None:
        if self.ck is not None:
            self.ck.save(AssemblyPosition(phase, s, history, self.steps, self.t_open, self.wall()))

    def resumed(self, phase: str, stepper: ModelStepper | None = None) -> State | None:
        """The saved state if the checkpoint stands in ``phase`` (its stepper, if given, goes
        on from the saved history), else None."""
        if self.saved is None or self.saved.phase != phase:
            return None
        saved, self.saved = self.saved, None
        self.steps, self.t_open = saved.steps, saved.t_open
        if stepper is not None:
            stepper.resume(saved.state, saved.history)
        return saved.state

    def open(self) -> State:
        """Opening forces until the content clears the layers by ``margin``."""
        st, c, f0 = self.st, self.c, self.f0
        s = self.model_a.initial_state()
        if f0 < 1.0:  # also when resumed: the model's content is scaled, too
            _scale_content(self.model_a, c, s, f0, self.xref_full)
        # one integrator through all opening chunks: a fresh one per chunk started again
        # from dt_initial and halved its way down (KP at 10 mm: 8 Newton failures at the
        # start of every 5 ms chunk); ModelStepper.begin goes on from where the last stopped
        stepper = ModelStepper(self.model_a, self.opt)
        if self.saved is not None and self.saved.phase != "opening":
            return s  # the opening is behind the checkpoint
        saved = self.resumed("opening", stepper)
        s = s if saved is None else saved
        while opening_clearance(c, s, f0) < st.margin:
            if s.time >= st.max_opening_time:
                raise AssemblyError(
                    f"{self.build.spec.id}: the packaging did not open enough in "
                    f"{st.max_opening_time} s (clearance {opening_clearance(c, s, f0) * 1e3:.2f}"
                    f" mm < margin {st.margin * 1e3:.2f} mm); raise "
                    f"AssemblySettings.opening_pressure or lower content_scale (now {f0:g})"
                )
            r = simulate(self.model_a, s.time + st.check_every, dt_out=st.check_every,
                         state=s, stepper=stepper)  # fmt: skip
            s, self.steps = r.final_state, r.stats["steps"]  # the stepper's count runs on
            self.save("opening", s, stepper.history())
            if self.progress:
                self.progress("opening", s.time)
        self.t_open = s.time
        return s

    def close(self, s: State) -> State:
        """Contact on (frictionless), forces released, a shrunk content grown back."""
        st, f0 = self.st, self.f0
        saved = self.resumed("closed")
        if saved is not None:
            return saved
        if self.saved is not None:  # in the settling: settle() takes its state
            return s
        t_open = self.t_open
        t_closed = t_open + st.release_time
        held = _held_nodes(self.model_a, self.c) if st.hold_film_centre else None
        if f0 < 1.0:
            # the content grows back once the forces are released, continuously (a jump
            # would be a jump in penetration or in the elements' strain), the layers pressed
            t_end = t_closed + st.growth_time
            t_pressed = max(t_closed + 0.5 * st.growth_time, t_end - st.release_time)
            press = -st.closing_pressure / st.opening_pressure
            release = Schedule((t_open, t_closed, t_pressed, t_end),
                               (self.opening(t_open), press, press, 0.0))  # fmt: skip
            model_b, self.c = _model(self.build, st, True, release, "none", held)
            growth = Schedule((t_closed, t_end), (f0, 1.0))
            _scale_content(model_b, self.c, None, growth, self.xref_full)
        else:
            t_end = t_closed
            release = Schedule((t_open, t_closed), (self.opening(t_open), 0.0))
            model_b, self.c = _model(self.build, st, True, release, "none", held)
        # one simulate() call (the release and the growth are one schedule), reported as it
        # goes; it resumes from its own run checkpoint, written at one of its
        # CLOSING_FRAMES output frames once a minute of wall time has passed since the last
        prog = None if self.progress is None else (lambda t, _: self.progress("closing", t))
        ck = None if self.ck is None else self.ck.closing_path()
        r = simulate(model_b, t_end, dt_out=(t_end - s.time) / CLOSING_FRAMES, options=self.opt,
                     state=s, progress=prog, checkpoint=ck)  # fmt: skip
        s, self.steps = r.final_state, self.steps + r.stats["steps"]
        self.save("closed", s, {})
        return s

    def settle(self, s: State) -> tuple[Model, State, float]:
        """Friction on, forces off, chunks of ``settle_chunk`` until at rest or the deadline;
        returns the model, the state and its kinetic energy [J]."""
        st = self.st
        model_c, self.c = _model(self.build, st, True, None, st.friction)
        # one integrator through all settling chunks, as through the opening's
        stepper = ModelStepper(model_c, replace(self.opt, rho_inf=st.settle_rho_inf))
        steps_before = self.steps
        saved = self.resumed("settling", stepper)
        if saved is not None:  # the stepper's count runs on from the saved history
            s, steps_before = saved, self.steps - stepper.statistics()["steps"]
        kin = asm.kinetic_energy(model_c, s.velocities, s.rotations)
        while kin >= st.kinetic_tolerance and s.time < _settle_deadline(st, self.t_open, self.f0):
            t_end = s.time + st.settle_chunk
            r = simulate(model_c, t_end, dt_out=t_end - s.time, state=s, stepper=stepper)
            s, self.steps = r.final_state, steps_before + r.stats["steps"]
            kin = asm.kinetic_energy(model_c, s.velocities, s.rotations)
            self.save("settling", s, stepper.history())
            if self.progress:
                self.progress("settling", s.time)
        return model_c, s, kin

    def snapshot(self, model_c: Model, s: State, kin: float) -> Snapshot:
        """The settled snapshot, its shape checked; raises :class:`AssemblyError` (with the
        state) if it is not at rest or in a wrong shape."""
        st, c, build = self.st, self.c, self.build
        info = {
            "settings": asdict(st),
            # plain Python numbers: the info goes to JSON and must read back equal
            "opening_time_s": float(self.t_open),
            "opening_pressure_Pa": float(st.opening_pressure * self.opening(self.t_open)),
            "content_scale": float(self.f0),
            "end_time_s": float(s.time),
            "kinetic_energy_J": float(kin),
            "steps": int(self.steps),
            "wall_s": self.wall(),
            "packaging_mass_kg": float(c.packaging_mass),
            "content_mass_kg": float(c.content_mass),
            "at_rest": bool(kin < st.kinetic_tolerance),
        }
        shape = check_shape(model_c, c, s.positions, s.rotations)
        # content nodes the closed packaging does not hold (see content_outside_packaging)
        info["content_nodes_outside"] = shape.content_outside
        info["shape"] = shape.to_dict()
        info["wall_s"] = self.wall()
        n = model_c.node_count
        snap = Snapshot(build, model_c.positions0[:n].copy(), s.positions.copy(),
                        s.rotations.copy(), info)  # fmt: skip
        if not info["at_rest"]:
            raise AssemblyError(
                f"{build.spec.id}: not at rest after {st.max_settle_time} s of settling "
                f"(kinetic energy {kin:.3g} J >= {st.kinetic_tolerance:g} J)",
                unsettled=snap,
            )
        if shape.failures():
            raise AssemblyError(
                f"{build.spec.id}: at rest in a wrong shape: " + "; ".join(shape.failures()),
                unsettled=snap,
            )
        return snap


def assemble(
    build: ConsignmentBuild,
    settings: AssemblySettings | None = None,
    *,
    options: IntegratorOptions | None = None,
    progress: Callable[[str, float], None] | None = None,
    checkpoint: str | Path | None = None,
) -> Snapshot:
    """Open, fill, close and settle ``build``; returns the settled :class:`Snapshot`.

    ``progress(phase, simulated_time)`` is called after every chunk. ``checkpoint``: an
    ``.npz`` path (:mod:`flexparcel.consignments.assembly_checkpoint`); the assembly saves
    its position there after every chunk (the closing every minute of wall time) and, if the
    file exists, resumes from it exactly as if uninterrupted. It is removed when the assembly
    ends, at rest or not; an error of the integrator leaves it for a look at the state.
    """
    st = settings or AssemblySettings()
    run = _Assembly(build, st, options or _default_options(st), progress, checkpoint)
    s = run.close(run.open())
    model_c, s, kin = run.settle(s)
    try:
        return run.snapshot(model_c, s, kin)
    finally:  # the assembly has ended, at rest or not: nothing to resume
        if run.ck is not None:
            run.ck.remove()
