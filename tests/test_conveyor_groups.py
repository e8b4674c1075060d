"""A conveyor scene integrated group by group (flexparcel.scenarios.conveyor_groups).

Two copies of the small example consignment (20 mm shells) on the belt: apart at the same
speed they stay separate groups and the frames match a one-model run within the
integrator's tolerance; a trailing copy arriving at belt speed behind one dropped at rest is
merged with it before they can touch. Moving a group between models (export, rebuild from
the export) continues bit for bit, so the worker count does not change the result.
"""

from dataclasses import replace

import numpy as np
import pytest

from flexparcel.consignments.snapshot import load_snapshot
from flexparcel.io.checkpoint import CheckpointError
from flexparcel.scenarios.conveyor_groups import GroupSettings, _Group, box_gap
from flexparcel.scenarios.conveyor_scene import (
    SceneLayout,
    build_conveyor_model,
    conveyor_options,
    run_conveyor,
    throughput_layout,
)


@pytest.fixture(scope="module")
def snap(snapshot_dir):
    return load_snapshot(snapshot_dir / "consignment_small" / "snapshot.npz")


def _centroids(run) -> dict[str, np.ndarray]:
    x = run.result.positions
    return {k: x[:, c.node_ids].mean(axis=1) for k, c in run.conveyor_model.consignments.items()}


def test_box_gap_is_the_distance_between_boxes():
    lo, hi = np.zeros(3), np.ones(3)
    assert box_gap(lo, hi, lo + [3.0, 0.0, 0.0], hi + [3.0, 0.0, 0.0]) == pytest.approx(2.0)
    # apart along x by 2 and y by 1 (a corner to corner gap): sqrt(2^2 + 1^2)
    assert box_gap(lo, hi, lo + [3.0, 2.0, 0.5], hi + [3.0, 2.0, 0.5]) == pytest.approx(5**0.5)
    assert box_gap(lo, hi, lo + 0.5, hi + 0.5) == 0.0
    assert box_gap(lo + [3.0, 0.0, 0.0], hi + [3.0, 0.0, 0.0], lo, hi) == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"workers": 0}, r"GroupSettings.workers must be an integer >= 1, got 0"),
        ({"threads_per_worker": 1.5}, r"threads_per_worker must be an integer >= 1"),
        ({"merge_slack": -1e-3}, r"merge_slack must be >= 0 m"),
        ({"lookahead": float("nan")}, r"lookahead must be >= 0, got nan"),
        ({"rebalance_frames": 0}, r"rebalance_frames must be an integer >= 1"),
    ],
)
def test_bad_group_settings_name_the_field(kw, message):
    with pytest.raises(ValueError, match=message):
        GroupSettings(**kw)


def _setup(snap, layout):
    cm = build_conveyor_model({"c": snap}, layout)
    ids = {k: c.node_ids for k, c in cm.consignments.items()}
    return cm, {"snapshots": {"c": snap}, "layout": layout, "build": {},
                "options": conveyor_options(), "full_ids": ids, "state0": cm.state0,
                "build_model": build_conveyor_model}  # fmt: skip


def test_a_group_rebuilt_from_its_export_continues_bit_for_bit(snap):
    # the export carries state and integrator history keyed by node and contact: a model
    # rebuilt from it (a move to another worker, a resumed checkpoint) steps exactly as the
    # original, stick springs and anchors included
    layout = throughput_layout(snap.build, 2)  # at rest, 1 mm above the running belt
    _, setup = _setup(snap, layout)
    g = _Group(setup, ("c0",), None)
    g.advance(0.02)  # on the belt by now, slipping
    moved = _Group(setup, ("c0",), [g.export()])
    a, b = g.advance(0.024), moved.advance(0.024)
    np.testing.assert_array_equal(a["positions"], b["positions"])
    np.testing.assert_array_equal(a["velocities"], b["velocities"])
    assert a["stats"]["steps"] == b["stats"]["steps"] > 0
    ha, hb = g.integ.history(), moved.integ.history()
    # the moved group analyses its held sparsity pattern once more (a restored solver holds
    # the pattern, not CHOLMOD's symbolic factor): every other count is the same
    from dataclasses import fields

    from flexparcel.integrate.dynamic import Stats

    k = [f.name for f in fields(Stats) if f.name != "wall_s"].index("symbolic_analyses")
    assert hb["stat_counts"][k] - ha["stat_counts"][k] in (0, 1)
    ha["stat_counts"][k] = hb["stat_counts"][k]
    for key in set(ha) - {"stat_wall"}:  # all but the wall clock
        if "anchor" in key:  # an anchor without its flag is a stale trial value
            held = ha[key.replace("anchor", "has")] > 0
            np.testing.assert_array_equal(ha[key][held], hb[key][held], err_msg=key)
        else:
            np.testing.assert_array_equal(ha[key], hb[key], err_msg=key)
    # the content's stick anchors in its packaging hold
    box_has = [v for k, v in ha.items() if k.startswith("contact.node_box") and k.endswith(".has")]
    assert box_has and any(np.any(v > 0) for v in box_has)


