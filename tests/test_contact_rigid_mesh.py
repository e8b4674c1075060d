"""Shell nodes against a rigid triangle-mesh surface."""

import numpy as np
import pytest

import flexparcel as fp
from conftest import assert_rests_at_contact_thickness, drop_sheet_on
from flexparcel.model.rigid import RoundedBox


def test_sheet_rests_on_a_fixed_triangulated_surface():
    # a 60 mm sheet falls 5 mm onto a fixed rigid body's two-triangle top surface (z = 0); it
    # comes to rest one contact thickness above it (static sink m_node g / c = 6e-6 m) as on
    # a plane, and never passes through
    b = fp.ModelBuilder()
    body = b.add_rigid_body(RoundedBox(0.2, 0.2, 0.02, mass=1.0), (0.0, 0.0, -0.01), motion="fixed")
    surf = np.array([[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]])
    verts = b.add_rigid_mesh(surf, np.array([[0, 1, 2], [0, 2, 3]]), body)
    sheet = drop_sheet_on(b, verts)
    assert_rests_at_contact_thickness(b.finalize(), sheet)


def test_rigid_mesh_bad_input():
    b = fp.ModelBuilder()
    body = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, mass=1.0))
    with pytest.raises(ValueError, match=r"triangle node ids must be in \[0, 2\]"):
        b.add_rigid_mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), body)
    with pytest.raises(ValueError, match=r"not a rigid body"):
        b.add_rigid_mesh(np.eye(3), np.array([[0, 1, 2]]), 7)
