"""Co-rotational flat triangular shell: OPT membrane with drilling freedoms + DKT plate.

Formulation (element-independent co-rotational, Rankin & Brogan 1986; Felippa & Haugen 2005,
CMAME 194:2285):

* Each triangle carries a moving frame ``R0 = [e1 e2 e3]``: e1 along side 1-2, e3 the normal,
  origin at the centroid. Removing this rigid motion leaves local deformational DOFs
  ``d_l = [u_i, theta_i]`` (18,): ``u_i = R0^T (x_i - x_c) - X_i`` and
  ``theta_i = log(R0^T R_i R0_ref)``, which stay small under large rigid motion.
* Locally the element is linear and small-strain: ``E = 1/2 d_l^T K_l d_l`` with
  - membrane: the ANDES "optimal" triangle with corner drilling rotations, OPT (Felippa 2003,
    "A study of optimal membrane triangles with drilling freedoms", CMAME 192:2125; ANDES
    template of Bergan & Felippa 1985 and Militello & Felippa 1991): a constant-strain basic
    stiffness with Allman-type rotation-driven edge displacements (alpha_b = 3/2) plus a
    higher-order stiffness on the deviatoric corner rotations with a linear assumed natural
    strain (beta_0 = (1 - 4 nu^2)/2, beta_1..9 of OPT). It passes the patch test, keeps the
    rigid in-plane rotation (u = -w y, v = w x, theta_z = w) strain free, and is exact in
    in-plane bending of rectangular two-triangle pairs, so it does not lock in in-plane bending
    as the constant-strain triangle does; the drilling rotation gets a physical stiffness;
  - bending: Discrete Kirchhoff Triangle (Batoz, Bathe & Ho 1980, IJNME 15:1771) — quadratic
    rotation fields with the Kirchhoff hypothesis imposed at corners and mid-sides, so there is no
    transverse shear and hence no shear locking at any thickness (tested to t/L = 1e-3);
    flat facets carry no membrane-bending coupling, hence no membrane locking.
  ``tests/test_shell_benchmarks.py`` and docs/shell-verification.md give the benchmarks
  (Cook's membrane, MacNeal-Harder cantilever, Scordelis-Lo roof, pinched cylinder).
* Internal force ``f = B^T K_l (d_l + beta * d_l')`` with ``B = d d_l / d(x, spin)``; the damping
  term is stiffness-proportional Rayleigh damping ``C = beta * K_cr`` where ``K_cr = B^T K_l B`` is
  the co-rotational material stiffness at the current configuration: rigid-body motion is not
  damped (RecurDyn FFlex "damping ratio" beta [s]).
* Tension-field membrane (``ShellMaterial(membrane="tension-field")``): a film far thinner than
  the mesh wrinkles under a compressive strain the mesh cannot resolve (a 0.3 mm film over a
  10 mm span buckles at 0.07 %), so the constant-strain (basic) membrane part carries no
  compressive principal stress. With the principal strains e1 >= e2 of the basic strain, the
  element is *taut* where the minor principal stress is >= 0 (e2 + nu e1 >= 0: the elastic law),
  *slack* where e1 <= 0 (no stress), and *wrinkled* in between: uniaxial tension
  ``sigma = E e1 n1 n1^T`` along the major principal direction n1 (Roddeman, Drukker, Oomens &
  Janssen 1987, "The wrinkling of thin membranes", J. Appl. Mech. 54:884; the isotropic form of
  Jarasjarungkiat, Wuechner & Bletzinger 2008, CMAME 197:773). Its energy density
  ``E e1^2 / 2`` meets the elastic one with its stress at the taut boundary, so forces are
  continuous. OPT's higher-order part, the DKT bending and the Rayleigh damping stay linear
  (RecurDyn's C = beta K with the elastic K).
* Tangent: the exact derivative of ``f`` with respect to nodal positions and spatial spins, by the
  complex-step method (the kernels are dtype-generic), i.e. consistent to machine precision and
  including all geometric (frame-rotation) terms. Tests compare it with finite differences.

Global DOFs per node: ``[x, y, z, spin_x, spin_y, spin_z]``.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flexparcel.elements.rotations import matmul, rotation_log, skew, tangent_inv
from flexparcel.model.interfaces import ElementGroup

__all__ = [
    "ShellGroup",
    "local_stiffness",
    "tension_field_data",
    "reference_frames",
    "element_forces",
    "element_tangents",
    "material_tangents",
]

_CS_STEP = 1e-30  # complex-step size: no subtractive cancellation, so any tiny h is exact


# --------------------------------------------------------------------------- reference geometry
def reference_frames(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reference frames ``R0_ref`` (m, 3, 3) and local centroidal coordinates (m, 3, 2) [m]."""
    p = points[triangles]  # (m, 3, 3)
    e1 = p[:, 1] - p[:, 0]
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e3 = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    e3 /= np.linalg.norm(e3, axis=1)[:, None]
    e2 = np.cross(e3, e1)
    frames = np.stack([e1, e2, e3], axis=2)  # columns are the axes
    xc = p.mean(axis=1, keepdims=True)
    xloc = np.einsum("mki,mjk->mji", frames, p - xc)  # R0^T (X - Xc)
    return frames, np.ascontiguousarray(xloc[:, :, :2])


