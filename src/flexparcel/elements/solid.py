"""Co-rotational linear solids: hex8 (incompatible modes), wedge6, pyr5 (Bedrosian), tet4.

Formulation (element-independent co-rotational, Rankin & Brogan 1986; for solids e.g. Crisfield &
Moita 1996, IJNME 39:2619; Felippa & Haugen 2005, CMAME 194:2285):

* Each element carries a rotation ``R`` (3, 3), the rotation factor of the polar decomposition
  ``F = R U`` of its *volume-averaged* deformation gradient
  ``F = (1/V) int grad_X x dV = sum_a x_a (x) g_a`` with ``g_a = (1/V) int grad_X N_a dV``
  (computed once from the reference geometry; exact for every element type, equal to the constant
  F of a tet4). ``R`` is computed by Higham's scaled Newton iteration ``X <- (g X + X^-T / g) / 2``
  (Higham 1986, SIAM J. Sci. Stat. Comput. 7:1160), quadratically convergent, 2-4 iterations for
  small strains, loops only (numba-friendly); elements with ``det F <= 0`` (inverted) fall back to
  the closest proper rotation (SVD via a Jacobi eigen-decomposition of F^T F) so that forces stay
  finite and push back; the kernels report ``det F`` so that the integrator can reject the step.
* Local deformational displacements (3k,): ``u_l,a = R^T (x_a - x_c) - (X_a - X_c)`` with
  ``x_c, X_c`` the node averages. They are small under arbitrarily large rigid motion.
* The local response is linear and small-strain: ``E = 1/2 u_l^T K_l u_l`` with ``K_l`` (3k, 3k)
  the linear isotropic stiffness integrated once by Gauss quadrature on the reference geometry.
* Internal force ``f_a = R (K_l u_l)_a`` (and ``f = R K_l u_l`` is the gradient of ``E`` up to the
  term from the derivative of ``R``, which is proportional to the moment
  ``sum_a R^T(x_a - x_c) x (K_l u_l)_a``: it vanishes for a rigid motion and for any constant-strain
  state of an isotropic material, e.g. always for tet4, and is of order |strain| * |stress| * V
  otherwise: measured 5e-4 (hex8) to 1.4e-3 (wedge6) of max|f_a| * size at a 10 % deformation).
* Damping: RecurDyn FFlex "damping ratio" beta [s], stiffness-proportional Rayleigh damping
  ``C = beta K_m`` with ``K_m = R K_l R^T`` (block-diagonal ``R``), the co-rotational *material*
  stiffness at the current configuration. The damping force is ``f_d = C v = beta R K_l R^T v``:
  rigid translations are exactly undamped, a rigid spin of an undeformed element is exactly
  undamped, a spin of a deformed element is damped at order |strain| * |spin|.
* Tangent: ``solid_material_tangents`` returns the material tangent ``K_m = R K_l R^T`` only; the
  geometric (rotation-derivative) terms are omitted. They scale with the element stress, so the
  tangent is exact at stress-free configurations (any rigid motion of the reference) and a
  modified-Newton approximation elsewhere; this is what the integrator uses by default.

Element technology (all isoparametric, 3 translational DOFs per node, DOFs node-major
``[u_0x, u_0y, u_0z, u_1x, ...]``):

* hex8: trilinear + the three incompatible (Wilson) modes ``1 - xi^2, 1 - eta^2, 1 - zeta^2`` per
  displacement component, statically condensed (QM6: Wilson, Taylor, Doherty & Ghaboussi 1973;
  Taylor, Beresford & Wilson 1976, IJNME 10:1211). Their gradients use the centroid Jacobian
  ``J0`` scaled by ``det J0 / det J``, so that ``int grad P dV = 0`` exactly and the element passes
  the patch test on distorted meshes. Why not B-bar / selective reduced integration: those cure
  only *volumetric* locking (nu -> 1/2); the dominant defect of the trilinear hex in bending is
  parasitic shear (shear locking: the 10x1x1-element cantilever of the tests deflects 36 % too
  little), which the incompatible modes remove: QM6 represents pure bending of a rectangular
  element exactly (cantilever error -0.35 % at nu = 0), and it is equivalent to the EAS-9
  enhanced-strain element (Simo & Rifai 1990, IJNME 29:1595), which also relieves volumetric
  locking in bending (10x1x1 cantilever at nu = 0.49: -8 %, of which several % are the clamp's
  Poisson restraint; tet4 on a 6x finer mesh: -90 %). Full 2x2x2 Gauss: no hourglass modes.
  Limitations: on strongly distorted (trapezoidal) meshes the bending accuracy degrades (as for
  every 8-node hex), and for nu -> 0.5 it is not fully locking-free.
* wedge6: linear triangle x linear line, 3-point triangle rule (degree 2) x 2-point Gauss. No
  enhancement, so stiffer than hex8 in bending (test cantilever, 20x2x2 hexes split into 2 wedges
  each: -13 % with the triangles across the thickness, -50 % with them in the bending plane).
* pyr5: the rational Bedrosian basis (Bedrosian 1992, IJNME 35:95; Bergot, Cohen & Durufle 2010)
  ``N_i = 1/4 [(1 + xi_i xi)(1 + eta_i eta) - zeta + xi_i eta_i xi eta zeta / (1 - zeta)]`` for
  the base, ``N_4 = zeta`` at the apex, on the reference pyramid with base ``[-1, 1]^2`` at
  ``zeta = 0`` and apex ``(0, 0, 1)``. It is bilinear on the base (conforming with hex8 faces) and
  linear on the triangular faces (conforming with tet4), reproduces linear fields and is
  non-negative. Quadrature: 2x2x2 Gauss on the collapsed cube ``xi = u (1 - zeta)``,
  ``eta = v (1 - zeta)`` (weight ``(1 - zeta)^2``); in these coordinates ``N`` and
  ``d N / d(xi, eta, zeta)`` are polynomials, so volume, mass and ``int grad N dV`` are exact
  (patch test) and the stiffness of an affine pyramid is exact.
* tet4: linear, one-point (exact). Constant strain: locks in bending (test cantilever, hexes split
  into 6 tets: -50 % on 20x2x2, -21 % on 40x4x4) and for nu -> 0.5 (-98 % at nu = 0.499).
  pyr5 in the same test (6 pyramids per hex around a centre node): -20 % on 20x2x2.

Node orderings are VTK's (so meshio/ParaView output needs no permutation), with reference
coordinates:

* hex8 (VTK_HEXAHEDRON 12): base ``0-1-2-3`` counter-clockwise seen from the top face ``4-5-6-7``
  (right-hand normal of the base points into the element), node ``a + 4`` above node ``a``:
  ``(-1,-1,-1) (1,-1,-1) (1,1,-1) (-1,1,-1) (-1,-1,1) (1,-1,1) (1,1,1) (-1,1,1)``.
* wedge6 (VTK_WEDGE 13): triangle ``0-1-2`` whose right-hand normal points towards the triangle
  ``3-4-5``, node ``a + 3`` above node ``a``: ``(r, s, t) = (0,0,-1) (1,0,-1) (0,1,-1) (0,0,1)
  (1,0,1) (0,1,1)``. This is the ordering of VTK's shape functions (vtkWedge
  InterpolationFunctions) and of gmsh; the vtkWedge class comment that says the normal points
  *away* from ``3-4-5`` is a known documentation inconsistency (Kitware/vtk-examples PR #9,
  which corrected the quadratic wedge docs and the linear-cells demo).
* pyr5 (VTK_PYRAMID 14): base ``0-1-2-3`` whose right-hand normal points towards the apex ``4``:
  ``(-1,-1,0) (1,-1,0) (1,1,0) (-1,1,0) (0,0,1)``.
* tet4 (VTK_TETRA 10): ``0-1-2`` whose right-hand normal points towards ``3``, i.e.
  ``(x1 - x0) x (x2 - x0) . (x3 - x0) > 0``: ``(0,0,0) (1,0,0) (0,1,0) (0,0,1)``.

An element whose Jacobian determinant is not positive at a Gauss point or at a vertex (the
pyramid apex excepted, where the rational basis is singular by construction) is rejected.

Lumped mass: row sums of the consistent mass matrix, ``m_a = rho int N_a dV`` (all shape functions
are non-negative, so every nodal mass is positive; the quadratures are exact, so the element masses
sum to ``rho V`` exactly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from flexparcel.model.interfaces import TranslationalElementGroup
from flexparcel.model.materials import validate_elastic

__all__ = [
    "SolidGroup",
    "ELEMENT_KINDS",
    "SolidMaterial",
    "SolidReference",
    "centre_shape_gradients",
    "polar_rotation",
    "scatter_forces",
    "solid_forces",
    "solid_material_tangents",
    "solid_reference_data",
]


# --------------------------------------------------------------------------- material
@dataclass(frozen=True)
class SolidMaterial:
    """Isotropic linear-elastic solid material (small strain, used in the co-rotated frame).

    Attributes:
        youngs_modulus: Young's modulus E [Pa], > 0.
        poisson_ratio: Poisson's ratio nu [-], 0 <= nu < 0.5.
        density: mass density rho [kg/m^3], > 0.
        damping_ratio: RecurDyn's FFlex "Damping Ratio", the stiffness-proportional Rayleigh
            coefficient beta [s] in C = beta * K (mass-proportional term zero), with K the
            co-rotational material stiffness ``R K_l R^T``. It is NOT a fraction of critical
            damping: mode i is damped with zeta_i = beta * omega_i / 2.
    """

    youngs_modulus: float
    poisson_ratio: float
    density: float
    damping_ratio: float = 0.0

    def __post_init__(self) -> None:
        validate_elastic(self, "SolidMaterial")

    @property
    def shear_modulus(self) -> float:
        """Shear modulus mu = G = E / (2 (1 + nu)) [Pa]."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))

    @property
    def lame_lambda(self) -> float:
        """First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) [Pa]."""
        e, nu = self.youngs_modulus, self.poisson_ratio
        return e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))

    @property
    def wave_speed(self) -> float:
        """Dilatational (P-) wave speed sqrt((lambda + 2 mu) / rho) [m/s]."""
        return math.sqrt((self.lame_lambda + 2.0 * self.shear_modulus) / self.density)