def _history_rows(export: dict) -> dict:
    """(row identity, name) -> value of every contact set's stick history in a group's
    export (plane springs ``u_el``, anchors)."""
    out = {}
    for key in export:
        if key.startswith("rows."):
            set_key = key[len("rows.") :]
            for name in ("u_el", "anchor"):
                arr = export.get(f"contact.{set_key}.{name}")
                if arr is not None:
                    out.update({(str(r), name): v for r, v in zip(export[key], arr, strict=True)})
    return out


def test_a_merged_group_takes_each_members_state_and_history(snap):
    layout = throughput_layout(snap.build, 2, speed=1.6)
    cm, setup = _setup(snap, layout)
    parts = [_Group(setup, (n,), None) for n in ("c0", "c1")]
    for g in parts:
        g.advance(0.002)
    merged = _Group(setup, ("c0", "c1"), [g.export() for g in parts])
    e = merged.export()
    assert merged.model.node_count == cm.model.node_count
    where = {int(n): k for k, n in enumerate(e["nodes"])}
    for g in parts:
        p = g.export()
        # the member's own nodes (the conveyor's fixed nodes are in every member's export)
        own = np.isin(p["nodes"], setup["full_ids"][g.names[0]])
        assert own.sum() == setup["full_ids"][g.names[0]].size
        rows = [where[int(n)] for n in p["nodes"][own]]
        for key in ("positions", "rotations", "velocities", "accelerations", "alg", "fc_prev"):
            np.testing.assert_array_equal(e[key][rows], p[key][own], err_msg=key)
        # each member's plane contact springs and box anchors, found by node and contact
        mine, theirs = _history_rows(p), _history_rows(e)
        for kind in ("plane:", "node_box:"):
            assert any(row.startswith(kind) for row, _ in mine), kind
        for row_name, v in mine.items():
            np.testing.assert_array_equal(theirs[row_name], v, err_msg=str(row_name))
    # the merged model has the two face contact sets between the members, without history
    faces = [k for k in e if k.startswith("rows.node_face")]
    assert len(faces) == sum(len([k for k in g.export() if k.startswith("rows.node_face")])
                             for g in parts) + 2  # fmt: skip
    assert merged.state.time == pytest.approx(0.002)


@pytest.fixture(scope="module")
def apart(snap):
    """Two copies at belt speed, 50 mm apart: 10 ms one model, and by groups on 1 and 2
    workers (frames every 2.5 ms, so the groups are dealt again four times)."""
    layout = throughput_layout(snap.build, 2, speed=1.6)
    one = run_conveyor({"c": snap}, layout, 0.01, dt_out=0.0025)
    local = run_conveyor({"c": snap}, layout, 0.01, dt_out=0.0025,
                         groups=GroupSettings(workers=1))  # fmt: skip
    two = run_conveyor({"c": snap}, layout, 0.01, dt_out=0.0025,
                       groups=GroupSettings(workers=2, rebalance_frames=1))  # fmt: skip
    return one, local, two


def test_groups_apart_stay_apart_and_match_one_model(apart):
    one, local, _ = apart
    g = local.result.stats["groups"]
    assert g["final"] == [["c0"], ["c1"]] and g["merges"] == [] and g["rewinds"] == 0
    np.testing.assert_allclose(local.result.time, one.result.time)
    # each model keeps its local error estimate below tol_displacement (0.1 mm) per step, on
    # its own step sequence: the two runs differ by that order, not by contact effects
    tol = conveyor_options().tol_displacement
    c1, c2 = _centroids(one), _centroids(local)
    for k in c1:
        assert np.abs(c1[k] - c2[k]).max() < tol, k
    assert np.abs(one.result.positions - local.result.positions).max() < 5 * tol
    # both moved with the belt (1.6 m/s for 10 ms: 16 mm)
    for k in c1:
        assert c2[k][-1, 0] - c2[k][0, 0] == pytest.approx(0.016, abs=1e-3), k


