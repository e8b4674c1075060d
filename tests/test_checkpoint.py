"""Checkpointed runs: an interrupted run resumes from its checkpoint and ends exactly as an
uninterrupted one; checkpoints of another run, version or format are refused by name."""

import json

import numpy as np
import pytest

import flexparcel as fp
from conftest import SHEET_T, soft_contact_law
from flexparcel.io.checkpoint import (
    CHECKPOINT_VERSION,
    CheckpointError,
    load_checkpoint,
    save_checkpoint,
)
from flexparcel.model.rigid import RoundedBox
from flexparcel.scenarios.conveyor import add_conveyor

T_END, DT_OUT = 0.06, 0.01


def _scene(friction: float = 0.3):
    """Every kind of step history at once: a shell sheet on the belt (plane contact with the
    stick model: the plane springs u_el, per node and per station of its border's line
    contact), a smaller sheet dropped on it (face contact with
    stick anchors; it starts touching it at zero distance and sinks in under its weight:
    1 um into it, the soft contact's 0.01 N per node would throw the 0.07 g nodes up at
    140 m/s^2, which the initial accelerations now count), a rigid box on the belt, and the
    step controller.
    Everything starts at belt speed. Returns the model and its initial state."""
    b = fp.ModelBuilder(gravity=(0.0, 0.0, -9.81))
    parts = add_conveyor(b)
    mat = fp.ShellMaterial(926e6, 0.1, 2424.0, SHEET_T, 1.71e-3)
    law = soft_contact_law().with_stick_model()
    law = type(law)(**{**law.to_dict(), "mu_static": friction, "mu_dynamic": friction})
    pts, quads = fp.mesh.rectangle(0.06, 0.06, 4, 4, origin=(0.2, -0.03, SHEET_T / 2))
    lower = b.add_shell_mesh(pts, quads, material=mat)
    pts, quads = fp.mesh.rectangle(0.04, 0.04, 2, 2, origin=(0.21, -0.02, 1.5 * SHEET_T))
    upper = b.add_shell_mesh(pts, quads, material=mat)
    b.add_contact(lower, parts.belt_plane, law, radius=SHEET_T / 2)
    # line contact takes half-spaces only: the belt's top as one, running with it
    top = b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (parts.scene.belt_speed, 0.0, 0.0))
    b.add_edge_contact(lower, top, law, radius=SHEET_T / 2)
    with b.monitored_contacts():  # its impulse record resumes too
        b.add_face_contact(upper, lower, law, thickness=SHEET_T)
    box = b.add_rigid_body(RoundedBox(0.1, 0.08, 0.04, 0.004, mass=0.3), (0.3, 0.3, 0.0205))
    b.add_contact(box, parts.belt_plane, law)
    model = b.finalize()
    s = model.initial_state()
    s.velocities[np.concatenate([lower, upper, [box]]), 0] = parts.scene.belt_speed
    return model, s


class _Stop(Exception):
    pass


def _interrupted(model, s0, path, t_stop):
    """Start the checkpointed run (a checkpoint at every frame) and stop it after t_stop."""

    def progress(t, _t_end):
        if t > t_stop:
            raise _Stop

    with pytest.raises(_Stop):
        fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path,
                    checkpoint_interval_s=0.0, progress=progress)  # fmt: skip


@pytest.fixture(scope="module")
def straight():
    model, s0 = _scene()
    return model, s0, fp.simulate(model, T_END, dt_out=DT_OUT, state=s0)


