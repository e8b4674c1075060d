"""Conveyor scene (belt + deflectors), its friction table and its responses."""

import json
from types import SimpleNamespace

import numpy as np
import pytest

import flexparcel as fp
from conftest import SHEET_T, soft_contact_law
from flexparcel.contact.law import REFERENCE_AREA, REFERENCE_SPACING, ContactLaw
from flexparcel.elements.rotations import rotation_exp
from flexparcel.model.rigid import RoundedBox
from flexparcel.scenarios.conveyor import (
    BeltTransfer,
    ConveyorScene,
    DeflectorGeometry,
    add_conveyor,
)
from flexparcel.scenarios.conveyor_responses import conveyor_responses
from flexparcel.scenarios.friction_pairs import (
    BELT,
    DEFAULT_FRICTION_TABLE,
    DEFLECTOR,
    PACKAGING_SURFACES,
    SURFACE_MATERIALS,
    FrictionTableError,
    friction_pair,
    load_friction_table,
    surface_material,
    with_friction,
)
from flexparcel.selection.export import PACKAGING_MATERIALS

G = 9.81
BOX = RoundedBox(0.2, 0.15, 0.05, 0.005, mass=0.5)
# static sink of the box on 4 corners of 1e5 N/m: m g / (4 c)
SINK = 0.5 * G / 4e5


def _law(mu):
    """Linear spring 1e5 N/m per corner, constant damping 20 N s/m, mu_s = mu_d = mu: the law
    of the box-on-plane tests in test_contact_dynamics.py (constant damping because resting
    penetrations are microns). Per unit area: a box corner carries REFERENCE_AREA (the
    default of add_contact for a rigid body), so these are the values per corner."""
    return ContactLaw.from_point_values(
        REFERENCE_AREA,
        stiffness=1e5,
        damping=20.0,
        damping_option="indentation",
        indentation_exponent=0.0,
        mu_static=mu,
        mu_dynamic=mu,
    )


# ------------------------------------------------------------------------------ physics


def test_box_dropped_on_the_conveyor_belt_reaches_belt_speed_at_v_over_mu_g():
    # test_contact_dynamics.py checks t = v / (mu g) on a bare plane with the box resting;
    # here the belt comes from add_conveyor (1.6 m/s) and the box falls 2 mm onto it.
    # While the box slides, friction is mu F_N, so m v_x(t) = mu * (normal impulse) and the
    # vertical momentum balance gives normal impulse = m (g t + v_z(t) - v_z(0)), v_z(0) = 0:
    #   v_x(t) = mu (g t + v_z(t)),
    # whatever the fall and the bounce. So v_x reaches 0.99 v_b at t = 0.99 v_b / (mu g) up to
    # |v_z(t)| / g. At 0.99 v_b the slip (16 mm/s) is far above v_d = 1.5 mm/s, so mu is
    # exactly mu_d, and v_x is a straight line there: interpolating between 5 ms frames is
    # exact. We check |v_z| < 0.01 m/s at that time, which bounds the error by 1 ms, 0.3 % of
    # 0.32 s.
    mu, vb = 0.5, 1.6
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    parts = add_conveyor(b)  # the paper's scene: 3 m belt at 1.6 m/s, two deflectors
    assert parts.scene.belt_speed == vb
    node = b.add_rigid_body(BOX, (0.3, 0.0, 0.025 + 0.002))  # deflectors start at x = 0.8
    b.add_contact(node, parts.belt_plane, _law(mu))
    r = fp.simulate(b.finalize(), 0.4, dt_out=5e-3)
    vx, vz = r.velocities[:, node, 0], r.velocities[:, node, 2]
    target = 0.99 * vb
    i = int(np.argmax(vx >= target))
    t_reach = r.time[i - 1] + (target - vx[i - 1]) / (vx[i] - vx[i - 1]) * (
        r.time[i] - r.time[i - 1]
    )
    assert abs(vz[i]) < 0.01
    assert t_reach == pytest.approx(target / (mu * G), rel=3e-3)
    # then it rides with the belt (mu_s = mu_d and no other horizontal force: no creep)
    assert abs(vx[-1] - vb) < 1.5e-3
    assert np.abs(r.velocities[:, node, 1]).max() < 1e-6


def _box_against_deflector(theta_deg, mu_f, mu_b, t_end, stick=False, options=None):
    """The 0.2 x 0.15 box at rest on the belt, its long side flat against the (only)
    deflector near its root. The box cannot touch the deflector's triangle mesh (only shell
    nodes can), so it touches an unbounded plane through the deflector face: valid while the
    box is alongside the deflector, which the belt width keeps it for the whole run.
    ``stick``: both laws with the stick model (k_t = c)."""

    def law(mu):
        return _law(mu).with_stick_model() if stick else _law(mu)

    scene = ConveyorScene(belt_width=1.4, deflector_x=(0.2,), deflector_angle_deg=theta_deg)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    parts = add_conveyor(b, scene)
    g = parts.deflectors[0]
    centre = g.point + 0.12 * g.tangent + 0.075 * g.normal + np.array([0.0, 0.0, 0.025 - SINK])
    node = b.add_rigid_body(BOX, tuple(centre))
    b.add_contact(node, parts.belt_plane, law(mu_b))
    face = b.add_plane(tuple(g.point), tuple(g.normal))
    with b.monitored_contacts():  # the deflector's load on the box
        b.add_contact(node, face, law(mu_f))
    model = b.finalize()
    s = model.initial_state()
    # body x (the long side) along the deflector: first deflector, tangent (cos, -sin, 0)
    s.rotations[node] = rotation_exp(np.array([0.0, 0.0, -np.radians(theta_deg)]))
    r = fp.simulate(model, t_end, dt_out=0.01, state=s, options=options)
    v = r.velocities[:, node, :3]
    resp = conveyor_responses(
        r,
        {"box": [node]},
        scene,
        contact_distance=0.075 + 1e-3,  # centre to face: half width
    )["box"]
    return r, node, g, v @ g.tangent, v @ g.normal, resp


