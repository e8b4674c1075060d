"""Contact per unit area: the law's c and d are per area of the slave surface (per length for
line contact), so a calibrated value means the same at every mesh size (paper section 2.1,
eqs. 1-10, applied per contact point by RecurDyn at its 10 mm nodes)."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact.law import REFERENCE_AREA, REFERENCE_SPACING, ContactLaw
from flexparcel.contact.planes import PlanePointSet, plane_contact_forces
from flexparcel.contact.tributary import corner_areas, station_areas
from flexparcel.model.rigid import RoundedBox

G = 9.81
T, RHO = 0.3e-3, 2424.0  # KP/BW-like film [m], [kg/m^3]
FILM = fp.ShellMaterial(926e6, 0.1, RHO, T, 1.71e-3)
SIDE = 0.1  # sheet side [m]
MESHES = {"5 mm": 20, "10 mm": 10, "25 mm": 4}  # quads along a 100 mm side


# ---------------------------------------------------------------------------- conversion


def test_paper_value_converts_through_the_10_mm_reference_spacing():
    # RecurDyn's 649 N/mm belongs to the paper's 10 mm nodes, i.e. to (10 mm)^2 = 1e-4 m^2:
    # per area c = 649e3 N/m / 1e-4 m^2 = 6.49e9 N/m^3 (and d = 579 N s/m / 1e-4 m^2).
    law = ContactLaw.from_paper_units(c_N_per_mm=649, d_Ns_per_mm=0.579, reference_spacing_mm=10)
    assert law.stiffness == pytest.approx(6.49e9, rel=1e-14)
    assert law.damping == pytest.approx(5.79e6, rel=1e-14)
    assert ContactLaw.from_paper_units(c_N_per_mm=649).stiffness == law.stiffness  # the default
    # a value stated for 25 mm nodes spreads over 6.25 times the area
    coarse = ContactLaw.from_paper_units(c_N_per_mm=649, reference_spacing_mm=25.0)
    assert coarse.stiffness == pytest.approx(6.49e9 / 6.25, rel=1e-14)
    # and back: to_paper_units states the spacing it refers to
    back = law.to_paper_units()
    assert back["reference_spacing_mm"] == 10.0
    assert back["c_N_per_mm"] == pytest.approx(649.0, rel=1e-14)
    assert law.to_paper_units(reference_spacing_mm=25.0)["c_N_per_mm"] == pytest.approx(
        649.0 * 6.25, rel=1e-14
    )
    # the per-point construction is explicit and named
    point = ContactLaw.from_point_values(REFERENCE_AREA, stiffness=649e3, damping=579.0)
    assert point.stiffness == pytest.approx(law.stiffness, rel=1e-14)
    assert point.damping == pytest.approx(law.damping, rel=1e-14)
    with pytest.raises(ValueError, match="point_area must be > 0"):
        ContactLaw.from_point_values(0.0, stiffness=1.0)
    with pytest.raises(ValueError, match="reference_spacing_mm must be > 0"):
        ContactLaw.from_paper_units(c_N_per_mm=649, reference_spacing_mm=0.0)


def test_interior_node_of_a_10_mm_mesh_gets_the_papers_per_point_stiffness():
    # A flat 50 mm sheet of 10 mm quads on a plane with Table 6's 649 N/mm law: its interior
    # node carries 1e-4 m^2, so its spring is 6.49e9 N/m^3 x 1e-4 m^2 = 649e3 N/m, the paper's
    # per-point value. Checked on the force the plane kernel returns for s = 10 um.
    law = ContactLaw.from_paper_units(c_N_per_mm=649, d_Ns_per_mm=0.579)
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.05, 0.05, 5, 5)
    ids = b.add_shell_mesh(pts, quads, material=FILM)
    b.add_contact(ids, b.add_plane((0, 0, 0), (0, 0, 1)), law)
    model = b.finalize()
    (cs,) = model.contact_sets
    assert isinstance(cs, PlanePointSet)
    interior = np.flatnonzero(np.all((pts[:, :2] > 1e-6) & (pts[:, :2] < 0.05 - 1e-6), axis=1))
    assert interior.size == 16
    np.testing.assert_allclose(cs.area[interior] * law.stiffness, 649e3, rtol=1e-12)
    s = 1e-5
    pos = model.positions0.copy()
    pos[:, 2] = -s  # every node 10 um into the plane, at rest
    n = len(pos)
    f = np.zeros((n, 6))
    p = cs.node.size
    plane_contact_forces(
        cs.node, cs.offset, cs.radius, np.zeros(p, np.int64), np.zeros(p, np.int64), np.ones(p),
        cs.area, model.plane_point, model.plane_normal, model.plane_velocity,
        model.plane_axis, model.plane_extent, model.contact_laws, pos,
        np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 6)), f,
        np.zeros((p, 6, 6)), np.zeros((p, 6, 6)), np.ones(n), 1.0, np.zeros(1),
        np.zeros((p, 3)), np.zeros((p, 3)), 1e-3, pos, np.tile(np.eye(3), (n, 1, 1)),
    )  # fmt: skip
    np.testing.assert_allclose(f[ids[interior], 2], 649e3 * s, rtol=1e-12)
    # the whole sheet carries c x its area: 6.49e9 x 2.5e-3 m^2 x s
    assert f[:, 2].sum() == pytest.approx(6.49e9 * 0.05**2 * s, rel=1e-12)


# ---------------------------------------------------------------------------- tributary areas


def test_edge_and_corner_nodes_get_half_and_a_quarter_of_the_interior_area():
    # median-dual areas on a regular quad mesh of spacing h: h^2 inside, h^2/2 on the mesh's
    # edge, h^2/4 at its corners; the areas add up to the sheet's area
    h = 0.01
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.04, 0.03, 4, 3)
    ids = b.add_shell_mesh(pts, quads, material=FILM)
    a = b.node_areas(ids)
    on_x = np.isclose(pts[:, 0], 0.0) | np.isclose(pts[:, 0], 0.04)
    on_y = np.isclose(pts[:, 1], 0.0) | np.isclose(pts[:, 1], 0.03)
    np.testing.assert_allclose(a[~on_x & ~on_y], h * h, rtol=1e-12)
    np.testing.assert_allclose(a[on_x ^ on_y], h * h / 2, rtol=1e-12)
    np.testing.assert_allclose(a[on_x & on_y], h * h / 4, rtol=1e-12)
    assert a.sum() == pytest.approx(0.04 * 0.03, rel=1e-12)


def test_tributary_areas_add_up_on_distorted_quads_triangles_and_solid_faces():
    # the median dual of any flat polygon mesh covers it exactly once: a triangle gives a third
    # of its area to each corner, a distorted quad the quadrilaterals (corner, mid-edge,
    # centroid, mid-edge), which add up to its area
    rng = np.random.default_rng(3)
    quad = np.array([[0.0, 0.0, 0.0], [0.03, 0.002, 0.0], [0.025, 0.02, 0.0], [0.004, 0.015, 0.0]])
    c = corner_areas(quad, np.array([[0, 1, 2, 3]]))
    shoelace = 0.5 * abs(np.cross(quad[2] - quad[0], quad[3] - quad[1])[2])
    assert c.sum() == pytest.approx(shoelace, rel=1e-12)
    assert c.min() > 0.0
    tri = rng.uniform(size=(3, 3))
    ct = corner_areas(tri, np.array([[0, 1, 2]]))
    np.testing.assert_allclose(
        ct, 0.5 * np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) / 3
    )
    # a hex block: its boundary faces, each node its share; interior nodes none
    from flexparcel.elements.solid import SolidMaterial

    n = 3
    g = np.linspace(0.0, 0.03, n + 1)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    spts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    k = lambda i, j, m: (i * (n + 1) + j) * (n + 1) + m  # noqa: E731
    cells = np.array([[k(i, j, m), k(i + 1, j, m), k(i + 1, j + 1, m), k(i, j + 1, m),
                       k(i, j, m + 1), k(i + 1, j, m + 1), k(i + 1, j + 1, m + 1),
                       k(i, j + 1, m + 1)]
                      for i in range(n) for j in range(n) for m in range(n)])  # fmt: skip
    b = fp.ModelBuilder()
    ids = b.add_solid_mesh(spts, cells, "hex8", material=SolidMaterial(1e5, 0.3, 1000.0))
    a = b.node_areas(ids)
    assert a.sum() == pytest.approx(6 * 0.03**2, rel=1e-12)
    inside = np.all((spts > 1e-6) & (spts < 0.03 - 1e-6), axis=1)
    assert inside.sum() == 8 and np.all(a[inside] == 0.0)


def test_line_contact_stations_carry_their_length_times_the_strip_width():
    # per length: a station of a 20 mm edge sampled 4 times carries 5 mm x width
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.06, 0.02, 3, 1)
    ids = b.add_shell_mesh(pts, quads, material=FILM)
    plane = b.add_plane((0, 0, 0), (0, 0, 1))
    law = ContactLaw(stiffness=1e8)
    b.add_edge_contact(ids[np.isclose(pts[:, 1], 0.0)], plane, law, samples=4)
    b.add_edge_contact(ids[np.isclose(pts[:, 1], 0.0)], plane, law, samples=4, width=2e-3)
    model = b.finalize()
    default, narrow = model.contact_sets
    np.testing.assert_allclose(default.station_area, 0.02 / 4 * REFERENCE_SPACING, rtol=1e-12)
    np.testing.assert_allclose(narrow.station_area, 0.02 / 4 * 2e-3, rtol=1e-12)
    assert station_areas(pts, np.array([[0, 1]]), 2, 0.01)[0] == pytest.approx(0.02 / 2 * 0.01)
    with pytest.raises(ValueError, match="width must be > 0 m"):
        b.add_edge_contact(ids, plane, law, width=0.0)


def test_points_without_a_surface_need_an_explicit_area():
    # a rigid box's corners carry REFERENCE_AREA unless told otherwise; a node on no surface
    # (a rigid mesh's vertex is on one; a bare reference node of an FDR is not) is refused
    b = fp.ModelBuilder()
    box = b.add_rigid_body(RoundedBox(0.1, 0.1, 0.05, 0.005, mass=1.0), (0.0, 0.0, 0.03))
    plane = b.add_plane((0, 0, 0), (0, 0, 1))
    law = ContactLaw(stiffness=1e8)
    b.add_contact(box, plane, law)
    b.add_contact(box, plane, law, area=2e-4)
    pts, quads = fp.mesh.rectangle(0.02, 0.02, 1, 1, origin=(0.0, 0.0, 0.2))
    ids = b.add_shell_mesh(pts, quads, material=FILM)
    ref = b.add_fdr(ids)
    with pytest.raises(ValueError, match="no tributary area.*give area="):
        b.add_contact([ref], plane, law)
    with pytest.raises(ValueError, match="area must be finite and >= 0"):
        b.add_contact(ids, plane, law, area=-1.0)
    with pytest.raises(ValueError, match="one per contact point"):
        b.add_contact(ids, plane, law, area=[1e-4, 1e-4])
    b.add_contact([ref], plane, law, area=1e-4)
    corners, given = b._contact_sets[:2]
    np.testing.assert_array_equal(corners.area, np.full(8, REFERENCE_AREA))
    np.testing.assert_array_equal(given.area, np.full(8, 2e-4))


# ---------------------------------------------------------------------------- mesh independence


def _box_on_sheet(nq: int):
    """A 1 kg box (150 x 150 mm, larger than the sheet) resting on a 100 mm sheet of ``nq`` x
    ``nq`` quads on a plane, from first touch; returns (sink of the box after 0.06 s [m],
    predicted sink [m])."""
    c, d = 4e7, 1.25e5  # per area [N/m^3], [N s/m^3]: constant (indentation, m_i = 0) damping
    law = ContactLaw(stiffness=c, damping=d, damping_option="indentation", indentation_exponent=0)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    pts, quads = fp.mesh.rectangle(SIDE, SIDE, nq, nq, origin=(-SIDE / 2, -SIDE / 2, T / 2))
    sheet = b.add_shell_mesh(pts, quads, material=FILM)
    hz, mass = 0.02, 1.0
    z_touch = T / 2 + T / 2 + hz / 2  # a node on the plane (z = T/2) + its radius + half box
    box = b.add_rigid_body(RoundedBox(0.15, 0.15, hz, 0.002, mass=mass), (0.0, 0.0, z_touch))
    b.add_contact(sheet, b.add_plane((0, 0, 0), (0, 0, 1)), law, radius=T / 2)
    b.add_body_contact(sheet, box, law, radius=T / 2)
    model = b.finalize()
    r = fp.simulate(model, 0.06, dt_out=0.01)
    sink = z_touch - r.positions[-1, box, 2]
    w_sheet = RHO * T * SIDE**2 * G
    # two contacts in series, each c x the sheet's area; the film's weight on the plane only
    predicted = (2 * mass * G + w_sheet) / (c * SIDE**2)
    assert np.abs(r.velocities[-1, box, :3]).max() < 1e-3  # at rest
    return sink, predicted


def test_box_on_a_sheet_sinks_the_same_on_5_10_and_25_mm_meshes():
    # Per area, every node under the box carries c x its tributary area, and the areas of any
    # mesh add up to the sheet's: a uniform pressure p = W / A presses each node equally deep,
    # s = p / c on either side of the film, whatever the mesh. So the box sinks
    # (2 W_box + W_film) / (c A) = 49 um on the 5, 10 and 25 mm meshes alike; within 5 %
    # of each other and of that value. (Per point, with c x 1e-4 m^2 at every node, it would
    # sink 16, 4 and 0.6 x 49 um: the node counts 441, 121 and 25 share the load.)
    sinks = {}
    for name, nq in MESHES.items():
        sinks[name], predicted = _box_on_sheet(nq)
    values = np.array(list(sinks.values()))
    print("box sink per mesh [um]:", {k: round(float(v) * 1e6, 3) for k, v in sinks.items()})
    assert values.max() / values.min() - 1.0 < 0.05
    np.testing.assert_allclose(values, predicted, rtol=0.05)


def _sheet_drop(nq: int):
    """A 100 mm sheet of ``nq`` x ``nq`` quads dropped flat from 1 mm onto a plane; returns the
    largest upward speed [m/s] of its mass centre after the impact and the impact speed."""
    c, d = 1e8, 3.4e3  # per area: each node's zeta = d / (2 sqrt(c rho t)) = 0.2
    law = ContactLaw(stiffness=c, damping=d, damping_option="indentation", indentation_exponent=0)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    drop = 1e-3
    pts, quads = fp.mesh.rectangle(SIDE, SIDE, nq, nq, origin=(-SIDE / 2, -SIDE / 2, T / 2 + drop))
    sheet = b.add_shell_mesh(pts, quads, material=FILM)
    b.add_contact(sheet, b.add_plane((0, 0, 0), (0, 0, 1)), law, radius=T / 2)
    model = b.finalize()
    r = fp.simulate(model, 0.02, dt_out=2e-4)
    m = model.mass[sheet, 0]
    vz = r.velocities[:, sheet, 2] @ m / m.sum()
    return vz.max(), np.sqrt(2 * G * drop)


def test_sheet_dropped_flat_rebounds_the_same_on_5_10_and_25_mm_meshes():
    # Landing flat, every node meets the plane at once and moves alike: a node of area A_i has
    # the mass rho t A_i (lumped mass of a rectangular mesh: its median-dual share) and the
    # spring c A_i, dashpot d A_i, so its frequency sqrt(c / (rho t)) and damping ratio
    # d / (2 sqrt(c rho t)) = 0.2, hence its restitution, do not depend on A_i: the sheet
    # rebounds with the same speed on every mesh; within 10 %. (Per point, zeta = d_point /
    # (2 sqrt(c_point rho t A_i)) would scale with 1 / h: 0.4, 0.2 and 0.08 here.)
    rebound = {}
    for name, nq in MESHES.items():
        up, v0 = _sheet_drop(nq)
        rebound[name] = up / v0
    values = np.array(list(rebound.values()))
    print(
        "rebound speed / impact speed per mesh:",
        {k: round(float(v), 4) for k, v in rebound.items()},
    )
    assert values.min() > 0.2  # it did bounce
    assert values.max() / values.min() - 1.0 < 0.10
