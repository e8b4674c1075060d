"""Linear-static prototype of the rotation-free Basic Shell Triangle (BST), 3 DOF per node.

A research prototype, not an element of flexparcel: it exists to measure candidate (b) of the
shell-formulation choice against the package's co-rotational facet (docs/shell-candidates.md).
numpy + scipy only; written from the papers, not from other code:

* E. Onate, F. Zarate (2000), "Rotation-free triangular plate and shell elements",
  Int. J. Numer. Meth. Engng 47:557-603 (the BST: constant curvature of a triangle from the
  boundary integral of the slopes at its sides, each side slope the average of the two
  triangles sharing the side, so the curvature of a triangle uses its three neighbours).
* F. Flores, E. Onate (2005), "Improvements in the membrane behaviour of the three node
  rotation-free BST shell triangle using an assumed strain approach", CMAME 194:907-932, and
  E. Onate, F. Flores (2005), "Advances in the formulation of the rotation-free basic shell
  triangle", CMAME 194:2406-2443 (the EBST: a quadratic interpolation over the six patch nodes
  gives the displacement gradient at the mid-sides; the membrane strain is built from it).

Bending (BST). With ``w`` linear on each triangle, the BST curvature of triangle M,
``kappa = -(1/A_M) int_dM sym(nu x grad w_side) ds`` with ``grad w_side = (grad w_M +
grad w_J)/2``, reduces (grad w is continuous along the side, its jump is normal to it) to a
sum over the three sides of the relative rotation ``psi_i`` of the neighbour J about the side:
``kappa_M = sum_i l_i / (2 A_M) psi_i (nu_i x nu_i)`` (``nu_i`` the outward in-plane normal of
side i, ``l_i`` its length). For a shell the prototype takes ``psi_i`` as the linearised change
of the dihedral angle at the side, ``psi = dn_J . (e x n_J) - dn_M . (e x n_M)`` (``e`` the unit
side vector, ``dn = -sum_a (n . u_a) grad N_a`` the first variation of a facet normal): on a
flat patch this is exactly the BST; on a curved one it differs from the linearisation of the
BST's large-strain curvature by terms of the order of the initial curvature times the membrane
strain (the usual latitude between thin-shell theories).

Membrane. ``membrane="cst"``: the constant strain triangle (the BST's membrane).
``membrane="ebst"``: the EBST's enhanced membrane in its one-point form (EBST1): at the
mid-point of each side the displacement gradient of the quadratic interpolation over the patch
(the triangle's three nodes plus the vertex of the neighbour across that side; the other two
patch nodes have zero gradient there) gives the linearised metric change ``(X_,a . u_,b +
X_,b . u_,a)/2``; the triangle's membrane strain is the average over its three sides. A side
without a neighbour uses the triangle's own (CST) gradient, as in the paper.

Boundary conditions of the rotation-free shell (translations are fixed node by node; the
rotation enters only through the sides):

* free or simply supported side (no neighbour, rotation free): the side slope is the
  triangle's own, so the side adds no curvature (``psi = 0``);
* clamped side or side on a symmetry plane (rotation about the side held at zero): the side
  slope keeps only its tangential part, ``grad w_side = grad w_M - (grad w_M . nu) nu``; in
  rotation terms this is a ghost triangle mirroring M through the side (rotating opposite to
  M), ``psi = -2 dn_M . (e x n_M)``. Pass those sides as ``rot_fixed`` (see
  :func:`boundary_sides`);
* a rigid diaphragm (Scordelis-Lo, pinched cylinder) holds the two in-plane translations of its
  nodes and nothing else: its sides are free sides.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = [
    "grid_triangles",
    "neighbours",
    "boundary_sides",
    "stiffness",
    "area_loads",
    "solve",
]

# the side opposite local node i joins nodes _SIDE[i] (counter-clockwise along the boundary)
_SIDE = ((1, 2), (2, 0), (0, 1))
# natural coordinates (xi, eta) of the mid-point of the side opposite node i (node 0 at (0, 0),
# node 1 at (1, 0), node 2 at (0, 1))
_MID = ((0.5, 0.5), (0.0, 0.5), (0.5, 0.0))


def grid_triangles(nx: int, ny: int, pattern: str = "alternate") -> np.ndarray:
    """Triangles (2 nx ny, 3) on the grid of nodes ``i + j (nx + 1)`` (that of
    ``flexparcel.model.mesh.rectangle``), counter-clockwise. ``pattern``: "alternate" flips the
    diagonal of the cell (i, j) with the parity of i + j (a mesh symmetric about both centre
    lines when nx, ny are even), "right" always splits along the 0-2 diagonal."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="xy")
    i, j = i.ravel(), j.ravel()
    n0 = i + j * (nx + 1)
    n1, n2, n3 = n0 + 1, n0 + nx + 2, n0 + nx + 1
    if pattern == "right":
        flip = np.zeros(n0.size, dtype=bool)
    elif pattern == "alternate":
        flip = (i + j) % 2 == 1
    else:
        raise ValueError(f"pattern must be 'alternate' or 'right', got {pattern!r}")
    a = np.where(flip[:, None], np.column_stack([n0, n1, n3]), np.column_stack([n0, n1, n2]))
    b = np.where(flip[:, None], np.column_stack([n1, n2, n3]), np.column_stack([n0, n2, n3]))
    return np.concatenate([a, b]).astype(np.int64)


