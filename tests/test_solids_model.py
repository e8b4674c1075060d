"""Solid elements inside the model: statics, dynamics with contact, bookkeeping."""

import numpy as np
import pytest

import flexparcel as fp
from conftest import assert_rests_at_contact_thickness, drop_sheet_on
from flexparcel.contact.law import REFERENCE_AREA, ContactLaw
from flexparcel.elements.solid import SolidMaterial


def _hex_bar(length, nx, width=1.0, height=1.0, z0=0.0):
    xs = np.linspace(0.0, length, nx + 1)
    pts = np.array([[x, y * width, z0 + z * height] for z in (0, 1) for y in (0, 1) for x in xs])

    def nid(i, j, k):
        return i + (nx + 1) * (j + 2 * k)

    cells = np.array(
        [
            [
                nid(i, 0, 0),
                nid(i + 1, 0, 0),
                nid(i + 1, 1, 0),
                nid(i, 1, 0),
                nid(i, 0, 1),
                nid(i + 1, 0, 1),
                nid(i + 1, 1, 1),
                nid(i, 1, 1),
            ]
            for i in range(nx)
        ]
    )
    return pts, cells


def test_hex_cantilever_through_the_model_matches_beam_theory():
    # w = P L^3 / (3 E I) (+ shear P L / (k G A), 0.6 % here); QM6 hexes one element thick
    # are accurate to ~0.4 % (element tests); allowed 1 %. Solid-only nodes carry no rotation
    # unknowns: 3 DOFs per free node.
    pts, cells = _hex_bar(10.0, 10)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    ids = b.add_solid_mesh(pts, cells, "hex8", material=SolidMaterial(1e6, 0.0, 1.0))
    b.fix(ids[pts[:, 0] == 0.0], "translations")
    tip = ids[pts[:, 0] == 10.0]
    b.add_force(tip, (0.0, 0.0, 1e-3 / len(tip)))
    model = b.finalize()
    assert model.dof_count == 3 * (len(pts) - 4)
    w = fp.solve_static(model, load_steps=1).displacements[-1, tip, 2].mean()
    assert w == pytest.approx(1e-3 * 10.0**3 / (3 * 1e6 / 12), rel=1e-2)
    assert model.total_mass() == pytest.approx(10.0, rel=1e-12)


def test_soft_block_falls_and_rests_on_the_ground():
    # a 100 x 20 x 20 mm soft block (granulate-like content) dropped 5 mm: it lands and comes
    # to rest on the plane at its contact penetration (weight / (nodes x c) = 0.0 mm scale)
    pts, cells = _hex_bar(0.1, 5, 0.02, 0.02, z0=0.005)
    b = fp.ModelBuilder()
    ids = b.add_solid_mesh(
        pts, cells, "hex8", material=SolidMaterial(1e5, 0.3, 1000.0, damping_ratio=1e-3)
    )
    # 1e4 N/m and 2 N s/m per point of a 10 mm node: the law is per unit area of the block's
    # boundary faces (1e8 N/m^3)
    law = ContactLaw.from_point_values(
        REFERENCE_AREA,
        stiffness=1e4,
        damping=2.0,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=0.3,
        mu_dynamic=0.3,
    )
    b.add_contact(ids, b.add_plane((0, 0, 0), (0, 0, 1)), law)
    r = fp.simulate(b.finalize(), 0.2, dt_out=0.01)
    z = r.positions[:, ids, 2]
    assert np.all(np.isfinite(z))
    assert -1e-4 < z[-1].min() < 1e-4  # resting on the plane
    assert np.abs(r.velocities[-1, ids, :3]).max() < 0.02


def test_sheet_rests_on_a_solid_block():
    # packaging on flexible content: a sheet falls 5 mm onto a clamped hex block's top face
    # (boundary faces of the solid mesh are contact faces) and rests one contact thickness
    # above it
    pts, cells = _hex_bar(0.1, 5, 0.1, 0.02, z0=-0.02)
    pts[:, 0] -= 0.05
    pts[:, 1] -= 0.05
    b = fp.ModelBuilder()
    block = b.add_solid_mesh(pts, cells, "hex8", material=SolidMaterial(1e5, 0.3, 1000.0))
    b.fix(block, "translations")
    sheet = drop_sheet_on(b, block)
    assert_rests_at_contact_thickness(b.finalize(), sheet)


def test_solid_growth_expands_the_elements_smoothly():
    # a solid group's growth scales its reference geometry at every step: a free hex bar
    # (no gravity, mass damping) whose reference grows by 10 % over 0.1 s ends, at rest, 10 %
    # larger in every direction: the co-rotational element is strain-free at its reference
    # shape. The lag behind the growth (1.8 % in z at 0.1 s) decays as exp(-alpha t / 2) =
    # exp(-10) over the next 0.1 s, to ~2e-6; the integrator's step error (tol_displacement
    # = 1e-7 m, 2e-6 of the 50 mm height) is as small. Tolerance 2e-5.
    from flexparcel.model.schedule import Schedule

    pts, cells = _hex_bar(0.2, 2, width=0.1, height=0.05)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0), mass_damping=200.0)
    ids = b.add_solid_mesh(pts, cells, "hex8", material=SolidMaterial(1e5, 0.3, 500.0))
    model = b.finalize()
    (group,) = model.element_groups
    full = group.xref.copy()
    group.growth = (full, Schedule((0.0, 0.1), (1.0, 1.1)))
    opt = fp.IntegratorOptions(tol_displacement=1e-7)
    r = fp.simulate(model, 0.2, dt_out=0.1, options=opt)
    p = r.positions[-1][ids]
    ext = p.max(axis=0) - p.min(axis=0)
    np.testing.assert_allclose(ext, 1.1 * np.array([0.2, 0.1, 0.05]), rtol=2e-5)
    np.testing.assert_allclose(group.xref, 1.1 * full)
