"""Contact geometry kernels and the broad phase: closed forms, continuity, finite differences,
brute-force references.

Tolerances: closed forms and exact references agree to round-off (1e-12 relative to the lengths,
which are O(0.1 m)). Central finite differences with step eps = 1e-6 m have a truncation error
O(eps^2 * curvature^3) ~ 1e-10 here and a round-off error O(1e-16 * |f| / eps) ~ 1e-10, so
derivatives are checked to 1e-6 (absolute, relative to O(1..10 /m) entries); FD points are placed
away from region boundaries (>= 1e-3 m) so that no FD stencil crosses one.
"""

from __future__ import annotations

import numpy as np
import pytest

from flexparcel.contact import broadphase as bp
from flexparcel.contact import geometry as geo
from flexparcel.elements.rotations import rotation_exp

RNG_SEED = 1234
EPS = 1e-6
FD_TOL = 1e-6


def _rot(theta):
    return rotation_exp(np.asarray(theta, float))


def _fd(fun, x, eps=EPS):
    """Central differences of fun (returning an array) with respect to vector x: shape
    fun.shape + x.shape."""
    x = np.asarray(x, float)
    f0 = np.asarray(fun(x))
    out = np.zeros(f0.shape + x.shape)
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = eps
        out[..., k] = (np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * eps)
    return out


# --------------------------------------------------------------------------------------------------
# point vs rounded box
# --------------------------------------------------------------------------------------------------

POSES = [
    (np.zeros(3), np.zeros(3)),
    (np.array([0.1, -0.2, 0.3]), np.array([0.3, -0.7, 1.1])),
    (np.array([-1.0, 0.5, 2.0]), np.array([2.0, 0.4, -0.9])),
]
H = np.array([0.12, 0.08, 0.05])  # inner half sizes [m]
R_BOX = 0.01  # edge radius [m]
R_PT = 0.002  # point radius [m]


def _box(q_local, pose):
    """World point for a local point, and the box's (centre, rotation)."""
    c, th = pose
    rot = _rot(th)
    return c + rot @ np.asarray(q_local, float), c, rot


@pytest.mark.parametrize("pose", POSES)
def test_point_box_closed_forms(pose):
    c, th = pose
    rot = _rot(th)
    cases = [
        # (local point, expected distance to the inner box, expected local normal, region)
        ((H[0] + 0.004, 0.3 * H[1], -0.2 * H[2]), 0.004, (1, 0, 0), geo.BOX_FACE),
        ((0.1 * H[0], -H[1] - 0.011, 0.0), 0.011, (0, -1, 0), geo.BOX_FACE),
        ((H[0] + 0.003, H[1] + 0.004, 0.2 * H[2]), 0.005, (0.6, 0.8, 0), geo.BOX_EDGE),
        ((-0.5 * H[0], H[1] + 0.006, -H[2] - 0.008), 0.01, (0, 0.6, -0.8), geo.BOX_EDGE),
        (
            (-H[0] - 0.002, -H[1] - 0.003, H[2] + 0.006),
            0.007,
            (-2 / 7, -3 / 7, 6 / 7),
            geo.BOX_CORNER,
        ),
    ]
    for q, dist, nl, region in cases:
        p = c + rot @ np.asarray(q, float)
        s, n, cb = geo.point_box_contact(p, c, rot, H, R_BOX, R_PT)
        s2, n2, cb2, reg, *_ = geo.point_box_contact_derivs(p, c, rot, H, R_BOX, R_PT)
        assert s == pytest.approx(R_BOX + R_PT - dist, abs=1e-13)
        np.testing.assert_allclose(n, rot @ np.asarray(nl, float), atol=1e-13)
        # closest point: p - dist * n lies on the inner box
        np.testing.assert_allclose(cb, p - dist * n, atol=1e-13)
        assert reg == region
        assert s2 == s and np.array_equal(n2, n) and np.array_equal(cb2, cb)
    # deep penetration: inside the inner box, least-penetration face (z, depth 0.01)
    q = np.array([0.02, -0.01, H[2] - 0.01])
    p = c + rot @ q
    s, n, cb = geo.point_box_contact(p, c, rot, H, R_BOX, R_PT)
    assert s == pytest.approx(R_BOX + R_PT + 0.01, abs=1e-13)
    np.testing.assert_allclose(n, rot[:, 2], atol=1e-13)
    np.testing.assert_allclose(cb, c + rot @ np.array([0.02, -0.01, H[2]]), atol=1e-13)
    q = np.array([-H[0] + 0.001, 0.03, 0.0])  # nearest face -x
    s, n, _ = geo.point_box_contact(c + rot @ q, c, rot, H, R_BOX, R_PT)
    assert s == pytest.approx(R_BOX + R_PT + 0.001, abs=1e-13)
    np.testing.assert_allclose(n, -rot[:, 0], atol=1e-13)


