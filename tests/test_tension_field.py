"""The tension-field (wrinkling) membrane law of the shell: the law against its closed forms,
homogeneous strain states of a meshed sheet against tension-field theory, and its tangents
against finite differences.

References: Roddeman, Drukker, Oomens & Janssen (1987), "The wrinkling of thin membranes",
J. Appl. Mech. 54:884 (taut / wrinkled / slack states; in a wrinkled isotropic membrane the
stress is uniaxial along the major principal strain, sigma_1 = E e_1); Mansfield (1989), "The
bending and stretching of plates", ch. 10 and Wagner's tension field: a membrane in simple shear
gamma is wrinkled at 45 degrees and carries the shear stress E gamma / 4, whatever nu, against
G gamma = E gamma / (2 (1 + nu)) when it may take compression.
"""

import numpy as np
import pytest

from conftest import fd_wrt_nodes
from flexparcel.builder import ModelBuilder
from flexparcel.elements import shell
from flexparcel.elements.rotations import rotation_exp
from flexparcel.integrate import assembly as asm
from flexparcel.model.materials import ShellMaterial

E, NU, T = 2.0e8, 0.3, 1e-3
VD = E / (1 - NU**2) * np.array([[1, NU, 0], [NU, 1, 0], [0, 0, (1 - NU) / 2]])  # V = 1


def _law(eps):
    return shell._tension_field(np.asarray(eps, float), VD)


@pytest.mark.parametrize(
    "eps, state",
    [
        ((1e-3, 2e-4, 3e-4), "taut"),
        ((1e-3, -5e-4, 2e-4), "wrinkled"),
        ((0.0, 0.0, 2e-3), "wrinkled"),
        ((-1e-3, -2e-4, 1e-4), "slack"),
    ],
)
def test_law_states_and_stress_is_the_energy_gradient(eps, state):
    sig, w = _law(eps)
    el = VD @ np.asarray(eps)
    if state == "taut":
        assert np.allclose(sig, el, rtol=1e-14) and w == pytest.approx(0.5 * el @ eps, rel=1e-14)
    elif state == "slack":
        assert np.all(sig == 0.0) and w == 0.0
    else:  # uniaxial tension along the major principal strain: sigma = E e1 n1 n1^T
        exx, eyy, gxy = eps
        e1 = 0.5 * (exx + eyy) + np.hypot(0.5 * (exx - eyy), 0.5 * gxy)
        phi = 0.5 * np.arctan2(gxy, exx - eyy)
        n = np.array([np.cos(phi), np.sin(phi)])
        ref = E * e1 * np.array([n[0] ** 2, n[1] ** 2, n[0] * n[1]])
        assert np.allclose(sig, ref, rtol=1e-12, atol=1e-12 * E * e1)
        assert w == pytest.approx(0.5 * E * e1**2, rel=1e-12)
        # principal stresses: E e1 and 0 (no compression)
        s = np.array([[sig[0], sig[2]], [sig[2], sig[1]]])
        assert np.linalg.eigvalsh(s) == pytest.approx([0.0, E * e1], abs=1e-9 * E * e1)
    # sigma = dW/d eps (engineering shear conjugate to tau), central differences
    h = 1e-9
    grad = [(_law(np.add(eps, h * np.eye(3)[i]))[1] - _law(np.add(eps, -h * np.eye(3)[i]))[1])
            / (2 * h) for i in range(3)]  # fmt: skip
    assert np.allclose(grad, sig, rtol=1e-5, atol=1e-6 * np.abs(el).max())


def test_law_is_continuous_across_the_taut_boundary():
    # on e2 = -nu e1 the minor principal stress of the elastic law is zero: both branches give
    # sigma = E e1 along x and the same energy E e1^2 / 2
    e1 = 1e-3
    for d in (-1e-12, 1e-12):  # just wrinkled, just taut
        sig, w = _law((e1, -NU * e1 + d, 0.0))
        assert sig == pytest.approx([E * e1, 0.0, 0.0], abs=1e-6 * E * e1)
        assert w == pytest.approx(0.5 * E * e1**2, rel=1e-6)


def _sheet(membrane, n=4, size=0.1):
    b = ModelBuilder()
    g = np.linspace(0.0, size, n + 1)
    xx, yy = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    idx = np.arange(pts.shape[0]).reshape(n + 1, n + 1)
    quads = np.column_stack(
        [idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()]
    )
    b.add_shell_mesh(pts, quads, material=ShellMaterial(E, NU, 1000.0, T, 0.0, membrane))
    return b.finalize(), pts


def _edge_traction(membrane, displacement):
    """Force per length [N/m] on the x = size edge of a square sheet under the homogeneous
    in-plane displacement field ``displacement(X, Y) -> (u, v)`` (every node moved, so the
    interior nodes balance and the edge nodes carry the boundary traction)."""
    model, pts = _sheet(membrane)
    u = np.array([displacement(x, y) for x, y, _ in pts])
    pos = pts + np.column_stack([u, np.zeros(len(pts))])
    rot = np.repeat(np.eye(3)[None], len(pts), axis=0)
    f, _ = asm.internal_forces(model, pos, rot, np.zeros((len(pts), 6)))
    inner = (pts[:, 0] > 1e-9) & (pts[:, 0] < 0.1 - 1e-9) & (pts[:, 1] > 1e-9)
    inner &= pts[:, 1] < 0.1 - 1e-9
    # homogeneous: interior nodes balance, to the round-off of 1e-7 m displacements on 0.1 m
    assert np.abs(f[inner, :2]).max() < 1e-7 * E * T * np.abs(u).max()
    edge = pts[:, 0] > 0.1 - 1e-9
    return f[edge, :2].sum(axis=0) / 0.1


