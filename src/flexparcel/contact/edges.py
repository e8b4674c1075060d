"""Line contact: shell edges against rigid planes (an envelope standing on its glued edge).

Each edge (nodes i, j) is sampled at ``k`` Gauss-Lobatto-like stations xi = (m + 1/2)/k,
m = 0..k-1 (midpoints of k equal parts), each carrying a contact point that moves with the edge,
``p(xi) = (1 - xi) x_i + xi x_j``. The law is per unit area (:mod:`flexparcel.contact.law`);
line contact is per unit length: each station carries the area ``w L / k`` (``L`` the edge's
reference length, ``w`` the set's strip width), so a uniformly pressed edge carries ``w L`` times
the law's force per area whatever the mesh. The point force f is shared by the two nodes as
``(1 - xi) f`` and ``xi f``; a belt's surface velocity enters the slip as for point contact.

Friction follows the law as point contact on a plane does (:mod:`flexparcel.contact.planes`):
with a stick stiffness k_t each station carries its own elastic slip ``u_el`` (the stick
model's return map, driven by the station's tangential displacement over the step relative to
the plane's surface), else the regularised law (eq. 8). Why the stick model matters here: the
regularised law takes mu from 0 to mu_s over v_s = 1 mm/s of slip, and at the microsecond
steps of an edge impact that is a few nanometres of displacement. Measured on the KP/BW
vertical drop at 10 mm (the glued edge landing at 2 m/s, 23 N on a station's node): Newton
could not settle that sigmoid, and the envelope carried a net residual force of 2-30 N in the
plate's plane until the step fell below its minimum.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.contact.common import ElasticSlipHistory, pair_blocks
from flexparcel.contact.law import (
    P_K_T,
    P_MAX_PEN,
    friction_force_packed,
    normal_force_packed,
    stick_friction_packed,
)
from flexparcel.model.interfaces import ContactSet, row_keys

__all__ = ["edge_plane_forces", "EdgePlaneSet"]


@nb.njit(cache=True)
def edge_plane_forces(
    edges,
    plane_point,
    plane_normal,
    plane_velocity,
    radius,
    samples,
    law,
    act,
    station_area,
    pos,
    vel,
    out_f,
    out_k,
    out_c,
    out_dofs,
    mass,
    v_impact,
    out_w2,
    u_el,
    u_el_new,
    h,
    pos0,
):
    """Forces of all edges (E, 2) against one plane, each station of edge e carrying the
    area ``station_area[e]`` [m^2] times the schedule factor ``act``; blocks (E, 6, 6) of
    d[f_i, f_j] / d[x_i, x_j] (``out_k``) and / d[v_i, v_j] (``out_c``), DOF numbers (E, 6).
    Stick model (the law's k_t > 0): elastic slips ``u_el`` (E * samples, 3) [m] of the last
    accepted step in, this iterate's in ``u_el_new``; ``pos0`` (n, 3) the step's start, ``h``
    its length [s].
    Returns (points in contact, deepest penetration [m], worst penetration / max)."""
    n = plane_normal
    n_contact = 0
    deepest = 0.0
    worst = 0.0
    proj = np.eye(3) - np.outer(n, n)
    stick = law[P_K_T] > 0.0
    for e in range(edges.shape[0]):
        scale = act * station_area[e]
        i, j = edges[e, 0], edges[e, 1]
        for a in range(3):
            out_dofs[e, a] = 6 * i + a
            out_dofs[e, 3 + a] = 6 * j + a
        for m in range(samples):
            xi = (m + 0.5) / samples
            w = np.array([1.0 - xi, xi])
            p = w[0] * pos[i] + w[1] * pos[j]
            s = radius - (
                n[0] * (p[0] - plane_point[0])
                + n[1] * (p[1] - plane_point[1])
                + n[2] * (p[2] - plane_point[2])
            )
            if s <= 0.0:
                continue
            n_contact += 1
            deepest = max(deepest, s)
            worst = max(worst, s / law[P_MAX_PEN])
            vc = w[0] * vel[i, :3] + w[1] * vel[j, :3] - plane_velocity
            vn = n[0] * vc[0] + n[1] * vc[1] + n[2] * vc[2]
            vt = vc - vn * n
            fn, dfn_ds, dfn_dsd = normal_force_packed(s, -vn, law)
            mw = w[0] * mass[i] + w[1] * mass[j]
            if abs(vn) > v_impact and mw > 0.0:
                out_w2[0] = max(out_w2[0], scale * dfn_ds / mw)
            if stick:
                q = e * samples + m
                # the station's tangential displacement over the step, relative to the surface
                du = p - w[0] * pos0[i] - w[1] * pos0[j] - plane_velocity * h
                du_t = du - (n[0] * du[0] + n[1] * du[1] + n[2] * du[2]) * n
                ft, u_new, _, dft_du, dft_dfn = stick_friction_packed(u_el[q], du_t, fn, h, law)
                u_el_new[q] = u_new
                dft_dp = dft_du @ proj
                dft_dvt = np.zeros((3, 3))
            else:
                ft, dft_dvt, dft_dfn = friction_force_packed(vt, fn, law)
                dft_dp = np.zeros((3, 3))
            f = scale * (fn * n + ft)
            g = n + dft_dfn
            kx = scale * (dft_dp - dfn_ds * np.outer(g, n))  # d f / d p
            kv = scale * (-dfn_dsd * np.outer(g, n) + dft_dvt @ proj)  # d f / d v_c
            for a in range(2):
                node = edges[e, a]
                for r in range(3):
                    out_f[node, r] += w[a] * f[r]
                    for b in range(2):
                        for c in range(3):
                            out_k[e, 3 * a + r, 3 * b + c] += w[a] * w[b] * kx[r, c]
                            out_c[e, 3 * a + r, 3 * b + c] += w[a] * w[b] * kv[r, c]
    return n_contact, deepest, worst


class EdgePlaneSet(ElasticSlipHistory, ContactSet):
    """Line contact of shell edges (E, 2) against one rigid plane, each edge sampled at
    ``samples`` stations (an envelope standing on its glued border); ``station_areas`` (E,):
    the area [m^2] each station of an edge carries (reference length / samples x strip width,
    :func:`flexparcel.contact.tributary.station_areas`).

    History: the stick model's elastic slip ``u_el`` (E * samples, 3) per station [m]."""

    kind = "edge_plane"

    def __init__(
        self, edges, plane: int, radius: float, samples: int, law, schedule, station_areas
    ) -> None:
        super().__init__(law, schedule)
        self.edges = np.ascontiguousarray(edges, dtype=np.int64)
        self.station_area = np.array(
            np.broadcast_to(station_areas, self.edges.shape[:1]), dtype=float
        )
        self.plane = int(plane)
        self.radius = float(radius)
        self.samples = int(samples)
        self._init_elastic_slip(self.edges.shape[0] * self.samples)

    def evaluate(self, ctx, state, out) -> None:
        m, k = ctx.model, self.plane
        ek, ec, dofs = pair_blocks(self.edges.shape[0], 6)
        n_contact, depth, ratio = edge_plane_forces(
            self.edges, m.plane_point[k], m.plane_normal[k], m.plane_velocity[k], self.radius,
            self.samples, ctx.laws[self.law_index], ctx.factors[self.schedule_index],
            self.station_area, state.positions, state.velocities, out.forces, ek, ec, dofs,
            ctx.node_mass, ctx.impact_speed, ctx.w2, self.u_el, self.u_el_trial, ctx.step,
            ctx.start.positions,
        )  # fmt: skip
        out.coupled_blocks.append((ek, ec, dofs))
        out.merge(n_contact, depth, ratio)

    def history_rows(self, numbering) -> np.ndarray:
        station = np.tile(np.arange(self.samples), self.edges.shape[0])
        ends = np.repeat(numbering[self.edges], self.samples, axis=0)
        cols = np.column_stack([ends, np.full(station.size, self.plane), station])
        return row_keys(self.kind, cols)

    def nodes(self) -> np.ndarray:
        return np.unique(self.edges)
