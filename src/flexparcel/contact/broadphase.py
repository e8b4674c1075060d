"""Broad phase: candidate (query, target) contact pairs in near-linear time with a uniform grid.

The narrow phase (:mod:`flexparcel.contact.geometry`) is exact but costs one kernel call per pair;
testing every shell node against every face is O(N M). The broad phase returns the pairs that
*can* be within reach, conservatively, by axis-aligned bounding boxes (AABBs):

    pair (i, j) is a candidate  <=>  the cube of half size ``r_i + margin`` around query point i
    overlaps the AABB of target j (closed intervals on all three axes), and query i does not
    share a node with target j (self contact: a node never touches its own faces/edges).

Every pair whose true distance is ``<= r_i + margin`` is therefore reported (the Euclidean
distance is at least the per-axis one); a few farther ones are too, and the narrow phase discards
them. ``margin`` [m] should cover the shell's contact thickness and the motion expected until the
next broad-phase update (e.g. a few steps of the fastest node).

Algorithm (uniform hash grid, Teschner et al., "Optimized spatial hashing for collision
detection of deformable objects", VMV 2003, with sorting instead of hashing): the query points are
binned into cubic cells of size ``h`` over the targets' inflated bounding box (points outside it
cannot touch anything and are dropped); their integer cell keys ``ix + nx (iy + ny iz)`` are sorted
with a radix sort. Each target visits the rows of cells its inflated AABB overlaps: one binary
search per row of cells along x finds the points there, which are then tested
exactly. With ``h`` = mean target AABB extent + 2 (margin + max radius) a target visits O(1) rows
and a cell holds O(1) points, so the cost is O((N + M) log N) for meshes of similar element size.
Very large targets (e.g. a ground plate of two triangles among small ones) visit
(extent/h)^2 rows: pass them to the plane kernels or subdivide them.

Kernels (numba, ``float64`` / ``int64`` arrays) and their Python wrappers with input checks:

* :func:`grid_pairs` -- the core: query points (N, 3) with radii vs target AABBs;
* :func:`point_triangle_candidates` -- points (shell/solid nodes) vs triangles;
* :func:`segment_triangle_candidates` -- segments (shell edges) vs triangles, by the segment's
  bounding sphere (midpoint, half length + radius) -- conservative;
* :func:`segment_segment_candidates` -- segments vs segments (edge-to-edge), same idea;
* :func:`brute_force_pairs` -- the O(N M) reference with the identical criterion (tests, debugging).

Pairs come back as an ``int64`` array (K, 2) ``[query index, target index]``, sorted by query, then
target.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

__all__ = [
    "grid_pairs",
    "brute_force_pairs",
    "triangle_bounds",
    "segment_bounds",
    "point_triangle_candidates",
    "segment_triangle_candidates",
    "segment_segment_candidates",
]

# Cap on the number of grid cells (keys must fit int64 with room to spare).
_MAX_CELLS = 1.0e15


@nb.njit(cache=True)
def triangle_bounds(tris, pos):
    """AABBs of triangles: (lo (M, 3), hi (M, 3)) [m] from node ids ``tris`` (M, 3) into ``pos``
    (n, 3) [m]."""
    m = tris.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    for j in range(m):
        for k in range(3):
            v0 = pos[tris[j, 0], k]
            v1 = pos[tris[j, 1], k]
            v2 = pos[tris[j, 2], k]
            lo[j, k] = min(v0, v1, v2)
            hi[j, k] = max(v0, v1, v2)
    return lo, hi


@nb.njit(cache=True)
def segment_bounds(segs, pos):
    """AABBs of segments: (lo (M, 3), hi (M, 3)) [m] from node ids ``segs`` (M, 2)."""
    m = segs.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    for j in range(m):
        for k in range(3):
            v0 = pos[segs[j, 0], k]
            v1 = pos[segs[j, 1], k]
            lo[j, k] = min(v0, v1)
            hi[j, k] = max(v0, v1)
    return lo, hi


@nb.njit(cache=True)
def _shares_node(qnodes, i, tnodes, j):
    for a in range(qnodes.shape[1]):
        u = qnodes[i, a]
        if u < 0:
            continue
        for b in range(tnodes.shape[1]):
            if tnodes[j, b] == u:
                return True
    return False


@nb.njit(cache=True)
def _overlaps(points, radii, i, lo, hi, j, margin):
    d = radii[i] + margin
    for k in range(3):
        x = points[i, k]
        if x < lo[j, k] - d or x > hi[j, k] + d:
            return False
    return True


@nb.njit(cache=True)
def _grow(pairs, k):
    """A copy of pairs (cap, 2) with twice the capacity (first k rows kept)."""
    grown = np.empty((2 * pairs.shape[0], 2), np.int64)
    for q in range(k):
        grown[q, 0] = pairs[q, 0]
        grown[q, 1] = pairs[q, 1]
    return grown


@nb.njit(cache=True)
def _argsort(keys):
    """Stable argsort of non-negative int64 keys (``-1`` allowed: sorted first) by an LSD radix
    sort with 16-bit digits: O(n) per digit, as many digits as the largest key needs. (Written out
    because numba's ``np.argsort`` takes seconds to compile and is slower on these keys.)"""
    n = keys.shape[0]
    order = np.empty(n, np.int64)
    kmax = 0
    for i in range(n):
        order[i] = i
        if keys[i] > kmax:
            kmax = keys[i]
    if n < 2:
        return order
    buf = np.empty(n, np.int64)
    count = np.empty(65537, np.int64)
    shift = 0
    while True:
        for d in range(65537):
            count[d] = 0
        # digit of key + 1 so that -1 sorts first (it is 0 in every digit)
        for i in range(n):
            count[(((keys[i] + 1) >> shift) & 0xFFFF) + 1] += 1
        for d in range(65536):
            count[d + 1] += count[d]
        for i in range(n):
            v = order[i]
            dgt = ((keys[v] + 1) >> shift) & 0xFFFF
            buf[count[dgt]] = v
            count[dgt] += 1
        order, buf = buf, order
        shift += 16
        if shift >= 63 or ((kmax + 1) >> shift) == 0:
            break
    return order


@nb.njit(cache=True)
def _lower_bound(a, x):
    """First index q with a[q] >= x in the sorted array a (len(a) if none)."""
    lo = 0
    hi = a.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@nb.njit(cache=True)
def _sort_pairs(pairs, k, m):
    if k == 0:
        return np.zeros((0, 2), np.int64)
    key = np.empty(k, np.int64)
    for q in range(k):
        key[q] = pairs[q, 0] * m + pairs[q, 1]
    order = _argsort(key)
    out = np.empty((k, 2), np.int64)
    for q in range(k):
        out[q, 0] = pairs[order[q], 0]
        out[q, 1] = pairs[order[q], 1]
    return out


@nb.njit(cache=True)
def brute_force_pairs(points, radii, qnodes, lo, hi, tnodes, margin):
    """Reference O(N M) candidate pairs with the same criterion as :func:`grid_pairs`."""
    n = points.shape[0]
    m = lo.shape[0]
    pairs = np.empty((16, 2), np.int64)
    k = 0
    for i in range(n):
        for j in range(m):
            if _overlaps(points, radii, i, lo, hi, j, margin) and not _shares_node(
                qnodes, i, tnodes, j
            ):
                if k == pairs.shape[0]:
                    pairs = _grow(pairs, k)
                pairs[k, 0] = i
                pairs[k, 1] = j
                k += 1
    return _sort_pairs(pairs, k, m)


@nb.njit(cache=True)
def grid_pairs(points, radii, qnodes, lo, hi, tnodes, margin, cell_size):
    """Candidate pairs of query points vs target AABBs by a sorted uniform grid.

    Args:
        points: query points [m], (N, 3) float64.
        radii: their radii [m], (N,) float64, >= 0.
        qnodes: node ids of each query (N, kq) int64, ``-1`` padding (e.g. (N, 1) for nodes,
            (N, 2) for segments); a pair sharing any node id is excluded.
        lo, hi: target AABBs [m], (M, 3) each (:func:`triangle_bounds`, :func:`segment_bounds`).
        tnodes: node ids of each target (M, kt) int64.
        margin: extra reach [m] >= 0.
        cell_size: grid cell size [m]; <= 0 picks mean target extent + 2 (margin + max radius).

    Returns:
        pairs (K, 2) int64 ``[query, target]``, sorted (see the module docstring for the exact
        criterion).
    """
    n = points.shape[0]
    m = lo.shape[0]
    if n == 0 or m == 0:
        return np.zeros((0, 2), np.int64)
    rmax = 0.0
    for i in range(n):
        rmax = max(rmax, radii[i])
    reach = rmax + margin
    # Domain: the targets' bounds inflated by the largest reach.
    gmin = np.empty(3)
    gmax = np.empty(3)
    for k in range(3):
        gmin[k] = np.inf
        gmax[k] = -np.inf
    mean_ext = 0.0
    for j in range(m):
        ext = 0.0
        for k in range(3):
            gmin[k] = min(gmin[k], lo[j, k] - reach)
            gmax[k] = max(gmax[k], hi[j, k] + reach)
            ext = max(ext, hi[j, k] - lo[j, k])
        mean_ext += ext
    mean_ext /= m
    h = cell_size
    if not h > 0.0:
        h = mean_ext + 2.0 * reach
    if not h > 0.0:
        # Point targets and no reach: any positive size works (pairs need exact coincidence).
        h = 1.0
        for k in range(3):
            h = max(h, gmax[k] - gmin[k])
    dims = np.empty(3, np.int64)
    while True:
        total = 1.0
        for k in range(3):
            total *= math.floor((gmax[k] - gmin[k]) / h) + 1.0
        if total <= _MAX_CELLS:
            break
        h *= 2.0
    for k in range(3):
        dims[k] = np.int64(math.floor((gmax[k] - gmin[k]) / h)) + 1
    nx = dims[0]
    ny = dims[1]
    # Bin the query points (those outside the domain cannot touch anything).
    keys = np.empty(n, np.int64)
    for i in range(n):
        inside = True
        c = np.empty(3, np.int64)
        for k in range(3):
            x = points[i, k]
            if not (gmin[k] <= x <= gmax[k]):
                inside = False
                break
            ck = np.int64(math.floor((x - gmin[k]) / h))
            c[k] = min(ck, dims[k] - 1)
        if inside:
            keys[i] = c[0] + nx * (c[1] + ny * c[2])
        else:
            keys[i] = -1
    order = _argsort(keys)
    skeys = np.empty(n, np.int64)
    for i in range(n):
        skeys[i] = keys[order[i]]
    if skeys[n - 1] < 0:  # no point inside the domain (outside ones have key -1, sorted first)
        return np.zeros((0, 2), np.int64)
    pairs = np.empty((4 * n + 16, 2), np.int64)
    kk = 0
    c0 = np.empty(3, np.int64)
    c1 = np.empty(3, np.int64)
    for j in range(m):
        for k in range(3):
            a = np.int64(math.floor((lo[j, k] - reach - gmin[k]) / h))
            b = np.int64(math.floor((hi[j, k] + reach - gmin[k]) / h))
            c0[k] = max(a, 0)
            c1[k] = min(b, dims[k] - 1)
        for iz in range(c0[2], c1[2] + 1):
            for iy in range(c0[1], c1[1] + 1):
                row = nx * (iy + ny * iz)
                key0 = c0[0] + row
                key1 = c1[0] + row
                q = _lower_bound(skeys, key0)
                while q < n and skeys[q] <= key1:
                    i = order[q]
                    q += 1
                    if not _overlaps(points, radii, i, lo, hi, j, margin):
                        continue
                    if _shares_node(qnodes, i, tnodes, j):
                        continue
                    if kk == pairs.shape[0]:
                        pairs = _grow(pairs, kk)
                    pairs[kk, 0] = i
                    pairs[kk, 1] = j
                    kk += 1
    return _sort_pairs(pairs, kk, m)


# --------------------------------------------------------------------------------------------------
# Python wrappers
# --------------------------------------------------------------------------------------------------


def _as_points(points, name):
    a = np.ascontiguousarray(points, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {np.shape(points)}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    return a


def _as_ids(ids, width, n_nodes, name):
    a = np.ascontiguousarray(ids, dtype=np.int64)
    if a.ndim != 2 or a.shape[1] != width:
        raise ValueError(f"{name} must have shape (M, {width}), got {np.shape(ids)}")
    if a.size and (a.min() < 0 or a.max() >= n_nodes):
        raise ValueError(f"{name} must hold node ids in [0, {n_nodes}), got {a.min()}..{a.max()}")
    return a


def _as_radii(radii, n, name):
    r = np.asarray(radii, dtype=np.float64)
    r = np.ascontiguousarray(np.broadcast_to(r, (n,)) if r.ndim == 0 else r)
    if r.shape != (n,):
        raise ValueError(f"{name} must be a number or have shape ({n},), got {np.shape(radii)}")
    if not (np.all(np.isfinite(r)) and np.all(r >= 0.0)):
        raise ValueError(f"{name} must be finite and >= 0")
    return r


def _as_margin(margin):
    m = float(margin)
    if not (math.isfinite(m) and m >= 0.0):
        raise ValueError(f"margin must be finite and >= 0 m, got {margin!r}")
    return m


def point_triangle_candidates(
    points, radii, tris, pos, margin, point_node=None, cell_size=0.0
) -> np.ndarray:
    """Candidate (point, triangle) pairs.

    Args:
        points: query points [m], (N, 3) (e.g. ``pos[nodes]``).
        radii: point radii [m], a number or (N,).
        tris: triangles as node ids into ``pos``, (M, 3).
        pos: node positions [m], (n, 3).
        margin: extra reach [m] >= 0 (contact thickness + expected motion).
        point_node: node id of each point (N,), or node ids (N, k) (e.g. an edge station's two
            nodes), or None; a point is never paired with a triangle that has one of its nodes
            as a vertex (self contact). ``-1`` for "no node".
        cell_size: grid cell size [m]; 0 for automatic.

    Returns:
        pairs (K, 2) int64 ``[point index, triangle index]``, sorted.
    """
    pts = _as_points(points, "points")
    p = _as_points(pos, "pos")
    t = _as_ids(tris, 3, p.shape[0], "tris")
    r = _as_radii(radii, pts.shape[0], "radii")
    if point_node is None:
        qn = np.full((pts.shape[0], 1), -1, np.int64)
    else:
        qn = np.ascontiguousarray(point_node, dtype=np.int64)
        qn = qn.reshape(-1, 1) if qn.ndim == 1 else qn
        if qn.ndim != 2 or qn.shape[0] != pts.shape[0]:
            raise ValueError(f"point_node must have shape ({pts.shape[0]},) or ({pts.shape[0]}, k)")
    lo, hi = triangle_bounds(t, p)
    return grid_pairs(pts, r, qn, lo, hi, t, _as_margin(margin), float(cell_size))


def _segment_spheres(segs, pos, radii):
    a = pos[segs[:, 0]]
    b = pos[segs[:, 1]]
    mid = np.ascontiguousarray(0.5 * (a + b))
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    return mid, np.ascontiguousarray(half + radii)


def segment_triangle_candidates(segs, radii, tris, pos, margin, cell_size=0.0) -> np.ndarray:
    """Candidate (segment, triangle) pairs for edge-to-face line contact.

    Each segment is represented by its bounding sphere (midpoint, half length + radius), so
    every pair with a segment point within ``radius + margin`` of the triangle is reported.
    Segments sharing a node with the triangle are excluded.

    Args:
        segs: (N, 2) node ids; radii: a number or (N,) [m]; tris: (M, 3) node ids;
        pos: (n, 3) [m]; margin [m] >= 0.

    Returns:
        pairs (K, 2) int64 ``[segment index, triangle index]``, sorted.
    """
    p = _as_points(pos, "pos")
    s = _as_ids(segs, 2, p.shape[0], "segs")
    t = _as_ids(tris, 3, p.shape[0], "tris")
    r = _as_radii(radii, s.shape[0], "radii")
    mid, rad = _segment_spheres(s, p, r)
    lo, hi = triangle_bounds(t, p)
    return grid_pairs(mid, rad, s, lo, hi, t, _as_margin(margin), float(cell_size))


def segment_segment_candidates(
    segs, radii, targets, pos, margin, cell_size=0.0, unique=False
) -> np.ndarray:
    """Candidate (segment, target segment) pairs for edge-to-edge line contact.

    Args:
        segs: query segments (N, 2) node ids; radii: a number or (N,) [m] (the query's radius;
            put the target's radius into ``margin``); targets: (M, 2) node ids; pos: (n, 3) [m];
            margin [m] >= 0.
        unique: for self contact (``targets is segs``): keep only pairs with ``i < j``.

    Returns:
        pairs (K, 2) int64 ``[segment index, target index]``, sorted. Segments sharing a node are
        excluded.
    """
    p = _as_points(pos, "pos")
    s = _as_ids(segs, 2, p.shape[0], "segs")
    t = _as_ids(targets, 2, p.shape[0], "targets")
    r = _as_radii(radii, s.shape[0], "radii")
    mid, rad = _segment_spheres(s, p, r)
    lo, hi = segment_bounds(t, p)
    pairs = grid_pairs(mid, rad, s, lo, hi, t, _as_margin(margin), float(cell_size))
    if unique:
        pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    return pairs
