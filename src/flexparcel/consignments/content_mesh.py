"""Solid meshes of a flexible content: a block with rounded edges in hex8, wedge6 and tet4.

A granulate bag or a folded garment is no sharp box: the paper meshes PB's content with
Solid8 elements and Solid6/5/4 where its rounded edges need them (section 3.1.2). The block
here is the Minkowski sum of an inner box (the block shrunk by the edge radius ``r`` on every
side) and a ball of radius ``r``: flat faces, quarter cylinders along the edges, sphere
octants at the corners. It is meshed region by region so that the rounded surface is resolved
with about one element size per segment, at any mesh:

- the inner box: hex8 on a grid of about ``h``;
- each face: the inner box's face grid extruded outwards by ``r`` in ``n_r`` hex8 layers;
- each edge: a quarter disc of ``n_t`` sectors and ``n_r`` rings swept along the edge: the
  sectors next to the edge line are triangles, so wedge6; the outer rings hex8;
- each corner: the sphere octant as a triangulated spherical triangle (``n_t`` segments per
  side) at ``n_r`` radii: tet4 from the corner point to the first radius, wedge6 between radii.
  The spherical grid maps integer barycentric coordinates ``(i, j, k)``, ``i + j + k = n_t``,
  to the direction ``(sin(pi i / 2n), sin(pi j / 2n), sin(pi k / 2n))`` (normalised): on each
  of its three arcs that is the uniform angle of the neighbouring edge's quarter disc, so the
  meshes conform.

Nodes of neighbouring regions are merged by their coordinates. An inner box of zero extent
along an axis (an edge radius of half the block's height, as for PB: a flat core) is allowed:
the regions on either side then share their nodes in that plane.

No pyramid is needed: corners take tets and wedges, edges wedges and hexes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexparcel.elements.solid import centre_shape_gradients

__all__ = ["RoundedBlockMesh", "rounded_block", "rounded_block_volume"]

# the node order that turns each kind inside out (its two triangle or square ends swapped,
# or two tet corners), to orient an element whose Jacobian is negative
_FLIP = {
    "hex8": [4, 5, 6, 7, 0, 1, 2, 3],
    "wedge6": [3, 4, 5, 0, 1, 2],
    "tet4": [0, 2, 1, 3],
}


@dataclass(frozen=True)
class RoundedBlockMesh:
    """A solid mesh of a rounded block: node positions [m] (n, 3), cells per element kind
    (``"hex8"``, ``"wedge6"``, ``"tet4"``: (m, 8), (m, 6), (m, 4) node ids, the element
    module's orientation), and ``rounded`` (n,) bool: the surface nodes on the edges' quarter
    cylinders and the corners' sphere octants, the tangent lines to the faces included."""

    points: np.ndarray
    cells: dict[str, np.ndarray]
    rounded: np.ndarray


def rounded_block_volume(size, radius: float) -> float:
    """Volume [m^3] of a block of outer ``size`` (3,) [m] with edges rounded by ``radius``
    [m]: the inner box ``a b c`` plus its faces extruded by r, its edges' quarter cylinders
    and its corners' eight sphere octants, ``abc + 2r(ab + bc + ca) + pi r^2 (a + b + c) +
    4/3 pi r^3`` (Steiner's formula for a box)."""
    a, b, c = np.asarray(size, float) - 2.0 * radius
    r = float(radius)
    return float(a * b * c + 2 * r * (a * b + b * c + c * a) + np.pi * r * r * (a + b + c)
                 + 4.0 / 3.0 * np.pi * r**3)  # fmt: skip


class _Nodes:
    """Node registry: one id per position, positions matched on a grid of ``quantum`` [m]."""

    def __init__(self, quantum: float):
        self.quantum = quantum
        self.ids: dict[tuple[int, int, int], int] = {}
        self.points: list[np.ndarray] = []

    def __call__(self, p: np.ndarray) -> int:
        key = tuple(int(v) for v in np.rint(p / self.quantum))
        if key not in self.ids:
            self.ids[key] = len(self.points)
            self.points.append(np.array(p, float))
        return self.ids[key]


def _check(size, radius: float, h: float) -> np.ndarray:
    s = np.asarray(size, float)
    if s.shape != (3,) or not np.all(np.isfinite(s) & (s > 0)):
        raise ValueError(f"size must be three lengths > 0 m, got {size!r}")
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"element size must be > 0 m, got {h!r}")
    half = 0.5 * float(s.min())
    if not (np.isfinite(radius) and 0.0 < radius <= half * (1.0 + 1e-9)):
        raise ValueError(f"edge radius must lie in (0, {half}] m, got {radius!r}")
    return s


