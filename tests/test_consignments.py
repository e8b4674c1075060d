"""Consignment builders, assembly, snapshots and the paper's tests on coarse meshes (issue 5).

The paper-mesh runs (10 mm, Table 6 parameters) are far too long for the default suite; they are
produced by ``flexparcel demo`` / ``flexparcel bench`` and reported in the issue's closing note.
Here: the presets' masses and sizes, the small example consignment (20 mm shells) assembled once
per module, its snapshot round trip, and short swing and drop runs from it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from contact_views import node_face_sets, plane_points
from flexparcel.builder import ModelBuilder
from flexparcel.consignments.assembly import (
    AssemblySettings,
    assemble,
    content_outside_packaging,
    content_scale_for,
)
from flexparcel.consignments.build import (
    FIT_CLEARANCE,
    FLEXIBLE_CONTENT_EDGE_RADIUS,
    GLUED_STRIP_WIDTH,
    PRESETS,
    ConsignmentBuild,
    _block_edges,
    _block_face_count,
    _hex_block,
    _round_block,
    add_consignment,
)
from flexparcel.consignments.snapshot import (
    SnapshotError,
    load_snapshot,
    place_snapshot,
    save_snapshot,
)
from flexparcel.consignments.userfile import load_consignment_file
from flexparcel.contact.geometry import point_box_contact
from flexparcel.model.rigid import RoundedBox
from flexparcel.scenarios.consignment_tests import drop_test, swing_test

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"


# --------------------------------------------------------------------------------------------
# The four presets (paper Table 2) at the paper's mesh sizes


@pytest.mark.parametrize("name", list(PRESETS))
def test_preset_mass_and_flat_size(name):
    spec = PRESETS[name]
    build = ConsignmentBuild.of(name)
    b = ModelBuilder()
    c = add_consignment(b, build)
    model = b.finalize()
    # total mass: the packaging (areal density x real mesh area) plus the content takes the rest;
    # Table 2's mass within 1 %
    total = model.mass[c.node_ids, 0].sum()
    assert total == pytest.approx(spec.mass_g * 1e-3, rel=0.01)
    # the builder's bookkeeping agrees with the lumped masses (to the rounding of the strip's
    # element areas, well below a milligram)
    assert c.packaging_mass + c.content_mass == pytest.approx(total, rel=1e-5)
    # the packaging is at most half the mass (all four hold a box or a bag that dominates)
    assert 0.0 < c.packaging_mass < 0.5 * total
    # flat extents: the envelope (+ KP/BW's glued strip) to within one element. The flat size is
    # Table 2's outer size unless the content cannot fit (PB, KP: a 310 mm content in a 315 /
    # 320 mm bag): then content + its height + the fit clearance, so it can close around it.
    # KP's gusseted bag wraps the height at its sealed ends only: its side walls give it, so
    # its width is Table 2's
    h = build.element_size
    p = model.positions0[c.packaging]
    ext = p.max(axis=0) - p.min(axis=0)
    strip = GLUED_STRIP_WIDTH if build.has_glued_strip else 0.0
    fit = max(FIT_CLEARANCE, h)  # ConsignmentBuild.fit_clearance
    side = 0.0 if spec.construction == "gusseted" else spec.content_height_mm
    need_l = (spec.content_length_mm + spec.content_height_mm) * 1e-3 + fit
    need_w = (spec.content_width_mm + side) * 1e-3 + fit
    assert ext[0] == pytest.approx(max(spec.length_mm * 1e-3, need_l + strip), abs=h)
    assert ext[1] == pytest.approx(max(spec.width_mm * 1e-3, need_w), abs=h)
    if name == "KP":  # the gusseted bag: Table 2's width exactly
        assert spec.construction == "gusseted"
        assert ext[1] == pytest.approx(spec.width_mm * 1e-3, abs=1e-12)
    if name in ("KPBW", "BW"):  # these fit: Table 2's outer size itself
        assert ext[0] == pytest.approx(spec.length_mm * 1e-3, abs=h)
        assert ext[1] == pytest.approx(spec.width_mm * 1e-3, abs=h)
    # the content: Table 2's size (rigid box or hex block)
    if c.content_body is not None:
        assert np.allclose(c.content_box, np.array([spec.content_length_mm,
                           spec.content_width_mm, spec.content_height_mm]) * 1e-3)  # fmt: skip
    else:
        q = model.positions0[c.content_nodes]
        assert np.allclose(q.max(axis=0) - q.min(axis=0), np.array([spec.content_length_mm,
                           spec.content_width_mm, spec.content_height_mm]) * 1e-3)  # fmt: skip
    # the vertical drop's edge: the +x outer edge (KP/BW: the glued strip's)
    assert np.allclose(model.positions0[c.edge, 0], p[:, 0].max())
    if name == "KP":
        assert c.glue.size > 0  # the content is glued to the bottom layer (FDR stripe)


def test_flexible_content_and_film_contact_both_ways():
    # PB's hex block: film nodes against the block's boundary faces, and the block's edge and
    # corner nodes against the film faces; with the first alone the block's edges slip
    # between the film nodes (found in the conveyor scene at 25 mm)
    build = ConsignmentBuild.of("PB", element_size=0.025)
    b = ModelBuilder()
    c = add_consignment(b, build)
    model = b.finalize()
    assert c.content_body is None
    # the block's lattice before its edges were rounded (same node order)
    s = PRESETS["PB"]
    sharp, _ = _hex_block(*(np.array([s.content_length_mm, s.content_width_mm,
                                      s.content_height_mm]) * 1e-3), 0.025, (0, 0, 0))  # fmt: skip
    on_faces = _block_face_count(sharp)
    on_edges = on_faces >= 2  # the block's edges and corners
    assert 0 < on_edges.sum() < (on_faces >= 1).sum()  # and face-inner nodes are left out
    film, content = set(c.packaging.tolist()), set(c.content_nodes.tolist())
    pairs = {}  # (whose nodes, whose faces) -> nodes
    for nodes, tris in node_face_sets(model):
        faces = "film" if set(tris.ravel().tolist()) <= film else "content"
        assert set(tris.ravel().tolist()) <= (film if faces == "film" else content)
        who = "film" if set(nodes.tolist()) <= film else "content"
        assert set(nodes.tolist()) <= (film if who == "film" else content)
        pairs.setdefault((who, faces), set()).update(nodes.tolist())
    assert pairs[("film", "content")] == film  # every film node against the block's faces
    assert pairs[("content", "film")] == set(c.content_nodes[on_edges].tolist())
    assert ("content", "content") not in pairs


def test_flexible_content_edges_are_rounded_and_its_mass_kept():
    # PB's granulate block has its edges rounded with half its height (a fold): face nodes
    # stay on the box's faces, edge nodes lie on quarter cylinders and corners on sphere
    # octants of that radius round the inner box, and the content keeps Table 2's mass
    build = ConsignmentBuild.of("PB", element_size=0.025)
    b = ModelBuilder()
    c = add_consignment(b, build)
    model = b.finalize()
    s = build.spec
    size = np.array([s.content_length_mm, s.content_width_mm, s.content_height_mm]) * 1e-3
    r = FLEXIBLE_CONTENT_EDGE_RADIUS * size[2]
    q = model.positions0[c.content_nodes]
    centre = 0.5 * (q.min(axis=0) + q.max(axis=0))
    np.testing.assert_allclose(q.max(axis=0) - q.min(axis=0), size, rtol=1e-12)
    inner = np.maximum(size / 2 - r, 0.0)
    dist = np.linalg.norm(q - np.clip(q, centre - inner, centre + inner), axis=1)
    sharp, _ = _hex_block(*size, 0.025, centre)
    on_edges = _block_edges(sharp)
    corners = _block_face_count(sharp) == 3
    assert corners.sum() == 8
    np.testing.assert_allclose(dist[on_edges], r, rtol=1e-12)  # on the rounded surface
    assert np.all(dist <= r * (1 + 1e-12))  # nothing outside it
    moved = np.linalg.norm(q - sharp, axis=1)
    assert np.all(moved[~on_edges] < 1e-12)  # face and interior nodes stay
    # a corner moves by r (sqrt 3 - 1) along the diagonal, an edge node by r (sqrt 2 - 1)
    np.testing.assert_allclose(moved[corners], r * (np.sqrt(3) - 1), rtol=1e-12)
    assert np.all(moved[on_edges & ~corners] <= r * (np.sqrt(2) - 1) * (1 + 1e-12))
    content_mass = model.mass[c.content_nodes, 0].sum()
    np.testing.assert_allclose(content_mass, c.content_mass, rtol=1e-12)
    np.testing.assert_allclose(content_mass + c.packaging_mass, s.mass_g * 1e-3, rtol=1e-12)
    with pytest.raises(ValueError, match="edge radius must lie in"):
        _round_block(sharp, 0.6 * size[2])


def test_content_outside_packaging_by_ray_parity():
    # BW's flat packaging (two layers 2 mm apart, joined at the rim: a closed surface) and
    # its content node put inside it (the centre: its vertical rays pass at film nodes), above
    # it, below it and beside it
    b = ModelBuilder()
    c = add_consignment(b, ConsignmentBuild.of("BW", element_size=0.05))
    model = b.finalize()
    pos = model.positions0.copy()
    lo, hi = pos[c.packaging].min(axis=0), pos[c.packaging].max(axis=0)
    inside = 0.5 * (lo + hi)
    pos[c.content_nodes[0]] = inside
    assert content_outside_packaging(model, c, pos).size == 0
    for outside in (inside + [0, 0, 0.01], inside + [hi[0] - lo[0], 0, 0], inside - [0, 0, 0.01]):
        pos[c.content_nodes[0]] = outside
        assert np.array_equal(content_outside_packaging(model, c, pos), c.content_nodes)


def test_builds_number_nodes_identically():
    # snapshots rely on it: two equal builds give the same mesh
    build = ConsignmentBuild.of("BW", element_size=0.02)
    meshes = []
    for _ in range(2):
        b = ModelBuilder()
        add_consignment(b, build)
        meshes.append(b.finalize().positions0)
    assert np.array_equal(meshes[0], meshes[1])


# --------------------------------------------------------------------------------------------
# The small example: assembled once


@pytest.fixture(scope="module")
def small(small_assembly):
    # conftest: assembled once per session by the CLI (shared with the CLI tests)
    snap = load_snapshot(small_assembly / "snapshot.npz")
    assert snap.build == load_consignment_file(EXAMPLE)
    return snap


def _content_penetration(snapshot) -> float:
    """Deepest penetration [m] of a packaging node (radius: half the thickness) into the rigid
    content box of the settled snapshot (negative: the closest gap)."""
    build = snapshot.build
    b = ModelBuilder()
    c = add_consignment(b, build)
    lc, wc, hc = c.content_box
    radius = min(3e-3, 0.25 * min(lc, wc, hc))
    half = RoundedBox(lc, wc, hc, edge_radius=radius, mass=1.0).half_inner
    centre = snapshot.positions[c.content_body]
    rot = snapshot.rotations[c.content_body]
    depth = [
        point_box_contact(snapshot.positions[i], centre, rot, half, radius, c.contact_radius)[0]
        for i in c.packaging
    ]
    return float(max(depth))


def test_assembly_ends_at_rest_wrapped_and_not_penetrated(small):
    info = small.info
    assert info["kinetic_energy_J"] < info["settings"]["kinetic_tolerance"]
    assert info["opening_time_s"] < info["settings"]["max_opening_time"]
    # penetration bound: the resting contact carries at most the packaging's prestress; with
    # c = 649 N/mm per node a 1 N node force is 1.5 um. 0.05 mm (half the STEP damping depth
    # s_max) is a generous bound that still catches a node through the box (mm)
    pen = _content_penetration(small)
    assert pen < 0.05e-3
    # and the packaging closed round the content: some node rests on it (within 0.5 mm)
    assert pen > -0.5e-3
    # the packaging wraps the content: its height is at least the content's
    p = small.positions
    assert p[:, 2].max() - p[:, 2].min() >= 10e-3


def test_assembly_checks_its_shape_against_table2(small):
    # the coarse (20 mm) assembly of the small example records its shape and passes it:
    # outer size within one element of its Table 2 row (or of the flat packaging the
    # construction needs, where larger), the film on the content's faces within half an
    # element (measured: micrometres), no content outside
    shape = small.info["shape"]
    assert shape["failures"] == []
    spec, h = small.build.spec, small.build.element_size * 1e3
    for outer, bound in zip(shape["outer_mm"], shape["bound_mm"], strict=True):
        assert outer <= bound
    assert shape["table2_mm"] == [spec.length_mm, spec.width_mm, spec.height_mm]
    # it wraps the content: at least the content's height, at most one element more than Table 2
    assert spec.content_height_mm <= shape["outer_mm"][2] <= spec.height_mm + h
    assert shape["gap_mm"]["uncovered"] == 0.0
    assert -h < shape["gap_mm"]["min"] <= shape["gap_mm"]["max"] < 0.5 * h
    assert shape["content_outside"] == 0 and shape["outside_depth_mm"] == 0.0


def test_shape_check_fails_a_balloon_an_oversize_and_a_content_outside(small):
    # the checks must be able to fail: the small example's settled state, altered
    from flexparcel.consignments.shape import check_shape

    b = ModelBuilder()
    c = add_consignment(b, small.build)
    model = b.finalize()
    pos, rot = small.positions.copy(), small.rotations.copy()
    assert check_shape(model, c, pos, rot).failures() == []
    h = small.build.element_size
    # balloon: the top layer lifted by one element off the content (the 15 mm KP/BW case)
    balloon = pos.copy()
    balloon[c.top, 2] += h
    failures = check_shape(model, c, balloon, rot).failures()
    assert any("film-content gap" in f for f in failures)
    assert any("outer height" in f for f in failures)
    # stretched 1.5-fold in length: longer than Table 2 + one element
    long = pos.copy()
    centre = pos[c.packaging, 0].mean()
    long[c.packaging, 0] = centre + 1.5 * (pos[c.packaging, 0] - centre)
    assert any("outer length" in f for f in check_shape(model, c, long, rot).failures())
    # the content moved out through the top, 5 mm above the film
    out = pos.copy()
    out[c.content_nodes, 2] = pos[c.packaging, 2].max() + 5e-3
    sc = check_shape(model, c, out, rot)
    assert sc.content_outside == len(c.content_nodes)
    assert sc.outside_depth_mm == pytest.approx(5.0 - c.contact_radius * 1e3, abs=0.5)
    assert any("outside the film" in f for f in sc.failures())


def test_surface_chord_bound_is_the_deepest_chord_over_a_rounded_edge():
    # closed form (shape.surface_chord_bound) against a brute-force search: chords of length
    # l with their ends on the two faces of a 90-degree edge rounded with radius r; the depth
    # of the rounded edge beyond the chord is its support in the chord's outer normal minus
    # the chord's offset
    from flexparcel.consignments.shape import surface_chord_bound

    h, r = 0.025, 3e-3
    ell = np.sqrt(2.0) * h
    a = np.linspace(r, ell - 1e-9, 20001)  # end on the top face at a from the edge
    b = np.sqrt(ell**2 - a**2)  # the other on the side face at b
    n = np.column_stack([b, a]) / ell  # outer normal of the chord from (-a, 0) to (0, -b)
    support = r + (-r) * n.sum(axis=1)  # quarter circle round (-r, -r), radius r
    depth = support - (-a * b / ell)
    ok = b >= r  # both ends on the flat faces
    assert surface_chord_bound(h, r) == pytest.approx(depth[ok].max(), rel=1e-6)
    assert surface_chord_bound(h, 0.0) == pytest.approx(h / np.sqrt(2.0))
    assert surface_chord_bound(1e-3, 0.05) == 0.0


def test_shape_check_fails_a_box_through_its_film(small):
    # the small example's rigid box: its whole surface is sampled; in the settled state every
    # point outside the film lies under a facet's chord, and the box pushed two thirds of
    # its length out through the end seam fails by its surface although its centre stays inside
    from flexparcel.consignments.shape import check_shape

    b = ModelBuilder()
    c = add_consignment(b, small.build)
    model = b.finalize()
    pos, rot = small.positions.copy(), small.rotations.copy()
    cs = check_shape(model, c, pos, rot).content_surface
    assert cs["points"] > 100 and cs["depth_mm"] <= cs["bound_mm"]
    shifted = pos.copy()
    # its centre 10 mm inside the seam, in the film's wedge; its end 20 mm out, beyond the
    # 20 mm film's chord bound (12.9 mm)
    far_end = pos[c.packaging, 0].max()
    shifted[c.content_body, 0] = far_end - c.content_box[0] / 6
    sc = check_shape(model, c, shifted, rot)
    assert sc.content_outside == 0
    assert sc.content_surface["outside"] > 0.2 * sc.content_surface["points"]
    assert sc.content_surface["depth_mm"] > sc.content_surface["bound_mm"]
    assert any("surface outside the film" in f for f in sc.failures())


def test_snapshot_round_trip_is_exact(small, tmp_path):
    path = save_snapshot(small, tmp_path / "s.npz")
    back = load_snapshot(path)
    assert back.build == small.build
    for name in ("reference_positions", "positions", "rotations"):
        assert np.array_equal(getattr(back, name), getattr(small, name)), name
    assert back.info == small.info
    # a model built from the snapshot's build starts exactly in the saved state
    b = ModelBuilder()
    add_consignment(b, back.build)
    s = place_snapshot(back, b.finalize())
    assert np.array_equal(s.positions, small.positions)
    assert np.array_equal(s.rotations, small.rotations)
    assert not np.any(s.velocities)


def test_snapshot_of_another_format_or_mesh_is_refused(small, tmp_path):
    path = save_snapshot(small, tmp_path / "s.npz")
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["meta"] = np.array(str(arrays["meta"]).replace('"format": 1', '"format": 99'))
    other = tmp_path / "other.npz"
    np.savez(other, **arrays)
    with pytest.raises(SnapshotError, match="snapshot format 99, this flexparcel reads format 1"):
        load_snapshot(other)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(SnapshotError, match="not a flexparcel snapshot"):
        load_snapshot(tmp_path / "junk.npz")
    b = ModelBuilder()
    add_consignment(b, ConsignmentBuild.of("BW", element_size=0.02))
    with pytest.raises(SnapshotError, match="does not fit this model"):
        place_snapshot(small, b.finalize())


def test_swing_start_is_deterministic(small):
    # the same snapshot and parameters give bit-identical runs (no hidden state, no randomness);
    # the full 1.4 s swing is far too long for the default suite. Clamped where the nodes
    # settled (jaws=None): the jaw closing is a run of the same integrator, and the jaws have
    # tests of their own
    a = swing_test(small, t_end=0.01, jaws=None)
    b = swing_test(small, t_end=0.01, jaws=None)
    assert np.array_equal(a.result.positions, b.result.positions)
    # released from horizontal under gravity: the free end starts to fall (measured 0.20 mm;
    # 0.15 mm at 0.02 s, it springs back on its bending stiffness) but, held by the clamped
    # bending stiffness, by less than a free fall, g t^2 / 2 = 0.49 mm
    z = a.result.positions[:, a.consignment.edge, 2].mean(axis=1)
    drop = z[0] - z[-1]
    assert 0.05e-3 < drop < 0.5 * 9.81 * 0.01**2


def test_packaging_friction_parameters_set_their_own_laws(small):
    # friction_packaging_content and friction_packaging_ground (not in the paper's Table 3;
    # default 0.3) must each reach their own law, node and edge contact alike, and change
    # nothing else: the vertical drop's rebound depends on them (docs/scenarios.md)
    from flexparcel.contact.law import P_MU_D, P_MU_S
    from flexparcel.scenarios.consignment_tests import drop_model, parse_assignments

    p0 = parse_assignments(None)
    assert p0["friction_packaging_content"] == p0["friction_packaging_ground"] == 0.3
    refused = r"friction_packaging_ground must be in \[0, 2\] -, got 2.5"
    with pytest.raises(ValueError, match=refused):
        parse_assignments(["friction_packaging_ground=2.5"])
    a = drop_model(small, "vertical", p0).model
    changed = {}
    for name, mu in (("content", 0.1), ("ground", 0.2)):
        b = drop_model(small, "vertical", parse_assignments([f"friction_packaging_{name}={mu}"]))
        la, lb = a.contact_laws, b.model.contact_laws
        assert la.shape == lb.shape
        rows = np.flatnonzero(la[:, P_MU_S] != lb[:, P_MU_S])
        assert rows.size >= 1, name
        for col in (P_MU_S, P_MU_D):
            assert np.all(la[rows, col] == 0.3) and np.all(lb[rows, col] == mu), name
        rest = np.ones(la.shape[1], bool)
        rest[[P_MU_S, P_MU_D]] = False
        np.testing.assert_array_equal(la[:, rest], lb[:, rest])
        changed[name] = set(rows.tolist())
    # two different laws: the film on the box (node-box) takes the content friction; the film
    # on the plate (plane points) and the glued edge's line contact on it (edge-plane) the
    # ground friction
    assert not changed["content"] & changed["ground"]
    by_kind = {}
    for cs in a.contact_sets:
        by_kind.setdefault(type(cs).__name__, set()).add(cs.law_index)
    assert by_kind["NodeBoxSet"] & changed["content"]
    assert not by_kind["NodeBoxSet"] & changed["ground"]
    for kind in ("PlanePointSet", "EdgePlaneSet"):
        assert by_kind[kind] & changed["ground"], kind


def test_vertical_drop_hold_leaves_the_consignment_at_rest_at_the_drop_height(small):
    # the optional hold (flexparcel.scenarios.holding): on end, gravity on, the top 20 mm held
    # for 0.2 s, then at rest and moved down to the drop height. Gravity may let the content
    # sink in its pouch (KP/BW at 25 mm: 0.01 mm, held by the film wrapped round it), and the
    # held nodes keep their shape
    from flexparcel.scenarios.consignment_tests import drop_model, end_nodes, parse_assignments
    from flexparcel.scenarios.holding import DropHold

    p = parse_assignments(None)
    free = drop_model(small, "vertical", p, drop_height=0.05)
    held = drop_model(small, "vertical", p, drop_height=0.05, hold=DropHold())
    c, s0, s1 = held.consignment, free.state0, held.state0
    rec = held.preparation["hold"]
    # at rest: 1e-8 J is 200 times below the assembly's rest bound (kinetic_tolerance, 2e-6 J;
    # measured 1.06e-9 J since the initial accelerations count the film's contact forces)
    assert rec["steps"] > 0 and rec["kinetic_end_j"] < 1e-8
    assert np.all(s1.velocities == 0.0) and s1.time == 0.0
    z = s1.positions[c.packaging, 2]
    assert z.min() == pytest.approx(s0.positions[c.packaging, 2].min(), abs=1e-12)
    top = end_nodes(small, c, DropHold().held_length)
    assert top.size > 0
    shift = s1.positions[top] - s0.positions[top]
    np.testing.assert_allclose(shift - shift[0], 0.0, atol=1e-12)
    # the content below the held end: it may sink (by less than a mm), not rise by more than
    # the integrator's noise (measured +0.5 um; its error tolerance is 0.1 mm)
    rel0 = s0.positions[c.content_nodes, 2].mean() - s0.positions[top, 2].mean()
    rel1 = s1.positions[c.content_nodes, 2].mean() - s1.positions[top, 2].mean()
    assert -1e-3 < rel1 - rel0 < 1e-5
    with pytest.raises(ValueError, match=r"DropHold.hold_time must be in \(0, 2\]"):
        DropHold(hold_time=0.0)
    with pytest.raises(ValueError, match="hold applies to the vertical drop only"):
        drop_model(small, "horizontal", p, hold=DropHold())


def test_an_interrupted_drop_resumes_from_its_checkpoint_bit_for_bit(small, tmp_path,
                                                                     monkeypatch):  # fmt: skip
    # a test with a checkpoint saves itself at its output frames (here every frame) and an
    # interrupted run resumes from the last save to the very frames of an uninterrupted run:
    # the state, the integrator's history and the contacts' (the film lies on its content)
    import flexparcel.scenarios.consignment_tests as ct
    from flexparcel.scenarios.registry import get_scenario

    monkeypatch.setattr(ct, "CHECKPOINT_INTERVAL_S", 0.0)
    path = tmp_path / "checkpoint.npz"
    scenario = get_scenario("drop-horizontal", checkpoint=path)

    class Stop(Exception):
        pass

    def stop(t, _t_end):
        if t >= 0.005:
            raise Stop

    with pytest.raises(Stop):
        scenario.run(small, {}, t_end=0.01, progress=stop)
    assert path.is_file()
    resumed = scenario.run(small, {}, t_end=0.01)
    full = get_scenario("drop-horizontal").run(small, {}, t_end=0.01)
    assert np.array_equal(resumed.simulation.time, full.simulation.time)
    assert np.array_equal(resumed.simulation.positions, full.simulation.positions)
    assert np.array_equal(resumed.simulation.velocities, full.simulation.velocities)
    assert resumed.record.responses == full.record.responses
    # a checkpoint of another run (another drop height: another start state) is refused
    other = get_scenario("drop-horizontal", drop_height=0.1, checkpoint=path)
    with pytest.raises(ValueError, match="written for another initial state"):
        other.run(small, {}, t_end=0.01)


def test_jaws_close_the_clamp_flat_and_leave_the_consignment_at_rest(small):
    # the paper's clamp presses both layers together over 2 cm; the settled envelope has them
    # apart there, so the swing closes the clamp as flat jaws before the release
    from flexparcel.consignments.snapshot import place_snapshot
    from flexparcel.scenarios.consignment_tests import parse_assignments, swing_model
    from flexparcel.scenarios.swing_jaws import jaw_targets

    p = parse_assignments(None)
    tm = swing_model(small, p)
    c = tm.consignment
    x = small.positions[c.packaging, 0]
    clamped = c.packaging[x <= x.min() + 0.020 + 1e-9]
    settled = place_snapshot(small, tm.model).positions
    target, z_mid = jaw_targets(c, clamped, settled)
    t = 2.0 * c.contact_radius
    # the open clamp spans several film thicknesses in height, the jaws one
    assert np.ptp(settled[clamped, 2]) > 5 * t
    np.testing.assert_allclose(tm.state0.positions[clamped], target, rtol=0, atol=1e-12)
    z = tm.state0.positions[clamped, 2]
    assert np.isclose(z.max() - z.min(), t) and np.isclose(z.max() + z.min(), 2 * z_mid)
    assert np.allclose(tm.state0.rotations[clamped], np.eye(3), atol=1e-12)
    # x and y stay: the jaws press, they do not pull
    np.testing.assert_array_equal(tm.state0.positions[clamped, :2], settled[clamped, :2])
    # at rest when the hold ends (measured 1.6e-8 J, against the 1.5e-4 J that a 1 mm drop
    # of the example's 15 g packaging end would give up), and released from rest
    assert tm.preparation["jaw_closing"]["kinetic_end_j"] < 1e-6
    assert not tm.state0.velocities.any()
    # jaws=None clamps the nodes where they settled
    open_clamp = swing_model(small, p, jaws=None)
    np.testing.assert_array_equal(open_clamp.state0.positions, settled)
    assert open_clamp.preparation == {}


def test_balanced_error_estimate_ignores_contact_jumps_the_film_balances(small):
    # In the swing the film hangs taut over its content: a contact force jump at a film node
    # is met by the film's own forces, so the node's acceleration does not jump. The "smooth"
    # estimate subtracts the contact jump anyway and rejects steps for an error that is not
    # there; "balanced" (the smaller of "full" and "smooth" per node) does not. Measured over
    # 0.02 s: 34 error rejections with "smooth", 1 with "balanced" (0.03 s: 49 and 2).
    from dataclasses import replace

    from flexparcel.scenarios.consignment_tests import consignment_options

    def run(**kw):
        opt = replace(consignment_options(), **kw)
        r = swing_test(small, t_end=0.02, dt_out=0.002, options=opt, jaws=None)
        return r.result.stats, r.result.positions[:, r.consignment.edge].mean(axis=1)

    smooth, smooth_path = run(error_estimate="smooth")
    balanced, path = run(error_estimate="balanced")
    _, ref = run(error_estimate="full", tol_displacement=1e-6)
    assert balanced["rejected_error"] * 5 <= smooth["rejected_error"]
    # both meet the reference (100x tighter) within the local error tolerance, 0.1 mm, which
    # bounds each step's error (measured: 36 and 49 um, on a 0.15 mm drop of the free end)
    for p in (smooth_path, path):
        assert np.abs(p - ref).max() < consignment_options().tol_displacement


def test_tests_too_short_for_their_responses_report_none_with_the_reason(small):
    """A run that ends before the response is reached says so: None and a note, never 0 (a
    0 mm rebound or swing would read as a measurement)."""
    drop = drop_test(small, "horizontal", drop_height=0.02, t_end=0.004, dt_out=0.002)
    assert drop.responses == {"rebound_mm": None, "com_rise_mm": None}
    assert "did not touch the plate" in drop.notes["rebound_mm"]
    assert "did not touch the plate" in drop.notes["com_rise_mm"]
    summary = drop.summary()
    assert summary["rebound_mm"] is None and summary["notes"] == drop.notes
    swing = swing_test(small, t_end=0.004, dt_out=0.002, jaws=None)
    assert swing.responses == {"first_swing_mm": None, "second_swing_mm": None}
    assert "did not swing past the clamp edge" in swing.notes["first_swing_mm"]


@pytest.fixture(scope="module")
def small_drop(small):
    return drop_test(small, "horizontal", drop_height=0.02, t_end=0.1)


@pytest.mark.slow  # 30-50 s each (make slow)
def test_horizontal_drop_rebounds_well_below_the_drop_height(small_drop):
    run = small_drop
    rebound = run.responses["rebound_mm"]
    # a limp, heavily contact-damped consignment: rebound far below the 20 mm drop. The
    # contact law is per area: the example's 20 mm nodes carry 4 times the paper's per-point
    # 611 N/mm (a 10 mm node's), so they indent about half as deep, where the STEP damping
    # (full only at s_max = 0.1 mm, growing as (s / s_max)^2) damps less: measured 6.6 mm
    # (6.4 and 6.3 mm with tol_displacement 1e-5 and rho_inf 0.8 as well, so not the
    # integrator's); per point it stayed below 5 mm. 40 % of the drop at most.
    assert 0.0 <= rebound < 8.0
    # it hit the plate and stays above it: no node sinks deeper than the contact's static
    # indentation bound (0.1 mm = s_max, the STEP damping depth) below its contact radius
    low = run.result.positions[:, run.consignment.packaging, 2].min(axis=1)
    assert low.min() > run.consignment.contact_radius - 0.1e-3
    assert low.min() < run.consignment.contact_radius  # and it did reach the plate


@pytest.mark.slow  # 30-50 s each (make slow)
def test_drop_plate_meets_the_content_box_once_through_its_packaging(small_drop):
    """The drop test's plate holds the rigid content back by its box's 8 corners with the
    packaging's plate law (``add_ground_contact``): without, KP/BW's box went 1.88 mm below
    the plate in a horizontal drop at 25 mm (its rounded edges pass between the film's nodes)."""
    from flexparcel.elements.rotations import rotation_exp

    run = small_drop
    m, c = run.model, run.consignment
    cp = plane_points(m)
    box = cp.node == c.content_body
    film = np.isin(cp.node, c.packaging)
    i = int(np.flatnonzero(m.rigid_nodes == c.content_body)[0])
    assert box.sum() == 8 and np.allclose(np.abs(cp.offset[box]), m.rigid_half_inner[i])
    assert np.allclose(cp.radius[box], m.rigid_radius[i])
    assert set(cp.law[box]) == set(cp.law[film]) and len(set(cp.law[film])) == 1
    # the box's lowest point (its inner box's lowest corner less the edge radius) stays above
    # the plate, to the contact's 0.1 mm indentation bound (s_max); measured 0.36 mm above, on
    # its packaging (two 0.5 mm layers pressed into each other between 20 mm-spaced nodes)
    rv = run.result.rotation_vectors[:, c.content_body]
    z = run.result.positions[:, c.content_body, 2]
    low = [
        zk - np.abs(rotation_exp(r)[2]) @ m.rigid_half_inner[i] for zk, r in zip(z, rv, strict=True)
    ]
    assert min(low) - m.rigid_radius[i] > -0.1e-3


def test_rebound_counts_from_the_first_touch_of_the_given_radius():
    from types import SimpleNamespace

    from flexparcel.scenarios.consignment_tests import com_rise

    # one node falling to z = 2 mm (an edge contact of radius 2 mm touches there), pushed back
    # up to 5 mm, then down again: the rebound is 3 mm above the touch; with the packaging's
    # 0.25 mm contact radius as the threshold it never "touches" and reads 0
    z = np.array([10.0, 6.0, 2.0, 1.5, 2.0, 5.0, 4.0]) * 1e-3
    pos = np.zeros((z.size, 1, 3))
    pos[:, 0, 2] = z
    model = SimpleNamespace(mass=np.ones((1, 6)))
    res = SimpleNamespace(positions=pos)
    c = SimpleNamespace(node_ids=np.array([0]), packaging=np.array([0]), contact_radius=0.25e-3)
    assert com_rise(model, res, c) == 0.0
    assert com_rise(model, res, c, touch_radius=2e-3) == pytest.approx(3e-3)


# --------------------------------------------------------------------------------------------
# Growing a content that nearly fills its packaging


@pytest.mark.parametrize(("name", "scale"), [("KPBW", 1.0), ("PB", 0.6), ("KP", 0.6), ("BW", 0.6)])
def test_tight_envelopes_get_a_grown_content(name, scale):
    # PB, KP, BW: flat envelope side - content side < 3 x content height (a few mm of slack
    # round the content's section), which no opened, lens-shaped envelope clears
    assert content_scale_for(ConsignmentBuild.of(name, element_size=0.025)) == scale
    # at the paper's meshes every envelope opens round a shrunk content: a fine film wrinkles
    # flat over the footprint instead of bulging (KP/BW at 10 mm did not clear its content)
    assert content_scale_for(ConsignmentBuild.of(name)) == 0.6


def test_opening_force_doubles_from_its_start_pressure_up_to_the_cap():
    from flexparcel.consignments.assembly import _opening_schedule

    st = AssemblySettings()  # 1 Pa doubling every 10 ms, cap 5 kPa
    f = _opening_schedule(st)
    p = [st.opening_pressure * f(t) for t in (0.0, 0.01, 0.05, 0.1, 0.2)]
    assert p == pytest.approx([1.0, 2.0, 32.0, 1024.0, 5000.0])
    # never above the cap, never decreasing
    ts = np.linspace(0.0, 0.3, 301)
    v = np.array([f(t) for t in ts])
    assert v.max() == pytest.approx(1.0) and np.all(np.diff(v) >= 0.0)


def test_kp_glue_stripe_takes_the_nearest_node_rows_on_an_odd_mesh():
    # KP at 25 mm: the bottom panel's middle strip (250 mm less the two 16 mm gussets) in
    # 9 elements puts no node row within the 20 mm stripe; the two rows nearest the centre
    # line (y = +-218 / 18 mm) carry the glue instead
    build = ConsignmentBuild.of("KP", element_size=0.025)
    b = ModelBuilder()
    c = add_consignment(b, build)
    model = b.finalize()
    glued = np.flatnonzero(np.isin(np.arange(model.node_count), model.slave_nodes))
    y = np.unique(np.round(model.positions0[glued, 1], 6))
    assert y == pytest.approx([-0.218 / 18, 0.218 / 18], abs=1e-6)
    assert c.content_body is not None


def test_content_scale_out_of_range_is_refused():
    with pytest.raises(ValueError, match=r"content_scale must be in \[0.3, 1\]"):
        AssemblySettings(content_scale=0.2)
    with pytest.raises(ValueError, match=r"friction must be one of none, regularised, stick"):
        AssemblySettings(friction="coulomb")
    with pytest.raises(ValueError, match=r"hold_film_centre must be true or false, got 'no'"):
        AssemblySettings(hold_film_centre="no")
    with pytest.raises(ValueError, match=r"settle_rho_inf must be in \[0, 1\], got 1.5"):
        AssemblySettings(settle_rho_inf=1.5)
    with pytest.raises(ValueError, match=r"settle_rho_inf must be in \[0, 1\], got True"):
        AssemblySettings(settle_rho_inf=True)
    assert AssemblySettings(settle_rho_inf=0.0).settle_rho_inf == 0.0  # 0 is allowed


class _Interrupt(Exception):
    """Stands for a kill: raised from the progress callback."""


def _interrupt_at(phase: str, count: int):
    """A progress callback that raises :class:`_Interrupt` at its ``count``-th call in
    ``phase``."""
    calls = []

    def progress(p: str, _t: float) -> None:
        calls.append(p)
        if calls.count(phase) == count:
            raise _Interrupt(phase)

    return progress


@pytest.mark.slow  # 60-90 s (make slow): about two assemblies of the small example
def test_an_interrupted_assembly_resumes_from_its_checkpoint_as_if_uninterrupted(small, tmp_path):
    from flexparcel.consignments.assembly_checkpoint import AssemblyCheckpoint

    # interrupted in the opening, in the closing (before its own checkpoint's first write,
    # so it starts over from the opened state) and in the settling, then run to the end:
    # the same snapshot as the one uninterrupted assembly (the CLI's, conftest), bit for bit
    build = load_consignment_file(EXAMPLE)
    ck = tmp_path / "assembly.npz"
    stops = (("opening", 2, "opening"), ("closing", 5, "opening"), ("settling", 1, "settling"))
    for phase, count, saved in stops:
        with pytest.raises(_Interrupt):
            assemble(build, checkpoint=ck, progress=_interrupt_at(phase, count))
        assert AssemblyCheckpoint(ck, {}).path.exists()
        assert str(np.load(ck)["position"]).count(f'"phase": "{saved}"') == 1
    snap = assemble(build, checkpoint=ck)
    assert not ck.exists()  # ended: nothing left to resume
    np.testing.assert_array_equal(snap.positions, small.positions)
    np.testing.assert_array_equal(snap.rotations, small.rotations)
    assert snap.info["steps"] == small.info["steps"]
    assert snap.info["end_time_s"] == small.info["end_time_s"]


def test_an_assembly_checkpoint_of_another_assembly_is_refused(tmp_path):
    from flexparcel.consignments.assembly_checkpoint import AssemblyCheckpoint, AssemblyPosition
    from flexparcel.io.checkpoint import CheckpointError
    from flexparcel.model.model import State

    n = 3
    s = State(0.25, np.ones((n, 3)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 6)),
              np.zeros((n, 6)))  # fmt: skip
    path = tmp_path / "a.npz"
    header = {"consignment": "KP", "element_size": 0.01, "settings": {"margin": 0.002}}
    AssemblyCheckpoint(path, header).save(AssemblyPosition("settling", s, {"alg": s.positions},
                                                           42, 0.1, 3.5))  # fmt: skip
    back = AssemblyCheckpoint(path, header).load()
    assert (back.phase, back.steps, back.t_open, back.wall_s) == ("settling", 42, 0.1, 3.5)
    assert back.state.time == 0.25
    np.testing.assert_array_equal(back.history["alg"], s.positions)
    other = {**header, "element_size": 0.025}
    with pytest.raises(
        CheckpointError, match=r"element_size = 0.01, this run has element_size = 0.025"
    ):
        AssemblyCheckpoint(path, other).load()
    path.write_bytes(b"not an npz")
    with pytest.raises(CheckpointError, match=r"assembly checkpoint .*a.npz: not a readable .npz"):
        AssemblyCheckpoint(path, header).load()
    assert AssemblyCheckpoint(tmp_path / "none.npz", header).load() is None


