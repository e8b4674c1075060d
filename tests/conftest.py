from pathlib import Path

import numpy as np
import pytest

import flexparcel as fp

REFERENCE = Path(__file__).resolve().parents[1].parent / "shared" / "reference"


def reference_dir() -> Path:
    """The shared reference data (../shared/reference next to the repository)."""
    if not REFERENCE.is_dir():
        pytest.skip(f"shared reference data not found at {REFERENCE}")
    return REFERENCE


def strip_model(
    length,
    width,
    thickness,
    nx,
    ny=1,
    *,
    e=1.2e6,
    nu=0.0,
    rho=1.0,
    beta=0.0,
    gravity=(0.0, 0.0, 0.0),
):
    """A strip clamped at x = 0; returns (model, node ids at the tip x = length, points)."""
    pts, quads = fp.mesh.rectangle(length, width, nx, ny)
    b = fp.ModelBuilder(gravity=gravity)
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(e, nu, rho, thickness, beta))
    b.clamp(ids[pts[:, 0] == 0.0])
    tip = ids[np.isclose(pts[:, 0], length)]
    return b, tip, pts