def _dkt_beta_map(xy: np.ndarray) -> np.ndarray:
    """Map (12, 9) from corner DOFs [w, theta_x, theta_y] x 3 to the slopes beta = grad w at the
    6 quadratic nodes (corners 1-3, mid-sides 4: 2-3, 5: 3-1, 6: 1-2), ``[bx, by]`` each.

    Kirchhoff at corners: beta = (dw/dx, dw/dy) = (-theta_y, theta_x) (small rotation of the
    normal). At mid-sides: tangential slope from the cubic Hermite w along the side,
    ``w_s(mid) = 3/(2l)(w_j - w_i) - (w_s,i + w_s,j)/4``; normal slope linear between corners.
    """
    t = np.zeros((12, 9))
    for i in range(3):  # corners
        t[2 * i, 3 * i + 2] = -1.0
        t[2 * i + 1, 3 * i + 1] = 1.0
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        d = xy[j] - xy[i]
        ell = np.hypot(d[0], d[1])
        tan = d / ell
        nor = np.array([tan[1], -tan[0]])
        row = 2 * (3 + k)
        # beta at the corners as rows of t: bi = t[2i:2i+2]
        bi, bj = t[2 * i : 2 * i + 2], t[2 * j : 2 * j + 2]
        ws = np.zeros(9)
        ws[3 * j] += 1.5 / ell
        ws[3 * i] -= 1.5 / ell
        ws -= 0.25 * (tan @ bi + tan @ bj)
        wn = 0.5 * (nor @ bi + nor @ bj)
        t[row : row + 2] = np.outer(tan, ws) + np.outer(nor, wn)
    return t


def _p2_gradients(xy: np.ndarray, l: np.ndarray) -> np.ndarray:
    """Gradients (6, 2) of the quadratic triangle shape functions at area coordinates ``l``."""
    x, y = xy[:, 0], xy[:, 1]
    b = np.array([y[1] - y[2], y[2] - y[0], y[0] - y[1]])
    c = np.array([x[2] - x[1], x[0] - x[2], x[1] - x[0]])
    two_a = x[1] * y[2] - x[2] * y[1] + x[2] * y[0] - x[0] * y[2] + x[0] * y[1] - x[1] * y[0]
    dl = np.stack([b, c], axis=1) / two_a  # (3, 2): grad L_i
    g = np.zeros((6, 2))
    for i in range(3):
        g[i] = (4.0 * l[i] - 1.0) * dl[i]
    for k, (i, j) in enumerate(((1, 2), (2, 0), (0, 1))):
        g[3 + k] = 4.0 * (l[i] * dl[j] + l[j] * dl[i])
    return g


# --------------------------------------------------------------------------- OPT membrane
# ANDES "optimal" membrane triangle with corner drilling freedoms (OPT): C. A. Felippa, "A study
# of optimal membrane triangles with drilling freedoms", CMAME 192 (2003) 2125-2168, built on the
# assumed natural deviatoric strain (ANDES) template of Bergan & Felippa (1985, CMAME 50:25) and
# Militello & Felippa (1991, CMAME 93:217). Its parameters are the set that
# Felippa (2003) names OPT:
OPT_ALPHA_B = 1.5
"""alpha_b of the basic stiffness (the Allman-type quadratic edge displacement weight)."""
OPT_BETAS = np.array([[1.0, 2.0, 1.0], [0.0, 1.0, -1.0], [-1.0, -1.0, -2.0]])
"""beta_1..beta_9 of the higher-order stiffness, as the 3x3 block ``[[b1 b2 b3] [b4 b5 b6]
[b7 b8 b9]]`` (rows: sides 1-2, 2-3, 3-1; columns: corners 1, 2, 3) of corner 1's matrix Q_1."""


def opt_beta0(poisson_ratio: float) -> float:
    """Higher-order scaling beta_0 of OPT for an isotropic material (Felippa 2003):
    ``(1 - 4 nu^2) / 2``, floored at 0.01 so the element keeps its rank near nu = 1/2."""
    return max(0.5 * (1.0 - 4.0 * poisson_ratio**2), 0.01)


def opt_basic_strain(xy: np.ndarray) -> np.ndarray:
    """OPT's basic (constant) membrane strain map ``B_b`` (3, 9) [1/m] over ``[u, v, theta_z]``
    per corner: ``[e_xx, e_yy, g_xy] = B_b d_m``, i.e. ``L^T / A`` with Felippa's (2003)
    force-lumping matrix L and alpha_b = 3/2."""
    x, y = xy[:, 0], xy[:, 1]
    nxt = np.array([1, 2, 0])
    prv = np.array([2, 0, 1])
    b = y[nxt] - y[prv]
    c = x[prv] - x[nxt]
    two_a = b[0] * c[1] - b[1] * c[0]
    ab = OPT_ALPHA_B
    bb = np.zeros((3, 9))
    for i in range(3):
        j, k = nxt[i], prv[i]
        xki, xij = x[k] - x[i], x[i] - x[j]
        yik, yji = y[i] - y[k], y[j] - y[i]
        bb[0, 3 * i] = b[i]
        bb[1, 3 * i + 1] = c[i]
        bb[2, 3 * i] = c[i]
        bb[2, 3 * i + 1] = b[i]
        bb[0, 3 * i + 2] = ab / 6.0 * b[i] * (yik - yji)
        bb[1, 3 * i + 2] = ab / 6.0 * c[i] * (xki - xij)
        bb[2, 3 * i + 2] = ab / 3.0 * (xki * yik - xij * yji)
    return bb / two_a


