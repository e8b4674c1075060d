"""Input checks of shell connectivity: shapes, ids, degenerate, inverted and inconsistently
oriented elements (each refused with the element and its node ids)."""

from __future__ import annotations

import numpy as np

from flexparcel.model.mesh import quads_to_triangles

__all__ = ["shell_cells", "check_orientation"]


def shell_cells(what: str, pts: np.ndarray, quads, triangles):
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
    check_orientation([c for _, c in cells])
    return cells, tri, np.concatenate(w_all)


def check_orientation(cells: list[np.ndarray]) -> None:
    """Within one mesh, an edge shared by two elements must be traversed in opposite directions
    (consistent normals); the same directed edge twice means one of them is inverted. Where
    more sheets meet at an edge (a seam through four plies), as many elements must run along
    it one way as the other."""
    edges, owner = [], []
    for ci, c in enumerate(cells):
        k = c.shape[1]
        for a in range(k):
            edges.append(c[:, [a, (a + 1) % k]])
            owner.append(np.column_stack([np.full(len(c), ci), np.arange(len(c))]))
    e = np.concatenate(edges)
    own = np.concatenate(owner)
    keys, counts = np.unique(e, axis=0, return_counts=True)
    if not np.any(counts > 1):
        return
    undirected, inverse = np.unique(np.sort(keys, axis=1), axis=0, return_inverse=True)
    forward = np.zeros(len(undirected), np.int64)
    np.add.at(forward, inverse.ravel(), np.where(keys[:, 0] < keys[:, 1], counts, 0))
    total = np.zeros(len(undirected), np.int64)
    np.add.at(total, inverse.ravel(), counts)
    bad = (counts > 1) & (2 * forward[inverse.ravel()] != total[inverse.ravel()])
    if np.any(bad):
        a, b = keys[np.argmax(bad)]
        idx = np.flatnonzero((e[:, 0] == a) & (e[:, 1] == b))
        first, second = (cells[own[i, 0]][own[i, 1]].tolist() for i in idx[:2])
        raise ValueError(
            f"add_shell_mesh: elements {first} and {second} run "
            f"along edge ({a}, {b}) in the same direction: one of them is inverted (normals "
            "must be consistently oriented)"
        )
