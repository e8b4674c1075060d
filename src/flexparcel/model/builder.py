"""ModelBuilder -> Model (static arrays) and State (time-varying arrays).

Every node carries 6 DOFs ``[x, y, z, spin_x, spin_y, spin_z]``: three translations [m] and a
rotation (stored as a rotation matrix; variations are spatial spins [rad]).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flexparcel.contact.law import PACKED_SIZE
from flexparcel.elements import shell
from flexparcel.model.checks import finite_number
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.mesh import quads_to_triangles, shell_edges, surface_triangles
from flexparcel.model.rigid import PrescribedMotion, RoundedBox
from flexparcel.model.schedule import Schedule

__all__ = ["ModelBuilder", "Model", "State", "DOFS_PER_NODE"]
# rigid bodies: see flexparcel.model.rigid (RoundedBox, PrescribedMotion)

DOFS_PER_NODE = 6
_DOF_NAMES = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_DOF_GROUPS = {"all": [0, 1, 2, 3, 4, 5], "translations": [0, 1, 2], "rotations": [3, 4, 5]}


@dataclass
class Model:
    """Compiled, immutable model: flat arrays used by the kernels. Build it with ModelBuilder."""

    positions0: np.ndarray
    """Reference node positions [m], shape (node_count, 3)."""
    triangles: np.ndarray
    """Shell triangles used by the kernels (quads are split), shape (m, 3) int64."""
    tri_kl: np.ndarray
    """Local linear stiffness per triangle [SI], shape (m, 18, 18)."""
    tri_xloc: np.ndarray
    """Reference local centroidal corner coordinates [m], shape (m, 3, 2)."""
    tri_frame0: np.ndarray
    """Reference element frames, shape (m, 3, 3) (columns e1, e2, e3)."""
    tri_beta: np.ndarray
    """Rayleigh stiffness-proportional damping beta [s] per triangle, shape (m,)."""
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
    # sparse pattern over the free DOFs
    free_index: np.ndarray
    """Free-DOF number of each DOF or -1 if fixed, shape (node_count * 6,)."""
    csr_indptr: np.ndarray
    csr_indices: np.ndarray
    tri_emap: np.ndarray
    """CSR data slot for each element matrix entry (trash slot nnz for fixed DOFs), (m,18,18)."""
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
    """Nodes moving with a prescribed constant velocity, shape (p,)."""
    prescribed_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    """Their [v, omega] [m/s, rad/s], shape (p, 6)."""
    node_block_slots: np.ndarray = field(default_factory=lambda: np.zeros((0, 6, 6), np.int64))
    """CSR data slots of every node's own 6x6 block, shape (node_count, 6, 6)."""
    plane_point: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """A point of each rigid plane [m], shape (k, 3)."""
    plane_normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Unit normal of each plane, out of its solid side, shape (k, 3)."""
    plane_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Tangential surface velocity of each plane (a belt) [m/s], shape (k, 3)."""
    contact_laws: np.ndarray = field(default_factory=lambda: np.zeros((0, PACKED_SIZE)))
    """Packed contact laws (see ContactLaw.packed), shape (L, PACKED_SIZE)."""
    cp_node: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Node of each contact point, shape (P,)."""
    cp_offset: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Body-frame offset of each contact point from its node [m], shape (P, 3)."""
    cp_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Radius of each contact point [m], shape (P,)."""
    cp_plane: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    cp_law: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    cp_schedule: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Index into ``contact_schedules`` (switching each pair on and off), shape (P,)."""
    contact_schedules: list = field(default_factory=list)
    bp_node: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Node of each (node, rigid box) contact pair, shape (Q,)."""
    bp_box: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """Rigid-body node of each pair, shape (Q,)."""
    bp_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bp_law: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    bp_schedule: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    box_half_by_node: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    """Inner half sizes of the rounded box carried by each node (zero if none) [m], (n, 3)."""
    box_radius_by_node: np.ndarray = field(default_factory=lambda: np.zeros(0))
    box_growth: list = field(default_factory=list)
    """Rounded boxes whose size changes in time (the assembly grows a content into its
    packaging): (rigid node, outer half sizes (3,) [m], Schedule of the scale factor). Contact
    uses ``factor * outer - edge radius`` as the inner half sizes."""
    solid_growth: list = field(default_factory=list)
    """Solid element groups whose size changes in time (the assembly grows a flexible content
    into its packaging): (index into ``solid_groups``, full-size ``xref`` (m, k, 3) [m],
    Schedule of the scale factor). The integrator sets the group's ``xref`` to ``factor x
    full-size`` at each step's end time, so the elements expand smoothly."""
    solid_groups: list = field(default_factory=list)
    """Solid element blocks: dicts with ``kind``, ``cells`` (m, k), ``kl``, ``xref``, ``grad``,
    ``beta`` (m,) and ``emap`` (m, 3k, 3k) CSR data slots (see flexparcel.elements.solid)."""
    edge_sets: list = field(default_factory=list)
    """Line-contact sets: (edges (E, 2), plane, radius [m], samples, law index, schedule)."""
    edge_face_sets: list = field(default_factory=list)
    """Line contact with faces: (edges (E, 2), triangles (M, 3), thickness [m], samples, law
    index, schedule)."""
    edge_edge_sets: list = field(default_factory=list)
    """Edge-to-edge line contact: (edges a (Ea, 2), edges b (Eb, 2), thickness [m], law
    index, schedule) (see :mod:`flexparcel.contact.edge_edge`)."""
    edge_box_sets: list = field(default_factory=list)
    """Line contact with rounded boxes: (edges (E, 2), rigid node, radius [m], samples, law
    index, schedule)."""
    face_sets: list = field(default_factory=list)
    """Node-to-face contact sets: (nodes (N,), triangles (M, 3), thickness [m], law index,
    schedule index) each."""
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
        """Whether any contact (points on planes, node-box, line, node-face) is defined."""
        return bool(
            self.cp_node.size or self.bp_node.size or self.edge_sets or self.edge_box_sets
            or self.face_sets or self.edge_face_sets or self.edge_edge_sets
        )  # fmt: skip

    def initial_state(self) -> State:
        n = self.node_count
        vel = np.zeros((n, 6))
        vel[self.prescribed_nodes] = self.prescribed_velocity
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


@dataclass
class _Load:
    nodes: np.ndarray
    vector: np.ndarray
    is_moment: bool
    follower: bool
    schedule: Schedule


