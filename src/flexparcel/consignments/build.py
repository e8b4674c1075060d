"""Consignment builders: the paper's four consignments (Table 2) and user-defined ones.

Each consignment is built bottom-up as in the paper (section 3.1): the packaging meshed with
square shells, KP/BW's 10 mm glued strip of doubled thickness along one short side, and the
content inside, a rigid rounded box or (PB) a hexahedral solid mesh. The packaging is built
flat by its construction (``ConsignmentSpec.construction``):

- ``"envelope"`` (KP/BW, PB, BW): two rectangles joined at their shared border nodes, the top
  layer 2 mm above the bottom one (:func:`flexparcel.scenarios.envelope.two_layer_envelope`);
- ``"gusseted"`` (KP): a flat-folded bag in six layers, a W-gusset along each long side and
  sealed ends (:func:`flexparcel.scenarios.envelope.gusseted_envelope`). The folds are the
  reference (stress-free) geometry, so once the bag is opened the film bends at its fold
  lines and keeps their memory as prestress, which is what the paper's KP construction is
  for (section 3.1.2, Figs. 13-14: eight layers folded, unfolded by forces). Its side walls
  give the content's height, so the flat bag is Table 2's width; its sealed ends are wedges.

The assembly (:mod:`flexparcel.consignments.assembly`) opens the packaging with forces,
switches the packaging-content contact on and lets the packaging close around the content,
which leaves the prestress of the real packaging in the model.

Simplifications, written down rather than hidden:

- KP's gusseted bag is not the paper's eight-layer wedge: its ends are sealed seams, not
  folded, so the flat bag must still be content + content height + one element long to hold
  its content, longer than Table 2's 320 mm; both its layers are pulled open (the paper holds
  one and pulls the other). Its content is glued to the bottom panel with the FDR stripe.
- BW's rounded short sides come from the opening (the layers bend round the content at
  every border); the FDR-and-torque fold of the paper is not reproduced.
- An envelope is made just large enough that the content fits once it is wrapped:
  ``max(outer, content + content height + 4 mm)`` in length and width (a flat bag of exactly the
  filled outer size cannot hold a content of the same width).

Coordinates: the bottom layer lies in z = 0 centred on the origin, x along the length.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.consignments.materials import (
    FLEXIBLE_CONTENT,
    PackagingMaterial,
    packaging_material,
)
from flexparcel.consignments.spec import ConsignmentSpec
from flexparcel.contact.law import ContactLaw
from flexparcel.elements.solid import SolidMaterial, solid_reference_data
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.rigid import RoundedBox
from flexparcel.model.schedule import Schedule
from flexparcel.scenarios.envelope import gusseted_envelope, two_layer_envelope

__all__ = [
    "PRESETS",
    "PRESET_ELEMENT_SIZE",
    "Consignment",
    "ConsignmentBuild",
    "preset",
    "add_consignment",
    "add_ground_contact",
    "add_air_drag",
    "default_packaging_content_law",
]

# Table 2 of the paper (reference/consignments.csv): outer and content sizes [mm], total mass [g]
PRESETS: dict[str, ConsignmentSpec] = {
    "KPBW": ConsignmentSpec(
        "KPBW", "kraft_paper_bubble_wrap", 275, 200, 20, "rigid", 165, 125, 20, 140,
        content_fixed_to_packaging=False, based_on_cluster=1,
    ),
    "PB": ConsignmentSpec(
        "PB", "polybag", 315, 225, 20, "flexible", 310, 225, 20, 180,
        content_fixed_to_packaging=False, based_on_cluster=3,
    ),
    "KP": ConsignmentSpec(
        "KP", "kraft_paper", 320, 250, 30, "rigid", 310, 225, 30, 380,
        content_fixed_to_packaging=True, based_on_cluster=4, construction="gusseted",
    ),
    "BW": ConsignmentSpec(
        "BW", "bubble_wrap", 200, 150, 20, "rigid", 165, 125, 20, 80,
        content_fixed_to_packaging=False, based_on_cluster=6,
    ),
}  # fmt: skip
PRESET_ELEMENT_SIZE = {"KPBW": 0.010, "PB": 0.010, "KP": 0.010, "BW": 0.005}
"""Shell edge length [m] per preset (paper 3.1.1: 10 mm, 5 mm for BW)."""

GLUED_STRIP_WIDTH = 0.010  # KP/BW, paper 3.1.1
INITIAL_GAP = 2e-3  # top layer above the bottom one before the opening [m]
FIT_CLEARANCE = 4e-3  # flat packaging >= content + content height + this (at least) [m]
CONTENT_EDGE_RADIUS = 3e-3  # rounded edges of the cardboard box contents [m]
FLEXIBLE_CONTENT_EDGE_RADIUS = 0.5  # flexible content: edge radius / content height
CONTENT_CLEARANCE = 0.2e-3  # content above the bottom layer's contact surface [m]
GLUE_STRIPE = (0.6, 0.020)  # KP: stripe length (fraction of content length), width [m]
GUSSET_SPACING = 1e-3  # gusseted bag: layers apart in the folded state [m]
GUSSET_SLACK = 2e-3  # gusseted bag: side wall height beyond the content's height [m]


def preset(name: str) -> ConsignmentSpec:
    """The Table 2 consignment ``name`` (KPBW, PB, KP, BW; "KP/BW" accepted)."""
    key = name.replace("/", "").upper()
    if key not in PRESETS:
        raise ValueError(f"unknown consignment {name!r}; allowed: {', '.join(PRESETS)}")
    return PRESETS[key]


def default_packaging_content_law(stick_model: bool = True) -> ContactLaw:
    """Packaging-content (and packaging-packaging) contact of the paper's Table 6: 649 N/mm,
    0.579 Ns/mm with STEP damping over 0.1 mm; friction 0.3 (not given in the paper).

    ``stick_model`` (default on, beyond the paper): friction by the stick model with k_t = c
    (:meth:`ContactLaw.with_stick_model`) instead of the paper's regularised eq. (8). The
    regularised law's band |v| < v_s = 1 mm/s is far narrower than the velocity corrections
    of a Newton iteration in a packaging that slides on its content, so Newton cycles across
    it: a KP/BW 25 mm horizontal drop (Table 6) took 3023 steps and 434 s with it, 816 steps
    and 40 s with the stick model. False gives the paper's law exactly.

    Per unit area (:mod:`flexparcel.contact.law`): Table 6's per-point values belong to the
    paper's 10 mm nodes, so c = 649 N/mm / (10 mm)^2 = 6.49e9 N/m^3 and d = 5.79e6 N s/m^3;
    a 25 mm node carries 6.25 times the paper's per-point value."""
    law = ContactLaw.from_paper_units(
        c_N_per_mm=649, d_Ns_per_mm=0.579, s_max_mm=0.1, mu_static=0.3, mu_dynamic=0.3,
        reference_spacing_mm=10.0,
    )  # fmt: skip
    return law.with_stick_model() if stick_model else law