def test_point_box_matches_rounded_box_geometry():
    """s agrees with a brute-force distance to a densely sampled inner-box surface."""
    rng = np.random.default_rng(RNG_SEED)
    c, th = POSES[1]
    rot = _rot(th)
    g = np.linspace(-1, 1, 41)
    u, v = np.meshgrid(g, g, indexing="ij")
    u, v = u.ravel(), v.ravel()
    surf = []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        for sg in (-1, 1):
            pts = np.zeros((u.size, 3))
            pts[:, k] = sg * H[k]
            pts[:, i] = u * H[i]
            pts[:, j] = v * H[j]
            surf.append(pts)
    surf = np.concatenate(surf) @ rot.T + c
    for _ in range(50):
        q = rng.uniform(-1.6, 1.6, 3) * H
        if np.all(np.abs(q) <= H):
            continue
        p = c + rot @ q
        s, n, cb = geo.point_box_contact(p, c, rot, H, R_BOX, R_PT)
        d_ref = np.min(np.linalg.norm(surf - p, axis=1))
        # grid spacing 0.05 * H <= 6 mm: the sampled distance overestimates by < spacing
        assert R_BOX + R_PT - s <= d_ref + 1e-12
        assert R_BOX + R_PT - s >= d_ref - 0.05 * H.max() * 1.5


def test_point_box_continuity_across_regions():
    c, th = POSES[2]
    rot = _rot(th)
    # paths in the local frame crossing face -> edge -> corner and inside -> outside
    paths = [
        (np.array([H[0] + 0.003, 0.0, 0.2 * H[2]]), np.array([0.0, 2.0 * H[1], 0.0])),
        (np.array([H[0] + 0.003, H[1] + 0.002, 0.0]), np.array([0.0, 0.0, 2.0 * H[2]])),
        (np.array([H[0] - 0.004, 0.01, 0.0]), np.array([0.01, 0.0, 0.0])),
    ]
    for q0, dq in paths:
        t = np.linspace(0.0, 1.0, 2001)
        s_all, n_all, reg_all = [], [], []
        for ti in t:
            p = c + rot @ (q0 + ti * dq)
            s, n, _, reg, *_ = geo.point_box_contact_derivs(p, c, rot, H, R_BOX, R_PT)
            s_all.append(s)
            n_all.append(n)
            reg_all.append(reg)
        s_all = np.array(s_all)
        n_all = np.array(n_all)
        assert len(set(reg_all)) >= 2  # the path does cross a region boundary
        step = np.linalg.norm(dq) / (t.size - 1)
        # s is 1-Lipschitz in p; n changes by at most step / dist (dist >= 2 mm here)
        assert np.max(np.abs(np.diff(s_all))) <= step * (1 + 1e-9)
        assert np.max(np.linalg.norm(np.diff(n_all, axis=0), axis=1)) <= step / 0.002 + 1e-12