# --------------------------------------------------------------------------- reference elements
ELEMENT_KINDS = {"hex8": 8, "wedge6": 6, "pyr5": 5, "tet4": 4}
"""Element kinds and their node counts. meshio/VTK names are accepted as aliases."""

_ALIASES = {"hexahedron": "hex8", "wedge": "wedge6", "pyramid": "pyr5", "tetra": "tet4"}

_HEX_NODES = np.array(
    [
        [-1, -1, -1],
        [1, -1, -1],
        [1, 1, -1],
        [-1, 1, -1],
        [-1, -1, 1],
        [1, -1, 1],
        [1, 1, 1],
        [-1, 1, 1],
    ],
    dtype=float,
)
_WEDGE_NODES = np.array(
    [[0, 0, -1], [1, 0, -1], [0, 1, -1], [0, 0, 1], [1, 0, 1], [0, 1, 1]], dtype=float
)
_PYR_NODES = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 1]], dtype=float)
_TET_NODES = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=float)
_NODES = {"hex8": _HEX_NODES, "wedge6": _WEDGE_NODES, "pyr5": _PYR_NODES, "tet4": _TET_NODES}
_CENTROIDS = {
    "hex8": np.zeros(3),
    "wedge6": np.array([1 / 3, 1 / 3, 0.0]),
    "pyr5": np.array([0.0, 0.0, 0.25]),
    "tet4": np.full(3, 0.25),
}
_GAUSS2 = np.array([-1.0, 1.0]) / math.sqrt(3.0)  # 2-point Gauss-Legendre on [-1, 1], weights 1