@dataclass
class ModelBuilder:
    """Collects meshes, materials, supports and loads; ``finalize()`` validates and compiles.

    Args:
        gravity: gravitational acceleration [m/s^2], shape (3,).
    """

    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    gravity_schedule: Schedule = field(default_factory=Schedule.constant)
    mass_damping: float = 0.0
    """Rayleigh alpha [1/s] (see :attr:`Model.mass_damping`); >= 0."""
    _points: list[np.ndarray] = field(default_factory=list, repr=False)
    _tris: list[np.ndarray] = field(default_factory=list, repr=False)
    _tri_w: list[np.ndarray] = field(default_factory=list, repr=False)
    _tri_mat: list[ShellMaterial] = field(default_factory=list, repr=False)
    _cells: dict = field(default_factory=dict, repr=False)
    _fixed: dict = field(default_factory=dict, repr=False)
    _loads: list[_Load] = field(default_factory=list, repr=False)
    _rigid: list = field(default_factory=list, repr=False)
    _planes: list = field(default_factory=list, repr=False)
    _contacts: list = field(default_factory=list, repr=False)
    _slaves: dict = field(default_factory=dict, repr=False)
    _body_contacts: list = field(default_factory=list, repr=False)
    _face_contacts: list = field(default_factory=list, repr=False)
    _solids: list = field(default_factory=list, repr=False)
    _edge_contacts: list = field(default_factory=list, repr=False)
    _edge_body_contacts: list = field(default_factory=list, repr=False)
    _edge_face_contacts: list = field(default_factory=list, repr=False)
    _edge_edge_contacts: list = field(default_factory=list, repr=False)
    _refs: list = field(default_factory=list, repr=False)
    _node_count: int = 0

    def __post_init__(self) -> None:
        g = np.asarray(self.gravity, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ValueError(f"ModelBuilder.gravity must be 3 finite numbers [m/s^2], got {g!r}")
        self.gravity = tuple(g)
        a = self.mass_damping
        if not (isinstance(a, int | float) and np.isfinite(a) and a >= 0.0):
            raise ValueError(f"ModelBuilder.mass_damping must be >= 0 1/s, got {a!r}")

    @property
    def node_count(self) -> int:
        return self._node_count

    # ------------------------------------------------------------------ geometry
    def add_shell_mesh(
        self,
        points: np.ndarray,
        quads: np.ndarray | None = None,
        *,
        material: ShellMaterial,
        triangles: np.ndarray | None = None,
    ) -> np.ndarray:
        """Add a shell mesh; returns the global node ids (len(points),) of its points.

        ``points`` [m] (n, 3); ``quads`` (q, 4) and/or ``triangles`` (t, 3) of local node ids,
        counter-clockwise about the side the user calls +normal, consistently oriented.
        """
        if not isinstance(material, ShellMaterial):
            raise TypeError("add_shell_mesh: material must be a ShellMaterial")
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3 or pts.shape[0] < 3:
            raise ValueError(f"add_shell_mesh: points must have shape (n>=3, 3), got {pts.shape}")
        bad = np.flatnonzero(~np.all(np.isfinite(pts), axis=1))
        if bad.size:
            raise ValueError(f"add_shell_mesh: points[{bad[0]}] is not finite: {pts[bad[0]]}")
        if quads is None and triangles is None:
            raise ValueError("add_shell_mesh: give quads and/or triangles")
        cells, tri, w = _shell_cells("add_shell_mesh", pts, quads, triangles)
        n = len(pts)
        ids = np.arange(self._node_count, self._node_count + n)
        self._points.append(pts)
        self._tris.append(tri + self._node_count)
        self._tri_w.append(w)
        self._tri_mat.append(material)
        for cname, c in cells:
            self._cells.setdefault(cname, []).append(c + self._node_count)
        self._node_count += n
        return ids

    def add_shell_elements(
        self,
        quads: np.ndarray | None = None,
        *,
        material: ShellMaterial,
        triangles: np.ndarray | None = None,
    ) -> None:
        """Add shell elements of another material on nodes that already exist (e.g. a glued
        strip of doubled thickness along an envelope's border): ``quads`` (q, 4) and/or
        ``triangles`` (t, 3) of global node ids, checked like :meth:`add_shell_mesh`."""
        if not isinstance(material, ShellMaterial):
            raise TypeError("add_shell_elements: material must be a ShellMaterial")
        if quads is None and triangles is None:
            raise ValueError("add_shell_elements: give quads and/or triangles")
        conns = [np.asarray(c) for c in (quads, triangles) if c is not None]
        used = np.unique(np.concatenate([c.ravel() for c in conns]))
        self._check_ids("add_shell_elements", used)
        if self._node_count:
            allpts = np.concatenate(self._points)
        local = {int(g): k for k, g in enumerate(used.tolist())}
        relabel = np.vectorize(lambda g: local[int(g)], otypes=[np.int64])
        q = relabel(np.asarray(quads)) if quads is not None else None
        t = relabel(np.asarray(triangles)) if triangles is not None else None
        cells, tri, w = _shell_cells("add_shell_elements", allpts[used], q, t)
        self._tris.append(used[tri])
        self._tri_w.append(w)
        self._tri_mat.append(material)
        for cname, c in cells:
            self._cells.setdefault(cname, []).append(used[c])

    def add_solid_mesh(
        self, points: np.ndarray, cells: np.ndarray, kind: str, *, material
    ) -> np.ndarray:
        """Add a solid mesh (flexible content): ``points`` [m] (n, 3), ``cells`` (m, k) of one
        ``kind`` ("hex8", "wedge6", "pyr5", "tet4" or the meshio names) in VTK node order,
        a :class:`flexparcel.elements.solid.SolidMaterial`. Returns the global node ids.
        Nodes used only by solids carry no rotations (those DOFs are held)."""
        from flexparcel.elements.solid import solid_reference_data

        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"add_solid_mesh: points must have shape (n, 3), got {pts.shape}")
        c = np.asarray(cells)
        ref = solid_reference_data(pts, c, kind, material)  # validates cells and material
        ids = np.arange(self._node_count, self._node_count + len(pts))
        self._points.append(pts)
        self._solids.append(
            (kind, c.astype(np.int64) + self._node_count, ref, float(material.damping_ratio))
        )
        self._node_count += len(pts)
        return ids

    def add_rigid_body(
        self,
        shape: RoundedBox,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
        motion: str | PrescribedMotion = "free",
    ) -> int:
        """Add a rigid body; returns its node id (a 6-DOF node at its centre of mass).

        ``position`` [m] of the centre; body axes start aligned with the world axes.
        ``motion``: "free", "fixed" (all 6 DOFs held), or a :class:`PrescribedMotion`.
        """
        if not isinstance(shape, RoundedBox):
            raise TypeError("add_rigid_body: shape must be a RoundedBox")
        pos = np.asarray(position, dtype=float)
        if pos.shape != (3,) or not np.all(np.isfinite(pos)):
            raise ValueError(
                f"add_rigid_body: position must be 3 finite numbers [m], got {position!r}"
            )
        if not (motion in ("free", "fixed") or isinstance(motion, PrescribedMotion)):
            raise ValueError(
                "add_rigid_body: motion must be 'free', 'fixed' or a PrescribedMotion, "
                f"got {motion!r}"
            )
        node = self._node_count
        self._points.append(pos[None, :])
        self._rigid.append((node, shape, motion))
        self._node_count += 1
        return node

    def add_plane(
        self,
        point: tuple[float, float, float],
        normal: tuple[float, float, float],
        surface_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> int:
        """Add a fixed rigid plane through ``point`` [m] with ``normal`` pointing out of its
        solid side; ``surface_velocity`` [m/s] (tangential) makes it a belt. Returns its id."""
        p = np.asarray(point, dtype=float)
        nrm = np.asarray(normal, dtype=float)
        vel = np.asarray(surface_velocity, dtype=float)
        for name, v in (("point", p), ("normal", nrm), ("surface_velocity", vel)):
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"add_plane: {name} must be 3 finite numbers, got {v!r}")
        length = np.linalg.norm(nrm)
        if length == 0.0:
            raise ValueError("add_plane: normal must be non-zero")
        nrm = nrm / length
        if abs(vel @ nrm) > 1e-12 * max(1.0, np.linalg.norm(vel)):
            raise ValueError("add_plane: surface_velocity must be tangential (normal . v = 0)")
        self._planes.append((p, nrm, vel))
        return len(self._planes) - 1

    def add_contact(
        self, target, plane: int, law, *, radius: float = 0.0, schedule: Schedule | None = None
    ) -> None:
        """Contact between ``target`` and plane ``plane`` with a :class:`ContactLaw`.

        ``target``: a rigid body's node id (from :meth:`add_rigid_body`): its rounded box's
        inner corners with its edge radius touch the plane; or an array of shell node ids with
        a contact ``radius`` [m] (e.g. half the shell thickness). ``schedule`` switches the
        pair on (1) and off (0) in time.
        """
        _require_law("add_contact", law)
        if not (isinstance(plane, int | np.integer) and 0 <= plane < len(self._planes)):
            raise ValueError(
                f"add_contact: unknown plane {plane!r}; planes are 0..{len(self._planes) - 1}"
            )
        r = _nonnegative_radius("add_contact", radius)
        sched = _schedule(schedule)
        rigid = {node: shape for node, shape, _ in self._rigid}
        if isinstance(target, int | np.integer) and int(target) in rigid:
            shape = rigid[int(target)]
            offsets = shape.corners()
            nodes = np.full(len(offsets), int(target))
            radii = np.full(len(offsets), shape.edge_radius)
        else:
            nodes = self._check_ids("add_contact", target)
            if set(nodes.tolist()) & set(rigid):
                raise ValueError("add_contact: give a rigid body as its single node id")
            offsets = np.zeros((len(nodes), 3))
            radii = np.full(len(nodes), r)
        self._contacts.append((nodes, offsets, radii, int(plane), law, sched))

    def add_fdr(self, node_ids, reference: int | None = None) -> int:
        """Tie ``node_ids`` rigidly to a reference node (RecurDyn FDR, Nastran RBE2): they follow
        its translation and rotation. ``reference``: an existing node (e.g. a rigid body's node,
        which makes a fixed joint between the FDR and the body) or None to create a massless
        reference node at the centroid of the set. Returns the reference node id; load it with
        :meth:`add_force` / :meth:`add_moment`, hold it with :meth:`fix`."""
        ids = self._check_ids("add_fdr", node_ids)
        if reference is None:
            pts = np.concatenate(self._points)[ids]
            reference = self._node_count
            self._points.append(pts.mean(axis=0)[None, :])
            self._refs.append(reference)
            self._node_count += 1
        else:
            reference = int(self._check_ids("add_fdr", [reference])[0])
        for node in ids.tolist():
            if node == reference:
                raise ValueError(f"add_fdr: node {node} cannot be tied to itself")
            if node in self._slaves:
                raise ValueError(
                    f"add_fdr: node {node} is already tied to node {self._slaves[node]}"
                )
            self._slaves[node] = reference
        return reference

    def add_rigid_mesh(self, points: np.ndarray, triangles: np.ndarray, body: int) -> np.ndarray:
        """Attach a triangle-mesh surface [m] to rigid body ``body`` (a deflector, a roller, a
        chute): its vertices become massless nodes tied to the body (FDR) and its triangles
        faces that shell nodes can touch through :meth:`add_face_contact`. Returns the vertex
        node ids."""
        pts = np.asarray(points, dtype=float)
        tri = np.asarray(triangles)
        if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
            raise ValueError(
                f"add_rigid_mesh: points must be finite, shape (n, 3), got {pts.shape}"
            )
        if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
            raise ValueError("add_rigid_mesh: triangles must be integers of shape (m, 3)")
        if tri.size and (tri.min() < 0 or tri.max() >= len(pts)):
            raise ValueError(f"add_rigid_mesh: triangle node ids must be in [0, {len(pts) - 1}]")
        rigid = {node for node, _, _ in self._rigid}
        if int(body) not in rigid:
            raise ValueError(f"add_rigid_mesh: body {body!r} is not a rigid body's node")
        ids = np.arange(self._node_count, self._node_count + len(pts))
        self._points.append(pts)
        self._node_count += len(pts)
        self._refs.extend(ids.tolist())  # element-free nodes are allowed
        self._cells.setdefault("triangle", []).append(tri.astype(np.int64) + ids[0])
        self.add_fdr(ids, reference=int(body))
        return ids

    def add_fixed_joint(self, body_a: int, body_b: int) -> None:
        """Weld two rigid bodies (or any two nodes): ``body_b`` follows ``body_a``."""
        self.add_fdr([body_b], reference=body_a)

    def add_body_contact(
        self, node_ids, body: int, law, *, radius: float = 0.0, schedule: Schedule | None = None
    ) -> None:
        """Contact between shell nodes (contact radius [m], e.g. half the shell thickness) and
        the rounded box of rigid body ``body`` (its node id), e.g. packaging on its content."""
        name = "add_body_contact"
        _require_law(name, law)
        body = self._rigid_body(name, body)
        nodes = self._check_ids(name, node_ids)
        r = _nonnegative_radius(name, radius)
        sched = _schedule(schedule)
        self._body_contacts.append((nodes, body, r, law, sched))

    def add_face_contact(
        self, node_ids, face_node_ids, law, *, thickness: float, schedule: Schedule | None = None
    ) -> None:
        """Node-to-face contact: nodes ``node_ids`` against the shell faces whose corners all
        lie in ``face_node_ids`` (packaging layer against layer, consignment against
        consignment). ``thickness`` [m]: the contact distance, e.g. the mean of the two shells'
        thicknesses. Both sides of a face are free (thin shells)."""
        name = "add_face_contact"
        _require_law(name, law)
        nodes = self._check_ids(name, node_ids)
        h = _positive_thickness(name, thickness)
        tris = self._face_triangles(name, face_node_ids)
        sched = _schedule(schedule)
        self._face_contacts.append((nodes, tris, h, law, sched))

    def add_edge_face_contact(
        self,
        node_ids,
        face_node_ids,
        law,
        *,
        thickness: float,
        samples: int = 3,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` against the
        shell (or solid boundary) faces whose corners all lie in ``face_node_ids``, e.g. a
        packaging's border against another consignment; each edge is sampled at ``samples``
        stations (see :func:`flexparcel.contact.faces.edge_face_forces`). ``thickness`` [m] as
        for :meth:`add_face_contact`."""
        name = "add_edge_face_contact"
        _require_law(name, law)
        h = _positive_thickness(name, thickness)
        edges = self._shell_edges(name, node_ids)
        tris = self._face_triangles(name, face_node_ids)
        self._edge_face_contacts.append(
            (edges, tris, h, _sample_count(name, samples), law, _schedule(schedule))
        )

    def add_edge_edge_contact(
        self,
        node_ids,
        other_node_ids,
        law,
        *,
        thickness: float,
        schedule: Schedule | None = None,
    ) -> None:
        """Edge-to-edge line contact of the shell (or rigid mesh) edges whose two nodes are both
        in ``node_ids`` against those whose two nodes are both in ``other_node_ids``, e.g. a
        deflector's tip edge against a packaging's element edges, which cross it between any
        stations of :meth:`add_edge_face_contact`. ``thickness`` [m]: the sum of the two
        edges' radii (:mod:`flexparcel.contact.edge_edge`). Edges sharing a node never touch."""
        name = "add_edge_edge_contact"
        _require_law(name, law)
        h = _positive_thickness(name, thickness)
        edges_a = self._shell_edges(name, node_ids)
        edges_b = self._shell_edges(name, other_node_ids)
        self._edge_edge_contacts.append((edges_a, edges_b, h, law, _schedule(schedule)))

    def _face_triangles(self, name: str, face_node_ids) -> np.ndarray:
        """Triangles (M, 3) of the shell faces (quads split once) and solid boundary faces
        whose corners all lie in ``face_node_ids``."""
        ids = self._check_ids(name, face_node_ids)
        keep = np.zeros(self._node_count, dtype=bool)
        keep[ids] = True
        cells = [(ctype, c) for ctype, lst in self._cells.items() for c in lst]
        solid = _solid_boundary_triangles(self._solids, set(ids.tolist()))
        tris = np.vstack([surface_triangles(cells, keep), solid])
        if len(tris) == 0:
            raise ValueError(
                f"{name}: face_node_ids contain no complete shell face or solid boundary face"
            )
        return tris.astype(np.int64)

    def add_edge_contact(
        self,
        node_ids,
        plane: int,
        law,
        *,
        radius: float = 0.0,
        samples: int = 3,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` (e.g. the
        glued border of an envelope standing on it) against plane ``plane``; each edge is
        sampled at ``samples`` stations (see :mod:`flexparcel.contact.edges`)."""
        if not (isinstance(plane, int | np.integer) and 0 <= plane < len(self._planes)):
            raise ValueError(
                f"add_edge_contact: unknown plane {plane!r}; planes are 0..{len(self._planes) - 1}"
            )
        self._edge_contacts.append(
            self._edge_set(
                "add_edge_contact", node_ids, int(plane), law, radius, samples, schedule
            )  # fmt: skip
        )

    def add_edge_body_contact(
        self,
        node_ids,
        body: int,
        law,
        *,
        radius: float = 0.0,
        samples: int = 3,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` against the
        rounded box of rigid body ``body`` (its node id), e.g. a packaging's border against its
        content's edges; ``samples`` stations per edge (see :mod:`flexparcel.contact.bodies`)."""
        name = "add_edge_body_contact"
        self._edge_body_contacts.append(
            self._edge_set(
                name, node_ids, self._rigid_body(name, body), law, radius, samples, schedule
            )  # fmt: skip
        )

    def _rigid_body(self, name: str, body) -> int:
        """``body`` as a rigid body's node id, else ``ValueError`` listing the rigid bodies."""
        rigid = {node for node, _, _ in self._rigid}
        if not (isinstance(body, int | np.integer) and int(body) in rigid):
            raise ValueError(
                f"{name}: body {body!r} is not a rigid body's node; rigid bodies: {sorted(rigid)}"
            )
        return int(body)

    def _edge_set(self, name, node_ids, target, law, radius, samples, schedule) -> tuple:
        """(edges (E, 2), target, radius, samples, law, schedule) of a line-contact set against
        a plane or a body, with its input checked."""
        _require_law(name, law)
        r = _nonnegative_radius(name, radius)
        n = _sample_count(name, samples)
        return (self._shell_edges(name, node_ids), target, r, n, law, _schedule(schedule))

    def _shell_edges(self, name: str, node_ids) -> np.ndarray:
        """Shell edges (E, 2), sorted, whose two nodes are both in ``node_ids``."""
        keep = np.zeros(self._node_count, dtype=bool)
        keep[self._check_ids(name, node_ids)] = True
        cells = [(ctype, c) for ctype, lst in self._cells.items() for c in lst]
        edges = shell_edges(cells, keep)
        if not edges.size:
            raise ValueError(f"{name}: node_ids contain no shell edge")
        return edges

    def add_self_contact(
        self, node_ids, law, *, thickness: float, schedule: Schedule | None = None
    ) -> None:
        """Self contact of a shell mesh (e.g. an envelope's layers): its nodes against its own
        faces, a node never against a face it is a corner of."""
        self.add_face_contact(node_ids, node_ids, law, thickness=thickness, schedule=schedule)

    # ------------------------------------------------------------------ supports
    def _check_ids(self, what: str, node_ids) -> np.ndarray:
        ids = np.atleast_1d(np.asarray(node_ids))
        if ids.size == 0:
            raise ValueError(f"{what}: node_ids is empty")
        if not np.issubdtype(ids.dtype, np.integer):
            raise ValueError(f"{what}: node_ids must be integers, got {ids.dtype}")
        bad = ids[(ids < 0) | (ids >= self._node_count)]
        if bad.size:
            raise ValueError(
                f"{what}: node id {int(bad[0])} is outside [0, {self._node_count - 1}]"
            )
        return ids.astype(np.int64).ravel()

    def fix(self, node_ids, dofs: str | list = "all") -> None:
        """Hold DOFs at their reference values: "all", "translations", "rotations", or a list
        of names from x, y, z, rx, ry, rz (or indices 0-5)."""
        ids = self._check_ids("fix", node_ids)
        if isinstance(dofs, str):
            if dofs not in _DOF_GROUPS:
                raise ValueError(
                    f"fix: dofs must be one of {sorted(_DOF_GROUPS)} or a list of "
                    f"{list(_DOF_NAMES)}, got {dofs!r}"
                )
            idx = _DOF_GROUPS[dofs]
        else:
            idx = []
            for d in dofs:
                if isinstance(d, str) and d in _DOF_NAMES:
                    idx.append(_DOF_NAMES[d])
                elif isinstance(d, int | np.integer) and 0 <= d < 6:
                    idx.append(int(d))
                else:
                    raise ValueError(f"fix: unknown DOF {d!r}; allowed {list(_DOF_NAMES)} or 0-5")
        for n in ids:
            self._fixed.setdefault(int(n), set()).update(idx)

    def clamp(self, node_ids) -> None:
        """Built-in support: no displacement and no rotation."""
        self.fix(node_ids, "all")

    # ------------------------------------------------------------------ loads
    def _add_load(self, what, node_ids, vector, is_moment, follower, schedule) -> None:
        ids = self._check_ids(what, node_ids)
        v = np.asarray(vector, dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"{what}: vector must be 3 finite numbers, got {vector!r}")
        sched = _schedule(schedule)
        if not isinstance(sched, Schedule):
            raise TypeError(f"{what}: schedule must be a Schedule")
        self._loads.append(_Load(ids, v, is_moment, bool(follower), sched))

    def add_force(self, node_ids, force, *, follower: bool = False, schedule=None) -> None:
        """Force [N] applied to each node (total per node), dead unless ``follower``."""
        self._add_load("add_force", node_ids, force, False, follower, schedule)

    def add_moment(self, node_ids, moment, *, follower: bool = False, schedule=None) -> None:
        """Moment [N m] applied to each node; a follower moment rotates with the node."""
        self._add_load("add_moment", node_ids, moment, True, follower, schedule)

    # ------------------------------------------------------------------ compile
    def finalize(self) -> Model:
        """Validate, compute element data, the lumped mass and the sparse pattern."""
        if not self._points:
            raise ValueError("ModelBuilder.finalize: no mesh or rigid body was added")
        pos0 = np.concatenate(self._points)
        n = len(pos0)
        tris, kls, xls, frs, betas, ws = [], [], [], [], [], []
        mass = np.zeros((n, 6))
        for tri, w, mat in zip(self._tris, self._tri_w, self._tri_mat, strict=True):
            frames, xloc = shell.reference_frames(pos0, tri)
            kl = np.empty((len(tri), 18, 18))
            # structured meshes repeat a few triangle shapes: compute each shape once (the
            # local stiffness depends only on the local corner coordinates and the material)
            shapes, first, which = np.unique(
                np.round(xloc.reshape(len(tri), 6), 12), axis=0, return_index=True,
                return_inverse=True,
            )  # fmt: skip
            k_shape = np.array([
                shell.local_stiffness(xloc[e], mat.youngs_modulus, mat.poisson_ratio,
                                      mat.thickness)
                for e in first
            ])  # fmt: skip
            kl[:] = w[:, None, None] * k_shape[which.ravel()]
            area = 0.5 * np.abs(
                (xloc[:, 1, 0] - xloc[:, 0, 0]) * (xloc[:, 2, 1] - xloc[:, 0, 1])
                - (xloc[:, 2, 0] - xloc[:, 0, 0]) * (xloc[:, 1, 1] - xloc[:, 0, 1])
            )
            # lumped mass: a third of each triangle's mass to each corner; isotropic rotational
            # inertia rho t^3/12 per area (the plate's, also used for the drilling axis)
            m_node = mat.density * mat.thickness * area * w / 3.0
            j_node = mat.density * mat.thickness**3 / 12.0 * area * w / 3.0
            for a in range(3):
                np.add.at(mass[:, 0], tri[:, a], m_node)
                np.add.at(mass[:, 3], tri[:, a], j_node)
            tris.append(tri)
            kls.append(kl)
            xls.append(xloc)
            frs.append(frames)
            betas.append(np.full(len(tri), mat.damping_ratio))
            ws.append(w)
        from flexparcel.elements.solid import ELEMENT_KINDS

        solid_nodes = np.zeros(0, np.int64)
        vtk_names = {"hex8": "hexahedron", "wedge6": "wedge", "pyr5": "pyramid", "tet4": "tetra"}
        for _kind, cells, ref, _ in self._solids:
            for a in range(cells.shape[1]):
                np.add.at(mass[:, 0], cells[:, a], ref.mass[:, a])
            solid_nodes = np.union1d(solid_nodes, cells.ravel())
            name = next(k for k in ELEMENT_KINDS if cells.shape[1] == ELEMENT_KINDS[k])
            self._cells.setdefault(vtk_names[name], []).append(cells)
        rigid_nodes = np.array([r[0] for r in self._rigid], dtype=np.int64)
        rigid_inertia = np.zeros((len(self._rigid), 3, 3))
        pres_nodes, pres_vel = [], []
        for k, (node, shape, motion) in enumerate(self._rigid):
            mass[node, 0] = shape.total_mass()
            rigid_inertia[k] = shape.inertia()  # rotary inertia handled as a tensor, not in mass
            if isinstance(motion, PrescribedMotion):
                pres_nodes.append(node)
                pres_vel.append(np.r_[motion.velocity, motion.angular_velocity])
        mass[:, 1] = mass[:, 2] = mass[:, 0]
        mass[:, 4] = mass[:, 5] = mass[:, 3]
        triangles = np.concatenate(tris) if tris else np.zeros((0, 3), np.int64)
        attached = np.union1d(np.union1d(np.unique(triangles), rigid_nodes), solid_nodes)
        orphan = np.setdiff1d(np.arange(n), np.union1d(attached, self._refs))
        if orphan.size:
            raise ValueError(f"finalize: node {int(orphan[0])} belongs to no element")
        fixed = np.zeros((n, 6), dtype=bool)
        for node, dofs in self._fixed.items():
            fixed[node, sorted(dofs)] = True
        for node, _, motion in self._rigid:
            if motion != "free":
                fixed[node] = True  # held or driven: not unknowns
        # nodes only in solids have no rotational stiffness or inertia: hold their rotations
        rot_free = np.union1d(np.unique(triangles), rigid_nodes)
        rot_free = np.union1d(rot_free, np.array(sorted(set(self._slaves.values())), np.int64))
        solid_only = np.setdiff1d(solid_nodes, rot_free)
        solid_only = np.setdiff1d(solid_only, np.array(sorted(self._slaves), np.int64))
        fixed[solid_only, 3:] = True
        loads = self._loads
        schedules: list[Schedule] = []
        ln, lv, lm, lf, ls = [], [], [], [], []
        for ld in loads:
            if ld.schedule not in schedules:
                schedules.append(ld.schedule)
            si = schedules.index(ld.schedule)
            for node in ld.nodes:
                block = slice(3, 6) if ld.is_moment else slice(0, 3)
                held = fixed[node, block] & (ld.vector != 0.0)
                if ld.follower and np.any(fixed[node, block]) and np.any(ld.vector != 0.0):
                    held = fixed[node, block]
                if np.any(held):
                    kind = "moment" if ld.is_moment else "force"
                    raise ValueError(
                        f"{kind} on node {int(node)} acts on a fixed DOF "
                        f"({'rx ry rz' if ld.is_moment else 'x y z'} fixed = "
                        f"{fixed[node, block].tolist()}): remove the load or the support"
                    )
                ln.append(node)
                lv.append(ld.vector)
                lm.append(ld.is_moment)
                lf.append(ld.follower)
                ls.append(si)
        slave_nodes, slave_master, slave_offset = self._resolve_slaves(pos0, fixed)
        # a slave of a master held in all six DOFs (the mesh nodes of a fixed deflector) never
        # moves: hold it as well instead of carrying it through the rigid-link reduction,
        # whose products would only add zeros (T's rows of such a slave are empty) at every
        # Newton iteration (measured on PB alone on the paper's conveyor, 60 deflector nodes:
        # 46.9 ms against 48.5 ms a Newton iteration)
        still = fixed[slave_master].all(axis=1) & ~np.isin(slave_master, pres_nodes)
        if still.any():
            fixed[slave_nodes[still]] = True
            keep = ~still
            slave_nodes, slave_master = slave_nodes[keep], slave_master[keep]
            slave_offset = slave_offset[keep]
        is_slave = np.zeros((n, 6), dtype=bool)
        is_slave[slave_nodes] = True
        free_index = np.full(6 * n, -1, dtype=np.int64)
        free = np.flatnonzero(~fixed.ravel() & ~is_slave.ravel())
        if free.size == 0:
            raise ValueError("finalize: every DOF is fixed; nothing to solve")
        free_index[free] = np.arange(free.size)
        # FDR slave DOFs are numbered after the unknowns: matrices are assembled over both and
        # reduced onto the unknowns with the rigid-link map (see integrate.assembly.reduction)
        slave_dofs = np.flatnonzero(is_slave.ravel())
        free_index[slave_dofs] = free.size + np.arange(slave_dofs.size)
        ext = free.size + slave_dofs.size
        solid_cells = [cells for _, cells, _, _ in self._solids]
        indptr, indices, emap, load_emap, diag, rigid_slots, node_slots, solid_maps = _sparsity(
            triangles,
            free_index,
            ext,
            np.asarray(ln, dtype=np.int64),
            rigid_nodes,
            n,
            solid_cells,
        )
        solid_groups = [
            {
                "kind": kind,
                "cells": np.ascontiguousarray(cells),
                "kl": ref.kl,
                "xref": ref.xref,
                "grad": ref.grad,
                "beta": np.full(len(cells), beta),
                "emap": smap,
            }
            for (kind, cells, ref, beta), smap in zip(self._solids, solid_maps, strict=True)
        ]
        laws, csched = [], []

        def index_of(lst: list, item) -> int:
            if item not in lst:
                lst.append(item)
            return lst.index(item)

        def indexed(entries: list) -> list:
            """Contact sets (..., law, schedule) as (..., law index, schedule index)."""
            return [(*e[:-2], index_of(laws, e[-2]), index_of(csched, e[-1])) for e in entries]

        cpn, cpo, cpr, cpp, cpl, cps = [], [], [], [], [], []
        bpn, bpb, bpr, bpl, bps = [], [], [], [], []
        for nodes, body, r, li, si in indexed(self._body_contacts):
            bpn.append(nodes)
            bpb.append(np.full(len(nodes), body))
            bpr.append(np.full(len(nodes), r))
            bpl.append(np.full(len(nodes), li))
            bps.append(np.full(len(nodes), si))
        edge_sets = indexed(self._edge_contacts)
        edge_box_sets = indexed(self._edge_body_contacts)
        edge_face_sets = indexed(self._edge_face_contacts)
        edge_edge_sets = indexed(self._edge_edge_contacts)
        face_sets = indexed(self._face_contacts)
        box_half = np.zeros((n, 3))
        box_rad = np.zeros(n)
        for node, shape, _ in self._rigid:
            box_half[node] = shape.half_inner
            box_rad[node] = shape.edge_radius
        for nodes, offsets, radii, plane, li, si in indexed(self._contacts):
            cpn.append(nodes)
            cpo.append(offsets)
            cpr.append(radii)
            cpp.append(np.full(len(nodes), plane))
            cpl.append(np.full(len(nodes), li))
            cps.append(np.full(len(nodes), si))
        cells = [(k, np.concatenate(v)) for k, v in self._cells.items()]
        return Model(
            positions0=pos0,
            triangles=triangles,
            tri_kl=np.concatenate(kls) if kls else np.zeros((0, 18, 18)),
            tri_xloc=np.concatenate(xls) if xls else np.zeros((0, 3, 2)),
            tri_frame0=np.concatenate(frs) if frs else np.zeros((0, 3, 3)),
            tri_beta=np.concatenate(betas) if betas else np.zeros(0),
            mass=mass,
            gravity=np.asarray(self.gravity, dtype=float),
            fixed=fixed,
            load_nodes=np.asarray(ln, dtype=np.int64),
            load_vectors=np.asarray(lv, dtype=float).reshape(-1, 3),
            load_is_moment=np.asarray(lm, dtype=bool),
            load_follower=np.asarray(lf, dtype=bool),
            load_schedule=np.asarray(ls, dtype=np.int64),
            schedules=schedules,
            gravity_schedule=self.gravity_schedule,
            cells=cells,
            free_index=free_index,
            csr_indptr=indptr,
            csr_indices=indices,
            tri_emap=emap,
            load_emap=load_emap,
            diag_slots=diag,
            rigid_nodes=rigid_nodes,
            rigid_inertia=rigid_inertia,
            rigid_half_inner=np.array([r[1].half_inner for r in self._rigid]).reshape(-1, 3),
            rigid_radius=np.array([r[1].edge_radius for r in self._rigid], dtype=float),
            rigid_rot_slots=rigid_slots,
            prescribed_nodes=np.asarray(pres_nodes, dtype=np.int64),
            prescribed_velocity=np.asarray(pres_vel, dtype=float).reshape(-1, 6),
            node_block_slots=node_slots,
            plane_point=np.array([p[0] for p in self._planes]).reshape(-1, 3),
            plane_normal=np.array([p[1] for p in self._planes]).reshape(-1, 3),
            plane_velocity=np.array([p[2] for p in self._planes]).reshape(-1, 3),
            contact_laws=(
                np.array([law.packed() for law in laws]) if laws else np.zeros((0, PACKED_SIZE))
            ),
            cp_node=np.concatenate(cpn) if cpn else np.zeros(0, np.int64),
            cp_offset=np.concatenate(cpo) if cpo else np.zeros((0, 3)),
            cp_radius=np.concatenate(cpr) if cpr else np.zeros(0),
            cp_plane=np.concatenate(cpp) if cpp else np.zeros(0, np.int64),
            cp_law=np.concatenate(cpl) if cpl else np.zeros(0, np.int64),
            cp_schedule=np.concatenate(cps) if cps else np.zeros(0, np.int64),
            contact_schedules=csched,
            free_count=int(free.size),
            bp_node=np.concatenate(bpn) if bpn else np.zeros(0, np.int64),
            bp_box=np.concatenate(bpb) if bpb else np.zeros(0, np.int64),
            bp_radius=np.concatenate(bpr) if bpr else np.zeros(0),
            bp_law=np.concatenate(bpl) if bpl else np.zeros(0, np.int64),
            bp_schedule=np.concatenate(bps) if bps else np.zeros(0, np.int64),
            box_half_by_node=box_half,
            box_radius_by_node=box_rad,
            face_sets=face_sets,
            edge_face_sets=edge_face_sets,
            edge_edge_sets=edge_edge_sets,
            edge_sets=edge_sets,
            edge_box_sets=edge_box_sets,
            solid_groups=solid_groups,
            slave_nodes=slave_nodes,
            slave_master=slave_master,
            slave_offset=slave_offset,
            mass_damping=float(self.mass_damping),
        )

    def _resolve_slaves(self, pos0: np.ndarray, fixed: np.ndarray):
        """Slave -> root master (chains of ties resolved), offsets in the master frame."""
        nodes, masters = [], []
        for node in sorted(self._slaves):
            root, seen = self._slaves[node], {node}
            while root in self._slaves:
                if root in seen:
                    raise ValueError(f"add_fdr: ties of node {node} form a loop")
                seen.add(root)
                root = self._slaves[root]
            if np.any(fixed[node]):
                raise ValueError(
                    f"node {node} is tied to node {root} by an FDR and cannot also be fixed: "
                    "fix the reference node instead"
                )
            nodes.append(node)
            masters.append(root)
        nodes = np.asarray(nodes, dtype=np.int64)
        masters = np.asarray(masters, dtype=np.int64)
        return nodes, masters, (pos0[nodes] - pos0[masters]).reshape(-1, 3)


# faces of the solid kinds in VTK node order (quads are split in two triangles below)
_SOLID_FACES = {
    8: ([0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]),
    6: ([0, 2, 1], [3, 4, 5], [0, 1, 4, 3], [1, 2, 5, 4], [2, 0, 3, 5]),
    5: ([0, 3, 2, 1], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]),
    4: ([0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]),
}