@pytest.mark.parametrize(
    "q",
    [
        (H[0] + 0.004, 0.3 * H[1], -0.2 * H[2]),  # face
        (H[0] + 0.003, -H[1] - 0.004, 0.2 * H[2]),  # edge
        (-H[0] - 0.002, -H[1] - 0.003, H[2] + 0.006),  # corner
        (0.02, -0.01, H[2] - 0.01),  # inside
    ],
)
def test_point_box_derivatives_fd(q):
    c, th = POSES[1]
    rot = _rot(th)
    p = c + rot @ np.asarray(q, float)
    s, n, _, _, dn_dp, ds_dth, dn_dth = geo.point_box_contact_derivs(p, c, rot, H, R_BOX, R_PT)

    def f_p(x):
        s_, n_, _ = geo.point_box_contact(x, c, rot, H, R_BOX, R_PT)
        return np.r_[s_, n_]

    def f_c(x):
        s_, n_, _ = geo.point_box_contact(p, x, rot, H, R_BOX, R_PT)
        return np.r_[s_, n_]

    def f_th(dth):
        s_, n_, _ = geo.point_box_contact(p, c, _rot(dth) @ rot, H, R_BOX, R_PT)
        return np.r_[s_, n_]

    jp = _fd(f_p, p)
    np.testing.assert_allclose(jp[0], -n, atol=FD_TOL)
    np.testing.assert_allclose(jp[1:], dn_dp, atol=FD_TOL)
    jc = _fd(f_c, c)
    np.testing.assert_allclose(jc[0], n, atol=FD_TOL)
    np.testing.assert_allclose(jc[1:], -dn_dp, atol=FD_TOL)
    jt = _fd(f_th, np.zeros(3))
    np.testing.assert_allclose(jt[0], ds_dth, atol=FD_TOL)
    np.testing.assert_allclose(jt[1:], dn_dth, atol=FD_TOL)


# --------------------------------------------------------------------------------------------------
# point vs triangle
# --------------------------------------------------------------------------------------------------

TRI = (np.array([0.0, 0.0, 0.0]), np.array([0.1, 0.01, 0.0]), np.array([0.03, 0.08, 0.0]))


def _posed_triangle(rot, shift):
    return tuple(rot @ v + shift for v in TRI)


def _region_points(a, b, c, z):
    """One point per Voronoi region (code -> point), at height z off the plane."""
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    g = (a + b + c) / 3
    pts = {geo.TRI_FACE: g + 0.2 * (a - g) + z * n}
    for code, v in ((geo.TRI_VERTEX_A, a), (geo.TRI_VERTEX_B, b), (geo.TRI_VERTEX_C, c)):
        pts[code] = v + 0.3 * (v - g) + z * n
    for code, (u, w, o) in (
        (geo.TRI_EDGE_AB, (a, b, c)),
        (geo.TRI_EDGE_BC, (b, c, a)),
        (geo.TRI_EDGE_CA, (c, a, b)),
    ):
        e = w - u
        out = np.cross(e, n)
        out /= np.linalg.norm(out)
        if np.dot(out, o - u) > 0:
            out = -out
        pts[code] = u + 0.4 * e + 0.02 * out + z * n
    return pts


def _brute_triangle(p, a, b, c, m=300):
    """Distance to a triangle by a barycentric grid (m + 1 points per edge), then refined by
    exact projection onto the best grid point's neighbourhood is unnecessary: the grid bound is
    used as the tolerance."""
    i, j = np.meshgrid(np.arange(m + 1), np.arange(m + 1), indexing="ij")
    keep = i + j <= m
    u = i[keep] / m
    v = j[keep] / m
    x = a + u[:, None] * (b - a) + v[:, None] * (c - a)
    d = np.linalg.norm(x - p, axis=1)
    k = np.argmin(d)
    return d[k], x[k]