def _opt_membrane(xy: np.ndarray, dmat: np.ndarray, thickness: float, beta0: float) -> np.ndarray:
    """OPT membrane stiffness (9, 9) over ``[u, v, theta_z]`` per corner (Felippa 2003).

    ``xy`` (3, 2) counter-clockwise corner coordinates [m], ``dmat`` the plane-stress modulus
    matrix (3, 3) [Pa], stresses/strains ordered ``[xx, yy, xy (engineering)]``.

    ``K = K_b + K_h``:

    * basic ``K_b = V B_b^T D B_b`` (V = A t): ``B_b`` is the mean strain of the field that is
      linear in the corners' translations plus an Allman-type quadratic normal displacement of
      each side driven by the difference of its corner rotations, weighted by ``alpha_b``; it is
      constant strain, so the
      element passes the patch test and a rigid rotation (equal theta at the corners) is strain
      free;
    * higher order ``K_h = beta_0 T^T K_theta T``: ``T`` (3, 9) gives the deviatoric corner
      rotations ``theta_i - theta_0`` (theta_0 the mean in-plane rotation ``(v,x - u,y) / 2``
      of the linear field); the assumed strain is linear over the triangle, ``3/2 sum_i
      zeta_i T_e Q_i`` with ``Q_i`` the natural (side-extension) strains at corner i, ``T_e``
      their map to Cartesian strains; integrated exactly by the mid-side rule. It vanishes for
      every constant-strain field and for rigid motion, so it adds no spurious stiffness there.
    """
    x, y = xy[:, 0], xy[:, 1]
    nxt = np.array([1, 2, 0])  # corner i -> j (next), k (previous): counter-clockwise cycle
    prv = np.array([2, 0, 1])
    # b_i = y_j - y_k, c_i = x_k - x_j: twice the area times the gradient of the linear function
    b = y[nxt] - y[prv]
    c = x[prv] - x[nxt]
    two_a = b[0] * c[1] - b[1] * c[0]
    area = 0.5 * two_a
    vol = area * thickness
    bb = opt_basic_strain(xy)
    k_basic = vol * bb.T @ dmat @ bb
    # --- higher-order part
    # deviatoric corner rotations: theta_i - theta_0, theta_0 = sum_i (b_i v_i - c_i u_i) / (4A)
    t_rot = np.zeros((3, 9))
    for i in range(3):
        t_rot[:, 3 * i] = c[i] / (2.0 * two_a)
        t_rot[:, 3 * i + 1] = -b[i] / (2.0 * two_a)
        t_rot[i, 3 * i + 2] = 1.0
    # sides 1-2, 2-3, 3-1: direction cosines; side-extension strain = n(side) . [exx eyy gxy]
    starts, ends = np.array([0, 1, 2]), np.array([1, 2, 0])
    d = xy[ends] - xy[starts]
    len2 = np.einsum("ij,ij->i", d, d)
    to_natural = np.column_stack([d[:, 0] ** 2, d[:, 1] ** 2, d[:, 0] * d[:, 1]]) / len2[:, None]
    t_e = np.linalg.inv(to_natural)  # natural -> Cartesian strains
    d_nat = t_e.T @ dmat @ t_e
    # Q_1 (natural strains at corner 1 per deviatoric rotation), Q_2 and Q_3 by cyclic symmetry
    q = [(two_a / 3.0) * np.roll(OPT_BETAS, (n, n), axis=(0, 1)) / len2[:, None] for n in range(3)]
    k_theta = np.zeros((3, 3))
    for qm in (0.5 * (q[0] + q[1]), 0.5 * (q[1] + q[2]), 0.5 * (q[2] + q[0])):  # mid-sides
        k_theta += qm.T @ d_nat @ qm
    k_theta *= 0.75 * beta0 * vol  # (3/2)^2 from the strain scale, 1/3 from the mid-side rule
    return k_basic + t_rot.T @ k_theta @ t_rot


def _plane_stress(nu: float) -> np.ndarray:
    """Isotropic plane-stress modulus over E (3, 3), ``[xx, yy, xy (engineering)]``."""
    return np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]]) / (1.0 - nu**2)


def local_stiffness(
    xy: np.ndarray, youngs_modulus: float, poisson_ratio: float, thickness: float
) -> np.ndarray:
    """Local linear stiffness (18, 18) of one triangle with local corner coordinates xy (3, 2) [m]:
    OPT membrane with drilling freedoms (Felippa 2003) + DKT plate bending (Batoz et al. 1980).

    Local DOFs per corner: ``[u, v, w, theta_x, theta_y, theta_z]``; membrane and bending are
    uncoupled (flat facet).
    """
    e, nu, h = youngs_modulus, poisson_ratio, thickness
    iso = _plane_stress(nu)
    x, y = xy[:, 0], xy[:, 1]
    b = np.array([y[1] - y[2], y[2] - y[0], y[0] - y[1]])
    c = np.array([x[2] - x[1], x[0] - x[2], x[1] - x[0]])
    area = 0.5 * (b[0] * c[1] - b[1] * c[0])
    k = np.zeros((18, 18))
    # membrane with drilling (OPT) over [u, v, theta_z] of each corner
    memb = np.array([[6 * i, 6 * i + 1, 6 * i + 5] for i in range(3)]).ravel()
    k[np.ix_(memb, memb)] += _opt_membrane(xy, e * iso, h, opt_beta0(nu))
    # bending (DKT): kappa = [bx,x  by,y  bx,y+by,x], beta from the 9 plate DOFs
    tmap = _dkt_beta_map(xy)
    plate = np.array([[6 * i + 2, 6 * i + 3, 6 * i + 4] for i in range(3)]).ravel()
    db = e * h**3 / 12.0 * iso
    kb = np.zeros((9, 9))
    for l in ([0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]):  # degree-2 exact rule
        g = _p2_gradients(xy, np.asarray(l))
        bb = np.zeros((3, 12))
        for a in range(6):
            bb[0, 2 * a] = g[a, 0]
            bb[1, 2 * a + 1] = g[a, 1]
            bb[2, 2 * a] = g[a, 1]
            bb[2, 2 * a + 1] = g[a, 0]
        bk = bb @ tmap
        kb += (area / 3.0) * bk.T @ db @ bk
    k[np.ix_(plate, plate)] += kb
    return k