def test_the_worker_count_does_not_change_the_frames(apart):
    # two worker processes, the groups dealt again at every frame: the same frames, bit for
    # bit, as one in-process worker (moves restore the integrator history exactly)
    _, local, two = apart
    np.testing.assert_array_equal(local.result.positions, two.result.positions)
    np.testing.assert_array_equal(local.result.velocities, two.result.velocities)
    assert local.result.stats["steps"] == two.result.stats["steps"]
    assert two.result.stats["groups"]["workers"] == 2
    assert two.responses.keys() == local.responses.keys()


@pytest.fixture(scope="module")
def closing(snap):
    """c1 arrives at belt speed 50 mm behind c0, which starts at rest on the running belt
    (they close at about 1.5 m/s and meet after 33 ms), 40 ms by groups: with the default
    lookahead, and with none (merged only once within reach)."""
    base = throughput_layout(snap.build, 2)
    lead, trail = base.placements
    layout = SceneLayout(base.conveyor, (lead, replace(trail, speed=1.6)))
    runs = {}
    for key, kw in (("ahead", {}), ("late", {"lookahead": 0.0, "merge_slack": 0.0})):
        runs[key] = run_conveyor({"c": snap}, layout, 0.04, dt_out=0.005,
                                 groups=GroupSettings(workers=1, **kw))  # fmt: skip
    return runs


@pytest.mark.slow  # 80-90 s each with worker processes (make slow)
def test_a_trailing_copy_is_merged_before_it_can_touch(closing):
    # the groups are merged at the frame where the gap falls below reach + 2 dt_out
    # (relative speed) + slack, before any contact is possible (no rewind), and the merged
    # model carries on where they were
    run = closing["ahead"]
    g = run.result.stats["groups"]
    assert g["rewinds"] == 0 and g["final"] == [["c0", "c1"]]
    (m,) = g["merges"]
    assert m["members"] == ["c0", "c1"] and 0.0 < m["time"] < 0.033
    cm = run.conveyor_model
    x = run.result.positions[int(round(m["time"] / 0.005))]
    a, b = (x[cm.consignments[n].node_ids] for n in ("c0", "c1"))
    gap = box_gap(a.min(axis=0), a.max(axis=0), b.min(axis=0), b.max(axis=0))
    assert gap > 2 * cm.consignments["c0"].contact_radius  # still apart when merged
    c = _centroids(run)
    assert c["c1"][-1, 0] - c["c1"][0, 0] > 0.03  # the trailing copy kept going
    assert np.all(np.isfinite(run.result.positions))


@pytest.mark.slow  # 80-90 s each with worker processes (make slow)
def test_a_missed_merge_rewinds_the_frame_and_does_it_again_together(closing):
    # without lookahead and slack the groups meet within reach at a frame: that frame is
    # integrated again from the frame before, merged, and the run goes on as one group
    late, ahead = closing["late"], closing["ahead"]
    g = late.result.stats["groups"]
    assert g["rewinds"] == 1 and g["final"] == [["c0", "c1"]]
    (m,) = g["merges"]
    assert m["time"] > ahead.result.stats["groups"]["merges"][0]["time"]  # merged later
    assert np.all(np.isfinite(late.result.positions))
    # both merged before the packagings met, so they push each other alike
    c_late, c_ahead = _centroids(late), _centroids(ahead)
    for k in c_late:
        assert np.abs(c_late[k][-1] - c_ahead[k][-1]).max() < 1e-3, k