def rounded_block(size, radius: float, h: float, centre=(0.0, 0.0, 0.0)) -> RoundedBlockMesh:
    """Mesh a block of outer ``size`` (length, width, height) [m] centred at ``centre`` [m],
    its edges and corners rounded by ``radius`` [m] (0 < r <= half the smallest side), with
    elements of about ``h`` [m]: at least one layer through the rounding and two segments per
    quarter circle."""
    s = _check(size, radius, h)
    r = float(radius)
    tol = 1e-9 * float(s.max())
    a = np.maximum(0.5 * s - r, 0.0)
    a[a < tol] = 0.0
    grids = [np.linspace(-ai, ai, max(1, round(2 * ai / h)) + 1) if ai > 0 else np.zeros(1)
             for ai in a]  # fmt: skip
    rho = np.linspace(0.0, r, max(1, round(r / h)) + 1)
    n_t = max(2, round(0.5 * np.pi * r / h))
    c0 = np.asarray(centre, float)
    node = _Nodes(tol)
    cells: dict[str, list] = {"hex8": [], "wedge6": [], "tet4": []}
    _core(grids, c0, node, cells)
    _faces(grids, a, rho, c0, node, cells)
    _edges(grids, a, rho, n_t, c0, node, cells)
    _corners(a, rho, n_t, c0, node, cells)
    points = np.array(node.points)
    out = {k: _oriented(k, points, np.array(v, np.int64).reshape(-1, len(_FLIP[k])))
           for k, v in cells.items() if v}  # fmt: skip
    return RoundedBlockMesh(points, out, _rounded_nodes(points, a, r, c0, tol))


def _hex(ids) -> list[int]:
    """A hex8 from the corner lattice ``ids[i][j][k]`` (2 x 2 x 2)."""
    return [ids[0][0][0], ids[1][0][0], ids[1][1][0], ids[0][1][0],
            ids[0][0][1], ids[1][0][1], ids[1][1][1], ids[0][1][1]]  # fmt: skip


def _core(grids, c0, node, cells) -> None:
    gx, gy, gz = grids
    for i in range(len(gx) - 1):
        for j in range(len(gy) - 1):
            for k in range(len(gz) - 1):
                ids = [[[node(c0 + (gx[i + di], gy[j + dj], gz[k + dk])) for dk in (0, 1)]
                        for dj in (0, 1)] for di in (0, 1)]  # fmt: skip
                cells["hex8"].append(_hex(ids))


def _faces(grids, a, rho, c0, node, cells) -> None:
    """Each face of the inner box extruded outwards by ``rho`` (its layers)."""
    for d in range(3):
        e, f = [x for x in range(3) if x != d]
        ge, gf = grids[e], grids[f]
        for sign in (-1.0, 1.0):

            def p(i, j, k, d=d, e=e, f=f, sign=sign, ge=ge, gf=gf):
                x = np.zeros(3)
                x[d], x[e], x[f] = sign * (a[d] + rho[k]), ge[i], gf[j]
                return node(c0 + x)

            for i in range(len(ge) - 1):
                for j in range(len(gf) - 1):
                    for k in range(len(rho) - 1):
                        ids = [[[p(i + di, j + dj, k + dk) for dk in (0, 1)] for dj in (0, 1)]
                               for di in (0, 1)]  # fmt: skip
                        cells["hex8"].append(_hex(ids))


