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


@pytest.mark.parametrize("motion", ["fixed", "prescribed"])
def test_mesh_of_a_held_body_is_held_and_of_a_driven_body_moves_with_it(motion):
    # the vertices of a fixed body's mesh are held, not carried as FDR slaves (their rows of
    # the rigid-link map would be empty); a driven body's vertices stay slaves and follow it
    from flexparcel.model.rigid import PrescribedMotion

    b = fp.ModelBuilder()
    drive = "fixed" if motion == "fixed" else PrescribedMotion(velocity=(0.5, 0.0, 0.0))
    body = b.add_rigid_body(RoundedBox(0.2, 0.2, 0.02, mass=1.0), (0.0, 0.0, -0.01), motion=drive)
    surf = np.array([[-0.1, -0.1, 0.0], [0.1, -0.1, 0.0], [0.1, 0.1, 0.0], [-0.1, 0.1, 0.0]])
    verts = b.add_rigid_mesh(surf, np.array([[0, 1, 2], [0, 2, 3]]), body)
    b.add_shell_mesh(
        *fp.mesh.rectangle(0.05, 0.05, 2, 2),
        material=fp.ShellMaterial(
            youngs_modulus=1e9, poisson_ratio=0.3, density=1000.0, thickness=1e-3
        ),
    )
    model = b.finalize()
    held = motion == "fixed"
    assert bool(model.fixed[verts].all()) is held
    assert bool(np.isin(verts, model.slave_nodes).all()) is not held
    assert model.ext_count == model.dof_count + (0 if held else 6 * verts.size)
    res = fp.simulate(model, 0.01, dt_out=0.01)
    shift = res.positions[-1, verts] - res.positions[0, verts]
    np.testing.assert_allclose(shift, [[0.0 if held else 0.005, 0.0, 0.0]] * 4, atol=1e-12)


def test_rigid_mesh_bad_input():
    b = fp.ModelBuilder()
    body = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, mass=1.0))
    with pytest.raises(ValueError, match=r"triangle node ids must be in \[0, 2\]"):
        b.add_rigid_mesh(np.zeros((3, 3)), np.array([[0, 1, 3]]), body)
    with pytest.raises(ValueError, match=r"not a rigid body"):
        b.add_rigid_mesh(np.eye(3), np.array([[0, 1, 2]]), 7)
