"""Conveyor scene of the paper's bulk run (section 4.4, Fig. 35): a belt at 1.6 m/s and two
fixed 45 deg deflectors reaching almost to the belt centre line, from alternating sides.

World frame: the belt runs along +x from x = 0 to x = ``belt_length``, its surface is z = 0,
its centre line is y = 0, it spans |y| <= ``belt_width`` / 2. Deflector k starts at the belt
edge (its *root*, at x = ``deflector_x[k]``) and runs downstream at ``deflector_angle_deg`` to
the belt direction until its *tip*, ``centre_gap`` short of the centre line; upstream of the
root the sheet runs on ``deflector_overhang`` (0.25 m) beyond the belt edge, where a real
deflector is fixed to the conveyor's frame. The first deflector comes from the y > 0 side,
the next from y < 0, and so on.

Modelling choices (they differ from the paper, which uses a shell belt on driven rollers):

* the belt is a rigid slab with a prescribed surface velocity (``ModelBuilder.add_plane`` with
  :class:`~flexparcel.contact.planes.PlaneBounds`): its top face is the belt, ``belt_length``
  by ``belt_width``, and its edges are rounded by ``belt_edge_radius`` (10 mm: the belt on
  its slider bed as a 20 mm slab). Packaging beyond a side edge hangs over the rounded edge
  or falls past it, and a consignment carried past x = ``belt_length`` tips over the end and
  falls; the responses (:mod:`flexparcel.scenarios.conveyor_responses`) report when it
  passes the end. The end is a rounded edge moving with the belt, where a real belt turns
  down round its end drum (of a larger radius, its surface moving down): the drag while a
  consignment tips over the end acts along the belt instead of along the drum.
  ``belt_edge_radius = 0`` gives the earlier model, an unbounded plane (packaging beside
  the belt is still carried; nothing falls off).
* each deflector is a fixed rigid body carrying a triangle mesh of its mid-plane, half the
  sheet thickness behind its upstream face (a vertical rectangle); shell nodes touch it with
  a contact thickness of half their own thickness plus half the sheet's, so they meet the
  upstream face. A face contact pushes a node back to the side of the mesh it came from:
  on a mesh at the upstream face itself, a node pressed harder than c h (611 N/mm x 0.1 mm
  = 61 N for packaging of Table 6) crosses the face plane within a step and is then held
  behind the deflector (measured in the paper's scene: KP's kraft rim went through the
  second deflector at 1.45 s and hooked KP onto it); through a 2 mm sheet it takes 670 N.
  A face draped round the tip passes between its nodes, so the tip edge also meets shell
  faces by line contact, and shell element edges edge to edge (:func:`add_deflector_contact`).
  Only *shell nodes* can touch a triangle mesh in flexparcel
  (``add_face_contact``); a rigid box content cannot. For a rigid box use a plane through
  :attr:`DeflectorGeometry.point` with :attr:`DeflectorGeometry.normal`, which is unbounded
  (it goes on past the tip and through the other half of the belt), so it is only right while
  the box is alongside the deflector.
* side guides, when asked for, are unbounded planes at the belt edges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.contact.law import ContactLaw
from flexparcel.contact.planes import PlaneBounds
from flexparcel.model.checks import finite_number
from flexparcel.model.rigid import RoundedBox

__all__ = [
    "BeltTransfer",
    "ConveyorScene",
    "DeflectorGeometry",
    "ConveyorParts",
    "add_conveyor",
    "add_deflector_contact",
]

# Steel density [kg/m^3]: the fixed deflector bodies get a plausible mass (it never matters
# for a fixed body, but a RoundedBox needs one).
_STEEL_DENSITY = 7850.0


def _bad(name: str, allowed: str, value: object) -> ValueError:
    return ValueError(f"ConveyorScene.{name} must be {allowed}, got {value!r}")


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise _bad(name, "a number", value)
    v = float(value)
    if not math.isfinite(v):
        raise _bad(name, "finite", value)
    return v


@dataclass(frozen=True, eq=False)
class DeflectorGeometry:
    """The upstream face of one deflector: a vertical rectangle (SI units).

    The face spans ``root + a * tangent + b * e_z`` for ``-overhang <= a <= length``,
    ``0 <= b <= height``: from the sheet's outer end, ``overhang`` beyond the belt edge, to
    its tip.
    """

    root: np.ndarray
    """Bottom corner at the belt edge [m], shape (3,)."""
    tangent: np.ndarray
    """Unit vector from the root towards the tip, horizontal, shape (3,)."""
    normal: np.ndarray
    """Unit normal of the face, horizontal, pointing to the upstream side (where consignments
    come from), shape (3,)."""
    length: float
    """Length of the face along ``tangent`` [m]."""
    height: float
    """Height of the face [m]."""
    overhang: float = 0.0
    """Length of the sheet beyond the belt edge, upstream of ``root`` [m], >= 0."""

    def __post_init__(self) -> None:
        overhang = finite_number("DeflectorGeometry.overhang", self.overhang)
        if overhang < 0.0:
            raise ValueError(f"DeflectorGeometry.overhang must be >= 0 m, got {overhang:g}")
        object.__setattr__(self, "overhang", overhang)
        for name in ("root", "tangent", "normal"):
            v = np.array(getattr(self, name), dtype=float)  # a private, read-only copy
            v.flags.writeable = False
            object.__setattr__(self, name, v)

    @property
    def point(self) -> np.ndarray:
        """A point on the face [m], shape (3,) (the root)."""
        return self.root

    @property
    def outer_end(self) -> np.ndarray:
        """Bottom corner at the sheet's outer end, ``overhang`` beyond the belt edge [m],
        shape (3,)."""
        return self.root - self.overhang * self.tangent

    @property
    def tip(self) -> np.ndarray:
        """Bottom corner near the belt centre line [m], shape (3,)."""
        return self.root + self.length * self.tangent

    def face_coordinates(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Coordinates [m] of ``points`` [m], shape (..., 3), in the face's frame: along the
        tangent from the root, height above the root, and signed distance from the face plane
        (> 0 on the upstream side); each shape (...)."""
        d = np.asarray(points, dtype=float) - self.root
        return d @ self.tangent, d[..., 2], d @ self.normal

    def over_face(self, points: np.ndarray, below: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance [m] of ``points`` [m], shape (..., 3), from the face plane (> 0 on
        the upstream side), and whether each projects onto the face rectangle, taken
        ``below`` [m] further down than its bottom edge; each shape (...)."""
        a, z, off = self.face_coordinates(points)
        on = (a >= -self.overhang) & (a <= self.length) & (z >= -below) & (z <= self.height)
        return off, on

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance [m] from ``points`` [m], shape (..., 3), to the face rectangle (not the
        unbounded plane), shape (...)."""
        a, b, off = self.face_coordinates(points)
        # tangent, e_z and normal are orthonormal: the offsets from the rectangle add in squares
        da = a - np.clip(a, -self.overhang, self.length)
        db = b - np.clip(b, 0.0, self.height)
        return np.sqrt(da * da + db * db + off * off)

    def to_dict(self) -> dict:
        """JSON-ready copy (lists of floats)."""
        return {
            "root": self.root.tolist(),
            "tip": self.tip.tolist(),
            "tangent": self.tangent.tolist(),
            "normal": self.normal.tolist(),
            "length": float(self.length),
            "height": float(self.height),
            "overhang": float(self.overhang),
        }


@dataclass(frozen=True)
class BeltTransfer:
    """A second belt after the first (a transfer between two conveyors): it starts ``gap``
    [m] in [0, 0.5] after the first belt's end, runs ``length`` [m] in (0, 50] at ``speed``
    [m/s] in [0, 10] along +x, with the first belt's width, surface height and edge radius.
    A consignment bridges the gap or tips into it, and is dragged by both belts while it
    lies on both."""

    gap: float = 0.02
    length: float = 1.0
    speed: float = 1.6

    def __post_init__(self) -> None:
        ranges = {
            "gap": ("in [0, 0.5] m", lambda v: 0.0 <= v <= 0.5),
            "length": ("in (0, 50] m", lambda v: 0.0 < v <= 50.0),
            "speed": ("in [0, 10] m/s", lambda v: 0.0 <= v <= 10.0),
        }
        for name, (allowed, ok) in ranges.items():
            v = _number(f"transfer.{name}", getattr(self, name))
            if not ok(v):
                raise _bad(f"transfer.{name}", allowed, v)
            object.__setattr__(self, name, v)


@dataclass(frozen=True)
class ConveyorScene:
    """Belt and deflectors (SI units; angles in degrees), validated on creation.

    Attributes:
        belt_length: [m] in (0, 50]; consignments exit at x = belt_length.
        belt_width: [m] in (0, 5].
        belt_speed: surface speed along +x [m/s] in [0, 10] (paper: 1.6).
        deflector_angle_deg: angle between each deflector and the belt direction [deg] in
            [10, 90] (paper: 45); below 10 deg the deflectors get impractically long.
        deflector_x: x of each deflector's root at the belt edge [m], increasing, each >= 0,
            each tip at most at x = belt_length. Our choice; the paper gives no positions.
        centre_gap: distance of each tip from the belt centre line [m] in [0, belt_width / 2).
        deflector_height: [m] in (0, 1].
        deflector_thickness: steel sheet thickness [m] in (0, 0.05]: the face mesh lies
            half of it behind the upstream face (see the module docstring).
        deflector_overhang: length of each sheet beyond the belt edge [m] in [0, 1], where
            it would be fixed to the conveyor's frame. Our choice (the paper's deflectors
            are "fixed in space"): with the sheet ending at the belt edge, packaging hanging
            over the edge goes round its free end (measured in the paper's scene, KP at the
            second deflector), which a real deflector fixed to the frame does not allow.
            The default 0.25 m puts the free end 0.177 m beyond the belt edge (at 45 deg),
            out of reach of packaging that still rests on the belt: a consignment more than
            half its length (at most 160 mm, Table 2) beyond the edge falls off. With 0.1 m
            (0.071 m) PB's film wrapped the free end in the paper's scene and jammed at
            1.074 s (docs/scenarios.md).
        side_guides: add unbounded guide planes along both belt edges.
        belt_edge_radius: [m] in [0, 0.05]: the belt is a slab of the belt's length and
            width with its edges rounded by this radius (half the slab's thickness; module
            docstring); 0: an unbounded plane, which carries packaging beside the belt and
            lets nothing fall off its end (for comparison with the earlier model).
        transfer: a second belt after this one (:class:`BeltTransfer`), or None; needs a
            bounded belt (``belt_edge_radius`` > 0). Consignments exit at the end of the
            last belt (:attr:`exit_x`).
    """

    belt_length: float = 3.0
    belt_width: float = 0.6
    belt_speed: float = 1.6
    deflector_angle_deg: float = 45.0
    deflector_x: tuple[float, ...] = (0.8, 1.7)
    centre_gap: float = 0.03
    deflector_height: float = 0.1
    deflector_thickness: float = 0.002
    deflector_overhang: float = 0.25
    side_guides: bool = False
    belt_edge_radius: float = 0.01
    transfer: BeltTransfer | None = None

    def __post_init__(self) -> None:
        ranges = {
            "belt_length": ("in (0, 50] m", lambda v: 0.0 < v <= 50.0),
            "belt_width": ("in (0, 5] m", lambda v: 0.0 < v <= 5.0),
            "belt_speed": ("in [0, 10] m/s", lambda v: 0.0 <= v <= 10.0),
            "deflector_angle_deg": ("in [10, 90] deg", lambda v: 10.0 <= v <= 90.0),
            "deflector_height": ("in (0, 1] m", lambda v: 0.0 < v <= 1.0),
            "deflector_thickness": ("in (0, 0.05] m", lambda v: 0.0 < v <= 0.05),
            "deflector_overhang": ("in [0, 1] m", lambda v: 0.0 <= v <= 1.0),
            "belt_edge_radius": ("in [0, 0.05] m", lambda v: 0.0 <= v <= 0.05),
        }
        for name, (allowed, ok) in ranges.items():
            v = _number(name, getattr(self, name))
            if not ok(v):
                raise _bad(name, allowed, v)
            object.__setattr__(self, name, v)
        half = 0.5 * self.belt_width
        gap = _number("centre_gap", self.centre_gap)
        if not 0.0 <= gap < half:
            raise _bad("centre_gap", f"in [0, belt_width / 2 = {half:g}) m", gap)
        object.__setattr__(self, "centre_gap", gap)
        if not isinstance(self.side_guides, bool):
            raise _bad("side_guides", "True or False", self.side_guides)
        if self.transfer is not None:
            if not isinstance(self.transfer, BeltTransfer):
                raise _bad("transfer", "a BeltTransfer or None", self.transfer)
            if self.belt_edge_radius == 0.0:
                raise _bad("belt_edge_radius", "> 0 m with a transfer (an unbounded belt "
                           "has no end to hand over from)", 0.0)  # fmt: skip
        try:
            xs = tuple(_number("deflector_x", x) for x in self.deflector_x)
        except TypeError:
            raise _bad("deflector_x", "a sequence of numbers [m]", self.deflector_x) from None
        reach = self.deflector_reach_x
        for k, x in enumerate(xs):
            if not 0.0 <= x <= self.belt_length - reach:
                raise _bad(
                    f"deflector_x[{k}]",
                    f"in [0, belt_length - {reach:.4g} = {self.belt_length - reach:.4g}] m "
                    "(its tip must stay on the belt)",
                    x,
                )
            if k and not x > xs[k - 1]:
                raise _bad(f"deflector_x[{k}]", f"> deflector_x[{k - 1}] = {xs[k - 1]:g} m", x)
        object.__setattr__(self, "deflector_x", xs)

    def belt_spans(self) -> tuple[tuple[float, float, float], ...]:
        """``(x_start, x_end, speed)`` [m, m, m/s] of each belt, upstream first."""
        spans = [(0.0, self.belt_length, self.belt_speed)]
        t = self.transfer
        if t is not None:
            start = self.belt_length + t.gap
            spans.append((start, start + t.length, t.speed))
        return tuple(spans)

    @property
    def exit_x(self) -> float:
        """Where consignments leave the conveyor [m]: the end of the last belt."""
        return self.belt_spans()[-1][1]

    @property
    def deflector_reach_x(self) -> float:
        """Extent of each deflector along the belt, root to tip [m]."""
        span = 0.5 * self.belt_width - self.centre_gap
        return span / math.tan(math.radians(self.deflector_angle_deg))

    def deflectors(self) -> tuple[DeflectorGeometry, ...]:
        """Geometry of each deflector's upstream face, in ``deflector_x`` order."""
        th = math.radians(self.deflector_angle_deg)
        span = 0.5 * self.belt_width - self.centre_gap
        out = []
        for k, x in enumerate(self.deflector_x):
            side = 1.0 if k % 2 == 0 else -1.0  # y > 0 first, then alternate
            # runs downstream (+x) and towards the centre line (-side in y)
            tangent = np.array([math.cos(th), -side * math.sin(th), 0.0])
            # of the two horizontal normals, the one with a negative x component faces the
            # oncoming consignments
            normal = np.array([-math.sin(th), -side * math.cos(th), 0.0])
            out.append(
                DeflectorGeometry(
                    root=np.array([x, side * 0.5 * self.belt_width, 0.0]),
                    tangent=tangent,
                    normal=normal,
                    length=span / math.sin(th),
                    height=self.deflector_height,
                    overhang=self.deflector_overhang,
                )
            )
        return tuple(out)


@dataclass(frozen=True, eq=False)
class ConveyorParts:
    """What :func:`add_conveyor` added to a builder."""

    scene: ConveyorScene
    belt_plane: int
    """Plane id of the belt (for ``add_contact`` / ``add_edge_contact``)."""
    deflector_bodies: tuple[int, ...]
    """Node id of each deflector's fixed rigid body. Its RoundedBox is axis-aligned and only
    carries the mesh: never use it in ``add_body_contact``."""
    deflector_vertices: tuple[np.ndarray, ...]
    """Node ids of each deflector's mid-plane mesh vertices (``face_node_ids`` of
    ``add_face_contact``, with :meth:`deflector_contact_thickness`), shape (v,) each."""
    deflectors: tuple[DeflectorGeometry, ...]
    deflector_tips: tuple[np.ndarray, ...]
    """Node ids of each deflector mesh's tip edge, the vertical edge near the belt's centre
    line, bottom to top (its segments, see :data:`TIP_SEGMENT_LENGTH`), shape (m + 1,) each."""
    deflector_ends: tuple[np.ndarray, ...]
    """Node ids of each deflector mesh's outer end edge, the vertical edge ``overhang``
    beyond the belt edge, bottom to top, shape (m + 1,) each."""
    side_guide_planes: tuple[int, ...] = field(default=())
    """Plane ids of the guides at y = +width/2 and y = -width/2, or () if none."""
    transfer_planes: tuple[int, ...] = field(default=())
    """Plane ids of the belts after the first (:class:`BeltTransfer`), or () if none."""

    @property
    def belt_planes(self) -> tuple[int, ...]:
        """Plane ids of every belt, upstream first (give each its contact pairs)."""
        return (self.belt_plane, *self.transfer_planes)

    def deflector_contact_thickness(self, shell_half_thickness: float) -> float:
        """Contact thickness [m] of shell nodes of half thickness ``shell_half_thickness``
        [m] against the deflector meshes: that plus half the sheet thickness."""
        return float(shell_half_thickness) + 0.5 * self.scene.deflector_thickness


TIP_SEGMENT_LENGTH = 25e-3
"""Length [m] of the segments a deflector's tip edge is cut into (the face mesh's rows): the
paper's conveyor mesh size. Each segment's stations together carry the contact law once
(:meth:`~flexparcel.builder.ModelBuilder.add_edge_face_contact`), so the tip holds a
face as firmly per length as packaging nodes 25 mm apart hold on the face."""

TIP_STATION_SPACING = 5e-3
"""Spacing [m] of the contact stations along a deflector's tip edge, a fifth of a segment:
a packaging face draped over the tip meets several of them."""


def _face_mesh(
    g: DeflectorGeometry,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Vertices ((n + 1) (m + 1), 3) [m] and triangles (2 n m, 3) of n columns by m rows of
    cells over the face, counter-clockwise seen from the upstream side, and the vertex
    indices (m + 1,) of the tip edge and of the outer end edge, bottom to top. Face contact
    takes the closest point on a triangle, so a flat face needs few columns (cells about as
    long as the face is high); the rows, about :data:`TIP_SEGMENT_LENGTH` high, cut the
    edges into segments."""
    n = max(1, math.ceil((g.overhang + g.length) / g.height))
    m = max(1, math.ceil(g.height / TIP_SEGMENT_LENGTH - 1e-9))
    a = np.linspace(-g.overhang, g.length, n + 1)
    z = np.linspace(0.0, g.height, m + 1)
    # vertex (row j, column i) is j (n + 1) + i: row 0 at the belt, column n at the tip
    pts = g.root + a[None, :, None] * g.tangent + z[:, None, None] * np.array([0.0, 0.0, 1.0])
    pts = pts.reshape(-1, 3)
    j, i = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
    v0 = (j * (n + 1) + i).ravel()
    quads = np.column_stack([v0, v0 + 1, v0 + n + 2, v0 + n + 1])
    tris = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    # orient the triangles so that their right-hand normal is the upstream normal
    p = pts[tris[0]]
    if np.cross(p[1] - p[0], p[2] - p[0]) @ g.normal < 0.0:
        tris = tris[:, [0, 2, 1]]
    tip = np.arange(m + 1) * (n + 1) + n
    return pts, tris.astype(np.int64), tip, tip - n


def add_conveyor(builder: ModelBuilder, scene: ConveyorScene | None = None) -> ConveyorParts:
    """Add the belt, the deflectors and (optionally) the side guides of ``scene`` (default
    :class:`ConveyorScene`) to ``builder``; returns their ids and geometry.

    Contact pairs are left to the caller, who knows the consignments and their laws:
    ``builder.add_contact(nodes, plane, law, radius=t / 2)`` for each of
    ``parts.belt_planes``,
    ``add_deflector_contact(builder, parts, nodes, law, shell_half_thickness=t / 2)`` for a
    shell mesh (thickness t) against the deflectors (their faces and tip edges).
    """
    scene = scene if scene is not None else ConveyorScene()
    if not isinstance(scene, ConveyorScene):
        raise TypeError(f"add_conveyor: scene must be a ConveyorScene, got {type(scene)}")
    belts = []
    for x0, x1, speed in scene.belt_spans():
        bounds = None
        if scene.belt_edge_radius > 0.0:
            bounds = PlaneBounds((1.0, 0.0, 0.0), x1 - x0, scene.belt_width,
                                 scene.belt_edge_radius)  # fmt: skip
        belts.append(builder.add_plane((0.5 * (x0 + x1), 0.0, 0.0), (0.0, 0.0, 1.0),
                                       (speed, 0.0, 0.0), bounds=bounds))  # fmt: skip
    bodies, vertices, tips, ends = [], [], [], []
    geometry = scene.deflectors()
    for g in geometry:
        pts, tris, tip, end = _face_mesh(g)
        t, h = scene.deflector_thickness, g.height
        pts = pts - 0.5 * t * g.normal  # the sheet's mid-plane
        centre = g.root + 0.5 * (g.length - g.overhang) * g.tangent + np.array([0, 0, 0.5 * h])
        # a sheet-thick column at the face centre with the sheet's mass: a RoundedBox cannot be
        # turned to the deflector angle at build time, and a fixed body's shape only matters
        # for body contact, which the deflector does not use
        shape = RoundedBox(t, t, h, mass=_STEEL_DENSITY * (g.overhang + g.length) * t * h)
        body = builder.add_rigid_body(shape, tuple(centre), motion="fixed")
        bodies.append(body)
        vertices.append(builder.add_rigid_mesh(pts, tris, body))
        tips.append(vertices[-1][tip])
        ends.append(vertices[-1][end])
    guides: tuple[int, ...] = ()
    if scene.side_guides:
        half = 0.5 * scene.belt_width
        guides = (
            builder.add_plane((0.0, half, 0.0), (0.0, -1.0, 0.0)),
            builder.add_plane((0.0, -half, 0.0), (0.0, 1.0, 0.0)),
        )
    return ConveyorParts(
        scene=scene,
        belt_plane=belts[0],
        transfer_planes=tuple(belts[1:]),
        deflector_bodies=tuple(bodies),
        deflector_vertices=tuple(vertices),
        deflectors=geometry,
        deflector_tips=tuple(tips),
        deflector_ends=tuple(ends),
        side_guide_planes=guides,
    )


def add_deflector_contact(
    builder: ModelBuilder,
    parts: ConveyorParts,
    node_ids: np.ndarray,
    law: ContactLaw,
    *,
    shell_half_thickness: float,
) -> None:
    """Contact of a shell mesh (``node_ids``: its nodes, e.g. a packaging; half thickness
    ``shell_half_thickness`` [m]) with every deflector of ``parts`` by ``law``: its nodes
    against each deflector's mid-plane mesh (:meth:`ConveyorParts.deflector_contact_thickness`),
    and each deflector's two free vertical edges (the tip, and the outer end beyond the belt
    edge) against its faces (line contact, the same thickness: the sheet's end rounded by
    half its thickness; stations every :data:`TIP_STATION_SPACING`, each segment of
    :data:`TIP_SEGMENT_LENGTH` carrying the law once), and those edges' segments against the
    shell's element edges (edge-to-edge, the same thickness, the law once per crossing pair,
    the stick model where ``law`` has one: :mod:`flexparcel.contact.edge_edge`). Node-to-face
    contact alone lets a face pressed on the tip pass through it between its nodes, and the
    tip's stations
    let an element edge wrapped round the tip pass between them (in 2 s runs of the paper
    scene without them, packaging edges came up to 1.2 mm inside the contact thickness
    there); in one such run a film hanging over the belt edge at the second deflector's root
    wrapped the sheet's outer end, and an element cut through the sheet there. All these
    contacts are monitored (:meth:`ModelBuilder.monitored_contacts`): a run records the
    deflectors' impulse on every node of the mesh."""
    thick = parts.deflector_contact_thickness(shell_half_thickness)
    for verts, tip, end, g in zip(
        parts.deflector_vertices,
        parts.deflector_tips,
        parts.deflector_ends,
        parts.deflectors,
        strict=True,
    ):
        # monitored: the run records the deflectors' impulse on the consignment's nodes
        with builder.monitored_contacts():
            builder.add_face_contact(node_ids, verts, law, thickness=thick)
            segment = g.height / (len(tip) - 1)
            samples = max(1, math.ceil(segment / TIP_STATION_SPACING - 1e-9))
            for edge in (tip, end):
                builder.add_edge_face_contact(edge, node_ids, law, thickness=thick,
                                              samples=samples)  # fmt: skip
                builder.add_edge_edge_contact(edge, node_ids, law, thickness=thick)
