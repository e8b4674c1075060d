"""Contact of shell nodes with rigid rounded boxes (packaging against its content).

For a node at ``p`` with contact radius ``r_p`` (half the shell thickness) and a box with
centre ``x_b``, rotation ``R_b``, inner half sizes ``h`` and edge radius ``r_b``, the geometry
kernel :func:`flexparcel.contact.geometry.point_box_contact_derivs` gives the penetration ``s``,
the box's outward normal ``n`` and the closest inner-box point ``c``. The contact point on the
box is ``c + r_b n`` at arm ``a`` from the box centre, and

    v_rel = v_p - (v_b + w_b x a),   s' = -n . v_rel,   vt = v_rel - (n . v_rel) n,
    f = A (F_N(s, s') n + F_T(vt, F_N))  on the node,   -f at the arm on the box,

with the per-area law of :mod:`flexparcel.contact.law` and ``A`` [m^2] the node's tributary
area (reference geometry, :mod:`flexparcel.contact.tributary`).

The Newton tangent includes the change of ``s``, ``s'``, ``n`` and the slip with the node's
translation and the box's translation, spin and velocities (``s'`` and the slip change with the
configuration through ``n`` and through the arm in ``w_b x a``); the change of the arm with the
configuration in the box moment ``a x f`` is left out (second order: ``|f| |da|`` against
``|a| |df|``, about ``s / |a|``).

With a stick stiffness in the law (:attr:`ContactLaw.stick_stiffness`) friction follows the stick
model (:func:`flexparcel.contact.law.anchored_friction`) instead: a tangential spring from the
node to a *stick anchor* fixed in the box's body frame (``xi``, carried from the last accepted
step; a new contact anchors where the node was at the step's start),

    e = p - x_b - R_b xi,   a = e - (n . e) n,   F_T = -k_t a  (stick)  or  -mu_k F_N a/|a|,

so the history turns and travels with the box.

Line contact (:func:`edge_box_forces`): a shell edge (nodes i, j) is sampled at ``k`` stations
``p = (1 - xi) x_i + xi x_j`` as in :mod:`flexparcel.contact.edges`, each a contact point
against the box carrying the area ``w L / k`` (line contact per unit length: ``L`` the edge's
reference length, ``w`` the strip width); a station's force is shared by the two nodes as
``(1 - xi) f`` and ``xi f``. Stations use the regularised friction law (no stick history).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.contact.common import AnchoredHistory, StickAnchors, pair_blocks
from flexparcel.contact.geometry import point_box_contact_derivs
from flexparcel.contact.law import P_K_T, P_MAX_PEN, contact_friction, normal_force_packed
from flexparcel.elements.rotations import skew
from flexparcel.model.interfaces import ContactSet, row_keys

__all__ = ["box_contact_forces", "edge_box_forces", "NodeBoxSet", "EdgeBoxSet"]


@nb.njit(cache=True)
def _point_box_pair(p, vp, xb, rb, vb, wb, half, r_box, r_p, law, scale, stick, xi):
    """One contact point (position ``p``, velocity ``vp``, radius ``r_p``) against a rounded
    box; the law's force scaled by ``scale``. ``stick``: use the stick model with the
    body-frame anchor ``xi`` (3,).

    Returns (s, force f (3,) on the point, arm a (3,) from the box centre, blocks (9, 9) of
    d[f_p, F_box, M_box] / d[p, x_b, spin_b] and / d[v_p, v_b, w_b] (F_box = -f, M_box =
    -(a x f); the change of the arm in M_box is left out, see the module docstring), new
    elastic displacement (3,), dF_N/ds, normal velocity n . v_rel); s <= 0: no contact (the
    other outputs are zeros).
    """
    s, n, c, _, dn_dp, ds_dth, dn_dth = point_box_contact_derivs(p, xb, rb, half, r_box, r_p)
    bk = np.zeros((9, 9))
    bc = np.zeros((9, 9))
    f = np.zeros(3)
    a = np.zeros(3)
    if s <= 0.0:
        return s, f, a, bk, bc, np.zeros(3), 0.0, 0.0
    a = c + r_box * n - xb
    vrel = vp - vb - np.cross(wb, a)
    vn = n[0] * vrel[0] + n[1] * vrel[1] + n[2] * vrel[2]
    vt = vrel - vn * n
    fn, dfn_ds, dfn_dsd = normal_force_packed(s, -vn, law)
    rxi = rb @ xi
    e = p - xb - rxi
    ft, u_new, dft_da, dft_dvt, dft_dfn, en = contact_friction(stick, e, n, vt, fn, law)
    f = scale * (fn * n + ft)
    # d s / d[p, x_box, spin_box]
    ds = np.zeros(9)
    ds[:3] = -n
    ds[3:6] = n
    ds[6:] = ds_dth
    # d n / d[...] (3 x 9)
    dn = np.zeros((3, 9))
    dn[:, :3] = dn_dp
    dn[:, 3:6] = -dn_dp
    dn[:, 6:] = dn_dth
    # d s' / d[v_p, v_box, w_box] with s' = -n . vrel
    dsd = np.zeros(9)
    dsd[:3] = -n
    dsd[3:6] = n
    dsd[6:] = np.cross(a, n)  # n . (w_b x a) = w_b . (a x n)
    proj = np.eye(3) - np.outer(n, n)
    dvrel = np.zeros((3, 9))
    dvrel[:, :3] = np.eye(3)
    dvrel[:, 3:6] = -np.eye(3)
    dvrel[:, 6:] = skew(a)
    # s' = -n . vrel and vt = vrel - (n . vrel) n change with the configuration through n
    # and through the arm in w_b x a, a = p - x_b + (s - r_p) n (outside and deep inside)
    da = np.outer(n, ds) + (s - r_p) * dn
    for i in range(3):
        da[i, i] += 1.0
        da[i, 3 + i] -= 1.0
    dvrel_q = -skew(wb) @ da
    vdn = vrel @ dn
    dsd_q = -(vdn + n @ dvrel_q)
    dvt_q = proj @ dvrel_q - np.outer(n, vdn) - vn * dn
    g = n + dft_dfn
    dfk = scale * (np.outer(g, dfn_ds * ds + dfn_dsd * dsd_q) + fn * dn + dft_dvt @ dvt_q)
    dfc = scale * (np.outer(g, dfn_dsd * dsd) + dft_dvt @ proj @ dvrel)
    if stick:
        # a = P e: da = P de - n (e . dn) - (n . e) dn, de/d[p, x_box, spin_box] =
        # [I, -I, W(R_b xi)] (the anchor turns with the box: d(R_b xi) = dtheta x R_b xi)
        de = np.zeros((3, 9))
        de[:, 6:] = skew(rxi)
        for i in range(3):
            de[i, i] = 1.0
            de[i, 3 + i] = -1.0
        dfk += scale * (dft_da @ (proj @ de - np.outer(n, e @ dn) - en * dn))
    # rows [f_p, F_box, M_box] = [f, -f, -(a x f)]
    mk = skew(a) @ dfk
    mc = skew(a) @ dfc
    for i in range(3):
        for j in range(9):
            bk[i, j] = dfk[i, j]
            bk[3 + i, j] = -dfk[i, j]
            bk[6 + i, j] = -mk[i, j]
            bc[i, j] = dfc[i, j]
            bc[3 + i, j] = -dfc[i, j]
            bc[6 + i, j] = -mc[i, j]
    return s, f, a, bk, bc, u_new, dfn_ds, vn


@nb.njit(cache=True)
def _box_dofs(out_dofs, k, nodes, box):
    """DOF numbers of a block over the translations of ``nodes`` then the box's translation
    and spin."""
    for r in range(3):
        for v in range(nodes.shape[0]):
            out_dofs[k, 3 * v + r] = 6 * nodes[v] + r
        out_dofs[k, 3 * nodes.shape[0] + r] = 6 * box + r
        out_dofs[k, 3 * nodes.shape[0] + 3 + r] = 6 * box + 3 + r


@nb.njit(cache=True)
def box_contact_forces(
    bp_node,
    bp_box,
    bp_radius,
    bp_law,
    bp_active,
    bp_area,
    box_half,
    box_radius,
    laws,
    pos,
    rot,
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
    rot0,
):
    """Forces of all (node, box) candidate pairs.

    Args: pair arrays (Q,): node, box node, node contact radius [m], law index, schedule factor,
    tributary area [m^2] (the per-area law is multiplied by it);
    per box node arrays indexed by node id: ``box_half`` (n, 3), ``box_radius`` (n,).
    Outputs: ``out_f`` (n, 6) accumulated generalised forces; ``out_k`` and ``out_c`` (Q, 9, 9)
    derivatives of the pair's generalised force [f_node(3), F_box(3), M_box(3)] with respect to
    [x_node, x_box, spin_box] and [v_node, v_box, w_box]; ``out_dofs`` (Q, 9) their DOF numbers
    (node * 6 + i), -1 for pairs not in contact.
    Stick model (laws with k_t > 0): ``anchor`` (Q, 3) body-frame anchors [m] of the last
    accepted step, valid where ``has_anchor`` (Q,) is nonzero; this evaluation's anchors go to
    ``anchor_new`` / ``has_anchor_new`` (0 for pairs out of contact); ``pos0`` (n, 3) and
    ``rot0`` (n, 3, 3) are the step's start state.
    Returns (contacts, deepest penetration [m], its pair, worst penetration / max_penetration).
    """
    n_contact = 0
    deepest = 0.0
    deepest_pair = -1
    worst = 0.0
    out_dofs[:, :] = -1
    node_ids = np.empty(1, np.int64)
    xi = np.zeros(3)
    for q in range(bp_node.shape[0]):
        has_anchor_new[q] = 0.0
        act = bp_active[q] * bp_area[q]
        if act == 0.0:
            continue
        node = bp_node[q]
        b = bp_box[q]
        law = laws[bp_law[q]]
        stick = law[P_K_T] > 0.0
        if stick:
            # a new contact anchors where the node was at the step's start, carried by the box
            xi = anchor[q] if has_anchor[q] != 0.0 else rot0[b].T @ (pos0[node] - pos0[b])
        s, f, a, bk, bc, u_new, dfn_ds, vn = _point_box_pair(
            pos[node], vel[node, :3], pos[b], rot[b], vel[b, :3], vel[b, 3:], box_half[b],
            box_radius[b], bp_radius[q], law, act, stick, xi,
        )  # fmt: skip
        if s <= 0.0:
            continue
        n_contact += 1
        if s > deepest:
            deepest = s
            deepest_pair = q
        if s / law[P_MAX_PEN] > worst:
            worst = s / law[P_MAX_PEN]
        if abs(vn) > v_impact and mass[node] > 0.0:
            out_w2[0] = max(out_w2[0], act * dfn_ds / mass[node])
        if stick:
            anchor_new[q] = rot[b].T @ (pos[node] - u_new - pos[b])
            has_anchor_new[q] = 1.0
        m = np.cross(a, f)
        for i in range(3):
            out_f[node, i] += f[i]
            out_f[b, i] -= f[i]
            out_f[b, 3 + i] -= m[i]
        out_k[q] = bk
        out_c[q] = bc
        node_ids[0] = node
        _box_dofs(out_dofs, q, node_ids, b)
    return n_contact, deepest, deepest_pair, worst


@nb.njit(cache=True)
def edge_box_forces(
    edges, box, radius, samples, law, act, station_area, box_half, box_radius, pos, rot, vel,
    out_f, out_k, out_c, out_dofs, mass, v_impact, out_w2,
):  # fmt: skip
    """Line contact of shell edges (E, 2) with the rounded box of rigid node ``box``; edge contact
    radius ``radius`` [m], ``samples`` stations per edge, packed ``law``, schedule factor ``act``,
    the area [m^2] ``station_area[e]`` of each station of edge e; ``box_half`` (n, 3),
    ``box_radius`` (n,) per node id as for :func:`box_contact_forces`. Outputs: ``out_f`` (n, 6)
    accumulated; blocks (E, 12, 12) of d[f_i, f_j, F_box, M_box] / d[x_i, x_j, x_box, spin_box]
    (``out_k``) and / d[v_i, v_j, v_box, w_box] (``out_c``); DOF numbers (E, 12), -1 for edges not
    in contact. Returns (stations in contact, deepest penetration [m], worst penetration / max)."""
    n_contact = 0
    deepest = 0.0
    worst = 0.0
    out_dofs[:, :] = -1
    if act == 0.0:
        return 0, 0.0, 0.0
    xb = pos[box]
    rb = rot[box]
    vb = vel[box, :3]
    wb = vel[box, 3:]
    half = box_half[box]
    r_box = box_radius[box]
    xi = np.zeros(3)
    tmap = np.zeros((9, 12))  # [p, x_box, spin_box] from [x_i, x_j, x_box, spin_box]
    for i in range(6):
        tmap[3 + i, 6 + i] = 1.0
    for e in range(edges.shape[0]):
        i0, i1 = edges[e, 0], edges[e, 1]
        scale = act * station_area[e]
        touched = False
        for st in range(samples):
            t = (st + 0.5) / samples
            p = (1.0 - t) * pos[i0] + t * pos[i1]
            vp = (1.0 - t) * vel[i0, :3] + t * vel[i1, :3]
            s, f, a, bk, bc, _, dfn_ds, vn = _point_box_pair(
                p, vp, xb, rb, vb, wb, half, r_box, radius, law, scale, False, xi
            )
            if s <= 0.0:
                continue
            touched = True
            n_contact += 1
            deepest = max(deepest, s)
            worst = max(worst, s / law[P_MAX_PEN])
            mw = (1.0 - t) * mass[i0] + t * mass[i1]
            if abs(vn) > v_impact and mw > 0.0:
                out_w2[0] = max(out_w2[0], scale * dfn_ds / mw)
            m = np.cross(a, f)
            for r in range(3):
                out_f[i0, r] += (1.0 - t) * f[r]
                out_f[i1, r] += t * f[r]
                out_f[box, r] -= f[r]
                out_f[box, 3 + r] -= m[r]
                tmap[r, r] = 1.0 - t
                tmap[r, 3 + r] = t
            # the station's force rows and position columns both split over the edge's nodes
            out_k[e] += tmap.T @ bk @ tmap
            out_c[e] += tmap.T @ bc @ tmap
        if touched:
            _box_dofs(out_dofs, e, edges[e], box)
    return n_contact, deepest, worst


class NodeBoxSet(AnchoredHistory, ContactSet):
    """Shell nodes (contact radius [m]) against the rounded box of one rigid body, e.g. a
    packaging on its content; ``areas`` (Q,): each node's tributary area [m^2] (reference
    geometry) by which the per-area law is multiplied. History: the stick model's anchors
    (body frame) per node."""

    kind = "node_box"

    def __init__(self, nodes, box: int, radius: float, law, schedule, areas) -> None:
        super().__init__(law, schedule)
        self.node = np.ascontiguousarray(nodes, dtype=np.int64)
        """Shell nodes, shape (Q,)."""
        self.box = int(box)
        """The rigid body's node."""
        self.radius = float(radius)
        self.area = np.array(np.broadcast_to(areas, self.node.shape), dtype=float)
        """Tributary area of each node [m^2], shape (Q,)."""
        # the kernel's per-pair box, radius and law rows; constant, so built once
        self._box_of = np.full(self.node.size, self.box, dtype=np.int64)
        self._radius_of = np.full(self.node.size, self.radius)
        self._law_of = np.zeros(self.node.size, np.int64)
        self.anchors = StickAnchors(self.node.size)

    def evaluate(self, ctx, state, out) -> None:
        q = self.node.size
        bk, bc, dofs = pair_blocks(q, 9)
        n_contact, depth, _, ratio = box_contact_forces(
            self.node, self._box_of, self._radius_of, self._law_of,
            np.full(q, ctx.factors[self.schedule_index]), self.area, ctx.box_half,
            ctx.model.box_radius_by_node, ctx.laws[self.law_index : self.law_index + 1],
            state.positions, state.rotations, state.velocities, out.forces, bk, bc, dofs,
            ctx.node_mass, ctx.impact_speed, ctx.w2, *self.anchors.kernel_args(),
            ctx.start.positions, ctx.start.rotations,
        )  # fmt: skip
        out.coupled_blocks.append((bk, bc, dofs))
        out.merge(n_contact, depth, ratio)

    def history_rows(self, numbering) -> np.ndarray:
        cols = np.column_stack([numbering[self.node], np.full(self.node.size, numbering[self.box])])
        return row_keys(self.kind, cols)

    def nodes(self) -> np.ndarray:
        return np.union1d(self.node, [self.box])