@pytest.mark.slow  # 30-50 s each (make slow)
def test_assembly_grows_a_shrunk_content_back_without_penetration():
    # the small example opened round a content of 0.6 x its size, which then grows back to
    # full size inside the closed packaging: the same bounds as the plain assembly above
    build = load_consignment_file(EXAMPLE)
    snap = assemble(build, AssemblySettings(content_scale=0.6))
    assert snap.info["content_scale"] == 0.6
    assert snap.info["kinetic_energy_J"] < snap.info["settings"]["kinetic_tolerance"]
    pen = _content_penetration(snap)
    assert -0.5e-3 < pen < 0.05e-3


def test_rebound_is_the_first_bounce_even_if_it_sinks_lower_afterwards():
    from types import SimpleNamespace

    from flexparcel.scenarios.consignment_tests import com_rise

    # touches at z = 3 mm (frame 1), bottoms out at 2 mm, bounces to 4 mm, then tips over and
    # sinks to 1 mm: the rebound is the bounce, 4 - 3 = 1 mm (the old global-minimum rule,
    # counting from the 1 mm at the end, gave 0)
    z = np.array([5.0, 3.0, 2.0, 4.0, 2.5, 1.0]) * 1e-3
    pos = np.zeros((z.size, 1, 3))
    pos[:, 0, 2] = z
    model = SimpleNamespace(mass=np.ones((1, 6)))
    res = SimpleNamespace(positions=pos)
    c = SimpleNamespace(node_ids=np.array([0]), packaging=np.array([0]), contact_radius=3e-3)
    assert com_rise(model, res, c) == pytest.approx(1e-3)
    # still sinking at the end: no bounce
    pos[:, 0, 2] = np.array([5.0, 3.0, 2.0, 1.5, 1.2, 1.0]) * 1e-3
    assert com_rise(model, res, c) == 0.0