@dataclass(frozen=True)
class ConsignmentBuild:
    """Everything that fixes a consignment's mesh: two equal builds number nodes identically
    (snapshots rely on it)."""

    spec: ConsignmentSpec
    material: PackagingMaterial
    element_size: float
    """Shell edge length [m]."""

    @classmethod
    def of(
        cls,
        spec: ConsignmentSpec | str,
        *,
        element_size: float | None = None,
        material: PackagingMaterial | None = None,
    ) -> ConsignmentBuild:
        spec = preset(spec) if isinstance(spec, str) else spec
        if element_size is None:
            element_size = PRESET_ELEMENT_SIZE.get(spec.id, 0.010)
        if not (np.isfinite(element_size) and 1e-3 <= element_size <= 0.1):
            raise ValueError(f"element_size must be in [0.001, 0.1] m, got {element_size!r}")
        mat = material or packaging_material(spec.packaging_material)
        return cls(spec, mat, float(element_size))

    def to_dict(self) -> dict:
        return {
            "spec": asdict(self.spec),
            "material": asdict(self.material),
            "element_size": self.element_size,
        }

    @classmethod
    def from_dict(cls, d: dict) -> ConsignmentBuild:
        return cls(
            ConsignmentSpec(**d["spec"]),
            PackagingMaterial(**d["material"]),
            float(d["element_size"]),
        )

    @property
    def flat_size(self) -> tuple[float, float]:
        """Length and width [m] of the flat packaging (without KP/BW's glued strip).

        An envelope wraps its content's height at both ends and both sides, so it is at least
        content + height + :attr:`fit_clearance` long and wide. A gusseted bag wraps it only
        at its sealed ends: its side walls give the height, so its width is Table 2's (at
        least the content's + :attr:`fit_clearance`)."""
        s = self.spec
        strip = GLUED_STRIP_WIDTH if self.has_glued_strip else 0.0
        need_l = (s.content_length_mm + s.content_height_mm) * 1e-3 + self.fit_clearance
        side = 0.0 if s.construction == "gusseted" else s.content_height_mm
        need_w = (s.content_width_mm + side) * 1e-3 + self.fit_clearance
        return max(s.length_mm * 1e-3 - strip, need_l), max(s.width_mm * 1e-3, need_w)

    @property
    def gusset_depth(self) -> float:
        """Depth [m] of each folded side gusset of a gusseted bag: half its unfolded wall's
        height, the content's height + :data:`GUSSET_SLACK` (room for the film on both
        faces and the content's clearance above the bottom layer)."""
        return 0.5 * (self.spec.content_height_mm * 1e-3 + GUSSET_SLACK)

    @property
    def fit_clearance(self) -> float:
        """Film [m] beyond the content's length (width) + height that a tight flat packaging
        gets: FIT_CLEARANCE, or one element where that is more. Two flat rectangles cannot
        wrap a box without excess film at its corners (the box's corners need double
        curvature); a real film takes it up in mm-sized wrinkles, a shell mesh only in folds
        of about one element. With 4 mm at 25 mm elements, KP's film could not close round
        its grown content: the content pushed 4 mm into it and the settling stalled at 5 us
        steps."""
        return max(FIT_CLEARANCE, self.element_size)

    @property
    def has_glued_strip(self) -> bool:
        return self.spec.packaging_material == "kraft_paper_bubble_wrap"