def tension_field_data(
    xy: np.ndarray, youngs_modulus: float, poisson_ratio: float, thickness: float
) -> np.ndarray:
    """Per-triangle data (3, 12) of the tension-field membrane: ``[B_b | V D]``, OPT's basic
    strain map (3, 9) [1/m] and the plane-stress modulus times the volume A t (3, 3) [N m].
    All zeros means an elastic membrane (the kernels test ``[0, 9] != 0``)."""
    x, y = xy[:, 0], xy[:, 1]
    area = 0.5 * abs((x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]))
    vd = youngs_modulus * _plane_stress(poisson_ratio) * area * thickness
    return np.hstack([opt_basic_strain(xy), vd])


# --------------------------------------------------------------------------- tension field
@nb.njit(cache=True)
def _tension_field(eps, vd):
    """Relaxed stress resultant ``V sigma`` (3,) and energy ``V W`` of the basic strain
    ``eps = [e_xx, e_yy, g_xy]`` for ``vd = V D`` (3, 3) of an isotropic film (see the module
    docstring: taut, wrinkled or slack). Dtype-generic for the complex-step tangent: states are
    chosen by real parts, and ``r > 0`` wherever it divides (a wrinkled state has e1 > 0 > e2)."""
    nu = vd[0, 1] / vd[0, 0]
    ev = vd[0, 0] * (1.0 - nu * nu)  # E V
    em = 0.5 * (eps[0] + eps[1])
    a = 0.5 * (eps[0] - eps[1])
    b = 0.5 * eps[2]
    r = np.sqrt(a * a + b * b)
    e1 = em + r
    e2 = em - r
    sig = np.zeros(3, eps.dtype)
    if (e2 + nu * e1).real >= 0.0:  # taut
        for i in range(3):
            sig[i] = vd[i, 0] * eps[0] + vd[i, 1] * eps[1] + vd[i, 2] * eps[2]
        return sig, 0.5 * (sig[0] * eps[0] + sig[1] * eps[1] + sig[2] * eps[2])
    if e1.real <= 0.0:  # slack
        return sig, 0.0 * em
    s1 = ev * e1  # wrinkled: uniaxial tension along n1, cos 2phi = a / r, sin 2phi = b / r
    sig[0] = 0.5 * s1 * (1.0 + a / r)
    sig[1] = 0.5 * s1 * (1.0 - a / r)
    sig[2] = 0.5 * s1 * (b / r)
    return sig, 0.5 * s1 * e1


@nb.njit(cache=True)
def _basic_strain(d, tfm):
    """Basic membrane strain (3,) from the local DOFs ``d`` (18,) and ``tfm`` = [B_b | V D]."""
    eps = np.zeros(3, d.dtype)
    for i in range(3):
        acc = 0.0 * d[0]
        for a in range(3):
            acc += tfm[i, 3 * a] * d[6 * a] + tfm[i, 3 * a + 1] * d[6 * a + 1]
            acc += tfm[i, 3 * a + 2] * d[6 * a + 5]
        eps[i] = acc
    return eps


@nb.njit(cache=True)
def _tension_field_correction(d, tfm, s):
    """Add to the local stress resultant ``s`` (18,) the tension-field minus the elastic
    basic membrane part; returns the matching energy correction [J]."""
    eps = _basic_strain(d, tfm)
    vd = tfm[:, 9:12]
    sig, w = _tension_field(eps, vd)
    for i in range(3):
        el = vd[i, 0] * eps[0] + vd[i, 1] * eps[1] + vd[i, 2] * eps[2]
        w -= 0.5 * el * eps[i]
        sig[i] -= el
    for a in range(3):
        for k in range(3):
            slot = 6 * a + (5 if k == 2 else k)  # [u, v, theta_z] of corner a
            col = 3 * a + k
            s[slot] += tfm[0, col] * sig[0] + tfm[1, col] * sig[1] + tfm[2, col] * sig[2]
    return w


@nb.njit(cache=True)
def _tension_field_stiffness(d, tfm, kl):
    """``kl`` with its basic membrane part replaced by the tension field's tangent
    ``B_b^T (dV sigma / d eps) B_b`` (by complex step over the three strains: exact)."""
    eps = _basic_strain(d, tfm)
    vd = tfm[:, 9:12]
    dsig = np.zeros((3, 3))
    h = _CS_STEP
    for j in range(3):
        ec = eps.astype(np.complex128)
        ec[j] += 1j * h
        sc, _ = _tension_field(ec, vd)
        for i in range(3):
            dsig[i, j] = sc[i].imag / h - vd[i, j]
    delta = 0.5 * (dsig + dsig.T)  # the Hessian of W: symmetric up to round-off
    k = kl.copy()
    memb = np.array([0, 1, 5, 6, 7, 11, 12, 13, 17])
    for p in range(9):
        for q in range(9):
            acc = 0.0
            for i in range(3):
                for j in range(3):
                    acc += tfm[i, p] * delta[i, j] * tfm[j, q]
            k[memb[p], memb[q]] += acc
    return k