def test_closing_holds_the_layers_centre_nodes_in_plane_only():
    # the closing model holds the top and the bottom layer's centre node in x and y, and one
    # more node of each on its centre line in y (a frictionless film must neither slide nor
    # turn on its growing content), nothing else
    from flexparcel.consignments import assembly as asm_mod

    build = ConsignmentBuild.of("PB", element_size=0.025)
    st = AssemblySettings()
    free, c = asm_mod._model(build, st, True, None, "none")
    centre, along = asm_mod._held_nodes(free, c)
    assert centre[0] in c.top and centre[1] in c.bottom
    assert along[0] in c.top and along[1] in c.bottom
    length = build.flat_size[0]
    for a, b in zip(centre, along, strict=True):  # within one element of where they belong
        assert np.linalg.norm(free.positions0[a, :2]) < 0.025
        assert abs(free.positions0[b, 0] - free.positions0[a, 0] - 0.4 * length) < 0.025
        assert abs(free.positions0[b, 1]) < 0.025
    model, _ = asm_mod._model(build, st, True, None, "none", (centre, along))
    added = model.fixed & ~free.fixed  # (solid nodes' rotations are held in both)
    assert added.sum() == 6 and not (free.fixed & ~model.fixed).any()
    assert added[centre][:, :2].all() and not added[centre][:, 2:].any()
    assert added[along][:, 1].all() and not added[along][:, [0, 2, 3, 4, 5]].any()
