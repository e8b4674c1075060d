"""Line contact: a sheet standing on its edge; a coarse sheet resting on a box between its
nodes."""

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.contact.law import REFERENCE_SPACING, ContactLaw
from flexparcel.model.rigid import RoundedBox


def test_sheet_lands_on_its_edge_and_carries_its_weight():
    # A 200 x 100 mm sheet in the vertical xz-plane (out-of-plane motion held) falls 2 mm onto
    # a plate edge first. At rest the line contact carries its weight W: line contact is per
    # length, the per-area law c times the 10 mm strip width, c_line = 5e5 N/m^2, so the
    # 200 mm edge sinks s = W / (c_line L) = 1.4 um (each 20 mm edge carries 1e4 N/m, as the
    # per-point law of 1e4 N/m per edge did); within 10 % (the edge's nodes share the load
    # unevenly near its ends).
    t, rho = 0.3e-3, 2424.0
    pts, quads = fp.mesh.rectangle(0.2, 0.1, 10, 5)
    pts = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1] + 0.002])
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(926e6, 0.1, rho, t, 1.71e-3))
    b.fix(ids, ["y", "rx", "rz"])
    bottom = ids[np.isclose(pts[:, 2], 0.002)]
    c = 5e7  # per area [N/m^3]
    law = ContactLaw(
        stiffness=c, damping=2.5e4, damping_option="indentation", indentation_exponent=0.0
    )
    b.add_edge_contact(bottom, b.add_plane((0, 0, 0), (0, 0, 1)), law)
    model = b.finalize()
    r = fp.simulate(model, 0.3, dt_out=0.01)
    weight = model.total_mass() * 9.81
    sink = -r.positions[-1, bottom, 2].mean()
    assert sink == pytest.approx(weight / (c * REFERENCE_SPACING * 0.2), rel=0.1)
    assert np.abs(r.velocities[-1, ids, 2]).max() < 1e-3


def test_edge_contact_bad_input():
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.1, 0.1, 2, 2)
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3))
    plane = b.add_plane((0, 0, 0), (0, 0, 1))
    law = ContactLaw(stiffness=1e8)  # per area [N/m^3]
    with pytest.raises(ValueError, match=r"unknown plane 5"):
        b.add_edge_contact(ids, 5, law)
    with pytest.raises(ValueError, match=r"no shell edge"):
        b.add_edge_contact(ids[[0, 8]], plane, law)
    with pytest.raises(ValueError, match=r"samples must be an integer >= 1"):
        b.add_edge_contact(ids, plane, law, samples=0)
    with pytest.raises(ValueError, match=r"radius must be >= 0 m"):
        b.add_edge_contact(ids, plane, law, radius=-1e-3)
    with pytest.raises(ValueError, match=r"not a rigid body's node"):
        b.add_edge_body_contact(ids, 3, law)
    box = b.add_rigid_body(RoundedBox(0.05, 0.05, 0.05, 0.005, mass=1.0), (0, 0, -0.1))
    with pytest.raises(ValueError, match=r"add_edge_body_contact: node_ids contain no shell"):
        b.add_edge_body_contact(ids[[0, 8]], box, law)
    with pytest.raises(TypeError, match=r"law must be a ContactLaw"):
        b.add_edge_body_contact(ids, box, "law")


T_SHEET, RHO_SHEET = 0.3e-3, 2424.0
C_AREA = 1e7  # contact stiffness per area [N/m^3] of the line-contact scenes
# the stations of these scenes: a 100 mm edge in 5, 20 mm each, times the 10 mm strip width
STATION_AREA = REFERENCE_SPACING * 0.1 / 5
C_LINE = C_AREA * STATION_AREA * 5  # a station's stiffness is C_LINE / 5 = 2e3 N/m
# linear spring with constant damping (near-critical for the stations of a ~1.5 g sheet)
LINE_LAW = ContactLaw(
    stiffness=C_AREA, damping=2e3, damping_option="indentation", indentation_exponent=0.0
)
SHEET = fp.ShellMaterial(926e6, 0.1, RHO_SHEET, T_SHEET, 1.71e-3)


def _settle(b):
    """The built scene after 0.15 s. Micron-scale contact deflections: the default 0.1 mm step
    error would leave it chattering."""
    model = b.finalize()
    opts = fp.IntegratorOptions(tol_displacement=1e-7)
    return model, fp.simulate(model, 0.15, dt_out=0.005, options=opts)


def _sheet_over_ridge(line_contact: bool):
    """A 100 x 20 mm sheet of ONE quad (nodes only at x = +-50 mm) dropped 1 mm onto a fixed
    box ridge 50 mm wide in x: the ridge lies between the nodes, only the sheet's two long
    edges (5 stations each, at x = -40 ... 40 mm) can find it."""
    t = T_SHEET
    b = fp.ModelBuilder()
    box = b.add_rigid_body(
        RoundedBox(0.05, 0.1, 0.05, 0.005, mass=1.0), (0.0, 0.0, 0.025), motion="fixed"
    )
    pts, quads = fp.mesh.rectangle(0.1, 0.02, 1, 1, origin=(-0.05, -0.01, 0.05 + t / 2 + 1e-3))
    ids = b.add_shell_mesh(pts, quads, material=SHEET)
    b.add_body_contact(ids, box, LINE_LAW, radius=t / 2)
    if line_contact:
        b.add_edge_body_contact(ids, box, LINE_LAW, radius=t / 2, samples=5)
    model, r = _settle(b)
    return model, r, ids, t