class EdgeBoxSet(ContactSet):
    """Line contact of shell edges (E, 2) against the rounded box of one rigid body, each
    edge sampled at ``samples`` stations (a packaging's border on its content's edges);
    ``station_areas`` (E,): the area [m^2] each station of an edge carries
    (:func:`flexparcel.contact.tributary.station_areas`)."""

    kind = "edge_box"

    def __init__(
        self, edges, box: int, radius: float, samples: int, law, schedule, station_areas
    ) -> None:
        super().__init__(law, schedule)
        self.edges = np.ascontiguousarray(edges, dtype=np.int64)
        self.station_area = np.array(
            np.broadcast_to(station_areas, self.edges.shape[:1]), dtype=float
        )
        self.box = int(box)
        self.radius = float(radius)
        self.samples = int(samples)

    def evaluate(self, ctx, state, out) -> None:
        ek, ec, dofs = pair_blocks(self.edges.shape[0], 12)
        n_contact, depth, ratio = edge_box_forces(
            self.edges, self.box, self.radius, self.samples, ctx.laws[self.law_index],
            ctx.factors[self.schedule_index], self.station_area, ctx.box_half,
            ctx.model.box_radius_by_node, state.positions, state.rotations, state.velocities,
            out.forces, ek, ec, dofs, ctx.node_mass, ctx.impact_speed, ctx.w2,
        )  # fmt: skip
        out.coupled_blocks.append((ek, ec, dofs))
        out.merge(n_contact, depth, ratio)

    def nodes(self) -> np.ndarray:
        return np.union1d(self.edges.ravel(), [self.box])
