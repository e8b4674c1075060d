"""The shape of an assembled consignment, checked against what it must be (paper Table 2).

An assembly can come to rest in a wrong shape: at 15 mm, KP/BW once settled into a
267 x 200 x 62 mm balloon round its 20 mm box, its bottom film 13.8 mm below the box, and a
rest check on kinetic energy alone passed it. :func:`check_shape` measures, at the end of
every assembly:

- the outer length, width and height (packaging nodes' extent plus the film thickness),
  against Table 2 within one element (the mesh cannot place a fold or a seam finer than
  that). Where the construction's flat packaging is itself longer or wider than Table 2
  (a two-layer envelope must be at least content + content height long to hold its content,
  :attr:`~flexparcel.consignments.build.ConsignmentBuild.flat_size`), the bound is the flat
  size instead and the deviation from Table 2 is reported as the construction's;
- the gap between the film and the content's top and bottom faces, on a grid of points over
  those faces (a rigid box: its faces inset by the edge rounding; a flexible content: its
  nodes that have no content node above, or below, them): the film must lie on its content,
  so the largest gap must stay below :data:`GAP_BOUND_ELEMENTS` element sizes;
- content nodes outside the closed film (:func:`content_outside_packaging`), each by how far
  (its distance to the nearest film triangle beyond the film's half thickness): none may lie
  farther out than :data:`OUTSIDE_BOUND` (a node between two film nodes can bulge through the
  film's flat facets by a fraction of a mm without the content being out);
- for a rigid content, whose one node is its centre, its surface too
  (:func:`content_surface_outside`): points over the whole rounded box, each outside the
  film by how far; none may lie farther out than the chord a film facet cuts over the box's
  rounded edge (:func:`surface_chord_bound`), which the mesh cannot resolve, so a box that
  slid or poked out of its packaging fails while a 25 mm film over a 3 mm rounding passes.

:class:`ShapeCheck` holds the figures; its :meth:`~ShapeCheck.failures` are what makes the
assembly fail.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flexparcel.contact.geometry import point_triangle
from flexparcel.model.mesh import surface_triangles

__all__ = [
    "GAP_BOUND_ELEMENTS",
    "OUTSIDE_BOUND",
    "ShapeCheck",
    "check_shape",
    "content_outside_packaging",
    "content_surface_outside",
    "film_gaps",
    "surface_chord_bound",
]

GAP_BOUND_ELEMENTS = 0.5
"""Largest film-content gap over the content's top and bottom faces, in element sizes. A film
pressed on its content by its own prestress follows the face to within the sag of one
element between its nodes; half an element allows a wrinkle, not a balloon (the 15 mm
balloon had 13.8 mm, 0.92 elements)."""
OUTSIDE_BOUND = 1.0e-3
"""How far [m] beyond the film's surface a content node may lie before the content counts
as out of its packaging."""
_CHUNK = 256  # points per ray batch: (points x triangles) arrays stay below ~50 MB


def _ray_hits(points: np.ndarray, tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which triangles (t, 3, 3) [m] the vertical line through each point (n, 3) [m] crosses,
    (n, t) bool, and the height of each crossing [m] (n, t): the ray-triangle test of Moeller
    & Trumbore (J. Graphics Tools 2, 1997), which for a vertical ray reduces to 2D
    barycentric coordinates of the point in the triangle's top view."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = (b - a)[:, :2], (c - a)[:, :2]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]  # top-view area x 2
    ok = np.abs(det) > 1e-18
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    d = points[:, None, :2] - a[None, :, :2]  # (n, t, 2)
    u = (d[..., 0] * e2[:, 1] - d[..., 1] * e2[:, 0]) * inv
    v = (e1[:, 0] * d[..., 1] - e1[:, 1] * d[..., 0]) * inv
    z = a[:, 2] + u * (b[:, 2] - a[:, 2]) + v * (c[:, 2] - a[:, 2])
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1), z


def _film_triangles(model, c, positions: np.ndarray) -> np.ndarray:
    """The closed film's triangles (t, 3, 3) [m] at ``positions``."""
    film = np.zeros(model.node_count, bool)
    film[c.packaging] = True
    return positions[surface_triangles(model.cells, film)]