def test_belt_drags_box_along_a_45_degree_deflector_at_the_closed_form_speed():
    # Steady sliding along a deflector at theta to the belt direction: the belt friction's
    # components along and into the deflector, mu_b F (v_b cos - u, v_b sin) / S, are
    # balanced by the deflector's friction mu_f N and normal force N, so
    #   u = v_b (cos(theta) - mu_f sin(theta))     (independent of mu_b).
    # Linearised about u, the error decays with tau = S / (mu_b g), S = v_b sin sqrt(1 +
    # mu_f^2) = 1.18 m/s: tau = 0.12 s with mu_b = 1, so from rest (error 100 %) it is below
    # 0.2 % after 0.8 s (measured 0.4 % at 0.7 s). Sliding is far above v_d, so mu = mu_d
    # exactly: allow 0.5 % over 0.8-0.9 s.
    vb, th, mu_f = 1.6, np.radians(45.0), 0.3
    r, node, g, u, un, resp = _box_against_deflector(45.0, mu_f, 1.0, 0.9)
    late = r.time >= 0.8 - 1e-9
    assert np.all(np.abs(u[late] / (vb * (np.cos(th) - mu_f * np.sin(th))) - 1.0) < 5e-3)
    assert np.abs(un[late]).max() < 1e-3  # pressed against the face, not bouncing
    # the deflector's mean force balances the belt's friction mu_b m g (the box moves
    # steadily): its normal part N = mu_b m g / sqrt(1 + mu_f^2), its friction mu_f N against
    # the sliding; within 1 % (the speed is 0.4 % from its limit at 0.8 s)
    mean = r.mean_monitored_forces([node])[late[1:]].mean(axis=0)
    n_exact = 1.0 * BOX.mass * G / np.sqrt(1.0 + mu_f**2)
    assert mean @ g.normal == pytest.approx(n_exact, rel=1e-2)
    assert mean @ g.tangent == pytest.approx(-mu_f * n_exact, rel=1e-2)
    # stays in contact all the way and is not jammed
    assert resp.deflector_contact_time == pytest.approx((0.9,), abs=0.01)
    assert resp.jam_start is None
    assert resp.exit_time is None


@pytest.mark.parametrize(
    "friction_tangent, newton_tol", [("consistent", 1e-2), ("stick", 1e-4), ("symmetric", 1e-2)]
)
def test_stick_model_sliding_along_a_deflector_with_either_friction_tangent(
    friction_tangent, newton_tol
):
    # The same closed form u = v_b (cos - mu_f sin) with the stick model on both contacts: the
    # belt and the deflector slip all the way, so the return map caps the force at mu_d F_N
    # (slip far above v_d) and the stick springs do not change the steady state; same 0.5 %
    # over 0.8-0.9 s as with the regularised law. The Newton tangent of a slipping contact
    # changes the iterations, not the forces. With the stick tangent (-k_t I) Newton
    # converges linearly, so the state is as accurate as the Newton tolerance and no better:
    # measured 1.0 % off at the default newton_tol 1e-2 (the box's velocity rattles by
    # displacement errors ~1e-6 m over ms steps), 0.14 % at 1e-4, 0.13 % with the consistent
    # tangent at 1e-2 (quadratic convergence lands far inside the tolerance).
    vb, th, mu_f = 1.6, np.radians(45.0), 0.3
    opt = fp.IntegratorOptions(friction_tangent=friction_tangent, newton_tol=newton_tol)
    r, _, _, u, _, _ = _box_against_deflector(45.0, mu_f, 1.0, 0.9, stick=True, options=opt)
    late = r.time >= 0.8 - 1e-9
    assert np.all(np.abs(u[late] / (vb * (np.cos(th) - mu_f * np.sin(th))) - 1.0) < 5e-3)


def test_box_stalls_against_a_deflector_when_mu_f_exceeds_cot_theta():
    # u = v_b (cos - mu_f sin) <= 0 when mu_f >= cot(theta): the deflector's friction holds
    # the box. The regularised law (eq. 8) holds it with a slip speed below v_s = 1 mm/s.
    # Shown at theta = 70 deg (cot = 0.36) with mu_f = 0.5, not at 45 deg: stalling at 45 deg
    # needs mu_f >= 1, and a 0.2 x 0.15 m rigid box sliding on a wall with mu_f >~ 0.7
    # chatters (Painlevé-type: friction's yaw moment pushes a corner into the wall,
    # mu (w/2)(L/2)/k^2 > 1 gives mu > 0.69); measured: at 45 deg with mu_f = 0.8 or 1.2 it
    # bounces off the face at up to 0.35 m/s and creeps, also with 10x smaller steps.
    r, node, g, u, un, resp = _box_against_deflector(70.0, 0.5, 1.0, 0.5)
    late = r.time >= 0.2 - 1e-9
    assert np.abs(u[late]).max() < 1e-3
    along = (r.positions[:, node] - g.point) @ g.tangent
    assert along[-1] - along[0] < 2e-3  # mostly the initial settling
    # held: the deflector's mean force is the belt's friction mu_b m g turned back (1 %)
    mean = r.mean_monitored_forces([node])[late[1:]]
    np.testing.assert_allclose(mean, np.tile([-0.5 * G, 0.0, 0.0], (len(mean), 1)),
                               rtol=0, atol=1e-2 * 0.5 * G)  # fmt: skip
    assert resp.jam_start == 0.0  # never 5 mm of progress along x in 0.3 s


