"""The bulk conveyor scene (issue 8): layouts, scene files, several consignments placed from
snapshots, a short four-consignment run through the CLI, and the benchmark scaling helper.

One assembly of the small example consignment (20 mm shells) is shared by the module; the
four-consignment run is 10 ms of simulated time (about 30 s wall on the 2-core machine): four
copies arrive at belt speed a few mm upstream of the two deflectors, so each touches one within
the first 2 ms and is pushed along it.
"""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import flexparcel as fp
from contact_views import plane_points
from flexparcel.cli import main
from flexparcel.consignments.build import ConsignmentBuild
from flexparcel.consignments.snapshot import SnapshotError, load_snapshot, place_snapshot
from flexparcel.consignments.userfile import load_consignment_file
from flexparcel.io.checkpoint import load_checkpoint
from flexparcel.model.rigid import RoundedBox
from flexparcel.scenarios.conveyor import BeltTransfer, ConveyorScene, add_conveyor
from flexparcel.scenarios.conveyor_scene import (
    Placement,
    SceneFileError,
    SceneLayout,
    build_conveyor_model,
    check_layout,
    default_layout,
    footprint,
    load_scene_file,
    paper_conveyor,
    throughput_layout,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "consignment_small.toml"
SCENE = ROOT / "examples" / "conveyor_scene.toml"
PAPER_SNAPSHOTS = ROOT / "data" / "paper-snapshots-25mm"
PRESETS = {k: ConsignmentBuild.of(k) for k in ("KPBW", "PB", "KP", "BW")}


# ------------------------------------------------------------------------------ layouts


def test_default_layout_queues_the_four_upstream_of_the_first_deflector():
    conveyor = paper_conveyor()
    layout = default_layout(PRESETS, conveyor)
    assert [p.name for p in layout.placements] == ["KPBW", "PB", "KP", "BW"]
    check_layout(layout, PRESETS)  # on the belt, clear of deflectors and of each other
    ends = []
    for p in layout.placements:
        x0, x1, _, _ = footprint(PRESETS[p.consignment])
        ends.append((p.x + x0, p.x + x1))
        assert p.y == 0.0 and p.yaw_deg == 0.0 and p.speed == 0.0
    # leading one 50 mm before the first deflector root, 50 mm gaps, queue within the belt
    assert ends[0][1] == pytest.approx(conveyor.deflector_x[0] - 0.05)
    for (a0, _), (_, b1) in zip(ends[:-1], ends[1:], strict=True):
        assert a0 - b1 == pytest.approx(0.05)
    assert ends[-1][0] > 0.0
    # the paper's deflectors: 45 deg, second one from the other side, tips on the belt
    g = conveyor.deflectors()
    assert conveyor.deflector_angle_deg == 45.0 and conveyor.belt_speed == 1.6
    assert g[0].root[1] > 0 > g[1].root[1] and g[1].tip[0] < conveyor.belt_length


def test_default_layout_that_does_not_fit_names_the_room_needed():
    short = ConveyorScene(deflector_x=(0.5, 1.5))
    with pytest.raises(ValueError, match=r"needs 1\.\d+ m upstream of the first deflector"):
        default_layout(PRESETS, short)


@pytest.mark.parametrize(
    ("placements", "message"),
    [
        ([Placement("a", "KPBW", 1.0), Placement("b", "PB", 1.1)], "'a' and 'b' overlap"),
        ([Placement("a", "XX", 1.0)], r"unknown consignment 'XX'; allowed: KPBW, PB, KP, BW"),
        ([Placement("a", "KPBW", 0.05)], r"must lie on the belt, x in \[0, "),
        ([Placement("a", "KPBW", 1.0, y=0.25)], r"must lie on the belt, y in \[-0.3, 0.3\]"),
        ([Placement("a", "KPBW", 1.62, y=0.15)], "overlaps deflector 0"),
    ],
)
def test_bad_layouts_name_the_placement(placements, message):
    layout = SceneLayout(paper_conveyor(), tuple(placements))
    with pytest.raises(ValueError, match=message):
        check_layout(layout, PRESETS)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Placement("a", "KP", 1.0, yaw_deg=400), r"yaw_deg must be in \[-360, 360\]"),
        (lambda: Placement("a", "KP", 1.0, speed=-1), r"speed must be in \[0, 10\] m/s"),
        (lambda: Placement("", "KP", 1.0), "Placement.name must be a non-empty string"),
        (lambda: Placement("a", "KP", float("nan")), "x must be finite"),
        (
            lambda: SceneLayout(
                paper_conveyor(), (Placement("a", "KP", 1), Placement("a", "BW", 2))
            ),
            r"duplicate name\(s\) \['a'\]",
        ),  # fmt: skip
        (lambda: SceneLayout(paper_conveyor(), ()), "at least one placement"),
        (lambda: paper_conveyor(belt_speed=12), r"belt_speed must be in \[0, 10\] m/s"),
        (lambda: paper_conveyor(deflector_angle_deg=5), r"deflector_angle_deg must be in \[10"),
    ],
)
def test_bad_placements_and_conveyors_name_the_field_and_range(make, message):
    with pytest.raises(ValueError, match=message):
        make()


