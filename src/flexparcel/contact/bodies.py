"""Contact of shell nodes with rigid rounded boxes (packaging against its content).

For a node at ``p`` with contact radius ``r_p`` (half the shell thickness) and a box with
centre ``x_b``, rotation ``R_b``, inner half sizes ``h`` and edge radius ``r_b``, the geometry
kernel :func:`flexparcel.contact.geometry.point_box_contact_derivs` gives the penetration ``s``,
the box's outward normal ``n`` and the closest inner-box point ``c``. The contact point on the
box is ``c + r_b n`` at arm ``a`` from the box centre, and

    v_rel = v_p - (v_b + w_b x a),   s' = -n . v_rel,   vt = v_rel - (n . v_rel) n,
    f = F_N(s, s') n + F_T(vt, F_N)  on the node,   -f at the arm on the box.

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
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.contact.geometry import point_box_contact_derivs
from flexparcel.contact.law import (
    P_K_T,
    P_MAX_PEN,
    anchored_friction,
    friction_force_packed,
    normal_force_packed,
)
from flexparcel.elements.rotations import skew

__all__ = ["box_contact_forces"]


@nb.njit(cache=True)
def box_contact_forces(
    bp_node,
    bp_box,
    bp_radius,
    bp_law,
    bp_active,
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

    Args: pair arrays (Q,): node, box node, node contact radius [m], law index, schedule factor;
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
    for q in range(bp_node.shape[0]):
        for j in range(9):
            out_dofs[q, j] = -1
        has_anchor_new[q] = 0.0
        act = bp_active[q]
        if act == 0.0:
            continue
        node = bp_node[q]
        b = bp_box[q]
        p = pos[node]
        xb = pos[b]
        rb = rot[b]
        s, n, c, region, dn_dp, ds_dth, dn_dth = point_box_contact_derivs(
            p, xb, rb, box_half[b], box_radius[b], bp_radius[q]
        )
        if s <= 0.0:
            continue
        law = laws[bp_law[q]]
        n_contact += 1
        if s > deepest:
            deepest = s
            deepest_pair = q
        if s / law[P_MAX_PEN] > worst:
            worst = s / law[P_MAX_PEN]
        a = c + box_radius[b] * n - xb
        wb = vel[b, 3:]
        vrel = vel[node, :3] - vel[b, :3] - np.cross(wb, a)
        vn = n[0] * vrel[0] + n[1] * vrel[1] + n[2] * vrel[2]
        vt = vrel - vn * n
        fn, dfn_ds, dfn_dsd = normal_force_packed(s, -vn, law)
        if abs(vn) > v_impact and mass[node] > 0.0:
            out_w2[0] = max(out_w2[0], act * dfn_ds / mass[node])
        stick = law[P_K_T] > 0.0
        dft_da = np.zeros((3, 3))
        e = np.zeros(3)
        rxi = np.zeros(3)
        en = 0.0
        if stick:
            if has_anchor[q] != 0.0:
                xi = anchor[q]
            else:
                xi = rot0[b].T @ (pos0[node] - pos0[b])
            rxi = rb @ xi
            e = p - xb - rxi
            en = n[0] * e[0] + n[1] * e[1] + n[2] * e[2]
            ft, u_new, dft_da, dft_dvt, dft_dfn = anchored_friction(e - en * n, vt, fn, law)
            anchor_new[q] = rb.T @ (p - u_new - xb)
            has_anchor_new[q] = 1.0
        else:
            ft, dft_dvt, dft_dfn = friction_force_packed(vt, fn, law)
        f = act * (fn * n + ft)
        m = np.cross(a, f)
        for i in range(3):
            out_f[node, i] += f[i]
            out_f[b, i] -= f[i]
            out_f[b, 3 + i] -= m[i]
        # d s / d[x_node, x_box, spin_box]
        ds = np.zeros(9)
        ds[:3] = -n
        ds[3:6] = n
        ds[6:] = ds_dth
        # d n / d[...] (3 x 9)
        dn = np.zeros((3, 9))
        dn[:, :3] = dn_dp
        dn[:, 3:6] = -dn_dp
        dn[:, 6:] = dn_dth
        # d s' / d[v_node, v_box, w_box] with s' = -n . vrel
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
        da = np.outer(n, ds) + (s - bp_radius[q]) * dn
        for i in range(3):
            da[i, i] += 1.0
            da[i, 3 + i] -= 1.0
        dvrel_q = -skew(wb) @ da
        vdn = vrel @ dn
        dsd_q = -(vdn + n @ dvrel_q)
        dvt_q = proj @ dvrel_q - np.outer(n, vdn) - vn * dn
        g = n + dft_dfn
        dfk = act * (np.outer(g, dfn_ds * ds + dfn_dsd * dsd_q) + fn * dn + dft_dvt @ dvt_q)
        dfc = act * (np.outer(g, dfn_dsd * dsd) + dft_dvt @ proj @ dvrel)
        if stick:
            # a = P e: da = P de - n (e . dn) - (n . e) dn, de/d[x_node, x_box, spin_box] =
            # [I, -I, W(R_b xi)] (the anchor turns with the box: d(R_b xi) = dtheta x R_b xi)
            de = np.zeros((3, 9))
            de[:, 6:] = skew(rxi)
            for i in range(3):
                de[i, i] = 1.0
                de[i, 3 + i] = -1.0
            da_q = proj @ de - np.outer(n, e @ dn) - en * dn
            dfk += act * (dft_da @ da_q)
        wa = skew(a)
        mk = wa @ dfk
        mc = wa @ dfc
        for i in range(3):
            for j in range(9):
                out_k[q, i, j] = dfk[i, j]
                out_k[q, 3 + i, j] = -dfk[i, j]
                out_k[q, 6 + i, j] = -mk[i, j]
                out_c[q, i, j] = dfc[i, j]
                out_c[q, 3 + i, j] = -dfc[i, j]
                out_c[q, 6 + i, j] = -mc[i, j]
        for i in range(3):
            out_dofs[q, i] = 6 * node + i
            out_dofs[q, 3 + i] = 6 * b + i
            out_dofs[q, 6 + i] = 6 * b + 3 + i
    return n_contact, deepest, deepest_pair, worst
