"""Verification of the co-rotational solid element kernels (flexparcel.elements.solid).

Patch tests, rigid-body invariance/objectivity, a cantilever against Timoshenko beam theory,
lumped mass, material tangent vs finite differences, and bad input.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from flexparcel.elements import solid as S

MAT = S.SolidMaterial(youngs_modulus=2.0e6, poisson_ratio=0.3, density=800.0)


# --------------------------------------------------------------------------- mesh helpers
def box_hex(nx, ny, nz, lx=1.0, ly=1.0, lz=1.0):
    """Structured hex8 mesh of [0,lx]x[0,ly]x[0,lz]; VTK ordering."""
    xs, ys, zs = (np.linspace(0.0, ln, n + 1) for ln, n in ((lx, nx), (ly, ny), (lz, nz)))
    pts = np.array([[x, y, z] for z in zs for y in ys for x in xs])

    def nid(i, j, k):
        return i + (nx + 1) * (j + (ny + 1) * k)

    cells = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                base = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                cells.append([nid(a, b, k) for a, b in base] + [nid(a, b, k + 1) for a, b in base])
    return pts, np.array(cells)


_BITS = {(0, 0, 0): 0, (1, 0, 0): 1, (1, 1, 0): 2, (0, 1, 0): 3}
_BITS.update({(a, b, 1): v + 4 for (a, b, _), v in list(_BITS.items())})


def _orient(pts, cells):
    """Swap nodes 1 and 2 of tets with negative volume (test helper only)."""
    p = pts[cells]
    vol = np.einsum("mi,mi->m", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    cells = cells.copy()
    cells[vol < 0, 1], cells[vol < 0, 2] = cells[vol < 0, 2], cells[vol < 0, 1].copy()
    return cells


def hex_to_tets(pts, hexes):
    """Kuhn (Freudenthal) split of every hex into 6 tets along the diagonal 0-6: conforming."""
    tets = []
    for perm in itertools.permutations(range(3)):
        v = [0, 0, 0]
        path = [_BITS[tuple(v)]]
        for ax in perm:
            v[ax] = 1
            path.append(_BITS[tuple(v)])
        tets.append(path)
    cells = hexes[:, np.array(tets)].reshape(-1, 4)
    return _orient(pts, cells)


def hex_to_wedges(hexes, axis="z"):
    """Split every hex into 2 wedges extruded along z (triangles 0-1-2 / 0-2-3 of the base), or
    along y (triangles in the x-z faces)."""
    if axis == "z":
        return hexes[:, np.array([[0, 1, 2, 4, 5, 6], [0, 2, 3, 4, 6, 7]])].reshape(-1, 6)
    # y-extrusion: front face y=0 is 0-1-5-4, back face 3-2-6-7; triangles 0-1-5 and 0-5-4
    # (right-hand normal of 0-1-5 is -y, so order the base as 0-5-1 to point towards +y)
    return hexes[:, np.array([[0, 5, 1, 3, 6, 2], [0, 4, 5, 3, 7, 6]])].reshape(-1, 6)


_HEX_FACES = [[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]]


def hex_to_pyramids(pts, hexes):
    """Split every hex into 6 pyramids (one per face) with a new apex node at its centre."""
    centres = pts[hexes].mean(axis=1)
    apex = np.arange(len(pts), len(pts) + len(hexes))
    cells = [np.column_stack([hexes[:, f], apex]) for f in _HEX_FACES]
    return np.vstack([pts, centres]), np.vstack(cells)


def assemble(pts, blocks, nodes_per_dof=3):
    """Global stiffness (CSR) from the kernel's material tangent at the reference positions.
    blocks: list of (cells, SolidReference)."""
    rows, cols, vals = [], [], []
    for cells, ref in blocks:
        m, k = cells.shape
        ke = tangents(cells, ref, pts)[3]
        dof = (3 * cells[:, :, None] + np.arange(3)).reshape(m, 3 * k)
        rows.append(np.repeat(dof, 3 * k, axis=1).ravel())
        cols.append(np.tile(dof, (1, 3 * k)).ravel())
        vals.append(ke.ravel())
    n = 3 * len(pts)
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), (n, n)
    )


def forces(cells, ref, pos, vel=None, beta=0.0):
    cells = np.ascontiguousarray(cells, dtype=np.int64)  # one numba specialisation only
    m, k = cells.shape
    vel = np.zeros_like(pos) if vel is None else vel
    fe, en, jac = np.empty((m, 3 * k)), np.empty(m), np.empty(m)
    b = np.full(m, beta)
    S.solid_forces(cells, ref.kl, ref.xref, ref.grad, b, pos, vel, fe, en, jac)
    return fe, en, jac


def tangents(cells, ref, pos, vel=None, beta=0.0):
    cells = np.ascontiguousarray(cells, dtype=np.int64)
    m, k = cells.shape
    vel = np.zeros_like(pos) if vel is None else vel
    fe, en, jac = np.empty((m, 3 * k)), np.empty(m), np.empty(m)
    ke = np.empty((m, 3 * k, 3 * k))
    b = np.full(m, beta)
    S.solid_material_tangents(cells, ref.kl, ref.xref, ref.grad, b, pos, vel, fe, en, jac, ke)
    return fe, en, jac, ke


def nodal_forces(pts, blocks, pos, vel=None, beta=0.0):
    out = np.zeros((len(pts), 3))
    for cells, ref in blocks:
        cells = np.ascontiguousarray(cells, dtype=np.int64)
        S.scatter_forces(cells, forces(cells, ref, pos, vel, beta)[0], out)
    return out


def rotation(theta):
    theta = np.asarray(theta, float)
    t = np.linalg.norm(theta)
    w = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    return np.eye(3) + np.sin(t) / t * w + (1 - np.cos(t)) / t**2 * w @ w


AMP = {"hex8": 0.25, "tet4": 0.25, "wedge6": 0.25, "pyr5": 0.1}  # pyramids are half as tall


def distorted_cube_mesh(kind, n=2, amp=None, seed=0):
    """Unit cube meshed with n^3 hexes split into `kind`; random node perturbations of up to
    amp * h (default AMP[kind]): interior nodes in all directions, boundary nodes only within
    their face planes (so the volume stays exactly 1). Returns points, cells, boundary mask."""
    pts, hexes = box_hex(n, n, n)
    if kind == "hex8":
        cells = hexes
    elif kind == "tet4":
        cells = hex_to_tets(pts, hexes)
    elif kind == "wedge6":
        cells = hex_to_wedges(hexes)
    elif kind == "pyr5":
        pts, cells = hex_to_pyramids(pts, hexes)
    amp = AMP[kind] if amp is None else amp
    rng = np.random.default_rng(seed)
    on_face = np.isclose(pts, 0.0) | np.isclose(pts, 1.0)  # (n, 3): fixed coordinate directions
    bnd = on_face.any(axis=1)
    move = rng.uniform(-1, 1, pts.shape) * amp / n
    move[on_face] = 0.0  # boundary nodes slide within their face planes
    return pts + move, cells, bnd


# --------------------------------------------------------------------------- material
def test_material_properties():
    m = S.SolidMaterial(1.0e5, 0.25, 50.0, 1e-3)
    assert m.shear_modulus == pytest.approx(4.0e4)
    assert m.lame_lambda == pytest.approx(4.0e4)
    assert m.wave_speed == pytest.approx(np.sqrt(1.2e5 / 50.0))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(youngs_modulus=0.0), r"youngs_modulus must be > 0 Pa"),
        (dict(poisson_ratio=0.5), r"poisson_ratio must be in \[0, 0.5\)"),
        (dict(poisson_ratio=-0.1), r"poisson_ratio must be in \[0, 0.5\)"),
        (dict(density=-1.0), r"density must be > 0 kg/m\^3"),
        (dict(damping_ratio=-1e-3), r"damping_ratio \(Rayleigh beta\) must be >= 0 s"),
        (dict(youngs_modulus=float("nan")), r"youngs_modulus must be finite"),
        (dict(density="heavy"), r"density must be a number"),
    ],
)
def test_material_bad_input(kwargs, match):
    args = dict(youngs_modulus=1e6, poisson_ratio=0.3, density=1e3, damping_ratio=0.0)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        S.SolidMaterial(**args)


# --------------------------------------------------------------------------- single elements
@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_reference_element_rank_and_symmetry(kind):
    """K_l is symmetric positive semi-definite with exactly the 6 rigid-body modes in its kernel
    (full integration: no hourglass modes)."""
    x = S._NODES[kind]
    ref = S.solid_reference_data(x, np.arange(len(x))[None], kind, MAT)
    kl = ref.kl[0]
    assert np.allclose(kl, kl.T, rtol=0, atol=1e-12 * np.abs(kl).max())
    ev = np.linalg.eigvalsh(kl)
    assert np.sum(ev < 1e-9 * ev.max()) == 6
    assert ev.min() > -1e-9 * ev.max()


def test_hex8_pure_bending_exact():
    """QM6 reproduces pure bending of a rectangular element: with the nodal values of the exact
    3D field u = k x z, v = -nu k y z, w = -k/2 (x^2 + nu (z^2 - y^2)) (curvature k about y,
    sigma_xx = E k z only), the condensed energy equals the exact E k^2 I_y a / 2."""
    a, b, c = 2.0, 0.7, 0.4  # element dimensions [m], centred at the origin
    pts, cells = box_hex(1, 1, 1, a, b, c)
    pts = pts - [a / 2, b / 2, c / 2]
    ref = S.solid_reference_data(pts, cells, "hex8", MAT)
    kap, nu, e = 1e-3, MAT.poisson_ratio, MAT.youngs_modulus
    x, y, z = pts.T
    u = np.column_stack([kap * x * z, -nu * kap * y * z, -0.5 * kap * (x**2 + nu * (z**2 - y**2))])
    ue = u[cells[0]].ravel()  # element-local (VTK) node order
    energy = 0.5 * ue @ ref.kl[0] @ ue
    exact = 0.5 * e * kap**2 * (b * c**3 / 12.0) * a
    assert energy == pytest.approx(exact, rel=1e-12)


# --------------------------------------------------------------------------- patch tests
def _linear_patch(pts, blocks, bnd):
    """Prescribe u = A X + b on boundary nodes, solve K u = 0 for the interior, return the max
    relative error of the interior displacements."""
    rng = np.random.default_rng(5)
    a = rng.uniform(-1e-3, 1e-3, (3, 3))
    b0 = rng.uniform(-1e-3, 1e-3, 3)
    u_exact = pts @ a.T + b0
    k = assemble(pts, blocks).toarray()
    dof_b = (3 * np.flatnonzero(bnd)[:, None] + np.arange(3)).ravel()
    dof_i = (3 * np.flatnonzero(~bnd)[:, None] + np.arange(3)).ravel()
    ui = np.linalg.solve(k[np.ix_(dof_i, dof_i)], -k[np.ix_(dof_i, dof_b)] @ u_exact.ravel()[dof_b])
    return np.abs(ui - u_exact.ravel()[dof_i]).max() / np.abs(u_exact).max()


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_patch_linear_distorted(kind):
    """Linear patch test on a distorted 3x3x3 mesh of a cube (interior nodes perturbed by up to
    25 % of the mesh size, 10 % for the pyramids, boundary nodes within their faces): the
    interior nodes reproduce the linear field to round-off.
    This requires exact completeness and int grad N dV exact, both guaranteed by the quadratures
    (module docstring), and for hex8 the zero-mean incompatible-mode gradients."""
    pts, cells, bnd = distorted_cube_mesh(kind, n=3, seed=1)
    ref = S.solid_reference_data(pts, cells, kind, MAT)
    err = _linear_patch(pts, [(cells, ref)], bnd)
    assert err < 1e-11, err


def test_patch_linear_mixed_hex_pyramid():
    """3x3x3 hexes whose middle hex is replaced by 6 pyramids: the Bedrosian pyramid is bilinear
    on its base, so it conforms to the neighbouring hex faces and the patch test passes."""
    pts, hexes = box_hex(3, 3, 3)
    rng = np.random.default_rng(3)
    inner = ~(np.isclose(pts, 0) | np.isclose(pts, 1)).any(axis=1)
    pts[inner] += rng.uniform(-0.05, 0.05, (inner.sum(), 3))
    mid = 13
    pts2, pyr = hex_to_pyramids(pts, hexes[mid : mid + 1])
    pts2[-1] += [0.03, -0.02, 0.04]
    hexes = np.delete(hexes, mid, axis=0)
    blocks = [
        (hexes, S.solid_reference_data(pts2, hexes, "hex8", MAT)),
        (pyr, S.solid_reference_data(pts2, pyr, "pyr5", MAT)),
    ]
    bnd = np.append((np.isclose(pts, 0) | np.isclose(pts, 1)).any(axis=1), False)
    assert _linear_patch(pts2, blocks, bnd) < 1e-11


def test_patch_linear_mixed_pyramid_tet():
    """A cube split into 6 pyramids around a (shifted) centre node, one pyramid split further into
    2 tets: the pyramid basis is linear on its triangular faces, so it conforms to the tets."""
    pts, hexes = box_hex(1, 1, 1)
    pts, pyr = hex_to_pyramids(pts, hexes)
    pts[-1] += [0.05, -0.08, 0.03]
    tets = _orient(pts, pyr[0][np.array([[0, 1, 2, 4], [0, 2, 3, 4]])])  # base split, same apex
    pyr = pyr[1:]
    blocks = [
        (pyr, S.solid_reference_data(pts, pyr, "pyr5", MAT)),
        (tets, S.solid_reference_data(pts, tets, "tet4", MAT)),
    ]
    bnd = np.arange(len(pts)) < 8
    assert _linear_patch(pts, blocks, bnd) < 1e-11


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_patch_corotational_homogeneous(kind):
    """Nonlinear patch test: x = Q (I + A) X + c with a large rotation Q and a 5 % general
    deformation A on all nodes. Every element then has R = Q polar(I + A), u_l linear in X, so the
    co-rotational internal forces at interior nodes cancel to round-off."""
    pts, cells, bnd = distorted_cube_mesh(kind, n=3, seed=2)
    ref = S.solid_reference_data(pts, cells, kind, MAT)
    rng = np.random.default_rng(7)
    f = rotation([0.9, -1.7, 0.6]) @ (np.eye(3) + rng.uniform(-0.05, 0.05, (3, 3)))
    pos = pts @ f.T + [3.0, -1.0, 2.0]
    out = nodal_forces(pts, [(cells, ref)], pos)
    scale = np.abs(out[bnd]).max()
    assert scale > 1e3  # the boundary carries the (large) stress resultants
    assert np.abs(out[~bnd]).max() < 1e-10 * scale


# --------------------------------------------------------------------------- invariance
def _one_element(kind, seed=4):
    """One randomly distorted element of each kind (size ~1 m)."""
    x = S._NODES[kind].copy()
    x = x + np.random.default_rng(seed).uniform(-0.1, 0.1, x.shape)
    cells = np.arange(len(x))[None]
    return x, cells, S.solid_reference_data(x, cells, kind, MAT)


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_rigid_motion_gives_zero_force(kind):
    """A large rigid rotation (2.9 rad) plus translation: zero force and energy (round-off),
    volume ratio 1; a rigid velocity field (translation + spin) gives zero damping force."""
    x, cells, ref = _one_element(kind)
    q = rotation([1.2, -2.0, 1.7])
    pos = x @ q.T + [10.0, -5.0, 3.0]
    spin = np.array([3.0, -1.0, 2.0])
    vel = np.cross(spin, pos) + [1.0, 2.0, -3.0]
    fe, en, jac = forces(cells, ref, pos, vel, beta=1e-2)
    fscale = np.abs(ref.kl[0]).max()  # force of a 1 m displacement
    assert np.abs(fe).max() < 1e-12 * fscale
    assert abs(en[0]) < 1e-24 * fscale
    assert jac[0] == pytest.approx(1.0, abs=1e-13)


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_objectivity_rotated_stretched(kind):
    """f(Q x + c) = Q f(x) for a 10 %-deformed element (stretch + shear) and any rotation Q;
    the energy is unchanged."""
    x, cells, ref = _one_element(kind)
    rng = np.random.default_rng(11)
    x1 = x @ (np.eye(3) + rng.uniform(-0.1, 0.1, (3, 3))).T + rng.uniform(-0.02, 0.02, x.shape)
    f1, e1, _ = forces(cells, ref, x1)
    q = rotation([-0.4, 2.2, 1.1])
    f2, e2, _ = forces(cells, ref, x1 @ q.T + [1.0, 2.0, 3.0])
    rotated = (f1.reshape(-1, 3) @ q.T).ravel()
    assert np.abs(f2[0] - rotated).max() < 1e-12 * np.abs(f1).max()
    assert e2[0] == pytest.approx(e1[0], rel=1e-12)
    assert np.abs(f1.reshape(-1, 3).sum(axis=0)).max() < 1e-12 * np.abs(f1).max()  # no net force


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_damping_force_is_beta_material_tangent_times_velocity(kind):
    """f(x, v) - f(x, 0) = beta K_m v exactly (C = beta R K_l R^T)."""
    x, cells, ref = _one_element(kind)
    rng = np.random.default_rng(2)
    pos = (x + rng.uniform(-0.03, 0.03, x.shape)) @ rotation([0.3, 1.0, -2.0]).T
    vel = rng.uniform(-1, 1, x.shape)
    beta = 4e-3
    f0 = forces(cells, ref, pos, beta=beta)[0][0]
    fv, _, _, ke = tangents(cells, ref, pos, vel, beta=beta)
    assert np.allclose(
        fv[0] - f0, beta * ke[0] @ vel.ravel(), rtol=0, atol=1e-12 * np.abs(f0).max()
    )


def test_polar_rotation():
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rotation(rng.uniform(-2, 2, 3))
        a = rng.uniform(-0.4, 0.4, (3, 3))
        u = np.eye(3) + 0.5 * (a + a.T)  # symmetric positive definite
        r = S.polar_rotation(q @ u)
        assert np.abs(r - q).max() < 1e-13
    # inverted F (det < 0): the closest proper rotation
    f = np.diag([1.0, 1.0, -0.1])
    r = S.polar_rotation(f)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert np.abs(r @ r.T - np.eye(3)).max() < 1e-14


# --------------------------------------------------------------------------- tangent
@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_material_tangent_vs_finite_differences(kind):
    """At a stress-free rotated state the material tangent R K_l R^T is the exact derivative of
    the force (the omitted geometric terms are proportional to the stress): central differences
    agree to ~1e-8. At a strained state (strain eps) the discrepancy is the geometric stiffness,
    O(eps) relative to |K| (measured 0.1-0.35 eps): it is below eps and halves with eps."""
    x, cells, ref = _one_element(kind)
    q = rotation([2.0, 0.5, -1.0])
    k = len(x)
    rng = np.random.default_rng(8)
    shape = rng.uniform(-1, 1, (3, 3))

    def fd_error(eps):
        pos = (x @ (np.eye(3) + eps * shape).T) @ q.T + [0.5, 0.0, 1.0]
        ke = tangents(cells, ref, pos)[3][0]
        h = 1e-6
        kfd = np.empty((3 * k, 3 * k))
        for j in range(3 * k):
            dp = np.zeros(3 * k)
            dp[j] = h
            fp = forces(cells, ref, pos + dp.reshape(k, 3))[0][0]
            fm = forces(cells, ref, pos - dp.reshape(k, 3))[0][0]
            kfd[:, j] = (fp - fm) / (2 * h)
        return np.abs(ke - kfd).max() / np.abs(ke).max()

    assert fd_error(0.0) < 1e-8
    e1, e2 = fd_error(1e-3), fd_error(5e-4)
    assert e1 < 1e-3
    assert e1 / e2 == pytest.approx(2.0, rel=0.05)


# --------------------------------------------------------------------------- mass
@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_lumped_mass_total(kind):
    """Distorted unit cube (boundary nodes slide within their faces, so V = 1 m^3 exactly): the
    lumped masses (consistent-mass row sums rho int N_a dV) are positive and sum to rho V."""
    pts, cells, _ = distorted_cube_mesh(kind, n=3, seed=9)
    ref = S.solid_reference_data(pts, cells, kind, MAT)
    assert np.all(ref.mass > 0)
    assert ref.mass.sum() == pytest.approx(MAT.density * 1.0, rel=1e-13)
    assert ref.volume.sum() == pytest.approx(1.0, rel=1e-13)
    assert np.allclose(ref.mass.sum(axis=1), MAT.density * ref.volume, rtol=1e-13)


def test_cantilever_frequencies_lumped_mass():
    """Free vibration of the 10x1x1-hex cantilever (10 x 1 x 1 m, nu = 0) with the lumped mass.

    Bending: Euler-Bernoulli f1 = 1.8751^2 / (2 pi) sqrt(E I / (rho A L^4)); shear and rotary
    inertia lower it by ~0.7 % at L/h = 10 (refinement converges to -0.67 %), the lumped-mass and
    QM6 discretisation error adds ~0.5 %: bound 2 % (measured -1.2 %).
    Axial: with nu = 0 the 1D rod is exact, f = sqrt(E / rho) / (4 L); the lumped-mass dispersion
    error of 10 linear elements is -(k h)^2 / 24 = -(pi / 20)^2 / 24 = -0.1 %: bound 0.3 %
    (measured -0.10 %)."""
    length, e, rho = 10.0, 2.0e6, 800.0
    mat = S.SolidMaterial(e, 0.0, rho)
    pts, cells = box_hex(10, 1, 1, length, 1.0, 1.0)
    ref = S.solid_reference_data(pts, cells, "hex8", mat)
    k = assemble(pts, [(cells, ref)]).toarray()
    m = np.zeros(len(pts))
    np.add.at(m, cells, ref.mass)
    free = np.ones((len(pts), 3), bool)
    free[np.isclose(pts[:, 0], 0.0)] = False
    free = free.ravel()
    minv_sqrt = 1.0 / np.sqrt(np.repeat(m, 3)[free])
    w2, modes = np.linalg.eigh(minv_sqrt[:, None] * k[np.ix_(free, free)] * minv_sqrt[None, :])
    f = np.sqrt(w2[:10]) / (2 * np.pi)
    f_bend = 1.87510407**2 / (2 * np.pi) * np.sqrt(e / 12.0 / (rho * length**4))
    assert f[0] == pytest.approx(f_bend, rel=0.02)
    assert f[1] == pytest.approx(f[0], rel=1e-10)  # square section: two equal bending modes
    x_share = (modes[0::3, :10] ** 2).sum(axis=0)  # free DOFs are node-major x, y, z
    f_axial = f[np.argmax(x_share)]
    assert f_axial == pytest.approx(np.sqrt(e / rho) / (4 * length), rel=0.003)


# --------------------------------------------------------------------------- cantilever
def _cantilever(kind, nx, ny, nz, nu=0.3, split="z"):
    """Cantilever L x b x h = 10 x 1 x 1 m clamped at x = 0 (all DOFs), uniform shear traction
    P in z on the tip face (consistent nodal forces). Returns FE tip deflection / beam theory."""
    length, b, h, p, e = 10.0, 1.0, 1.0, 1.0e3, 2.0e6
    mat = S.SolidMaterial(e, nu, 800.0)
    pts, cells = box_hex(nx, ny, nz, length, b, h)
    if kind == "tet4":
        cells = hex_to_tets(pts, cells)
    elif kind == "wedge6":
        cells = hex_to_wedges(cells, split)
    elif kind == "pyr5":
        pts, cells = hex_to_pyramids(pts, cells)
    ref = S.solid_reference_data(pts, cells, kind, mat)
    k = assemble(pts, [(cells, ref)]).tocsc()
    tip = np.flatnonzero(np.isclose(pts[:, 0], length))
    # tributary-area weights of a uniform traction on the bilinear/linear tip face grid
    wy = np.where(np.isclose(pts[tip, 1], 0) | np.isclose(pts[tip, 1], b), 0.5, 1.0) * b / ny
    wz = np.where(np.isclose(pts[tip, 2], 0) | np.isclose(pts[tip, 2], h), 0.5, 1.0) * h / nz
    w = wy * wz / (b * h)
    f = np.zeros((len(pts), 3))
    f[tip, 2] = p * w
    free = np.ones((len(pts), 3), bool)
    free[np.isclose(pts[:, 0], 0.0)] = False
    free = free.ravel()
    u = np.zeros(3 * len(pts))
    u[free] = spla.spsolve(k[free][:, free], f.ravel()[free])
    tip_w = u.reshape(-1, 3)[tip, 2] @ w
    # Timoshenko: P L^3 / (3 E I) + P L / (kappa G A), Cowper kappa = 10 (1 + nu) / (12 + 11 nu)
    inertia = b * h**3 / 12.0
    kappa = 10 * (1 + nu) / (12 + 11 * nu)
    ref_w = p * length**3 / (3 * e * inertia) + p * length / (kappa * mat.shear_modulus * b * h)
    return tip_w / ref_w


def test_cantilever_hex8_one_element_thick():
    """10x1x1 QM6 hexes (one element through the thickness) vs Timoshenko beam theory.

    Tolerance argument. nu = 0: beam theory is then the exact thin-beam limit up to end effects of
    relative size O((h/L)^2) ~ 1 % of the 1 % shear part, and QM6 represents the bending field of
    each rectangular element up to O((L_e/L)^2) of a linear moment (~0.3 % at 10 elements):
    bound 1 % (measured 10x1x1: -0.35 %, 20x2x2: -0.16 %, 40x4x4: -0.05 %).
    nu = 0.3: the fully clamped face also restrains the Poisson contraction, which makes the 3D
    solution stiffer than beam theory: refinement converges to -0.8 % (40x4x4: -0.95 %,
    80x8x8: -0.77 %); with the discretisation error: bound 2.5 % (measured 10x1x1: -1.44 %).
    For comparison, a plain trilinear hex gives -36 % at 10x1x1 (shear locking)."""
    assert abs(_cantilever("hex8", 10, 1, 1, nu=0.0) - 1.0) < 0.01
    assert abs(_cantilever("hex8", 20, 2, 2, nu=0.0) - 1.0) < 0.005
    assert abs(_cantilever("hex8", 10, 1, 1, nu=0.3) - 1.0) < 0.025


@pytest.mark.parametrize(
    ("kind", "meshes", "low"),
    [
        # constant-strain tets lock in bending: measured 0.50 (20x2x2 hexes split in 6 tets each)
        # and 0.79 (40x4x4)
        ("tet4", ((20, 2, 2), (40, 4, 4)), 0.7),
        # linear wedges, triangles in the x-y plane, linear through the thickness:
        # measured 0.87 (20x2x2 hexes split in 2) and 0.96 (40x4x4); with triangles in the
        # bending plane (extruded along y) 0.50 at 20x2x2
        ("wedge6", ((10, 1, 1), (20, 2, 2)), 0.8),
        # pyramids, 6 per hex around a centre node: measured 0.80 (20x2x2), 0.93 (40x4x4)
        ("pyr5", ((10, 1, 1), (20, 2, 2)), 0.75),
    ],
)
def test_cantilever_low_order(kind, meshes, low):
    """Low-order elements without enhancement are too stiff in bending (locking, documented):
    on the finer mesh the deflection lies between `low` and 1.0 of beam theory (they are
    stiffer than the exact solution, being displacement-based and conforming), and it grows
    with refinement."""
    coarse, fine = (_cantilever(kind, *m) for m in meshes)
    assert coarse < fine
    assert low < fine < 1.0, fine


# --------------------------------------------------------------------------- bad input
def test_bad_input():
    x = S._NODES["hex8"]
    cells = np.arange(8)[None]
    with pytest.raises(ValueError, match="unknown solid element kind 'brick'"):
        S.solid_reference_data(x, cells, "brick", MAT)
    with pytest.raises(TypeError, match="material must be a SolidMaterial"):
        S.solid_reference_data(x, cells, "hex8", object())
    with pytest.raises(ValueError, match=r"cells must have shape \(element_count, 8\)"):
        S.solid_reference_data(x, cells[:, :6], "hex8", MAT)
    with pytest.raises(ValueError, match=r"points must have shape \(node_count, 3\)"):
        S.solid_reference_data(x[:, :2], cells, "hex8", MAT)
    with pytest.raises(ValueError, match=r"element 0 \(nodes \[0, 1, 2, 3, 4, 5, 6, 8\]\) refers"):
        S.solid_reference_data(x, np.array([[0, 1, 2, 3, 4, 5, 6, 8]]), "hex8", MAT)
    with pytest.raises(ValueError, match="refers to nodes outside"):
        S.solid_reference_data(x, np.array([[0, 1, 2, 3, 4, 5, 6, -1]]), "hex8", MAT)
    with pytest.raises(ValueError, match="repeats a node id"):
        S.solid_reference_data(x, np.array([[0, 1, 2, 3, 4, 5, 6, 6]]), "hex8", MAT)
    bad = x.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="points must be finite; node 0"):
        S.solid_reference_data(bad, cells, "hex8", MAT)
    with pytest.raises(ValueError, match="integer node ids"):
        S.solid_reference_data(x, cells + 0.5, "hex8", MAT)


@pytest.mark.parametrize("kind", list(S.ELEMENT_KINDS))
def test_inverted_element_named(kind):
    """A mirrored element (wrong orientation) is rejected, naming its index and node ids."""
    pts, cells, _ = distorted_cube_mesh(kind, n=2, amp=0.0)
    cells = cells.copy()
    e = 3
    k = cells.shape[1]
    # mirror: swap the two "layers" (hex, wedge) / base orientation (pyramid) / two nodes (tet)
    perm = {8: [4, 5, 6, 7, 0, 1, 2, 3], 6: [3, 4, 5, 0, 1, 2], 5: [0, 3, 2, 1, 4], 4: [0, 2, 1, 3]}
    cells[e] = cells[e, perm[k]]
    ids = ", ".join(str(i) for i in cells[e])
    with pytest.raises(ValueError, match=rf"element {e} \(nodes \[{ids}\]\) is inverted"):
        S.solid_reference_data(pts, cells, kind, MAT)


def test_degenerate_and_badly_distorted_hex():
    """A hex collapsed to zero volume at a corner, and a hex with an inverted corner (positive
    Gauss-point Jacobians but a re-entrant vertex), are rejected."""
    x = S._NODES["hex8"].copy()
    flat = x.copy()
    flat[6] = flat[2]  # node 6 onto node 2: zero Jacobian at vertices 2 and 6
    with pytest.raises(ValueError, match=r"Jacobian determinant .* at vertex"):
        S.solid_reference_data(flat, np.arange(8)[None], "hex8", MAT)
    dent = x.copy()
    dent[6] = [0.3, 0.3, 0.3]  # pushed through the opposite corner's planes
    with pytest.raises(ValueError, match="inverted or degenerate"):
        S.solid_reference_data(dent, np.arange(8)[None], "hex8", MAT)


def test_inverted_in_motion_is_flagged():
    """An element inverted during a simulation gives vol_ratio <= 0 and finite forces."""
    x, cells, ref = _one_element("tet4")
    pos = x.copy()
    pos[3] = 2 * pos[:3].mean(axis=0) - pos[3]  # apex pushed through the base
    fe, en, jac = forces(cells, ref, pos)
    assert jac[0] < 0
    assert np.all(np.isfinite(fe)) and np.isfinite(en[0])


def test_meshio_aliases():
    x = S._NODES["tet4"]
    a = S.solid_reference_data(x, np.arange(4)[None], "tetra", MAT)
    b = S.solid_reference_data(x, np.arange(4)[None], "tet4", MAT)
    assert np.array_equal(a.kl, b.kl)
