"""The two plug-in interfaces of a :class:`~flexparcel.model.model.Model`: element groups and
contact sets.

A model holds a list of each. The integrator, the static solver, the checkpoint code and the
group-by-group conveyor loop over these lists and never name a kind, so a new element or a new
contact pair is one module that implements one of these classes plus one call that adds an
instance to a :class:`~flexparcel.builder.ModelBuilder` (``add_element_group`` /
``add_contact_set``). The kernels live in :mod:`flexparcel.elements` and
:mod:`flexparcel.contact`; this module (the ground) only states what they promise.

DOF numbering used throughout: node ``i`` carries the global DOFs ``6 i + d`` with ``d`` in
``x y z spin_x spin_y spin_z``; matrices are assembled into CSR data arrays over the model's
free and FDR-slave DOFs (``Model.free_index``), with one trailing trash slot for fixed DOFs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# Model and State (flexparcel.model.model) hold lists of these classes; they are named in
# annotations as Any so that the two modules do not import each other
Model = State = Any

__all__ = [
    "ElementGroup",
    "TranslationalElementGroup",
    "ContactSet",
    "ContactContext",
    "ContactOutput",
]


class ElementGroup(ABC):
    """Elements of one kind and material data, with their kernels.

    Subclasses hold flat arrays (numba kernels take them directly) and implement the force and
    tangent evaluations. The builder calls :meth:`element_dofs` to lay out the sparse pattern
    and :meth:`bind` to hand back each element matrix entry's CSR data slot.
    """

    kind: str = "element"
    """Short name of the element kind, e.g. ``"shell"``; also the checkpoint key prefix."""

    @abstractmethod
    def element_dofs(self) -> np.ndarray:
        """Global DOF numbers (``6 node + d``) of each element's matrix rows, shape (m, w)."""

    @abstractmethod
    def bind(self, slots: np.ndarray) -> None:
        """Store the CSR data slot of each element matrix entry, shape (m, w, w)."""

    @abstractmethod
    def lumped_mass(self, node_count: int) -> np.ndarray:
        """Lumped mass [kg] and rotary inertia [kg m^2] per node DOF, shape (node_count, 6)."""

    @abstractmethod
    def nodes(self) -> np.ndarray:
        """Nodes the group's elements use, shape (k,)."""

    def rotation_nodes(self) -> np.ndarray:
        """Nodes whose rotations the group gives stiffness and inertia (others are held
        unless something else carries them), shape (k,)."""
        return np.zeros(0, np.int64)

    @abstractmethod
    def forces(self, positions, rotations, velocities, out: np.ndarray) -> float:
        """Add the elastic plus Rayleigh damping forces [N, N m] to ``out`` (n, 6); returns the
        strain energy [J]. A configuration without a meaningful force (an inverted element)
        writes NaN into ``out`` so that the step is rejected."""

    @abstractmethod
    def forces_and_tangent(
        self, positions, rotations, velocities, out, data_k, data_c, consistent: bool
    ) -> float:
        """As :meth:`forces`, and add ``K = df/dq`` and ``C = df/dv`` into the CSR data arrays
        ``data_k``, ``data_c`` (nnz + 1,). ``consistent=False`` allows the material tangent."""

    def output_cells(self) -> list[tuple[str, np.ndarray]]:
        """Cells for output files as (meshio cell type, connectivity) pairs."""
        return []

    def node_pairs(self) -> np.ndarray:
        """Node pairs (k, 2) joined by an element edge (self contact ignores them)."""
        return np.zeros((0, 2), np.int64)

    def characteristic_length(self) -> float | None:
        """Typical element size [m] (converts rotation corrections into lengths for the
        Newton test), None where the group has no rotations."""
        return None

    def at_time(self, time: float) -> None:  # noqa: B027 (a no-op by default)
        """Update time-dependent reference data (e.g. a content grown into its packaging)."""

    def fingerprint_arrays(self) -> list[np.ndarray]:
        """Arrays that identify the group's dynamics (a checkpoint belongs to one model)."""
        return [np.array(self.kind), self.element_dofs()]


class TranslationalElementGroup(ElementGroup):
    """An element group whose elements ``cells`` (m, k) carry the three translations of each
    node (solids, air drag) and whose force and tangent come from one evaluation,
    :meth:`_evaluate`, with the same (material) tangent for both tangent modes."""

    cells: np.ndarray
    """Node ids per element, shape (m, k)."""
    emap: np.ndarray
    """CSR data slot of each element matrix entry, shape (m, 3k, 3k)."""

    def element_dofs(self) -> np.ndarray:
        m, k = self.cells.shape
        return (6 * self.cells[:, :, None] + np.arange(3)).reshape(m, 3 * k)

    def bind(self, slots: np.ndarray) -> None:
        self.emap = np.ascontiguousarray(slots)

    def nodes(self) -> np.ndarray:
        return np.unique(self.cells)

    @abstractmethod
    def _evaluate(self, positions, velocities, out, data_k, data_c) -> float:
        """Add the forces to ``out``; with ``data_k`` (not None) also K and C; returns the
        strain energy [J]."""

    def forces(self, positions, rotations, velocities, out) -> float:
        return self._evaluate(positions, velocities, out, None, None)

    def forces_and_tangent(
        self, positions, rotations, velocities, out, data_k, data_c, consistent
    ) -> float:
        return self._evaluate(positions, velocities, out, data_k, data_c)


