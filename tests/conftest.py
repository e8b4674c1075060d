from pathlib import Path

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.data import VERIFICATION_DIR

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
    """Linear contact 1e4 N/m with constant damping 0.5 N s/m and friction 0.3 (test scenes)."""
    from flexparcel.contact.law import ContactLaw

    return ContactLaw(
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
    r = fp.simulate(model, 0.1, dt_out=0.002)
    z = r.positions[:, sheet, 2]
    assert z.min() > 0.0
    assert abs(np.median(z[-1]) - t) < 5e-5
    return r


SMALL_CONSIGNMENT = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"


@pytest.fixture(scope="session")
def small_assembly(tmp_path_factory) -> Path:
    """``flexparcel assemble`` of the small example consignment (20 mm shells), run once per
    session (about a minute): the directory with snapshot.npz, assembly.json, pictures."""
    from flexparcel.cli import main

    out = tmp_path_factory.mktemp("small") / "assembly"
    assert main(["assemble", str(SMALL_CONSIGNMENT), "--out", str(out), "--no-progress"]) == 0
    return out


@pytest.fixture(scope="session")
def snapshot_dir(tmp_path_factory) -> Path:
    """DIR/consignment_small/snapshot.npz: the small example consignment
    (examples/consignment_small.toml), assembled once for the session."""
    from flexparcel.cli import main

    example = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"
    d = tmp_path_factory.mktemp("snaps")
    out = d / "consignment_small"
    assert main(["assemble", str(example), "--out", str(out), "--no-progress"]) == 0
    return d