# --------------------------------------------------------------------------- kernels
@nb.njit(cache=True)
def _tri_kinematics(x, rot, xloc, r0ref):
    """Current frame, local DOFs d_l (18,) and B (18, 18) for one triangle (dtype-generic)."""
    dt = x.dtype
    r0ref = r0ref.astype(dt)
    d12 = x[1] - x[0]
    d13 = x[2] - x[0]
    l12 = np.sqrt(d12[0] * d12[0] + d12[1] * d12[1] + d12[2] * d12[2])
    e1 = d12 / l12
    n = np.zeros(3, dt)
    n[0] = d12[1] * d13[2] - d12[2] * d13[1]
    n[1] = d12[2] * d13[0] - d12[0] * d13[2]
    n[2] = d12[0] * d13[1] - d12[1] * d13[0]
    e3 = n / np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    e2 = np.zeros(3, dt)
    e2[0] = e3[1] * e1[2] - e3[2] * e1[1]
    e2[1] = e3[2] * e1[0] - e3[0] * e1[2]
    e2[2] = e3[0] * e1[1] - e3[1] * e1[0]
    r0 = np.zeros((3, 3), dt)
    for i in range(3):
        r0[i, 0] = e1[i]
        r0[i, 1] = e2[i]
        r0[i, 2] = e3[i]
    xc = (x[0] + x[1] + x[2]) / 3.0
    xl = np.zeros((3, 3), dt)  # current local coordinates
    for a in range(3):
        for i in range(3):
            for k in range(3):
                xl[a, i] += r0[k, i] * (x[a, k] - xc[k])
    d = np.zeros(18, dt)
    tinv = np.zeros((3, 3, 3), dt)
    rr = np.empty((3, 3), dt)  # r0^T R_a, then r0^T R_a r0ref (loops: no temporaries)
    rb = np.empty((3, 3), dt)
    for a in range(3):
        d[6 * a] = xl[a, 0] - xloc[a, 0]
        d[6 * a + 1] = xl[a, 1] - xloc[a, 1]
        d[6 * a + 2] = xl[a, 2]
        for i in range(3):
            for j in range(3):
                rr[i, j] = (
                    r0[0, i] * rot[a, 0, j] + r0[1, i] * rot[a, 1, j] + r0[2, i] * rot[a, 2, j]
                )
        for i in range(3):
            for j in range(3):
                rb[i, j] = rr[i, 0] * r0ref[0, j] + rr[i, 1] * r0ref[1, j] + rr[i, 2] * r0ref[2, j]
        th = rotation_log(rb)
        d[6 * a + 3 : 6 * a + 6] = th
        tinv[a] = tangent_inv(th)
    # frame spin in local components: omega = G @ dx_loc (3 x 9)
    b0 = xl[1, 1] - xl[2, 1]
    b1 = xl[2, 1] - xl[0, 1]
    b2 = xl[0, 1] - xl[1, 1]
    c0 = xl[2, 0] - xl[1, 0]
    c1 = xl[0, 0] - xl[2, 0]
    c2 = xl[1, 0] - xl[0, 0]
    two_a = b0 * c1 - b1 * c0
    g = np.zeros((3, 9), dt)
    g[0, 2] = c0 / two_a
    g[0, 5] = c1 / two_a
    g[0, 8] = c2 / two_a
    g[1, 2] = -b0 / two_a
    g[1, 5] = -b1 / two_a
    g[1, 8] = -b2 / two_a
    g[2, 1] = -1.0 / l12
    g[2, 4] = 1.0 / l12
    bl = np.zeros((18, 18), dt)
    for a in range(3):
        xa, ya, za = xl[a, 0], xl[a, 1], xl[a, 2]
        for b in range(3):
            for j in range(3):
                c = 3 * b + j
                # W(x_a) G and T^-1 G, column c, written into B directly
                bl[6 * a, 6 * b + j] = -za * g[1, c] + ya * g[2, c]
                bl[6 * a + 1, 6 * b + j] = za * g[0, c] - xa * g[2, c]
                bl[6 * a + 2, 6 * b + j] = -ya * g[0, c] + xa * g[1, c]
                for i in range(3):
                    tgi = tinv[a, i, 0] * g[0, c] + tinv[a, i, 1] * g[1, c]
                    bl[6 * a + 3 + i, 6 * b + j] = -(tgi + tinv[a, i, 2] * g[2, c])
            for i in range(3):
                bl[6 * a + i, 6 * b + i] -= 1.0 / 3.0
        for i in range(3):
            bl[6 * a + i, 6 * a + i] += 1.0
        for i in range(3):
            for j in range(3):
                bl[6 * a + 3 + i, 6 * a + 3 + j] = tinv[a, i, j]
    # columns: local components of global variations -> global components (right-multiply R0^T)
    bg = np.zeros((18, 18), dt)
    for b in range(6):
        for i in range(18):
            for j in range(3):
                acc = bl[i, 3 * b] * r0[j, 0] + bl[i, 3 * b + 1] * r0[j, 1]
                bg[i, 3 * b + j] = acc + bl[i, 3 * b + 2] * r0[j, 2]
    return d, bg


