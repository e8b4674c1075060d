"""Candidate shell formulations measured side by side (docs/shell-candidates.md).

(a) flexparcel's co-rotational flat facet (ANDES/OPT membrane + DKT bending, 6 DOF per node),
    through the package's public API; (b) the rotation-free BST triangle of ``bst.py`` (3 DOF
    per node), with the CST membrane (``b/cst``) and the EBST1 enhanced membrane (``b/ebst``).

Accuracy: Scordelis-Lo roof and pinched cylinder (MacNeal & Harder 1985) and a clamped square
plate under uniform pressure (Timoshenko & Woinowsky-Krieger: w_max = 0.00126 q a^4 / D).
Cost: the stiffness matrices of both on the same nodes of a 320 x 250 mm plate meshed at 10 mm
and 5 mm (edges' translations held): DOFs, nnz, SuperLU L+U fill, factor and solve times,
(a) and (b) interleaved in one process, best of 5, one thread.

Run: ``OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python tools/shell_candidates/compare.py``
(``--quick``: meshes 8/16 only and the 10 mm cost mesh).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bst  # noqa: E402

import flexparcel as fp  # noqa: E402
from flexparcel import verification  # noqa: E402
from flexparcel.integrate import assembly as asm  # noqa: E402
from flexparcel.model import mesh  # noqa: E402

SCORDELIS_REF = 0.3024
PINCHED_REF = 1.8248e-5
PLATE_COEF = 0.00126  # clamped square plate, nu = 0.3 (Timoshenko & Woinowsky-Krieger, table 35)
PATTERN = "right"  # the BST mesh: every grid cell split along its 0-2 diagonal


def _grid(n: int, m: int | None = None) -> np.ndarray:
    m = n if m is None else m
    return mesh.rectangle(1.0, 1.0, n, m)[0]


def _cylinder(unit: np.ndarray, radius, length, phi0, phi1) -> np.ndarray:
    phi = phi0 + unit[:, 1] * (phi1 - phi0)
    return np.column_stack([length * unit[:, 0], radius * np.sin(phi), radius * np.cos(phi)])


def _bst_run(pts, fixed, forces, e_mod, nu, t, membrane, rot_nodes=None):
    tri = bst.grid_triangles(*_cells(pts), PATTERN)
    opp = bst.neighbours(tri)
    rot = None if rot_nodes is None else bst.boundary_sides(tri, opp, rot_nodes)
    k = bst.stiffness(pts, tri, e_mod, nu, t, membrane=membrane, rot_fixed=rot, opp=opp)
    f = forces(tri) if callable(forces) else forces
    return bst.solve(k, f, fixed)


def _cells(pts: np.ndarray) -> tuple[int, int]:
    # a (nx+1) x (ny+1) grid of mesh.rectangle: nx from the first row
    row = np.flatnonzero(np.isclose(pts[:, 1], pts[0, 1]) & np.isclose(pts[:, 2], pts[0, 2]))
    nx = len(row) - 1
    return nx, len(pts) // (nx + 1) - 1


def scordelis_bst(n: int, membrane: str) -> float:
    unit = _grid(n)
    phi = np.deg2rad(40.0)
    pts = _cylinder(unit, 25.0, 50.0, -phi, phi)
    xi, eta = unit[:, 0], unit[:, 1]
    fixed = np.zeros((len(pts), 3), dtype=bool)
    ends = np.isclose(xi, 0.0) | np.isclose(xi, 1.0)
    fixed[ends, 1:] = True  # rigid diaphragms: y, z; their sides are free sides
    fixed[np.isclose(xi, 0.5) & np.isclose(eta, 0.5), 0] = True  # axial rigid motion
    u = _bst_run(pts, fixed, lambda tri: bst.area_loads(pts, tri, (0, 0, -90.0)), 4.32e8, 0.0,
                 0.25, membrane)  # fmt: skip
    return float(-u[np.isclose(xi, 0.5) & np.isclose(eta, 1.0), 2].mean())


def pinched_bst(n: int, membrane: str) -> float:
    unit = _grid(n)
    pts = _cylinder(unit, 300.0, 300.0, 0.0, 0.5 * np.pi)
    xi, eta = unit[:, 0], unit[:, 1]
    fixed = np.zeros((len(pts), 3), dtype=bool)
    fixed[np.isclose(xi, 0.0), 1:] = True  # diaphragm
    mid, top, side = np.isclose(xi, 1.0), np.isclose(eta, 0.0), np.isclose(eta, 1.0)
    fixed[mid, 0] = fixed[top, 1] = fixed[side, 2] = True  # symmetry planes x, y, z
    f = np.zeros((len(pts), 3))
    f[mid & top, 2] = -0.25
    u = _bst_run(pts, fixed, f, 3e6, 0.3, 3.0, membrane, rot_nodes=mid | top | side)
    return float(-u[mid & top, 2].mean())


PLATE = {"a": 1.0, "t": 0.01, "E": 1e7, "nu": 0.3}


def _plate_d() -> float:
    return PLATE["E"] * PLATE["t"] ** 3 / (12.0 * (1.0 - PLATE["nu"] ** 2))


def plate_bst(n: int, membrane: str) -> float:
    """Clamped square plate, centre deflection over the closed form."""
    pts = _grid(n) * PLATE["a"]
    edge = np.isclose(pts[:, 0] % PLATE["a"], 0.0) | np.isclose(pts[:, 1] % PLATE["a"], 0.0)
    fixed = np.zeros((len(pts), 3), dtype=bool)
    fixed[edge] = True
    u = _bst_run(pts, fixed, lambda tri: bst.area_loads(pts, tri, (0, 0, -1.0)), PLATE["E"],
                 PLATE["nu"], PLATE["t"], membrane, rot_nodes=edge)  # fmt: skip
    centre = np.argmin(np.linalg.norm(pts[:, :2] - 0.5 * PLATE["a"], axis=1))
    return float(-u[centre, 2] / (PLATE_COEF * PLATE["a"] ** 4 / _plate_d()))


def plate_facet(n: int) -> float:
    """The same plate with flexparcel's facet (quads, clamped edges), linear range."""
    a = PLATE["a"]
    pts, quads = mesh.rectangle(a, a, n, n)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(PLATE["E"], PLATE["nu"], 1.0,
                                                                   PLATE["t"]))  # fmt: skip
    edge = np.isclose(pts[:, 0] % a, 0.0) | np.isclose(pts[:, 1] % a, 0.0)
    b.clamp(ids[edge])
    q = 1e-3 * PLATE["t"] / (PLATE_COEF * a**4 / _plate_d())  # w_max ~ t / 1000: linear
    area = np.zeros(len(pts))
    np.add.at(area, quads.ravel(), (a / n) ** 2 / 4.0)
    for node in np.flatnonzero(~edge):
        b.add_force(ids[node], (0.0, 0.0, -q * area[node]))
    res = fp.solve_static(b.finalize(), load_steps=1)
    centre = np.argmin(np.linalg.norm(pts[:, :2] - 0.5 * a, axis=1))
    return float(-res.displacements[-1, ids[centre], 2] / q / (PLATE_COEF * a**4 / _plate_d()))