def _require_law(name: str, law) -> None:
    from flexparcel.contact.law import ContactLaw

    if not isinstance(law, ContactLaw):
        raise TypeError(f"{name}: law must be a ContactLaw")


def _positive_thickness(name: str, thickness) -> float:
    h = finite_number(f"{name}: thickness", thickness)
    if not h > 0.0:
        raise ValueError(f"{name}: thickness must be > 0 m, got {thickness!r}")
    return h


def _nonnegative_radius(name: str, radius) -> float:
    r = finite_number(f"{name}: radius", radius)
    if not r >= 0.0:
        raise ValueError(f"{name}: radius must be >= 0 m, got {radius!r}")
    return r


def _sample_count(name: str, samples) -> int:
    n = finite_number(f"{name}: samples", samples)
    if n != int(n) or n < 1:
        raise ValueError(f"{name}: samples must be an integer >= 1, got {samples!r}")
    return int(n)


def _schedule(schedule: Schedule | None) -> Schedule:
    return schedule if schedule is not None else Schedule.constant()


def _solid_boundary_triangles(solids: list, nodes: set) -> np.ndarray:
    """Triangles of the boundary faces (faces of exactly one solid element, over all solid
    blocks) whose corners all lie in ``nodes``, shape (m, 3)."""
    count: dict = {}
    faces = []
    for _, cells, _, _ in solids:
        for face in _SOLID_FACES[cells.shape[1]]:
            for row in cells[:, face].tolist():
                key = tuple(sorted(row))
                count[key] = count.get(key, 0) + 1
                faces.append((key, row))
    out = []
    for key, row in faces:
        if count[key] == 1 and all(v in nodes for v in row):
            out.append(row[:3])
            if len(row) == 4:
                out.append([row[0], row[2], row[3]])
    return np.asarray(out, dtype=np.int64).reshape(-1, 3)