def neighbours(tri: np.ndarray) -> np.ndarray:
    """``opp[e, i]``: the vertex of the triangle across the side opposite local node i of
    triangle e (-1 on a boundary side). Raises on a non-manifold side."""
    tri = np.asarray(tri, dtype=np.int64)
    m = len(tri)
    owner: dict[tuple[int, int], tuple[int, int]] = {}
    opp = np.full((m, 3), -1, dtype=np.int64)
    for e in range(m):
        for i, (a, b) in enumerate(_SIDE):
            key = (min(tri[e, a], tri[e, b]), max(tri[e, a], tri[e, b]))
            if key in owner:
                f, k = owner.pop(key)
                if opp[f, k] >= 0:
                    raise ValueError(f"side {key} is shared by more than two triangles")
                opp[e, i], opp[f, k] = tri[f, k], tri[e, i]
            else:
                owner[key] = (e, i)
    return opp


def boundary_sides(tri: np.ndarray, opp: np.ndarray, node_mask: np.ndarray) -> np.ndarray:
    """Boolean (m, 3): boundary sides (no neighbour) whose two nodes both have ``node_mask``;
    use it for ``rot_fixed`` of clamped edges and symmetry planes."""
    node_mask = np.asarray(node_mask, dtype=bool)
    out = np.zeros(opp.shape, dtype=bool)
    for i, (a, b) in enumerate(_SIDE):
        out[:, i] = (opp[:, i] < 0) & node_mask[tri[:, a]] & node_mask[tri[:, b]]
    return out


def _facet(x: np.ndarray):
    """Unit normal, area and the in-plane gradients (3, 3) of the linear shape functions
    (rows: nodes, as 3-D vectors) of the triangle with vertices ``x`` (3, 3)."""
    c = np.cross(x[1] - x[0], x[2] - x[0])
    twice = np.linalg.norm(c)
    n = c / twice
    g = np.empty((3, 3))
    for a, (b, d) in enumerate(_SIDE):
        # grad N_a is normal to the opposite side, pointing to a, of length 1 / height
        g[a] = np.cross(n, x[d] - x[b]) / twice
    return n, 0.5 * twice, g


def _quadratic_derivatives(xi: float, eta: float) -> np.ndarray:
    """d/d(xi, eta) of the six patch shape functions (Onate & Flores 2005) at (xi, eta):
    N0 = z + xi eta, N1 = xi + eta z, N2 = eta + z xi, N3 = z (z - 1)/2, N4 = xi (xi - 1)/2,
    N5 = eta (eta - 1)/2 with z = 1 - xi - eta; N3..N5 belong to the vertices across the
    sides opposite nodes 0, 1, 2. Returns (6, 2)."""
    z = 1.0 - xi - eta
    return np.array(
        [
            [-1.0 + eta, -1.0 + xi],
            [1.0 - eta, z - eta],
            [z - xi, 1.0 - xi],
            [-(z - 0.5), -(z - 0.5)],
            [xi - 0.5, 0.0],
            [0.0, eta - 0.5],
        ]
    )


def _membrane_rows(grads: np.ndarray, e1, e2, p1, p2) -> np.ndarray:
    """(3, 3k) rows of [eps_xx, eps_yy, gamma_xy] for nodes with in-plane gradient vectors
    ``grads`` (k, 3); ``p1``, ``p2`` are the reference tangents X_,x and X_,y."""
    k = len(grads)
    b = np.zeros((3, 3 * k))
    for a in range(k):
        gx, gy = grads[a] @ e1, grads[a] @ e2
        b[0, 3 * a : 3 * a + 3] = gx * p1
        b[1, 3 * a : 3 * a + 3] = gy * p2
        b[2, 3 * a : 3 * a + 3] = gy * p1 + gx * p2
    return b