def accuracy_rows(meshes) -> list[tuple]:
    rows = []
    for n in meshes:
        a = verification.scordelis_lo_roof(n)["value"]
        b = [scordelis_bst(n, m) / SCORDELIS_REF for m in ("cst", "ebst")]
        rows.append(("Scordelis-Lo roof (full)", n, a / SCORDELIS_REF, *b))
    for n in meshes:
        a = verification.pinched_cylinder(n)["value"]
        b = [pinched_bst(n, m) / PINCHED_REF for m in ("cst", "ebst")]
        rows.append(("Pinched cylinder (octant)", n, a / PINCHED_REF, *b))
    for n in meshes:
        rows.append(("Clamped square plate", n, plate_facet(n), *[plate_bst(n, m) for m in
                                                                  ("cst", "ebst")]))  # fmt: skip
        print(f"  ... {n}", file=sys.stderr, flush=True)
    return rows


def cost_matrices(h_mm: float):
    """The two stiffness matrices over the free DOFs of the same nodes (320 x 250 mm plate,
    element size h_mm, paper-like E = 3 GPa, t = 0.3 mm, edges' translations held)."""
    lx, ly = 0.32, 0.25
    nx, ny = round(320 / h_mm), round(250 / h_mm)
    pts, quads = mesh.rectangle(lx, ly, nx, ny)
    edge = (np.isclose(pts[:, 0], 0) | np.isclose(pts[:, 0], lx) | np.isclose(pts[:, 1], 0)
            | np.isclose(pts[:, 1], ly))  # fmt: skip
    e_mod, nu, t = 3e9, 0.3, 3e-4
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(e_mod, nu, 700.0, t))
    b.fix(ids[edge], "translations")
    model = b.finalize()
    st = model.initial_state()
    _, data_k, _, _ = asm.internal_forces_and_tangent(
        model, st.positions, st.rotations, st.velocities
    )
    nf = model.dof_count
    k_a = asm.csr_from_data(model, data_k)[:nf, :nf].tocsc()
    tri = bst.grid_triangles(nx, ny, PATTERN)
    k_full = bst.stiffness(pts, tri, e_mod, nu, t, membrane="ebst")
    free = ~np.repeat(edge, 3)
    k_b = k_full[free][:, free].tocsc()
    return len(pts), k_a, k_b


