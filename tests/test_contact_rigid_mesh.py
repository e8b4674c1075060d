"""Shell nodes against a rigid triangle-mesh surface."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact.law import ContactLaw
from flexparcel.model.rigid import RoundedBox


def test_sheet_rests_on_a_fixed_triangulated_surface():
    # a 60 mm sheet falls 5 mm onto a fixed rigid body's two-triangle top surface (z = 0); it
    # comes to rest one contact thickness above it (static sink m_node g / c = 6e-6 m) as on
    # a plane, and never passes through
    t = 0.3e-3
    b = fp.ModelBuilder()
    body = b.add_rigid_body(RoundedBox(0.2, 0.2, 0.02, mass=1.0), (0.0, 0.0, -0.01), motion="fixed")
    surf = np.array([[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]])
    verts = b.add_rigid_mesh(surf, np.array([[0, 1, 2], [0, 2, 3]]), body)
    pts, quads = fp.mesh.rectangle(0.06, 0.06, 6, 6, origin=(-0.03, -0.03, 0.005))
    sheet = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, 2424.0, t, 1.71e-3))
    law = ContactLaw(
        stiffness=1e4,
        damping=0.5,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=0.3,
        mu_dynamic=0.3,
    )
    b.add_face_contact(sheet, verts, law, thickness=t)
    r = fp.simulate(b.finalize(), 0.1, dt_out=0.002)
    z = r.positions[:, sheet, 2]
    assert z.min() > 0.0
    assert np.median(z[-1]) == pytest.approx(t, abs=5e-5)


def test_rigid_mesh_bad_input():
    b = fp.ModelBuilder()
    body = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, mass=1.0))
    with pytest.raises(ValueError, match=r"triangle node ids must be in \[0, 2\]"):
        b.add_rigid_mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), body)
    with pytest.raises(ValueError, match=r"not a rigid body"):
        b.add_rigid_mesh(np.eye(3), np.array([[0, 1, 2]]), 7)