def test_conveyor_parts_geometry_and_face_meshes():
    scene = ConveyorScene(side_guides=True)
    b = fp.ModelBuilder()
    parts = add_conveyor(b, scene)
    b.add_rigid_body(BOX, (0.3, 0.0, 0.5))  # a conveyor alone has nothing to solve
    model = b.finalize()
    assert len(parts.deflectors) == 2 and len(parts.side_guide_planes) == 2
    assert np.allclose(model.plane_velocity[parts.belt_plane], [1.6, 0.0, 0.0])
    first, second = parts.deflectors
    # alternating sides, tips 30 mm short of the centre line, reach (0.3 - 0.03) / tan 45
    assert first.root[1] == pytest.approx(0.3) and first.tip[1] == pytest.approx(0.03)
    assert second.root[1] == pytest.approx(-0.3) and second.tip[1] == pytest.approx(-0.03)
    assert first.tip[0] - first.root[0] == pytest.approx(0.27)
    for g, body, verts in zip(
        parts.deflectors, parts.deflector_bodies, parts.deflector_vertices, strict=True
    ):
        assert g.normal[0] < 0.0  # faces the oncoming consignments
        assert abs(g.normal @ g.tangent) < 1e-12
        assert model.fixed[body].all()
        # the vertices lie on the sheet's mid-plane, half its thickness behind the face
        # rectangle, and are held as the deflector body is (a held body's mesh nodes are not
        # carried as FDR slaves)
        behind = (model.positions0[verts] - g.point) @ g.normal
        assert np.allclose(behind, -0.5 * scene.deflector_thickness, rtol=0, atol=1e-12)
        # from the sheet's outer end, past the belt edge, to the tip
        along = (model.positions0[verts] - g.root) @ g.tangent
        assert along.min() == pytest.approx(-scene.deflector_overhang, abs=1e-12)
        assert along.max() == pytest.approx(g.length)
        assert abs(g.outer_end[1]) == pytest.approx(0.3 + scene.deflector_overhang / np.sqrt(2.0))
        assert model.fixed[verts].all() and not np.isin(verts, model.slave_nodes).any()
    for g, ends in zip(parts.deflectors, parts.deflector_ends, strict=True):
        # the outer end edge: bottom to top, overhang beyond the belt edge
        along = (model.positions0[ends] - g.root) @ g.tangent
        assert np.allclose(along, -scene.deflector_overhang, rtol=0, atol=1e-12)
        assert np.all(np.diff(model.positions0[ends, 2]) > 0.0)
    for g, verts, tip in zip(
        parts.deflectors, parts.deflector_vertices, parts.deflector_tips, strict=True
    ):
        # the tip edge, bottom to top, in 25 mm segments (the mesh's rows)
        p = model.positions0[tip]
        assert np.isin(tip, verts).all()
        assert np.allclose((p - g.root) @ g.tangent, g.length)
        assert np.allclose(p[:, 2], np.linspace(0.0, g.height, 5))
    # distance to the face rectangle, not to its unbounded plane: beyond the tip is far
    beyond = first.tip + 0.1 * first.tangent + 0.001 * first.normal
    assert first.distance(beyond) == pytest.approx(np.hypot(0.1, 0.001))
    assert first.distance(first.root + 0.1 * first.tangent + 0.002 * first.normal) == (
        pytest.approx(0.002)
    )
    # the overhang is part of the face; beyond the outer end is off it
    assert first.distance(first.root - 0.05 * first.tangent + 0.002 * first.normal) == (
        pytest.approx(0.002)
    )
    assert first.distance(first.outer_end - 0.01 * first.tangent) == pytest.approx(0.01)


def _sheet_dragged_to_deflector(scene, corner_xy, size, t_end):
    """A square sheet of the KP/BW material, ``size`` [m] with 10 mm quads and its corner at
    ``corner_xy`` [m], lying on the belt of ``scene`` (friction 0.3) and touching the first
    deflector's face mesh, simulated for ``t_end`` [s]: (result, sheet node ids, parts)."""
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    parts = add_conveyor(b, scene)
    n = round(size / 0.01)
    pts, quads = fp.mesh.rectangle(size, size, n, n, origin=(*corner_xy, SHEET_T / 2))
    mat = fp.ShellMaterial(926e6, 0.1, 2424.0, SHEET_T, 1.71e-3)
    sheet = b.add_shell_mesh(pts, quads, material=mat)
    law = soft_contact_law()
    b.add_contact(sheet, parts.belt_plane, law, radius=SHEET_T / 2)
    thick = parts.deflector_contact_thickness(SHEET_T / 2)
    b.add_face_contact(sheet, parts.deflector_vertices[0], law, thickness=thick)
    return fp.simulate(b.finalize(), t_end, dt_out=0.01), sheet, parts


def test_shell_sheet_is_stopped_by_the_deflector_face_mesh():
    # The path packaging takes: shell nodes against a deflector's triangle mesh
    # (add_face_contact with parts.deflector_vertices). A 60 mm sheet of the KP/BW material
    # lies on the belt, a corner 7.6 mm upstream of the first deflector's face; the belt
    # (friction 0.3) drags it into the face within 0.1 s. Without the face contact its nodes
    # would cross the face plane; with it they stay on the upstream side (a node rests at
    # half its thickness, 0.15 mm, from the face) and the sheet is pushed along the face,
    # towards the belt centre.
    g = ConveyorScene().deflectors()[0]
    c = g.point + 0.15 * g.tangent + 0.05 * g.normal
    r, sheet, parts = _sheet_dragged_to_deflector(
        ConveyorScene(), (c[0] - 0.03, c[1] - 0.03), 0.06, 0.2
    )
    p = r.positions[:, sheet]
    side = (p - g.point) @ g.normal  # signed distance from the face plane [m], (k, n)
    assert side[0].min() == pytest.approx(0.05 - 0.03 * np.sqrt(2.0))
    assert side.min() > 0.0
    # deflected towards the belt centre line: the belt alone only moves it along +x
    y = p[:, :, 1].mean(axis=1)
    assert y[-1] - y[0] < -0.01
    resp = conveyor_responses(r, {"sheet": sheet}, parts.scene, contact_distance=2e-3)["sheet"]
    assert resp.deflector_contact_time[0] > 0.0 and resp.deflector_contact_time[1] == 0.0