@nb.njit(cache=True)
def _tri_force(x, rot, vel, kl, xloc, r0ref, beta, tfm):
    """Internal force (18,) and strain energy of one triangle; ``vel`` (18,) nodal [v, omega]."""
    d, bg = _tri_kinematics(x, rot, xloc, r0ref)
    return _force_from_kinematics(d, bg, vel, kl, beta, tfm)


@nb.njit(cache=True)
def _force_from_kinematics(d, bg, vel, kl, beta, tfm):
    """Force (18,) and strain energy from local DOFs ``d`` and ``B`` of :func:`_tri_kinematics`
    (the tangent kernel has them already: computing them once saves a third of its time);
    ``tfm`` (3, 12) the tension-field data, zeros for an elastic membrane."""
    dd = d.copy()
    if beta != 0.0:
        for i in range(18):
            acc = 0.0 * d[0]
            for j in range(18):
                acc += bg[i, j] * vel[j]
            dd[i] += beta * acc
    s = np.zeros(18, d.dtype)
    energy = 0.0 * d[0]
    for i in range(18):
        acc = 0.0 * d[0]
        acc2 = 0.0 * d[0]
        for j in range(18):
            acc += kl[i, j] * dd[j]
            acc2 += kl[i, j] * d[j]
        s[i] = acc
        energy += 0.5 * d[i] * acc2
    if tfm[0, 9] != 0.0:
        energy += _tension_field_correction(d, tfm, s)
    f = np.zeros(18, d.dtype)
    for j in range(18):
        acc = 0.0 * d[0]
        for i in range(18):
            acc += bg[i, j] * s[i]
        f[j] = acc
    return f, energy


@nb.njit(cache=True)
def _gather(e, tris, pos, rot, vel):
    x = np.zeros((3, 3))
    r = np.zeros((3, 3, 3))
    v = np.zeros(18)
    for a in range(3):
        n = tris[e, a]
        x[a] = pos[n]
        r[a] = rot[n]
        v[6 * a : 6 * a + 6] = vel[n]
    return x, r, v


@nb.njit(cache=True, parallel=True)
def _element_force_blocks(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, fe, en):
    for e in nb.prange(tris.shape[0]):
        x, r, v = _gather(e, tris, pos, rot, vel)
        f, energy = _tri_force(x, r, v, kl[e], xloc[e], r0ref[e], beta[e], tfm[e])
        fe[e] = f
        en[e] = energy


@nb.njit(cache=True)
def _scatter_forces(tris, fe, out):
    for e in range(tris.shape[0]):
        for a in range(3):
            for i in range(6):
                out[tris[e, a], i] += fe[e, 6 * a + i]


def element_forces(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, out):
    """Assemble internal forces of all triangles into ``out`` (node_count, 6); returns strain
    energy [J]. ``pos`` (n, 3) [m], ``rot`` (n, 3, 3), ``vel`` (n, 6) [m/s, rad/s]; ``tfm``
    (m, 3, 12) the tension-field data (:func:`tension_field_data`; zeros: elastic).

    Element blocks are computed in parallel (numba threads), then scattered serially so the
    sum is deterministic."""
    m = tris.shape[0]
    fe = np.empty((m, 18))
    en = np.empty(m)
    _element_force_blocks(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, fe, en)
    _scatter_forces(tris, fe, out)
    return float(en.sum())


@nb.njit(cache=True)
def _btkb_into(bg, kl, out):
    """out = B^T K_l B (18, 18) for symmetric K_l: only the upper triangle is summed and then
    mirrored (exactly symmetric, which the Cholesky backend relies on), and the zeros of K_l
    (membrane and bending do not couple in a flat facet: half of it) and of B (about 40 %: a
    translation row has no rotation columns, a rotation row only its own node's) are
    skipped."""
    t = np.zeros((18, 18))
    for i in range(18):
        for p in range(18):
            kip = kl[i, p]
            if kip != 0.0:
                for j in range(18):
                    t[i, j] += kip * bg[p, j]
    for i in range(18):
        for j in range(i, 18):
            out[i, j] = 0.0
    for p in range(18):
        for i in range(18):
            bpi = bg[p, i]
            if bpi != 0.0:
                for j in range(i, 18):
                    out[i, j] += bpi * t[p, j]
    for i in range(18):
        for j in range(i + 1, 18):
            out[j, i] = out[i, j]


@nb.njit(cache=True, parallel=True)
def _material_tangent_blocks(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, fe, en, ke, kt):
    """Forces, energies and ``B^T K_l B`` per triangle; where the membrane is a tension field,
    ``kt[e]`` gets the stiffness with its relaxed tangent (``ke`` stays elastic: the damping)."""
    for e in nb.prange(tris.shape[0]):
        x, r, v = _gather(e, tris, pos, rot, vel)
        d, bg = _tri_kinematics(x, r, xloc[e], r0ref[e])
        f, energy = _force_from_kinematics(d, bg, v, kl[e], beta[e], tfm[e])
        fe[e] = f
        en[e] = energy
        _btkb_into(bg, kl[e], ke[e])
        if tfm[e, 0, 9] != 0.0:
            _btkb_into(bg, _tension_field_stiffness(d, tfm[e], kl[e]), kt[e])


