"""Tributary areas and lengths of contact points: the per-point factors of the per-area
contact law (:mod:`flexparcel.contact.law`).

The law's c, d and k_t are per unit area of the slave surface; each contact point carries the
area of the surface it stands for, computed once from the reference (undeformed) geometry:

* a node: its median-dual share of every surface polygon around it, i.e. a third of each
  triangle and, for a quad, the area of the quadrilateral (corner, mid-edge, centroid,
  mid-edge), a quarter of a parallelogram. On a regular quad mesh of spacing h an interior node
  gets h**2, a node on the mesh's edge h**2 / 2 and a corner node h**2 / 4; over the mesh the
  areas add up to the surface's area, whatever the mesh;
* a station of line contact: the length of its edge divided by the stations on it, times the
  strip width of the set (per unit length law times length).
"""

from __future__ import annotations

import numpy as np

__all__ = ["corner_areas", "node_areas", "edge_lengths", "station_areas"]


def corner_areas(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Median-dual area [m**2] of each corner of each polygon, shape (m, k), for ``cells``
    (m, 3) triangles or (m, 4) quads of node ids into ``points`` (n, 3) [m].

    Triangle: a third of its area per corner (exact median dual). Quad: corner i gets the
    quadrilateral (x_i, midpoint of edge i, centroid, midpoint of edge i - 1), whose area is
    half the norm of the cross product of its diagonals (exact for a flat quad; a warped quad is
    measured on its mean plane); the four add up to the quad's area.
    """
    p = np.asarray(points, dtype=float)
    c = np.asarray(cells, dtype=np.int64)
    if c.ndim != 2 or c.shape[1] not in (3, 4):
        raise ValueError(f"corner_areas: cells must have shape (m, 3) or (m, 4), got {c.shape}")
    x = p[c]  # (m, k, 3)
    if c.shape[1] == 3:
        a = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
        return np.repeat(a[:, None] / 3.0, 3, axis=1)
    centre = x.mean(axis=1)  # (m, 3)
    nxt = 0.5 * (x + np.roll(x, -1, axis=1))  # midpoint of edge i (i, i + 1)
    prv = 0.5 * (x + np.roll(x, 1, axis=1))  # midpoint of edge i - 1 (i - 1, i)
    d1 = centre[:, None, :] - x
    d2 = prv - nxt
    return 0.5 * np.linalg.norm(np.cross(d1, d2), axis=2)


def node_areas(points: np.ndarray, faces: list[np.ndarray], node_count: int) -> np.ndarray:
    """Tributary area [m**2] of every node, shape (node_count,): the sum of its
    :func:`corner_areas` over the polygons ``faces`` (a list of (m, 3) and (m, 4) arrays);
    zero for a node on no face."""
    out = np.zeros(node_count)
    for f in faces:
        f = np.asarray(f, dtype=np.int64)
        if f.size:
            np.add.at(out, f.ravel(), corner_areas(points, f).ravel())
    return out


def edge_lengths(points: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Length [m] of each edge (E, 2) of ``points`` (n, 3), shape (E,)."""
    p = np.asarray(points, dtype=float)
    e = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    return np.linalg.norm(p[e[:, 1]] - p[e[:, 0]], axis=1)


def station_areas(points: np.ndarray, edges: np.ndarray, samples: int, width: float) -> np.ndarray:
    """Area [m**2] carried by each of the ``samples`` stations of each edge (E, 2): its
    tributary length (edge length / samples) times the strip ``width`` [m], shape (E,)."""
    return edge_lengths(points, edges) * (float(width) / int(samples))