def test_throughput_layout_makes_the_belt_long_enough():
    small = load_consignment_file(EXAMPLE)
    layout = throughput_layout(small, 20)
    check_layout(layout, {"c": small})
    assert len(layout.placements) == 20
    assert layout.conveyor.deflector_x[0] > max(p.x for p in layout.placements)
    with pytest.raises(ValueError, match=r"count must be an integer in \[1, 200\]"):
        throughput_layout(small, 0)


# ------------------------------------------------------------------------------ scene files


def _scene(tmp_path, text: str) -> Path:
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


HEAD = "format_version = 1\n"


def test_example_scene_file():
    s = load_scene_file(SCENE)
    assert [p.name for p in s.placements] == ["a", "b", "c", "d"]
    assert s.consignments == {"consignment_small": str(EXAMPLE.resolve())}
    assert s.conveyor.deflector_x == (0.3, 0.45) and s.conveyor.belt_speed == 1.6
    assert s.t_end == pytest.approx(0.012) and s.placements[0].speed == 1.6
    builds = {"consignment_small": load_consignment_file(EXAMPLE)}
    check_layout(SceneLayout(s.conveyor, s.placements, s.gap_above_belt), builds)


def test_jam_example_scene_puts_the_pouch_at_rest_just_before_the_steep_deflector():
    # examples/conveyor_jam_scene.toml (run by tests/test_slow_verification.py): the pouch's
    # footprint clear of the 75 deg deflector by a few mm, at rest on the 2 m/s belt
    s = load_scene_file(ROOT / "examples" / "conveyor_jam_scene.toml")
    assert s.conveyor.deflector_angle_deg == 75 and s.conveyor.belt_speed == 2.0
    (p,) = s.placements
    assert p.speed == 0.0 and s.t_end == pytest.approx(0.7)
    builds = {"consignment_small": load_consignment_file(EXAMPLE)}
    check_layout(SceneLayout(s.conveyor, s.placements, s.gap_above_belt), builds)
    # the flat footprint's front corner on the root side is the nearest point to the face
    length, width = builds["consignment_small"].flat_size
    corner = np.array([p.x + 0.5 * length, p.y + 0.5 * width, 0.0])
    g = s.conveyor.deflectors()[0]
    assert 0.0 < (corner - g.point) @ g.normal < 0.01


def test_scene_file_default_queue_takes_the_paper_conveyor(tmp_path):
    s = load_scene_file(_scene(tmp_path, HEAD + 'consignments = ["KPBW", "BW"]\n'
                               "[belt]\nspeed_m_s = 2.0\n"))  # fmt: skip
    assert s.placements == () and list(s.consignments) == ["KPBW", "BW"]
    assert s.conveyor == paper_conveyor(2.0, 45.0)


