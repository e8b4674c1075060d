"""The physical tests as calibration simulators (flexparcel.scenarios.simulators): found by
name through the entry points without the calibration layer loading FE code, refusing bad
input by name, and failing a run whose response was not reached instead of returning 0."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from flexparcel.calibration.simulators import get_simulator

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "consignment_small.toml"


def test_the_four_tests_are_registered_through_entry_points_without_fe_imports():
    code = (
        "import sys\n"
        "from flexparcel.calibration.simulators import get_simulator\n"
        "infos = [get_simulator(n) for n in ('swing', 'drop-vertical', 'drop-horizontal',"
        " 'conveyor')]\n"
        "assert infos[0].responses == ('first_swing_mm', 'second_swing_mm')\n"
        "assert infos[1].responses == ('rebound_mm', 'com_rise_mm')\n"
        "assert 'numba' not in sys.modules and 'flexparcel.integrate' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize(
    ("params", "setup", "message"),
    [
        ({"young": 900.0}, {"consignment": "KPBW"}, "unknown parameter.*young.*youngs_modulus"),
        ({}, {"consignment": "KPBW", "mesh": 10}, "unknown setup option.*mesh"),
        ({}, {}, "needs 'consignment'"),
        ({}, {"consignment": "XYZ"}, "unknown consignment 'XYZ'"),
        ({"youngs_modulus": -5.0}, {"consignment": "KPBW", "snapshot_dir": "nowhere"}, "> 0"),
    ],
)
def test_bad_input_names_the_field(params, setup, message, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if "snapshot_dir" in setup:  # a parameter out of range is refused before any assembly
        setup = {**setup, "snapshot": str(tmp_path / "none.npz")}
    with pytest.raises((ValueError, FileNotFoundError), match=message):
        get_simulator("swing").func(params, **setup)


def test_a_study_may_name_a_function_in_a_file_or_module(tmp_path):
    from flexparcel.calibration.study import _simulator_reference

    (tmp_path / "mysim.py").write_text(
        "def run(params, **setup):\n    return {'y': 2.0 * params['x']}\n"
    )
    name = _simulator_reference(tmp_path / "study.toml", "mysim.py:run")
    assert name == f"{tmp_path / 'mysim.py'}:run"
    assert get_simulator(name).func({"x": 3.0}) == {"y": 6.0}
    assert get_simulator("json:dumps").func([1]) == "[1]"
    with pytest.raises(ValueError, match="has no 'nothing'"):
        get_simulator("json:nothing")


def test_a_response_not_reached_fails_the_run_with_its_reason(snapshot_dir):
    # 5 ms after its release 200 mm above the plate the consignment has fallen 0.12 mm: there
    # is no rebound yet, and a calibration must not fit 0 mm for it
    snap = snapshot_dir / "consignment_small" / "snapshot.npz"
    drop = get_simulator("drop-horizontal").func
    with pytest.raises(ValueError, match="rebound_mm not reached: .* did not touch the plate"):
        drop({}, consignment=str(EXAMPLE), snapshot=str(snap), t_end_s=0.005)


def test_a_campaign_run_of_a_test_keeps_a_checkpoint_until_it_has_ended(snapshot_dir, tmp_path):
    # execute_run gives a resumable simulator its checkpoint: the 4 ms drop saves its run
    # (then fails as not reached: no touch yet); a second call with the same file takes the
    # run from it (a complete checkpoint: no stepping) to the same outcome; run_campaign
    # removes the file once the run has ended, done or failed for good
    from flexparcel.calibration import RunSpec, StudyStore, run_campaign
    from flexparcel.calibration.execution import _checkpoint_path, execute_run

    snap = snapshot_dir / "consignment_small" / "snapshot.npz"
    setup = {"consignment": str(EXAMPLE), "snapshot": str(snap), "t_end_s": 0.004}
    info = get_simulator("drop-horizontal")
    assert info.func.resumable
    path = tmp_path / "run.npz"
    args = ("drop-horizontal", info.version, setup, {}, (), (), None, str(path))
    first = execute_run(*args)
    assert not first["ok"] and "did not touch the plate" in first["error"]
    assert path.is_file()
    again = execute_run(*args)
    assert again["error"].splitlines()[0] == first["error"].splitlines()[0]
    assert again["wall_s"] < first["wall_s"]
    with StudyStore(tmp_path / "s.sqlite") as store:
        spec = RunSpec("drop-horizontal", info.version, setup, {})
        (key,) = store.add_design("design", "drop", [spec])
        ckpt = _checkpoint_path(store, key)
        assert ckpt.parent.name == "s.sqlite.runs"
        run_campaign(store, [key], workers=0, progress=False)
        assert store.get_runs([key])[0]["status"] == "failed"
        assert ckpt.parent.is_dir() and not ckpt.exists()


def test_conveyor_runs_a_study_scene_with_its_placements(snapshot_dir, tmp_path):
    """setup.scene: the scene file's belt, deflector and placements, names and all (the example
    design study's scene, 4 ms: the consignments have not reached the deflector yet)."""
    scene = str(ROOT / "examples" / "conveyor_design_scene.toml")
    snaps = tmp_path / "snaps"
    snaps.mkdir()
    shutil.copy(
        snapshot_dir / "consignment_small" / "snapshot.npz", snaps / "CONSIGNMENT_SMALL_20mm.npz"
    )
    conveyor = get_simulator("conveyor").func
    out = conveyor({"belt_speed": 2.0}, scene=scene, t_end_s=0.004, snapshot_dir=str(snaps))
    # the scene's placements: a at y = 0.1 m, b at y = -0.13 m, both at x = 0.07 m moving at
    # 2 m/s (4 ms: 8 mm on)
    assert out["a.final_y"] == pytest.approx(0.1, abs=1e-3)
    assert out["b.final_y"] == pytest.approx(-0.13, abs=1e-3)
    assert out["a.final_x"] == pytest.approx(0.078, abs=2e-3)
    assert out["group.peak_contact_force"] == 0.0
    with pytest.raises(ValueError, match="'consignments' and a 'scene'"):
        conveyor({}, scene=scene, consignments=["KPBW"], snapshot_dir=str(snaps))