@pytest.mark.parametrize("pose", POSES)
@pytest.mark.parametrize("z", [0.015, -0.007, 0.0])
def test_point_triangle_regions_vs_brute_force(pose, z):
    rot = _rot(pose[1])
    a, b, c = _posed_triangle(rot, pose[0])
    n_t = np.cross(b - a, c - a)
    n_t /= np.linalg.norm(n_t)
    spacing = np.linalg.norm(b - a) / 300 * 2  # grid resolution bound on the distance error
    for code, p in _region_points(a, b, c, z).items():
        dist, cl, bary, normal, region = geo.point_triangle(p, a, b, c)
        assert region == code
        d_ref, x_ref = _brute_triangle(p, a, b, c)
        assert abs(dist) <= d_ref + 1e-13
        assert abs(dist) >= d_ref - spacing
        np.testing.assert_allclose(cl, x_ref, atol=spacing)
        np.testing.assert_allclose(cl, bary @ np.array([a, b, c]), atol=1e-14)
        assert bary.min() >= 0.0 and bary.sum() == pytest.approx(1.0, abs=1e-14)
        np.testing.assert_allclose(p, cl + dist * normal, atol=1e-14)
        assert np.linalg.norm(normal) == pytest.approx(1.0, abs=1e-14)
        assert np.dot(normal, n_t) >= -1e-14
        if code == geo.TRI_FACE:
            assert dist == pytest.approx(z, abs=1e-14)
            np.testing.assert_allclose(normal, n_t, atol=1e-14)
        elif z != 0.0:
            assert np.sign(dist) == np.sign(z)


def test_point_triangle_random_vs_brute_force():
    rng = np.random.default_rng(RNG_SEED)
    seen = set()
    for _ in range(60):
        a, b, c = rng.uniform(-0.05, 0.05, (3, 3))
        p = rng.uniform(-0.08, 0.08, 3)
        dist, cl, bary, normal, region = geo.point_triangle(p, a, b, c)
        seen.add(region)
        d_ref, _ = _brute_triangle(p, a, b, c, m=200)
        scale = max(np.linalg.norm(b - a), np.linalg.norm(c - a))
        assert abs(dist) <= d_ref + 1e-13
        assert abs(dist) >= d_ref - 2 * scale / 200
    assert len(seen) == 7


def test_point_triangle_degenerate():
    a = np.zeros(3)
    b = np.array([1.0, 0.0, 0.0])
    c = np.array([2.0, 0.0, 0.0])  # collinear
    p = np.array([1.5, 0.3, 0.4])
    dist, cl, bary, normal, region = geo.point_triangle(p, a, b, c)
    assert dist == pytest.approx(0.5)
    np.testing.assert_allclose(cl, [1.5, 0, 0])
    np.testing.assert_allclose(normal, [0, 0.6, 0.8])
    np.testing.assert_allclose(bary @ np.array([a, b, c]), cl)


@pytest.mark.parametrize("z", [0.012, -0.009])
def test_point_triangle_derivatives_fd(z):
    rot = _rot(POSES[2][1])
    a, b, c = _posed_triangle(rot, POSES[2][0])
    for code, p in _region_points(a, b, c, z).items():
        x0 = np.concatenate([p, a, b, c])
        out = geo.point_triangle_derivs(p, a, b, c)
        dist, _, bary, normal, region, ddist, dn, dbary = out
        assert region == code

        def f(x, code=code):
            d_, _, b_, n_, r_ = geo.point_triangle(x[:3], x[3:6], x[6:9], x[9:])
            assert r_ == code  # the stencil stays in the region
            return np.r_[d_, n_, b_]

        j = _fd(f, x0)
        np.testing.assert_allclose(j[0], ddist, atol=FD_TOL)
        np.testing.assert_allclose(j[1:4], dn, atol=FD_TOL * 10)
        np.testing.assert_allclose(j[4:7], dbary, atol=FD_TOL * 10)
        # translation invariance of all three
        for arr in (ddist[None], dn, dbary):
            np.testing.assert_allclose(arr.reshape(arr.shape[0], 4, 3).sum(axis=1), 0, atol=1e-9)


