"""Node-to-face contact between shells: packaging layers against each other, consignment
against consignment, and self contact.

A contact set pairs a set of nodes with a set of triangles (the shells' quads split once).
Candidate pairs come from the broad phase (:mod:`flexparcel.contact.broadphase`) once per time
step, together with the side of the face each node is on at the start of the step, so a node is
always pushed back to the side it came from (a thin shell has two free sides). Per node only the
deepest candidate is used (a node near a shared edge is a candidate of several faces), with
hysteresis: a node keeps the face it used last while that face still holds it and is no more than
:data:`FACE_KEEP_MARGIN` times the contact thickness shallower than the deepest.

Why the hysteresis. A node inside a fold of the faceted surface (a content node against the
film wrapped round its edge) lies in the prisms of both faces next to the fold line, at nearly
equal depths; each face pushes along its own normal, so the force turns by the fold angle where
the two depths cross. Newton's iterates straddled that crossing on the paper's conveyor at 25 mm
(PB's content node 689 against film faces 17 deg apart, depths 223.83 and 223.80 nm): the
force's tangential part jumped by 0.08 N between iterates 0.1 nm apart, Newton cycled, and the
steps fell to 0.4 us. With the margin a face change needs the other face to be deeper by
1e-3 h (30 nm for PB's content on its 0.06 mm film, h = 0.03 mm), so iterates no longer
flip; in the motion the force turns at most that much later: a 30 nm dead band on 25 mm
facets, whose fold is itself the discretisation's (a smooth surface would turn the normal over
the whole element).

With the closest point ``sum_i l_i x_i`` on the face (barycentric ``l``), the face normal ``n``
towards the node and the contact thickness ``h`` (half the two shells' thicknesses):

    s = h - n . (p - closest),  v_rel = v_p - sum_i l_i v_i,  s' = -n . v_rel,
    f = A (F_N n + F_T) on the node,  -l_i f on face vertex i,

with the per-area law of :mod:`flexparcel.contact.law` and ``A`` [m^2] the slave node's
tributary area (reference geometry, :mod:`flexparcel.contact.tributary`). Line contact of edges
against faces (:func:`edge_face_forces`) is per unit length: each station carries the area
``w L / k`` of its edge (reference length ``L``, ``k`` stations, strip width ``w``).

With a stick stiffness in the law, friction follows the stick model
(:func:`flexparcel.contact.law.anchored_friction`): the tangential spring runs from the node to a
*stick anchor* that moves with the face. The anchor is kept as a world point ``A0`` at the end
of each accepted step (a new contact anchors where the node was at the step's start); during a
step it moves with the node's current triangle by the (unclamped, in-plane) barycentric weights
``m`` it had there at the step's start, so a node that slides onto the next triangle keeps its
history:

    e = p - A0 - sum_i m_i (x_i - x0_i),   a = e - (n . e) n,
    F_T = -k_t a  (stick)  or  -mu_k F_N a/|a|.

The anchor's offset from the face's plane (the contact thickness) is carried unturned through a
step: an error of (the face's turn in one step) x (thickness), second order.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.contact.broadphase import point_triangle_candidates
from flexparcel.contact.common import StickAnchors, check_history, pair_blocks, set_digest
from flexparcel.contact.geometry import (
    point_triangle,
    point_triangle_contact_derivs,
    side_used,
)
from flexparcel.contact.law import P_K_T, P_MAX_PEN, contact_friction, normal_force_packed
from flexparcel.model.interfaces import ContactSet, row_keys

__all__ = [
    "face_sides",
    "face_contact_forces",
    "edge_stations",
    "edge_face_forces",
    "point_face_candidates",
    "NodeFaceSet",
    "EdgeFaceSet",
    "FACE_KEEP_MARGIN",
]

FACE_KEEP_MARGIN = 1e-3
"""A node-face contact keeps its face while that face is at most this fraction of the contact
thickness shallower than the deepest candidate (see the module docstring)."""


@nb.njit(cache=True)
def face_sides(pairs, points, tris, pos):
    """Side (+1/-1) of each candidate's point (``points`` (N, 3) [m]) relative to its face,
    shape (K,)."""
    out = np.empty(pairs.shape[0])
    for k in range(pairs.shape[0]):
        t = tris[pairs[k, 1]]
        d = point_triangle(points[pairs[k, 0]], pos[t[0]], pos[t[1]], pos[t[2]])[0]
        out[k] = 1.0 if d >= 0.0 else -1.0
    return out


@nb.njit(cache=True)
def plane_barycentric(x, a, b, c):
    """Barycentric weights (3,) of the projection of ``x`` onto the plane of triangle (a, b, c),
    unclamped (outside the triangle some are negative); x, a, b, c shape (3,) [m]."""
    e1 = b - a
    e2 = c - a
    d = x - a
    d11 = e1 @ e1
    d12 = e1 @ e2
    d22 = e2 @ e2
    r1 = d @ e1
    r2 = d @ e2
    det = d11 * d22 - d12 * d12
    out = np.empty(3)
    out[1] = (d22 * r1 - d12 * r2) / det
    out[2] = (d11 * r2 - d12 * r1) / det
    out[0] = 1.0 - out[1] - out[2]
    return out


@nb.njit(cache=True)
def _point_face_pair(p, vp, tx, tv, thickness, side, law, scale, stick, m, c0):
    """One contact point (position ``p``, velocity ``vp``) against a triangle with vertex
    positions ``tx`` (3, 3) and velocities ``tv`` (3, 3); the law's force scaled by ``scale``.
    ``stick``: stick model with the anchor at ``c0 + sum_v m_v x_v`` (``m`` (3,) weights,
    ``c0`` (3,) [m]).

    Returns (s, force f (3,) on the point (-bary_v f on vertex v), barycentric weights bary
    (3,) of the closest point, blocks (12, 12) of d[f_p, f_a, f_b, f_c] /
    d[p, x_a, x_b, x_c] and / d[v_p, v_a, v_b, v_c], new elastic displacement (3,), dF_N/ds,
    normal velocity n . v_rel); s <= 0: no contact (the other outputs are zeros).
    """
    bk = np.zeros((12, 12))
    bc = np.zeros((12, 12))
    f = np.zeros(3)
    s, _, bary, n, _, _, ds, dn, dbary = point_triangle_contact_derivs(
        p, tx[0], tx[1], tx[2], thickness, side
    )
    if s <= 0.0:
        return s, f, bary, bk, bc, np.zeros(3), 0.0, 0.0
    vrel = vp - bary[0] * tv[0] - bary[1] * tv[1] - bary[2] * tv[2]
    vn = n[0] * vrel[0] + n[1] * vrel[1] + n[2] * vrel[2]
    vt = vrel - vn * n
    fn, dfn_ds, dfn_dsd = normal_force_packed(s, -vn, law)
    e = p - c0 - m[0] * tx[0] - m[1] * tx[1] - m[2] * tx[2]
    ft, u_new, dft_da, dft_dvt, dft_dfn, en = contact_friction(stick, e, n, vt, fn, law)
    f = scale * (fn * n + ft)
    w = np.empty(4)
    w[0] = 1.0
    w[1:] = -bary
    g = n + dft_dfn
    # s' = -n . vrel and vt = vrel - (n . vrel) n change with the configuration through n
    # and through the barycentric weights of the face velocities in vrel
    dvrel_x = np.zeros((3, 12))
    for a in range(3):
        for i in range(3):
            for j in range(12):
                dvrel_x[i, j] -= tv[a, i] * dbary[a, j]
    vdn = vrel @ dn
    dsd_x = -(vdn + n @ dvrel_x)
    proj = np.eye(3) - np.outer(n, n)
    dvt_x = proj @ dvrel_x - np.outer(n, vdn) - vn * dn
    dfx = scale * (np.outer(g, dfn_ds * ds + dfn_dsd * dsd_x) + fn * dn + dft_dvt @ dvt_x)
    if stick:
        # a = P e: da = P de - n (e . dn) - (n . e) dn, de/d[p, x_a, x_b, x_c] =
        # [I, -m_a I, -m_b I, -m_c I]
        de = np.zeros((3, 12))
        for i in range(3):
            de[i, i] = 1.0
            for v in range(3):
                de[i, 3 + 3 * v + i] = -m[v]
        dfx += scale * (dft_da @ (proj @ de - np.outer(n, e @ dn) - en * dn))
    dvrel = np.zeros((3, 12))
    for a in range(4):
        for i in range(3):
            dvrel[i, 3 * a + i] = w[a]
    dsd = np.zeros(12)
    for j in range(12):
        dsd[j] = -(n[0] * dvrel[0, j] + n[1] * dvrel[1, j] + n[2] * dvrel[2, j])
    dfv = scale * (np.outer(g, dfn_dsd * dsd) + dft_dvt @ proj @ dvrel)
    for a in range(4):
        for i in range(3):
            for j in range(12):
                bk[3 * a + i, j] = w[a] * dfx[i, j]
                bc[3 * a + i, j] = w[a] * dfv[i, j]
                if a > 0:
                    bk[3 * a + i, j] -= f[i] * dbary[a - 1, j]
    return s, f, bary, bk, bc, u_new, dfn_ds, vn


@nb.njit(cache=True)
def _best_candidates(pairs, sides, points, tris, pos, thickness, face, margin):
    """Candidate per query point (-1 if none penetrates): the deepest, unless the point's
    previous face ``face[q]`` (a row of ``tris``, -1: none) penetrates too and is at most
    ``margin`` [m] shallower, in which case that one (hysteresis, see the module docstring)."""
    best = np.full(points.shape[0], -1)
    best_s = np.zeros(points.shape[0])
    kept = np.full(points.shape[0], -1)
    kept_s = np.zeros(points.shape[0])
    for k in range(pairs.shape[0]):
        q = pairs[k, 0]
        t = tris[pairs[k, 1]]
        dist, _, _, _, region = point_triangle(points[q], pos[t[0]], pos[t[1]], pos[t[2]])
        s = thickness - side_used(int(sides[k]), dist, region) * dist
        if s > best_s[q]:
            best_s[q] = s
            best[q] = k
        if pairs[k, 1] == face[q] and s > 0.0:
            kept[q] = k
            kept_s[q] = s
    for q in range(points.shape[0]):
        if kept[q] >= 0 and kept_s[q] >= best_s[q] - margin:
            best[q] = kept[q]
    return best


@nb.njit(cache=True)
def face_contact_forces(
    pairs,
    sides,
    nodes,
    tris,
    thickness,
    law,
    act,
    node_area,
    pos,
    vel,
    out_f,
    out_k,
    out_c,
    out_dofs,
    mass,
    v_impact,
    out_w2,
    anchor,
    has_anchor,
    anchor_new,
    has_anchor_new,
    pos0,
    face,
):
    """Forces of one contact set, the law at node q of ``nodes`` multiplied by the schedule factor
    ``act`` and its tributary area ``node_area[q]`` [m^2]; blocks (K, 12, 12) of d[f_node, f_a, f_b,
    f_c]/d[x_node, x_a, x_b, x_c] (``out_k``) and /d[v...] (``out_c``), DOF numbers (K, 12) (-1 if
    unused).
    Stick model (law with k_t > 0): ``anchor`` (N, 3) world anchors [m] per node of the set at
    the step's start, valid where ``has_anchor`` (N,) is nonzero; this evaluation's anchors go
    to ``anchor_new`` / ``has_anchor_new``; ``pos0`` (n, 3) are the step's start positions.
    ``face`` (N,) int: each node's face (row of ``tris``) in the previous evaluation, -1 none;
    read for the hysteresis of the face choice and overwritten with this evaluation's.
    Returns (contacts, deepest penetration [m], worst penetration / max_penetration)."""
    npts = nodes.shape[0]
    points = np.empty((npts, 3))
    for q in range(npts):
        points[q] = pos[nodes[q]]
        has_anchor_new[q] = 0.0
    out_dofs[:, :] = -1
    best = _best_candidates(
        pairs, sides, points, tris, pos, thickness, face, FACE_KEEP_MARGIN * thickness
    )
    for q in range(npts):
        face[q] = -1
    n_contact = 0
    deepest = 0.0
    worst = 0.0
    if act == 0.0:
        return 0, 0.0, 0.0
    stick = law[P_K_T] > 0.0
    tx = np.empty((3, 3))
    tv = np.empty((3, 3))
    c0 = np.zeros(3)
    m = np.zeros(3)
    for q in range(npts):
        k = best[q]
        if k < 0:
            continue
        t = tris[pairs[k, 1]]
        node = nodes[q]
        for v in range(3):
            tx[v] = pos[t[v]]
            tv[v] = vel[t[v], :3]
        if stick:
            # anchor weights on this triangle from the step's start (constant in the step);
            # the anchor moves with the face by the weighted motion of its vertices and keeps
            # its offset off the face's plane, so a new contact starts without a spring
            a0 = anchor[q] if has_anchor[q] != 0.0 else pos0[node]
            m = plane_barycentric(a0, pos0[t[0]], pos0[t[1]], pos0[t[2]])
            c0 = a0 - m[0] * pos0[t[0]] - m[1] * pos0[t[1]] - m[2] * pos0[t[2]]
        scale = act * node_area[q]
        s, f, bary, bk, bc, u_new, dfn_ds, vn = _point_face_pair(
            pos[node], vel[node, :3], tx, tv, thickness, int(sides[k]), law, scale, stick, m, c0
        )
        if s <= 0.0:
            continue
        n_contact += 1
        face[q] = pairs[k, 1]
        deepest = max(deepest, s)
        worst = max(worst, s / law[P_MAX_PEN])
        if abs(vn) > v_impact and mass[node] > 0.0:
            out_w2[0] = max(out_w2[0], scale * dfn_ds / mass[node])
        if stick:
            anchor_new[q] = pos[node] - u_new
            has_anchor_new[q] = 1.0
        for i in range(3):
            out_f[node, i] += f[i]
            out_dofs[k, i] = 6 * node + i
            for v in range(3):
                out_f[t[v], i] -= bary[v] * f[i]
                out_dofs[k, 3 + 3 * v + i] = 6 * t[v] + i
        out_k[k] = bk
        out_c[k] = bc
    return n_contact, deepest, worst


@nb.njit(cache=True)
def edge_stations(edges, samples, pos):
    """Stations of shell edges (E, 2): positions (E * samples, 3) [m] at
    ``(1 - xi) x_i + xi x_j``, xi = (m + 1/2) / samples, and their two nodes (E * samples, 2)."""
    ne = edges.shape[0]
    pts = np.empty((ne * samples, 3))
    owners = np.empty((ne * samples, 2), np.int64)
    for e in range(ne):
        for st in range(samples):
            xi = (st + 0.5) / samples
            q = e * samples + st
            pts[q] = (1.0 - xi) * pos[edges[e, 0]] + xi * pos[edges[e, 1]]
            owners[q, 0] = edges[e, 0]
            owners[q, 1] = edges[e, 1]
    return pts, owners


@nb.njit(cache=True)
def edge_face_forces(
    pairs, sides, edges, samples, tris, thickness, law, act, station_area, pos, vel, out_f,
    out_k, out_c, out_dofs, mass, v_impact, out_w2,
):  # fmt: skip
    """Line contact of shell edges (E, 2) against the triangles of one contact set.

    ``pairs`` (K, 2): candidate [station, triangle] (station ``e * samples + m`` of edge e, see
    :func:`edge_stations`), ``sides`` (K,) the side each station started on. Each station is a
    contact point carrying the area ``station_area[e]`` [m^2] of its edge e times the schedule
    factor ``act`` (regularised friction), against its deepest candidate; its force f goes to the
    edge's nodes as ``(1 - xi) f``, ``xi f`` and to the triangle as ``-l_v f``. Blocks (K, 15, 15)
    of d[f_i, f_j, f_a, f_b, f_c] / d[x_i, x_j, x_a, x_b, x_c] (``out_k``) and / d[v...]
    (``out_c``), DOF numbers (K, 15) (-1 if unused). Returns (stations in contact, deepest
    penetration [m], worst penetration / max)."""
    stations, _ = edge_stations(edges, samples, pos)
    out_dofs[:, :] = -1
    no_face = np.full(stations.shape[0], -1)
    best = _best_candidates(pairs, sides, stations, tris, pos, thickness, no_face, 0.0)
    if act == 0.0:
        return 0, 0.0, 0.0
    n_contact = 0
    deepest = 0.0
    worst = 0.0
    tx = np.empty((3, 3))
    tv = np.empty((3, 3))
    zero = np.zeros(3)
    tmap = np.zeros((12, 15))  # [p, x_a, x_b, x_c] from [x_i, x_j, x_a, x_b, x_c]
    for i in range(9):
        tmap[3 + i, 6 + i] = 1.0
    for q in range(stations.shape[0]):
        k = best[q]
        if k < 0:
            continue
        e = q // samples
        scale = act * station_area[e]
        xi = (q % samples + 0.5) / samples
        i0, i1 = edges[e, 0], edges[e, 1]
        t = tris[pairs[k, 1]]
        for v in range(3):
            tx[v] = pos[t[v]]
            tv[v] = vel[t[v], :3]
        vp = (1.0 - xi) * vel[i0, :3] + xi * vel[i1, :3]
        s, f, bary, bk, bc, _, dfn_ds, vn = _point_face_pair(
            stations[q], vp, tx, tv, thickness, int(sides[k]), law, scale, False, zero, zero
        )
        if s <= 0.0:
            continue
        n_contact += 1
        deepest = max(deepest, s)
        worst = max(worst, s / law[P_MAX_PEN])
        mw = (1.0 - xi) * mass[i0] + xi * mass[i1]
        if abs(vn) > v_impact and mw > 0.0:
            out_w2[0] = max(out_w2[0], scale * dfn_ds / mw)
        for i in range(3):
            tmap[i, i] = 1.0 - xi
            tmap[i, 3 + i] = xi
            out_f[i0, i] += (1.0 - xi) * f[i]
            out_f[i1, i] += xi * f[i]
            out_dofs[k, i] = 6 * i0 + i
            out_dofs[k, 3 + i] = 6 * i1 + i
            for v in range(3):
                out_f[t[v], i] -= bary[v] * f[i]
                out_dofs[k, 6 + 3 * v + i] = 6 * t[v] + i
        # the station's force rows and position columns both split over the edge's nodes
        out_k[k] = tmap.T @ bk @ tmap
        out_c[k] = tmap.T @ bc @ tmap
    return n_contact, deepest, worst


def point_face_candidates(points, owners, tris, thickness, ctx, start):
    """Candidate (point, face) pairs (K, 2) of ``points`` (N, 3) [m] owned by nodes ``owners``
    (N, k) within the contact ``thickness`` plus the step's reach, and the side (K,) of its
    face each point starts on."""
    pairs = point_triangle_candidates(
        points, thickness, tris, start.positions, thickness + ctx.reach, point_node=owners
    )
    adj = ctx.adjacent_keys
    if pairs.size and adj.size:
        # a point never touches a face next to one of its nodes in its own mesh: it lies on
        # the extension of such a face (a shared border of two layers, a fold), at zero
        # distance, which would read as a full-depth penetration
        corner = tris[pairs[:, 1]]
        own = owners[pairs[:, 0]]
        keys = own[:, :, None] * start.positions.shape[0] + corner[:, None, :]
        # membership by binary search in the sorted keys: np.isin sorts or hashes them
        # again on every call (measured 6.6 ms a step on the paper's conveyor)
        at = np.minimum(np.searchsorted(adj, keys), adj.size - 1)
        near = (adj[at] == keys).any(axis=(1, 2))
        pairs = pairs[~near]
    return pairs, face_sides(pairs, points, tris, start.positions)


class NodeFaceSet(ContactSet):
    """Node-to-face contact: nodes against triangles (shell faces or solid boundary faces),
    both sides of a face free, contact distance ``thickness`` [m]; ``areas`` (N,): each slave
    node's tributary area [m^2] (reference geometry) by which the per-area law is multiplied.
    Candidates are found once per step; each node keeps the side of its face it started the
    step on. History: the stick model's world anchors per node, and each node's face (for the
    hysteresis of the face choice, module docstring)."""

    kind = "node_face"

    def __init__(self, nodes, triangles, thickness: float, law, schedule, areas) -> None:
        super().__init__(law, schedule)
        self.node = np.ascontiguousarray(nodes, dtype=np.int64)
        """Slave nodes, shape (N,)."""
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        """Master faces, shape (M, 3)."""
        self.thickness = float(thickness)
        self.area = np.array(np.broadcast_to(areas, self.node.shape), dtype=float)
        """Tributary area of each slave node [m^2], shape (N,)."""
        self.anchors = StickAnchors(self.node.size)
        self.face = np.full(self.node.size, -1, dtype=np.int64)
        """Each node's face (row of ``triangles``) at the last accepted step, -1: none."""
        self.face_trial = self.face.copy()
        self.candidates = (np.zeros((0, 2), np.int64), np.zeros(0))

    def begin_step(self) -> None:
        self.face_trial = self.face.copy()

    def commit(self) -> None:
        self.anchors.commit()
        self.face = self.face_trial.copy()

    def history(self) -> dict[str, np.ndarray]:
        return {**self.anchors.history(), "face": self.face}

    def restore_history(self, history) -> None:
        self.anchors.restore(history)
        # a checkpoint written before the face history existed: no preference, so the first
        # step chooses the deepest face as it did then
        none = np.full(self.node.size, -1, dtype=np.int64)
        self.face = check_history({"face": history.get("face", none)}, "face", none)
        self.face_trial = self.face.copy()

    def prepare(self, ctx, start, step) -> None:
        points = start.positions[self.node]
        self.candidates = point_face_candidates(
            points, self.node[:, None], self.triangles, self.thickness, ctx, start
        )

    def evaluate(self, ctx, state, out) -> None:
        pairs, sides = self.candidates
        fk, fc, dofs = pair_blocks(pairs.shape[0], 12)
        n_contact, depth, ratio = face_contact_forces(
            pairs, sides, self.node, self.triangles, self.thickness, ctx.laws[self.law_index],
            ctx.factors[self.schedule_index], self.area, state.positions, state.velocities,
            out.forces, fk, fc, dofs, ctx.node_mass, ctx.impact_speed, ctx.w2,
            *self.anchors.kernel_args(), ctx.start.positions, self.face_trial,
        )  # fmt: skip
        out.coupled_blocks.append((fk, fc, dofs))
        out.merge(n_contact, depth, ratio)

    def history_rows(self, numbering) -> np.ndarray:
        # a node's anchor belongs to this very set: the same nodes against the same faces
        digest = set_digest(self.kind, numbering[self.node], numbering[self.triangles],
                             np.array(self.thickness))  # fmt: skip
        return row_keys(f"{self.kind}:{digest}", numbering[self.node][:, None])

    def nodes(self) -> np.ndarray:
        return np.union1d(self.node, self.triangles.ravel())


