"""Resumable campaigns: a real SIGKILL mid-campaign, and Dask versus local execution."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flexparcel.calibration import Study, StudyStore

N_RUNS = 12
DELAY_S = 0.5


def write_study(folder: Path, *, setup: str, runs: int, screening: bool = False) -> Path:
    text = f"""
version = 1
name = "resume"
store = "study.sqlite"
output = "report"
random_state = 7

[execution]
workers = 2
retries = 1

[parameters.youngs_modulus]
bounds = [200, 2000]
unit = "MPa"
scale = "log"

[parameters.damping_ratio]
bounds = [1e-4, 5e-3]
unit = "s"

[parameters.contact_stiffness]
bounds = [100, 1000]
unit = "N/mm"

[parameters.contact_damping]
bounds = [0.1, 1.0]
unit = "Ns/mm"

[experiments.swing]
simulator = "analytic"
setup = {{ mode = "swing", {setup} }}
parameters = ["youngs_modulus", "damping_ratio"]
design = {{ runs = {runs} }}
targets = {{ first_swing_mm = 97.2, second_swing_mm = 35.0 }}

[experiments.drop]
simulator = "analytic"
setup = {{ mode = "drop" }}
parameters = ["youngs_modulus", "damping_ratio", "contact_stiffness", "contact_damping"]
design = {{ runs = {runs} }}
targets = {{ rebound_mm = 5.8 }}
"""
    if screening:
        text += '[experiments.drop.screening]\ndesign = "full-factorial"\n'
    path = folder / "study.toml"
    path.write_text(text)
    return path


def read_log(path: Path):
    starts, ends = {}, []
    if not path.exists():
        return starts, ends
    for line in path.read_text().splitlines():
        kind, digest, t = line.split()
        if kind == "start":
            starts.setdefault(digest, []).append(float(t))
        else:
            ends.append((digest, float(t)))
    return starts, ends


def start_design_campaign(folder: Path):
    """``flexparcel calibrate --stage design`` of a study of slow logged runs, started in a
    new session (its own process group); returns the process, the command, its environment
    and the call log."""
    log = folder / "calls.log"
    study = write_study(folder, setup=f'delay_s = {DELAY_S}, log_file = "{log}"', runs=N_RUNS)
    cmd = [sys.executable, "-m", "flexparcel.cli", "calibrate", str(study), "--stage",
           "design", "--no-progress"]  # fmt: skip
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(cmd, start_new_session=True, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)  # fmt: skip
    return proc, cmd, env, log


def wait_for(proc, log: Path, condition, timeout_s: float = 90.0) -> bool:
    """Poll the call log until ``condition(starts, ends)`` holds (True), or the process ends
    or the time is up (False)."""
    deadline = time.time() + timeout_s
    while time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)
        if condition(*read_log(log)):
            return True
    return False


def test_sigkill_mid_campaign_then_resume_loses_and_repeats_nothing(tmp_path):
    """Kill the whole campaign (controller and worker processes) with SIGKILL mid-way, resume.

    Every simulator call logs ``start`` and, when it completes, ``end``. The kill is timed to
    land while runs are sleeping (>= 0.1 s after the last completion, so its result is committed,
    and >= 0.15 s before the in-flight runs could complete), because the one window no store can
    close is between a simulator finishing and its result being committed: a result lost there
    is correctly re-run, but would show up here as a duplicate ``end``.
    """
    proc, cmd, env, log = start_design_campaign(tmp_path)
    killed_at = None

    def mid_sleep(starts, ends) -> bool:
        if len(ends) < 4:
            return False
        now = time.time()
        ended = {d for d, _ in ends}
        open_ages = [now - ts[-1] for d, ts in starts.items() if d not in ended]
        last_end = max(t for _, t in ends)
        return now - last_end > 0.1 and bool(open_ages) and max(open_ages) < DELAY_S - 0.15

    try:
        if wait_for(proc, log, mid_sleep):
            os.killpg(proc.pid, signal.SIGKILL)  # controller and its worker processes
            killed_at = len(read_log(log)[1])
    finally:
        if proc.poll() is None and killed_at is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert killed_at is not None, proc.stderr.read().decode()[-2000:]
    assert proc.returncode == -signal.SIGKILL

    store_path = tmp_path / "study.sqlite"
    with StudyStore(store_path) as store:
        keys = store.design_keys("design", "swing")
        counts = store.status_counts(keys)
        # Killed mid-way: some runs done, some not; every completed call reached the store.
        assert 4 <= counts["done"] < N_RUNS
        assert counts["done"] == killed_at
        assert counts["running"] >= 1  # in flight when killed

    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "interrupted runs resumed" in res.stdout

    starts, ends = read_log(log)
    digests = [d for d, _ in ends]
    assert len(digests) == N_RUNS  # the swing design (the logged one) has 12 points ...
    assert len(set(digests)) == N_RUNS  # ... and every one completed exactly once
    assert sum(len(v) for v in starts.values()) > len(digests)  # killed calls were restarted
    with StudyStore(store_path) as store:
        runs = store.get_runs(store.design_keys("design", "swing"))
        assert all(r["status"] == "done" for r in runs)
        assert any(a["status"] == "interrupted" for r in runs for a in store.attempts(r["run_key"]))


@pytest.mark.skipif(not hasattr(signal, "SIGUSR1"), reason="SIGUSR1 is POSIX")
def test_sigusr1_drains_the_campaign_then_resume_repeats_nothing(tmp_path):
    """SIGUSR1 to the controller mid-campaign: no new run starts, the runs in flight finish
    and are recorded, the command exits with 75; resumed, the campaign runs the rest, each
    run started exactly once over both commands (nothing lost, nothing repeated)."""
    from flexparcel.cli.calibrate_cmd import DRAINED_STATUS

    proc, cmd, env, log = start_design_campaign(tmp_path)

    def in_flight(starts, ends) -> bool:
        return len(ends) >= 2 and bool(set(starts) - {d for d, _ in ends})

    try:
        signalled = wait_for(proc, log, in_flight)
        if signalled:
            proc.send_signal(signal.SIGUSR1)  # the controller alone, not its workers
        err = proc.communicate(timeout=60)[1].decode()
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=30)
    assert signalled, err[-2000:]
    assert proc.returncode == DRAINED_STATUS, err[-2000:]
    assert "drained on SIGUSR1" in err and "left pending" in err
    starts, ends = read_log(log)
    # every run that started finished: the drain lost none
    assert sorted(starts) == sorted(d for d, _ in ends)
    with StudyStore(tmp_path / "study.sqlite") as store:
        counts = store.status_counts(store.design_keys("design", "swing"))
        assert counts.get("running", 0) == 0
        assert counts["done"] == len(ends) < N_RUNS

    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    starts, ends = read_log(log)
    assert len(ends) == N_RUNS and all(len(t) == 1 for t in starts.values())


def test_time_limit_starts_no_run_that_would_end_after_it(tmp_path):
    """A study with a time limit starts a run only while its measured cost (the median wall
    time of the finished runs of its kind) fits in what is left. With a limit of 1 ms the
    first run, of a kind never run, has no cost yet and starts; the second has the first's
    cost (DELAY_S and more) and does not: the campaign stops with the rest pending. A study
    without a limit then finishes them, starting each run once."""
    from flexparcel.calibration import CampaignDrained

    log = tmp_path / "calls.log"
    study = write_study(tmp_path, setup=f'delay_s = {DELAY_S}, log_file = "{log}"', runs=N_RUNS)
    with Study(study, workers=0, progress=False, time_limit_s=1e-3) as st:
        with pytest.raises(CampaignDrained, match="drained at the time limit") as info:
            st.design()
        (run,) = [r for r in st.store.all_runs() if r["status"] == "done"]
        assert run["wall_s"] >= DELAY_S
    starts, ends = read_log(log)
    assert len(starts) == len(ends) == 1
    assert info.value.pending == 2 * N_RUNS - 1 and info.value.finished == 0
    with Study(study, workers=0, progress=False) as st:
        st.design()
    starts, ends = read_log(log)
    assert len(ends) == N_RUNS and all(len(t) == 1 for t in starts.values())
    with pytest.raises(ValueError, match="time_limit_s must be > 0 s"):
        Study(study, time_limit_s=0.0)


def test_time_limit_takes_a_stated_cost_for_a_kind_never_run(tmp_path, capsys):
    # estimated_run_s stands in for the cost of a kind of run with no finished run yet: with
    # one of 10 s and a limit of 5 s not even the first run starts
    from flexparcel.calibration import CampaignDrained

    log = tmp_path / "calls.log"
    study = write_study(tmp_path, setup=f'delay_s = {DELAY_S}, log_file = "{log}"', runs=N_RUNS)
    text = study.read_text().replace(
        f"design = {{ runs = {N_RUNS} }}\ntargets = {{ first_swing_mm",
        f"design = {{ runs = {N_RUNS} }}\nestimated_run_s = 10\ntargets = {{ first_swing_mm",
    )
    assert "estimated_run_s = 10" in text
    study.write_text(text)
    with Study(study, workers=0, progress=False, time_limit_s=5.0) as st:
        with pytest.raises(CampaignDrained, match="drained at the time limit.* 24 left"):
            st.design()
    assert "the next run takes about 10 s, 5 s are left" in capsys.readouterr().err
    assert read_log(log) == ({}, [])


@pytest.mark.parametrize(
    "text, seconds",
    [
        ("2h", 7200.0),
        ("1h30m", 5400.0),
        ("90m", 5400.0),
        ("45s", 45.0),
        ("600", 600.0),
        ("1.5h", 5400.0),
    ],  # fmt: skip
)
def test_time_limit_durations(text, seconds):
    from flexparcel.cli.calibrate_cmd import parse_duration

    assert parse_duration(text) == seconds


@pytest.mark.parametrize("text", ["", "0", "2x", "h", "2h30", "-5m"])
def test_time_limit_bad_durations_name_the_option(text):
    from flexparcel.cli.calibrate_cmd import parse_duration

    with pytest.raises(ValueError, match="--time-limit .*expected a duration > 0"):
        parse_duration(text)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_dask_cluster_gives_the_same_study_as_local_processes(tmp_path):
    from distributed import LocalCluster

    results = {}
    for mode in ("local", "dask"):
        folder = tmp_path / mode
        folder.mkdir()
        path = write_study(folder, setup="noise = 0.003", runs=6, screening=True)
        if mode == "local":
            with Study(path, workers=1, progress=False) as st:
                st.screen()
                st.design()
        else:
            with LocalCluster(
                n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
            ) as cluster:
                with Study(path, scheduler=cluster.scheduler_address, progress=False) as st:
                    st.screen()
                    st.design()
                    assert st.campaigns["design"].executor.startswith("dask")
        with StudyStore(folder / "study.sqlite") as store:
            results[mode] = {
                "screening": store.get_result("screening", "drop")["significant"],
                "runs": {r["run_key"]: r["responses"] for r in store.all_runs()},
                "status": store.status_counts(),
                "design": [store.design_keys("design", e) for e in ("swing", "drop")],
            }
    assert results["dask"] == results["local"]
    assert results["local"]["status"]["done"] == 16 + 6 + 6  # 2^4 screening + two designs
    assert results["local"]["screening"] == [
        "youngs_modulus",
        "contact_stiffness",
        "contact_damping",
    ]