def test_point_triangle_contact_sides():
    a, b, c = TRI  # normal +z
    h = 0.003
    above = np.array([0.03, 0.02, 0.001])
    below = np.array([0.03, 0.02, -0.001])
    far_below = np.array([0.03, 0.02, -0.02])
    # one-sided (+1): above within h -> s = h - z; below -> s > h, pushed up
    s, _, _, n, _, sd = geo.point_triangle_contact(above, a, b, c, h, 1)
    assert s == pytest.approx(0.002) and n[2] == 1.0 and sd == 1.0
    s, _, _, n, _, _ = geo.point_triangle_contact(far_below, a, b, c, h, 1)
    assert s == pytest.approx(0.023) and n[2] == 1.0
    # one-sided (-1): mirror image
    s, _, _, n, _, _ = geo.point_triangle_contact(below, a, b, c, h, -1)
    assert s == pytest.approx(0.002) and n[2] == -1.0
    s, _, _, n, _, _ = geo.point_triangle_contact(above, a, b, c, h, -1)
    assert s == pytest.approx(0.004) and n[2] == -1.0
    # two-sided: either side, pushed away from the mid-surface; out of reach far below
    s, _, _, n, _, sd = geo.point_triangle_contact(above, a, b, c, h, 0)
    assert s == pytest.approx(0.002) and n[2] == 1.0 and sd == 1.0
    s, _, _, n, _, sd = geo.point_triangle_contact(below, a, b, c, h, 0)
    assert s == pytest.approx(0.002) and n[2] == -1.0 and sd == -1.0
    s, *_ = geo.point_triangle_contact(far_below, a, b, c, h, 0)
    assert s == pytest.approx(h - 0.02)
    # two-sided beside an edge: the point is pushed away from the edge, within reach
    beside = np.array([0.05, -0.002, -0.001])
    s, cl, _, n, region, sd = geo.point_triangle_contact(beside, a, b, c, h, 0)
    assert region == geo.TRI_EDGE_AB and sd == -1.0
    assert s == pytest.approx(h - np.linalg.norm(beside - cl))
    np.testing.assert_allclose(beside, cl + (h - s) * n, atol=1e-15)
    # a remembered side holds only within the triangle's prism: a point that went round the
    # edge to below the plane (a film wrapping a content's border) is 2.2 mm from the edge,
    # not 2.2 mm + h deep, and is pushed away from the edge like the two-sided case
    for side in (1, -1):
        s, cl, _, n, region, sd = geo.point_triangle_contact(beside, a, b, c, h, side)
        assert region == geo.TRI_EDGE_AB and sd == -1.0
        assert s == pytest.approx(h - np.linalg.norm(beside - cl))
        assert n @ (beside - cl) > 0
    round_edge = np.array([0.05, -0.01, -0.02])  # 22 mm from the edge: out of reach
    assert geo.point_triangle_contact(round_edge, a, b, c, h, 1)[0] < 0
    # derivatives: ds = -side d(dist)
    for side in (-1, 0, 1):
        for p in (above, below, beside):
            out = geo.point_triangle_contact_derivs(p, a, b, c, h, side)
            ref = geo.point_triangle_derivs(p, a, b, c)
            sd = out[5]
            np.testing.assert_array_equal(out[6], -sd * ref[5])
            np.testing.assert_array_equal(out[7], sd * ref[6])
            x0 = np.concatenate([p, a, b, c])
            j = _fd(
                lambda x, side=side: geo.point_triangle_contact(
                    x[:3], x[3:6], x[6:9], x[9:], h, side
                )[0],
                x0,
            )
            np.testing.assert_allclose(j, out[6], atol=FD_TOL)


# --------------------------------------------------------------------------------------------------
# segments
# --------------------------------------------------------------------------------------------------


def test_segment_plane():
    n = np.array([0.0, 0.6, 0.8])
    x0 = np.array([0.1, 0.2, 0.3])
    tang = np.array([1.0, 0.0, 0.0])
    tang2 = np.array([0.0, 0.8, -0.6])
    p0 = x0 + 0.05 * tang - 0.002 * n
    p1 = x0 - 0.05 * tang2 + 0.001 * n
    s, t = geo.segment_plane(p0, p1, x0, n, 0.003)
    assert s == pytest.approx(0.005) and t == 0.0
    s, t = geo.segment_plane(p1, p0, x0, n, 0.003)
    assert s == pytest.approx(0.005) and t == 1.0
    q1 = p0 + 0.07 * tang2  # parallel to the plane
    s, t = geo.segment_plane(p0, q1, x0, n, 0.003)
    assert s == pytest.approx(0.005) and t == 0.5
    s, t = geo.segment_plane(p0 + 0.01 * n, p1 + 0.01 * n, x0, n, 0.0)
    assert s == pytest.approx(-0.008)