@pytest.mark.parametrize("overhang", [0.25, 0.1, 0.0])
def test_packaging_beside_the_belt_meets_the_deflector_overhang(overhang):
    # A 40 mm sheet of the KP/BW material lies beside the belt edge (y = 0.31-0.35 m) and is
    # carried there: the belt is an unbounded plane (belt_edge_radius = 0), standing in for
    # packaging hanging over the edge while its part on the belt drags it, 21 mm upstream of
    # the first deflector's plane. With the sheet running on past the belt edge (0.25 m, the
    # default, or 0.1 m) the belt drags it into the overhang, which stops it and turns it towards
    # the centre line; with no overhang the deflector ends at the belt edge (y = 0.3 m) and
    # the sheet passes its free end (in the paper's scene KP's film went round it).
    scene = ConveyorScene(deflector_overhang=overhang, belt_edge_radius=0.0)
    r, sheet, parts = _sheet_dragged_to_deflector(scene, (0.68, 0.31), 0.04, 0.3)
    g = parts.deflectors[0]
    p = r.positions[:, sheet]
    side = (p - g.point) @ g.normal  # signed distance from the face plane [m], (k, n)
    assert side[0].min() == pytest.approx(0.03 / np.sqrt(2.0))
    y = p[:, :, 1].mean(axis=1)
    if overhang > 0.0:
        assert side.min() > 0.0
        assert y[-1] - y[0] < -0.01
    else:
        assert side[-1].max() < 0.0  # all past the deflector's plane, beside its root
        assert abs(y[-1] - y[0]) < 1e-3


@pytest.mark.parametrize("sheet_thickness", [2e-3, 1e-6])
def test_pressed_packaging_stays_in_front_of_a_deflector_sheet(sheet_thickness):
    # A 20 x 20 mm sheet (2 x 2 quads, 9 nodes) lies flat against the first deflector's face
    # and is pressed into it by a uniform pressure p = 2e6 Pa (ramped over 2 ms, no gravity):
    # each node gets p times its tributary area, F = 200 N on the centre node (10 mm quads:
    # 1e-4 m^2), 100 N on an edge node, 50 N on a corner. The deflector law of the paper's
    # scene (Table 6: c = 611 N/mm per 10 mm node, per area c / (10 mm)^2, linear) gives each
    # node the penetration s = p / c_area = 0.327 mm (the law is per area, so a uniform
    # pressure presses every node equally deep), and it sits at h - s = 0.15 - 0.327 mm from
    # the face. A face contact pushes a node back to the side of
    # the mesh it started the step on; the mesh is the sheet's mid-plane, so the node holds
    # while s < h + t/2. For the 2 mm default sheet that is 1.15 mm (703 N); for a sheet of
    # 1 um, 0.15 mm (92 N), less than F: the nodes cross the mid-plane and go through (in
    # the paper's scene KP's rim went through the second deflector that way and hooked KP
    # onto it).
    from flexparcel.scenarios.conveyor_scene import belt_law

    scene = ConveyorScene(belt_speed=0.0, deflector_thickness=sheet_thickness)
    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    parts = add_conveyor(b, scene)
    g = parts.deflectors[0]
    law = belt_law(stick_model=False)
    h = SHEET_T / 2
    u, w = np.meshgrid(np.linspace(-0.01, 0.01, 3), np.linspace(-0.01, 0.01, 3), indexing="ij")
    centre = g.point + 0.5 * g.length * g.tangent + np.array([0.0, 0.0, 0.05]) + h * g.normal
    pts = centre + u.reshape(-1, 1) * g.tangent + w.reshape(-1, 1) * np.array([0.0, 0.0, 1.0])
    quads = np.array([[0, 3, 4, 1], [1, 4, 5, 2], [3, 6, 7, 4], [4, 7, 8, 5]])
    mat = fp.ShellMaterial(926e6, 0.1, 2424.0, SHEET_T, 1.71e-3)
    sheet = b.add_shell_mesh(pts, quads, material=mat)
    b.add_face_contact(
        sheet, parts.deflector_vertices[0], law, thickness=parts.deflector_contact_thickness(h)
    )
    pressure = 2e6
    area = b.node_areas(sheet)
    for a in np.unique(area):
        b.add_force(sheet[area == a], -pressure * a * g.normal,
                    schedule=fp.Schedule((0.0, 2e-3), (0.0, 1.0)))  # fmt: skip
    assert area.max() == pytest.approx(1e-4)
    # the contact's damping (0.591 N s/mm) makes the approach a creep with time constant
    # d / c = 0.97 ms: 8 of them after the ramp leave e^-8 of the lag
    r = fp.simulate(b.finalize(), 10e-3, dt_out=1e-3)
    gap = (r.positions[-1, sheet] - g.point) @ g.normal  # from the upstream face [m]
    if sheet_thickness == 2e-3:
        s = pressure / law.stiffness
        assert gap == pytest.approx(np.full(9, h - s), rel=0.005)
    else:
        assert gap.max() < -h  # through the face: nothing stops them behind it


def _tip_scene():
    """A builder with the paper conveyor (belt at rest, no gravity); its first deflector, the
    scene's deflector law (linear, no stick model), the contact thickness of a 0.3 mm film
    on the sheet and the tip's mid-plane line (a point of it)."""
    from flexparcel.scenarios.conveyor_scene import belt_law

    b = fp.ModelBuilder(gravity=(0.0, 0.0, 0.0))
    parts = add_conveyor(b, ConveyorScene(belt_speed=0.0))
    g = parts.deflectors[0]
    h = parts.deflector_contact_thickness(SHEET_T / 2)
    mid = g.tip - 0.5 * parts.scene.deflector_thickness * g.normal
    return b, parts, g, belt_law(stick_model=False), h, mid