def test_line_contact_holds_a_coarse_sheet_on_a_box_between_its_nodes():
    # Node contact alone cannot see the ridge: the sheet falls through it (its nodes, 50 mm
    # from the middle, are beyond the 25 mm half width). With line contact the three stations
    # over the ridge of each long edge carry the weight W: the sheet rests one contact radius
    # above the ridge top (z = 0.05 m + t/2), sunk by s = W / (6 c/5) = 1.2e-6 m (the
    # stations interpolate the nodes linearly, so the straight edge rests level); 1 % (measured
    # 7e-5: the static solution is exact for linear springs).
    model, r, ids, t = _sheet_over_ridge(True)
    z = r.positions[-1, ids, 2]
    weight = model.mass[ids, 0].sum() * 9.81
    sink = weight / (6 * C_LINE / 5)
    assert (0.05 + t / 2) - z == pytest.approx(np.full(4, sink), rel=0.01)
    assert np.abs(r.velocities[-1, ids, :3]).max() < 1e-3
    _, r0, _, _ = _sheet_over_ridge(False)
    assert r0.positions[-1, ids, 2].max() < 0.05 - 0.01  # fell past the ridge top


def _strip_across_strip(line_contact: bool):
    """A 20 x 100 mm strip of ONE quad (nodes at y = +-50 mm) dropped 1 mm across a clamped
    100 x 50 mm strip of one quad (y = +-25 mm): no node of the upper strip lies over the lower
    one; the stations of its two long edges (5 each, y = -40 ... 40 mm) at y = -20, 0, 20 mm do."""
    t = T_SHEET
    b = fp.ModelBuilder()
    p1, q1 = fp.mesh.rectangle(0.1, 0.05, 1, 1, origin=(-0.05, -0.025, 0.0))
    low = b.add_shell_mesh(p1, q1, material=SHEET)
    b.clamp(low)
    p2, q2 = fp.mesh.rectangle(0.02, 0.1, 1, 1, origin=(-0.01, -0.05, t + 1e-3))
    up = b.add_shell_mesh(p2, q2, material=SHEET)
    b.add_face_contact(up, low, LINE_LAW, thickness=t)
    if line_contact:
        b.add_edge_face_contact(up, low, LINE_LAW, thickness=t, samples=5)
    model, r = _settle(b)
    return model, r, up, t


def test_line_contact_holds_a_coarse_strip_across_another_between_its_nodes():
    # As on the box ridge: node-to-face contact alone lets the upper strip fall past the lower
    # one; with edge-to-face line contact the 6 stations over it carry the weight W and it
    # rests one contact thickness t above it, sunk by W / (6 c/5); 1 %.
    model, r, up, t = _strip_across_strip(True)
    z = r.positions[-1, up, 2]
    sink = model.mass[up, 0].sum() * 9.81 / (6 * C_LINE / 5)
    assert t - z == pytest.approx(np.full(4, sink), rel=0.01)
    assert np.abs(r.velocities[-1, up, :3]).max() < 1e-3
    _, r0, _, _ = _strip_across_strip(False)
    assert r0.positions[-1, up, 2].max() < -0.01


def test_edge_face_contact_bad_input():
    b = fp.ModelBuilder()
    pts, quads = fp.mesh.rectangle(0.1, 0.1, 2, 2)
    ids = b.add_shell_mesh(pts, quads, material=fp.ShellMaterial(1e9, 0.3, 1000.0, 1e-3))
    law = ContactLaw(stiffness=1e8)  # per area [N/m^3]
    with pytest.raises(ValueError, match=r"add_edge_face_contact: thickness must be > 0 m"):
        b.add_edge_face_contact(ids, ids, law, thickness=0.0)
    with pytest.raises(ValueError, match=r"add_edge_face_contact: node_ids contain no shell"):
        b.add_edge_face_contact(ids[[0, 8]], ids, law, thickness=1e-3)
    with pytest.raises(ValueError, match=r"add_edge_face_contact: face_node_ids contain no"):
        b.add_edge_face_contact(ids, ids[:2], law, thickness=1e-3)
    with pytest.raises(ValueError, match=r"samples must be an integer >= 1"):
        b.add_edge_face_contact(ids, ids, law, thickness=1e-3, samples=0)