def _brute_segments(p0, p1, q0, q1, m=400):
    g = np.linspace(0, 1, m + 1)
    xp = p0 + g[:, None] * (p1 - p0)
    xq = q0 + g[:, None] * (q1 - q0)
    d = np.linalg.norm(xp[:, None, :] - xq[None, :, :], axis=2)
    return d.min()


def test_segment_segment_vs_brute_force():
    rng = np.random.default_rng(RNG_SEED)
    cases = [rng.uniform(-0.05, 0.05, (4, 3)) for _ in range(30)]
    d = np.array([0.04, 0.01, 0.0])
    off = np.array([0.0, 0.0, 0.01])
    cases += [
        np.array([[0, 0, 0], d, 0.5 * d + off, 1.5 * d + off]),  # parallel, overlapping
        np.array([[0, 0, 0], d, 2 * d + off, 3 * d + off]),  # parallel, disjoint
        np.array([[0, 0, 0], [0.02, 0, 0], [0.01, -0.01, 0], [0.01, 0.01, 0]]),  # crossing
        np.array([[0, 0, 0], [0.0, 0, 0], [0.01, -0.01, 0.02], [0.01, 0.01, 0.0]]),  # point
    ]
    for p0, p1, q0, q1 in cases:
        s, t, dist, n = geo.segment_segment(p0, p1, q0, q1)
        assert 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0
        xp = p0 + s * (p1 - p0)
        xq = q0 + t * (q1 - q0)
        assert dist == pytest.approx(np.linalg.norm(xp - xq), abs=1e-15)
        assert np.linalg.norm(n) == pytest.approx(1.0)
        if dist > 0:
            np.testing.assert_allclose(xp - xq, dist * n, atol=1e-15)
        ref = _brute_segments(p0, p1, q0, q1)
        scale = np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0)
        assert dist <= ref + 1e-13
        assert dist >= ref - scale / 400
    # parallel overlap: middle of the overlap [0.5, 1] on p
    s, t, dist, n = geo.segment_segment(*cases[30])
    assert s == pytest.approx(0.75) and t == pytest.approx(0.25)
    assert dist == pytest.approx(0.01)
    np.testing.assert_allclose(n, [0, 0, -1], atol=1e-14)
    # crossing: dist 0, n along the cross product of the directions
    s, t, dist, n = geo.segment_segment(*cases[32])
    assert dist == 0.0 and s == pytest.approx(0.5) and t == pytest.approx(0.5)
    np.testing.assert_allclose(np.abs(n), [0, 0, 1])


def test_segment_segment_derivatives_fd():
    cases = [
        # interior / interior
        np.array([[0, 0, 0], [0.04, 0.01, 0.0], [0.01, -0.02, 0.01], [0.025, 0.03, 0.015]]),
        # s clamped at 1, t interior
        np.array([[0, 0, 0], [0.01, 0.0, 0.0], [0.03, -0.02, 0.01], [0.025, 0.03, 0.005]]),
        # t clamped at 0, s interior
        np.array([[0, 0, 0], [0.04, 0.0, 0.0], [0.02, 0.01, 0.01], [0.025, 0.03, 0.02]]),
        # both clamped (end points)
        np.array([[0, 0, 0], [0.01, 0.0, 0.0], [0.03, 0.01, 0.01], [0.05, 0.03, 0.02]]),
    ]
    for p0, p1, q0, q1 in cases:
        x0 = np.concatenate([p0, p1, q0, q1]).astype(float)
        s, t, dist, n, dd, dn = geo.segment_segment_derivs(*x0.reshape(4, 3))

        def f(x):
            s_, t_, d_, n_ = geo.segment_segment(*x.reshape(4, 3))
            return np.r_[d_, n_]

        j = _fd(f, x0)
        np.testing.assert_allclose(j[0], dd, atol=FD_TOL)
        np.testing.assert_allclose(j[1:], dn, atol=FD_TOL * 10)


