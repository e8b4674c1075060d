"""Edge-to-edge line contact: a shell element edge crossing another edge, e.g. a packaging's
25 mm element edge wrapped round a deflector's tip edge, which passes between any stations of
node-to-face or edge-to-face contact.

Each candidate pair of segments ``a = p0-p1`` and ``b = q0-q1`` meets at the closest points
``x_p = p0 + s (p1 - p0)``, ``x_q = q0 + t (q1 - q0)``
(:func:`~flexparcel.contact.geometry.segment_segment_param_derivs`), ``dist = |x_p - x_q|``,
``n = (x_p - x_q) / dist``. Like a node on a thin shell face, a segment can be on either side of
the other, so each pair keeps the direction ``n0`` it had at the start of the step (found by the
broad phase, :func:`edge_edge_sides`): with ``sigma = sign(n . n0)``,

    penetration  g = h - sigma dist       (h: the contact thickness, the two radii),
    push         m = sigma n              (continuous where the segments pass through each other),
    v_rel = v(x_p) - v(x_q),  g' = -m . v_rel,
    f = A_b (F_N(g, g') m + F_T(v_rel - (m . v_rel) m))   on x_p, and -f on x_q,

with the per-area law of :mod:`flexparcel.contact.law`. Friction is the regularised law (eq. 8) on
the tangential part of v_rel, or, where the law has a stick stiffness, the stick model
(:func:`~flexparcel.contact.law.stick_friction`): a tangential spring on the closest points'
relative displacement over the step, ``du = sum_i w_i (x_i - x0_i)`` (the material points at
the current closest points' weights ``w``, from the step's start ``x0``), its tangential part
driving the return map from the pair's elastic slip of the last accepted step. The regularised
law's 1 mm/s sigmoid acts like a sign switch at microsecond steps: a film wrapped round a
deflector's outer end (the paper's conveyor at 25 mm, 1.054 s; 40 N on one film node) slid
along the edge at a relative speed near zero, the friction (12 N) turned with Newton's
micrometre corrections, and the steps fell below 0.1 us. The elastic slip is kept per edge b
(a packaging's element edge) together with the edge a it belongs to: a pair that finds another
pair's spring on its edge b starts without one (an edge b rarely crosses two edges a at once).
Line contact is per unit length, and a pair carries the area ``A_b = w L_b`` of
its edge b (reference length ``L_b``, strip width ``w``): edges b (a packaging's element edges) that
cross a line a (a deflector's tip) cross it one such length apart, and an edge b lying along a
touches it over its length, so the force per length of the line does not depend on b's mesh. The
force goes to the nodes by the closest points' weights, ``(1 - s) f``, ``s f`` to p0, p1 and ``-(1 -
t) f``, ``-t f`` to q0, q1; its derivative includes the change of those weights (``ds/dX``,
``dt/dX``), so the blocks are the exact derivatives of the force the kernel returns (checked against
finite differences in ``tests/test_contact_tangents.py``).
The closest points are Ericson's (*Real-Time Collision Detection*, 2005, section 5.1.9); the
normal law is the paper's (eqs. 1-10) on the gap between the two segments' capsules.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.contact.broadphase import segment_segment_candidates
from flexparcel.contact.common import check_history, pair_blocks, set_digest
from flexparcel.contact.geometry import segment_segment, segment_segment_param_derivs
from flexparcel.contact.law import (
    P_K_T,
    P_MAX_PEN,
    friction_force_packed,
    normal_force_packed,
    stick_friction_packed,
)
from flexparcel.model.interfaces import ContactSet, row_keys

__all__ = ["edge_edge_sides", "edge_edge_forces", "EdgeEdgeSet"]


@nb.njit(cache=True)
def edge_edge_sides(pairs, edges_a, edges_b, pos):
    """Start directions ``n0`` (K, 3) of candidate pairs (K, 2) ``[edge of a, edge of b]``:
    the unit vector from b's closest point towards a's (:func:`segment_segment`)."""
    out = np.empty((pairs.shape[0], 3))
    for k in range(pairs.shape[0]):
        ea = edges_a[pairs[k, 0]]
        eb = edges_b[pairs[k, 1]]
        _, _, _, n = segment_segment(pos[ea[0]], pos[ea[1]], pos[eb[0]], pos[eb[1]])
        out[k] = n
    return out


@nb.njit(cache=True)
def _edge_pair(x, v, x0, n0, thickness, law, scale, u_prev, h):
    """One pair: nodes ``x``, ``v``, ``x0`` (start of the step) (4, 3) = [p0, p1, q0, q1];
    ``scale``: schedule factor x area [m^2]; ``u_prev`` (3,) the elastic slip carried into the
    step [m] (stick model, law with k_t > 0), ``h`` the step [s]. Returns (g, node forces
    (4, 3), d forces / d x (12, 12), d forces / d v (12, 12), dF_N/dg, normal speed m . v_rel,
    new elastic slip (3,)); g <= 0: no contact (zeros)."""
    fk = np.zeros((12, 12))
    fc = np.zeros((12, 12))
    fnode = np.zeros((4, 3))
    u_new = np.zeros(3)
    s, t, dist, n, dd, dn, ds, dt = segment_segment_param_derivs(x[0], x[1], x[2], x[3])
    sigma = 1.0 if n[0] * n0[0] + n[1] * n0[1] + n[2] * n0[2] >= 0.0 else -1.0
    g = thickness - sigma * dist
    if g <= 0.0:
        return g, fnode, fk, fc, 0.0, 0.0, u_new
    m = sigma * n
    dm = sigma * dn  # (3, 12)
    dg = -sigma * dd  # (12,)
    w = np.array([1.0 - s, s, -(1.0 - t), -t])  # force on node i = w_i f
    dw = np.zeros((4, 12))
    for j in range(12):
        dw[0, j] = -ds[j]
        dw[1, j] = ds[j]
        dw[2, j] = dt[j]
        dw[3, j] = -dt[j]
    vrel = w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3]
    vn = m[0] * vrel[0] + m[1] * vrel[1] + m[2] * vrel[2]
    vt = vrel - vn * m
    fn, dfn_dg, dfn_dgd = normal_force_packed(g, -vn, law)
    stick = law[P_K_T] > 0.0
    if stick:
        du = np.zeros(3)
        for i in range(4):
            du += w[i] * (x[i] - x0[i])
        dun = m[0] * du[0] + m[1] * du[1] + m[2] * du[2]
        ft, u_new, _, dft_du, dft_dfn = stick_friction_packed(u_prev, du - dun * m, fn, h, law)
        dft_dvt = np.zeros((3, 3))
    else:
        ft, dft_dvt, dft_dfn = friction_force_packed(vt, fn, law)
    f = scale * (fn * m + ft)
    gvec = m + dft_dfn
    # v_rel moves with the closest points: d v_rel / dX = sum_i v_i dw_i / dX
    dvrel_x = np.zeros((3, 12))
    for i in range(4):
        for a in range(3):
            for j in range(12):
                dvrel_x[a, j] += v[i, a] * dw[i, j]
    dvn_x = vrel @ dm + m @ dvrel_x
    dvt_x = dvrel_x - np.outer(m, dvn_x) - vn * dm
    dfx = scale * (np.outer(gvec, dfn_dg * dg - dfn_dgd * dvn_x) + fn * dm + dft_dvt @ dvt_x)
    proj = np.eye(3) - np.outer(m, m)
    if stick:
        # du = sum_i w_i (x_i - x0_i): d du/dX = [w_i I] + (x_i - x0_i) dw_i/dX; its
        # tangential part P du turns with m: - m (du . dm) - (m . du) dm
        ddu = np.zeros((3, 12))
        for i in range(4):
            for a in range(3):
                ddu[a, 3 * i + a] += w[i]
                for j in range(12):
                    ddu[a, j] += (x[i, a] - x0[i, a]) * dw[i, j]
        ddu_t = proj @ ddu - np.outer(m, du @ dm) - dun * dm
        dfx += scale * (dft_du @ ddu_t)
    dvrel_v = np.zeros((3, 12))
    for i in range(4):
        for a in range(3):
            dvrel_v[a, 3 * i + a] = w[i]
    dvn_v = m @ dvrel_v
    dfv = scale * (-dfn_dgd * np.outer(gvec, dvn_v) + dft_dvt @ proj @ dvrel_v)
    for i in range(4):
        for a in range(3):
            fnode[i, a] = w[i] * f[a]
            for j in range(12):
                fk[3 * i + a, j] = w[i] * dfx[a, j] + f[a] * dw[i, j]
                fc[3 * i + a, j] = w[i] * dfv[a, j]
    return g, fnode, fk, fc, dfn_dg, vn, u_new


@nb.njit(cache=True)
def edge_edge_forces(
    pairs, sides, edges_a, edges_b, thickness, law, act, area_b, pos, vel, out_f, out_k,
    out_c, out_dofs, mass, v_impact, out_w2, pos0, u_prev, u_new, h,
):  # fmt: skip
    """Edge-to-edge contact of the candidate pairs (K, 2) ``[edge of a, edge of b]`` with
    start directions ``sides`` (K, 3) (:func:`edge_edge_sides`); the per-area law's force
    multiplied by the schedule factor ``act`` and the area ``area_b`` (Eb,) [m^2] of the
    pair's edge b. Forces go into ``out_f`` (n, 6); blocks (K, 12, 12) of
    d[f_p0, f_p1, f_q0, f_q1] / d[x_p0, x_p1, x_q0, x_q1] (``out_k``) and / d[v...]
    (``out_c``), DOF numbers (K, 12) (-1 if not in contact). Stick model (law with k_t > 0):
    ``pos0`` (n, 3) the step's start positions, ``u_prev`` (K, 3) each pair's elastic slip
    carried into the step [m], ``u_new`` (K, 3) this evaluation's (NaN where out of contact),
    ``h`` the step [s]. Returns (pairs in contact, deepest penetration [m], worst penetration
    / max)."""
    out_dofs[:, :] = -1
    u_new[:, :] = np.nan
    if act == 0.0:
        return 0, 0.0, 0.0
    n_contact = 0
    deepest = 0.0
    worst = 0.0
    x = np.empty((4, 3))
    v = np.empty((4, 3))
    x0 = np.empty((4, 3))
    nodes = np.empty(4, np.int64)
    for k in range(pairs.shape[0]):
        nodes[0] = edges_a[pairs[k, 0], 0]
        nodes[1] = edges_a[pairs[k, 0], 1]
        nodes[2] = edges_b[pairs[k, 1], 0]
        nodes[3] = edges_b[pairs[k, 1], 1]
        for i in range(4):
            x[i] = pos[nodes[i]]
            v[i] = vel[nodes[i], :3]
            x0[i] = pos0[nodes[i]]
        scale = act * area_b[pairs[k, 1]]
        g, fnode, fk, fc, dfn_dg, vn, uk = _edge_pair(
            x, v, x0, sides[k], thickness, law, scale, u_prev[k], h
        )
        if g <= 0.0:
            continue
        u_new[k] = uk
        n_contact += 1
        deepest = max(deepest, g)
        worst = max(worst, g / law[P_MAX_PEN])
        # the lighter segment rings fastest (a rigid or fixed one has no node mass here)
        ma = 0.5 * (mass[nodes[0]] + mass[nodes[1]])
        mb = 0.5 * (mass[nodes[2]] + mass[nodes[3]])
        mw = min(ma, mb) if ma > 0.0 and mb > 0.0 else max(ma, mb)
        if abs(vn) > v_impact and mw > 0.0:
            out_w2[0] = max(out_w2[0], scale * dfn_dg / mw)
        for i in range(4):
            for a in range(3):
                out_f[nodes[i], a] += fnode[i, a]
                out_dofs[k, 3 * i + a] = 6 * nodes[i] + a
        out_k[k] = fk
        out_c[k] = fc
    return n_contact, deepest, worst


class EdgeEdgeSet(ContactSet):
    """Edge-to-edge line contact of edges a (Ea, 2) against edges b (Eb, 2), ``thickness``
    [m] the sum of the two edges' radii (a deflector's tip against packaging element edges);
    ``areas_b`` (Eb,): the area [m^2] a pair with edge b carries (its reference length times the
    strip width). Candidates once per step; each pair keeps the direction it started the step
    in. History (stick model): the elastic slip (Eb, 3) [m] per edge b and the edge a it
    belongs to (Eb,), -1: none."""

    kind = "edge_edge"

    def __init__(self, edges_a, edges_b, thickness: float, law, schedule, areas_b) -> None:
        super().__init__(law, schedule)
        self.edges_a = np.ascontiguousarray(edges_a, dtype=np.int64)
        self.edges_b = np.ascontiguousarray(edges_b, dtype=np.int64)
        self.area_b = np.array(np.broadcast_to(areas_b, self.edges_b.shape[:1]), dtype=float)
        self.thickness = float(thickness)
        self.candidates = (np.zeros((0, 2), np.int64), np.zeros((0, 3)))
        self.u_el = np.zeros((self.edges_b.shape[0], 3))
        """Elastic slip [m] per edge b at the last accepted step, shape (Eb, 3)."""
        self.partner = np.full(self.edges_b.shape[0], -1, dtype=np.int64)
        """The edge a whose pair with edge b holds ``u_el``, -1: none, shape (Eb,)."""
        self._u_prev = np.zeros((0, 3))
        self._u_trial = np.zeros((0, 3))

    def prepare(self, ctx, start, step) -> None:
        pos = start.positions
        pairs = segment_segment_candidates(
            self.edges_a, self.thickness, self.edges_b, pos, ctx.reach
        )
        sides = edge_edge_sides(pairs, self.edges_a, self.edges_b, pos)
        self.candidates = (pairs, sides)
        # each pair's spring from the last accepted step, in the tangent plane it starts in
        held = self.partner[pairs[:, 1]] == pairs[:, 0]
        u = np.where(held[:, None], self.u_el[pairs[:, 1]], 0.0)
        self._u_prev = u - np.sum(u * sides, axis=1)[:, None] * sides
        self._u_trial = np.full((pairs.shape[0], 3), np.nan)

    def evaluate(self, ctx, state, out) -> None:
        pairs, sides = self.candidates
        ek, ec, dofs = pair_blocks(pairs.shape[0], 12)
        n_contact, depth, ratio = edge_edge_forces(
            pairs, sides, self.edges_a, self.edges_b, self.thickness, ctx.laws[self.law_index],
            ctx.factors[self.schedule_index], self.area_b, state.positions, state.velocities,
            out.forces, ek, ec, dofs, ctx.node_mass, ctx.impact_speed, ctx.w2,
            ctx.start.positions, self._u_prev, self._u_trial, ctx.step,
        )  # fmt: skip
        out.coupled_blocks.append((ek, ec, dofs))
        out.merge(n_contact, depth, ratio)

    def commit(self) -> None:
        # the accepted step's pairs in contact keep their springs; every other edge b loses its
        pairs = self.candidates[0]
        live = ~np.isnan(self._u_trial[:, 0])
        self.partner[:] = -1
        self.u_el[:] = 0.0
        self.partner[pairs[live, 1]] = pairs[live, 0]
        self.u_el[pairs[live, 1]] = self._u_trial[live]

    def history(self) -> dict[str, np.ndarray]:
        return {"u_el": self.u_el, "partner": self.partner}

    def restore_history(self, history) -> None:
        # a checkpoint written before edge pairs had springs: none
        none = {"u_el": np.zeros_like(self.u_el), "partner": np.full_like(self.partner, -1)}
        self.u_el = check_history({**none, **history}, "u_el", self.u_el)
        self.partner = check_history({**none, **history}, "partner", self.partner)

    def history_rows(self, numbering) -> np.ndarray:
        # an edge b's spring belongs to this very set: the same edges a and b
        digest = set_digest(self.kind, numbering[self.edges_a], numbering[self.edges_b],
                            np.array(self.thickness))  # fmt: skip
        return row_keys(f"{self.kind}:{digest}", numbering[self.edges_b])

    def nodes(self) -> np.ndarray:
        return np.union1d(self.edges_a.ravel(), self.edges_b.ravel())