class EdgeFaceSet(ContactSet):
    """Line contact of shell edges (E, 2), sampled at ``samples`` stations each, against
    triangles (a packaging's border against another consignment); ``station_areas`` (E,): the
    area [m^2] each station of an edge carries
    (:func:`flexparcel.contact.tributary.station_areas`)."""

    kind = "edge_face"

    def __init__(
        self, edges, triangles, thickness: float, samples: int, law, schedule, station_areas
    ) -> None:
        super().__init__(law, schedule)
        self.edges = np.ascontiguousarray(edges, dtype=np.int64)
        self.station_area = np.array(
            np.broadcast_to(station_areas, self.edges.shape[:1]), dtype=float
        )
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        self.thickness = float(thickness)
        self.samples = int(samples)
        self.candidates = (np.zeros((0, 2), np.int64), np.zeros(0))

    def prepare(self, ctx, start, step) -> None:
        points, owners = edge_stations(self.edges, self.samples, start.positions)
        self.candidates = point_face_candidates(
            points, owners, self.triangles, self.thickness, ctx, start
        )

    def evaluate(self, ctx, state, out) -> None:
        pairs, sides = self.candidates
        ek, ec, dofs = pair_blocks(pairs.shape[0], 15)
        n_contact, depth, ratio = edge_face_forces(
            pairs, sides, self.edges, self.samples, self.triangles, self.thickness,
            ctx.laws[self.law_index], ctx.factors[self.schedule_index], self.station_area,
            state.positions, state.velocities, out.forces, ek, ec, dofs, ctx.node_mass,
            ctx.impact_speed, ctx.w2,
        )  # fmt: skip
        out.coupled_blocks.append((ek, ec, dofs))
        out.merge(n_contact, depth, ratio)

    def nodes(self) -> np.ndarray:
        return np.union1d(self.edges.ravel(), self.triangles.ravel())