def test_interrupted_run_resumes_exactly(straight, tmp_path):
    model, s0, ref = straight
    path = tmp_path / "run.npz"
    _interrupted(model, s0, path, 0.035)
    part = load_checkpoint(path)
    assert not part.header["complete"]
    # the last frame before the interruption (0.03 s) was saved, nothing after it
    np.testing.assert_allclose(part.frames["time"], [0.0, 0.01, 0.02, 0.03], atol=1e-15)
    calls = []
    res = fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path,
                      progress=lambda t, te: calls.append(t))  # fmt: skip
    assert min(calls) > 0.03  # no step before the checkpoint was redone
    # the restored history (algorithmic accelerations, stick springs and anchors, step
    # controller) makes the resumed run repeat the uninterrupted one bit for bit
    np.testing.assert_array_equal(res.time, ref.time)
    np.testing.assert_array_equal(res.positions, ref.positions)
    np.testing.assert_array_equal(res.velocities, ref.velocities)
    np.testing.assert_array_equal(res.final_state.rotations, ref.final_state.rotations)
    # the upper sheet's weight on the lower one, recorded across the interruption
    assert np.abs(ref.monitored_impulses[-1]).sum() > 0.0
    np.testing.assert_array_equal(res.monitored_impulses, ref.monitored_impulses)
    for k in ("steps", "rejected_steps", "newton_iterations"):
        assert res.stats[k] == ref.stats[k], k
    # the checkpoint held live stick history: plane springs and face anchors of the upper
    # sheet resting on the lower one
    # (each contact set's arrays under "contact.<set key>.<name>")
    hist = part.history
    springs = [v for k, v in hist.items() if k.startswith("contact.plane") and k.endswith(".u_el")]
    stations = [
        v for k, v in hist.items() if k.startswith("contact.edge_plane") and k.endswith(".u_el")
    ]
    assert stations and max(np.abs(u).max() for u in stations) > 0.0
    anchors = [
        v for k, v in hist.items() if k.startswith("contact.node_face") and k.endswith(".has")
    ]
    assert springs and max(np.abs(u).max() for u in springs) > 0.0
    assert anchors and anchors[0].sum() >= 2
    assert load_checkpoint(path).header["complete"]


def test_complete_checkpoint_is_returned_without_stepping(straight, tmp_path):
    model, s0, ref = straight
    path = tmp_path / "run.npz"
    first = fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path)
    np.testing.assert_array_equal(first.positions, ref.positions)
    calls = []
    again = fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path,
                        progress=lambda t, te: calls.append(t))  # fmt: skip
    assert calls == []
    np.testing.assert_array_equal(again.positions, ref.positions)
    np.testing.assert_array_equal(again.energies["total"], ref.energies["total"])
    assert again.stats["steps"] == ref.stats["steps"]


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(t_end=0.05), "t_end = 0.06, this run has t_end = 0.05"),
        (dict(dt_out=0.02), "dt_out = 0.01, this run has dt_out = 0.02"),
        (dict(options=fp.IntegratorOptions(rho_inf=0.5)), "options = "),
        (dict(model="other"), "another model"),
        (dict(state="moved"), "another initial state"),
    ],
)
def test_checkpoint_of_another_run_is_refused(straight, tmp_path, change, message):
    model, s0, _ = straight
    path = tmp_path / "run.npz"
    _interrupted(model, s0, path, 0.015)
    kw = dict(t_end=T_END, dt_out=DT_OUT)
    kw["state"] = s0
    if change.get("model"):
        model, _ = _scene(friction=0.4)
    elif change.get("state"):
        kw["state"] = s0.copy()
        kw["state"].positions[-1, 0] += 1e-3
    else:
        kw.update(change)
    t_end = kw.pop("t_end")
    with pytest.raises(CheckpointError, match=message) as e:
        fp.simulate(model, t_end, checkpoint=path, **kw)
    assert str(path) in str(e.value) and "remove it" in str(e.value)


def test_bad_checkpoint_files_name_the_file(tmp_path, straight):
    model, s0, _ = straight
    bad = tmp_path / "bad.npz"
    bad.write_text("not a zip")
    with pytest.raises(CheckpointError, match="bad.npz: not a readable .npz"):
        fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=bad)
    path = tmp_path / "run.npz"
    _interrupted(model, s0, path, 0.015)
    ck = load_checkpoint(path)
    ck.header["version"] = 99
    save_checkpoint(path, ck)
    with pytest.raises(
        CheckpointError, match=f"version 99, this flexparcel reads version {CHECKPOINT_VERSION}"
    ):
        fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path)
    ck.header = {"format": "something else"}
    save_checkpoint(path, ck)
    with pytest.raises(CheckpointError, match="not a flexparcel-run-checkpoint file"):
        load_checkpoint(path)
    # data, never code: the header is JSON and the arrays load without pickle
    with np.load(path, allow_pickle=False) as z:
        assert json.loads(str(z["header"])) == {"format": "something else"}
    # one written before its model's monitored contacts recorded their impulse
    _interrupted(model, s0, path := tmp_path / "old.npz", 0.015)
    ck = load_checkpoint(path)
    del ck.frames["monitored_impulses"]
    save_checkpoint(path, ck)
    with pytest.raises(CheckpointError, match="old.npz: .*no monitored contact impulses"):
        fp.simulate(model, T_END, dt_out=DT_OUT, state=s0, checkpoint=path)
    with pytest.raises(ValueError, match="checkpoint_interval_s must be >= 0"):
        fp.simulate(model, T_END, state=s0, checkpoint=path, checkpoint_interval_s=-1.0)