def _factor(k):
    return spla.splu(k, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options=dict(SymmetricMode=True))  # fmt: skip


def cost_rows(sizes, repeats: int = 5) -> list[tuple]:
    rows = []
    for h in sizes:
        nodes, k_a, k_b = cost_matrices(h)
        mats = {"a": k_a, "b": k_b}
        best_f = {"a": np.inf, "b": np.inf}
        best_s = {"a": np.inf, "b": np.inf}
        lus = {}
        for _ in range(repeats):  # interleaved: the machine's load hits both alike
            for key, k in mats.items():
                t0 = time.perf_counter()
                lus[key] = _factor(k)
                best_f[key] = min(best_f[key], time.perf_counter() - t0)
                rhs = np.ones(k.shape[0])
                t0 = time.perf_counter()
                x = lus[key].solve(rhs)
                best_s[key] = min(best_s[key], time.perf_counter() - t0)
                res = np.linalg.norm(k @ x - rhs) / np.linalg.norm(rhs)
                assert res < 1e-6, f"{key}: residual {res:.2e}"
        for key, k in mats.items():
            lu = lus[key]
            rows.append((h, nodes, key, k.shape[0], k.nnz, lu.L.nnz + lu.U.nnz,
                         1e3 * best_f[key], 1e3 * best_s[key]))  # fmt: skip
        print(f"  ... {h} mm", file=sys.stderr, flush=True)
    return rows


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="meshes 8/16, 10 mm cost mesh only")
    args = p.parse_args(argv)
    meshes = (8, 16) if args.quick else (8, 16, 24, 32)
    sizes = (10.0,) if args.quick else (10.0, 5.0)
    print(
        "| benchmark | mesh | (a) facet OPT+DKT | (b) BST, CST membrane | (b) BST, EBST1 membrane |"
    )
    print("|---|---|---|---|---|")
    for case, n, *vals in accuracy_rows(meshes):
        print(f"| {case} | {n}x{n} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
    print()
    print("| mesh | nodes | candidate | DOFs | nnz | L+U fill | fill/nnz | factor [ms] "
          "| solve [ms] |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for h, nodes, key, ndof, nnz, fill, tf, ts in cost_rows(sizes):
        name = "(a) facet, 6 DOF/node" if key == "a" else "(b) BST, 3 DOF/node"
        print(f"| {h:g} mm | {nodes} | {name} | {ndof} | {nnz} | {fill} | {fill / nnz:.1f} "
              f"| {tf:.1f} | {ts:.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