def test_scene_file_transfer_adds_a_second_belt(tmp_path):
    text = "[transfer]\ngap_m = 0.03\nlength_m = 1.5\nspeed_m_s = 1.2\n"
    s = load_scene_file(_scene(tmp_path, HEAD + 'consignments = ["KPBW"]\n' + text))
    c = s.conveyor
    assert c.transfer == BeltTransfer(gap=0.03, length=1.5, speed=1.2)
    assert c.belt_spans()[1] == pytest.approx((c.belt_length + 0.03, c.belt_length + 1.53, 1.2))
    assert c.exit_x == pytest.approx(c.belt_length + 1.53)
    b = fp.ModelBuilder()
    parts = add_conveyor(b, c)
    b.add_rigid_body(RoundedBox(0.1, 0.1, 0.1, mass=1.0), (0.3, 0.0, 0.5))
    m = b.finalize()
    (second,) = parts.transfer_planes
    assert parts.belt_planes == (parts.belt_plane, second)
    # both belts are slabs of their spans with the scene's edge radius
    np.testing.assert_allclose(m.plane_extent[second], [0.75, c.belt_width / 2, 0.01])
    np.testing.assert_allclose(m.plane_point[second], [c.belt_length + 0.03 + 0.75, 0.0, 0.0])
    np.testing.assert_allclose(m.plane_velocity[second], [1.2, 0.0, 0.0])


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("format_version = 1\nconsignments = [", "not valid TOML"),
        ('consignments = ["KP"]\n', "format_version must be 1"),
        (HEAD + 'consignments = ["KP"]\ncolour = 3\n', r"unknown key\(s\) \['colour'\]"),
        (HEAD, "give either consignments"),
        (
            HEAD + 'consignments = ["KP"]\n[belt]\nspeed_m_s = 20\n',
            r"speed_m_s must be in \[0, 10\] m/s, got 20",
        ),  # fmt: skip
        (
            HEAD + 'consignments = ["KP"]\n[deflectors]\nangle_deg = 95\n',
            r"angle_deg must be in \[10, 90\] deg",
        ),  # fmt: skip
        (
            HEAD + 'consignments = ["KP"]\n[deflectors]\noverhang_m = -0.1\n',
            r"overhang_m must be in \[0, 1\] m, got -0.1",
        ),  # fmt: skip
        (HEAD + 'consignments = ["KP"]\n[belt]\nlength = 3\n', r"\[belt\]: unknown key"),
        (HEAD + 'consignments = ["KP"]\n[deflectors]\nx_m = 1.0\n', "x_m must be a non-empty"),
        (HEAD + '[[consignment]]\nconsignment = "KP"\n', "consignment\\[0\\]: missing key 'x_m'"),
        (
            HEAD + '[[consignment]]\nconsignment = "KP"\nx_m = "1"\n',
            r"consignment\[0\].x_m must be a number",
        ),  # fmt: skip
        (
            HEAD + '[[consignment]]\nconsignment = "KP"\nx_m = 1\nyaw_deg = 720\n',
            r"yaw_deg must be in \[-360, 360\] deg",
        ),  # fmt: skip
        (
            HEAD + '[[consignment]]\nconsignment = "KP"\nx_m = 1\n'
            '[[consignment]]\nconsignment = "KP"\nx_m = 2\n',
            r"consignment\[1\].name 'KP' is used by consignment\[0\]",
        ),  # fmt: skip
        (HEAD + 't_end_s = 0\nconsignments = ["KP"]\n', r"t_end_s must be in \[0.001, 10\] s"),
        (
            HEAD + 'consignments = ["KP"]\n[transfer]\ngap_m = 0.9\n',
            r"\[transfer\]: gap_m must be in \[0, 0.5\] m, got 0.9",
        ),  # fmt: skip
        (HEAD + 'consignments = ["KP"]\n[transfer]\nwidth_m = 1\n', r"\[transfer\]: unknown key"),
        (
            HEAD + 'consignments = ["KP"]\n[belt]\nedge_radius_m = 0\n[transfer]\n',
            r"edge_radius_m must be > 0 m with a transfer",
        ),  # fmt: skip
        (
            HEAD + 'consignments = ["KP"]\n[belt]\nedge_radius_m = 0.2\n',
            r"edge_radius_m must be in \[0, 0.05\] m, got 0.2",
        ),  # fmt: skip
    ],
)
def test_bad_scene_files_name_the_file_and_key(tmp_path, text, message):
    path = _scene(tmp_path, text)
    with pytest.raises(SceneFileError, match=message) as info:
        load_scene_file(path)
    assert str(path) in str(info.value)


def test_missing_scene_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothere.toml"):
        load_scene_file(tmp_path / "nothere.toml")


# ------------------------------------------------------------------------------ model + run


def test_place_snapshot_at_a_node_offset(snapshot_dir):
    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    key = "consignment_small"
    layout = SceneLayout(
        ConveyorScene(belt_length=1.2, deflector_x=(0.6, 0.75)),
        (Placement("a", key, 0.2, 0.1, 90.0), Placement("b", key, 0.4, -0.1, speed=1.0)),
    )
    cm = build_conveyor_model({key: snap}, layout)
    a, b = cm.consignments["a"], cm.consignments["b"]
    n = len(snap.positions)
    assert a.node_ids.max() < b.node_ids.min() and len(b.node_ids) == n
    s = cm.state0
    pb = s.positions[b.node_ids]
    # b: the settled shape, moved rigidly (yaw 0); lowest packaging contact surface 1 mm up
    shift = pb - snap.positions
    assert np.allclose(shift, shift[0], atol=1e-12)
    assert shift[0, :2] == pytest.approx([0.4, -0.1])
    assert pb[:, 2].min() == pytest.approx(b.contact_radius + 1e-3)
    assert np.all(s.velocities[b.node_ids, 0] == 1.0) and np.all(s.velocities[a.node_ids] == 0)
    # a: turned 90 deg about z (x -> y), the rotations turned with it
    pa = s.positions[a.node_ids]
    assert np.ptp(pa[:, 1]) == pytest.approx(np.ptp(snap.positions[:, 0]))
    assert np.allclose(s.rotations[a.node_ids[0]], layout.placements[0].rotation()
                       @ snap.rotations[0])  # fmt: skip
    # contacts: belt + 2 deflectors per consignment, and the pair both ways
    assert cm.consignment_pairs == [("a", "b")]
    # the old callers' default (first node 0) still checks the fit
    with pytest.raises(SnapshotError, match=f"its {n} nodes from node {b.node_ids.min() + 1}"):
        place_snapshot(snap, cm.model, first_node=int(b.node_ids.min()) + 1)
    moved = place_snapshot(snap, cm.model, first_node=int(b.node_ids.min()), state=s)
    assert np.allclose(moved.positions[a.node_ids], pa)  # others copied from `state`


