"""Contact geometry kernels: closest points, penetrations, contact normals and their derivatives.

Pure geometry (no forces): these kernels turn positions into the kinematic quantities that the
contact law (:mod:`flexparcel.contact.law`) needs -- a penetration ``s`` [m] (``s > 0`` in
contact, ``-s`` is the gap otherwise), a unit contact normal ``n`` and the closest points -- plus
exact derivatives for consistent Newton tangents. All kernels are numba ``njit`` functions over
``float64`` arrays and can be called from other kernels. Lengths in m; normals and barycentric
coordinates dimensionless.

Conventions shared by all kernels (the same as :mod:`flexparcel.contact.planes`):

* ``s = (contact thickness) - (signed distance)``: the sum of the radii (or a shell's half
  thickness) minus the distance between the core geometries, so ``s >= 0`` means contact.
* the normal ``n`` points from the *target* (box, triangle, second segment) towards the
  *query* (point, first segment): the force on the query is ``F_N n``, on the target ``-F_N n``.
* rotations are spatial (left) spins as in :mod:`flexparcel.elements.rotations`:
  ``R <- exp(W(dtheta)) R``.
* derivative arrays are taken with respect to the stacked coordinates listed in each docstring,
  e.g. ``X = [p, a, b, c]`` (12,) for a point and a triangle; ``d(out)/dX`` has shape
  ``out.shape + (12,)``.

Kernels:

* :func:`point_box_contact`, :func:`point_box_contact_derivs` -- a point (sphere) against a
  rounded box (inner box inflated by the edge radius, :class:`flexparcel.model.rigid.RoundedBox`);
* :func:`point_triangle`, :func:`point_triangle_derivs` -- closest point on a triangle with its
  Voronoi region, signed distance;
  :func:`point_triangle_contact`, :func:`point_triangle_contact_derivs` -- node-to-face contact,
  one-sided (solid faces, rigid meshes) or two-sided (thin shells with a contact thickness);
* :func:`segment_plane` -- the deepest point of a segment (shell edge) below a plane;
* :func:`segment_segment`, :func:`segment_segment_derivs` -- closest points of two segments
  (edge-to-edge "line contact").
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from flexparcel.elements.rotations import skew

__all__ = [
    "BOX_INSIDE",
    "BOX_FACE",
    "BOX_EDGE",
    "BOX_CORNER",
    "TRI_FACE",
    "TRI_VERTEX_A",
    "TRI_VERTEX_B",
    "TRI_VERTEX_C",
    "TRI_EDGE_AB",
    "TRI_EDGE_BC",
    "TRI_EDGE_CA",
    "point_box_contact",
    "point_box_contact_derivs",
    "point_triangle",
    "point_triangle_derivs",
    "point_triangle_contact",
    "point_triangle_contact_derivs",
    "side_used",
    "segment_plane",
    "segment_segment",
    "segment_segment_derivs",
    "segment_segment_param_derivs",
]

# Region codes of point_box_contact_derivs: how many local axes are clamped to the inner box.
BOX_INSIDE = 0  # point inside (or on) the inner box: least-penetration face
BOX_FACE = 1
BOX_EDGE = 2
BOX_CORNER = 3

# Voronoi region codes of point_triangle.
TRI_FACE = 0
TRI_VERTEX_A = 1
TRI_VERTEX_B = 2
TRI_VERTEX_C = 3
TRI_EDGE_AB = 4
TRI_EDGE_BC = 5
TRI_EDGE_CA = 6


# --------------------------------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@nb.njit(cache=True)
def _cross(u, v):
    w = np.empty(3)
    w[0] = u[1] * v[2] - u[2] * v[1]
    w[1] = u[2] * v[0] - u[0] * v[2]
    w[2] = u[0] * v[1] - u[1] * v[0]
    return w


@nb.njit(cache=True)
def _pick(a, b, c, i):
    if i == 0:
        return a
    if i == 1:
        return b
    return c


@nb.njit(cache=True)
def _projskew(n, v, scale):
    """scale * (I - n n^T) W(v), shape (3, 3)."""
    w = skew(v)
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            acc = w[i, j]
            for k in range(3):
                acc -= n[i] * n[k] * w[k, j]
            out[i, j] = scale * acc
    return out


@nb.njit(cache=True)
def _clamp01(x):
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


# --------------------------------------------------------------------------------------------------
# point vs rounded box
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _point_box(p, box_center, box_rot, half_inner, radius, point_radius):
    """Shared core: (s, n, c_box, region, dist, active (3,) 0/1, local normal)."""
    q = np.empty(3)
    for i in range(3):
        q[i] = (
            box_rot[0, i] * (p[0] - box_center[0])
            + box_rot[1, i] * (p[1] - box_center[1])
            + box_rot[2, i] * (p[2] - box_center[2])
        )
    cl = np.empty(3)
    dl = np.empty(3)
    active = np.zeros(3)
    dist2 = 0.0
    nclamp = 0
    for i in range(3):
        h = half_inner[i]
        if q[i] > h:
            cl[i] = h
            active[i] = 1.0
            nclamp += 1
        elif q[i] < -h:
            cl[i] = -h
            active[i] = 1.0
            nclamp += 1
        else:
            cl[i] = q[i]
        dl[i] = q[i] - cl[i]
        dist2 += dl[i] * dl[i]
    dist = math.sqrt(dist2)
    nl = np.zeros(3)
    if dist > 0.0:
        for i in range(3):
            nl[i] = dl[i] / dist
        s = radius + point_radius - dist
        region = nclamp
    else:
        # Inside (or on) the inner box: push out through the nearest face (least penetration).
        best = np.inf
        k = 0
        sg = 1.0
        for i in range(3):
            dp = half_inner[i] - q[i]
            if dp < best:
                best = dp
                k = i
                sg = 1.0
            dm = half_inner[i] + q[i]
            if dm < best:
                best = dm
                k = i
                sg = -1.0
        nl[k] = sg
        cl[k] = sg * half_inner[k]
        for i in range(3):
            active[i] = 0.0
        s = radius + point_radius + best
        region = BOX_INSIDE
    n = np.empty(3)
    c_box = np.empty(3)
    for i in range(3):
        n[i] = box_rot[i, 0] * nl[0] + box_rot[i, 1] * nl[1] + box_rot[i, 2] * nl[2]
        c_box[i] = box_center[i] + (
            box_rot[i, 0] * cl[0] + box_rot[i, 1] * cl[1] + box_rot[i, 2] * cl[2]
        )
    return s, n, c_box, region, dist, active


@nb.njit(cache=True)
def point_box_contact(p, box_center, box_rot, half_inner, radius, point_radius):
    """Penetration of a sphere (a point with a radius) into a rounded box.

    The rounded box is its inner box (half sizes ``half_inner``) inflated by ``radius``
    (:class:`flexparcel.model.rigid.RoundedBox`). With ``q = R^T (p - box_center)`` the point in
    the box frame and ``c`` the closest point of the inner box:

    * outside the inner box (``dist = |q - c| > 0``): ``s = radius + point_radius - dist``,
      ``n = R (q - c)/dist`` -- exact for faces, rounded edges and rounded corners, and
      continuous (C0 in ``n``, C1 in ``s``) across their boundaries;
    * inside or on the inner box (deep penetration, ``dist = 0``): the *least-penetration face*:
      the face k, sign sg of the smallest depth ``h_k - sg q_k``;
      ``s = radius + point_radius + (h_k - sg q_k)``, ``n = sg R e_k``, ``c`` = the projection
      of ``q`` onto that face. ``s`` stays continuous; ``n`` jumps on the inner medial planes
      (where two faces are equally near), which a step controller should never reach.

    Args:
        p: point [m], shape (3,), world frame.
        box_center: centre of the box [m], shape (3,).
        box_rot: rotation matrix body -> world, shape (3, 3) (columns are the box axes).
        half_inner: half sizes of the inner box [m], shape (3,), >= 0.
        radius: edge radius of the box [m] >= 0.
        point_radius: radius of the point [m] >= 0 (0 for a shell node).

    Returns:
        (s [m], n (3,) outward unit normal of the box at the contact (world frame), c_box (3,)
        closest point on the inner box [m] (world)). ``s < 0``: separated by ``-s``. The contact
        point on the box surface is ``c_box + radius * n``; on the sphere ``p - point_radius n``.
    """
    s, n, c_box, _region, _dist, _active = _point_box(
        p, box_center, box_rot, half_inner, radius, point_radius
    )
    return s, n, c_box


@nb.njit(cache=True)
def point_box_contact_derivs(p, box_center, box_rot, half_inner, radius, point_radius):
    """:func:`point_box_contact` plus the derivatives for a Newton tangent.

    Derivatives (world frame; ``r = p - box_center``; box spins are spatial,
    ``R <- exp(W(dtheta)) R``, about the box centre):

    * ``ds/dp = -n`` and ``ds/d(box_center) = +n`` (not returned: trivial);
    * ``dn/dp = (R A R^T - n n^T)/dist`` where ``A = diag(axis clamped)``: zero on the flat faces
      (``A = e_k e_k^T``, ``n = R e_k``), ``(R A R^T - n n^T)/dist`` on a rounded edge (no change
      along the edge), ``(I - n n^T)/dist`` on a rounded corner; zero in the deep (inside) region;
      ``dn/d(box_center) = -dn/dp``;
    * ``ds/dtheta = r x n`` (3,);
    * ``dn/dtheta = -W(n) + (dn/dp) W(r)`` (3, 3).

    Returns:
        (s, n (3,), c_box (3,), region, dn_dp (3, 3) [1/m], ds_dtheta (3,) [m],
        dn_dtheta (3, 3) [-]); region is :data:`BOX_INSIDE`, :data:`BOX_FACE`,
        :data:`BOX_EDGE` or :data:`BOX_CORNER`.
    """
    s, n, c_box, region, dist, active = _point_box(
        p, box_center, box_rot, half_inner, radius, point_radius
    )
    dn_dp = np.zeros((3, 3))
    if region >= BOX_EDGE:
        for i in range(3):
            for j in range(3):
                ra = 0.0
                for k in range(3):
                    ra += box_rot[i, k] * active[k] * box_rot[j, k]
                dn_dp[i, j] = (ra - n[i] * n[j]) / dist
    r = np.empty(3)
    for i in range(3):
        r[i] = p[i] - box_center[i]
    ds_dtheta = _cross(r, n)
    dn_dtheta = -skew(n)
    wr = skew(r)
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                acc += dn_dp[i, k] * wr[k, j]
            dn_dtheta[i, j] += acc
    return s, n, c_box, region, dn_dp, ds_dtheta, dn_dtheta


# --------------------------------------------------------------------------------------------------
# point vs triangle
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def _closest_on_segment(p, a, b):
    """(t, closest) of p on segment a-b (t = 0 for a zero-length segment)."""
    ab = b - a
    l2 = _dot(ab, ab)
    t = 0.0
    if l2 > 0.0:
        t = _clamp01(_dot(p - a, ab) / l2)
    return t, a + t * ab


@nb.njit(cache=True)
def _tri_closest(p, a, b, c, bary):
    """Closest point on a non-degenerate triangle: fills ``bary`` (3,), returns the region.

    Voronoi-region walk of Ericson, *Real-Time Collision Detection*, Morgan Kaufmann 2005,
    section 5.1.5 (ClosestPtPointTriangle), on scalars (no temporaries)."""
    abx = b[0] - a[0]
    aby = b[1] - a[1]
    abz = b[2] - a[2]
    acx = c[0] - a[0]
    acy = c[1] - a[1]
    acz = c[2] - a[2]
    bary[0] = 0.0
    bary[1] = 0.0
    bary[2] = 0.0
    d1 = abx * (p[0] - a[0]) + aby * (p[1] - a[1]) + abz * (p[2] - a[2])
    d2 = acx * (p[0] - a[0]) + acy * (p[1] - a[1]) + acz * (p[2] - a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        bary[0] = 1.0
        return TRI_VERTEX_A
    d3 = abx * (p[0] - b[0]) + aby * (p[1] - b[1]) + abz * (p[2] - b[2])
    d4 = acx * (p[0] - b[0]) + acy * (p[1] - b[1]) + acz * (p[2] - b[2])
    if d3 >= 0.0 and d4 <= d3:
        bary[1] = 1.0
        return TRI_VERTEX_B
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        bary[0] = 1.0 - v
        bary[1] = v
        return TRI_EDGE_AB
    d5 = abx * (p[0] - c[0]) + aby * (p[1] - c[1]) + abz * (p[2] - c[2])
    d6 = acx * (p[0] - c[0]) + acy * (p[1] - c[1]) + acz * (p[2] - c[2])
    if d6 >= 0.0 and d5 <= d6:
        bary[2] = 1.0
        return TRI_VERTEX_C
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        bary[0] = 1.0 - w
        bary[2] = w
        return TRI_EDGE_CA
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        bary[1] = 1.0 - w
        bary[2] = w
        return TRI_EDGE_BC
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    bary[0] = 1.0 - v - w
    bary[1] = v
    bary[2] = w
    return TRI_FACE


@nb.njit(cache=True)
def _point_degenerate_triangle(p, a, b, c):
    """point_triangle for a zero-area triangle: the closest of its three edges."""
    # Degenerate triangle: best of its three edges.
    best = np.inf
    bary = np.zeros(3)
    closest = a.copy()
    region = TRI_EDGE_AB
    for k in range(3):
        if k == 0:
            i, j, code = 0, 1, TRI_EDGE_AB
            x0, x1 = a, b
        elif k == 1:
            i, j, code = 1, 2, TRI_EDGE_BC
            x0, x1 = b, c
        else:
            i, j, code = 2, 0, TRI_EDGE_CA
            x0, x1 = c, a
        t, x = _closest_on_segment(p, x0, x1)
        d2 = _dot(p - x, p - x)
        if d2 < best:
            best = d2
            for v in range(3):
                bary[v] = 0.0
            bary[i] = 1.0 - t
            bary[j] += t
            closest = x
            region = code
    dist = math.sqrt(best)
    normal = np.zeros(3)
    if dist > 0.0:
        normal = (p - closest) / dist
    return dist, closest, bary, normal, region


@nb.njit(cache=True)
def point_triangle(p, a, b, c):
    """Closest point of a triangle to a point, with signed distance and Voronoi region.

    The triangle's unit normal is ``n_t = (b - a) x (c - a) / |...|`` (``a, b, c``
    counter-clockwise seen from the +normal side).

    * face region (the projection of ``p`` falls inside): ``dist_signed = n_t . (p - closest)``
      and ``normal = n_t``;
    * edge and vertex regions: ``dist_signed = sg |p - closest|`` with ``sg = +1`` on the +n_t
      side of the triangle's plane (and in it), ``-1`` below, and ``normal = sg (p - closest)/|p -
      closest|`` (``n_t`` when ``p`` lies on the triangle).

    So ``p = closest + dist_signed * normal`` in every region, ``normal . n_t >= 0``, and
    ``dist_signed`` is continuous except where ``p`` crosses the triangle's plane outside the
    triangle (the sign flips there, at distance ``|p - closest| > 0``).

    A degenerate (zero-area) triangle has ``n_t = 0``; the closest point is then found on its
    edges and reported with ``region`` of that edge, ``dist_signed = +|p - closest|``.

    Args:
        p, a, b, c: point and triangle vertices [m], shape (3,) each.

    Returns:
        (dist_signed [m], closest (3,) [m], bary (3,) barycentric coordinates of ``closest``
        (sum 1, all >= 0), normal (3,) unit, region code :data:`TRI_FACE` ... :data:`TRI_EDGE_CA`).
    """
    abx = b[0] - a[0]
    aby = b[1] - a[1]
    abz = b[2] - a[2]
    acx = c[0] - a[0]
    acy = c[1] - a[1]
    acz = c[2] - a[2]
    ex = aby * acz - abz * acy
    ey = abz * acx - abx * acz
    ez = abx * acy - aby * acx
    ee = math.sqrt(ex * ex + ey * ey + ez * ez)
    if ee == 0.0:
        return _point_degenerate_triangle(p, a, b, c)
    bary = np.empty(3)
    region = _tri_closest(p, a, b, c, bary)
    closest = np.empty(3)
    normal = np.empty(3)
    normal[0] = ex / ee
    normal[1] = ey / ee
    normal[2] = ez / ee
    d2 = 0.0
    for k in range(3):
        closest[k] = bary[0] * a[k] + bary[1] * b[k] + bary[2] * c[k]
        d2 += (p[k] - closest[k]) ** 2
    if region == TRI_FACE:
        dist = (
            normal[0] * (p[0] - closest[0])
            + normal[1] * (p[1] - closest[1])
            + normal[2] * (p[2] - closest[2])
        )
        return dist, closest, bary, normal, region
    h = normal[0] * (p[0] - a[0]) + normal[1] * (p[1] - a[1]) + normal[2] * (p[2] - a[2])
    sg = 1.0 if h >= 0.0 else -1.0
    d = math.sqrt(d2)
    if d > 0.0:
        for k in range(3):
            normal[k] = sg * (p[k] - closest[k]) / d
    return sg * d, closest, bary, normal, region


@nb.njit(cache=True)
def _add_vec_grad(out, row, col0, v, scale):
    """out[row, col0:col0+3] += scale * v."""
    for k in range(3):
        out[row, col0 + k] += scale * v[k]


@nb.njit(cache=True)
def point_triangle_derivs(p, a, b, c):
    """:func:`point_triangle` plus exact derivatives with respect to ``X = [p, a, b, c]`` (12,).

    * ``d(dist_signed)/dX = [normal, -bary_a normal, -bary_b normal, -bary_c normal]`` in every
      region (envelope theorem: the distance is minimal over the triangle, so only the explicit
      dependence counts);
    * ``d(normal)/dX`` (3, 12): face region ``dn_t/dX`` (zero with respect to ``p``); edge and
      vertex regions ``sg (I - normal normal^T)/|p - closest| d(p - closest)/dX`` (zero when
      ``p`` lies on the triangle, where it is undefined);
    * ``d(bary)/dX`` (3, 12): of the projection's barycentric coordinates (face), of the edge
      parameter (edge), zero (vertex).

    Derivatives are one-sided on region boundaries and undefined for degenerate triangles
    (returned as zero, except the distance gradient).

    Returns:
        (dist_signed, closest (3,), bary (3,), normal (3,), region, ddist_dX (12,),
        dnormal_dX (3, 12) [1/m], dbary_dX (3, 12) [1/m]).
    """
    dist, closest, bary, normal, region = point_triangle(p, a, b, c)
    ddist = np.zeros(12)
    for k in range(3):
        ddist[k] = normal[k]
        for v in range(3):
            ddist[3 + 3 * v + k] = -bary[v] * normal[k]
    dn = np.zeros((3, 12))
    db = np.zeros((3, 12))
    e = _cross(b - a, c - a)
    ee2 = _dot(e, e)
    if ee2 == 0.0:
        return dist, closest, bary, normal, region, ddist, dn, db
    ee = math.sqrt(ee2)
    if region == TRI_FACE:
        # n = e/|e|, de = -W(c - a) (db - da) + W(b - a) (dc - da).
        m_b = _projskew(normal, c - a, -1.0 / ee)
        m_c = _projskew(normal, b - a, 1.0 / ee)
        for i in range(3):
            for j in range(3):
                dn[i, 6 + j] = m_b[i, j]
                dn[i, 9 + j] = m_c[i, j]
                dn[i, 3 + j] = -m_b[i, j] - m_c[i, j]
        # bary_b = ((p-a) x (c-a)).e / e.e, bary_c = ((b-a) x (p-a)).e / e.e, bary_a = 1 - rest.
        ba = b - a
        ca = c - a
        pa = p - a
        # gradient of D = e.e: 2 e.de -> d/db = 2 (c-a) x e, d/dc = 2 e x (b-a)
        gd_b = 2.0 * _cross(ca, e)
        gd_c = 2.0 * _cross(e, ba)
        for which in range(2):
            if which == 0:
                g = _cross(pa, ca)  # N = (x x y).e with x = p - a, y = c - a
                lam = bary[1]
                row = 1
                # d/dx (x = p - a): y x e ; d/dy (y = c - a): e x x
                gx = _cross(ca, e)
                gy = _cross(e, pa)
                # N's explicit gradients: p <- gx, c <- gy, a <- -(gx + gy)
                grad_p = gx
                grad_b = np.zeros(3)
                grad_c = gy.copy()
            else:
                g = _cross(ba, pa)  # x = b - a, y = p - a
                lam = bary[2]
                row = 2
                gx = _cross(pa, e)
                gy = _cross(e, ba)
                grad_p = gy
                grad_b = gx.copy()
                grad_c = np.zeros(3)
            # g.de: d/db = (c-a) x g, d/dc = g x (b-a)
            grad_b += _cross(ca, g)
            grad_c += _cross(g, ba)
            # d lam = (dN - lam dD) / D
            grad_b -= lam * gd_b
            grad_c -= lam * gd_c
            for k in range(3):
                gp = grad_p[k] / ee2
                gb = grad_b[k] / ee2
                gc = grad_c[k] / ee2
                db[row, k] = gp
                db[row, 6 + k] = gb
                db[row, 9 + k] = gc
                db[row, 3 + k] = -(gp + gb + gc)
        for j in range(12):
            db[0, j] = -db[1, j] - db[2, j]
        return dist, closest, bary, normal, region, ddist, dn, db
    # Edge and vertex regions.
    r = p - closest
    d = math.sqrt(_dot(r, r))
    if d == 0.0:
        return dist, closest, bary, normal, region, ddist, dn, db
    # d(p - closest)/dX (3, 12)
    dr = np.zeros((3, 12))
    for k in range(3):
        dr[k, k] = 1.0
    if region == TRI_VERTEX_A or region == TRI_VERTEX_B or region == TRI_VERTEX_C:
        iv = region - TRI_VERTEX_A
        for k in range(3):
            dr[k, 3 + 3 * iv + k] = -1.0
    else:
        if region == TRI_EDGE_AB:
            i0, i1 = 0, 1
        elif region == TRI_EDGE_BC:
            i0, i1 = 1, 2
        else:
            i0, i1 = 2, 0
        x0 = _pick(a, b, c, i0)
        x1 = _pick(a, b, c, i1)
        t = bary[i1]
        ll = x1 - x0
        l2 = _dot(ll, ll)
        # t = (p - x0).L / L.L
        dt = np.zeros(12)
        dt_dx1 = ((p - x0) - 2.0 * t * ll) / l2
        for k in range(3):
            dt[k] = ll[k] / l2
            dt[3 + 3 * i1 + k] = dt_dx1[k]
            dt[3 + 3 * i0 + k] = -ll[k] / l2 - dt_dx1[k]
        # closest = (1 - t) x0 + t x1 ; dclosest = (1-t) dx0 + t dx1 + L dt
        for k in range(3):
            dr[k, 3 + 3 * i0 + k] -= 1.0 - t
            dr[k, 3 + 3 * i1 + k] -= t
            for j in range(12):
                dr[k, j] -= ll[k] * dt[j]
        for j in range(12):
            db[i1, j] = dt[j]
            db[i0, j] = -dt[j]
    u = r / d
    sg = 1.0 if dist >= 0.0 else -1.0
    for i in range(3):
        for j in range(12):
            acc = dr[i, j]
            for k in range(3):
                acc -= u[i] * u[k] * dr[k, j]
            dn[i, j] = sg * acc / d
    return dist, closest, bary, normal, region, ddist, dn, db


@nb.njit(cache=True)
def side_used(side, dist, region):
    """The side (+1.0/-1.0) a contact pushes a point to: ``side`` (the remembered side, see
    :func:`point_triangle_contact`) while the point's projection falls inside the triangle
    (``region`` :data:`TRI_FACE`), else the side it is on now (sign of ``dist``).

    Outside the triangle's prism a change of side means the point went *round* the
    triangle's edge, not through it: a film wrapping round a content's edge passes below the
    plane of the top face's border triangles, at a distance |p - closest| from them, and
    counting that as a penetration of ``thickness + |p - closest|`` (17 mm on PB's wrapping film
    at 25 mm) threw its Newton iterations off. A point that does pass through a surface is in
    the face region of the triangle it crossed, which the deepest-candidate rule then picks.
    """
    if side == 0 or region != TRI_FACE:
        return 1.0 if dist >= 0.0 else -1.0
    return float(side)


@nb.njit(cache=True)
def point_triangle_contact(p, a, b, c, thickness, side):
    """Node-to-face contact of a point against a triangle with a contact thickness.

    ``s = thickness - side_used * dist_signed`` and ``n = side_used * normal`` (from
    :func:`point_triangle`): the penetration into a layer of half thickness ``thickness`` around
    the triangle on the side ``side_used``; the force on the point is ``F_N n`` and
    ``-bary_i F_N n`` on vertex i.

    * ``side = +1``: one-sided, the +n_t side (``a, b, c`` counter-clockwise seen from outside) is
      free: solid faces and rigid meshes with outward normals, ``thickness`` = the point's radius.
      Points below the face, within its prism, get ``s > thickness`` and are pushed back out
      along +n_t; outside the prism the side is the point's current one (:func:`side_used`).
    * ``side = -1``: one-sided, the other side is free.
    * ``side = 0``: two-sided thin shell: ``side_used`` is the side ``p`` is on now (``+1`` in the
      plane), ``thickness`` = half the shell's contact thickness plus the point's radius; points
      within ``+-thickness`` of either face are in contact. A point that has passed through the
      mid-surface is pushed out of the *wrong* side: callers that track history pass the
      remembered side (+1/-1) instead of 0.

    Args:
        p, a, b, c: [m], shape (3,); thickness [m] >= 0; side: -1, 0 or +1.

    Returns:
        (s [m], closest (3,), bary (3,), n (3,), region, side_used (+1.0 or -1.0)).
    """
    dist, closest, bary, normal, region = point_triangle(p, a, b, c)
    sd = side_used(side, dist, region)
    return thickness - sd * dist, closest, bary, sd * normal, region, sd


@nb.njit(cache=True)
def point_triangle_contact_derivs(p, a, b, c, thickness, side):
    """:func:`point_triangle_contact` plus ``ds/dX`` (12,), ``dn/dX`` (3, 12) and ``dbary/dX``
    (3, 12) with ``X = [p, a, b, c]``: ``ds/dX = -side_used d(dist)/dX``,
    ``dn/dX = side_used d(normal)/dX`` (see :func:`point_triangle_derivs`).

    Returns:
        (s, closest (3,), bary (3,), n (3,), region, side_used, ds_dX (12,), dn_dX (3, 12),
        dbary_dX (3, 12)).
    """
    dist, closest, bary, normal, region, ddist, dnorm, dbary = point_triangle_derivs(p, a, b, c)
    sd = side_used(side, dist, region)
    return (
        thickness - sd * dist,
        closest,
        bary,
        sd * normal,
        region,
        sd,
        -sd * ddist,
        sd * dnorm,
        dbary,
    )


# --------------------------------------------------------------------------------------------------
# segments
# --------------------------------------------------------------------------------------------------


@nb.njit(cache=True)
def segment_plane(p0, p1, plane_point, normal, radius):
    """Deepest point of a segment (a capsule of radius ``radius``) against a half-space.

    Heights above the plane ``h_i = normal . (p_i - plane_point)`` (``normal`` unit, pointing out
    of the solid side). A segment's height is linear in its parameter, so the deepest point is an
    end point: ``s = radius - min(h_0, h_1)`` at ``t = 0`` (``h_0 < h_1``), ``t = 1``
    (``h_1 < h_0``) or ``t = 0.5`` when the segment is parallel to the plane (``|h_0 - h_1| <=
    1e-12 |p1 - p0|``: the whole segment is equally deep; line contact). The contact point is
    ``p0 + t (p1 - p0)``.
    Derivatives: ``ds/dp0 = -(1 - t) normal``, ``ds/dp1 = -t normal``.

    Args:
        p0, p1: segment end points [m], shape (3,); plane_point [m] (3,); normal (3,) unit;
        radius [m] >= 0.

    Returns:
        (s [m], t [-] in [0, 1]).
    """
    h0 = (
        normal[0] * (p0[0] - plane_point[0])
        + normal[1] * (p0[1] - plane_point[1])
        + normal[2] * (p0[2] - plane_point[2])
    )
    h1 = (
        normal[0] * (p1[0] - plane_point[0])
        + normal[1] * (p1[1] - plane_point[1])
        + normal[2] * (p1[2] - plane_point[2])
    )
    dx = p1[0] - p0[0]
    dy = p1[1] - p0[1]
    dz = p1[2] - p0[2]
    tol = 1e-12 * math.sqrt(dx * dx + dy * dy + dz * dz)
    if h0 < h1 - tol:
        return radius - h0, 0.0
    if h1 < h0 - tol:
        return radius - h1, 1.0
    return radius - min(h0, h1), 0.5


@nb.njit(cache=True)
def _segment_segment_params(p0, p1, q0, q1):
    """(s, t, parallel) of the closest points of segments p0-p1 and q0-q1.

    Ericson, *Real-Time Collision Detection* (2005), section 5.1.9, with overlapping parallel
    segments resolved to the middle of their overlap (instead of an arbitrary end)."""
    d1 = p1 - p0
    d2 = q1 - q0
    r = p0 - q0
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    f = _dot(d2, r)
    if a == 0.0 and e == 0.0:
        return 0.0, 0.0, True
    if a == 0.0:
        return 0.0, _clamp01(f / e), True
    c = _dot(d1, r)
    if e == 0.0:
        return _clamp01(-c / a), 0.0, True
    b = _dot(d1, d2)
    den = a * e - b * b
    if den > 1e-14 * a * e:
        s = _clamp01((b * f - c * e) / den)
        parallel = False
    else:
        # Parallel: parameters on p of the projections of q0, q1; the middle of the overlap.
        sq0 = -c / a
        sq1 = (b - c) / a
        lo = max(0.0, min(sq0, sq1))
        hi = min(1.0, max(sq0, sq1))
        if lo <= hi:
            s = 0.5 * (lo + hi)
        else:
            s = _clamp01(0.5 * (sq0 + sq1))
        parallel = True
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = _clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = _clamp01((b - c) / a)
    return s, t, parallel


@nb.njit(cache=True)
def _any_perp(d):
    """A unit vector perpendicular to d (e_z for d = 0)."""
    ax = abs(d[0])
    ay = abs(d[1])
    az = abs(d[2])
    e = np.zeros(3)
    if ax <= ay and ax <= az:
        e[0] = 1.0
    elif ay <= az:
        e[1] = 1.0
    else:
        e[2] = 1.0
    w = _cross(d, e)
    nw = math.sqrt(_dot(w, w))
    if nw == 0.0:
        w[0] = 0.0
        w[1] = 0.0
        w[2] = 1.0
        return w
    return w / nw


@nb.njit(cache=True)
def segment_segment(p0, p1, q0, q1):
    """Closest points of two segments (edge-to-edge line contact).

    Args:
        p0, p1: first segment [m], shape (3,); q0, q1: second segment [m], shape (3,).

    Returns:
        (s [-], t [-], dist [m], n (3,)): parameters of the closest points ``x_p = p0 + s (p1 -
        p0)`` and ``x_q = q0 + t (q1 - q0)``, both in [0, 1]; their distance; the unit vector
        ``n = (x_p - x_q)/dist`` from the second segment towards the first (the push direction of
        the first). For capsules of radii r_p, r_q the penetration is ``r_p + r_q - dist``.
        Intersecting segments (``dist = 0``) get ``n`` along ``(p1 - p0) x (q1 - q0)`` (any unit
        vector perpendicular to the segments if that vanishes). Parallel overlapping segments
        have no unique closest pair; the middle of the overlap is used.
    """
    s, t, _parallel = _segment_segment_params(p0, p1, q0, q1)
    xp = p0 + s * (p1 - p0)
    xq = q0 + t * (q1 - q0)
    r = xp - xq
    dist = math.sqrt(_dot(r, r))
    if dist > 0.0:
        return s, t, dist, r / dist
    w = _cross(p1 - p0, q1 - q0)
    nw = math.sqrt(_dot(w, w))
    if nw > 0.0:
        return s, t, 0.0, w / nw
    d = p1 - p0
    if _dot(d, d) == 0.0:
        d = q1 - q0
    return s, t, 0.0, _any_perp(d)


@nb.njit(cache=True)
def segment_segment_derivs(p0, p1, q0, q1):
    """:func:`segment_segment` plus derivatives with respect to ``X = [p0, p1, q0, q1]`` (12,).

    * ``d(dist)/dX = [(1 - s) n, s n, -(1 - t) n, -t n]`` (envelope theorem);
    * ``dn/dX = (I - n n^T)/dist d(x_p - x_q)/dX`` (3, 12), with ``ds``, ``dt`` from the implicit
      differentiation of the stationarity conditions ``(x_p - x_q) . (p1 - p0) = 0`` (interior
      ``s``) and ``(x_p - x_q) . (q1 - q0) = 0`` (interior ``t``); a parameter at 0 or 1 is held
      fixed. For parallel segments (no unique closest pair) ``s`` is held fixed. Zero when
      ``dist = 0``.

    Returns:
        (s, t, dist, n (3,), ddist_dX (12,), dn_dX (3, 12) [1/m]).
    """
    s, t, dist, n, dd, dn, _, _ = segment_segment_param_derivs(p0, p1, q0, q1)
    return s, t, dist, n, dd, dn


@nb.njit(cache=True)
def segment_segment_param_derivs(p0, p1, q0, q1):
    """:func:`segment_segment_derivs` plus the derivatives of the closest points' parameters,
    ``ds/dX`` and ``dt/dX`` (12,) [1/m] (zero for a parameter held at 0 or 1, and for
    ``s`` of parallel segments), which move a contact force between a segment's nodes.

    Returns:
        (s, t, dist, n (3,), ddist_dX (12,), dn_dX (3, 12), ds_dX (12,), dt_dX (12,)).
    """
    s, t, dist, n = segment_segment(p0, p1, q0, q1)
    _s, _t, parallel = _segment_segment_params(p0, p1, q0, q1)
    dd = np.zeros(12)
    for k in range(3):
        dd[k] = (1.0 - s) * n[k]
        dd[3 + k] = s * n[k]
        dd[6 + k] = -(1.0 - t) * n[k]
        dd[9 + k] = -t * n[k]
    dn = np.zeros((3, 12))
    ds = np.zeros(12)
    dt = np.zeros(12)
    if dist == 0.0:
        return s, t, dist, n, dd, dn, ds, dt
    d1 = p1 - p0
    d2 = q1 - q0
    r = dist * n
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    b = _dot(d1, d2)
    # J = d(x_p - x_q)/dX at fixed (s, t)
    jac = np.zeros((3, 12))
    for k in range(3):
        jac[k, k] = 1.0 - s
        jac[k, 3 + k] = s
        jac[k, 6 + k] = -(1.0 - t)
        jac[k, 9 + k] = -t
    # R1 = d1 . J + r . d(d1)/dX ; R2 = d2 . J + r . d(d2)/dX
    r1 = np.zeros(12)
    r2 = np.zeros(12)
    for k in range(3):
        r1[k] = (1.0 - s) * d1[k] - r[k]
        r1[3 + k] = s * d1[k] + r[k]
        r1[6 + k] = -(1.0 - t) * d1[k]
        r1[9 + k] = -t * d1[k]
        r2[k] = (1.0 - s) * d2[k]
        r2[3 + k] = s * d2[k]
        r2[6 + k] = -(1.0 - t) * d2[k] - r[k]
        r2[9 + k] = -t * d2[k] + r[k]
    s_free = (0.0 < s < 1.0) and a > 0.0 and not parallel
    t_free = (0.0 < t < 1.0) and e > 0.0
    if s_free and t_free:
        # [a, -b; b, -e] [ds; dt] = -[R1; R2]
        det = -a * e + b * b
        for j in range(12):
            ds[j] = (e * r1[j] - b * r2[j]) / det
            dt[j] = (b * r1[j] - a * r2[j]) / det
    elif s_free:
        for j in range(12):
            ds[j] = -r1[j] / a
    elif t_free:
        for j in range(12):
            dt[j] = r2[j] / e
    for i in range(3):
        for j in range(12):
            jac[i, j] += d1[i] * ds[j] - d2[i] * dt[j]
    for i in range(3):
        for j in range(12):
            acc = jac[i, j]
            for k in range(3):
                acc -= n[i] * n[k] * jac[k, j]
            dn[i, j] = acc / dist
    return s, t, dist, n, dd, dn, ds, dt