def _shell_cells(what: str, pts: np.ndarray, quads, triangles):
    """Validate shell connectivity over ``pts``; returns (cells [(name, conn)], triangles
    (m, 3), triangle weights (m,)) with quads split along both diagonals."""
    n = len(pts)
    cells = []
    tri_all, w_all = [], []
    for name, conn, k in (("quads", quads, 4), ("triangles", triangles, 3)):
        if conn is None:
            continue
        c = np.asarray(conn)
        if c.ndim != 2 or c.shape[1] != k or c.shape[0] == 0:
            raise ValueError(f"{what}: {name} must have shape (m>=1, {k}), got {c.shape}")
        if not np.issubdtype(c.dtype, np.integer):
            raise ValueError(f"{what}: {name} must be integers, got {c.dtype}")
        c = c.astype(np.int64)
        out = np.flatnonzero(np.any((c < 0) | (c >= n), axis=1))
        if out.size:
            raise ValueError(
                f"{what}: {name}[{out[0]}] = {c[out[0]].tolist()} has node ids outside [0, {n - 1}]"
            )
        srt = np.sort(c, axis=1)
        rep = np.flatnonzero(np.any(srt[:, 1:] == srt[:, :-1], axis=1))
        if rep.size:
            raise ValueError(
                f"{what}: {name}[{rep[0]}] = {c[rep[0]].tolist()} repeats a node "
                "(degenerate element)"
            )
        _, first, counts = np.unique(srt, axis=0, return_index=True, return_counts=True)
        if np.any(counts > 1):
            i = first[np.argmax(counts > 1)]
            raise ValueError(f"{what}: {name}[{i}] = {c[i].tolist()} is duplicated")
        if k == 4:
            t, w = quads_to_triangles(c)
            cells.append(("quad", c))
        else:
            t, w = c, np.ones(len(c))
            cells.append(("triangle", c))
        # degenerate check on every sub-triangle, relative to the element size
        p = pts[t]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        area2 = np.linalg.norm(np.cross(e1, e2), axis=1)
        h2 = np.maximum(np.sum(e1 * e1, axis=1), np.sum(e2 * e2, axis=1))
        deg = np.flatnonzero(area2 <= 1e-8 * h2)
        if deg.size:
            j = deg[0] % len(c)
            raise ValueError(
                f"{what}: {name}[{j}] = {c[j].tolist()} is degenerate (zero area or "
                "collinear nodes); element areas must be > 0"
            )
        if k == 4:
            # a convex, non-inverted quad has both diagonal splits oriented like the quad
            m = len(c)
            nrm = np.cross(e1, e2)
            ref = nrm[:m] + nrm[m : 2 * m]
            sgn = np.einsum("ij,kij->ki", ref, nrm.reshape(4, m, 3))
            inv = np.flatnonzero(np.any(sgn <= 0, axis=0))
            if inv.size:
                raise ValueError(
                    f"{what}: quads[{inv[0]}] = {c[inv[0]].tolist()} is inverted or "
                    "non-convex (its corners must go counter-clockwise around a convex quad)"
                )
        tri_all.append(t)
        w_all.append(w)
    tri = np.concatenate(tri_all)
    _check_orientation([c for _, c in cells])
    return cells, tri, np.concatenate(w_all)