@dataclass
class ContactContext:
    """What every contact set's evaluation needs besides its own data; built by the
    integrator once per evaluation."""

    model: Model
    laws: np.ndarray
    """Packed contact laws (L, PACKED_SIZE) as the integrator uses them."""
    factors: np.ndarray
    """Value of each contact schedule at the evaluation time, shape (S,)."""
    node_mass: np.ndarray
    """Node masses [kg] as the impact step limit sees them (inf: never limits), shape (n,)."""
    impact_speed: float
    """Approach speed [m/s] above which a contact counts as an impact."""
    start: State
    """The state at the start of the step (stick anchors, sides)."""
    step: float
    """The step size h [s]."""
    box_half: np.ndarray
    """Inner half sizes [m] of the rounded box carried by each node at this time, (n, 3)."""
    reach: float = 0.0
    """Distance [m] any node can travel in the step (broad phase margin)."""
    adjacent_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Sorted keys ``a * node_count + b`` of node pairs that share an element: a point never
    touches a face next to one of its nodes in its own mesh."""
    w2: np.ndarray = field(default_factory=lambda: np.zeros(1))
    """Largest (contact stiffness / node mass) of impacting contacts, shape (1,) (in/out)."""


@dataclass
class ContactOutput:
    """Accumulators of one contact evaluation."""

    forces: np.ndarray
    """Contact forces [N, N m] per node, shape (n, 6)."""
    node_blocks: list = field(default_factory=list)
    """(nodes (P,), dF/dq (P, 6, 6), dF/dv (P, 6, 6)) of contacts acting on one node each."""
    coupled_blocks: list = field(default_factory=list)
    """(dF/dq (k, w, w), dF/dv (k, w, w), DOF numbers (k, w), -1 unused) of contacts that
    couple several nodes."""
    count: int = 0
    """Contacts in touch."""
    depth: float = 0.0
    """Deepest penetration [m]."""
    worst_node: int = -1
    """Node of the deepest plane contact point (-1: unknown)."""
    ratio: float = 0.0
    """Largest penetration / the law's ``max_penetration``."""

    def merge(self, count: int, depth: float, ratio: float, node: int = -1) -> None:
        """Add one kernel's contact count, deepest penetration and worst ratio."""
        if depth > self.depth:
            self.depth = depth
            if node >= 0:
                self.worst_node = node
        self.count += int(count)
        self.ratio = max(self.ratio, ratio)


class ContactSet(ABC):
    """A set of contact pairs of one kind with its law, schedule, candidates and history.

    Attributes set by the builder: ``key`` (unique within the model, prefixes the set's
    checkpoint arrays), ``law_index`` and ``schedule_index`` (rows of ``Model.contact_laws`` /
    ``Model.contact_schedules``).
    """

    kind: str = "contact"
    key: str = ""
    law_index: int = -1
    schedule_index: int = -1
    monitored: bool = False
    """The integrator records this set's impulse on every node
    (:meth:`flexparcel.builder.model_builder.ModelBuilder.monitored_contacts`)."""

    def __init__(self, law, schedule) -> None:
        self.law = law
        """The :class:`~flexparcel.contact.law.ContactLaw` (the builder packs it)."""
        self.schedule = schedule
        """:class:`~flexparcel.model.schedule.Schedule` switching the set on (1) and off (0)."""

    def prepare(self, ctx: ContactContext, start: State, step: float) -> None:  # noqa: B027 (a no-op by default)
        """Broad phase, once per step at its start (candidate pairs and their sides)."""

    @abstractmethod
    def evaluate(self, ctx: ContactContext, state: State, out: ContactOutput) -> None:
        """Add forces and derivative blocks at ``state`` to ``out``."""

    def begin_step(self) -> None:  # noqa: B027 (a no-op by default)
        """Reset trial history at the start of a step's Newton iteration."""

    def commit(self) -> None:  # noqa: B027 (a no-op by default)
        """Keep the trial history of an accepted step."""

    def history(self) -> dict[str, np.ndarray]:
        """Arrays the next step depends on (stick springs, anchors); rows first."""
        return {}

    def restore_history(self, history: dict[str, np.ndarray]) -> None:  # noqa: B027 (a no-op by default)
        """Inverse of :meth:`history` (shapes are checked by the caller)."""

    def history_rows(self, numbering: np.ndarray) -> np.ndarray | None:
        """Identity of each history row in another node numbering (``numbering[i]``: the
        other number of node i), as strings (k,), so that a model of other members can take
        over the rows it shares (group-by-group integration). None: no history."""
        return None

    def nodes(self) -> np.ndarray:
        """Nodes whose DOFs the set's forces act on, shape (k,)."""
        return np.zeros(0, np.int64)

    def fingerprint_arrays(self) -> list[np.ndarray]:
        """Arrays that identify the set (a checkpoint belongs to one model)."""
        return [np.array(self.kind), self.nodes(), np.array([self.law_index, self.schedule_index])]


def row_keys(prefix: str, columns: np.ndarray) -> np.ndarray:
    """One string key per row of ``columns`` (k, c) (numbers), with ``prefix``."""
    cols = np.atleast_2d(np.asarray(columns, dtype=float))
    return np.array([prefix + ":" + ",".join(f"{v:.17g}" for v in row) for row in cols], dtype=str)
