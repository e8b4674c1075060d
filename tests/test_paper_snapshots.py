"""The shipped snapshots of the four paper consignments (data/paper-snapshots-25mm): they
load, were assembled from today's Table 2 presets at 25 mm, ended at rest, and today's
builders make the meshes they hold (placing them into the paper scene checks every node)."""

from pathlib import Path

import numpy as np
import pytest

from flexparcel.builder import ModelBuilder
from flexparcel.consignments.assembly import content_outside_packaging
from flexparcel.consignments.build import (
    ConsignmentBuild,
    _block_face_count,
    _hex_block,
    add_consignment,
)
from flexparcel.consignments.snapshot import check_snapshot_matches, load_snapshot
from flexparcel.scenarios.conveyor_scene import build_conveyor_model, default_layout

DATA = Path(__file__).resolve().parents[1] / "data" / "paper-snapshots-25mm"
KEYS = ("KPBW", "PB", "KP", "BW")


@pytest.fixture(scope="module")
def snapshots():
    return {k: load_snapshot(DATA / f"{k}.npz") for k in KEYS}


@pytest.mark.parametrize("key", KEYS)
def test_snapshot_is_the_preset_at_25_mm_and_at_rest(snapshots, key):
    snap = snapshots[key]
    check_snapshot_matches(snap, ConsignmentBuild.of(key, element_size=0.025), 0.025)
    assert snap.info["at_rest"] is True
    assert snap.info["kinetic_energy_J"] < 2e-6  # the assembly's rest bound
    assert np.all(np.isfinite(snap.positions))


def test_snapshots_place_into_the_paper_scene(snapshots):
    builds = {k: s.build for k, s in snapshots.items()}
    cm = build_conveyor_model(snapshots, default_layout(builds))
    # 1,128 + 3,030 + 2,238 + 690 DOF (data/paper-snapshots-25mm/README.md; KP's glued
    # nodes follow its content and carry none); the belt and deflectors are prescribed rigid
    # bodies and add none
    assert cm.model.dof_count == 7086
    for name, nodes in cm.node_sets().items():
        assert cm.state0.positions[nodes, 2].min() > 0.0, name  # above the belt surface z = 0


def test_pb_film_holds_its_content(snapshots):
    # PB's assembled film must hold its content block: no block corner outside the closed film
    # (ray parity), and no content node below the film's lowest node, since only the film
    # touches the belt. The snapshot assembled with sharp block corners had 4 corners outside,
    # up to 6.6 mm under the film's rim, and they sank into the belt in the conveyor scene.
    snap = snapshots["PB"]
    b = ModelBuilder()
    c = add_consignment(b, snap.build)
    model = b.finalize()
    outside = content_outside_packaging(model, c, snap.positions)
    s = snap.build.spec
    size = np.array([s.content_length_mm, s.content_width_mm, s.content_height_mm]) * 1e-3
    sharp, _ = _hex_block(*size, 0.025, (0.0, 0.0, 0.0))  # the block's lattice, node order
    corner = _block_face_count(sharp) == 3
    assert corner.sum() == 8
    assert not np.isin(c.content_nodes[corner], outside).any()
    z = snap.positions[:, 2]
    assert z[c.content_nodes].min() >= z[c.packaging].min()


PAPER_MESH = Path(__file__).resolve().parents[1] / "data" / "paper-snapshots-10mm"


def test_rigid_contents_stay_inside_their_film_to_within_a_chord(snapshots):
    # a rigid box's whole surface against the closed film (shape.content_surface_outside):
    # the points outside lie under facets that chord the box's rounded edges, never deeper
    # than the chord bound; KP/BW at the paper's 10 mm cuts less deep than at 25 mm
    from flexparcel.consignments.shape import content_surface_outside

    depth = {}
    for key, snap in [(k, snapshots[k]) for k in ("KPBW", "KP", "BW")] + [
        ("KPBW-10", load_snapshot(PAPER_MESH / "KPBW.npz"))
    ]:
        b = ModelBuilder()
        c = add_consignment(b, snap.build)
        cs = content_surface_outside(b.finalize(), c, snap.positions, snap.rotations)
        assert cs["depth_mm"] <= cs["bound_mm"], key
        depth[key] = cs["depth_mm"]
    assert depth["KPBW-10"] < 0.5 * depth["KPBW"]


@pytest.mark.parametrize(
    ("path", "element_size"),
    [(p, None) for p in sorted(PAPER_MESH.glob("*.npz"))]
    + [(DATA / f"{k}.npz", 0.025) for k in KEYS],
    ids=lambda v: f"{v.parent.name[-4:]}-{v.stem}" if isinstance(v, Path) else "",
)
def test_shipped_snapshots_are_taken_by_the_commands(path, element_size):
    # each shipped snapshot is the preset at its element size (the paper's: 10 mm, BW 5 mm; or
    # the 25 mm low-fidelity level), passed the assembly's rest and shape checks, and fits the
    # mesh today's builder makes, so run / demo / bench / the conveyor take it
    # (shipped_snapshot); a builder change fails here: assemble again
    from flexparcel.consignments.snapshot import shipped_snapshot

    snap = load_snapshot(path)
    build = ConsignmentBuild.of(path.stem, element_size=element_size)
    assert snap.build.element_size == build.element_size
    shape = snap.info["shape"]
    assert snap.info["at_rest"] and shape["failures"] == []
    assert shape["outer_mm"][0] <= shape["bound_mm"][0]
    found = shipped_snapshot(build)
    assert found is not None and found[1] == path
