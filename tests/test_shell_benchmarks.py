"""Linear shell benchmarks of the flat OPT + DKT triangle (docs/shell-verification.md).

Element-level properties of the OPT membrane (Felippa 2003, CMAME 192:2125) and the standard
benchmarks of MacNeal & Harder (1985, Finite Elements in Analysis and Design 1:3-20) and Cook's
membrane, each through the public model-building API (flexparcel.verification). Every case is
solved as a linear problem (load scaled to 1e-5 of the model size, see
verification.LINEAR_SPAN), so the references are the linear solutions.
"""

import numpy as np
import pytest

from flexparcel import verification
from flexparcel.elements import shell


def _random_triangles(count, seed=3):
    """Counter-clockwise triangles in local centroidal coordinates, shapes from slender to fat."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        p = rng.uniform(-1.0, 1.0, (3, 2))
        two_a = (p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[2, 0] - p[0, 0]) * (
            p[1, 1] - p[0, 1]
        )
        if abs(two_a) < 0.05:
            continue
        if two_a < 0:
            p = p[[0, 2, 1]]
        out.append(p - p.mean(axis=0))
    return out


def _linear_field(xy, grad, omega):
    """Local DOFs (18,) of u = grad @ [x, y] (in-plane) with every corner's drilling rotation
    equal to ``omega``."""
    d = np.zeros(18)
    for i in range(3):
        d[6 * i : 6 * i + 2] = grad @ xy[i]
        d[6 * i + 5] = omega
    return d


# --------------------------------------------------------------------------- element level
@pytest.mark.parametrize("nu", [0.0, 0.3, 1.0 / 3.0, 0.49])
def test_exactly_six_rigid_body_modes(nu):
    # 18 local DOFs, 6 rigid motions (3 translations, 3 rotations); every other mode strains the
    # element. Eigenvalues relative to the largest: zero modes at round-off (< 1e-12), the
    # smallest deformation mode is bending, ~ (t/L)^2 = 1e-2 of the membrane modes (> 1e-6).
    for xy in _random_triangles(6):
        k = shell.local_stiffness(xy, 1.0, nu, 0.1)
        assert np.abs(k - k.T).max() <= 1e-14 * np.abs(k).max()
        ev = np.linalg.eigvalsh(k) / np.abs(k).max()
        assert np.all(np.abs(ev[:6]) < 1e-12), ev[:7]
        assert ev[6] > 1e-6, ev[:7]


def test_rigid_in_plane_rotation_is_force_free():
    # u = -w y, v = w x, theta_z = w: a rigid rotation about the normal; the OPT basic strain
    # and the deviatoric rotations theta_i - theta_0 both vanish, so the force is round-off.
    for xy in _random_triangles(6):
        k = shell.local_stiffness(xy, 2.0e9, 0.3, 1e-3)
        d = _linear_field(xy, np.array([[0.0, -0.7], [0.7, 0.0]]), 0.7)
        assert np.abs(k @ d).max() <= 1e-14 * np.abs(k).max()


def test_constant_strain_fields_see_only_the_basic_stiffness():
    # Any linear displacement field with theta_z = its rotation (v,x - u,y)/2 at every corner is
    # a constant-strain state. The higher-order stiffness acts on the deviatoric rotations only
    # (Felippa 2003), which vanish here, and the basic stiffness's rotation columns sum to zero
    # for equal corner rotations; so the element stores exactly the constant-strain energy
    # V eps^T D eps and its corner forces are the CST's, A t B^T sigma. (Its drilling moments
    # are the basic stiffness's lumping of sigma to the corners; they cancel between
    # neighbours, which the patch test in test_shell_verification checks.) Round-off: 1e-12.
    e, nu, t = 1.0, 0.25, 0.2
    iso = e / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    rng = np.random.default_rng(5)
    for xy in _random_triangles(6):
        grad = rng.standard_normal((2, 2))
        d = _linear_field(xy, grad, 0.5 * (grad[1, 0] - grad[0, 1]))
        eps = np.array([grad[0, 0], grad[1, 1], grad[0, 1] + grad[1, 0]])
        sig = iso @ eps
        x, y = xy[:, 0], xy[:, 1]
        b = np.array([y[1] - y[2], y[2] - y[0], y[0] - y[1]])
        c = np.array([x[2] - x[1], x[0] - x[2], x[1] - x[0]])
        area = 0.5 * (b[0] * c[1] - b[1] * c[0])
        f_cst = np.zeros(18)
        for i in range(3):
            f_cst[6 * i] = 0.5 * t * (b[i] * sig[0] + c[i] * sig[2])
            f_cst[6 * i + 1] = 0.5 * t * (c[i] * sig[1] + b[i] * sig[2])
        f = shell.local_stiffness(xy, e, nu, t) @ d
        assert 0.5 * d @ f == pytest.approx(0.5 * area * t * eps @ sig, rel=1e-12)
        transl = np.array([[6 * i, 6 * i + 1] for i in range(3)]).ravel()
        np.testing.assert_allclose(f[transl], f_cst[transl], atol=1e-12 * np.abs(f_cst).max())


@pytest.mark.parametrize("nu", [0.0, 0.3])
@pytest.mark.parametrize("aspect", [0.2, 1.0, 5.0])
def test_opt_is_exact_in_in_plane_pure_bending_of_rectangles(aspect, nu):
    # The design property of OPT (Felippa 2003): a rectangle a x b made of two triangles, with
    # the nodal values of the exact plane-stress pure-bending field u = -k x y,
    # v = k (x^2 + nu y^2)/2, theta_z = k x, stores the exact energy E I k^2 a / 2 for any
    # aspect ratio a/b and either diagonal; the CST stores 3 to 40 times that (locking).
    # Exactness up to round-off: tolerance 1e-10.
    a, b, kap, e, t = aspect, 1.0, 1.0, 1.0, 1.0
    corners = np.array([[0, 0], [a, 0], [a, b], [0, b]], float) - [a / 2, b / 2]
    exact = 0.5 * e * (t * b**3 / 12.0) * kap**2 * a
    for split in ([(0, 1, 2), (0, 2, 3)], [(0, 1, 3), (1, 2, 3)]):
        energy = 0.0
        for tri in split:
            xy = corners[list(tri)]
            side = (xy[1] - xy[0]) / np.linalg.norm(xy[1] - xy[0])
            rot = np.column_stack([side, [-side[1], side[0]]])  # element frame: e1 along 1-2
            xy_loc = (xy - xy.mean(axis=0)) @ rot
            d = np.zeros(18)
            for i, (x, y) in enumerate(xy):
                d[6 * i : 6 * i + 2] = rot.T @ [-kap * x * y, 0.5 * kap * (x * x + nu * y * y)]
                d[6 * i + 5] = kap * x
            energy += 0.5 * d @ shell.local_stiffness(xy_loc, e, nu, t) @ d
        assert energy == pytest.approx(exact, rel=1e-10)


def test_opt_beta0():
    # beta_0 = (1 - 4 nu^2)/2 (Felippa 2003), floored at 0.01 (nu -> 1/2).
    assert shell.opt_beta0(0.0) == 0.5
    assert shell.opt_beta0(0.3) == pytest.approx(0.32)
    assert shell.opt_beta0(0.5) == 0.01


# --------------------------------------------------------------------------- benchmarks
def _values(rows):
    return np.array([r["value"] for r in rows])


@pytest.fixture(scope="module")
def cook():
    return [verification.cook_membrane(n) for n in (4, 8, 16)]


def test_cook_membrane_converges_within_two_percent(cook):
    # Reference 23.96: vertical displacement of the mid-point (48, 52) of the loaded edge
    # (converged value, e.g. Felippa 2003). OPT is stable and passes the patch test, so it
    # converges; with a smooth solution at O(h^2) in energy, slowed by the stress singularity at
    # the clamped top corner (0, 44). Checks: monotone convergence from below on 4, 8, 16 (the
    # coarse meshes are too stiff), successive differences shrinking by more than the
    # first-order factor 2, and the 16x16 mesh within 2 %.
    v = _values(cook)
    assert np.all(np.diff(v) > 0.0) and v[-1] < 23.96 * 1.005, v
    d = np.diff(v)
    assert d[0] / d[1] > 2.0, v
    assert abs(cook[-1]["rel_err"]) <= 0.02, cook[-1]
    # the top corner moves more than the mid-point (the loaded edge rotates): about 25.2
    assert cook[-1]["corner"] > v[-1]


@pytest.mark.parametrize("direction", ["in-plane", "out-of-plane"])
def test_macneal_harder_straight_cantilever(direction):
    # MacNeal & Harder (1985): length 6, width 0.2, t = 0.1, E = 1e7, nu = 0.3, unit tip
    # shear; tip deflection 0.1081 in-plane, 0.4321 out-of-plane (beam theory with shear
    # deformation). 6x1 mesh of 1 x 0.2 rectangles (aspect ratio 5).
    # In-plane: OPT is exact in pure in-plane bending of rectangles of any aspect ratio
    # (test_opt_is_exact_in_in_plane_pure_bending_of_rectangles), so only the linear variation
    # of the moment along each element and the shear deformation (0.1 % of the deflection) are
    # approximated: within 5 % (the MacNeal-Harder goal; the CST gives 3 % of the reference).
    # Out-of-plane: DKT, cubic deflection along the strip up to the Kirchhoff constraints at
    # the 1 x 0.2 elements' mid-sides: within 5 %.
    r = verification.macneal_cantilever(direction, 6, 1)
    assert abs(r["rel_err"]) <= 0.05, r


@pytest.fixture(scope="module")
def scordelis():
    return [verification.scordelis_lo_roof(n) for n in (8, 16, 24)]


def test_scordelis_lo_roof(scordelis):
    # MacNeal & Harder (1985): mid-side deflection of the free edge 0.3024 (0.3086 is the
    # deep-shell value; the difference, 2 %, bounds how closely a reference can be claimed).
    # The membrane-bending (flat facet) discretisation converges at O(h^2): the change from
    # 16 to 24 must be smaller than that from 8 to 16 by more than the first-order factor 3
    # ((1/8 - 1/16) / (1/16 - 1/24)); and the 24x24 full roof within 2 % of 0.3024.
    v = _values(scordelis)
    d = np.abs(np.diff(v))
    assert d[0] / d[1] > 3.0, v
    assert abs(scordelis[-1]["rel_err"]) <= 0.02, scordelis[-1]


@pytest.fixture(scope="module")
def pinched():
    return [verification.pinched_cylinder(n) for n in (4, 8, 16)]


def test_pinched_cylinder_converges(pinched):
    # MacNeal & Harder (1985): radial displacement under the load 1.8248e-5. A point load on a
    # thin cylinder (R/t = 100) is a membrane-bending problem with a local boundary layer of
    # width ~ sqrt(R t) = 30, about one element of a 16x16 octant (elements 29 around, 19
    # along): flat facets converge slowly. Trend: monotone from below on 4, 8, 16, the
    # differences shrinking by more than the first-order factor 2. The finest mesh is checked
    # in the slow suite.
    v = _values(pinched)
    assert np.all(np.diff(v) > 0.0), v
    d = np.diff(v)
    assert d[0] / d[1] > 2.0, v
    assert abs(pinched[-1]["rel_err"]) <= 0.05, pinched[-1]


@pytest.mark.slow
def test_fine_meshes():
    # Cook 32x32: the differences shrink by > 2 per halving (test above), so the 32x32 error is
    # below half the 16x16 one: within 1 %.
    assert abs(verification.cook_membrane(32)["rel_err"]) <= 0.01
    # Scordelis-Lo 32x32: within 2 %, and the change 24 -> 32 smaller than 16 -> 24 by more
    # than the first-order factor 2 ((1/16 - 1/24) / (1/24 - 1/32)).
    v16, v24, v32 = (verification.scordelis_lo_roof(n) for n in (16, 24, 32))
    assert abs(v32["rel_err"]) <= 0.02
    assert abs(v24["value"] - v16["value"]) > 2.0 * abs(v32["value"] - v24["value"])
    # Pinched cylinder 24x24 and 32x32 octants: the 32x32 mesh spans the load's boundary layer
    # sqrt(R t) = 30 with 2 elements around and 3 along; with O(h^2) convergence the change
    # 24 -> 32 (required below 0.5 %) bounds the remaining discretisation error to about the
    # same size, and the reference is an analytical series solution of the same (Kirchhoff)
    # shell theory: within 1 %.
    p24, p32 = (verification.pinched_cylinder(n) for n in (24, 32))
    assert abs(p32["value"] / p24["value"] - 1.0) <= 5e-3
    assert abs(p32["rel_err"]) <= 0.01


# --------------------------------------------------------------------------- verify command
def test_verify_table_prints_the_benchmarks(capsys):
    from flexparcel.cli import build_parser

    args = build_parser().parse_args(["verify", "--table"])
    assert args.table and not args.fine
    rows = verification.shell_benchmarks({"cook": (4,), "macneal": ((6, 1),)})
    table = verification.benchmark_table(rows)
    lines = table.splitlines()
    assert lines[0].startswith("| case | mesh |") and len(lines) == 2 + 3
    assert "Cook's membrane | 4x4 |" in lines[2] and "MacNeal-Harder" in lines[3]