@pytest.mark.parametrize("tip_contact", [True, False])
def test_packaging_face_pressed_on_a_deflector_tip_is_held_by_the_tip_edge(tip_contact):
    # A 40 x 40 mm one-quad sheet stands across the first deflector's tip, square to the
    # sheet (its nodes 20 mm either side of the sheet's mid-plane, 30-70 mm above the belt),
    # 0.5 mm beyond the contact thickness h = 0.15 + 1 = 1.15 mm, and each node is pressed
    # towards the deflector's root by F = 5 N (ramped over 2 ms, no gravity; the deflector
    # law of the paper's scene, linear c = 611 N/mm at a 10 mm node). No node comes near the
    # sheet: only the tip edge can hold the face. The 100 mm edge is cut into 4 segments of
    # 25 mm, each with 5 stations 5 mm apart; line contact is per length, each station
    # carrying 5 mm x the 10 mm strip width = 5e-5 m^2 of the per-area law, i.e. c / 2;
    # 8 of them meet the face (32.5 ... 67.5 mm), so at rest the face carries 4 F on 4 c:
    # penetration s = 4 F / (4 c) = 0.008 mm (the per-point law had c / 5 per station:
    # 0.020 mm), and the face rests h - s from the tip's mid-plane line. Without the tip contact
    # (node-to-face only) it goes through.
    from flexparcel.scenarios.conveyor import (
        TIP_SEGMENT_LENGTH,
        TIP_STATION_SPACING,
        add_deflector_contact,
    )

    b, parts, g, law, h, mid = _tip_scene()
    start = mid + (h + 0.5e-3) * g.tangent
    pts = np.array([start + u * g.normal + np.array([0.0, 0.0, z])
                    for z in (0.03, 0.07) for u in (-0.02, 0.02)])  # fmt: skip
    # a stiff plate, so that the quad cannot twist about its diagonal: a film this coarse
    # would fold round the tip along its triangle split (it does, checked), which is what a
    # film does, but hides the face's distance from the tip; its contact thickness stays
    # the film's
    mat = fp.ShellMaterial(210e9, 0.3, 7850.0, 2e-3, 1e-5)
    sheet = b.add_shell_mesh(pts, np.array([[0, 1, 3, 2]]), material=mat)
    if tip_contact:
        add_deflector_contact(b, parts, sheet, law, shell_half_thickness=SHEET_T / 2)
    else:
        b.add_face_contact(sheet, parts.deflector_vertices[0], law, thickness=h)
    force = 5.0
    b.add_force(sheet, -force * g.tangent, schedule=fp.Schedule((0.0, 2e-3), (0.0, 1.0)))
    r = fp.simulate(b.finalize(), 10e-3, dt_out=1e-3)
    gap = (r.positions[-1, sheet] - mid) @ g.tangent  # the face's distance from the tip [m]
    if tip_contact:
        assert len(parts.deflector_tips[0]) == round(g.height / TIP_SEGMENT_LENGTH) + 1 == 5
        samples = round(TIP_SEGMENT_LENGTH / TIP_STATION_SPACING)
        stations = 8
        station_area = REFERENCE_SPACING * TIP_SEGMENT_LENGTH / samples
        s = 4 * force / (stations * law.stiffness * station_area)
        # the damping's creep (d / c = 0.97 ms) has decayed to e^-8 after the ramp; the
        # stations share their force over the two triangles of the split unequally, which the
        # plate balances by a small tilt: its nodes within 20 um, a turn below 0.5 mrad
        # (measured 12.5 um with c / 5 and with c / 20 per station alike)
        assert gap.mean() == pytest.approx(h - s, rel=0.01)
        assert np.ptp(gap) < 20e-6
    else:
        assert gap.max() < 0.0  # through the tip: nothing holds a face between its nodes


@pytest.mark.parametrize("edge_contact", [True, False])
@pytest.mark.parametrize("edge", ["tip", "end"])
def test_packaging_edge_across_a_deflector_edge_is_held_edge_to_edge(edge, edge_contact):
    # A 40 x 40 mm one-quad stiff plate lies flat, 60 mm above the belt, beyond the first
    # deflector's tip (or beyond its outer end, past the belt edge): its near edge runs
    # square to the sheet (its nodes 20 mm either side of the sheet's mid-plane) 0.5 mm
    # beyond the contact thickness h from the edge's mid-plane line, and each node is pushed
    # towards the sheet by F = 5 N (ramped over 2 ms, no gravity; the paper scene's
    # deflector law, linear c = 611 N/mm at a 10 mm node). No node comes near the sheet and
    # the plate's face is 2.5 mm from the edge's nearest stations: only the edge crossing the
    # sheet's edge can hold it. One pair (the plate's near edge, the sheet edge's segment
    # from 50 to 75 mm) carries the per-area law times the strip width (10 mm) times the
    # plate edge's 40 mm, i.e. 4 c (per length: the plate's edges cross the line one element,
    # 40 mm, apart): at rest it carries 4 F, so g = 4 F / (4 c) = 0.008 mm (the per-point law
    # had c: 0.033 mm) and the edge rests h - g from the line. Without edge-to-edge contact it
    # goes through.
    from flexparcel.scenarios.conveyor import add_deflector_contact

    b, parts, g, law, h, mid = _tip_scene()
    out = g.tangent  # from the sheet's edge outwards, along the sheet
    if edge == "end":
        mid = g.outer_end - 0.5 * parts.scene.deflector_thickness * g.normal
        out = -g.tangent
    start = mid + (h + 0.5e-3) * out + np.array([0.0, 0.0, 0.06])
    pts = np.array([start + u * g.normal + v * out
                    for v in (0.0, 0.04) for u in (-0.02, 0.02)])  # fmt: skip
    mat = fp.ShellMaterial(210e9, 0.3, 7850.0, 2e-3, 1e-5)
    plate = b.add_shell_mesh(pts, np.array([[0, 1, 3, 2]]), material=mat)
    if edge_contact:
        add_deflector_contact(b, parts, plate, law, shell_half_thickness=SHEET_T / 2)
    else:  # the contacts of add_deflector_contact without the edge-to-edge ones
        b.add_face_contact(plate, parts.deflector_vertices[0], law, thickness=h)
        for line in (parts.deflector_tips[0], parts.deflector_ends[0]):
            b.add_edge_face_contact(line, plate, law, thickness=h, samples=5)
    force = 5.0
    b.add_force(plate, -force * out, schedule=fp.Schedule((0.0, 2e-3), (0.0, 1.0)))
    r = fp.simulate(b.finalize(), 10e-3, dt_out=1e-3)
    near = plate[:2]
    gap = (r.positions[-1, near] - mid) @ out  # the near edge's distance from the line
    if edge_contact:
        s = 4 * force / (law.stiffness * REFERENCE_SPACING * 0.04)
        assert gap.mean() == pytest.approx(h - s, rel=0.01)
        assert np.ptp(gap) < 5e-6  # square to the edge: no turn
    else:
        assert gap.max() < 0.0  # through the edge: no station reaches an edge between them


# ------------------------------------------------------------------------------ responses

T = np.round(np.arange(0.0, 0.6 + 1e-9, 0.01), 10)


