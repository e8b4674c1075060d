"""ModelBuilder: collects meshes, materials, supports, loads and contact pairs and compiles
them into a :class:`~flexparcel.model.model.Model`.

It lives above :mod:`flexparcel.elements` and :mod:`flexparcel.contact`: each ``add_*`` method
validates its input and creates an element group or a contact set of those packages;
``finalize`` numbers the DOFs, lays out the sparse pattern and binds groups and sets to it.
An element kind or contact pair without an ``add_*`` method comes in through
:meth:`ModelBuilder.add_element_group` / :meth:`ModelBuilder.add_contact_set`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from flexparcel.builder.law_checks import check_law
from flexparcel.builder.mesh_checks import shell_cells
from flexparcel.builder.sparsity import SparsePattern
from flexparcel.contact.bodies import EdgeBoxSet, NodeBoxSet
from flexparcel.contact.edge_edge import EdgeEdgeSet
from flexparcel.contact.edges import EdgePlaneSet
from flexparcel.contact.faces import EdgeFaceSet, NodeFaceSet
from flexparcel.contact.law import PACKED_SIZE, REFERENCE_AREA, REFERENCE_SPACING, ContactLaw
from flexparcel.contact.planes import PlaneBounds, PlanePointSet
from flexparcel.contact.tributary import node_areas, station_areas
from flexparcel.elements.shell import ShellGroup
from flexparcel.elements.solid import SolidGroup
from flexparcel.model.checks import finite_number
from flexparcel.model.interfaces import ContactSet, ElementGroup
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.mesh import shell_edges, surface_triangles
from flexparcel.model.model import Model
from flexparcel.model.rigid import PrescribedMotion, RoundedBox
from flexparcel.model.schedule import Schedule

__all__ = ["ModelBuilder"]

_DOF_NAMES = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}
_DOF_GROUPS = {"all": [0, 1, 2, 3, 4, 5], "translations": [0, 1, 2], "rotations": [3, 4, 5]}


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
    _groups: list[ElementGroup] = field(default_factory=list, repr=False)
    _cells: dict = field(default_factory=dict, repr=False)
    _fixed: dict = field(default_factory=dict, repr=False)
    _loads: list[_Load] = field(default_factory=list, repr=False)
    _rigid: list = field(default_factory=list, repr=False)
    _planes: list = field(default_factory=list, repr=False)
    _slaves: dict = field(default_factory=dict, repr=False)
    _contact_sets: list[ContactSet] = field(default_factory=list, repr=False)
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
        cells, tri, w = shell_cells("add_shell_mesh", pts, quads, triangles)
        n = len(pts)
        ids = np.arange(self._node_count, self._node_count + n)
        self._points.append(pts)
        group = ShellGroup.from_mesh(pts, tri, w, material)
        group.renumber(ids[0])
        self._groups.append(group)
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
        cells, tri, w = shell_cells("add_shell_elements", allpts[used], q, t)
        self._groups.append(ShellGroup.from_mesh(allpts, used[tri], w, material))
        for cname, c in cells:
            self._cells.setdefault(cname, []).append(used[c])

    def add_solid_mesh(
        self,
        points: np.ndarray,
        cells: np.ndarray | Mapping[str, np.ndarray],
        kind: str | None = None,
        *,
        material,
    ) -> np.ndarray:
        """Add a solid mesh (flexible content): ``points`` [m] (n, 3), ``cells`` (m, k) of one
        ``kind`` ("hex8", "wedge6", "pyr5", "tet4" or the meshio names) in VTK node order, or
        a mapping kind -> cells for a mesh of several kinds on the same points (``kind``
        then None), a :class:`flexparcel.elements.solid.SolidMaterial`. Returns the global
        node ids. Nodes used only by solids carry no rotations (those DOFs are held)."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"add_solid_mesh: points must have shape (n, 3), got {pts.shape}")
        if isinstance(cells, Mapping):
            if kind is not None:
                raise ValueError("add_solid_mesh: give kind only with one array of cells")
            blocks = list(cells.items())
        elif kind is None:
            raise ValueError("add_solid_mesh: kind is needed with one array of cells")
        else:
            blocks = [(kind, cells)]
        # validates cells and material per kind
        groups = [SolidGroup(pts, np.asarray(c), k, material) for k, c in blocks]
        ids = np.arange(self._node_count, self._node_count + len(pts))
        for group in groups:
            group.renumber(ids[0])
        self._points.append(pts)
        self._groups.extend(groups)
        self._node_count += len(pts)
        return ids

    def add_element_group(self, group: ElementGroup) -> None:
        """Add an element group built on nodes that already exist (its node ids in this
        builder's numbering): the way in for an element kind without its own ``add_*``
        method (see :class:`flexparcel.model.interfaces.ElementGroup`)."""
        if not isinstance(group, ElementGroup):
            raise TypeError("add_element_group: group must be an ElementGroup")
        self._check_ids("add_element_group", group.nodes())
        self._groups.append(group)

    def add_contact_set(self, contact_set: ContactSet) -> None:
        """Add a contact set (see :class:`flexparcel.model.interfaces.ContactSet`): the way
        in for a contact pair without its own ``add_*`` method. Its nodes must exist."""
        if not isinstance(contact_set, ContactSet):
            raise TypeError("add_contact_set: contact_set must be a ContactSet")
        _require_law("add_contact_set", contact_set.law)
        if not isinstance(contact_set.schedule, Schedule):
            raise TypeError("add_contact_set: the set's schedule must be a Schedule")
        nodes = contact_set.nodes()
        if nodes.size:
            self._check_ids("add_contact_set", nodes)
        self._contact_sets.append(contact_set)

    @contextmanager
    def monitored_contacts(self) -> Iterator[None]:
        """Contact sets added inside this ``with`` block are *monitored*: the integrator
        records the impulse [N s] they exert on every node
        (:attr:`flexparcel.simulate.SimulationResult.monitored_impulses`), so that a load
        such as a deflector's on a consignment can be read as a mean force over any
        interval, whatever the contact's stiffness and the step sizes."""
        first = len(self._contact_sets)
        yield
        for cs in self._contact_sets[first:]:
            cs.monitored = True

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
        *,
        bounds: PlaneBounds | None = None,
    ) -> int:
        """Add a fixed rigid plane through ``point`` [m] with ``normal`` pointing out of its
        solid side; ``surface_velocity`` [m/s] (tangential) makes it a belt. ``bounds``: a
        :class:`~flexparcel.contact.planes.PlaneBounds` makes it a slab of that length and
        width centred on ``point``, with rounded edges (default: a half-space). Returns its
        id. Edge (line) contact takes half-spaces only."""
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
        axis, extent = np.zeros(3), np.zeros(3)
        if bounds is not None:
            if not isinstance(bounds, PlaneBounds):
                raise TypeError(f"add_plane: bounds must be a PlaneBounds, got {type(bounds)}")
            axis = np.asarray(bounds.axis, dtype=float)
            axis = axis / np.linalg.norm(axis)
            if abs(axis @ nrm) > 1e-9:
                raise ValueError("add_plane: bounds.axis must be tangential (normal . axis = 0)")
            extent = np.array([bounds.length / 2, bounds.width / 2, bounds.edge_radius])
        self._planes.append((p, nrm, vel, axis, extent))
        return len(self._planes) - 1

    def add_contact(
        self,
        target,
        plane: int,
        law,
        *,
        radius: float = 0.0,
        area=None,
        schedule: Schedule | None = None,
    ) -> None:
        """Contact between ``target`` and plane ``plane`` with a :class:`ContactLaw` (per unit
        area, see :mod:`flexparcel.contact.law`).

        ``target``: a rigid body's node id (from :meth:`add_rigid_body`): its rounded box's
        inner corners with its edge radius touch the plane; or an array of shell (or solid
        surface) node ids with a contact ``radius`` [m] (e.g. half the shell thickness).
        ``area`` [m^2], a number or one per point: the area each contact point carries. For
        nodes it defaults to their tributary areas on the surfaces added so far (see
        :meth:`node_areas`). A box corner has no surface of its own: it defaults to
        :data:`~flexparcel.contact.law.REFERENCE_AREA` (1e-4 m^2, a 10 mm node), i.e. the
        paper's per-point semantics, so a law from :meth:`ContactLaw.from_paper_units` gives
        each corner the paper's per-point stiffness. ``schedule`` switches the pair on (1) and
        off (0) in time.
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
            areas = _given_areas("add_contact", REFERENCE_AREA if area is None else area, nodes)
        else:
            nodes = self._check_ids("add_contact", target)
            if set(nodes.tolist()) & set(rigid):
                raise ValueError("add_contact: give a rigid body as its single node id")
            offsets = np.zeros((len(nodes), 3))
            radii = np.full(len(nodes), r)
            areas = self._point_areas("add_contact", nodes, area)
        self._contact_sets.append(
            PlanePointSet(nodes, offsets, radii, int(plane), law, sched, areas)
        )

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
        self,
        node_ids,
        body: int,
        law,
        *,
        radius: float = 0.0,
        area=None,
        schedule: Schedule | None = None,
    ) -> None:
        """Contact between shell nodes (contact radius [m], e.g. half the shell thickness) and
        the rounded box of rigid body ``body`` (its node id), e.g. packaging on its content.
        Each node carries its tributary ``area`` [m^2] (default: :meth:`node_areas`) times
        the per-area law."""
        name = "add_body_contact"
        _require_law(name, law)
        body = self._rigid_body(name, body)
        nodes = self._check_ids(name, node_ids)
        r = _nonnegative_radius(name, radius)
        sched = _schedule(schedule)
        areas = self._point_areas(name, nodes, area)
        self._contact_sets.append(NodeBoxSet(nodes, body, r, law, sched, areas))

    def add_face_contact(
        self,
        node_ids,
        face_node_ids,
        law,
        *,
        thickness: float,
        area=None,
        schedule: Schedule | None = None,
    ) -> None:
        """Node-to-face contact: nodes ``node_ids`` against the shell faces whose corners all
        lie in ``face_node_ids`` (packaging layer against layer, consignment against
        consignment). ``thickness`` [m]: the contact distance, e.g. the mean of the two shells'
        thicknesses. Both sides of a face are free (thin shells). Each slave node carries its
        tributary ``area`` [m^2] (default: :meth:`node_areas`) times the per-area law."""
        name = "add_face_contact"
        _require_law(name, law)
        nodes = self._check_ids(name, node_ids)
        h = _positive_thickness(name, thickness)
        tris = self._face_triangles(name, face_node_ids)
        sched = _schedule(schedule)
        areas = self._point_areas(name, nodes, area)
        self._contact_sets.append(NodeFaceSet(nodes, tris, h, law, sched, areas))

    def add_edge_face_contact(
        self,
        node_ids,
        face_node_ids,
        law,
        *,
        thickness: float,
        samples: int = 3,
        width: float = REFERENCE_SPACING,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` against the
        shell (or solid boundary) faces whose corners all lie in ``face_node_ids``, e.g. a
        packaging's border against another consignment; each edge is sampled at ``samples``
        stations (see :func:`flexparcel.contact.faces.edge_face_forces`). ``thickness`` [m] as
        for :meth:`add_face_contact`. Line contact is per unit length: the per-area law times
        the strip ``width`` [m] (default 10 mm, the paper's node spacing, so a 10 mm edge
        carries a paper law's per-point value), each station its edge's length / samples."""
        name = "add_edge_face_contact"
        _require_law(name, law)
        h = _positive_thickness(name, thickness)
        edges = self._shell_edges(name, node_ids)
        tris = self._face_triangles(name, face_node_ids)
        n = _sample_count(name, samples)
        areas = self._station_areas(name, edges, n, width)
        self._contact_sets.append(EdgeFaceSet(edges, tris, h, n, law, _schedule(schedule), areas))

    def add_edge_edge_contact(
        self,
        node_ids,
        other_node_ids,
        law,
        *,
        thickness: float,
        width: float = REFERENCE_SPACING,
        schedule: Schedule | None = None,
    ) -> None:
        """Edge-to-edge line contact of the shell (or rigid mesh) edges whose two nodes are both
        in ``node_ids`` against those whose two nodes are both in ``other_node_ids``, e.g. a
        deflector's tip edge against a packaging's element edges, which cross it between any
        stations of :meth:`add_edge_face_contact`. ``thickness`` [m]: the sum of the two
        edges' radii (:mod:`flexparcel.contact.edge_edge`). Edges sharing a node never touch.
        Per unit length: a pair carries the per-area law times ``width`` [m] (default 10 mm)
        times the reference length of its edge of ``other_node_ids`` (the packaging's)."""
        name = "add_edge_edge_contact"
        _require_law(name, law)
        h = _positive_thickness(name, thickness)
        edges_a = self._shell_edges(name, node_ids)
        edges_b = self._shell_edges(name, other_node_ids)
        areas_b = self._station_areas(name, edges_b, 1, width)
        self._contact_sets.append(
            EdgeEdgeSet(edges_a, edges_b, h, law, _schedule(schedule), areas_b)
        )

    def _face_triangles(self, name: str, face_node_ids) -> np.ndarray:
        """Triangles (M, 3) of the shell faces (quads split once) and solid boundary faces
        whose corners all lie in ``face_node_ids``."""
        ids = self._check_ids(name, face_node_ids)
        keep = np.zeros(self._node_count, dtype=bool)
        keep[ids] = True
        cells = [(ctype, c) for ctype, lst in self._cells.items() for c in lst]
        solid_cells = [g.cells for g in self._groups if isinstance(g, SolidGroup)]
        solid = _solid_boundary_triangles(solid_cells, set(ids.tolist()))
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
        width: float = REFERENCE_SPACING,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` (e.g. the
        glued border of an envelope standing on it) against plane ``plane``; each edge is
        sampled at ``samples`` stations (see :mod:`flexparcel.contact.edges`). Per unit
        length: the per-area law times the strip ``width`` [m] (default 10 mm, the paper's node
        spacing), each station its edge's reference length / samples. With a stick model in
        the law each station keeps its own stick spring, as a node on a plane does."""
        if not (isinstance(plane, int | np.integer) and 0 <= plane < len(self._planes)):
            raise ValueError(
                f"add_edge_contact: unknown plane {plane!r}; planes are 0..{len(self._planes) - 1}"
            )
        if self._planes[int(plane)][4][2] > 0.0:
            raise ValueError(
                f"add_edge_contact: plane {plane} is bounded (PlaneBounds); edge contact takes "
                "half-space planes only"
            )
        self._contact_sets.append(EdgePlaneSet(*self._edge_set(
            "add_edge_contact", node_ids, int(plane), law, radius, samples, width, schedule
        )))  # fmt: skip

    def add_edge_body_contact(
        self,
        node_ids,
        body: int,
        law,
        *,
        radius: float = 0.0,
        samples: int = 3,
        width: float = REFERENCE_SPACING,
        schedule: Schedule | None = None,
    ) -> None:
        """Line contact of the shell edges whose two nodes are both in ``node_ids`` against the
        rounded box of rigid body ``body`` (its node id), e.g. a packaging's border against its
        content's edges; ``samples`` stations per edge (see :mod:`flexparcel.contact.bodies`).
        Per unit length: the per-area law times the strip ``width`` [m] (default 10 mm)."""
        name = "add_edge_body_contact"
        self._contact_sets.append(EdgeBoxSet(*self._edge_set(
            name, node_ids, self._rigid_body(name, body), law, radius, samples, width, schedule
        )))  # fmt: skip

    def _rigid_body(self, name: str, body) -> int:
        """``body`` as a rigid body's node id, else ``ValueError`` listing the rigid bodies."""
        rigid = {node for node, _, _ in self._rigid}
        if not (isinstance(body, int | np.integer) and int(body) in rigid):
            raise ValueError(
                f"{name}: body {body!r} is not a rigid body's node; rigid bodies: {sorted(rigid)}"
            )
        return int(body)

    def _edge_set(self, name, node_ids, target, law, radius, samples, width, schedule) -> tuple:
        """(edges (E, 2), target, radius, samples, law, schedule, station areas (E,)) of a
        line-contact set against a plane or a body, with its input checked."""
        _require_law(name, law)
        r = _nonnegative_radius(name, radius)
        n = _sample_count(name, samples)
        edges = self._shell_edges(name, node_ids)
        areas = self._station_areas(name, edges, n, width)
        return (edges, target, r, n, law, _schedule(schedule), areas)

    def node_areas(self, node_ids) -> np.ndarray:
        """Tributary area [m^2] of each node in ``node_ids``, shape (k,), on the reference
        geometry of the surfaces added so far: its median-dual share of every shell cell
        (quad or triangle, each once), rigid mesh triangle and solid boundary face around it
        (:func:`flexparcel.contact.tributary.node_areas`: a third of each triangle, a quarter
        of a parallelogram quad). The per-area contact law is multiplied by it; zero for a
        solid's interior node."""
        ids = self._check_ids("node_areas", node_ids)
        pts = np.concatenate(self._points)
        return node_areas(pts, self._surface_faces(), self._node_count)[ids]

    def _surface_faces(self) -> list[np.ndarray]:
        """Polygons (m, 3) and (m, 4) of every surface a contact point can stand for: the
        shell cells and rigid mesh triangles (a cell given twice counted once) and the solid
        boundary faces."""
        by_size: dict[int, list] = {3: [], 4: []}
        for ctype, lst in self._cells.items():
            if ctype in ("quad", "triangle"):
                for c in lst:
                    by_size[c.shape[1]].append(np.asarray(c, dtype=np.int64))
        solid_cells = [g.cells for g in self._groups if isinstance(g, SolidGroup)]
        for face in _solid_boundary_faces(solid_cells):
            by_size[len(face)].append(np.asarray(face, dtype=np.int64)[None, :])
        out = []
        for lst in by_size.values():
            if lst:
                c = np.vstack(lst)
                _, first = np.unique(np.sort(c, axis=1), axis=0, return_index=True)
                out.append(c[np.sort(first)])
        return out

    def _point_areas(self, name: str, nodes: np.ndarray, area) -> np.ndarray:
        """Areas [m^2] the contact points at ``nodes`` carry: ``area`` if given (a number or
        one per node), else their tributary areas (:meth:`node_areas`). A node on no surface
        (not a solid's interior node) has none: ``ValueError`` asking for ``area``."""
        if area is not None:
            return _given_areas(name, area, nodes)
        a = self.node_areas(nodes)
        solid = _union([g.nodes() for g in self._groups if isinstance(g, SolidGroup)])
        bad = nodes[(a == 0.0) & ~np.isin(nodes, solid)]
        if bad.size:
            raise ValueError(
                f"{name}: node {int(bad[0])} lies on no shell cell or solid boundary face, so it "
                "has no tributary area for the per-area contact law; give area= [m^2]"
            )
        return a

    def _station_areas(self, name: str, edges: np.ndarray, samples: int, width) -> np.ndarray:
        """Area [m^2] of each station of each edge: reference length / samples x ``width``."""
        w = finite_number(f"{name}: width", width)
        if not w > 0.0:
            raise ValueError(f"{name}: width must be > 0 m, got {width!r}")
        return station_areas(np.concatenate(self._points), edges, samples, w)

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
        self, node_ids, law, *, thickness: float, area=None, schedule: Schedule | None = None
    ) -> None:
        """Self contact of a shell mesh (e.g. an envelope's layers): its nodes against its own
        faces, a node never against a face it is a corner of (``area`` as for
        :meth:`add_face_contact`)."""
        self.add_face_contact(
            node_ids, node_ids, law, thickness=thickness, area=area, schedule=schedule
        )

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
        """Validate, bind the element groups and contact sets, lump the mass and lay out the
        sparse pattern."""
        if not self._points:
            raise ValueError("ModelBuilder.finalize: no mesh or rigid body was added")
        pos0 = np.concatenate(self._points)
        n = len(pos0)
        groups = _joined_groups(self._groups)
        mass = np.zeros((n, 6))
        for g in groups:
            mass += g.lumped_mass(n)
        rigid_nodes = np.array([r[0] for r in self._rigid], dtype=np.int64)
        rigid_inertia = np.zeros((len(self._rigid), 3, 3))
        pres_nodes, pres_vel, pres_sched = [], [], []
        for k, (node, shape, motion) in enumerate(self._rigid):
            mass[node, :3] = shape.total_mass()
            rigid_inertia[k] = shape.inertia()  # rotary inertia handled as a tensor, not in mass
            if isinstance(motion, PrescribedMotion):
                pres_nodes.append(node)
                pres_vel.append(np.r_[motion.velocity, motion.angular_velocity])
                pres_sched.append(motion.schedule)
        element_nodes = _union([g.nodes() for g in groups])
        attached = np.union1d(element_nodes, rigid_nodes)
        orphan = np.setdiff1d(np.arange(n), np.union1d(attached, self._refs))
        if orphan.size:
            raise ValueError(f"finalize: node {int(orphan[0])} belongs to no element")
        fixed = self._fixed_dofs(n, groups, element_nodes, rigid_nodes)
        loads, schedules = self._compiled_loads(fixed)
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
        free_index, free_count = _dof_numbering(fixed, slave_nodes)
        pattern = SparsePattern(free_index, [g.element_dofs() for g in groups])
        for g, slots in zip(groups, pattern.group_slots, strict=True):
            g.bind(slots)
        laws, contact_schedules = self._bind_contact_sets()
        box_half = np.zeros((n, 3))
        box_rad = np.zeros(n)
        for node, shape, _ in self._rigid:
            box_half[node] = shape.half_inner
            box_rad[node] = shape.edge_radius
        load_nodes = np.asarray(loads["nodes"], dtype=np.int64)
        cells = _output_cells(self._cells, groups)
        return Model(
            positions0=pos0,
            mass=mass,
            gravity=np.asarray(self.gravity, dtype=float),
            fixed=fixed,
            load_nodes=load_nodes,
            load_vectors=np.asarray(loads["vectors"], dtype=float).reshape(-1, 3),
            load_is_moment=np.asarray(loads["is_moment"], dtype=bool),
            load_follower=np.asarray(loads["follower"], dtype=bool),
            load_schedule=np.asarray(loads["schedule"], dtype=np.int64),
            schedules=schedules,
            gravity_schedule=self.gravity_schedule,
            cells=cells,
            element_groups=groups,
            free_index=free_index,
            csr_indptr=pattern.indptr,
            csr_indices=pattern.indices,
            load_emap=pattern.load_slots(load_nodes),
            diag_slots=pattern.diag,
            rigid_nodes=rigid_nodes,
            rigid_inertia=rigid_inertia,
            rigid_half_inner=np.array([r[1].half_inner for r in self._rigid]).reshape(-1, 3),
            rigid_radius=np.array([r[1].edge_radius for r in self._rigid], dtype=float),
            rigid_rot_slots=pattern.rotation_slots(rigid_nodes),
            prescribed_nodes=np.asarray(pres_nodes, dtype=np.int64),
            prescribed_velocity=np.asarray(pres_vel, dtype=float).reshape(-1, 6),
            prescribed_schedules=pres_sched,
            node_block_slots=pattern.node_slots(n),
            plane_point=np.array([p[0] for p in self._planes]).reshape(-1, 3),
            plane_normal=np.array([p[1] for p in self._planes]).reshape(-1, 3),
            plane_velocity=np.array([p[2] for p in self._planes]).reshape(-1, 3),
            plane_axis=np.array([p[3] for p in self._planes]).reshape(-1, 3),
            plane_extent=np.array([p[4] for p in self._planes]).reshape(-1, 3),
            contact_laws=(
                np.array([law.packed() for law in laws]) if laws else np.zeros((0, PACKED_SIZE))
            ),
            contact_schedules=contact_schedules,
            contact_sets=list(self._contact_sets),
            free_count=free_count,
            box_half_by_node=box_half,
            box_radius_by_node=box_rad,
            slave_nodes=slave_nodes,
            slave_master=slave_master,
            slave_offset=slave_offset,
            mass_damping=float(self.mass_damping),
        )

    def _fixed_dofs(self, n: int, groups, element_nodes, rigid_nodes) -> np.ndarray:
        """Held DOFs (n, 6): the user's supports, held or driven bodies, and the rotations of
        nodes that no element, body or FDR gives rotational stiffness or inertia."""
        fixed = np.zeros((n, 6), dtype=bool)
        for node, dofs in self._fixed.items():
            fixed[node, sorted(dofs)] = True
        for node, _, motion in self._rigid:
            if motion != "free":
                fixed[node] = True  # held or driven: not unknowns
        rot_free = _union([g.rotation_nodes() for g in groups] + [rigid_nodes])
        masters = np.array(sorted(set(self._slaves.values())), np.int64)
        rot_free = np.union1d(rot_free, masters)
        translation_only = np.setdiff1d(element_nodes, rot_free)
        translation_only = np.setdiff1d(translation_only, np.array(sorted(self._slaves), np.int64))
        fixed[translation_only, 3:] = True
        return fixed

    def _compiled_loads(self, fixed: np.ndarray) -> tuple[dict, list[Schedule]]:
        """Nodal loads as flat lists (nodes, vectors, is_moment, follower, schedule index)
        and their schedules; a load on a held DOF is refused."""
        schedules: list[Schedule] = []
        out = {"nodes": [], "vectors": [], "is_moment": [], "follower": [], "schedule": []}
        for ld in self._loads:
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
                for key, v in zip(out, (node, ld.vector, ld.is_moment, ld.follower, si),
                                  strict=True):  # fmt: skip
                    out[key].append(v)
        return out, schedules

    def _bind_contact_sets(self) -> tuple[list, list[Schedule]]:
        """Give each contact set its key and the rows of its law and schedule in the model's
        tables; returns the tables (distinct laws, distinct schedules)."""
        laws, schedules = [], []
        for i, cs in enumerate(self._contact_sets):
            if cs.law not in laws:
                laws.append(cs.law)
            if cs.schedule not in schedules:
                schedules.append(cs.schedule)
            cs.law_index = laws.index(cs.law)
            cs.schedule_index = schedules.index(cs.schedule)
            cs.key = f"{cs.kind}{i}"
        return laws, schedules

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
    """A :class:`ContactLaw`, else ``TypeError``; implausible values are warned about
    (:func:`~flexparcel.builder.law_checks.check_law`)."""
    if not isinstance(law, ContactLaw):
        raise TypeError(f"{name}: law must be a ContactLaw")
    check_law(name, law)


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


def _solid_boundary_triangles(solid_cells: list, nodes: set) -> np.ndarray:
    """Triangles of the boundary faces (faces of exactly one solid element, over all solid
    blocks ``solid_cells``, each (m, k)) whose corners all lie in ``nodes``, shape (m, 3)."""
    count: dict = {}
    faces = []
    for cells in solid_cells:
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


def _solid_boundary_faces(solid_cells: list) -> list:
    """Boundary faces (faces of exactly one solid element, over all solid blocks
    ``solid_cells``, each (m, k)) as node lists of 3 or 4 corners, unsplit."""
    count: dict = {}
    faces = []
    for cells in solid_cells:
        for face in _SOLID_FACES[cells.shape[1]]:
            for row in np.asarray(cells)[:, face].tolist():
                key = tuple(sorted(row))
                count[key] = count.get(key, 0) + 1
                faces.append((key, row))
    return [row for key, row in faces if count[key] == 1]


def _given_areas(name: str, area, nodes: np.ndarray) -> np.ndarray:
    """``area`` [m^2] (a number or one per contact point) checked, shape (len(nodes),)."""
    a = np.asarray(area, dtype=float)
    if a.ndim > 1 or (a.ndim == 1 and a.shape != nodes.shape):
        raise ValueError(
            f"{name}: area must be a number or one per contact point ({nodes.size}), "
            f"got shape {a.shape}"
        )
    if not np.all(np.isfinite(a) & (a >= 0.0)):
        raise ValueError(f"{name}: area must be finite and >= 0 m^2, got {area!r}")
    return np.array(np.broadcast_to(a, nodes.shape), dtype=float)


def _union(parts: list) -> np.ndarray:
    """Sorted union of integer arrays (int64, empty if none)."""
    parts = [np.asarray(p, dtype=np.int64).ravel() for p in parts]
    return np.unique(np.concatenate(parts)) if parts else np.zeros(0, np.int64)


def _joined_groups(groups: list) -> list:
    """The element groups with every run of groups of one class that can be joined
    (``concatenate``) made one, so that one kernel call covers them."""
    out: list = []
    by_class: dict = {}
    for g in groups:
        cls = type(g)
        if hasattr(cls, "concatenate"):
            by_class.setdefault(cls, []).append(g)
        else:
            out.append(g)
    joined = [cls.concatenate(gs) if len(gs) > 1 else gs[0] for cls, gs in by_class.items()]
    return joined + out


_VTK_SOLIDS = {"hex8": "hexahedron", "wedge6": "wedge", "pyr5": "pyramid", "tet4": "tetra"}


def _output_cells(shell_cells: dict, groups: list) -> list[tuple[str, np.ndarray]]:
    """Cells for output files: the shell and rigid-mesh cells as added, then the solids."""
    cells = {k: list(v) for k, v in shell_cells.items()}
    for g in groups:
        if isinstance(g, SolidGroup):
            cells.setdefault(_VTK_SOLIDS[g.element_kind], []).append(g.cells)
    return [(k, np.concatenate(v)) for k, v in cells.items()]


def _dof_numbering(fixed: np.ndarray, slave_nodes: np.ndarray) -> tuple[np.ndarray, int]:
    """Number of each DOF (n * 6,): the unknowns first, then the FDR slave DOFs, -1 where
    held. Matrices are assembled over both and reduced onto the unknowns with the rigid-link
    map (see flexparcel.integrate.assembly.reduction). Returns (numbers, unknown count)."""
    is_slave = np.zeros(fixed.shape, dtype=bool)
    is_slave[slave_nodes] = True
    free_index = np.full(fixed.size, -1, dtype=np.int64)
    free = np.flatnonzero(~fixed.ravel() & ~is_slave.ravel())
    if free.size == 0:
        raise ValueError("finalize: every DOF is fixed; nothing to solve")
    free_index[free] = np.arange(free.size)
    slave_dofs = np.flatnonzero(is_slave.ravel())
    free_index[slave_dofs] = free.size + np.arange(slave_dofs.size)
    return free_index, int(free.size)
