"""Model (static arrays, element groups, contact sets) and State (time-varying arrays).

Every node carries 6 DOFs ``[x, y, z, spin_x, spin_y, spin_z]``: three translations [m] and a
rotation (stored as a rotation matrix; variations are spatial spins [rad]).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flexparcel.model.interfaces import ContactSet, ElementGroup
from flexparcel.model.schedule import Schedule

__all__ = ["Model", "State", "BoxGrowth", "DOFS_PER_NODE", "PACKED_LAW_SIZE"]

DOFS_PER_NODE = 6
PACKED_LAW_SIZE = 15
"""Length of a packed contact law row (checked against flexparcel.contact.law.PACKED_SIZE)."""


@dataclass(frozen=True)
class BoxGrowth:
    """A rigid body's rounded box growing in time: contact uses ``factor(t) * outer_half -
    edge radius`` as the inner half sizes."""

    node: int
    """The rigid body's node."""
    outer_half: np.ndarray
    """Outer half sizes at factor 1 [m], shape (3,)."""
    schedule: Schedule
    """The size factor over time."""


@dataclass
class Model:
    """Compiled model: flat arrays plus element groups and contact sets, each owning its
    kernels. Build it with :class:`flexparcel.builder.ModelBuilder`."""

    positions0: np.ndarray
    """Reference node positions [m], shape (node_count, 3)."""
    mass: np.ndarray
    """Lumped mass [kg] and rotational inertia [kg m^2] per DOF, shape (node_count, 6)."""
    gravity: np.ndarray
    """Gravitational acceleration [m/s^2], shape (3,)."""
    fixed: np.ndarray
    """True where a DOF is held at its reference value, shape (node_count, 6)."""
    load_nodes: np.ndarray
    """Node of each nodal load, shape (k,)."""
    load_vectors: np.ndarray
    """Force [N] or moment [N m] per node at factor 1, shape (k, 3)."""
    load_is_moment: np.ndarray
    """True for moments, shape (k,)."""
    load_follower: np.ndarray
    """True if the load rotates with its node, shape (k,)."""
    load_schedule: np.ndarray
    """Index into ``schedules`` per load, shape (k,)."""
    schedules: list[Schedule]
    gravity_schedule: Schedule
    cells: list[tuple[str, np.ndarray]]
    """The user's cells for output: ("quad", (q,4)) and/or ("triangle", (t,3))."""
    element_groups: list[ElementGroup]
    """Element groups (shells, solids, ...), each with its own data and kernels."""
    # sparse pattern over the free DOFs
    free_index: np.ndarray
    """Free-DOF number of each DOF or -1 if fixed, shape (node_count * 6,)."""
    csr_indptr: np.ndarray
    csr_indices: np.ndarray
    load_emap: np.ndarray
    """CSR data slots of the (translation|rotation rows, spin cols) 3x3 blocks of each load's
    node, shape (k, 2, 3, 3); used for the follower-load stiffness."""
    diag_slots: np.ndarray
    """CSR data slot of each free DOF's diagonal, shape (free_count,)."""
    rigid_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Node of each rigid body (its centre of mass), shape (k,)."""
    rigid_inertia: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    """Inertia about the centre in the body frame [kg m^2], shape (k, 3, 3)."""
    rigid_half_inner: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Half sizes of each body's inner box [m], shape (k, 3) (rounded box = inner box + r)."""
    rigid_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Edge radius of each rounded box [m], shape (k,)."""
    rigid_rot_slots: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3), np.int64))
    """CSR data slots of each free body's rotation-rotation block, shape (k, 3, 3)."""
    prescribed_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Nodes moving with a prescribed velocity, shape (p,)."""
    prescribed_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    """Their [v, omega] [m/s, rad/s] at schedule factor 1, shape (p, 6)."""
    prescribed_schedules: list = field(default_factory=list)
    """Schedule scaling each prescribed velocity, (p,) (see :class:`PrescribedMotion`)."""
    node_block_slots: np.ndarray = field(default_factory=lambda: np.zeros((0, 6, 6), np.int64))
    """CSR data slots of every node's own 6x6 block, shape (node_count, 6, 6)."""
    plane_point: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """A point of each rigid plane [m], shape (k, 3)."""
    plane_normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Unit normal of each plane, out of its solid side, shape (k, 3)."""
    plane_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Tangential surface velocity of each plane (a belt) [m/s], shape (k, 3)."""
    plane_axis: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Unit length direction of each bounded plane (zeros for a half-space), shape (k, 3)."""
    plane_extent: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Half length, half width and edge radius [m] of each bounded plane (all 0: a half-space;
    :class:`~flexparcel.contact.planes.PlaneBounds`), shape (k, 3)."""
    contact_laws: np.ndarray = field(default_factory=lambda: np.zeros((0, PACKED_LAW_SIZE)))
    """Packed contact laws (see ContactLaw.packed), shape (L, PACKED_LAW_SIZE)."""
    contact_schedules: list = field(default_factory=list)
    """Schedules switching contact sets on (1) and off (0), indexed by ``schedule_index``."""
    contact_sets: list[ContactSet] = field(default_factory=list)
    """Contact sets, each with its kernels, candidates and history (see ContactSet)."""
    box_half_by_node: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Inner half sizes of the rounded box carried by each node (zero if none) [m], (n, 3)."""
    box_radius_by_node: np.ndarray = field(default_factory=lambda: np.zeros(0))
    box_growth: list[BoxGrowth] = field(default_factory=list)
    """Rounded boxes whose size changes in time (the assembly grows a content into its
    packaging), see :class:`BoxGrowth`."""
    free_count: int = -1
    """Number of unknowns; ``free_index`` values >= free_count are FDR slave DOFs."""
    slave_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Nodes rigidly tied (FDR / fixed joint) to a master node, shape (s,)."""
    slave_master: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Master node of each slave (always a root master), shape (s,)."""
    slave_offset: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Offset of each slave from its master in the master's body frame [m], shape (s, 3)."""
    mass_damping: float = 0.0
    """Mass-proportional (Rayleigh alpha) damping [1/s]: a force -alpha M v on every node.
    Not a material property: an aid that brings assembly and settling runs to rest quickly
    (it also damps rigid motion), 0 for the tests themselves."""

    @property
    def node_count(self) -> int:
        return self.positions0.shape[0]

    @property
    def dof_count(self) -> int:
        """Number of unknowns (free DOFs of nodes that are not FDR slaves)."""
        return int(self.free_count) if self.free_count >= 0 else int(self.diag_slots.shape[0])

    @property
    def ext_count(self) -> int:
        """Unknowns plus the DOFs of FDR slave nodes (the size of assembled matrices)."""
        return int(self.diag_slots.shape[0])

    @property
    def nnz(self) -> int:
        return int(self.csr_indices.shape[0])

    @property
    def has_contact(self) -> bool:
        """Whether any contact set is defined."""
        return bool(self.contact_sets)

    @property
    def has_monitored_contact(self) -> bool:
        """Whether any contact set is monitored (its impulse recorded by the integrator)."""
        return any(cs.monitored for cs in self.contact_sets)

    def prescribed_motion(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Velocities (p, 6) [m/s, rad/s] of the prescribed nodes at ``time`` [s] and the
        integral of their schedules S(t) (p,) [s] (see :class:`PrescribedMotion`)."""
        fac = np.array([s(time) for s in self.prescribed_schedules]).reshape(-1, 1)
        area = np.array([s.integral(time) for s in self.prescribed_schedules])
        return self.prescribed_velocity * fac, area

    def box_half_at(self, time: float) -> np.ndarray:
        """Inner half sizes [m] of the rounded box carried by each node at ``time`` [s]
        (``box_growth`` applied), shape (node_count, 3)."""
        if not self.box_growth:
            return self.box_half_by_node
        half = self.box_half_by_node.copy()
        for g in self.box_growth:
            scaled = np.asarray(g.outer_half, dtype=float) * g.schedule(time)
            half[g.node] = np.maximum(scaled - self.box_radius_by_node[g.node], 0.0)
        return half

    def element_nodes(self) -> np.ndarray:
        """Nodes used by any element group, shape (k,)."""
        parts = [g.nodes() for g in self.element_groups]
        return np.unique(np.concatenate(parts)) if parts else np.zeros(0, np.int64)

    def initial_state(self) -> State:
        n = self.node_count
        vel = np.zeros((n, 6))
        vel[self.prescribed_nodes] = self.prescribed_motion(0.0)[0]
        return State(
            time=0.0,
            positions=self.positions0.copy(),
            rotations=np.tile(np.eye(3), (n, 1, 1)),
            velocities=vel,
            accelerations=np.zeros((n, 6)),
        )

    def total_mass(self) -> float:
        """Total mass [kg]."""
        return float(self.mass[:, 0].sum())


@dataclass
class State:
    """Time-varying state. Angular quantities are spatial (world components)."""

    time: float
    positions: np.ndarray
    """Node positions [m], shape (node_count, 3)."""
    rotations: np.ndarray
    """Nodal rotation matrices from the reference, shape (node_count, 3, 3)."""
    velocities: np.ndarray
    """[v (m/s), omega (rad/s)] per node, shape (node_count, 6)."""
    accelerations: np.ndarray
    """Algorithmic accelerations of the generalized-alpha scheme, shape (node_count, 6)."""

    def copy(self) -> State:
        return State(
            self.time,
            self.positions.copy(),
            self.rotations.copy(),
            self.velocities.copy(),
            self.accelerations.copy(),
        )