# --------------------------------------------------------------------------------------------------
# broad phase
# --------------------------------------------------------------------------------------------------


def _random_mesh(rng, nx, ny, size=1.0, amp=0.05):
    """A wavy triangulated sheet (n, 3) positions, (M, 3) triangles, and its quad edges."""
    x, y = np.meshgrid(np.linspace(0, size, nx), np.linspace(0, size, ny), indexing="ij")
    z = amp * np.sin(7 * x) * np.cos(5 * y)
    pos = np.c_[x.ravel(), y.ravel(), z.ravel()] + rng.normal(0, size / nx * 0.05, (nx * ny, 3))
    idx = np.arange(nx * ny).reshape(nx, ny)
    a = idx[:-1, :-1].ravel()
    b = idx[1:, :-1].ravel()
    c = idx[1:, 1:].ravel()
    d = idx[:-1, 1:].ravel()
    tris = np.r_[np.c_[a, b, c], np.c_[a, c, d]]
    segs = np.r_[np.c_[a, b], np.c_[a, d], np.c_[a, c]]
    return pos, tris, segs


def _pairs_set(p):
    return set(map(tuple, p.tolist()))


def test_broadphase_points_vs_brute_force_and_distance():
    rng = np.random.default_rng(RNG_SEED)
    pos, tris, _ = _random_mesh(rng, 25, 20)
    # foreign points around the sheet, plus the sheet's own nodes (self contact)
    foreign = rng.uniform([-0.1, -0.1, -0.2], [1.1, 1.1, 0.2], (800, 3))
    pts = np.r_[foreign, pos]
    node = np.r_[np.full(len(foreign), -1), np.arange(len(pos))]
    radii = rng.uniform(0.0, 0.01, len(pts))
    margin = 0.02
    pairs = bp.point_triangle_candidates(pts, radii, tris, pos, margin, point_node=node)
    lo, hi = bp.triangle_bounds(tris, pos)
    ref = bp.brute_force_pairs(pts, radii, node.reshape(-1, 1), lo, hi, tris, margin)
    assert len(pairs) > 1000
    np.testing.assert_array_equal(pairs, ref)  # same set, same (sorted) order
    # no pair where the point is a vertex of the triangle
    for i, j in pairs:
        assert node[i] not in tris[j]
    # conservative: every pair within r + margin (true distance) is a candidate. The true
    # distance is >= the Euclidean distance to the triangle's AABB, so only pairs with an AABB
    # distance <= r + margin need the exact kernel.
    got = _pairs_set(pairs)
    checked = 0
    for i in rng.choice(len(pts), 300, replace=False):
        gap = np.maximum(np.maximum(lo - pts[i], pts[i] - hi), 0.0)
        for j in np.nonzero(np.linalg.norm(gap, axis=1) <= radii[i] + margin)[0]:
            if node[i] in tris[j]:
                continue
            d, *_ = geo.point_triangle(pts[i], *pos[tris[j]])
            if abs(d) <= radii[i] + margin:
                assert (i, j) in got
                checked += 1
    assert checked > 100
    # cell size does not change the result
    for h in (0.01, 0.3, 5.0):
        p2 = bp.point_triangle_candidates(pts, radii, tris, pos, margin, node, cell_size=h)
        np.testing.assert_array_equal(p2, ref)