def test_content_law_replaces_the_packaging_content_contact(snapshot_dir):
    from flexparcel.consignments.build import default_packaging_content_law
    from flexparcel.contact.law import P_C, P_K_T

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    layout = throughput_layout(snap.build, 2)
    stiff = build_conveyor_model({"c": snap}, layout).model.contact_laws
    # per-area laws: Table 6's 649 N/mm at the paper's 10 mm nodes is 6.49e9 N/m^3; a tenth
    soft_c = 6.49e8
    soft_law = replace(default_packaging_content_law(), stiffness=soft_c, stick_stiffness=soft_c)
    soft = build_conveyor_model({"c": snap}, layout, content_law=soft_law).model.contact_laws
    assert np.isclose(stiff[:, P_C], 6.49e9).any() and not np.isclose(stiff[:, P_C], soft_c).any()
    # the packaging-content law is swapped; the belt, deflector and consignment-consignment
    # laws stay
    assert soft_c in soft[:, P_C] and soft_c in soft[:, P_K_T]
    assert len(soft) == len(stiff) + 1 and np.isclose(soft[:, P_C], 6.49e9).any()


def test_contents_meet_the_belt_once_through_their_packaging():
    """PB's content nodes are belt contact points of radius half the film thickness with the
    film's belt law: a backstop for the face-inner content nodes, which bulge through the film
    between its nodes (a 2 s run of the paper scene without it: 0.84 mm below the belt). A
    rigid content (KP/BW's box) meets the belt by its 8 rounded corners with its packaging's
    belt law (2.1 mm below the belt without)."""
    snaps = {k: load_snapshot(PAPER_SNAPSHOTS / f"{k}.npz") for k in ("KPBW", "PB")}
    cm = build_conveyor_model(snaps, default_layout({k: s.build for k, s in snaps.items()}))
    m = cm.model
    cp = plane_points(m)
    on_belt = cp.plane == cm.parts.belt_plane
    pb, kpbw = cm.consignments["PB"], cm.consignments["KPBW"]
    content = on_belt & np.isin(cp.node, pb.content_nodes)
    film = on_belt & np.isin(cp.node, pb.packaging)
    assert sorted(cp.node[content]) == sorted(pb.content_nodes)
    assert np.allclose(cp.radius[content], pb.contact_radius)
    assert pb.contact_radius == pytest.approx(0.03e-3)  # PB's 0.06 mm film
    assert set(cp.law[content]) == set(cp.law[film]) and len(set(cp.law[film])) == 1
    box = on_belt & (cp.node == kpbw.content_body)
    box_film = on_belt & np.isin(cp.node, kpbw.packaging)
    i = int(np.flatnonzero(m.rigid_nodes == kpbw.content_body)[0])
    assert box.sum() == 8 and np.allclose(cp.radius[box], m.rigid_radius[i])
    corners = np.abs(cp.offset[box])  # the inner box's corners in the box's frame
    assert np.allclose(corners, m.rigid_half_inner[i])
    assert set(cp.law[box]) == set(cp.law[box_film]) and len(set(cp.law[box_film])) == 1
    # placed on the belt, each content rests on its packaging, clear of its backstop
    z = cm.state0.positions[pb.content_nodes, 2]
    assert z.min() > pb.contact_radius
    rot = cm.state0.rotations[kpbw.content_body]
    low = cm.state0.positions[kpbw.content_body, 2] - np.abs(rot[2]) @ m.rigid_half_inner[i]
    assert low - m.rigid_radius[i] > 2 * kpbw.contact_radius


def test_pair_reach_keeps_only_neighbours(snapshot_dir):
    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    layout = throughput_layout(snap.build, 4)
    cm = build_conveyor_model({"c": snap}, layout, pair_reach=0.06)
    assert cm.consignment_pairs == [("c0", "c1"), ("c1", "c2"), ("c2", "c3")]
    assert len(build_conveyor_model({"c": snap}, layout).consignment_pairs) == 6


def test_deflector_crossings_flag_packaging_behind_a_deflector(snapshot_dir):
    from types import SimpleNamespace

    from flexparcel.scenarios.conveyor_scene import deflector_crossings

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    cm = build_conveyor_model({"c": snap}, throughput_layout(snap.build, 2))
    g = cm.parts.deflectors[0]
    half = 0.5 * cm.parts.scene.deflector_thickness
    mid = g.root + 0.5 * g.length * g.tangent + np.array([0.0, 0.0, 0.5 * g.height])
    node = int(cm.consignments["c1"].packaging[0])
    frames = np.repeat(cm.state0.positions[None], 4, axis=0)
    frames[1, node] = mid + 0.005 * g.normal  # in front of the face: fine
    frames[2, node] = mid - (half + 0.001) * g.normal  # 1 mm behind the mid-plane
    frames[3, node] = mid - (half + 0.02) * g.normal  # deeper than depth: elsewhere
    res = SimpleNamespace(time=np.array([0.0, 0.01, 0.02, 0.03]), positions=frames)
    assert deflector_crossings(cm, res) == {"c0": None, "c1": 0.02}
    res = SimpleNamespace(time=res.time[:3], positions=frames[[0, 1, 3]])
    assert deflector_crossings(cm, res)["c1"] is None
    assert deflector_crossings(cm, res, depth=0.05)["c1"] == 0.02
    with pytest.raises(ValueError, match="depth must be > 0 m"):
        deflector_crossings(cm, res, depth=0.0)