@nb.njit(cache=True)
def _scatter_matrices(emap, ke, beta, tfm, kt, data_k, data_c):
    """K_e into ``data_k`` (``kt[e]`` for a tension-field membrane) and beta_e K_e into
    ``data_c``, in one pass over the slots."""
    for e in range(ke.shape[0]):
        b = beta[e]
        relaxed = tfm[e, 0, 9] != 0.0
        for i in range(18):
            for j in range(18):
                slot = emap[e, i, j]
                k = ke[e, i, j]
                data_k[slot] += kt[e, i, j] if relaxed else k
                data_c[slot] += b * k


def material_tangents(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, out_f, data_k, data_c, emap):
    """Forces into ``out_f``; material stiffness ``B^T K_l B`` (with the tension field's
    relaxed membrane tangent where it applies) into CSR ``data_k`` and the Rayleigh damping
    ``beta B^T K_l B`` into ``data_c``. Returns the strain energy [J]."""
    m = tris.shape[0]
    fe = np.empty((m, 18))
    en = np.empty(m)
    ke = np.empty((m, 18, 18))
    kt = np.empty((m if tfm[:, 0, 9].any() else 1, 18, 18))  # only read where relaxed
    _material_tangent_blocks(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, fe, en, ke, kt)
    _scatter_forces(tris, fe, out_f)
    _scatter_matrices(emap, ke, beta, tfm, kt, data_k, data_c)
    return float(en.sum())


@nb.njit(cache=True)
def element_tangents(tris, kl, xloc, r0ref, beta, tfm, pos, rot, vel, out_f, data_k, data_c, emap):
    """Forces into ``out_f``; stiffness ``dF/d(x, spin)`` scattered into CSR ``data_k`` and
    damping ``dF/d(v, omega)`` into ``data_c`` through ``emap`` (m, 18, 18) of data indices.
    Returns the strain energy [J].

    ``dF/d(x, spin)`` is the complex-step derivative of the full co-rotational force at fixed
    velocities (exact, with all frame-rotation terms); ``dF/d(v, omega) = beta B^T K_l B`` is
    the Rayleigh damping matrix C.
    """
    energy = 0.0
    h = _CS_STEP
    for e in range(tris.shape[0]):
        x, r, v = _gather(e, tris, pos, rot, vel)
        f, en = _tri_force(x, r, v, kl[e], xloc[e], r0ref[e], beta[e], tfm[e])
        energy += en
        for a in range(3):
            out_f[tris[e, a]] += f[6 * a : 6 * a + 6]
        xc = x.astype(np.complex128)
        rc = r.astype(np.complex128)
        ke = np.zeros((18, 18))
        for a in range(3):
            for i in range(3):
                xc[a, i] += 1j * h
                fc, _ = _tri_force(xc, rc, v, kl[e], xloc[e], r0ref[e], beta[e], tfm[e])
                xc[a, i] -= 1j * h
                ke[:, 6 * a + i] = fc.imag / h
            for i in range(3):
                # spatial spin: R -> (I + i h W(e_i)) R, exact to first order in h
                ei = np.zeros(3)
                ei[i] = 1.0
                dr = matmul(skew(ei), r[a].copy())
                rc[a] += 1j * h * dr
                fc, _ = _tri_force(xc, rc, v, kl[e], xloc[e], r0ref[e], beta[e], tfm[e])
                rc[a] = r[a]
                ke[:, 6 * a + 3 + i] = fc.imag / h
        for i in range(18):
            for j in range(18):
                data_k[emap[e, i, j]] += ke[i, j]
        if beta[e] != 0.0:
            d, bg = _tri_kinematics(x, r, xloc[e], r0ref[e])
            ce = beta[e] * matmul(matmul(bg.T.copy(), kl[e].copy()), bg)
            for i in range(18):
                for j in range(18):
                    data_c[emap[e, i, j]] += ce[i, j]
    return energy