def _rectangle_nodes(centre_xy, yaw_rad, z=0.01):
    """Corners of a 0.2 x 0.1 m rectangle, shape (k, 4, 3), at centres (k, 2) and yaws (k,)."""
    local = np.array([[0.1, 0.05], [-0.1, 0.05], [-0.1, -0.05], [0.1, -0.05]])
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (k, 2, 2)
    xy = centre_xy[:, None, :] + np.einsum("kij,nj->kni", rot, local)
    return np.concatenate([xy, np.full(xy.shape[:2] + (1,), z)], axis=-1)


def _responses(x, y=None, yaw=None, **kw):
    y = np.zeros_like(x) if y is None else y
    yaw = np.zeros_like(x) if yaw is None else yaw
    pos = _rectangle_nodes(np.column_stack([x, y]), yaw)
    res = SimpleNamespace(time=T, positions=pos)
    return conveyor_responses(res, {"c": np.arange(4)}, ConveyorScene(), **kw)["c"]


def test_exit_time_and_position_are_interpolated_at_the_belt_end():
    r = _responses(2.5 + 1.6 * T)
    # x = 3.0 at t = 0.5 / 1.6 = 0.3125 s, between frames: linear interpolation is exact here
    assert r.exit_time == pytest.approx(0.3125, abs=1e-12)
    assert r.exit_position == pytest.approx([3.0, 0.0, 0.01])
    assert r.jam_start is None
    assert _responses(1.0 + 1.6 * T).exit_time is None


def test_exit_is_at_the_end_of_the_last_belt():
    # with a transfer belt (0.02 m gap, 0.5 m) the consignment exits 0.52 m later
    scene = ConveyorScene(transfer=BeltTransfer(gap=0.02, length=0.5, speed=1.6))
    x = 3.0 + 1.6 * T
    pos = _rectangle_nodes(np.column_stack([x, 0 * x]), 0 * x)
    res = SimpleNamespace(time=T, positions=pos)
    r = conveyor_responses(res, {"c": np.arange(4)}, scene)["c"]
    assert r.exit_time == pytest.approx(0.52 / 1.6, abs=1e-12)


def test_box_is_handed_over_to_a_slower_transfer_belt():
    # a 100 g box riding the first belt at 1 m/s bridges a 5 mm gap onto a second belt at
    # 0.5 m/s, slides there at mu_d and rides it: it loses 0.5 m/s in 0.5 / (mu_d g) =
    # 0.127 s, then moves at the second belt's speed. A box touches the belts by its corners
    # (as a plane): over the gap a corner sinks between the two rounded edges (radius 10 mm)
    # to where it is 10 + 3 mm from both edge axes, sqrt(13^2 - 2.5^2) - 10 = 2.76 mm above
    # the belt's surface instead of 3 mm: 0.24 mm (a 20 mm gap: 4.7 mm)
    mu, v1, v2 = 0.5, 1.0, 0.5
    scene = ConveyorScene(belt_length=0.4, belt_speed=v1, deflector_x=(),
                          transfer=BeltTransfer(gap=0.005, length=0.6, speed=v2))  # fmt: skip
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -G))
    parts = add_conveyor(b, scene)
    box = RoundedBox(0.06, 0.04, 0.02, edge_radius=0.003, mass=0.1)
    node = b.add_rigid_body(box, (0.3, 0.0, 0.0101))
    for plane in parts.belt_planes:
        b.add_contact(node, plane, _law(mu))
    model = b.finalize()
    s0 = model.initial_state()
    s0.velocities[node, 0] = v1
    r = fp.simulate(model, 0.45, dt_out=0.01, state=s0,
                    options=fp.IntegratorOptions(tol_displacement=1e-5))  # fmt: skip
    x, z, vx = r.positions[:, node, 0], r.positions[:, node, 2], r.velocities[:, node, 0]
    assert np.abs(z - 0.0101).max() < 0.24e-3 + 0.2e-3  # bridged: the corner sink, bounce
    assert x[-1] > 0.405 + 0.1 and abs(vx[-1] - v2) < 0.01  # on the second belt, at its speed
    arrive = r.time[np.argmax(x > 0.405 + 0.03)]  # its rear corners leave the first belt
    slowed = r.time[np.argmax(vx < v2 + 0.01)]
    assert slowed - arrive == pytest.approx((v1 - v2 - 0.01) / (mu * G), abs=0.03)


def test_jam_exit_and_group_responses_for_design_studies():
    from flexparcel.scenarios.conveyor_scenario import (
        _consignment_responses,
        _group_responses,
    )

    stuck = _responses(np.minimum(1.6 * T, 1.6 * 0.2))  # jams at 0.2 s, run ends at 0.6 s
    out = _responses(2.5 + 1.6 * T, y=np.full_like(T, 0.1))  # exits at 0.3125 s, y = 0.1
    other = _responses(2.6 + 1.6 * T, y=np.full_like(T, -0.1))  # exits at 0.25 s, y = -0.1
    r = _consignment_responses("a", stuck, None)
    assert r["a.jammed"].value == 1.0 and r["a.time_stuck"].value == pytest.approx(0.4)
    assert not r["a.exit_y"].reached and "did not reach" in r["a.exit_y"].note
    r = _consignment_responses("b", out, None)
    assert r["b.jammed"].value == 0.0 and r["b.time_stuck"].value == 0.0
    assert r["b.exit_y"].value == pytest.approx(0.1)
    g = _group_responses({"b": out, "c": other})
    assert g["group.jammed"].value == 0.0
    assert g["group.exit_time_last"].value == pytest.approx(0.3125)
    assert g["group.exit_spread"].value == pytest.approx(0.1)  # std of +-0.1 m
    g = _group_responses({"a": stuck, "b": out})
    assert g["group.jammed"].value == 1.0
    assert not g["group.exit_time_last"].reached and "a did not reach" in g[
        "group.exit_time_last"].note  # fmt: skip
    assert not g["group.exit_spread"].reached  # one exit: no spread
    x = 1.6 * T[:5]  # 0.04 s: shorter than the 0.3 s jam window
    res = SimpleNamespace(
        time=T[:5], positions=_rectangle_nodes(np.column_stack([x, 0 * x]), 0 * x)
    )
    short = conveyor_responses(res, {"c": np.arange(4)}, ConveyorScene())["c"]
    assert not _consignment_responses("s", short, None)["s.jammed"].reached
    assert not _group_responses({"s": short})["group.jammed"].reached


