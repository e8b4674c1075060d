from pathlib import Path

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.data import VERIFICATION_DIR
from flexparcel.elements.rotations import rotation_exp

REFERENCE = Path(__file__).resolve().parent / "data" / "reference"


def _required(path: Path) -> Path:
    # Reference data ships with the repository: a missing file is a failure, never a skip.
    if not path.is_file():
        pytest.fail(f"reference data missing: {path}")
    return path


def reference_file(name: str) -> Path:
    """A file of the paper's reference data in tests/data/reference (see its README.md)."""
    return _required(REFERENCE / name)


def verification_table(name: str) -> Path:
    """A Sze 2004 table of the package data (flexparcel/data/verification, see its README.md)."""
    return _required(VERIFICATION_DIR / name)


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


SHEET_T = 0.3e-3


def soft_contact_law():
    """Linear contact 1e4 N/m with constant damping 0.5 N s/m and friction 0.3 (test scenes),
    per point of a 10 mm node: the law is per unit area, 1e8 N/m^3 and 5e3 N s/m^3."""
    from flexparcel.contact.law import REFERENCE_AREA, ContactLaw

    return ContactLaw.from_point_values(
        REFERENCE_AREA,
        stiffness=1e4,
        damping=0.5,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=0.3,
        mu_dynamic=0.3,
    )


def drop_sheet_on(b, face_node_ids, drop=0.005, t=SHEET_T):
    """Add a 60 mm KP/BW-material sheet ``drop`` [m] above z = 0 in contact with the faces of
    ``face_node_ids``; returns its node ids."""
    pts, quads = fp.mesh.rectangle(0.06, 0.06, 6, 6, origin=(-0.03, -0.03, drop))
    sheet = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, 2424.0, t, 1.71e-3))
    b.add_face_contact(sheet, face_node_ids, soft_contact_law(), thickness=t)
    return sheet


def assert_rests_at_contact_thickness(model, sheet, t=SHEET_T):
    """Simulate 0.1 s: the sheet never passes z = 0 and its typical node rests at z = t
    (static sink m_node g / c = 6e-6 m; within 0.05 mm)."""
    # A flat landing: with the per-area law every node of the sheet has the same contact
    # frequency sqrt(c / (rho t)) (11.7e3 rad/s) and the sheet bounces as one body. With the
    # default step error tolerance (0.1 mm) the rebound gained energy (measured on a plane:
    # back to 2.6 mm of the 5 mm drop, then 3.2 mm; with steps of 20 us it rises 1.1 mm, the
    # restitution of the law's zeta = 0.29). Per point, the corner nodes (a quarter of the
    # mass on the full c) rang twice as fast and bent the sheet, which hid it. 1 um does it.
    opts = fp.IntegratorOptions(tol_displacement=1e-6)
    r = fp.simulate(model, 0.1, dt_out=0.002, options=opts)
    z = r.positions[:, sheet, 2]
    assert z.min() > 0.0
    assert abs(np.median(z[-1]) - t) < 5e-5
    return r


SMALL_CONSIGNMENT = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"


@pytest.fixture(scope="session")
def snapshot_dir(tmp_path_factory) -> Path:
    """DIR/consignment_small/: ``flexparcel assemble`` of the small example consignment
    (examples/consignment_small.toml, 20 mm shells), run once per session: snapshot.npz,
    assembly.json, pictures. Read it; a test that writes copies it first."""
    from flexparcel.cli import main

    d = tmp_path_factory.mktemp("snaps")
    out = d / "consignment_small"
    assert main(["assemble", str(SMALL_CONSIGNMENT), "--out", str(out), "--no-progress"]) == 0
    return d


@pytest.fixture(scope="session")
def small_assembly(snapshot_dir) -> Path:
    """The directory of :func:`snapshot_dir`'s assembly (one assembly serves both)."""
    return snapshot_dir / "consignment_small"


def fd_wrt_nodes(func, x, rot, eps):
    """Central differences (step ``eps``) of func(x, rot) (an array) with respect to the 18
    triangle DOFs: node translations and spatial spins R -> exp(+-eps e_i) R; shape
    (func size, 18)."""
    cols = []
    for a in range(3):
        for kind in ("x", "spin"):
            for i in range(3):
                xp, xm, rp, rm = x.copy(), x.copy(), rot.copy(), rot.copy()
                if kind == "x":
                    xp[a, i] += eps
                    xm[a, i] -= eps
                else:
                    e = np.zeros(3)
                    e[i] = eps
                    rp[a] = rotation_exp(e) @ rot[a]
                    rm[a] = rotation_exp(-e) @ rot[a]
                cols.append((np.atleast_1d(func(xp, rp)) - np.atleast_1d(func(xm, rm))) / (2 * eps))
    return np.column_stack(cols)
