"""Verification cases of the structural core against published and closed-form references.

Each case returns a dict with the computed values, the reference and the error, so the tests
(which assert tolerances argued from the discretisation) and ``flexparcel verify`` (which
reports the figures) share one implementation. References: the package data folder
:data:`REFERENCE_DIR` (``flexparcel/data/verification``, its README names the sources: Sze, Liu &
Lo 2004, FEAD 40:1551; Euler-Bernoulli cantilever; Leissa 1973).
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
    }
