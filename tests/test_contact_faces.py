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


# A V-shaped fold of two faces sharing the edge (-10, 0, 0)-(10, 0, 0) mm, each rising 3 mm over
# 10 mm (16.7 deg), and a node in the valley, inside both faces' prisms: the geometry of a
# content node against the film wrapped round its edge (the conveyor at 25 mm, where Newton's
# iterates straddled the two faces' equal depth; see flexparcel.contact.faces).
_FOLD = np.array([[0.0, 0.0, 0.0], [-0.01, 0.0, 0.0], [0.01, 0.0, 0.0],
                  [0.0, -0.01, 0.003], [0.0, 0.01, 0.003]])  # fmt: skip
_FOLD_TRIS = np.array([[2, 1, 3], [1, 2, 4]])  # both normals up, n_A towards +y, n_B towards -y
_FOLD_H = 1e-4  # contact thickness [m]


def _fold_force(y, face):
    """Force (3,) on the valley node at lateral offset ``y`` [m], 50 um above the fold line,
    with the preferred face ``face`` (1,) (updated in place to the face used)."""
    from flexparcel.contact.faces import face_contact_forces

    pos = _FOLD.copy()
    pos[0] = (0.001, y, 5e-5)
    f = np.zeros((5, 6))
    fk, fc, dofs = np.zeros((2, 12, 12)), np.zeros((2, 12, 12)), np.zeros((2, 12), np.int64)
    law = ContactLaw(stiffness=6.49e9).packed()  # Table 6's 649 N/mm per (10 mm)^2
    nc = face_contact_forces(
        np.array([[0, 0], [0, 1]]), np.array([1.0, 1.0]), np.array([0]), _FOLD_TRIS, _FOLD_H,
        law, 1.0, np.array([1e-4]), pos, np.zeros((5, 6)), f, fk, fc, dofs, np.ones(5), 1e9,
        np.zeros(1), np.zeros((1, 3)), np.zeros(1), np.zeros((1, 3)), np.zeros(1), pos, face,
    )[0]  # fmt: skip
    assert nc == 1
    return f[0, :3]


def _fold_normals():
    from flexparcel.contact.geometry import point_triangle_contact

    return [point_triangle_contact(_FOLD[0] + (0.001, 0, 5e-5), *_FOLD[t], _FOLD_H, 1)[3]
            for t in _FOLD_TRIS]  # fmt: skip


def test_node_in_a_fold_keeps_its_face_within_the_margin_and_takes_the_deeper_beyond_it():
    from flexparcel.contact.faces import FACE_KEEP_MARGIN

    n_a, n_b = _fold_normals()
    assert np.degrees(np.arccos(n_a @ n_b)) > 30.0  # the fold turns the normal by 33 deg
    # depth difference s_A - s_B = 2 y sin(16.7 deg) = 0.57 y: at y = 1e-8 m it is 6 nm, below
    # the margin (1e-3 h = 100 nm); at 1e-6 m 0.57 um, beyond it
    assert 0.57e-8 < FACE_KEEP_MARGIN * _FOLD_H < 0.57e-6
    unit = lambda f: f / np.linalg.norm(f)  # noqa: E731
    normals = (n_a, n_b)
    for y, deeper in ((1e-8, 1), (-1e-8, 0)):  # a node towards +y is nearer face B's rise
        # no preference: the deepest face, pushing along its own normal
        face = np.full(1, -1)
        f = _fold_force(y, face)
        assert np.allclose(unit(f), normals[deeper], atol=1e-6) and face[0] == deeper
        # a preference for the other face, within the margin: kept
        face = np.array([1 - deeper])
        f = _fold_force(y, face)
        assert face[0] == 1 - deeper
        assert np.allclose(unit(f), normals[1 - deeper], atol=1e-6)
        # beyond the margin the deeper face takes over
        face = np.array([1 - deeper])
        _fold_force(1e2 * y, face)
        assert face[0] == deeper
    # a node out of contact forgets its face
    face = np.array([0])
    pos_far = 0.01  # 10 mm above the fold: no penetration
    from flexparcel.contact.faces import face_contact_forces

    pos = _FOLD.copy()
    pos[0] = (0.001, 0.0, pos_far)
    args = (np.zeros((5, 6)), np.zeros((2, 12, 12)), np.zeros((2, 12, 12)),
            np.zeros((2, 12), np.int64))  # fmt: skip
    nc = face_contact_forces(
        np.array([[0, 0], [0, 1]]), np.array([1.0, 1.0]), np.array([0]), _FOLD_TRIS, _FOLD_H,
        ContactLaw(stiffness=6.49e9).packed(), 1.0, np.array([1e-4]), pos, np.zeros((5, 6)),
        *args, np.ones(5), 1e9, np.zeros(1), np.zeros((1, 3)), np.zeros(1), np.zeros((1, 3)),
        np.zeros(1), pos, face,
    )[0]  # fmt: skip
    assert nc == 0 and face[0] == -1


def test_iterates_straddling_a_fold_see_one_continuous_force():
    # Newton's iterates 0.1 nm either side of the faces' equal depth: carried from evaluation
    # to evaluation (as NodeFaceSet does within a step), the face stays put and the force
    # changes by what 0.1 nm of motion makes; chosen afresh each time, it turns by the fold
    # angle, a jump of 0.57 of its size (the 2-cycle of the conveyor's stall)
    face = np.full(1, -1)
    kept = [_fold_force(y, face) for y in (1e-10, -1e-10, 1e-10, -1e-10)]
    fresh = [_fold_force(y, np.full(1, -1)) for y in (1e-10, -1e-10)]
    size = np.linalg.norm(kept[0])
    k_point = 6.49e9 * 1e-4  # the law's stiffness times the node's area [N/m]
    assert max(np.linalg.norm(k - kept[0]) for k in kept) < k_point * 2e-10  # 0.1 nm each way
    assert np.linalg.norm(fresh[1] - fresh[0]) > 0.5 * size


def test_node_face_set_carries_its_faces_through_a_step_and_a_checkpoint():
    model, _ = _stack()
    cs = next(c for c in model.contact_sets if c.kind == "node_face")
    cs.face_trial[:] = 3
    cs.commit()
    assert (cs.face == 3).all()
    cs.face_trial[:] = 5  # a rejected try's evaluations
    cs.begin_step()  # the retry starts from the accepted step's faces
    assert (cs.face_trial == 3).all()
    hist = {k: v.copy() for k, v in cs.history().items()}  # as the integrator keeps it
    assert (hist["face"] == 3).all()
    cs.face[:] = -1
    cs.restore_history(hist)
    assert (cs.face == 3).all() and (cs.face_trial == 3).all()
    # a checkpoint written before faces were kept: no preference
    old = {k: v for k, v in hist.items() if k != "face"}
    cs.restore_history(old)
    assert (cs.face == -1).all()