@dataclass
class Consignment:
    """Node ids and masses of a consignment added to a :class:`ModelBuilder`."""

    build: ConsignmentBuild
    packaging: np.ndarray
    """All packaging shell nodes (both layers and the glued strip)."""
    top: np.ndarray
    """Top-layer nodes off the border (the opening force pulls them up)."""
    bottom: np.ndarray
    """Bottom-layer nodes off the border (pulled down), minus KP's glue stripe."""
    border: np.ndarray
    """Nodes shared by both layers."""
    edge: np.ndarray
    """Nodes of the outer edge at +x (KP/BW: the glued strip's): the vertical drop's line
    contact stands on it."""
    content_body: int | None
    """Rigid content's node, or None for a flexible content."""
    content_nodes: np.ndarray
    """Solid content's nodes (flexible), or [content_body]."""
    packaging_mass: float
    content_mass: float
    contact_radius: float
    """Half the packaging thickness [m]."""
    content_box: tuple[float, float, float]
    """Content length, width, height [m]."""
    glue: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    """KP: bottom-layer nodes tied to the content (FDR glue stripe)."""
    top_quads: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.int64))
    """The top layer's shell quads (q, 4), node ids: the envelope's face for air drag."""

    @property
    def node_ids(self) -> np.ndarray:
        """Every node of the consignment."""
        return np.union1d(self.packaging, self.content_nodes)