def test_broadphase_segments_vs_brute_force():
    rng = np.random.default_rng(RNG_SEED + 1)
    pos, tris, segs = _random_mesh(rng, 15, 12)
    margin = 0.1  # > the sheet's spacing (0.07 x 0.09 m): reaches the neighbours' neighbours
    r = 0.002
    pairs = bp.segment_triangle_candidates(segs, r, tris, pos, margin)
    a, b = pos[segs[:, 0]], pos[segs[:, 1]]
    mid = 0.5 * (a + b)
    rad = 0.5 * np.linalg.norm(b - a, axis=1) + r
    lo, hi = bp.triangle_bounds(tris, pos)
    ref = bp.brute_force_pairs(mid, rad, segs, lo, hi, tris, margin)
    np.testing.assert_array_equal(pairs, ref)
    for i, j in pairs:
        assert not set(segs[i]) & set(tris[j])
    # conservative w.r.t. points sampled on the segments (AABB prefilter as above)
    got = _pairs_set(pairs)
    checked = 0
    for i in rng.choice(len(segs), 60, replace=False):
        for u in (0.0, 0.3, 0.7, 1.0):
            x = a[i] + u * (b[i] - a[i])
            gap = np.maximum(np.maximum(lo - x, x - hi), 0.0)
            for j in np.nonzero(np.linalg.norm(gap, axis=1) <= r + margin)[0]:
                if set(segs[i]) & set(tris[j]):
                    continue
                d, *_ = geo.point_triangle(x, *pos[tris[j]])
                if abs(d) <= r + margin:
                    assert (i, j) in got
                    checked += 1
    assert checked > 50
    # edge-edge self contact
    pairs = bp.segment_segment_candidates(segs, r, segs, pos, margin, unique=True)
    lo, hi = bp.segment_bounds(segs, pos)
    ref = bp.brute_force_pairs(mid, rad, segs, lo, hi, segs, margin)
    ref = ref[ref[:, 0] < ref[:, 1]]
    np.testing.assert_array_equal(pairs, ref)
    got = _pairs_set(pairs)
    checked = 0
    for i in rng.choice(len(segs), 60, replace=False):
        gap = np.maximum(np.maximum(lo - a[i], a[i] - hi), 0.0)
        near = np.linalg.norm(gap, axis=1) <= r + margin + np.linalg.norm(b[i] - a[i])
        for j in np.nonzero(near)[0]:
            if j == i or set(segs[i]) & set(segs[j]):
                continue
            _, _, d, _ = geo.segment_segment(a[i], b[i], a[j], b[j])
            if d <= r + margin:
                assert (min(i, j), max(i, j)) in got
                checked += 1
    assert checked > 50


def test_broadphase_edge_cases():
    pos = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    tris = np.array([[0, 1, 2]])
    assert bp.point_triangle_candidates(np.zeros((0, 3)), 0.0, tris, pos, 0.1).shape == (0, 2)
    assert bp.point_triangle_candidates(pos, 0.0, np.zeros((0, 3), int), pos, 0.1).shape == (0, 2)
    far = np.array([[10.0, 10, 10]])
    assert bp.point_triangle_candidates(far, 0.0, tris, pos, 0.1).shape == (0, 2)
    # the triangle's own vertices are excluded, a point just above it is not
    pts = np.r_[pos, [[0.2, 0.2, 0.05]]]
    pairs = bp.point_triangle_candidates(pts, 0.0, tris, pos, 0.1, point_node=[0, 1, 2, -1])
    np.testing.assert_array_equal(pairs, [[3, 0]])
    # exactly at the reach (closed interval), and just beyond
    pts = np.array([[0.5, 0.2, 0.75], [0.5, 0.2, 0.75 + 1e-9]])
    pairs = bp.point_triangle_candidates(pts, 0.25, tris, pos, 0.5)
    np.testing.assert_array_equal(pairs, [[0, 0]])
    with pytest.raises(ValueError, match="margin"):
        bp.point_triangle_candidates(pts, 0.0, tris, pos, -1.0)
    with pytest.raises(ValueError, match="radii"):
        bp.point_triangle_candidates(pts, [-1.0, 0.0], tris, pos, 0.1)
    with pytest.raises(ValueError, match="tris"):
        bp.point_triangle_candidates(pts, 0.0, [[0, 1, 3]], pos, 0.1)
    with pytest.raises(ValueError, match="points"):
        bp.point_triangle_candidates(np.zeros((2, 2)), 0.0, tris, pos, 0.1)