def test_jam_detection():
    moving = np.minimum(1.6 * T, 1.6 * 0.2)  # stops dead at t = 0.2 s
    assert _responses(moving).jam_start == pytest.approx(0.2)
    # creeping 6 mm per 0.3 s is progress (> 5 mm); 4.5 mm per 0.3 s is not
    assert _responses(0.02 * T).jam_start is None
    assert _responses(0.015 * T).jam_start == 0.0
    # rocking back and forth by 20 mm without net progress is a jam
    assert _responses(0.01 * np.sin(2 * np.pi * 8 * T)).jam_start is not None
    # at rest after leaving the belt is not a jam; jam_time and jam_distance are honoured
    assert _responses(np.minimum(2.9 + 1.6 * T, 3.2)).jam_start is None
    assert _responses(moving, jam_time=0.5).jam_start is None  # 0.2 + 0.5 > 0.6 s recorded
    assert _responses(0.015 * T, jam_distance=4e-3).jam_start is None


def test_jam_verdict_tells_no_jam_from_not_judged():
    # a None jam_start is one of three outcomes; the verdict (and the report) says which
    state, text = _responses(np.minimum(1.6 * T, 0.32)).jam_verdict()
    assert state == "jam" and "jammed from t = 0.200 s" in text
    state, text = _responses(0.02 * T).jam_verdict()
    # windows of 0.3 s judged up to 0.6 - 0.3 s: the later ones run past the record
    assert state == "none" and "starting up to t = 0.300 s" in text
    assert _responses(2.5 + 1.6 * T).jam_verdict()[0] == "left"
    short = _responses(0.02 * T, jam_time=0.8).jam_verdict()
    assert short[0] == "not judged" and short[1].startswith("not reached in this run")
    assert _responses(0.02 * T, jam_time=0.8).to_dict()["notes"]["jam_start_s"] == short[1]


def test_yaw_is_unwrapped_through_the_axis_ambiguity():
    # a rectangle turning by 200 deg: its long axis is only defined modulo 180 deg
    yaw = np.radians(200.0) * T / T[-1]
    r = _responses(0.5 + 0.3 * T, yaw=yaw + 0.3)
    assert r.yaw_deg == pytest.approx(np.degrees(yaw), abs=1e-9)
    assert np.allclose(_responses(0.5 + T).yaw_deg, 0.0)
    # a square has no long axis: no yaw
    pos = np.repeat(np.array([[[0, 0, 0], [0.1, 0, 0], [0.1, 0.1, 0], [0, 0.1, 0]]]), len(T), 0)
    res = SimpleNamespace(time=T, positions=pos.astype(float))
    assert conveyor_responses(res, {"sq": [0, 1, 2, 3]}, ConveyorScene())["sq"].yaw_deg is None


def test_deflector_contact_time_uses_any_node_near_the_face_rectangle():
    g = ConveyorScene().deflectors()[0]
    # one node of the set touches the first deflector (1 mm off its face, 0.1 m from the
    # root) for 0.1 <= t <= 0.3 s, far away otherwise; the other node stays far
    near = g.root + 0.1 * g.tangent + 0.001 * g.normal + [0.0, 0.0, 0.02]
    far = np.array([0.2, 0.0, 0.01])
    on = (T >= 0.1 - 1e-9) & (T <= 0.3 + 1e-9)
    pos = np.stack([np.where(on[:, None], near, far), np.broadcast_to(far, (len(T), 3))], 1)
    forces = np.zeros((len(T), 3))
    forces[25] = [3.0, 4.0, 0.0]
    res = SimpleNamespace(time=T, positions=pos)
    r = conveyor_responses(res, {"c": [0, 1]}, ConveyorScene(), contact_forces={"c": forces})
    # trapezoidal rule over the in/out frames: the 0.2 s episode plus half a frame each side
    assert r["c"].deflector_contact_time[0] == pytest.approx(0.2, abs=0.01 + 1e-12)
    assert r["c"].deflector_contact_time[1] == 0.0
    assert (r["c"].peak_contact_force, r["c"].peak_contact_force_time) == (5.0, 0.25)
    # a point past the deflector's tip lies on its unbounded plane but is not near the face
    beyond = g.tip + 0.05 * g.tangent + [0.0, 0.0, 0.02]
    assert g.distance(beyond) > 0.04
    d = json.loads(json.dumps(r["c"].to_dict()))
    assert d["peak_contact_force_N"] == 5.0 and len(d["trajectory"]["x_m"]) == len(T)
    assert d == r["c"].to_dict() and d["exit_time_s"] is None
    assert d["contact_force_N"][25] == 5.0 and d["contact_force_N"][0] == 0.0
    # never touching deflector 2 is null with a note, not a contact of 0.0 s (read as t = 0)
    assert d["deflector_contact_duration_s"][0] == pytest.approx(0.2, abs=0.01 + 1e-12)
    assert d["deflector_contact_duration_s"][1] is None
    assert d["deflector_first_contact_s"][0] == pytest.approx(0.1, abs=1e-9)
    assert d["deflector_first_contact_s"][1] is None
    assert (
        "no node came within 2 mm of the face of deflector 2"
        in (d["notes"]["deflector_contact_duration_s"])
    )
    assert d["notes"]["exit_time_s"] == "did not reach the belt end within the run"
    # every key with a number carries its unit
    units = ("_s", "_m", "_deg", "_N")
    assert all(k.endswith(units) for k in d if k not in ("name", "trajectory", "notes",
                                                          "jam_verdict"))  # fmt: skip
    assert all(k.endswith(units) for k in d["trajectory"])


def test_response_bad_input():
    res = SimpleNamespace(time=T, positions=np.zeros((len(T), 3, 3)))
    with pytest.raises(ValueError, match=r"consignment 'c': node id 3 outside \[0, 2\]"):
        conveyor_responses(res, {"c": [0, 3]}, ConveyorScene())
    with pytest.raises(ValueError, match=r"contact_forces\['c'\] must have shape"):
        conveyor_responses(res, {"c": [0]}, ConveyorScene(), contact_forces={"c": np.ones(3)})
    with pytest.raises(ValueError, match=r"jam_time must be > 0"):
        conveyor_responses(res, {"c": [0]}, ConveyorScene(), jam_time=0.0)