def add_consignment(
    b: ModelBuilder,
    build: ConsignmentBuild,
    *,
    content_law: ContactLaw | None = None,
    content_contact: Schedule | None = None,
    self_contact: bool = True,
) -> Consignment:
    """Add the packaging, the content, the packaging-content contact (switched by
    ``content_contact``, default on) and the packaging's self contact (layer on layer)."""
    spec, mat, h = build.spec, build.material, build.element_size
    pm = _packaging_mesh(build)
    pts, quads = pm.points, pm.quads
    strip_area = 0.0
    strip_quads = None
    if build.has_glued_strip:
        # one row of doubled-thickness shells outside the +x border, in the border's plane
        col = pm.edge  # ordered by y
        new = len(pts) + np.arange(len(col))
        pts = np.vstack([pts, pts[col] + (GLUED_STRIP_WIDTH, 0.0, 0.0)])
        strip_quads = np.column_stack([col[:-1], new[:-1], new[1:], col[1:]])
        edge_local = new
        strip_area = GLUED_STRIP_WIDTH * build.flat_size[1]
    else:
        edge_local = pm.edge
    t = mat.thickness
    shell = ShellMaterial(mat.youngs_modulus, mat.poisson_ratio, mat.density, t,
                          mat.damping_ratio, mat.membrane)  # fmt: skip
    ids = b.add_shell_mesh(pts, quads, material=shell)
    if strip_quads is not None:
        doubled = replace(shell, thickness=2 * t)
        b.add_shell_elements(ids[strip_quads], material=doubled)
    # real mesh area (the first ring of the top layer slopes up to the initial gap)
    q = pts[quads]
    area = 0.5 * np.linalg.norm(np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1]), axis=1).sum()
    packaging_mass = mat.areal_density * (area + 2 * strip_area)
    content_mass = spec.mass_g * 1e-3 - packaging_mass
    if content_mass <= 0:
        raise ValueError(
            f"consignment {spec.id!r}: the packaging alone weighs {packaging_mass * 1e3:.1f} g, "
            f"more than mass_g = {spec.mass_g} g; lower the packaging's areal_density"
        )
    lc, wc, hc = (spec.content_length_mm * 1e-3, spec.content_width_mm * 1e-3,
                  spec.content_height_mm * 1e-3)  # fmt: skip
    zc = t / 2 + CONTENT_CLEARANCE + hc / 2
    law = content_law or default_packaging_content_law()
    sched = content_contact or Schedule.constant(1.0)
    glue = np.zeros(0, np.int64)
    if spec.content_kind == "rigid":
        radius = min(CONTENT_EDGE_RADIUS, 0.25 * min(lc, wc, hc))
        body = b.add_rigid_body(RoundedBox(lc, wc, hc, edge_radius=radius, mass=content_mass),
                                (0.0, 0.0, zc))  # fmt: skip
        content_nodes = np.array([body])
        contact_nodes = ids
        if spec.content_fixed_to_packaging:
            gl, gw = GLUE_STRIPE[0] * lc, GLUE_STRIPE[1]
            p = np.abs(pts[pm.bottom_layer, :2])
            # a stripe narrower than an element takes the row of nodes nearest its centre line
            # (an odd number of elements across has no node row on it)
            half = np.maximum((gl / 2, gw / 2), p.min(axis=0)) + 1e-9
            inside = (p[:, 0] <= half[0]) & (p[:, 1] <= half[1])
            glue = ids[pm.bottom_layer[inside & ~np.isin(pm.bottom_layer, pm.border)]]
            if glue.size == 0:
                raise ValueError(f"consignment {spec.id!r}: the glue stripe holds no node")
            b.add_fdr(glue, reference=body)
            contact_nodes = np.setdiff1d(ids, glue)
        b.add_body_contact(contact_nodes, body, law, radius=t / 2, schedule=sched)
    else:
        body = None
        sp_, cells = _hex_block(lc, wc, hc, h, (0.0, 0.0, zc))
        edges = _block_edges(sp_)
        # A granulate bag is no sharp box: its edges are rounded with half its height, the
        # radius of a fold. With sharp corners a flat pillow bag of 25 mm film elements cannot
        # wrap them: in PB assembled at 25 mm, 4 of the 8 corners ended outside the film.
        sp_ = _round_block(sp_, FLEXIBLE_CONTENT_EDGE_RADIUS * hc)
        unit = SolidMaterial(
            FLEXIBLE_CONTENT["youngs_modulus"], FLEXIBLE_CONTENT["poisson_ratio"], 1.0,
            FLEXIBLE_CONTENT["damping_ratio"],
        )  # fmt: skip
        volume = float(solid_reference_data(sp_, cells, "hex8", unit).volume.sum())
        solid = replace(unit, density=content_mass / volume)
        content_nodes = b.add_solid_mesh(sp_, cells, "hex8", material=solid)
        # Node-to-face contact both ways (the two-pass method, Wriggers, Computational
        # Contact Mechanics, 2006, sec. 5.2): film nodes against the block's boundary faces,
        # and the block's edge and corner nodes against the film faces. With the first pass
        # alone the block's edges slip between the film nodes, where a film face spans the
        # corner as a chord: in PB assembled at 25 mm (sharp block), 114 of 390 content
        # nodes ended outside the film, with both passes 35 (4 corners under the film's rim),
        # with both passes and rounded edges 40, no corner among them, at most 0.43 mm out
        # (data/paper-snapshots-25mm/README.md). The block's face-inner nodes are left out
        # of the second pass: with all boundary nodes in it PB's assembly (sharp block) took
        # 10,662 steps and did not come to rest, against 3,629 with edges and corners.
        b.add_face_contact(ids, content_nodes, law, thickness=t / 2, schedule=sched)
        b.add_face_contact(content_nodes[edges], ids, law, thickness=t / 2, schedule=sched)
    if self_contact:
        b.add_self_contact(ids, law, thickness=t)
    return Consignment(
        build=build,
        packaging=ids,
        top=ids[pm.top],
        bottom=np.setdiff1d(ids[pm.bottom], glue),
        border=ids[pm.border],
        edge=ids[edge_local],
        content_body=body,
        content_nodes=content_nodes,
        packaging_mass=packaging_mass,
        content_mass=content_mass,
        contact_radius=t / 2,
        content_box=(lc, wc, hc),
        glue=glue,
        top_quads=ids[quads[pm.top_quads]],
    )