def _edges(grids, a, rho, n_t, c0, node, cells) -> None:
    """Each edge of the inner box: a quarter disc (rings ``rho``, ``n_t`` sectors) swept
    along it; wedges at the edge line, hexes outside."""
    theta = np.linspace(0.0, 0.5 * np.pi, n_t + 1)
    for d in range(3):
        e, f = [x for x in range(3) if x != d]
        g = grids[d]
        for se in (-1.0, 1.0):
            for sf in (-1.0, 1.0):

                def p(k, m, l, d=d, e=e, f=f, se=se, sf=sf, g=g):
                    x = np.zeros(3)
                    x[d] = g[l]
                    x[e] = se * (a[e] + rho[k] * np.cos(theta[m]))
                    x[f] = sf * (a[f] + rho[k] * np.sin(theta[m]))
                    return node(c0 + x)

                for l in range(len(g) - 1):
                    for m in range(n_t):
                        cells["wedge6"].append([p(0, 0, l), p(1, m, l), p(1, m + 1, l),
                                                p(0, 0, l + 1), p(1, m, l + 1),
                                                p(1, m + 1, l + 1)])  # fmt: skip
                        for k in range(1, len(rho) - 1):
                            ids = [[[p(k + dk, m + dm, l + dl) for dl in (0, 1)]
                                    for dm in (0, 1)] for dk in (0, 1)]  # fmt: skip
                            cells["hex8"].append(_hex(ids))


def _octant_directions(n: int, signs) -> dict[tuple[int, int], np.ndarray]:
    """Unit directions of the octant's spherical grid by (j, k), i = n - j - k."""
    out = {}
    for j in range(n + 1):
        for k in range(n + 1 - j):
            i = n - j - k
            v = np.sin(0.5 * np.pi * np.array([i, j, k]) / n) * signs
            out[(j, k)] = v / np.linalg.norm(v)
    return out


def _corners(a, rho, n_t, c0, node, cells) -> None:
    """Each corner of the inner box: a sphere octant, tets from the corner point to the first
    radius, wedges between radii."""
    for sx in (-1.0, 1.0):
        for sy in (-1.0, 1.0):
            for sz in (-1.0, 1.0):
                signs = np.array([sx, sy, sz])
                corner = c0 + signs * a
                u = _octant_directions(n_t, signs)
                tris = [
                    ((j, k), (j + 1, k), (j, k + 1)) for j in range(n_t) for k in range(n_t - j)
                ]
                tris += [((j + 1, k), (j + 1, k + 1), (j, k + 1))
                         for j in range(n_t - 1) for k in range(n_t - 1 - j)]  # fmt: skip
                apex = node(corner)
                for t in tris:
                    ring = [[node(corner + rq * u[v]) for v in t] for rq in rho[1:]]
                    cells["tet4"].append([apex, *ring[0]])
                    for q in range(len(ring) - 1):
                        cells["wedge6"].append([*ring[q], *ring[q + 1]])


def _oriented(kind: str, points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``cells`` with collapsed cells (a node twice) dropped and each turned so that its
    Jacobian at its centroid, from the element module's own shape functions, is positive."""
    keep = np.array([len(set(c)) == len(c) for c in cells.tolist()], bool)
    cells = cells[keep].copy()
    jac = np.einsum("mki,kj->mij", points[cells], centre_shape_gradients(kind))
    inverted = np.linalg.det(jac) < 0
    cells[inverted] = cells[inverted][:, _FLIP[kind]]
    return cells


def _rounded_nodes(points, a, r, c0, tol) -> np.ndarray:
    """Surface nodes (on the rounded box, distance r from the inner box) on an edge's or a
    corner's rounding: at or beyond the inner box's bounds along two axes or more (an axis
    where the inner box has no extent counts for every node), so the tangent lines where a
    face meets a quarter cylinder are in, and so is the rim of a flat core (PB)."""
    q = points - c0
    core = np.clip(q, -a, a)
    on_surface = np.abs(np.linalg.norm(q - core, axis=1) - r) < 1e3 * tol
    at_bound = np.abs(q) >= a - 1e3 * tol
    return on_surface & (at_bound.sum(axis=1) >= 2)