def _shape_functions(kind: str, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (q, k) and parametric derivatives dN/d(xi, eta, zeta) (q, k, 3) at
    reference points p (q, 3)."""
    p = np.atleast_2d(p)
    q = p.shape[0]
    if kind == "hex8":
        c = _HEX_NODES
        f = 1.0 + p[:, None, :] * c[None, :, :]  # (q, 8, 3): 1 + xi_a xi etc.
        n = 0.125 * f.prod(axis=2)
        dn = np.empty((q, 8, 3))
        dn[..., 0] = 0.125 * c[:, 0] * f[..., 1] * f[..., 2]
        dn[..., 1] = 0.125 * c[:, 1] * f[..., 0] * f[..., 2]
        dn[..., 2] = 0.125 * c[:, 2] * f[..., 0] * f[..., 1]
        return n, dn
    if kind == "wedge6":
        r, s, t = p[:, 0], p[:, 1], p[:, 2]
        tri = np.stack([1.0 - r - s, r, s], axis=1)  # (q, 3)
        dtri = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
        lo, hi = 0.5 * (1.0 - t), 0.5 * (1.0 + t)
        n = np.concatenate([tri * lo[:, None], tri * hi[:, None]], axis=1)
        dn = np.empty((q, 6, 3))
        for a in range(3):
            dn[:, a, 0:2] = dtri[a] * lo[:, None]
            dn[:, a + 3, 0:2] = dtri[a] * hi[:, None]
            dn[:, a, 2] = -0.5 * tri[:, a]
            dn[:, a + 3, 2] = 0.5 * tri[:, a]
        return n, dn
    if kind == "pyr5":
        xi, eta, zeta = p[:, 0], p[:, 1], p[:, 2]
        if np.any(zeta >= 1.0):
            raise ValueError("the pyramid basis is singular at the apex (zeta = 1)")
        om = 1.0 - zeta
        n = np.empty((q, 5))
        dn = np.empty((q, 5, 3))
        for a in range(4):
            xa, ea = _PYR_NODES[a, 0], _PYR_NODES[a, 1]
            n[:, a] = 0.25 * (
                (1.0 + xa * xi) * (1.0 + ea * eta) - zeta + xa * ea * xi * eta * zeta / om
            )
            dn[:, a, 0] = 0.25 * (xa * (1.0 + ea * eta) + xa * ea * eta * zeta / om)
            dn[:, a, 1] = 0.25 * (ea * (1.0 + xa * xi) + xa * ea * xi * zeta / om)
            dn[:, a, 2] = 0.25 * (-1.0 + xa * ea * xi * eta / om**2)
        n[:, 4] = zeta
        dn[:, 4] = [0.0, 0.0, 1.0]
        return n, dn
    if kind == "tet4":
        n = np.stack([1.0 - p.sum(axis=1), p[:, 0], p[:, 1], p[:, 2]], axis=1)
        dn = np.broadcast_to(
            np.array([[-1.0, -1.0, -1.0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]), (q, 4, 3)
        ).copy()
        return n, dn
    raise AssertionError(kind)


def centre_shape_gradients(kind: str) -> np.ndarray:
    """Derivatives dN/d(xi, eta, zeta) (k, 3) of ``kind``'s shape functions at its
    reference centroid: with node positions ``x`` (k, 3), ``x.T @ dN`` is the element's
    Jacobian there (its sign tells the element's orientation, its ratio to the reference
    one the mean deformation of a linear element)."""
    key = _normalise_kind(kind)
    return _shape_functions(key, _CENTROIDS[key])[1][0]


def _quadrature(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Gauss points (q, 3) in reference coordinates and weights (q,) (sum = reference volume)."""
    g = _GAUSS2
    if kind == "hex8":  # 2x2x2 Gauss: full integration, no hourglass modes
        pts = np.array([[x, y, z] for z in g for y in g for x in g])
        return pts, np.ones(8)
    if kind == "wedge6":  # 3-point interior triangle rule (degree 2) x 2-point Gauss in t
        tri = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
        pts = np.array([[r, s, t] for t in g for r, s in tri])
        return pts, np.full(6, 1.0 / 6.0)
    if kind == "pyr5":  # collapsed 2x2x2 Gauss: xi = u (1 - zeta), weight (1 - zeta)^2
        pts, w = [], []
        for t in g:
            zeta = 0.5 * (1.0 + t)
            om = 1.0 - zeta
            for v in g:
                for u in g:
                    pts.append([u * om, v * om, zeta])
                    w.append(0.5 * om * om)
        return np.array(pts), np.array(w)
    if kind == "tet4":
        return np.full((1, 3), 0.25), np.array([1.0 / 6.0])
    raise AssertionError(kind)


def _jacobians(xe: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """Jacobians dX/dxi (m, q, 3, 3) of elements with node coordinates xe (m, k, 3) [m]."""
    return np.einsum("mai,qaj->mqij", xe, dn)


# --------------------------------------------------------------------------- reference data
class SolidReference(NamedTuple):
    """Reference data of m solid elements with k nodes each (computed once, SI units)."""

    kl: np.ndarray
    """Local linear stiffness K_l [N/m], shape (m, 3k, 3k), node-major DOFs."""
    xref: np.ndarray
    """Reference node positions relative to the node average, X_a - X_c [m], shape (m, k, 3)."""
    grad: np.ndarray
    """Volume-averaged shape-function gradients g_a = (1/V) int grad_X N_a dV [1/m], (m, k, 3);
    the mean deformation gradient is ``F = sum_a x_a (x) g_a``."""
    mass: np.ndarray
    """Lumped nodal masses rho int N_a dV [kg], shape (m, k)."""
    volume: np.ndarray
    """Element volumes [m^3], shape (m,)."""


def _normalise_kind(kind: str) -> str:
    if not isinstance(kind, str):
        raise ValueError(f"solid element kind must be a string, got {kind!r}")
    key = _ALIASES.get(kind.lower(), kind.lower())
    if key not in ELEMENT_KINDS:
        allowed = ", ".join(list(ELEMENT_KINDS) + list(_ALIASES))
        raise ValueError(f"unknown solid element kind {kind!r}; allowed: {allowed}")
    return key


def _check_input(points, cells, kind: str) -> tuple[np.ndarray, np.ndarray]:
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points must have shape (node_count, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        bad = int(np.flatnonzero(~np.isfinite(pts).all(axis=1))[0])
        raise ValueError(f"points must be finite; node {bad} is {pts[bad].tolist()}")
    k = ELEMENT_KINDS[kind]
    c = np.asarray(cells)
    if c.ndim != 2 or c.shape[1] != k:
        raise ValueError(f"{kind} cells must have shape (element_count, {k}), got {c.shape}")
    if c.shape[0] == 0:
        raise ValueError(f"no {kind} cells given")
    if not np.issubdtype(c.dtype, np.integer):
        if not np.all(np.isfinite(c)) or np.any(c != np.round(c)):
            raise ValueError(f"{kind} cells must hold integer node ids")
    c = c.astype(np.int64)
    out = (c < 0) | (c >= pts.shape[0])
    if out.any():
        e = int(np.flatnonzero(out.any(axis=1))[0])
        raise ValueError(
            f"{kind} element {e} (nodes {c[e].tolist()}) refers to nodes outside 0..."
            f"{pts.shape[0] - 1}"
        )
    srt = np.sort(c, axis=1)
    rep = (srt[:, 1:] == srt[:, :-1]).any(axis=1)
    if rep.any():
        e = int(np.flatnonzero(rep)[0])
        raise ValueError(
            f"{kind} element {e} (nodes {c[e].tolist()}) is degenerate: it repeats a node id"
        )
    return pts, c


def _check_jacobians(kind, cells, xe, det, where) -> None:
    """Raise if any determinant (m, p) is non-positive (relative to the element size)."""
    size = np.linalg.norm(xe - xe.mean(axis=1, keepdims=True), axis=2).max(axis=1)  # (m,)
    bad = det <= 1e-10 * size[:, None] ** 3
    if bad.any():
        e, p = (int(i) for i in np.argwhere(bad)[0])
        count = int(bad.any(axis=1).sum())
        order = {
            "hex8": "base 0-1-2-3 counter-clockwise seen from 4-5-6-7",
            "wedge6": "triangle 0-1-2 counter-clockwise seen from 3-4-5",
            "pyr5": "base 0-1-2-3 counter-clockwise seen from the apex 4",
            "tet4": "(x1-x0) x (x2-x0) . (x3-x0) > 0",
        }[kind]
        raise ValueError(
            f"{kind} element {e} (nodes {cells[e].tolist()}) is inverted or degenerate: Jacobian "
            f"determinant {det[e, p]:.3g} <= 0 at {where(p)} ({count} bad element(s) in all); "
            f"check the node ordering (VTK: {order})"
        )


def _gradients(j: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """Physical gradients (m, q, k, 3) from Jacobians j (m, q, 3, 3) and dN (q, k, 3)."""
    jinv = np.linalg.inv(j)
    return np.einsum("qaj,mqji->mqai", dn, jinv)


def _isotropic_stiffness(g: np.ndarray, wdet: np.ndarray, lam: float, mu: float) -> np.ndarray:
    """K (m, 3k, 3k) = sum_q w det J B^T D B for gradients g (m, q, k, 3), wdet (m, q).

    Block (a, b): ``K_ab,ij = sum_q w det J [lam g_ai g_bj + mu g_aj g_bi + mu d_ij g_a.g_b]``,
    the Hessian of ``lam/2 (tr eps)^2 + mu eps:eps``."""
    m, q, k, _ = g.shape
    gf = g.reshape(m, q, 3 * k)
    a = (np.swapaxes(gf * wdet[:, :, None], 1, 2) @ gf).reshape(m, k, 3, k, 3)  # sum gw_ai g_bj
    kk = lam * a + mu * a.transpose(0, 1, 4, 3, 2)  # + mu sum gw_aj g_bi
    dot = np.einsum("maibi->mab", a)  # sum gw_a . g_b
    kk += mu * dot[:, :, None, :, None] * np.eye(3)[None, None, :, None, :]
    return kk.reshape(m, 3 * k, 3 * k)


def _incompatible_gradients(kind, xe, det) -> np.ndarray | None:
    """Gradients (m, q, 3, 3) of the hex8 incompatible modes P_c = 1 - xi_c^2 at the Gauss points,
    with the centroid Jacobian and the factor det J0 / det J (Taylor et al. 1976)."""
    if kind != "hex8":
        return None
    pts, _ = _quadrature(kind)
    _, dn0 = _shape_functions(kind, np.zeros((1, 3)))
    j0 = _jacobians(xe, dn0)[:, 0]  # (m, 3, 3)
    j0inv = np.linalg.inv(j0)
    det0 = np.linalg.det(j0)
    dp = np.zeros((pts.shape[0], 3, 3))  # (q, mode c, d/dxi_j)
    for c in range(3):
        dp[:, c, c] = -2.0 * pts[:, c]
    g = np.einsum("qcj,mji->mqci", dp, j0inv)
    return g * (det0[:, None] / det)[:, :, None, None]


def solid_reference_data(
    points: np.ndarray, cells: np.ndarray, kind: str, material: SolidMaterial
) -> SolidReference:
    """Reference data of one block of solid elements of a single kind and material.

    Args:
        points: reference node positions [m], shape (node_count, 3).
        cells: node ids per element, shape (m, k), in VTK order (see the module docstring).
        kind: "hex8", "wedge6", "pyr5" or "tet4" (meshio names "hexahedron", "wedge",
            "pyramid", "tetra" are accepted).
        material: the SolidMaterial of all elements of the block.

    Returns:
        SolidReference(kl (m, 3k, 3k) [N/m], xref (m, k, 3) [m], grad (m, k, 3) [1/m],
        mass (m, k) [kg], volume (m,) [m^3]).

    Raises:
        ValueError: unknown kind, bad shapes, node ids out of range or repeated, non-finite
            points, or an inverted/degenerate element (named with its index and node ids).
    """
    if not isinstance(material, SolidMaterial):
        raise TypeError(f"material must be a SolidMaterial, got {type(material).__name__}")
    kind = _normalise_kind(kind)
    pts, c = _check_input(points, cells, kind)
    k = ELEMENT_KINDS[kind]
    lam, mu, rho = material.lame_lambda, material.shear_modulus, material.density

    # vertex Jacobians (the pyramid apex excepted): catches inverted corners of hexes and wedges
    vert = _NODES[kind] if kind != "pyr5" else _PYR_NODES[:4]
    _, dnv = _shape_functions(kind, vert)
    qp, qw = _quadrature(kind)
    nq, dnq = _shape_functions(kind, qp)

    m = c.shape[0]
    kl = np.empty((m, 3 * k, 3 * k))
    grad = np.empty((m, k, 3))
    mass = np.empty((m, k))
    volume = np.empty(m)
    chunk = 4096
    for s in range(0, m, chunk):
        sl = slice(s, min(s + chunk, m))
        ce = c[sl]
        xe = pts[ce]  # (mc, k, 3)
        detv = np.linalg.det(_jacobians(xe, dnv))
        _check_jacobians(kind, ce, xe, detv, lambda p: f"vertex {p}")
        jq = _jacobians(xe, dnq)
        det = np.linalg.det(jq)  # (mc, q)
        _check_jacobians(kind, ce, xe, det, lambda p: f"Gauss point {p}")
        wdet = det * qw[None, :]
        g = _gradients(jq, dnq)  # (mc, q, k, 3)
        vol = wdet.sum(axis=1)
        volume[sl] = vol
        grad[sl] = np.einsum("mq,mqai->mai", wdet, g) / vol[:, None, None]
        mass[sl] = rho * np.einsum("mq,qa->ma", wdet, nq)
        ginc = _incompatible_gradients(kind, xe, det)
        if ginc is None:
            kl[sl] = _isotropic_stiffness(g, wdet, lam, mu)
        else:  # static condensation of the incompatible modes: K_uu - K_ua K_aa^-1 K_au
            kext = _isotropic_stiffness(np.concatenate([g, ginc], axis=2), wdet, lam, mu)
            n = 3 * k
            kua = kext[:, :n, n:]
            cond = kua @ np.linalg.solve(kext[:, n:, n:], np.swapaxes(kua, 1, 2))
            kl[sl] = kext[:, :n, :n] - cond
    kl = 0.5 * (kl + np.swapaxes(kl, 1, 2))  # symmetric to round-off
    xe = pts[c]
    xref = xe - xe.mean(axis=1, keepdims=True)
    return SolidReference(kl, np.ascontiguousarray(xref), grad, mass, volume)


# --------------------------------------------------------------------------- kernels
@nb.njit(cache=True)
def _det3(a):
    return (
        a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
        - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
        + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0])
    )


@nb.njit(cache=True)
def _cofactor(a):
    """Cofactor matrix cof(A) = det(A) A^-T, shape (3, 3)."""
    c = np.empty((3, 3))
    c[0, 0] = a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]
    c[0, 1] = a[1, 2] * a[2, 0] - a[1, 0] * a[2, 2]
    c[0, 2] = a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]
    c[1, 0] = a[0, 2] * a[2, 1] - a[0, 1] * a[2, 2]
    c[1, 1] = a[0, 0] * a[2, 2] - a[0, 2] * a[2, 0]
    c[1, 2] = a[0, 1] * a[2, 0] - a[0, 0] * a[2, 1]
    c[2, 0] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    c[2, 1] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    c[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    return c


@nb.njit(cache=True)
def _sym_eig3(c):
    """Eigenvalues (3,) in descending order and eigenvectors (3, 3) (columns, det +1) of a
    symmetric 3x3 matrix, by cyclic Jacobi rotations (loops only; any multiplicity)."""
    a = c.copy()
    v = np.eye(3)
    scale = 0.0
    for i in range(3):
        for j in range(3):
            scale += a[i, j] * a[i, j]
    for _ in range(50):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        if off <= 1e-32 * scale:
            break
        for pair in range(3):
            p = 0 if pair < 2 else 1
            q = 1 if pair == 0 else 2
            if a[p, q] == 0.0:
                continue
            theta = 0.5 * (a[q, q] - a[p, p]) / a[p, q]
            t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
            cs = 1.0 / math.sqrt(t * t + 1.0)
            sn = t * cs
            for k in range(3):  # a <- a G (columns p, q)
                akp, akq = a[k, p], a[k, q]
                a[k, p] = cs * akp - sn * akq
                a[k, q] = sn * akp + cs * akq
            for k in range(3):  # a <- G^T a (rows p, q)
                apk, aqk = a[p, k], a[q, k]
                a[p, k] = cs * apk - sn * aqk
                a[q, k] = sn * apk + cs * aqk
            for k in range(3):
                vkp, vkq = v[k, p], v[k, q]
                v[k, p] = cs * vkp - sn * vkq
                v[k, q] = sn * vkp + cs * vkq
    order = np.empty(3, np.int64)  # descending
    for j in range(3):
        order[j] = j
    for i in range(3):
        for j in range(2 - i):
            if a[order[j], order[j]] < a[order[j + 1], order[j + 1]]:
                order[j], order[j + 1] = order[j + 1], order[j]
    ws = np.empty(3)
    vs = np.empty((3, 3))
    for j in range(3):
        ws[j] = a[order[j], order[j]]
        for i in range(3):
            vs[i, j] = v[i, order[j]]
    if _det3(vs) < 0.0:
        for i in range(3):
            vs[i, 2] = -vs[i, 2]
    return ws, vs


@nb.njit(cache=True)
def _closest_rotation(f):
    """Closest proper rotation to any F (3, 3): ``U diag(1, 1, det(U V^T)) V^T`` from the SVD
    ``F = U S V^T``, built as ``u1 v1^T + u2 v2^T + (u1 x u2) v3^T`` with ``u_i = F v_i / s_i``
    (needs rank F >= 2; identity otherwise)."""
    c = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                c[i, j] += f[k, i] * f[k, j]
    w, v = _sym_eig3(c)
    if not w[1] > 1e-28 * max(w[0], 1e-300):
        return np.eye(3)
    u = np.zeros((3, 3))
    for j in range(2):
        s = math.sqrt(w[j])
        for i in range(3):
            for k in range(3):
                u[i, j] += f[i, k] * v[k, j] / s
    u[0, 2] = u[1, 0] * u[2, 1] - u[2, 0] * u[1, 1]
    u[1, 2] = u[2, 0] * u[0, 1] - u[0, 0] * u[2, 1]
    u[2, 2] = u[0, 0] * u[1, 1] - u[1, 0] * u[0, 1]
    r = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                r[i, j] += u[i, k] * v[j, k]
    return r


@nb.njit(cache=True)
def polar_rotation(f):
    """Rotation factor R (3, 3) of the polar decomposition F = R U of F (3, 3), det F > 0.

    Higham's scaled Newton iteration ``X <- (g X + X^-T / g) / 2`` with the Frobenius-norm
    scaling ``g = (|X^-1| / |X|)^(1/2)`` (Higham 1986); quadratic convergence, stopped one step
    after the update falls below 1e-8 (final orthogonality error ~1e-16). For det F <= 0 (an
    inverted element) it returns the closest proper rotation ``U diag(1, 1, -1) V^T`` of the SVD
    ``F = U S V^T`` (Jacobi eigen-decomposition of F^T F); NaN for a non-finite F.
    """
    x = f.copy()
    det = _det3(x)
    if not np.isfinite(det):
        return np.full((3, 3), np.nan)
    if not det > 0.0:
        return _closest_rotation(x)
    last = False
    for _ in range(100):
        cof = _cofactor(x)
        det = _det3(x)
        nx = 0.0
        ni = 0.0
        for i in range(3):
            for j in range(3):
                nx += x[i, j] * x[i, j]
                ni += cof[i, j] * cof[i, j]
        ni /= det * det  # |X^-T|^2
        g = 1.0 if last else math.sqrt(math.sqrt(ni / nx))
        diff = 0.0
        for i in range(3):
            for j in range(3):
                xn = 0.5 * (g * x[i, j] + cof[i, j] / (g * det))
                d = xn - x[i, j]
                diff += d * d
                x[i, j] = xn
        if last:
            break
        if diff < 1e-16:
            last = True
    return x


@nb.njit(cache=True)
def _corotate(e, cells, xref, grad, pos):
    """Current nodes x (k, 3), rotation R, local displacements u_l (3k,), det F of element e."""
    k = cells.shape[1]
    x = np.empty((k, 3))
    xc = np.zeros(3)
    f = np.zeros((3, 3))
    for a in range(k):
        n = cells[e, a]
        for i in range(3):
            xi = pos[n, i]
            x[a, i] = xi
            xc[i] += xi
            for j in range(3):
                f[i, j] += xi * grad[e, a, j]
    jac = _det3(f)
    r = polar_rotation(f)
    ul = np.empty(3 * k)
    for a in range(k):
        d0 = x[a, 0] - xc[0] / k
        d1 = x[a, 1] - xc[1] / k
        d2 = x[a, 2] - xc[2] / k
        for i in range(3):
            ul[3 * a + i] = r[0, i] * d0 + r[1, i] * d1 + r[2, i] * d2 - xref[e, a, i]
    return r, ul, jac


@nb.njit(cache=True)
def _element_force(e, cells, kl, xref, grad, beta, pos, vel, fe, energy, vol_ratio):
    """f = R K_l (u_l + beta R^T v) into fe[e]; strain energy 1/2 u_l^T K_l u_l into energy[e]."""
    k = cells.shape[1]
    n = 3 * k
    r, ul, jac = _corotate(e, cells, xref, grad, pos)
    vol_ratio[e] = jac
    b = beta[e]
    w = ul.copy()
    if b != 0.0:
        for a in range(k):
            node = cells[e, a]
            for i in range(3):
                w[3 * a + i] += b * (
                    r[0, i] * vel[node, 0] + r[1, i] * vel[node, 1] + r[2, i] * vel[node, 2]
                )
    s = np.empty(n)
    en = 0.0
    for i in range(n):
        acc = 0.0
        acc_u = 0.0
        if b != 0.0:
            for j in range(n):
                kij = kl[e, i, j]
                acc += kij * w[j]
                acc_u += kij * ul[j]
        else:
            for j in range(n):
                acc += kl[e, i, j] * ul[j]
            acc_u = acc
        s[i] = acc
        en += 0.5 * ul[i] * acc_u
    energy[e] = en
    for a in range(k):
        for i in range(3):
            fe[e, 3 * a + i] = r[i, 0] * s[3 * a] + r[i, 1] * s[3 * a + 1] + r[i, 2] * s[3 * a + 2]
    return r


@nb.njit(cache=True, parallel=True)
def solid_forces(cells, kl, xref, grad, beta, pos, vel, fe, energy, vol_ratio):
    """Co-rotational internal + damping force blocks of m solid elements (parallel over elements).

    Inputs: ``cells`` (m, k) C-contiguous int64 node ids (other layouts/dtypes work but compile
    another specialisation, ~10 s); ``kl`` (m, 3k, 3k) [N/m], ``xref`` (m, k, 3) [m],
    ``grad`` (m, k, 3) [1/m] from ``solid_reference_data``; ``beta`` (m,) Rayleigh coefficients
    [s]; ``pos`` (n, 3) current node positions [m]; ``vel`` (n, 3) node velocities [m/s].

    Outputs (written): ``fe`` (m, 3k) element forces [N], node-major, ``f = R K_l (u_l + beta R^T
    v)`` (the internal force the nodes exert on the element: the residual is ``M a + f - f_ext``);
    ``energy`` (m,) strain energy [J]; ``vol_ratio`` (m,) det of the mean deformation gradient
    (<= 0: the element is inverted, the step should be rejected).
    """
    for e in nb.prange(cells.shape[0]):
        _element_force(e, cells, kl, xref, grad, beta, pos, vel, fe, energy, vol_ratio)


@nb.njit(cache=True, parallel=True)
def solid_material_tangents(cells, kl, xref, grad, beta, pos, vel, fe, energy, vol_ratio, ke):
    """As ``solid_forces``, plus the material tangent blocks ``ke`` (m, 3k, 3k) [N/m]:
    ``K_m = R K_l R^T`` (block-diagonal R). The geometric terms from the derivative of R are
    omitted (exact at stress-free states). The Rayleigh damping matrix is ``C_e = beta[e] K_m``
    (scale ``ke[e]`` by ``beta[e]`` when scattering), and ``d fe / d v = C_e`` exactly.
    """
    k = cells.shape[1]
    for e in nb.prange(cells.shape[0]):
        r = _element_force(e, cells, kl, xref, grad, beta, pos, vel, fe, energy, vol_ratio)
        t = np.empty((3, 3))
        for a in range(k):
            for b in range(k):
                # t = K_ab R^T, then ke_ab = R t
                for i in range(3):
                    for j in range(3):
                        acc = 0.0
                        for p in range(3):
                            acc += kl[e, 3 * a + i, 3 * b + p] * r[j, p]
                        t[i, j] = acc
                for i in range(3):
                    for j in range(3):
                        ke[e, 3 * a + i, 3 * b + j] = (
                            r[i, 0] * t[0, j] + r[i, 1] * t[1, j] + r[i, 2] * t[2, j]
                        )


@nb.njit(cache=True)
def scatter_forces(cells, fe, out):
    """Serially add element force blocks fe (m, 3k) [N] into nodal forces out (n, 3) (a fixed
    summation order keeps results deterministic)."""
    k = cells.shape[1]
    for e in range(cells.shape[0]):
        for a in range(k):
            for i in range(3):
                out[cells[e, a], i] += fe[e, 3 * a + i]


# --------------------------------------------------------------------------- element group
class SolidGroup(TranslationalElementGroup):
    """A block of co-rotational solid elements of one kind and material; 3 translational
    DOFs per node (the nodes' rotations carry nothing of it).

    ``growth`` (full-size ``xref`` (m, k, 3) [m], Schedule of the scale factor) or None: the
    assembly grows a flexible content into its packaging by scaling the reference geometry
    at every step (:meth:`at_time`), so the elements expand smoothly.
    """

    kind = "solid"

    def __init__(self, points: np.ndarray, cells, kind: str, material: SolidMaterial) -> None:
        ref = solid_reference_data(points, cells, kind, material)  # validates its input
        self.element_kind = _normalise_kind(kind)
        """"hex8", "wedge6", "pyr5" or "tet4"."""
        self.cells = np.ascontiguousarray(cells, dtype=np.int64)
        """Node ids per element in VTK order, shape (m, k)."""
        self.kl, self.xref, self.grad = ref.kl, ref.xref, ref.grad
        self.mass = ref.mass
        """Lumped mass [kg] per element corner, shape (m, k)."""
        self.beta = np.full(len(self.cells), float(material.damping_ratio))
        w = 3 * self.cells.shape[1]
        self.emap = np.zeros((len(self.cells), w, w), np.int64)
        """CSR data slot of each element matrix entry, shape (m, 3k, 3k)."""
        self.growth = None

    def renumber(self, offset: int) -> None:
        """Raise the node ids by ``offset`` (from mesh-local to model numbering)."""
        self.cells = self.cells + int(offset)

    def lumped_mass(self, node_count: int) -> np.ndarray:
        mass = np.zeros((node_count, 6))
        for a in range(self.cells.shape[1]):
            np.add.at(mass[:, 0], self.cells[:, a], self.mass[:, a])
        mass[:, 1] = mass[:, 2] = mass[:, 0]
        return mass

    def at_time(self, time: float) -> None:
        if self.growth is not None:
            full, schedule = self.growth
            self.xref = np.ascontiguousarray(full * schedule(time))

    def _evaluate(self, positions, velocities, out, data_k, data_c) -> float:
        m, k = self.cells.shape
        pos = np.ascontiguousarray(positions)
        vel = np.ascontiguousarray(velocities[:, :3])
        fe = np.empty((m, 3 * k))
        en = np.empty(m)
        vr = np.empty(m)
        args = (self.cells, self.kl, self.xref, self.grad, self.beta, pos, vel, fe, en, vr)
        if data_k is None:
            solid_forces(*args)
        else:
            ke = np.empty((m, 3 * k, 3 * k))
            solid_material_tangents(*args, ke)
            np.add.at(data_k, self.emap.ravel(), ke.ravel())
            np.add.at(data_c, self.emap.ravel(), (self.beta[:, None, None] * ke).ravel())
        f3 = np.zeros((out.shape[0], 3))
        scatter_forces(self.cells, fe, f3)
        out[:, :3] += f3
        if np.any(vr <= 0.0):
            # an inverted element has no meaningful force: poison the residual so the solver
            # rejects the step (and retries smaller) instead of continuing
            out[:] = np.nan
        # the material tangent in both modes (no consistent one yet, see the module docstring)
        return float(en.sum())