def test_grouped_checkpoint_resumes_and_refuses_a_one_model_one(snap, tmp_path):
    layout = throughput_layout(snap.build, 2, speed=1.6)
    settings = GroupSettings(workers=1)
    full = run_conveyor({"c": snap}, layout, 0.006, dt_out=0.002, groups=settings)

    class Stop(Exception):
        pass

    def stop_at(t, _t_end):
        if t > 0.0035:
            raise Stop

    ck = tmp_path / "ck.npz"
    from flexparcel.scenarios import conveyor_groups

    with pytest.raises(Stop):
        conveyor_groups.integrate_by_groups(
            build_conveyor_model({"c": snap}, layout), {"c": snap}, 0.006, dt_out=0.002,
            options=conveyor_options(), build_kwargs={}, settings=settings,
            progress=stop_at, checkpoint=ck, checkpoint_interval_s=0.0,
        )  # fmt: skip
    assert ck.is_file()
    before = ck.read_bytes()
    # what the checkpoint holds so far (run conveyor --preview), without stepping
    seen = run_conveyor({"c": snap}, layout, 0.006, dt_out=0.002, groups=settings,
                        checkpoint=ck, checkpoint_only=True)  # fmt: skip
    assert seen.result.time[-1] == pytest.approx(0.002)  # the last frame saved before 0.0035
    k = len(seen.result.time)
    np.testing.assert_array_equal(seen.result.positions, full.result.positions[:k])
    assert ck.read_bytes() == before
    again = run_conveyor({"c": snap}, layout, 0.006, dt_out=0.002, groups=settings, checkpoint=ck)
    np.testing.assert_array_equal(again.result.positions, full.result.positions)
    assert again.result.stats["steps"] == full.result.stats["steps"]
    with pytest.raises(CheckpointError, match=r"mode = 'groups', this run has mode = 'one-model'"):
        run_conveyor({"c": snap}, layout, 0.006, dt_out=0.002, checkpoint=ck)


def test_groups_start_from_the_scenes_given_state(snap):
    # a scene restarted from a state of its own (here c0 pushed sideways at 0.5 m/s): each
    # group takes its members' part of that state, not the placement's state at rest
    from dataclasses import replace as dc_replace

    from flexparcel.scenarios.conveyor_groups import integrate_by_groups

    cm = build_conveyor_model({"c": snap}, throughput_layout(snap.build, 2, speed=1.6))
    s0 = cm.state0.copy()
    ids = cm.consignments["c0"].node_ids
    s0.velocities[ids, 1] = 0.5
    cm = dc_replace(cm, state0=s0)
    res = integrate_by_groups(cm, {"c": snap}, 0.004, dt_out=0.002, options=conveyor_options(),
                              build_kwargs={}, settings=GroupSettings(workers=1))  # fmt: skip
    np.testing.assert_array_equal(res.positions[0], s0.positions)
    y = res.positions[:, ids, 1].mean(axis=1)
    assert y[-1] - y[0] == pytest.approx(0.5 * 0.004, rel=0.05)  # sideways at 0.5 m/s
    other = res.positions[:, cm.consignments["c1"].node_ids, 1].mean(axis=1)
    assert abs(other[-1] - other[0]) < 1e-5


@pytest.mark.slow  # 80-90 s each with worker processes (make slow)
def test_a_merged_group_splits_again_once_its_parts_are_apart(snap):
    # c0 leaves at belt speed, c1 starts at rest 50 mm behind it. With a merge slack of 60 mm
    # they start as one group; they part at about 1.6 m/s, and once the packagings are
    # farther apart than the merge gap plus split_slack the group splits into the two, each
    # with its part of the state: the frames go on as one model's within its tolerance
    base = throughput_layout(snap.build, 2)
    lead, trail = base.placements
    layout = SceneLayout(base.conveyor, (replace(lead, speed=1.6), trail))
    settings = GroupSettings(workers=1, merge_slack=0.06, split_slack=0.01)
    run = run_conveyor({"c": snap}, layout, 0.04, dt_out=0.005, groups=settings)
    g = run.result.stats["groups"]
    assert [m["time"] for m in g["merges"]] == [0.0]
    (sp,) = g["splits"]
    assert sp["parts"] == [["c0"], ["c1"]] and 0.0 < sp["time"] < 0.04
    assert g["final"] == [["c0"], ["c1"]] and g["rewinds"] == 0
    one = run_conveyor({"c": snap}, layout, 0.04, dt_out=0.005)
    tol = conveyor_options().tol_displacement
    c1, c2 = _centroids(one), _centroids(run)
    for k in c1:
        assert np.abs(c1[k] - c2[k]).max() < tol, k