@dataclass(frozen=True)
class _PackagingMesh:
    """The flat packaging's shells before the glued strip: points (n, 3) [m], quads (q, 4),
    and node ids (into ``points``) by role."""

    points: np.ndarray
    quads: np.ndarray
    bottom_layer: np.ndarray
    """Every node of the bottom layer (the glue stripe is chosen among them)."""
    bottom: np.ndarray
    """Bottom-layer nodes off the border and folds (pulled down by the opening)."""
    top: np.ndarray
    """Top-layer nodes off the border and folds (pulled up by the opening)."""
    border: np.ndarray
    """Nodes where the layers are joined: the envelope's border, the gusseted bag's seams."""
    edge: np.ndarray
    """The +x border's nodes, ordered by y."""
    top_quads: np.ndarray
    """Rows of ``quads`` that belong to the top layer."""


def _packaging_mesh(build: ConsignmentBuild) -> _PackagingMesh:
    """The flat packaging of ``build`` by its construction (``spec.construction``)."""
    length, width = build.flat_size
    h = build.element_size
    if build.spec.construction == "gusseted":
        pts, quads, roles = gusseted_envelope(length, width, build.gusset_depth, GUSSET_SPACING, h)
        return _PackagingMesh(pts, quads, roles["bottom_layer"], roles["bottom"],
                              roles["top"], roles["seam"], roles["edge"],
                              roles["top_quads"])  # fmt: skip
    pts, quads, bottom_ids, top_ids = two_layer_envelope(length, width, INITIAL_GAP, h)
    nx = max(2, round(length / h))
    ny = max(2, round(width / h))
    i, j = bottom_ids % (nx + 1), bottom_ids // (nx + 1)
    on_border = (i == 0) | (i == nx) | (j == 0) | (j == ny)
    return _PackagingMesh(
        points=pts,
        quads=quads,
        bottom_layer=bottom_ids,
        bottom=bottom_ids[~on_border],
        top=top_ids,
        border=bottom_ids[on_border],
        edge=bottom_ids[i == nx],
        top_quads=np.nonzero(np.isin(quads, top_ids).any(axis=1))[0],
    )