def test_deflector_edge_depths_measure_packaging_edges_at_the_tips_and_ends(snapshot_dir):
    from types import SimpleNamespace

    from flexparcel.scenarios.conveyor_scene import deflector_edge_depths

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    cm = build_conveyor_model({"c": snap}, throughput_layout(snap.build, 2))
    x0 = cm.state0.positions
    pack = cm.consignments["c1"].packaging
    centre = x0[pack].mean(axis=0)
    node = int(pack[0])
    h = cm.parts.deflector_contact_thickness(cm.consignments["c1"].contact_radius)

    def near(line, gap):
        """A point ``gap`` [m] from the vertical edge ``line`` (node ids) at mid height,
        horizontally towards c1's packaging: every edge from there to c1's other nodes then
        stays at least ``gap`` from the line, so the closest approach is exactly ``gap``."""
        lo, hi = x0[line[0]], x0[line[-1]]
        w = centre - lo
        w[2] = 0.0
        w /= np.linalg.norm(w)
        assert np.all((x0[pack] - lo) @ w > 2 * h)  # the packaging lies on that side
        return 0.5 * (lo + hi) + gap * w

    frames = np.repeat(x0[None], 4, axis=0)
    frames[1, node] = near(cm.parts.deflector_tips[0], 0.6 * h)  # depth 0.4 h at tip 1
    frames[2, node] = near(cm.parts.deflector_ends[1], 0.1 * h)  # depth 0.9 h at end 2
    frames[3, node] = near(cm.parts.deflector_tips[1], 2.0 * h)  # not within h
    res = SimpleNamespace(time=np.array([0.0, 0.01, 0.02, 0.03]), positions=frames)
    d = deflector_edge_depths(cm, res)
    assert d["c0"] == {"depth_m": None, "thickness_m": h, "time_s": None, "edge": None}
    assert d["c1"]["depth_m"] == pytest.approx(0.9 * h, rel=1e-9)
    assert (d["c1"]["time_s"], d["c1"]["edge"]) == (0.02, "end 2")
    res = SimpleNamespace(time=res.time[[0, 1, 3]], positions=frames[[0, 1, 3]])
    d = deflector_edge_depths(cm, res)["c1"]
    assert d["depth_m"] == pytest.approx(0.4 * h, rel=1e-9)
    assert (d["time_s"], d["edge"]) == (0.01, "tip 1")


def test_content_below_belt_counts_only_over_the_belt(snapshot_dir):
    from types import SimpleNamespace

    from flexparcel.scenarios.conveyor_scene import content_below_belt

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    cm = build_conveyor_model({"c": snap}, throughput_layout(snap.build, 1))
    m, c = cm.model, cm.consignments["c0"]
    body = c.content_body
    i = int(np.flatnonzero(m.rigid_nodes == body)[0])
    half, radius = m.rigid_half_inner[i], m.rigid_radius[i]
    frames = np.repeat(cm.state0.positions[None], 4, axis=0)
    rv = np.zeros(frames.shape)
    # frame 1: the box's lowest corner sphere 0.3 mm under the belt surface, over the belt
    frames[1, body] = (0.5, 0.0, half[2] + radius - 3e-4)
    # frame 2: 2 mm under it, but past the belt's end (fallen off): not counted
    frames[2, body] = (cm.parts.scene.belt_length + 0.05, 0.0, half[2] + radius - 2e-3)
    # frame 3: turned 90 deg about x (its y half-size now points down), 0.5 mm under
    rv[3, body] = (np.pi / 2, 0.0, 0.0)
    frames[3, body] = (0.6, 0.0, half[1] + radius - 5e-4)
    res = SimpleNamespace(time=np.array([0.0, 0.01, 0.02, 0.03]), positions=frames,
                          rotation_vectors=rv)  # fmt: skip
    d = content_below_belt(cm, res)["c0"]
    assert d["depth_m"] == pytest.approx(5e-4, abs=1e-12) and d["time_s"] == 0.03
    assert d["limit_m"] == cm.laws["c0"]["belt"].damping_depth == pytest.approx(1e-4)
    res = SimpleNamespace(time=res.time[:3], positions=frames[:3], rotation_vectors=rv[:3])
    assert content_below_belt(cm, res)["c0"]["depth_m"] == pytest.approx(3e-4, abs=1e-12)
    res = SimpleNamespace(
        time=res.time[[0, 2]], positions=frames[[0, 2]], rotation_vectors=rv[[0, 2]]
    )
    assert content_below_belt(cm, res)["c0"] == {"depth_m": None, "limit_m": d["limit_m"],
                                                 "time_s": None}  # fmt: skip