def _element(x6: np.ndarray, has: np.ndarray, fixed: np.ndarray, membrane: str):
    """Membrane and bending strain operators (3, 18) of one patch: nodes 0-2 of the triangle,
    3-5 the vertices across its sides (``has[i]`` False: no neighbour), ``fixed[i]``: the
    rotation about side i is held. Also returns the triangle's area."""
    x = x6[:3]
    n, area, g = _facet(x)
    e1 = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    e2 = np.cross(n, e1)
    bm = np.zeros((3, 18))
    cst = _membrane_rows(g, e1, e2, e1, e2)
    if membrane == "cst":
        bm[:, :9] = cst
    else:
        for i in range(3):
            if not has[i]:
                bm[:, :9] += cst / 3.0
                continue
            d = _quadratic_derivatives(*_MID[i])[[0, 1, 2, 3 + i]]
            pts = x6[[0, 1, 2, 3 + i]]
            jac = pts.T @ d  # (3, 2): X_,xi and X_,eta
            gq = d @ np.linalg.solve(jac.T @ jac, jac.T)  # (4, 3): in-plane gradients
            proj = jac @ np.linalg.solve(jac.T @ jac, jac.T)  # tangent-plane projector
            rows = _membrane_rows(gq, e1, e2, proj @ e1, proj @ e2)
            bm[:, :9] += rows[:, :9] / 3.0
            bm[:, 9 + 3 * i : 12 + 3 * i] += rows[:, 9:] / 3.0
    bb = np.zeros((3, 18))
    for i, (a, b) in enumerate(_SIDE):
        if not (has[i] or fixed[i]):
            continue  # free or simply supported side: no curvature from it
        side = x[b] - x[a]
        length = np.linalg.norm(side)
        e = side / length
        m_m = np.cross(e, n)  # outward in-plane normal of the side
        psi = np.zeros(18)
        for c in range(3):  # -dn_M . m_M
            psi[3 * c : 3 * c + 3] += (g[c] @ m_m) * n
        if has[i]:
            nodes_j = (b, a, 3 + i)  # the neighbour, counter-clockwise
            nj, _, gj = _facet(x6[list(nodes_j)])
            m_j = np.cross(e, nj)
            for c, node in enumerate(nodes_j):  # + dn_J . m_J
                psi[3 * node : 3 * node + 3] -= (gj[c] @ m_j) * nj
        else:  # held rotation: the mirrored ghost triangle
            psi *= 2.0
        mx, my = m_m @ e1, m_m @ e2
        bb += (length / (2.0 * area)) * np.outer([mx * mx, my * my, 2.0 * mx * my], psi)
    return bm, bb, area


def stiffness(
    points: np.ndarray,
    tri: np.ndarray,
    e_mod: float,
    nu: float,
    t: float,
    *,
    membrane: str = "ebst",
    rot_fixed: np.ndarray | None = None,
    opp: np.ndarray | None = None,
) -> sp.csr_matrix:
    """Linear stiffness (3 n, 3 n) [N/m] of the BST mesh, DOFs ``3 node + (x, y, z)``.

    ``membrane``: "ebst" (enhanced, EBST1) or "cst"; ``rot_fixed`` (m, 3) bool: boundary sides
    whose rotation is held (clamped, symmetry), see :func:`boundary_sides`."""
    if membrane not in ("ebst", "cst"):
        raise ValueError(f"membrane must be 'ebst' or 'cst', got {membrane!r}")
    points = np.asarray(points, dtype=float)
    tri = np.asarray(tri, dtype=np.int64)
    opp = neighbours(tri) if opp is None else opp
    fixed = np.zeros(opp.shape, dtype=bool) if rot_fixed is None else np.asarray(rot_fixed)
    c = np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1.0 - nu)]])
    dm = e_mod * t / (1.0 - nu * nu) * c
    db = e_mod * t**3 / (12.0 * (1.0 - nu * nu)) * c
    m = len(tri)
    blocks = np.empty((m, 18, 18))
    dofs = np.empty((m, 18), dtype=np.int64)
    for k in range(m):
        has = opp[k] >= 0
        nodes = np.concatenate([tri[k], np.where(has, opp[k], tri[k])])
        bm, bb, area = _element(points[nodes], has, fixed[k], membrane)
        blocks[k] = area * (bm.T @ dm @ bm + bb.T @ db @ bb)
        dofs[k] = (3 * nodes[:, None] + np.arange(3)).ravel()
    rows = np.repeat(dofs, 18, axis=1).ravel()
    cols = np.tile(dofs, (1, 18)).ravel()
    ndof = 3 * len(points)
    return sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(ndof, ndof))


def area_loads(points: np.ndarray, tri: np.ndarray, traction) -> np.ndarray:
    """Consistent nodal forces (n, 3) of a uniform traction [N/m^2] (a 3-vector, e.g. self
    weight) over the mesh: a third of each triangle's load to each of its nodes."""
    x = np.asarray(points, dtype=float)
    a = 0.5 * np.linalg.norm(np.cross(x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]),
                             axis=1)  # fmt: skip
    f = np.zeros((len(x), 3))
    np.add.at(f, tri.ravel(), np.repeat(a / 3.0, 3)[:, None] * np.asarray(traction, float))
    return f


def solve(k: sp.csr_matrix, forces: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """Displacements (n, 3) of ``k u = f`` with the DOFs of ``fixed`` ((n, 3) bool) at zero."""
    free = ~np.asarray(fixed, dtype=bool).ravel()
    kf = k[free][:, free].tocsc()
    u = np.zeros(free.size)
    u[free] = spla.splu(kf).solve(np.asarray(forces, dtype=float).ravel()[free])
    return u.reshape(-1, 3)
