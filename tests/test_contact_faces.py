"""Node-to-face contact between shells."""

import numpy as np

import flexparcel as fp
from conftest import drop_sheet_on
from flexparcel.contact.law import ContactLaw


def _stack(drop=0.005, t=0.3e-3):
    b = fp.ModelBuilder()
    p1, q1 = fp.mesh.rectangle(0.1, 0.1, 8, 8, origin=(-0.05, -0.05, 0.0))
    low = b.add_shell_mesh(p1, q1, material=fp.ShellMaterial(926e6, 0.1, 2424.0, t, 1.71e-3))
    b.clamp(low)
    up = drop_sheet_on(b, low, drop, t)
    return b.finalize(), up


def test_sheet_lands_on_sheet_and_rests_at_the_contact_thickness():
    # A 60 mm sheet falls 5 mm onto a clamped sheet. It must come to rest one contact
    # thickness (0.3 mm) above it: the static penetration is its weight per node over the
    # contact stiffness, m_node g / c = 6e-6 m, so within 0.05 mm; it never passes through;
    # and the impact does not gain energy (the impact step limit resolves the contact
    # oscillation; without it the rebound rose above the drop height): rebound < half the drop.
    # At 0.1 s the sheet still bounces by up to 0.1 mm (vz ~ 0.05 m/s at 0.096 s with numpy
    # 2.4 / numba 0.68 / scipy 1.17; with earlier versions that frame fell between bounces):
    # it is at rest by 0.2 s (median 1e-7 m off).
    t, drop = 0.3e-3, 0.005
    model, up = _stack(drop, t)
    # A flat landing: with the per-area law every node of the sheet has the same contact
    # frequency sqrt(c / (rho t)) (11.7e3 rad/s) and the sheet bounces as one body. With the
    # default step error tolerance (0.1 mm) the rebound gained energy (measured on a plane:
    # back to 2.6 mm of the 5 mm drop, then 3.2 mm; with steps of 20 us it rises 1.1 mm, the
    # restitution of the law's zeta = 0.29). Per point, the corner nodes (a quarter of the
    # mass on the full c) rang twice as fast and bent the sheet, which hid it. 1 um does it.
    opts = fp.IntegratorOptions(tol_displacement=1e-6)
    r = fp.simulate(model, 0.2, dt_out=0.002, options=opts)
    z = r.positions[:, up, 2]
    assert z.min() > 0.0  # never through the lower sheet
    # (the free corners may still curl up slightly while settling: allow 0.2 mm there)
    assert np.median(np.abs(z[-1] - t)) < 5e-5 and np.abs(z[-1] - t).max() < 2e-4
    first = np.argmax(z.min(axis=1) < 2 * t)
    assert z[first:].max() < drop / 2


def test_face_contact_bad_input():
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.1, 0.1, 2, 2)
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3))
    law = ContactLaw(stiffness=1e8)  # per area [N/m^3]
    import pytest

    with pytest.raises(ValueError, match=r"thickness must be > 0 m"):
        b.add_self_contact(ids, law, thickness=0.0)
    with pytest.raises(ValueError, match=r"no complete shell face"):
        b.add_face_contact(ids, ids[:2], law, thickness=1e-3)
    with pytest.raises(TypeError, match=r"law must be a ContactLaw"):
        b.add_face_contact(ids, ids, "stiff", thickness=1e-3)


def test_surface_triangles_split_each_kept_quad_once():
    # the contact surfaces' triangulation: a kept quad gives its two 0-2-diagonal triangles,
    # a kept triangle itself; a cell with any node not kept, and solid cells, give nothing
    from flexparcel.model.mesh import surface_triangles

    cells = [
        ("quad", np.array([[0, 1, 2, 3], [1, 4, 5, 2]])),
        ("triangle", np.array([[3, 2, 6], [5, 7, 6]])),
        ("hexahedron", np.arange(8)[None, :]),
    ]
    keep = np.ones(8, dtype=bool)
    keep[[4, 7]] = False
    tris = surface_triangles(cells, keep)
    np.testing.assert_array_equal(tris, [[0, 1, 2], [0, 2, 3], [3, 2, 6]])
    assert surface_triangles([], keep).shape == (0, 3)


def test_shell_edges_lists_each_kept_element_edge_once():
    # the edges of line and edge-to-edge contact: every side of a quad or triangle whose two
    # nodes are kept, a side shared by two cells once, solid cells skipped (the hexahedron's
    # 0-6 would otherwise appear)
    from flexparcel.model.mesh import shell_edges

    cells = [
        ("quad", np.array([[0, 1, 2, 3], [1, 4, 5, 2]])),
        ("triangle", np.array([[3, 2, 6], [5, 7, 6]])),
        ("hexahedron", np.array([[0, 6, 5, 3, 1, 2, 4, 7]])),
    ]
    keep = np.ones(8, dtype=bool)
    keep[[4, 7]] = False
    edges = shell_edges(cells, keep)
    np.testing.assert_array_equal(
        edges, [[0, 1], [0, 3], [1, 2], [2, 3], [2, 5], [2, 6], [3, 6], [5, 6]]
    )
    assert shell_edges([], keep).shape == (0, 2)