# --------------------------------------------------------------------------- element group
class ShellGroup(ElementGroup):
    """Flat shell triangles (OPT membrane with drilling + DKT bending, co-rotational),
    quads split into four half-weight triangles; 6 DOFs per node.

    Build it with :meth:`from_mesh`; groups of several meshes are joined by
    :meth:`concatenate` so that one kernel call covers every shell of a model.
    """

    kind = "shell"

    def __init__(
        self, triangles, kl, xloc, frame0, beta, node_mass, node_inertia, tension_field=None
    ) -> None:
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        """Triangles used by the kernels, shape (m, 3)."""
        self.kl = kl
        """Local linear stiffness per triangle [SI], shape (m, 18, 18)."""
        self.xloc = xloc
        """Reference local centroidal corner coordinates [m], shape (m, 3, 2)."""
        self.frame0 = frame0
        """Reference element frames, shape (m, 3, 3) (columns e1, e2, e3)."""
        self.beta = beta
        """Rayleigh stiffness-proportional damping beta [s] per triangle, shape (m,)."""
        self.tension_field = (
            np.zeros((len(self.triangles), 3, 12)) if tension_field is None else tension_field
        )
        """Tension-field membrane data per triangle (:func:`tension_field_data`), shape
        (m, 3, 12); zeros where the membrane is elastic."""
        self._node_mass = node_mass  # (m,) mass [kg] each corner of a triangle gets
        self._node_inertia = node_inertia  # (m,) rotary inertia [kg m^2] each corner gets
        self.emap = np.zeros((len(self.triangles), 18, 18), np.int64)
        """CSR data slot of each element matrix entry, shape (m, 18, 18)."""

    @classmethod
    def from_mesh(cls, points: np.ndarray, triangles, weights, material) -> ShellGroup:
        """Triangles (m, 3) of global node ids into ``points`` (n, 3) [m] with weights (m,)
        (0.5 for the four triangles of a split quad) and one ShellMaterial."""
        tri = np.asarray(triangles, dtype=np.int64)
        w = np.asarray(weights, dtype=float)
        frames, xloc = reference_frames(points, tri)
        # structured meshes repeat a few triangle shapes: compute each shape once (the
        # local stiffness depends only on the local corner coordinates and the material)
        _, first, which = np.unique(
            np.round(xloc.reshape(len(tri), 6), 12), axis=0, return_index=True,
            return_inverse=True,
        )  # fmt: skip
        k_shape = np.array([
            local_stiffness(xloc[e], material.youngs_modulus, material.poisson_ratio,
                            material.thickness)
            for e in first
        ])  # fmt: skip
        kl = w[:, None, None] * k_shape[which.ravel()]
        area = 0.5 * np.abs(
            (xloc[:, 1, 0] - xloc[:, 0, 0]) * (xloc[:, 2, 1] - xloc[:, 0, 1])
            - (xloc[:, 2, 0] - xloc[:, 0, 0]) * (xloc[:, 1, 1] - xloc[:, 0, 1])
        )
        # lumped mass: a third of each triangle's mass to each corner; isotropic rotational
        # inertia rho t^3/12 per area (the plate's, also used for the drilling axis)
        rho_t = material.density * material.thickness
        m_node = rho_t * area * w / 3.0
        j_node = rho_t * material.thickness**2 / 12.0 * area * w / 3.0
        beta = np.full(len(tri), float(material.damping_ratio))
        tfm = np.zeros((len(tri), 3, 12))
        if material.membrane == "tension-field":
            t_shape = np.array([
                tension_field_data(xloc[e], material.youngs_modulus, material.poisson_ratio,
                                   material.thickness)
                for e in first
            ])  # fmt: skip
            tfm = t_shape[which.ravel()]
            tfm[:, :, 9:] *= w[:, None, None]  # the modulus times the weighted volume
        return cls(tri, kl, xloc, frames, beta, m_node, j_node, tfm)

    @classmethod
    def concatenate(cls, groups: list[ShellGroup]) -> ShellGroup:
        """One group holding the triangles of ``groups`` in order."""

        def cat(name):
            return np.concatenate([getattr(g, name) for g in groups])

        return cls(cat("triangles"), cat("kl"), cat("xloc"), cat("frame0"), cat("beta"),
                   cat("_node_mass"), cat("_node_inertia"), cat("tension_field"))  # fmt: skip

    def renumber(self, offset: int) -> None:
        """Raise the node ids by ``offset`` (from mesh-local to model numbering)."""
        self.triangles = self.triangles + int(offset)

    def element_dofs(self) -> np.ndarray:
        m = len(self.triangles)
        return (6 * self.triangles[:, :, None] + np.arange(6)).reshape(m, 18)

    def bind(self, slots: np.ndarray) -> None:
        self.emap = np.ascontiguousarray(slots.reshape(-1, 18, 18))

    def lumped_mass(self, node_count: int) -> np.ndarray:
        mass = np.zeros((node_count, 6))
        for a in range(3):
            np.add.at(mass[:, 0], self.triangles[:, a], self._node_mass)
            np.add.at(mass[:, 3], self.triangles[:, a], self._node_inertia)
        mass[:, 1] = mass[:, 2] = mass[:, 0]
        mass[:, 4] = mass[:, 5] = mass[:, 3]
        return mass

    def nodes(self) -> np.ndarray:
        return np.unique(self.triangles)

    def rotation_nodes(self) -> np.ndarray:
        return self.nodes()

    def _data(self) -> tuple:
        return self.triangles, self.kl, self.xloc, self.frame0, self.beta, self.tension_field

    def forces(self, positions, rotations, velocities, out) -> float:
        return element_forces(*self._data(), positions, rotations, velocities, out)

    def forces_and_tangent(
        self, positions, rotations, velocities, out, data_k, data_c, consistent
    ) -> float:
        kernel = element_tangents if consistent else material_tangents
        return kernel(*self._data(), positions, rotations, velocities, out, data_k, data_c,
                      self.emap)  # fmt: skip

    def node_pairs(self) -> np.ndarray:
        t = self.triangles
        return np.column_stack([t.ravel(), np.roll(t, -1, axis=1).ravel()])

    def fingerprint_arrays(self) -> list[np.ndarray]:
        arrays = [np.array(self.kind), self.triangles, self.xloc, self.beta]
        relaxed = self.tension_field[:, 0, 9] != 0.0
        # only a model with a tension field adds it: elastic models keep their fingerprints
        return arrays + [relaxed] if relaxed.any() else arrays

    def characteristic_length(self) -> float | None:
        x = self.xloc
        area = 0.5 * np.abs(
            (x[:, 1, 0] - x[:, 0, 0]) * (x[:, 2, 1] - x[:, 0, 1])
            - (x[:, 2, 0] - x[:, 0, 0]) * (x[:, 1, 1] - x[:, 0, 1])
        )
        return float(np.sqrt(np.mean(area))) if area.size else None
