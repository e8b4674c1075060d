"""Workers die with their campaign, and a crashed worker charges no innocent run.

A campaign's controller killed with SIGKILL (alone, not its process group) must take its
worker processes along (flexparcel.io.lifetime.die_with_parent); a worker process that dies
while several runs are in flight must not cost those runs an attempt."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import psutil

from flexparcel.calibration import StudyStore
from flexparcel.calibration.execution import run_campaign
from flexparcel.calibration.store import RunSpec
from test_calibration_resume import read_log, write_study


def _gone(pids: list[int], within_s: float) -> bool:
    """Whether every process in ``pids`` has ended (or is a zombie) within ``within_s``."""
    deadline = time.time() + within_s
    while time.time() < deadline:
        alive = []
        for pid in pids:
            try:
                if psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                    alive.append(pid)
            except psutil.NoSuchProcess:
                pass
        if not alive:
            return True
        time.sleep(0.1)
    return False


def kill_controller_and_check_workers(proc: subprocess.Popen) -> None:
    """SIGKILL the campaign's controller alone (not its process group) and assert that its
    worker processes end too; whatever is left of the group is killed afterwards."""
    try:
        workers = [p.pid for p in psutil.Process(proc.pid).children(recursive=True)]
        assert workers, proc.stderr.read().decode()[-2000:] if proc.poll() else "no workers"
        os.kill(proc.pid, signal.SIGKILL)  # the controller alone, not its process group
        proc.wait(timeout=10)
        # the kernel's parent-death signal ends them at once; the polling fallback in 0.5 s
        assert _gone(workers, within_s=5.0), f"workers {workers} outlived their campaign"
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def test_sigkill_of_the_campaign_ends_its_workers(tmp_path):
    log = tmp_path / "calls.log"
    study = write_study(tmp_path, setup=f'delay_s = 5.0, log_file = "{log}"', runs=6)
    cmd = [sys.executable, "-m", "flexparcel.cli", "calibrate", str(study), "--stage",
           "design", "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)  # fmt: skip
    try:
        deadline = time.time() + 60
        while time.time() < deadline and len(read_log(log)[0]) < 2:  # two runs started
            time.sleep(0.05)
    finally:
        kill_controller_and_check_workers(proc)


SIMULATOR = """
import os, time

def run(params, **setup):
    if params["x"] > 0.9:
        os._exit(70)  # a solver that takes its process down, every time
    time.sleep(0.3)
    return {"y": params["x"]}
"""


def test_a_crashed_worker_charges_no_innocent_run(tmp_path):
    # two workers: the crasher takes the pool down while an innocent run is in flight; both
    # run again alone: the innocent one succeeds on its first charged attempt, the crasher
    # crashes alone each time and exhausts its 1 + retries attempts
    (tmp_path / "sim.py").write_text(SIMULATOR)
    name = f"{tmp_path / 'sim.py'}:run"
    with StudyStore(tmp_path / "s.sqlite") as store:
        xs = (0.1, 0.95, 0.2, 0.3)
        keys = store.add_design("d", "e", [RunSpec(name, "1", {}, {"x": x}) for x in xs])
        rep = run_campaign(store, keys, workers=2, retries=1, progress=False)
        runs = dict(zip(xs, store.get_runs(keys), strict=True))
    assert runs[0.95]["status"] == "failed" and runs[0.95]["attempts"] == 2
    for x in (0.1, 0.2, 0.3):
        assert runs[x]["status"] == "done" and runs[x]["attempts"] == 1, x
    assert rep.failed == [keys[1]]