def add_air_drag(b: ModelBuilder, c: Consignment, drag_coefficient: float) -> None:
    """Quadratic air drag (:class:`flexparcel.elements.air.AirDrag`) on consignment ``c``.

    The flat envelope moves through the air as one plate: the drag acts on its top layer
    alone, with the plate's ``drag_coefficient`` C_d (a flat plate normal to the flow:
    1.17); on both layers it would count the plate twice. The glued strip is left out."""
    from flexparcel.elements.air import AirDrag
    from flexparcel.model.mesh import quads_to_triangles

    tri, weights = quads_to_triangles(c.top_quads)
    b.add_element_group(AirDrag(tri, weights, drag_coefficient=drag_coefficient))


def add_ground_contact(b: ModelBuilder, c: Consignment, plane: int, law: ContactLaw) -> None:
    """Contact of consignment ``c`` with ground plane ``plane`` (a belt, a plate) by ``law``:
    its packaging nodes with its contact radius (half the packaging thickness), and its
    content as a backstop with the same law.

    The backstop: a flexible content's nodes with half the packaging thickness (its
    face-inner nodes meet the film's nodes but not its faces, see :func:`add_consignment`,
    and bulge through the film between them: PB's content went 0.84 mm below the belt in a
    2 s conveyor run without it), a rigid content's rounded box by its corners, the lowest
    points of a box over a plane (its rounded edges pass between the film's nodes too:
    KP/BW's box went 2.08 mm below the belt while tilted against a deflector). A content
    resting on its packaging stays clear of it."""
    b.add_contact(c.packaging, plane, law, radius=c.contact_radius)
    if c.content_body is None:
        b.add_contact(c.content_nodes, plane, law, radius=c.contact_radius)
    else:
        b.add_contact(c.content_body, plane, law)


def _block_face_count(points: np.ndarray) -> np.ndarray:
    """On how many of its six faces (0 to 3) each point (n, 3) of a block of
    :func:`_hex_block` lies: 3 at corners, 2 on edges, 1 on faces, 0 inside."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    tol = 1e-9 * float(np.max(hi - lo))
    return ((points <= lo + tol) | (points >= hi - tol)).sum(axis=1)


def _block_edges(points: np.ndarray) -> np.ndarray:
    """Mask (n,) of the points of a block of :func:`_hex_block` on its edges and corners."""
    return _block_face_count(points) >= 2


def _round_block(points: np.ndarray, radius: float) -> np.ndarray:
    """Points (n, 3) of a block of :func:`_hex_block` with its edges rounded by ``radius``
    [m]: each point outside the rounded box moves onto it along the line from the nearest point
    of the inner box (shrunk by ``radius``), so edge nodes go onto the edge's quarter
    cylinder, corners onto the corner's sphere octant, and face and interior nodes stay."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    if not 0.0 <= radius <= float(np.min(half)) * (1.0 + 1e-9):
        raise ValueError(f"edge radius must lie in [0, {float(np.min(half))}] m, got {radius}")
    inner = np.maximum(half - radius, 0.0)
    core = np.clip(points, centre - inner, centre + inner)
    d = points - core
    dist = np.linalg.norm(d, axis=1)
    out = dist > radius * (1.0 + 1e-12)
    rounded = points.copy()
    rounded[out] = core[out] + d[out] * (radius / dist[out])[:, None]
    return rounded


def _hex_block(lx: float, ly: float, lz: float, h: float, centre) -> tuple[np.ndarray, np.ndarray]:
    """Points and hex8 cells (VTK order) of a block centred at ``centre``, cells about ``h``
    (at least two through the height so it can bend)."""
    nx, ny = max(1, round(lx / h)), max(1, round(ly / h))
    nz = max(2, round(lz / h))
    xs = np.linspace(-lx / 2, lx / 2, nx + 1) + centre[0]
    ys = np.linspace(-ly / 2, ly / 2, ny + 1) + centre[1]
    zs = np.linspace(-lz / 2, lz / 2, nz + 1) + centre[2]
    z, y, x = np.meshgrid(zs, ys, xs, indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])

    def nid(i, j, k):
        return (k * (ny + 1) + j) * (nx + 1) + i

    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    cells = np.column_stack([
        nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
        nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1),
    ])  # fmt: skip
    return pts, cells.astype(np.int64)