def test_sheet_in_simple_shear_carries_the_wagner_tension_field():
    # pure shear gamma (u = gamma y / 2, v = gamma x / 2, no rigid rotation, so the nodes'
    # drilling rotations stay 0): principal strains +-gamma/2 at 45 degrees, e2 + nu e1 < 0,
    # wrinkled; shear flow E t gamma / 4 (Wagner), elastic G t gamma. The co-rotated small
    # strain is exact to O(gamma) relative: gamma = 1e-6 for rel 1e-5
    gamma = 1e-6

    def pure_shear(x, y):
        return 0.5 * gamma * y, 0.5 * gamma * x

    tf = _edge_traction("tension-field", pure_shear)
    el = _edge_traction("elastic", pure_shear)
    g = E / (2 * (1 + NU))
    assert el[1] == pytest.approx(g * T * gamma, rel=1e-5)
    assert tf[1] == pytest.approx(E * T * gamma / 4, rel=1e-5)
    assert tf[0] == pytest.approx(E * T * gamma / 4, rel=1e-5)  # sigma_xx = E e1 / 2 too


def test_sheet_takes_tension_and_no_compression():
    eps = 1e-6  # exact to O(eps) relative, as above

    def stretch(x, y):
        return eps * x, 0.0

    def squeeze(x, y):
        return -eps * x, 0.0

    def tension_lateral_squeeze(x, y):  # e_y = -eps: beyond Poisson's -nu eps, wrinkled
        return eps * x, -eps * y

    tf = _edge_traction("tension-field", stretch)
    full = E / (1 - NU**2) * T * eps
    assert tf[0] == pytest.approx(full, rel=1e-5)  # taut: elastic, laterally held
    assert np.abs(_edge_traction("tension-field", squeeze)).max() < 1e-6 * full  # slack
    assert _edge_traction("elastic", squeeze)[0] == pytest.approx(-full, rel=1e-5)
    assert _edge_traction("tension-field", tension_lateral_squeeze)[0] == pytest.approx(
        E * T * eps, rel=1e-5
    )  # wrinkled along y: uniaxial sigma_x = E e_x


def _triangle(seed, strain):
    rng = np.random.default_rng(seed)
    x0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.3, 0.8, 0.0]])
    frames, xloc = shell.reference_frames(x0, np.array([[0, 1, 2]]))
    kl = shell.local_stiffness(xloc[0], E, NU, T)[None]
    tfm = shell.tension_field_data(xloc[0], E, NU, T)[None]
    f = np.eye(3)
    f[:2, :2] += strain  # in-plane stretch, then a rigid turn and small noise
    rot0 = rotation_exp(np.array([0.3, -0.2, 0.5]))
    x = (x0 @ f.T) @ rot0.T + 1e-5 * rng.standard_normal((3, 3))
    rot = np.array([rotation_exp(1e-4 * rng.standard_normal(3)) @ rot0 for _ in range(3)])
    return frames, xloc, kl, tfm, x, rot


@pytest.mark.parametrize(
    "strain", [np.diag([2e-3, 1e-3]), np.diag([2e-3, -2e-3]), np.diag([-1e-3, -2e-3])],
    ids=["taut", "wrinkled", "slack"],
)  # fmt: skip
def test_tension_field_tangents_match_finite_differences(strain):
    frames, xloc, kl, tfm, x, rot = _triangle(0, strain)
    tris = np.array([[0, 1, 2]])
    beta = np.array([0.0])
    zero = np.zeros((3, 6))
    emap = np.arange(324).reshape(1, 18, 18)

    def forces(xx, rr):
        out = np.zeros((3, 6))
        shell.element_forces(tris, kl, xloc, frames, beta, tfm, xx, rr, zero, out)
        return out.ravel()

    # strains ~1e-3: central differences with 1e-7 exact to ~(1e-7 / 1e-3)^2
    kfd = fd_wrt_nodes(forces, x, rot, 1e-7)
    dk, dc = np.zeros(325), np.zeros(325)
    shell.element_tangents(tris, kl, xloc, frames, beta, tfm, x, rot, zero, zero.copy(), dk,
                           dc, emap)  # fmt: skip
    k = dk[:324].reshape(18, 18)
    assert np.abs(k - kfd).max() <= 1e-5 * np.abs(kfd).max()
    # the material tangent drops only the frame-rotation (geometric) terms: of relative order
    # strain (1e-3) against the membrane stiffness
    dm = np.zeros(325)
    shell.material_tangents(tris, kl, xloc, frames, beta, tfm, x, rot, zero, zero.copy(), dm,
                            np.zeros(325), emap)  # fmt: skip
    km = dm[:324].reshape(18, 18)
    assert np.abs(km - kfd).max() <= 1e-2 * np.abs(kfd).max()


def test_membrane_law_is_checked_by_name():
    with pytest.raises(ValueError, match="ShellMaterial.membrane must be one of"):
        ShellMaterial(E, NU, 1000.0, T, 0.0, "wrinkly")