def test_deflector_friction_parameter_sets_every_deflector_law(snapshot_dir):
    import pickle

    from flexparcel.scenarios.conveyor_scenario import deflector_friction_table
    from flexparcel.scenarios.friction_pairs import DEFAULT_FRICTION_TABLE, DEFLECTOR
    from flexparcel.scenarios.registry import get_scenario

    snap = load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")
    scenario = get_scenario("conveyor", scene=load_scene_file(SCENE))
    cm = scenario.build({"consignment_small": snap}, {"deflector_friction": 0.7})
    for laws in cm.laws.values():
        assert laws["deflector"].mu_static == laws["deflector"].mu_dynamic == 0.7
        assert laws["belt"].mu_static != 0.7  # the belt's friction is the table's
    table = deflector_friction_table(0.7)
    assert {k for k, v in table.items() if v.mu_static == 0.7} == {
        k for k in DEFAULT_FRICTION_TABLE if k[1] == DEFLECTOR
    }
    pickle.dumps(table)  # it travels to the group workers, which are spawned
    assert deflector_friction_table(None) is None


@pytest.fixture(scope="module")
def conveyor_run(snapshot_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("conveyor") / "run"
    args = ["run", "conveyor", "--scene", str(SCENE), "--snapshot-dir", str(snapshot_dir),
            "--t-end", "0.01", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    return out, json.loads((out / "responses.json").read_text())


def test_scene_with_a_transfer_runs_and_draws_both_belts(snapshot_dir, tmp_path):
    # the command end to end with a [transfer] table: the layout records it, the checks run,
    # and ParaView's belt holds both belts (two quads, each with its own speed)
    import meshio

    scene = tmp_path / "transfer.toml"
    text = SCENE.read_text().replace('consignment = "consignment_small.toml"',
                                     f'consignment = "{EXAMPLE.resolve().as_posix()}"')  # fmt: skip
    scene.write_text(text + "\n[transfer]\ngap_m = 0.02\nlength_m = 0.5\nspeed_m_s = 1.0\n")
    out = tmp_path / "run"
    args = ["run", "conveyor", "--scene", str(scene), "--snapshot-dir", str(snapshot_dir),
            "--t-end", "0.002", "--workers", "0", "--out", str(out)]  # fmt: skip
    assert main(args) == 0
    r = json.loads((out / "responses.json").read_text())
    assert r["layout"]["conveyor"]["transfer"] == {"gap_m": 0.02, "length_m": 0.5,
                                                   "speed_m_s": 1.0}  # fmt: skip
    assert set(r["content_below_belt"]) == {"a", "b", "c", "d"}
    belt = meshio.read(out / "paraview" / "belt_0000.vtu")
    assert belt.points[:, 0].max() == pytest.approx(1.2 + 0.02 + 0.5)
    assert sorted(set(belt.point_data["velocity_m_per_s"][:, 0])) == [1.0, 1.6]


def test_four_consignments_move_downstream_and_are_deflected(conveyor_run):
    _, r = conveyor_run
    assert r["simulated_s"] == pytest.approx(0.01) and r["steps"] > 0 and r["wall_s"] > 0
    cons = r["consignments"]
    assert list(cons) == ["a", "b", "c", "d"]
    for name, c in cons.items():
        x, y = np.array(c["trajectory"]["x_m"]), np.array(c["trajectory"]["y_m"])
        assert x[-1] - x[0] > 2e-3, name  # downstream
        k = 0 if name in ("a", "b") else 1  # a, b start beside deflector 0 (y > 0), c, d 1
        assert c["deflector_contact_duration_s"][k] > 0.0, name
        assert c["deflector_contact_duration_s"][1 - k] is None, name  # never: null
        assert "deflector_contact_duration_s" in c["notes"], name
        # pushed along the face towards the centre line: |y| falls (the belt alone drives
        # only x and every copy starts with v_y = 0; the 12 ms run of the example file
        # moved them 3 mm)
        assert abs(y[-1]) < abs(y[0]) - 1e-3, name
        assert c["peak_contact_force_N"] > 0.0, name
        assert max(c["contact_force_N"]) == c["peak_contact_force_N"], name
    assert r["parameters"]["belt_speed_m_s"] == 1.6 and r["parameters"]["t_end_s"] == 0.01
    assert r["friction"]["a"]["belt"] == [0.5, 0.4]  # bubble_wrap on PU, table default
    assert r["deflector_crossings"] == {"a": None, "b": None, "c": None, "d": None}


def test_conveyor_cli_writes_its_files(conveyor_run, capsys):
    out, r = conveyor_run
    for name in ("responses.json", "results.npz", "paraview/conveyor.pvd",
                 "paraview/contents.pvd", "snapshots.png", "trajectories.png", "motion.png",
                 "animation.gif", "view.html", "report.html"):  # fmt: skip
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert set(r["files"]) >= {"snapshots", "trajectories", "animation", "paraview", "report"}
    # the report: the verdict of a run shorter than the jam window, a row per consignment
    report = (out / "report.html").read_text()
    assert "Jam verdict: not reached in this run" in report
    assert all(f"<tr><td>{name}</td>" in report for name in "abcd")
    assert r["files"]["report"] == str(out / "report.html")
    from PIL import Image

    with Image.open(out / "animation.gif") as gif:
        assert gif.n_frames > 1


def test_conveyor_cli_resumes_from_its_checkpoint(conveyor_run, snapshot_dir, capsys):
    # the finished run left a complete checkpoint: the same command takes the run from it
    # (no step) and writes the same responses; a changed scene is refused by name
    out, r = conveyor_run
    assert load_checkpoint(out / "checkpoint.npz").header["complete"]
    args = ["run", "conveyor", "--scene", str(SCENE), "--snapshot-dir", str(snapshot_dir),
            "--t-end", "0.01", "--out", str(out), "--no-progress"]  # fmt: skip
    capsys.readouterr()
    assert main(args) == 0
    assert f"resuming from {out / 'checkpoint.npz'}" in capsys.readouterr().err
    again = json.loads((out / "responses.json").read_text())
    for name, c in r["consignments"].items():
        assert again["consignments"][name]["trajectory"] == c["trajectory"], name
    assert again["steps"] == r["steps"]
    err = _error(capsys, [*args, "--belt-speed", "1.2"])
    assert "written for another model" in err and "remove it" in err


def test_conveyor_cli_preview_of_a_run_in_progress(snapshot_dir, tmp_path, capsys):
    # a run interrupted after its first frames: --preview writes the files of those frames
    # to DIR/preview/ without stepping and leaves the checkpoint as it was (the scene as one
    # model; the group-by-group run's checkpoint: tests/test_conveyor_groups.py)
    out = tmp_path / "run"
    args = ["run", "conveyor", "--scene", str(SCENE), "--snapshot-dir", str(snapshot_dir),
            "--t-end", "0.01", "--out", str(out), "--no-progress", "--workers", "0"]  # fmt: skip
    assert "no checkpoint" in _error(capsys, [*args, "--preview"])
    from flexparcel.scenarios import conveyor_scene

    real = conveyor_scene.simulate

    def interrupted(*a, **kw):
        def stop(t, t_end):
            if t > 0.0021:  # after the frame at 0.002 s (dt_out = t_end / 20)
                raise KeyboardInterrupt

        return real(*a, **{**kw, "progress": stop, "checkpoint_interval_s": 0.0})

    conveyor_scene.simulate = interrupted
    try:  # Ctrl-C: one line and exit status 130, the checkpoint kept
        assert main(args) == 130
    finally:
        conveyor_scene.simulate = real
    assert "interrupted" in capsys.readouterr().err
    ckpt = out / "checkpoint.npz"
    before = ckpt.read_bytes()
    assert main([*args, "--preview"]) == 0
    assert "preview of the checkpoint" in capsys.readouterr().out
    r = json.loads((out / "preview" / "responses.json").read_text())
    assert r["simulated_s"] == pytest.approx(0.002)
    for name in ("snapshots.png", "trajectories.png", "animation.gif"):
        assert (out / "preview" / name).stat().st_size > 0, name
    assert not (out / "responses.json").exists()
    assert ckpt.read_bytes() == before
    assert "only apply to 'flexparcel run conveyor'" in _error(
        capsys, ["run", "swing", "--consignment", "KP", "--preview", "--out", str(tmp_path)]
    )


def test_conveyor_cli_reuses_cached_snapshots(snapshot_dir, tmp_path, capsys):
    # a snapshot already in DIR/snapshots/ is reused (no assembly); a --snapshot-dir one of
    # another element size is refused
    out = tmp_path / "run"
    cache = out / "snapshots" / "consignment_small_20mm"
    cache.mkdir(parents=True)
    shutil.copy(snapshot_dir / "consignment_small" / "snapshot.npz", cache / "snapshot.npz")
    from flexparcel.cli.snapshots import snapshot_for

    build = load_consignment_file(EXAMPLE)
    snap, source = snapshot_for("consignment_small", build, out, log=lambda m: None)
    assert source == str(cache / "snapshot.npz")
    other = replace(build, element_size=0.03)
    with pytest.raises(ValueError, match="assembled with 20 mm elements, not 30 mm"):
        snapshot_for("consignment_small", other, out, snapshot_dir=snapshot_dir,
                     element_size_given=True)  # fmt: skip


def _error(capsys, args) -> str:
    assert main(args) == 2
    return capsys.readouterr().err


def test_conveyor_cli_rejects_bad_input_before_running(tmp_path, capsys):
    out = ["--out", str(tmp_path / "o")]
    assert "--belt-speed must be in [0, 10] m/s, got 12" in _error(
        capsys, ["run", "conveyor", "--belt-speed", "12", *out]
    )
    assert "--deflector-angle must be in [10, 90] deg, got 5" in _error(
        capsys, ["run", "conveyor", "--deflector-angle", "5", *out]
    )
    assert "unknown consignment 'XX'" in _error(
        capsys, ["run", "conveyor", "--consignments", "KPBW,XX", *out]
    )
    assert "given twice" in _error(capsys, ["run", "conveyor", "--consignments", "KP,KP", *out])
    assert "--workers must be an integer in [0, 64], got -1" in _error(
        capsys, ["run", "conveyor", "--workers", "-1", *out]
    )
    assert "--workers must be an integer in [0, 64], got 65" in _error(
        capsys, ["bench", "conveyor", "--workers", "65", *out]
    )
    assert "--content-stiffness must be in [1, 10000] N/mm, got 0" in _error(
        capsys, ["run", "conveyor", "--content-stiffness", "0", *out]
    )
    # the benchmark takes the same option, checked before any run
    assert "--content-stiffness must be in [1, 10000] N/mm, got 20000" in _error(
        capsys, ["bench", "conveyor", "--content-stiffness", "2e4", *out]
    )
    assert "--stick-stiffness must be in [0.01, 10000] N/mm, got 0" in _error(
        capsys, ["run", "conveyor", "--stick-stiffness", "0", *out]
    )
    assert "--stick-stiffness must be in [0.01, 10000] N/mm, got 20000" in _error(
        capsys, ["bench", "conveyor", "--stick-stiffness", "2e4", *out]
    )
    assert "--sizes must be in [1, 100] mm, got '0.5,10'" in _error(
        capsys, ["bench", "kpbw-convergence", "--sizes", "0.5,10", *out]
    )
    assert "--scaling-counts must be integers separated by commas, got '1,x'" in _error(
        capsys, ["bench", "conveyor-scaling", "--scaling-counts", "1,x", *out]
    )
    bad = tmp_path / "bad.toml"
    bad.write_text("format_version = 1\n[belt]\nspeed_m_s = -1\n")
    err = _error(capsys, ["run", "conveyor", "--scene", str(bad), *out])
    assert str(bad) in err and "speed_m_s must be in [0, 10] m/s, got -1" in err
    assert "only apply to 'flexparcel run conveyor'" in _error(
        capsys, ["run", "swing", "--consignment", "KP", "--belt-speed", "1", *out]
    )
    assert "do not apply to the conveyor" in _error(
        capsys, ["run", "conveyor", "--consignment", "KP", *out]
    )
    # a layout that does not fit fails before any (minutes long) assembly
    short = tmp_path / "short.toml"
    short.write_text('format_version = 1\nconsignments = ["KPBW", "PB", "KP", "BW"]\n'
                     "[belt]\nlength_m = 3.0\n[deflectors]\nx_m = [0.5, 1.5]\n")  # fmt: skip
    assert "the queue needs 1.3" in _error(capsys, ["run", "conveyor", "--scene", str(short),
                                                    *out])  # fmt: skip
    assert not (tmp_path / "o" / "snapshots").exists()


def test_content_law_takes_the_stiffness_and_the_stick_stiffness_per_10_mm_node():
    # per point of the paper's 10 mm nodes: the per-area law gets the value / (10 mm)^2
    from flexparcel.consignments.build import default_packaging_content_law
    from flexparcel.scenarios.conveyor_scenario import content_law_for

    table6 = default_packaging_content_law()
    assert content_law_for(None) is None
    assert table6.stick_stiffness == table6.stiffness == pytest.approx(6.49e9)
    soft = content_law_for(64.9)
    assert soft.stiffness == soft.stick_stiffness == pytest.approx(6.49e8)
    # k_t alone: c stays Table 6's, and only the tangential spring changes
    kt = content_law_for(None, stick_n_per_mm=6.49)
    assert kt.stiffness == pytest.approx(6.49e9) and kt.stick_stiffness == pytest.approx(6.49e7)
    assert kt.damping == table6.damping and kt.mu_static == table6.mu_static
    both = content_law_for(100.0, stick_n_per_mm=1.0)
    assert both.stiffness == pytest.approx(1e9) and both.stick_stiffness == pytest.approx(1e7)
    with pytest.raises(ValueError, match=r"stick_stiffness must be in \[0.01, 10000\] N/mm"):
        content_law_for(None, stick_n_per_mm=0.001)