def _outside_closed_film(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Which points (n, 3) [m] lie outside the closed surface ``tri`` (t, 3, 3) [m], (n,)
    bool: a ray from a point inside crosses it an odd number of times (Jordan curve
    theorem); outside only when the rays up and down both say so, which keeps a ray through
    a film edge (counted twice) from misjudging it."""
    # a nudge off the mesh's regular lines, so rays do not pass exactly through film nodes
    p = points + np.array([1.1e-7, 1.3e-7, 0.0])
    out = np.zeros(p.shape[0], bool)
    for s in range(0, p.shape[0], _CHUNK):
        hit, z = _ray_hits(p[s : s + _CHUNK], tri)
        up = (hit & (z > p[s : s + _CHUNK, None, 2])).sum(axis=1)
        down = (hit & (z < p[s : s + _CHUNK, None, 2])).sum(axis=1)
        out[s : s + _CHUNK] = (up % 2 == 0) & (down % 2 == 0)
    return out


def content_outside_packaging(model, c, positions: np.ndarray) -> np.ndarray:
    """Ids of ``c``'s content nodes that lie outside its closed packaging at ``positions``
    (node_count, 3) [m], by ray parity (:func:`_outside_closed_film`). Meaningful once the
    packaging is closed round its content (after the assembly), not for the flat packaging
    before its opening. For a rigid content the node is its centre of mass (its surface:
    :func:`content_surface_outside`)."""
    tri = _film_triangles(model, c, positions)
    out = _outside_closed_film(positions[c.content_nodes], tri)
    return c.content_nodes[out]


@nb.njit(cache=True)
def _nearest_distance(points, tri):  # pragma: no cover - numba
    """Distance [m] of each point (n, 3) to the nearest triangle (t, 3, 3)."""
    out = np.full(points.shape[0], np.inf)
    for i in range(points.shape[0]):
        for k in range(tri.shape[0]):
            d = abs(point_triangle(points[i], tri[k, 0], tri[k, 1], tri[k, 2])[0])
            if d < out[i]:
                out[i] = d
    return out


def _face_points(c, positions: np.ndarray, rotations: np.ndarray) -> tuple[np.ndarray, ...]:
    """Points [m] on the content's top (k, 3) and bottom (m, 3) faces: a rigid box's faces on
    a grid of half an element, inset by the edge rounding; a flexible content's nodes that
    have no content node above (below) them within half an element in the top view."""
    h = c.build.element_size
    if c.content_body is not None:
        from flexparcel.consignments.build import CONTENT_EDGE_RADIUS

        half = np.asarray(c.content_box) / 2
        inset = half[:2] - CONTENT_EDGE_RADIUS
        gx = np.linspace(-inset[0], inset[0], max(2, int(2 * inset[0] / (0.5 * h)) + 1))
        gy = np.linspace(-inset[1], inset[1], max(2, int(2 * inset[1] / (0.5 * h)) + 1))
        xy = np.array(np.meshgrid(gx, gy)).reshape(2, -1).T
        rot, centre = rotations[c.content_body], positions[c.content_body]
        faces = []
        for sign in (1.0, -1.0):
            local = np.column_stack([xy, np.full(len(xy), sign * half[2])])
            faces.append(centre + local @ rot.T)
        return faces[0], faces[1]
    from scipy.spatial import cKDTree

    p = positions[c.content_nodes]
    pairs = cKDTree(p[:, :2]).query_ball_point(p[:, :2], 0.5 * h)
    top = np.array([p[i, 2] >= p[js, 2].max() for i, js in enumerate(pairs)])
    bottom = np.array([p[i, 2] <= p[js, 2].min() for i, js in enumerate(pairs)])
    return p[top], p[bottom]


def film_gaps(model, c, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Gaps [m] between the film and the content's top and bottom faces (see
    :func:`_face_points`): from each face point to the highest film crossing of the vertical
    line through it (top face) or the lowest (bottom face), minus the film's half thickness.
    Negative where the film's flat facets cut below the face: a facet from a node on the face
    to one past the box's rounded edge makes a chord of up to an element's length; a point
    with no film over (under) it gets +inf."""
    tri = _film_triangles(model, c, positions)
    out = []
    for pts, sign in zip(_face_points(c, positions, rotations), (1.0, -1.0), strict=True):
        pts = pts + np.array([1.1e-7, 1.3e-7, 0.0])
        for s in range(0, pts.shape[0], _CHUNK):
            chunk = pts[s : s + _CHUNK]
            hit, z = _ray_hits(chunk, tri)
            dz = np.where(hit, sign * (z - chunk[:, None, 2]), -np.inf).max(axis=1)
            out.append(np.where(np.isfinite(dz), dz - c.contact_radius, np.inf))
    return np.concatenate(out)


def surface_chord_bound(element_size: float, edge_radius: float) -> float:
    """How far [m] a rounded box edge can reach beyond a film that lies on both its faces.

    A straight facet edge of length ``l`` with its ends on the two faces of a 90-degree edge,
    at ``a`` and ``b`` from it (a^2 + b^2 = l^2), leaves the edge's apex beyond it by
    a b / l; rounding the edge with radius ``r`` takes r (a + b) / l - r off. Both are
    largest at a = b = l / sqrt(2): l / 2 - (sqrt(2) - 1) r. The longest facet edge of a
    quad film is its diagonal, l = sqrt(2) h. (At a box corner, a triangle over three edges
    cuts at most l / sqrt(6), less.) A point deeper than this is not under a chord: the
    content is out of its packaging there."""
    chord = np.sqrt(2.0) * element_size
    return max(0.0, float(chord / 2.0 - (np.sqrt(2.0) - 1.0) * edge_radius))


def _box_surface_points(c, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Points (n, 3) [m] over a rigid content's whole rounded surface, at most half an
    element apart: a grid on each face of the sharp box (edges included) projected onto the
    rounded box as the block builder rounds its lattice (``build._round_block``: a sharp
    edge's grid line lands on the rounding's apex, where a chord cuts deepest)."""
    from flexparcel.consignments.build import CONTENT_EDGE_RADIUS, _round_block

    half = np.asarray(c.content_box) / 2
    n = [max(2, int(np.ceil(2 * v / (0.5 * c.build.element_size))) + 1) for v in half]
    grid = [np.linspace(-v, v, k) for v, k in zip(half, n, strict=True)]
    pts = []
    for ax in range(3):
        o = [a for a in range(3) if a != ax]
        u, v = np.meshgrid(grid[o[0]], grid[o[1]], indexing="ij")
        for sign in (-1.0, 1.0):
            p = np.empty((u.size, 3))
            p[:, o[0]], p[:, o[1]], p[:, ax] = u.ravel(), v.ravel(), sign * half[ax]
            pts.append(p)
    local = _round_block(np.vstack(pts), CONTENT_EDGE_RADIUS)
    rot, centre = rotations[c.content_body], positions[c.content_body]
    return centre + local @ rot.T


def content_surface_outside(model, c, positions: np.ndarray, rotations: np.ndarray) -> dict:
    """A rigid content's surface against its closed film at ``positions`` (node_count, 3)
    [m] and ``rotations`` (node_count, 3, 3): ``points`` sampled over the rounded box
    (:func:`_box_surface_points`), how many lie ``outside`` the film, the ``depth_mm`` of the
    farthest beyond the film's outer face (its distance to the nearest film triangle minus
    the film's half thickness; 0 for none) and the ``bound_mm`` it may reach
    (:func:`surface_chord_bound`). ``None`` for a flexible content, whose nodes are its
    surface and are checked as nodes."""
    if c.content_body is None:
        return None
    from flexparcel.consignments.build import CONTENT_EDGE_RADIUS

    pts = _box_surface_points(c, positions, rotations)
    tri = _film_triangles(model, c, positions)
    out = _outside_closed_film(pts, tri)
    depth = 0.0
    if out.any():
        depth = max(0.0, float((_nearest_distance(pts[out], tri) - c.contact_radius).max()))
    bound = surface_chord_bound(c.build.element_size, CONTENT_EDGE_RADIUS)
    return {"points": int(pts.shape[0]), "outside": int(out.sum()), "depth_mm": depth * 1e3,
            "bound_mm": bound * 1e3}  # fmt: skip


@dataclass(frozen=True)
class ShapeCheck:
    """An assembled consignment's shape against its bounds (lengths in mm)."""

    outer_mm: tuple[float, float, float]
    """Outer length, width, height: the packaging nodes' extent plus the film thickness."""
    table2_mm: tuple[float, float, float]
    """Table 2's (the spec's) length, width, height."""
    bound_mm: tuple[float, float, float]
    """Largest allowed outer size: Table 2 (or the construction's flat size, where larger)
    plus one element."""
    element_size_mm: float
    gap_mm: dict[str, float]
    """Film-content gap over the faces: ``max``, ``p95``, ``median``, ``min`` (negative: the
    film's facets cut below the face, see :func:`film_gaps`), ``uncovered`` (share of face
    points with no film over them)."""
    gap_bound_mm: float
    content_outside: int
    """Content nodes outside the closed film."""
    outside_depth_mm: float
    """How far the farthest of them lies beyond the film's surface (0 for none)."""
    content_surface: dict | None = None
    """A rigid content's surface outside the film (:func:`content_surface_outside`: points,
    outside, depth_mm, bound_mm); ``None`` for a flexible content."""

    def failures(self) -> list[str]:
        """What is out of bounds, each in words with its figure and bound (empty: fine)."""
        out = []
        for name, v, b, t in zip(("length", "width", "height"), self.outer_mm, self.bound_mm,
                                 self.table2_mm, strict=True):  # fmt: skip
            if v > b:
                out.append(f"outer {name} {v:.1f} mm > {b:.1f} mm (Table 2 {t:g} mm + one element)")
        if not self.gap_mm["max"] <= self.gap_bound_mm:
            out.append(f"film-content gap {self.gap_mm['max']:.1f} mm > {self.gap_bound_mm:.1f} "
                       f"mm ({GAP_BOUND_ELEMENTS:g} element): the film does not lie on its "
                       "content")  # fmt: skip
        if self.gap_mm["uncovered"] > 0.0:
            out.append(f"{100 * self.gap_mm['uncovered']:.0f} % of the content's top and "
                       "bottom faces have no film over them")  # fmt: skip
        if self.outside_depth_mm > OUTSIDE_BOUND * 1e3:
            out.append(f"{self.content_outside} content node(s) outside the film, up to "
                       f"{self.outside_depth_mm:.2f} mm > {OUTSIDE_BOUND * 1e3:g} mm")  # fmt: skip
        cs = self.content_surface
        if cs is not None and cs["depth_mm"] > cs["bound_mm"]:
            out.append(f"the content's surface outside the film: {cs['outside']} of "
                       f"{cs['points']} points, up to {cs['depth_mm']:.1f} mm > "
                       f"{cs['bound_mm']:.1f} mm (a facet's chord over the box edge)")  # fmt: skip
        return out

    def table2_deviation_mm(self) -> tuple[float, float, float]:
        """Outer size minus Table 2's, per dimension [mm]."""
        return tuple(v - t for v, t in zip(self.outer_mm, self.table2_mm, strict=True))

    def to_dict(self) -> dict:
        """Plain numbers for ``assembly.json``."""
        return {
            "outer_mm": list(self.outer_mm), "table2_mm": list(self.table2_mm),
            "bound_mm": list(self.bound_mm), "element_size_mm": self.element_size_mm,
            "gap_mm": dict(self.gap_mm), "gap_bound_mm": self.gap_bound_mm,
            "content_outside": self.content_outside,
            "outside_depth_mm": self.outside_depth_mm,
            "content_surface": None if self.content_surface is None
            else dict(self.content_surface),
            "failures": self.failures(),
        }  # fmt: skip


def check_shape(model, c, positions: np.ndarray, rotations: np.ndarray) -> ShapeCheck:
    """Measure the consignment ``c`` of ``model`` at ``positions`` (node_count, 3) [m] and
    ``rotations`` (node_count, 3, 3) against its bounds (module docstring)."""
    spec, build = c.build.spec, c.build
    h_mm = build.element_size * 1e3
    p = positions[c.packaging]
    outer = tuple(float(v) for v in (np.ptp(p, axis=0) + 2.0 * c.contact_radius) * 1e3)
    table2 = (float(spec.length_mm), float(spec.width_mm), float(spec.height_mm))
    from flexparcel.consignments.build import GLUED_STRIP_WIDTH

    strip = GLUED_STRIP_WIDTH if build.has_glued_strip else 0.0
    flat = (build.flat_size[0] + strip) * 1e3, build.flat_size[1] * 1e3, table2[2]
    bound = tuple(max(t, f) + h_mm for t, f in zip(table2, flat, strict=True))
    gaps = film_gaps(model, c, positions, rotations) * 1e3
    covered = gaps[np.isfinite(gaps)]
    gap = {
        "max": float(covered.max()) if covered.size else float("inf"),
        "p95": float(np.percentile(covered, 95)) if covered.size else float("inf"),
        "median": float(np.median(covered)) if covered.size else float("inf"),
        "min": float(covered.min()) if covered.size else float("inf"),
        "uncovered": float(1.0 - covered.size / max(gaps.size, 1)),
    }
    outside = content_outside_packaging(model, c, positions)
    depth = 0.0
    if outside.size:
        d = _nearest_distance(positions[outside], _film_triangles(model, c, positions))
        depth = float(max(0.0, (d - c.contact_radius).max()) * 1e3)
    surface = content_surface_outside(model, c, positions, rotations)
    return ShapeCheck(outer, table2, bound, h_mm, gap, GAP_BOUND_ELEMENTS * h_mm,
                      int(outside.size), depth, surface)  # fmt: skip