# ------------------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"belt_length": -1.0}, r"ConveyorScene\.belt_length must be in \(0, 50\] m"),
        ({"belt_length": "3"}, r"ConveyorScene\.belt_length must be a number"),
        ({"belt_width": 6.0}, r"ConveyorScene\.belt_width must be in \(0, 5\] m"),
        ({"belt_speed": -1.6}, r"ConveyorScene\.belt_speed must be in \[0, 10\] m/s"),
        ({"deflector_angle_deg": 5.0}, r"ConveyorScene\.deflector_angle_deg must be in \[10, 90\]"),
        ({"deflector_height": 0.0}, r"ConveyorScene\.deflector_height must be in \(0, 1\] m"),
        ({"deflector_overhang": -0.1}, r"ConveyorScene\.deflector_overhang must be in \[0, 1\] m"),
        ({"centre_gap": 0.3}, r"ConveyorScene\.centre_gap must be in \[0, belt_width / 2 = 0\.3\)"),
        (
            {"deflector_x": (1.0, 0.5)},
            r"ConveyorScene\.deflector_x\[1\] must be > deflector_x\[0\]",
        ),
        ({"deflector_x": (2.9,)}, r"ConveyorScene\.deflector_x\[0\] must be in \[0, belt_length"),
        ({"deflector_x": 0.8}, r"ConveyorScene\.deflector_x must be a sequence"),
        ({"side_guides": "yes"}, r"ConveyorScene\.side_guides must be True or False"),
    ],
)
def test_bad_scene_parameters_name_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ConveyorScene(**kwargs)


def test_deflector_geometry_refuses_a_negative_overhang():
    g = ConveyorScene().deflectors()[0]
    with pytest.raises(ValueError, match=r"DeflectorGeometry\.overhang must be >= 0 m, got -0\.01"):
        DeflectorGeometry(g.root, g.tangent, g.normal, g.length, g.height, overhang=-0.01)


def test_friction_table_defaults_and_lookups():
    assert set(PACKAGING_SURFACES) == set(PACKAGING_MATERIALS)
    assert surface_material("polybag") == "pe_film"
    assert surface_material("kraft_paper_bubble_wrap") == "kraft_paper"
    for m in SURFACE_MATERIALS:
        for c in (BELT, DEFLECTOR):
            mu_s, mu_d = friction_pair(m, c)
            assert 0.0 <= mu_d <= mu_s
            assert "not measured" in DEFAULT_FRICTION_TABLE[(m, c)].source
    law = with_friction(_law(0.1), "pe_film", DEFLECTOR)
    assert (law.mu_static, law.mu_dynamic) == friction_pair("pe_film", DEFLECTOR)
    assert law.stiffness == _law(0.1).stiffness  # friction only: 1e5 N/m per 1e-4 m^2 corner
    with pytest.raises(FrictionTableError, match=r"unknown surface material 'paper'.*kraft_paper"):
        friction_pair("paper", BELT)
    with pytest.raises(FrictionTableError, match=r"'polybag' is a packaging material"):
        friction_pair("polybag", BELT)
    with pytest.raises(FrictionTableError, match=r"unknown counterpart 'rubber'; allowed: pu"):
        friction_pair("pe_film", "rubber")
    with pytest.raises(FrictionTableError, match=r"unknown packaging material 'box'"):
        surface_material("box")


def test_friction_table_override_file(tmp_path):
    f = tmp_path / "mu.toml"
    f.write_text('[pe_film.pu]\nmu_static = 0.45\nmu_dynamic = 0.4\nsource = "own test"\n')
    table = load_friction_table(f)
    assert friction_pair("pe_film", BELT, table) == (0.45, 0.4)
    assert table[("pe_film", BELT)].source == "own test"
    assert table[("cardboard", DEFLECTOR)] == DEFAULT_FRICTION_TABLE[("cardboard", DEFLECTOR)]
    f.write_text("[cardboard.steel_x6cr17]\nmu_static = 0.3\nmu_dynamic = 0.3\n")
    assert load_friction_table(f)[("cardboard", DEFLECTOR)].source == "override from mu.toml"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[paper.pu]\nmu_static = 0.4\nmu_dynamic = 0.3\n", r"\[paper\]: unknown surface material"),
        ("[pe_film.rubber]\nmu_static = 0.4\nmu_dynamic = 0.3\n", r"\[pe_film\.rubber\]: unknown"),
        (
            "[pe_film.pu]\nmu_static = 0.4\nmu_kinetic = 0.3\n",
            r"\[pe_film\.pu\]: unknown key\(s\) mu_kinetic; allowed: mu_static, mu_dynamic",
        ),
        ("[pe_film.pu]\nmu_static = 0.4\n", r"\[pe_film\.pu\]: missing mu_dynamic"),
        (
            "[pe_film.pu]\nmu_static = 0.3\nmu_dynamic = 0.4\n",
            r"\[pe_film\.pu\]: mu_dynamic = 0\.4 must be <= mu_static = 0\.3",
        ),
        ("[kraft_paper.pu]\nmu_static = 40\nmu_dynamic = 0.3\n", r"mu_static must be in \[0, 2\]"),
        ("[kraft_paper.pu]\nmu_static = true\nmu_dynamic = 0.3\n", r"mu_static must be a finite"),
        ("[kraft_paper.pu]\nmu_static = 0.5\nmu_dynamic = -0.1\n", r"mu_dynamic must be in \[0, 2"),
        ("pe_film = 0.3\n", r"pe_film must be a table of counterparts"),
        ("[pe_film.pu\n", r"not valid TOML"),
    ],
)
def test_bad_friction_file_names_the_key(tmp_path, text, message):
    f = tmp_path / "mu.toml"
    f.write_text(text)
    with pytest.raises(FrictionTableError, match=message):
        load_friction_table(f)


def test_missing_friction_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"friction table file not found"):
        load_friction_table(tmp_path / "none.toml")
