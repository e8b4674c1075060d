"""Contact of points (shell nodes, rigid-box corners) with rigid planes, e.g. the ground, a
belt or a deflector.

A plane is a half-space, or, with :class:`PlaneBounds`, a bounded slab: a rectangle (length
along its axis, width across) whose surface is rounded by an edge radius ``r_b``, i.e. the set
of points within ``r_b`` of the rectangle ``r_b`` below the surface (a Minkowski sum, like the
rounded box). A belt of finite width and length is such a slab: packaging beyond its edges
hangs over the rounded edge or falls past it. Its distance function is continuous everywhere
(the closest point on a convex set moves continuously), so a node coming back from beside the
belt meets the rounded edge, not the top surface from below at full penetration (which threw
a sheet hanging over a belt cut off at its edge 1.7 m up). For a bounded plane the normal
below is the unit vector from the closest rectangle point q to the contact point, ``n = (p -
q) / |p - q|``, and ``s = r + r_b - |p - q|``; on the top face this is the plane's n and s.

Each contact point belongs to one node and sits at a body-frame offset ``b`` from it (zero for a
shell node; an inner-box corner for a rounded box) with a radius ``r`` (the box's edge radius:
a rounded box is its inner box inflated by r, so contact with it is contact with spheres of
radius r at the inner corners, exact for a plane). With ``rho = R b`` and the plane's unit
normal ``n`` through ``p0`` (pointing out of the solid side):

    penetration  s  = r - n . (x + rho - p0)
    contact arm  a  = rho - r n          (contact point relative to the node)
    its velocity vc = v + w x a - v_plane   (v_plane: the surface velocity of a belt)
    rate         s' = -n . vc,   slip  vt = vc - (n . vc) n

The law (:mod:`flexparcel.contact.law`, paper eqs. 1-10, per unit area) gives F_N(s, s') and the
friction F_T(vt, F_N) per unit area; each point carries its tributary area ``A`` [m^2] (a shell
node's share of the surface around it, a box corner's stated area), and the point force
``f = A (F_N n + F_T)`` acts at the arm, i.e. ``[f, a x f]`` on the
node. The kernel also returns the derivatives of that generalised force with respect to the
node's position/spin and velocity/angular velocity, for the Newton tangent (terms of order
w x (dtheta x rho) in the rate are left out). On a bounded plane's rounded edge the normal
turns with the point, ``dn/dp = (I - n n^T) P / |p - q|`` (P: the projection out of the
directions along which q slides with p); the tangent carries that term for the normal force
and its rate, and leaves out its effect on the friction direction and on the arm (of the
order of the friction force over the distance |p - q|; tested against finite differences).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from flexparcel.contact.common import ElasticSlipHistory
from flexparcel.contact.law import (
    P_K_T,
    P_MAX_PEN,
    friction_force_packed,
    normal_force_packed,
    stick_friction_packed,
)
from flexparcel.elements.rotations import skew
from flexparcel.model.interfaces import ContactSet, row_keys

__all__ = ["plane_contact_forces", "PlanePointSet", "PlaneBounds", "plane_gap"]


@dataclass(frozen=True)
class PlaneBounds:
    """The extent of a bounded plane (a slab with rounded edges, see the module docstring):
    ``axis`` the direction of its length (tangential to the plane; a belt's running
    direction), ``length`` and ``width`` [m] of the top face around the plane's point, and
    ``edge_radius`` [m] (> 0) of the rounded edges, half the slab's thickness."""

    axis: tuple[float, float, float]
    length: float
    width: float
    edge_radius: float

    def __post_init__(self) -> None:
        for name in ("length", "width", "edge_radius"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and 0.0 < v <= 1e3):
                raise ValueError(f"PlaneBounds.{name} must be in (0, 1000] m, got {v!r}")
        a = np.asarray(self.axis, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0.0:
            raise ValueError(
                f"PlaneBounds.axis must be 3 finite numbers, not all 0, got {self.axis!r}"
            )


@nb.njit(cache=True)
def _gap_into(px, py, pz, radius, point, normal, axis, extent, n_out, curv_out):
    """:func:`plane_gap` without allocation (the contact kernel calls it for every point in
    every evaluation): returns ``(s, turning)``; only for a point in contact (s > 0) it
    writes the normal into ``n_out`` (3,) and, where ``turning`` (on a rounded edge),
    ``dn/dp`` into ``curv_out`` (3, 3)."""
    rb = extent[2]
    if rb == 0.0:  # a half-space
        s = radius - (normal[0] * (px - point[0]) + normal[1] * (py - point[1])
                      + normal[2] * (pz - point[2]))  # fmt: skip
        if s > 0.0:
            n_out[:] = normal
        return s, False
    # from the rectangle's centre, which lies r_b below the surface
    d0 = px - point[0] + rb * normal[0]
    d1 = py - point[1] + rb * normal[1]
    d2 = pz - point[2] + rb * normal[2]
    w0 = normal[1] * axis[2] - normal[2] * axis[1]  # w = n x u, across the plane
    w1 = normal[2] * axis[0] - normal[0] * axis[2]
    w2 = normal[0] * axis[1] - normal[1] * axis[0]
    a = axis[0] * d0 + axis[1] * d1 + axis[2] * d2
    b = w0 * d0 + w1 * d1 + w2 * d2
    free_u = abs(a) < extent[0]
    free_w = abs(b) < extent[1]
    ac = min(max(a, -extent[0]), extent[0])
    bc = min(max(b, -extent[1]), extent[1])
    d0 -= ac * axis[0] + bc * w0
    d1 -= ac * axis[1] + bc * w1
    d2 -= ac * axis[2] + bc * w2
    dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    s = radius + rb - dist
    if s <= 0.0:
        return s, False
    if dist <= 1e-12:  # on the rectangle itself, deep inside the slab: push out of the top
        n_out[:] = normal
        return s, False
    n_out[0], n_out[1], n_out[2] = d0 / dist, d1 / dist, d2 / dist
    if free_u and free_w:  # over the top or bottom face: flat
        return s, False
    # dn/dp = (I - n n^T) P / dist, P the projection out of the directions q slides along
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                pkj = (1.0 if k == j else 0.0) - (axis[k] * axis[j] if free_u else 0.0)
                if free_w:
                    wk = w0 if k == 0 else (w1 if k == 1 else w2)
                    wj = w0 if j == 0 else (w1 if j == 1 else w2)
                    pkj -= wk * wj
                acc += ((1.0 if i == k else 0.0) - n_out[i] * n_out[k]) * pkj
            curv_out[i, j] = acc / dist
    return s, True


@nb.njit(cache=True)
def plane_gap(p, radius, point, normal, axis, extent):
    """Penetration ``s`` [m] (> 0 in contact) of a point ``p`` (3,) with contact ``radius``
    [m] into a plane (``point``, unit ``normal``; ``axis`` and ``extent`` = [half length,
    half width, edge radius] of a bounded one, edge radius 0: a half-space), the contact
    normal ``n`` (3,) and its derivative ``dn/dp`` (3, 3) (zero on a flat face; both zero
    out of contact)."""
    n = np.zeros(3)
    curv = np.zeros((3, 3))
    s, _ = _gap_into(p[0], p[1], p[2], radius, point, normal, axis, extent, n, curv)
    return s, n, curv


@nb.njit(cache=True)
def plane_contact_forces(
    cp_node,
    cp_offset,
    cp_radius,
    cp_plane,
    cp_law,
    cp_active,
    cp_area,
    plane_point,
    plane_normal,
    plane_velocity,
    plane_axis,
    plane_extent,
    laws,
    pos,
    rot,
    vel,
    out_f,
    out_dq,
    out_dv,
    mass,
    v_impact,
    out_w2,
    u_el,
    u_el_new,
    h,
    pos0,
    rot0,
):
    """Generalised contact forces of all points.

    Args: point arrays (P,) / (P, 3); ``cp_active`` (P,) schedule factors in [0, 1];
    ``cp_area`` (P,) tributary areas [m^2] (the law's per-area values times these);
    planes (k, 3) (``plane_extent`` [half length, half width, edge radius], edge radius 0:
    a half-space); ``laws`` (L, PACKED_SIZE); state ``pos`` (n, 3), ``rot`` (n, 3, 3),
    ``vel`` (n, 6).
    Outputs (accumulated): ``out_f`` (n, 6) forces [N, N m]; ``out_dq`` (P, 6, 6) and
    ``out_dv`` (P, 6, 6) derivatives per point (zero for points not in contact).
    Returns (number of points in contact, deepest penetration [m], its point, worst ratio of
    penetration to the law's max_penetration).
    """
    n_buf = np.zeros(3)  # the contact normal and dn/dp of the current point
    curv = np.zeros((3, 3))
    n_contact = 0
    deepest = 0.0
    deepest_pt = -1
    worst_ratio = 0.0
    for q in range(cp_node.shape[0]):
        act = cp_active[q] * cp_area[q]
        if act == 0.0:
            continue
        node = cp_node[q]
        pl = cp_plane[q]
        law = laws[cp_law[q]]
        r = rot[node]
        rho = r @ cp_offset[q]
        x = pos[node]
        s, turning = _gap_into(x[0] + rho[0], x[1] + rho[1], x[2] + rho[2], cp_radius[q],
                               plane_point[pl], plane_normal[pl], plane_axis[pl],
                               plane_extent[pl], n_buf, curv)  # fmt: skip
        if s <= 0.0:
            continue
        n = n_buf  # read only below; the next point's _gap_into overwrites it
        n_contact += 1
        if s > deepest:
            deepest = s
            deepest_pt = q
        ratio = s / law[P_MAX_PEN]
        if ratio > worst_ratio:
            worst_ratio = ratio
        a = rho - cp_radius[q] * n
        w = vel[node, 3:]
        vc = vel[node, :3] + np.cross(w, a) - plane_velocity[pl]
        vn = n[0] * vc[0] + n[1] * vc[1] + n[2] * vc[2]
        sdot = -vn
        vt = vc - vn * n
        fn, dfn_ds, dfn_dsd = normal_force_packed(s, sdot, law)
        if abs(sdot) > v_impact and mass[node] > 0.0:
            out_w2[0] = max(out_w2[0], act * dfn_ds / mass[node])
        stick = law[P_K_T] > 0.0
        dft_du = np.zeros((3, 3))
        if stick:
            # stick model: elastic tangential spring with a slip limit, history u_el carried
            # (per area: spring A k_t against the limit mu_s A F_N, so u_el does not see A)
            # from the last accepted step; the tangential displacement of the contact point
            # relative to the (moving) surface over this step drives it
            du = x + rho - pos0[node] - rot0[node] @ cp_offset[q] - plane_velocity[pl] * h
            du_t = du - (n[0] * du[0] + n[1] * du[1] + n[2] * du[2]) * n
            ft, u_new, _, dft_du, dft_dfn = stick_friction_packed(u_el[q], du_t, fn, h, law)
            u_el_new[q] = u_new
            dft_dvt = np.zeros((3, 3))
        else:
            ft, dft_dvt, dft_dfn = friction_force_packed(vt, fn, law)
        f = act * (fn * n + ft)
        m = np.cross(a, f)
        for i in range(3):
            out_f[node, i] += f[i]
            out_f[node, 3 + i] += m[i]
        # derivatives of s, s', vt with respect to [dx, dtheta] and [dv, dw]
        ds_dq = np.zeros(6)
        ds_dq[:3] = -n
        ds_dq[3:] = -np.cross(rho, n)
        dsd_dv = np.zeros(6)
        dsd_dv[:3] = -n
        dsd_dv[3:] = -np.cross(a, n)
        proj = np.eye(3) - np.outer(n, n)
        dvc_dv = np.zeros((3, 6))
        dvc_dv[:, :3] = np.eye(3)
        dvc_dv[:, 3:] = -skew(a)
        dvt_dv = proj @ dvc_dv
        # force derivatives (3 x 6)
        dfn_q = dfn_ds * ds_dq
        dfn_v = dfn_dsd * dsd_dv
        if turning:
            # the normal turning on a rounded edge: dn/d[x, theta] = curv dp/d[x, theta]; the
            # rate s' = -n . vc turns with it
            dn_q = np.zeros((3, 6))
            dn_q[:, :3] = curv
            dn_q[:, 3:] = -(curv @ skew(rho))
            dfn_q = dfn_q - dfn_dsd * (vc @ dn_q)
        df_q = np.outer(n + dft_dfn, dfn_q)
        if turning:
            df_q += fn * dn_q
        if stick:
            dp_dq = np.zeros((3, 6))
            dp_dq[:, :3] = np.eye(3)
            dp_dq[:, 3:] = -skew(rho)
            df_q += dft_du @ proj @ dp_dq
        df_v = np.outer(n + dft_dfn, dfn_v) + dft_dvt @ dvt_dv
        df_q *= act
        df_v *= act
        wa = skew(a)
        # moment a x f: d(a x f) = a x df + (dtheta x rho) x f = a x df + W(f) W(rho) dtheta
        extra = skew(f) @ skew(rho)
        for i in range(3):
            for j in range(6):
                out_dq[q, i, j] += df_q[i, j]
                out_dv[q, i, j] += df_v[i, j]
        mq = wa @ df_q
        mv = wa @ df_v
        for i in range(3):
            for j in range(6):
                out_dq[q, 3 + i, j] += mq[i, j]
                out_dv[q, 3 + i, j] += mv[i, j]
            for j in range(3):
                out_dq[q, 3 + i, 3 + j] += extra[i, j]
    return n_contact, deepest, deepest_pt, worst_ratio


class PlanePointSet(ElasticSlipHistory, ContactSet):
    """Contact points on one rigid plane: shell nodes with a contact radius, or the corners of
    a rigid body's rounded box (their offsets in the body frame, the edge radius as radius).

    ``areas`` (P,): each point's tributary area [m^2] of the reference geometry, by which the
    per-area law is multiplied (:mod:`flexparcel.contact.tributary`).

    History: the stick model's elastic slip ``u_el`` (P, 3) per point [m].
    """

    kind = "plane"

    def __init__(self, nodes, offsets, radii, plane: int, law, schedule, areas) -> None:
        super().__init__(law, schedule)
        self.node = np.ascontiguousarray(nodes, dtype=np.int64)
        """Node of each contact point, shape (P,)."""
        self.offset = np.ascontiguousarray(offsets, dtype=float).reshape(-1, 3)
        """Body-frame offset of each point from its node [m], shape (P, 3)."""
        self.radius = np.ascontiguousarray(radii, dtype=float)
        """Radius of each point [m], shape (P,)."""
        self.plane = int(plane)
        self.area = np.array(np.broadcast_to(areas, self.node.shape), dtype=float)
        """Tributary area of each point [m^2], shape (P,)."""
        # the kernel's per-point plane and law rows; constant, so built once, not per call
        self._plane_of = np.full(self.node.size, self.plane, dtype=np.int64)
        self._law_of = np.zeros(self.node.size, np.int64)
        self._init_elastic_slip(self.node.size)

    def evaluate(self, ctx, state, out) -> None:
        m = ctx.model
        p = self.node.size
        dq = np.zeros((p, 6, 6))
        dv = np.zeros((p, 6, 6))
        n_contact, depth, point, ratio = plane_contact_forces(
            self.node, self.offset, self.radius, self._plane_of, self._law_of,
            np.full(p, ctx.factors[self.schedule_index]), self.area, m.plane_point, m.plane_normal,
            m.plane_velocity, m.plane_axis, m.plane_extent,
            ctx.laws[self.law_index : self.law_index + 1], state.positions, state.rotations,
            state.velocities, out.forces, dq, dv, ctx.node_mass,
            ctx.impact_speed, ctx.w2, self.u_el, self.u_el_trial, ctx.step,
            ctx.start.positions, ctx.start.rotations,
        )  # fmt: skip
        out.node_blocks.append((self.node, dq, dv))
        out.merge(n_contact, depth, ratio, int(self.node[point]) if point >= 0 else -1)

    def history_rows(self, numbering) -> np.ndarray:
        cols = np.column_stack([numbering[self.node], np.full(self.node.size, self.plane),
                                self.offset])  # fmt: skip
        return row_keys(self.kind, cols)

    def nodes(self) -> np.ndarray:
        return np.unique(self.node)
