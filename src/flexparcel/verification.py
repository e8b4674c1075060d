"""Verification cases of the structural core against published and closed-form references.

Each case returns a dict with the computed values, the reference and the error, so the tests
(which assert tolerances argued from the discretisation) and ``flexparcel verify`` (which
reports the figures) share one implementation. References: the package data folder
:data:`REFERENCE_DIR` (``flexparcel/data/verification``, its README names the sources: Sze, Liu &
Lo 2004, FEAD 40:1551; Euler-Bernoulli cantilever; Leissa 1973) and, for the linear shell
benchmarks (:func:`cook_membrane`, :func:`macneal_cantilever`, :func:`scordelis_lo_roof`,
:func:`pinched_cylinder`), the reference values in their docstrings (MacNeal & Harder 1985,
Finite Elements in Analysis and Design 1:3-20; Cook 1974). docs/shell-verification.md tabulates
them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexparcel.builder import ModelBuilder
from flexparcel.data import VERIFICATION_DIR
from flexparcel.integrate import assembly as asm
from flexparcel.integrate.static import solve_static
from flexparcel.model import mesh
from flexparcel.model.materials import ShellMaterial
from flexparcel.model.model import Model

__all__ = [
    "REFERENCE_DIR",
    "sze_end_shear",
    "sze_end_moment",
    "strip_frequencies",
    "plate_frequencies",
    "natural_frequencies",
    "cook_membrane",
    "macneal_cantilever",
    "scordelis_lo_roof",
    "pinched_cylinder",
    "SHELL_BENCHMARK_MESHES",
    "shell_benchmarks",
    "benchmark_table",
    "run_all",
]

REFERENCE_DIR: Path = VERIFICATION_DIR
"""The packaged Sze 2004 tables (``sze2004_cantilever_end_shear.csv``, ``..._end_moment.csv``)."""


def _strip(length, width, thickness, nx, ny=1, *, e=1.2e6, nu=0.0, rho=1.0):
    pts, quads = mesh.rectangle(length, width, nx, ny)
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_shell_mesh(pts, quads, material=ShellMaterial(e, nu, rho, thickness))
    b.clamp(ids[pts[:, 0] == 0.0])
    return b, ids[np.isclose(pts[:, 0], length)]


def sze_end_shear(reference_csv: str | Path, nx: int = 16) -> dict:
    """Sze 3.1: strip L = 10, b = 1, h = 0.1, E = 1.2e6, nu = 0, tip shear up to Pmax = 4."""
    ref = np.loadtxt(reference_csv, delimiter=",", skiprows=1)
    b, tip = _strip(10.0, 1.0, 0.1, nx)
    b.add_force(tip, (0.0, 0.0, 4.0 / len(tip)))
    res = solve_static(b.finalize(), load_steps=20)
    minus_u = -res.displacements[:, tip, 0].mean(axis=1)
    w = res.displacements[:, tip, 2].mean(axis=1)
    return {
        "load_fraction": res.load_factors,
        "minus_u": minus_u,
        "w": w,
        "ref_minus_u": ref[:, 1],
        "ref_w": ref[:, 2],
        "max_rel_err_w": float(np.max(np.abs(w - ref[:, 2]) / ref[:, 2])),
        "max_rel_err_minus_u": float(np.max(np.abs(minus_u - ref[:, 1]) / ref[:, 1])),
        "max_abs_err_minus_u": float(np.max(np.abs(minus_u - ref[:, 1]))),
        "newton_iterations": res.newton_iterations,
    }


def sze_end_moment(nx: int = 16) -> dict:
    """Sze 3.2: strip L = 12, follower tip moment up to Mmax = 2 pi EI / L (full circle).
    Exact: theta = 2 pi M/Mmax, R = L/theta, -u = L - R sin(theta), w = R (1 - cos(theta))."""
    length = 12.0
    mmax = 50.0 * np.pi / 3.0
    b, tip = _strip(length, 1.0, 0.1, nx)
    b.add_moment(tip, (0.0, -mmax / len(tip), 0.0), follower=True)
    res = solve_static(b.finalize(), load_steps=20)
    th = 2.0 * np.pi * res.load_factors
    r = length / th
    minus_u = -res.displacements[:, tip, 0].mean(axis=1)
    w = res.displacements[:, tip, 2].mean(axis=1)
    eu = np.abs(minus_u - (length - r * np.sin(th)))
    ew = np.abs(w - r * (1.0 - np.cos(th)))
    return {
        "load_fraction": res.load_factors,
        "minus_u": minus_u,
        "w": w,
        "max_err_over_L": float(max(eu.max(), ew.max()) / length),
        "closed_circle_err_over_L": float(max(eu[-1], ew[-1]) / length),
        "newton_iterations": res.newton_iterations,
    }


def natural_frequencies(model: Model, k: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``k`` natural frequencies [Hz] and mode shapes (free DOFs) about the reference
    configuration, from the tangent stiffness and the lumped mass (shift-invert Lanczos)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    n = model.node_count
    _, dk, _, _ = asm.internal_forces_and_tangent(
        model, model.positions0, np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 6))
    )
    kmat = asm.csr_from_data(model, dk).tocsc()  # no FDRs in the verification models
    mmat = sp.diags(asm.free_vector(model, model.mass)).tocsc()
    vals, vecs = spla.eigsh(kmat, k=k, M=mmat, sigma=0.0)
    order = np.argsort(vals)
    return np.sqrt(np.abs(vals[order])) / (2.0 * np.pi), vecs[:, order]


def strip_frequencies(nx: int = 16) -> dict:
    """Out-of-plane bending frequencies of strip 3.1 with rho = 3.1314e-4 (f1 = 10.00 Hz):
    omega_n = (beta_n L)^2 sqrt(EI / (rho A L^4)), beta_n L = 1.87510, 4.69409, 7.85476."""
    b, tip = _strip(10.0, 1.0, 0.1, nx, rho=3.1314e-4)
    model = b.finalize()
    f, vecs = natural_frequencies(model, k=10)
    keep = []
    for i in range(vecs.shape[1]):
        full = asm.nodal_from_ext(model, vecs[:, i])
        z = full[tip, 2]
        # out-of-plane bending: both tip nodes move in z together (not torsion, not in-plane)
        keep.append(
            np.sign(z[0]) == np.sign(z[1]) and np.abs(z).min() > 1e-3 * np.abs(full[:, :3]).max()
        )
    fb = f[np.array(keep)][:3]
    exact = (
        np.array([1.87510, 4.69409, 7.85476]) ** 2
        * np.sqrt(100.0 / (3.1314e-4 * 0.1 * 10.0**4))
        / (2.0 * np.pi)
    )
    return {"f_hz": fb, "exact_hz": exact, "rel_err": fb / exact - 1.0}


def plate_frequencies(n: int = 12) -> dict:
    """Square cantilever (CFFF) plate, nu = 0.3: lambda = omega a^2 sqrt(rho h / D) =
    3.492, 8.525, 21.43 (Leissa 1973)."""
    a, t, e, nu, rho = 1.0, 0.01, 1e9, 0.3, 1000.0
    b, _ = _strip(a, a, t, n, n, e=e, nu=nu, rho=rho)
    f, _ = natural_frequencies(b.finalize(), k=6)
    d = e * t**3 / (12 * (1 - nu**2))
    lam = 2 * np.pi * f[:3] * a**2 * np.sqrt(rho * t / d)
    ref = np.array([3.492, 8.525, 21.43])
    return {"lambda": lam, "reference": ref, "rel_err": lam / ref - 1.0}


# --------------------------------------------------------------------------- linear benchmarks
# The references are linear (small-displacement) solutions, while solve_static is geometrically
# nonlinear: each case scales its load so that the reference displacement is LINEAR_SPAN of the
# model's size, and divides the result by that scale. The nonlinear terms are then of relative
# size ~ LINEAR_SPAN (rotations ~ 1e-5 rad), 1e3 times below the smallest tolerance used.
LINEAR_SPAN = 1e-5


def _load_scale(reference: float, span: float) -> float:
    return min(1.0, LINEAR_SPAN * span / reference)


def _result(case: str, mesh_label: str, value: float, reference: float, **extra) -> dict:
    return {
        "case": case,
        "mesh": mesh_label,
        "value": float(value),
        "reference": float(reference),
        "ratio": float(value / reference),
        "rel_err": float(value / reference - 1.0),
        **extra,
    }


def _edge_loads(count: int, total: float) -> np.ndarray:
    """Consistent nodal loads of a uniform edge load ``total`` on ``count`` equal segments."""
    w = np.full(count + 1, total / count)
    w[[0, -1]] *= 0.5
    return w


def cook_membrane(n: int = 16) -> dict:
    """Cook's membrane (Cook 1974): tapered panel, corners (0, 0), (48, 44), (48, 60), (0, 44),
    clamped at x = 0 (translations; the drilling rotation stays free, as u = v = 0 along a wall
    does not make the rotation (v,x - u,y)/2 vanish), E = 1, nu = 1/3, t = 1, uniform shear load
    1 in total on the right edge; an n x n mesh (n even). Reference: vertical displacement of
    the midpoint of the loaded edge, (48, 52), 23.96 (the converged value of the literature,
    e.g. Felippa 2003). The top corner (48, 60) moves more, about 25.2 (6-node triangles,
    extrapolated); it is returned as ``corner``."""
    if n % 2:
        raise ValueError(f"cook_membrane: n must be even (a node at mid-edge), got {n}")
    ref = 23.96
    scale = _load_scale(ref, 60.0)
    unit, quads = mesh.rectangle(1.0, 1.0, n, n)
    xi, eta = unit[:, 0], unit[:, 1]
    y_low, y_high = 44.0 * xi, 44.0 + 16.0 * xi
    pts = np.column_stack([48.0 * xi, y_low + eta * (y_high - y_low), np.zeros(len(unit))])
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    # E = 1 in the benchmark's units: built with E = 1e6 Pa (a plausible SI modulus) and the
    # load times 1e6, the same linear displacements
    e_si = 1e6
    ids = b.add_shell_mesh(pts, quads, material=ShellMaterial(e_si, 1.0 / 3.0, 1.0, 1.0))
    b.fix(ids, ["z", "rx", "ry"])  # plane stress
    b.fix(ids[xi == 0.0], ["x", "y"])
    right = np.flatnonzero(np.isclose(xi, 1.0))
    right = right[np.argsort(eta[right])]
    for node, f in zip(ids[right], _edge_loads(n, scale * e_si), strict=True):
        b.add_force(node, (0.0, f, 0.0))
    v = solve_static(b.finalize(), load_steps=1).displacements[-1, :, 1] / scale
    mid, corner = ids[right[n // 2]], ids[right[-1]]
    return _result("Cook's membrane", f"{n}x{n}", v[mid], ref, corner=float(v[corner]))


def macneal_cantilever(direction: str = "in-plane", nx: int = 6, ny: int = 1) -> dict:
    """MacNeal-Harder straight cantilever (MacNeal & Harder 1985): length 6, width 0.2,
    thickness 0.1, E = 1e7, nu = 0.3, clamped root (translations and the bending rotations rx,
    ry; the drilling rotation free, see :func:`cook_membrane`), unit tip shear shared by the
    tip nodes. Reference tip deflection: in-plane 0.1081, out-of-plane 0.4321 (beam theory with
    shear deformation)."""
    if direction not in ("in-plane", "out-of-plane"):
        raise ValueError(f"direction must be 'in-plane' or 'out-of-plane', got {direction!r}")
    axis, ref = (1, 0.1081) if direction == "in-plane" else (2, 0.4321)
    scale = _load_scale(ref, 6.0)
    pts, quads = mesh.rectangle(6.0, 0.2, nx, ny)
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_shell_mesh(pts, quads, material=ShellMaterial(1e7, 0.3, 1.0, 0.1))
    b.fix(ids[pts[:, 0] == 0.0], ["x", "y", "z", "rx", "ry"])
    tip = ids[np.isclose(pts[:, 0], 6.0)]
    load = np.zeros(3)
    load[axis] = scale / len(tip)
    b.add_force(tip, tuple(load))
    res = solve_static(b.finalize(), load_steps=1)
    w = res.displacements[-1, tip, axis].mean() / scale
    return _result(f"MacNeal-Harder cantilever, {direction} shear", f"{nx}x{ny}", w, ref)


def _cylinder_points(unit: np.ndarray, radius, length, phi0, phi1) -> np.ndarray:
    """Map the unit square (xi along the axis x, eta around it) to the cylinder
    ``y = R sin(phi), z = R cos(phi)``, phi from phi0 to phi1 [rad]."""
    phi = phi0 + unit[:, 1] * (phi1 - phi0)
    return np.column_stack([length * unit[:, 0], radius * np.sin(phi), radius * np.cos(phi)])


def scordelis_lo_roof(n: int = 24) -> dict:
    """Scordelis-Lo roof (MacNeal & Harder 1985): cylindrical panel R = 25, L = 50, +-40 deg,
    t = 0.25, E = 4.32e8, nu = 0, self weight 90 per unit area, rigid diaphragms at both ends
    (y = z = 0 and the rotation about the axis rx = 0), straight edges free, x held at the
    mid-span crown (zero by symmetry) against axial rigid motion; the full roof on an
    n x n mesh (n even). Reference: vertical deflection at the middle of a free edge 0.3024."""
    if n % 2:
        raise ValueError(f"scordelis_lo_roof: n must be even (a node at mid-span), got {n}")
    ref, t = 0.3024, 0.25
    scale = _load_scale(ref, 50.0)
    phi = np.deg2rad(40.0)
    unit, quads = mesh.rectangle(1.0, 1.0, n, n)
    pts = _cylinder_points(unit, 25.0, 50.0, -phi, phi)
    # self weight as gravity on the lumped mass: rho t g = 90 per unit area (times the scale)
    b = ModelBuilder(gravity=(0.0, 0.0, -90.0 * scale / t))
    ids = b.add_shell_mesh(pts, quads, material=ShellMaterial(4.32e8, 0.0, 1.0, t))
    ends = np.isclose(unit[:, 0], 0.0) | np.isclose(unit[:, 0], 1.0)
    b.fix(ids[ends], ["y", "z", "rx"])
    # the diaphragms leave the axial rigid translation free: hold x at the mid-span crown, where
    # it is zero by symmetry anyway
    b.fix(ids[np.isclose(unit[:, 0], 0.5) & np.isclose(unit[:, 1], 0.5)], ["x"])
    res = solve_static(b.finalize(), load_steps=1)
    mid = ids[np.isclose(unit[:, 0], 0.5) & np.isclose(unit[:, 1], 1.0)]
    return _result("Scordelis-Lo roof", f"{n}x{n} full", -res.displacements[-1, mid, 2].mean()
                   / scale, ref)  # fmt: skip


def pinched_cylinder(n: int = 16) -> dict:
    """Pinched cylinder with rigid diaphragms (MacNeal & Harder 1985): R = 300, L = 600, t = 3,
    E = 3e6, nu = 0.3, two opposite unit loads at mid-length. One octant on an n x n mesh
    (x from the diaphragm to mid-length, phi from the loaded line to the plane z = 0) with
    symmetry conditions (plane x = L/2: x, ry, rz; plane y = 0: y, rx, rz; plane z = 0: z, rx,
    ry) and the diaphragm y = z = rx = 0; a quarter load. Reference: radial displacement under
    the load 1.8248e-5."""
    ref = 1.8248e-5
    scale = _load_scale(ref, 600.0)
    unit, quads = mesh.rectangle(1.0, 1.0, n, n)
    pts = _cylinder_points(unit, 300.0, 300.0, 0.0, 0.5 * np.pi)
    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_shell_mesh(pts, quads, material=ShellMaterial(3e6, 0.3, 1.0, 3.0))
    xi, eta = unit[:, 0], unit[:, 1]
    b.fix(ids[np.isclose(xi, 0.0)], ["y", "z", "rx"])
    b.fix(ids[np.isclose(xi, 1.0)], ["x", "ry", "rz"])
    b.fix(ids[np.isclose(eta, 0.0)], ["y", "rx", "rz"])
    b.fix(ids[np.isclose(eta, 1.0)], ["z", "rx", "ry"])
    load = ids[np.isclose(xi, 1.0) & np.isclose(eta, 0.0)]
    b.add_force(load, (0.0, 0.0, -0.25 * scale))
    res = solve_static(b.finalize(), load_steps=1)
    w = -res.displacements[-1, load, 2].mean() / scale
    return _result("Pinched cylinder (octant)", f"{n}x{n} octant", w, ref)


SHELL_BENCHMARK_MESHES: dict = {
    "cook": (4, 8, 16),
    "macneal": ((6, 1),),
    "scordelis": (8, 16, 24),
    "pinched": (4, 8, 16),
}
"""Meshes :func:`shell_benchmarks` runs by default (a few seconds in all)."""


def shell_benchmarks(meshes: dict | None = None) -> list[dict]:
    """The linear shell benchmarks on the meshes of ``meshes`` (default
    :data:`SHELL_BENCHMARK_MESHES`; keys cook, macneal ((nx, ny) pairs), scordelis, pinched),
    one result dict (case, mesh, value, reference, ratio, rel_err) per run."""
    m = SHELL_BENCHMARK_MESHES if meshes is None else meshes
    rows = [cook_membrane(n) for n in m.get("cook", ())]
    for nx, ny in m.get("macneal", ()):
        rows += [macneal_cantilever(d, nx, ny) for d in ("in-plane", "out-of-plane")]
    rows += [scordelis_lo_roof(n) for n in m.get("scordelis", ())]
    rows += [pinched_cylinder(n) for n in m.get("pinched", ())]
    return rows


def benchmark_table(rows: list[dict]) -> str:
    """Markdown table of :func:`shell_benchmarks` rows."""
    lines = [
        "| case | mesh | result | reference | ratio | error |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['case']} | {r['mesh']} | {r['value']:.5g} | {r['reference']:.5g} "
            f"| {r['ratio']:.4f} | {100.0 * r['rel_err']:+.2f} % |"
        )
    return "\n".join(lines)


def run_all(reference_dir: str | Path = REFERENCE_DIR) -> dict:
    """All cases, summarised as max errors (JSON-ready); ``reference_dir`` holds the Sze 2004
    tables (default: the packaged copy)."""
    ref = Path(reference_dir)
    s31 = sze_end_shear(ref / "sze2004_cantilever_end_shear.csv")
    s32 = sze_end_moment()
    fr = strip_frequencies()
    pl = plate_frequencies()
    return {
        "sze31_end_shear_16x1": {
            "max_rel_err_w": s31["max_rel_err_w"],
            "max_abs_err_minus_u": s31["max_abs_err_minus_u"],
            "note": "reference printed to 3 decimals (+-5e-4)",
        },
        "sze32_end_moment_16x1": {
            "max_err_over_L": s32["max_err_over_L"],
            "closed_circle_err_over_L": s32["closed_circle_err_over_L"],
        },
        "strip_bending_frequencies_16x1": {
            "f_hz": fr["f_hz"].tolist(),
            "max_abs_rel_err": float(np.abs(fr["rel_err"]).max()),
            "rel_err": fr["rel_err"].tolist(),
        },
        "leissa_cfff_plate_12x12": {
            "lambda": pl["lambda"].tolist(),
            "rel_err": pl["rel_err"].tolist(),
        },
        "shell_benchmarks": shell_benchmarks(),
    }
