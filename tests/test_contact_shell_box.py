"""A shell sheet falling onto and draping over a fixed rigid box."""

import numpy as np

import flexparcel as fp
from flexparcel.contact.geometry import point_box_contact
from flexparcel.contact.law import ContactLaw
from flexparcel.elements.rotations import rotation_exp
from flexparcel.model.rigid import RoundedBox


def test_sheet_drapes_over_box_without_tunnelling():
    # The sheet starts 10 mm above the box top and lands at v = sqrt(2 g 0.01) = 0.44 m/s. A node
    # (mass m_n = rho t h^2 = 1.5e-4 kg at h = 14 mm) against a linear contact spring
    # c = 1e4 N/m penetrates at most v sqrt(m_n / c) = 5.4e-5 m (its neighbours only help),
    # which is asserted at every recorded instant (measured 4.7e-5 m): no tunnelling through
    # the 50 mm box.
    side, t = 0.2, 0.3e-3
    b = fp.ModelBuilder()
    box = b.add_rigid_body(
        RoundedBox(0.1, 0.1, 0.05, 0.005, mass=1.0), (0.0, 0.0, 0.025), motion="fixed"
    )
    pts, quads = fp.mesh.rectangle(side, side, 14, 14, origin=(-side / 2, -side / 2, 0.06))
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, 2424.0, t, 1.71e-3))
    # 1e4 N/m and 0.5 N s/m at an interior node of this mesh: the law is per unit area
    law = ContactLaw.from_point_values(
        (side / 14) ** 2,
        stiffness=1e4,
        damping=0.5,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=0.3,
        mu_dynamic=0.3,
    )
    b.add_body_contact(ids, box, law, radius=t / 2)
    model = b.finalize()
    r = fp.simulate(model, 0.15, dt_out=0.005)
    worst = 0.0
    for k in range(len(r.time)):
        rot = rotation_exp(r.rotation_vectors[k, box])
        for i in ids:
            s = point_box_contact(
                r.positions[k, i],
                r.positions[k, box],
                rot,
                model.box_half_by_node[box],
                model.box_radius_by_node[box],
                t / 2,
            )[0]
            worst = max(worst, s)
    m_node = 2424.0 * t * (side / 14) ** 2
    bound = np.sqrt(2 * 9.81 * 0.01) * np.sqrt(m_node / 1e4)
    assert 0.0 < worst < bound  # it did touch, and never went deeper than the bound
    # draped: the sheet's edges hang below the box top (z = 0.05) while its middle is held on
    # top of the box (still settling after 0.15 s: within 5 mm above it, never through it)
    z = r.positions[-1, ids, 2]
    assert z.min() < 0.045
    centre = ids[np.argmin(np.linalg.norm(pts[:, :2], axis=1))]
    assert 0.05 + t / 2 - 1e-4 < r.positions[-1, centre, 2] < 0.055
