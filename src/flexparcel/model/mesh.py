"""Structured shell meshes and mesh checks.

Meshes are plain arrays: node coordinates ``points`` [m], shape (n, 3), and element connectivity
(quads (m, 4) or triangles (m, 3), int64, counter-clockwise seen from the +normal side).
"""

from __future__ import annotations

import numpy as np

__all__ = ["rectangle", "quads_to_triangles", "surface_triangles", "shell_edges", "triangle_areas"]


def rectangle(
    length: float,
    width: float,
    nx: int,
    ny: int,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """Structured quad mesh of a ``length`` x ``width`` rectangle [m] in the xy-plane.

    Returns ``points`` (``(nx+1)*(ny+1)``, 3) and ``quads`` (``nx*ny``, 4); node ``i + j*(nx+1)``
    sits at ``(i*length/nx, j*width/ny, 0) + origin``. Quads are counter-clockwise about +z.
    """
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"rectangle: length must be > 0 m, got {length!r}")
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"rectangle: width must be > 0 m, got {width!r}")
    if int(nx) != nx or nx < 1 or int(ny) != ny or ny < 1:
        raise ValueError(f"rectangle: nx and ny must be integers >= 1, got nx={nx!r}, ny={ny!r}")
    nx, ny = int(nx), int(ny)
    xs = np.linspace(0.0, length, nx + 1)
    ys = np.linspace(0.0, width, ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    points = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)]) + np.asarray(origin)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    n0 = (i + j * (nx + 1)).ravel()
    quads = np.column_stack([n0, n0 + 1, n0 + nx + 2, n0 + nx + 1]).astype(np.int64)
    return points, quads


def quads_to_triangles(quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split each quad into the four triangles of both diagonals, each weighted 1/2.

    Using both diagonals (instead of one) removes the directional bias of a single split: the
    stiffness and mass of the quad are the average of the two possible two-triangle splits.
    Returns ``triangles`` (4m, 3) and ``weights`` (4m,).
    """
    q = np.asarray(quads, dtype=np.int64)
    tris = np.concatenate(
        [q[:, [0, 1, 2]], q[:, [0, 2, 3]], q[:, [0, 1, 3]], q[:, [1, 2, 3]]], axis=0
    )
    return tris, np.full(len(tris), 0.5)


def surface_triangles(cells, keep: np.ndarray) -> np.ndarray:
    """Triangles (m, 3) of the shell cells whose nodes all have ``keep`` (bool, per node):
    ``cells`` is an iterable of ("quad", (q, 4)) or ("triangle", (t, 3)) pairs (other kinds are
    skipped); each quad is split once, along its 0-2 diagonal, as the contact surfaces are."""
    tris = [np.zeros((0, 3), np.int64)]
    for kind, conn in cells:
        if kind not in ("quad", "triangle"):
            continue
        c = np.asarray(conn, dtype=np.int64)
        c = c[keep[c].all(axis=1)]
        tris += [c[:, [0, 1, 2]], c[:, [0, 2, 3]]] if kind == "quad" else [c]
    return np.vstack(tris)


def shell_edges(cells, keep: np.ndarray) -> np.ndarray:
    """Element edges (E, 2) of the shell cells, each once as (low, high) node ids, in
    lexicographic order, whose two nodes both have ``keep`` (bool, per node). ``cells`` as for
    :func:`surface_triangles` (other kinds than quads and triangles are skipped)."""
    edges = [np.zeros((0, 2), np.int64)]
    for kind, conn in cells:
        if kind not in ("quad", "triangle"):
            continue
        c = np.asarray(conn, dtype=np.int64)
        e = np.sort(np.stack([c, np.roll(c, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
        edges.append(e[keep[e].all(axis=1)])
    return np.unique(np.vstack(edges), axis=0)


def triangle_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Signed-free triangle areas [m^2], shape (m,)."""
    p = np.asarray(points)
    t = np.asarray(triangles)
    n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    return 0.5 * np.linalg.norm(n, axis=1)