def _check_orientation(cells: list[np.ndarray]) -> None:
    """Within one mesh, an edge shared by two elements must be traversed in opposite directions
    (consistent normals); the same directed edge twice means one of them is inverted."""
    edges, owner = [], []
    for ci, c in enumerate(cells):
        k = c.shape[1]
        for a in range(k):
            edges.append(c[:, [a, (a + 1) % k]])
            owner.append(np.column_stack([np.full(len(c), ci), np.arange(len(c))]))
    e = np.concatenate(edges)
    own = np.concatenate(owner)
    keys, counts = np.unique(e, axis=0, return_counts=True)
    if np.any(counts > 1):
        a, b = keys[np.argmax(counts > 1)]
        idx = np.flatnonzero((e[:, 0] == a) & (e[:, 1] == b))
        first, second = (cells[own[i, 0]][own[i, 1]].tolist() for i in idx[:2])
        raise ValueError(
            f"add_shell_mesh: elements {first} and {second} run "
            f"along edge ({a}, {b}) in the same direction: one of them is inverted (normals "
            "must be consistently oriented)"
        )


def _sparsity(triangles, free_index, nfree, load_nodes, block_nodes, node_count, solid_cells):
    """CSR pattern over the free DOFs and the data-slot maps; slot ``nnz`` is a trash slot.
    Every node gets its 6x6 block; ``block_nodes`` (rigid bodies) also get rotation slots."""
    m = len(triangles)
    dofs = (6 * triangles[:, :, None] + np.arange(6)).reshape(m, 18)
    fd = free_index[dofs]  # (m, 18)
    rows = np.repeat(fd, 18, axis=1).reshape(m, 18, 18)
    cols = np.tile(fd, (1, 18)).reshape(m, 18, 18)
    ok = (rows >= 0) & (cols >= 0)
    keys = rows[ok] * nfree + cols[ok]
    # every node gets its own 6x6 block: rigid-body inertia, follower loads on element-free
    # reference nodes, contact and rigid links all couple a node's DOFs among themselves
    bd = free_index[(6 * np.arange(node_count)[:, None] + np.arange(6)).reshape(-1, 6)]
    br = np.repeat(bd, 6, axis=1).ravel()
    bc = np.tile(bd, (1, 6)).ravel()
    bok = (br >= 0) & (bc >= 0)
    keys = np.concatenate([keys, np.arange(nfree) * (nfree + 1), br[bok] * nfree + bc[bok]])
    # solid elements: translational DOFs of their nodes, node-major
    solid_idx = []
    for cells in solid_cells:
        k = cells.shape[1]
        sd = free_index[(6 * cells[:, :, None] + np.arange(3)).reshape(len(cells), 3 * k)]
        sr = np.repeat(sd, 3 * k, axis=1).reshape(len(cells), 3 * k, 3 * k)
        sc = np.tile(sd, (1, 3 * k)).reshape(len(cells), 3 * k, 3 * k)
        solid_idx.append((sr, sc))
        sok = (sr >= 0) & (sc >= 0)
        keys = np.concatenate([keys, sr[sok] * nfree + sc[sok]])
    uniq, inv = np.unique(keys, return_inverse=True)
    nnz = uniq.size
    emap = np.full((m, 18, 18), nnz, dtype=np.int64)
    emap[ok] = inv[: ok.sum()]
    r = uniq // nfree
    indices = (uniq % nfree).astype(np.int64)
    indptr = np.zeros(nfree + 1, dtype=np.int64)
    np.add.at(indptr, r + 1, 1)
    indptr = np.cumsum(indptr)
    diag = np.searchsorted(uniq, np.arange(nfree) * (nfree + 1))

    def slot(i, j):
        if i < 0 or j < 0:
            return nnz
        k = np.searchsorted(uniq, i * nfree + j)
        return int(k) if k < nnz and uniq[k] == i * nfree + j else nnz

    load_emap = np.full((len(load_nodes), 2, 3, 3), nnz, dtype=np.int64)
    for k, node in enumerate(load_nodes):
        for blk in range(2):
            for i in range(3):
                for j in range(3):
                    load_emap[k, blk, i, j] = slot(
                        free_index[6 * node + 3 * blk + i], free_index[6 * node + 3 + j]
                    )
    rigid_slots = np.full((len(block_nodes), 3, 3), nnz, dtype=np.int64)
    for k, node in enumerate(block_nodes):
        for i in range(3):
            for j in range(3):
                rigid_slots[k, i, j] = slot(
                    free_index[6 * node + 3 + i], free_index[6 * node + 3 + j]
                )
    # every node's own 6x6 block (contact with fixed surfaces couples a node with itself)
    nd = free_index[(6 * np.arange(node_count)[:, None] + np.arange(6))]  # (n, 6)
    rr = np.repeat(nd, 6, axis=1).reshape(-1, 6, 6)
    cc = np.tile(nd, (1, 6)).reshape(-1, 6, 6)
    key = rr * nfree + cc
    pos = np.searchsorted(uniq, key)
    pos = np.minimum(pos, nnz - 1)
    found = (rr >= 0) & (cc >= 0) & (uniq[pos] == key)
    node_slots = np.where(found, pos, nnz).astype(np.int64)
    solid_maps = []
    for sr, sc in solid_idx:
        key = sr * nfree + sc
        pos_ = np.minimum(np.searchsorted(uniq, key), nnz - 1)
        found = (sr >= 0) & (sc >= 0) & (uniq[pos_] == key)
        solid_maps.append(np.where(found, pos_, nnz).astype(np.int64))
    return indptr, indices, emap, load_emap, diag, rigid_slots, node_slots, solid_maps