def _edge_creep(law: ContactLaw) -> float:
    """Speed [m/s] down the slope, the least-squares slope of the edge's mean position over
    0.2-0.5 s, of a 200 x 100 mm sheet (20 mm quads) landing 1 mm onto its bottom edge on a
    plate inclined 8 deg along that edge (its out-of-plane motion held); line contact alone
    carries it."""
    angle = np.radians(8.0)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    pts, quads = fp.mesh.rectangle(0.2, 0.1, 10, 5)
    pts = np.column_stack([pts[:, 0], np.zeros(len(pts)), pts[:, 1] + 0.001]) @ rot.T
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(pts, quads, material=SHEET)
    b.fix(ids, ["y", "rx", "rz"])
    bottom = ids[:11]  # the first row of the grid: the edge on the plate
    b.add_edge_contact(bottom, b.add_plane((0, 0, 0), rot @ np.array([0.0, 0.0, 1.0])), law)
    model = b.finalize()
    # micrometre contact deflections: the default 0.1 mm step error would not resolve them
    opts = fp.IntegratorOptions(tol_displacement=1e-7)
    r = fp.simulate(model, 0.5, dt_out=0.01, options=opts)
    down = rot @ np.array([1.0, 0.0, 0.0])  # down the slope
    late = r.time > 0.2 - 1e-9
    along = r.positions[late][:, bottom].mean(axis=1) @ down
    return float(np.polyfit(r.time[late], along, 1)[0])


def test_edge_contact_stick_model_holds_a_sheet_on_an_incline():
    # tan(8 deg) = 0.14 < mu = 0.3: once landed (it slides 0.7 mm while it lands, its fall
    # having a component along the slope) the sheet must stay. The regularised law (eq. 8) has
    # mu(0) = 0 and creeps where mu(v) = tan(8 deg), at a fraction of v_s = 1 mm/s (measured
    # 0.26 mm/s); with the stick model the stations' springs hold it (measured drift 6e-9
    # m/s, the fit's noise). Bound: 1 um/s, 1/260 of the regularised creep.
    law = ContactLaw(stiffness=C_AREA, damping=2e3, damping_option="indentation",
                     indentation_exponent=0.0, mu_static=0.3, mu_dynamic=0.3)  # fmt: skip
    assert abs(_edge_creep(law.with_stick_model())) < 1e-6
    assert _edge_creep(law) > 1e-4


def test_edge_pair_springs_follow_the_accepted_step_and_a_checkpoint():
    # Two crossing 1-quad sheets, B 0.1 mm above A within the 0.3 mm contact thickness: B's
    # edge x = 0 crosses A's edges y = +-10 mm. B moved 1 um along +x over a step: each of the
    # two pairs sticks with the elastic slip du = x_a - x_b = -1 um x (in the tangent plane),
    # which the accepted step hands on to B's edge, with A's edge it belongs to.
    from flexparcel.contact.edge_edge import EdgeEdgeSet
    from flexparcel.integrate.dynamic import GeneralizedAlpha

    b = fp.ModelBuilder()
    pa, qa = fp.mesh.rectangle(0.02, 0.02, 1, 1, origin=(-0.01, -0.01, 0.0))
    sheet_a = b.add_shell_mesh(pa, qa, material=SHEET)
    b.clamp(sheet_a)
    pb, qb = fp.mesh.rectangle(0.02, 0.04, 1, 1, origin=(0.0, -0.02, 1e-4))
    sheet_b = b.add_shell_mesh(pb, qb, material=SHEET)
    law = ContactLaw(stiffness=6.49e9, mu_static=0.3, mu_dynamic=0.3).with_stick_model()
    b.add_edge_edge_contact(sheet_a, sheet_b, law, thickness=3e-4)
    model = b.finalize()
    integ = GeneralizedAlpha(model)
    cs = next(c for c in integ.model.contact_sets if isinstance(c, EdgeEdgeSet))
    s0 = model.initial_state()
    integ.initialize(s0)
    s1 = s0.copy()
    s1.positions[sheet_b, 0] += 1e-6

    def step(start, end):  # a step's contact evaluation, as GeneralizedAlpha._try_step does
        integ._s0, integ._h_now = start, 1e-4
        integ._prepare_contacts(start, 1e-4)
        integ._contact(end, start.time + 1e-4)
        cs.commit()

    step(s0, s1)
    held = np.flatnonzero(cs.partner >= 0)
    edge_x0 = [k for k, e in enumerate(cs.edges_b) if np.allclose(s0.positions[e, 0], 0.0)]
    assert list(held) == edge_x0  # one edge b, held by one of A's two edges (the last pair)
    np.testing.assert_allclose(cs.u_el[held[0]], [-1e-6, 0.0, 0.0], atol=1e-15)
    # the next step's pair starts from that spring; a step without contact clears it
    integ._s0 = s1
    integ._prepare_contacts(s1, 1e-4)
    pairs = cs.candidates[0]
    start = cs._u_prev[(pairs[:, 1] == held[0]) & (pairs[:, 0] == cs.partner[held[0]])]
    np.testing.assert_allclose(start, [[-1e-6, 0.0, 0.0]], atol=1e-15)
    hist = {k: v.copy() for k, v in cs.history().items()}
    far = s1.copy()
    far.positions[sheet_b, 2] += 0.01
    step(far, far)
    assert (cs.partner == -1).all() and not cs.u_el.any()
    cs.restore_history(hist)  # a checkpoint
    assert list(np.flatnonzero(cs.partner >= 0)) == edge_x0
    cs.restore_history({})  # a checkpoint written before edge pairs had springs
    assert (cs.partner == -1).all()
