"""The SQLite study store and campaign execution: keys, schema checks, failures, retries."""

from __future__ import annotations

import math
import sqlite3

import pytest

from flexparcel.calibration import (
    RunSpec,
    StudyStore,
    StudyStoreError,
    register_simulator,
    run_campaign,
)
from flexparcel.calibration.store import run_key


@register_simulator("test-nan", replace=True)
def _nan_simulator(params, **setup):
    return {"y": math.nan}


@register_simulator("test-missing", replace=True)
def _missing_simulator(params, **setup):
    return {"other": 1.0}


class _Outcome(ValueError):
    retryable = False  # as flexparcel.scenarios.simulators.ResponseNotReached


@register_simulator("test-not-reached", replace=True)
def _not_reached_simulator(params, **setup):
    raise _Outcome("rebound_mm not reached: did not touch the plate")


def swing(E, beta=1e-3, **setup):
    return RunSpec(
        "analytic",
        "1",
        {"mode": "swing", **setup},
        {"youngs_modulus": float(E), "damping_ratio": beta},
    )


def test_run_key_is_canonical_and_exact():
    k = run_key("analytic", "1", {"mode": "swing"}, {"a": 1.0, "b": 2.0})
    assert k == run_key("analytic", "1", {"mode": "swing"}, {"b": 2.0, "a": 1})
    assert k != run_key("analytic", "1", {"mode": "swing"}, {"a": 1.0 + 2**-52, "b": 2.0})
    assert k != run_key("analytic", "2", {"mode": "swing"}, {"a": 1.0, "b": 2.0})
    assert k != run_key("analytic", "1", {"mode": "drop"}, {"a": 1.0, "b": 2.0})


def test_store_schema_version_is_checked(tmp_path):
    path = tmp_path / "s.sqlite"
    StudyStore(path).close()
    con = sqlite3.connect(path)
    con.execute("UPDATE meta SET value='99' WHERE key='schema_version'")
    con.commit()
    con.close()
    with pytest.raises(StudyStoreError, match="schema version 99.*reads version 1"):
        StudyStore(path)


def test_foreign_files_are_refused(tmp_path):
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not sqlite at all" * 100)
    with pytest.raises(StudyStoreError, match="not a flexparcel study store"):
        StudyStore(junk)
    other = tmp_path / "other.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE t (x)")
    con.commit()
    con.close()
    with pytest.raises(StudyStoreError, match="not a flexparcel study store"):
        StudyStore(other)


def test_designs_share_runs_and_conflicts_are_refused(tmp_path):
    with StudyStore(tmp_path / "s.sqlite") as store:
        k1 = store.add_design("design", "swing", [swing(500), swing(900)])
        k2 = store.add_design("validation", "swing", [swing(900)])
        assert k2[0] == k1[1]  # the same simulation is one run
        assert len(store.all_runs()) == 2
        assert store.add_design("design", "swing", [swing(500), swing(900)]) == k1
        with pytest.raises(StudyStoreError, match="different run at position 1"):
            store.add_design("design", "swing", [swing(500), swing(901)])


def test_campaign_lock_is_exclusive(tmp_path):
    a, b = StudyStore(tmp_path / "s.sqlite"), StudyStore(tmp_path / "s.sqlite")
    a.acquire_lock()
    with pytest.raises(StudyStoreError, match="in use"):
        b.acquire_lock()
    a.release_lock()
    b.acquire_lock()
    b.close()
    a.close()


def test_failed_run_is_recorded_and_retried(tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    with StudyStore(tmp_path / "s.sqlite") as store:
        keys = store.add_design(
            "design", "swing", [swing(E, fail_first_dir=str(marks)) for E in (300, 600, 1200)]
        )
        rep = run_campaign(store, keys, workers=0, retries=1, progress=False)
        assert rep.complete and rep.succeeded == 3 and rep.attempts == 6
        for key in keys:
            run = store.get_runs([key])[0]
            assert run["status"] == "done" and run["attempts"] == 2
            log = store.attempts(key)
            assert [a["status"] for a in log] == ["failed", "done"]
            assert "deliberate first-attempt failure" in log[0]["error"]
        # Done runs are never run again.
        rep = run_campaign(store, keys, workers=0, progress=False)
        assert rep.already_done == 3 and rep.attempts == 0


def test_permanent_failures_stay_visible_until_retried(tmp_path):
    with StudyStore(tmp_path / "s.sqlite") as store:
        bad = RunSpec("analytic", "1", {"mode": "bogus"}, {"youngs_modulus": 500.0})
        nan = RunSpec("test-nan", "1", {}, {"a": 1.0})
        missing = RunSpec("test-missing", "1", {}, {"a": 1.0})
        keys = store.add_design("design", "e", [bad, nan, missing])
        expect = {keys[2]: ("y",)}
        rep = run_campaign(store, keys, workers=0, retries=2, expect=expect, progress=False)
        assert sorted(rep.failed) == sorted(keys) and rep.attempts == 9
        runs = {r["run_key"]: r for r in store.get_runs(keys)}
        assert all(r["status"] == "failed" and r["attempts"] == 3 for r in runs.values())
        assert "mode must be one of" in runs[keys[0]]["error"]
        assert "non-finite y = nan" in runs[keys[1]]["error"]
        assert "returned no response 'y'" in runs[keys[2]]["error"]
        assert runs[keys[1]]["responses"] is None  # never a NaN written as a result
        # Exhausted: a new campaign leaves them alone unless asked to retry.
        rep = run_campaign(store, keys, workers=0, retries=2, expect=expect, progress=False)
        assert rep.attempts == 0 and len(rep.failed) == 3
        rep = run_campaign(store, keys[:1], workers=0, retries=0, retry_failed=True, progress=False)
        assert rep.attempts == 1
        assert store.get_runs(keys[:1])[0]["attempts"] == 4


def test_crashed_worker_process_is_recorded_and_retried(tmp_path):
    """A worker killed mid-run (os._exit, like a segfault) breaks the process pool; the run is
    recorded as failed with the reason, a fresh pool is started and the run retried."""
    marks = tmp_path / "marks"
    marks.mkdir()
    with StudyStore(tmp_path / "s.sqlite") as store:
        keys = store.add_design(
            "design", "swing", [swing(400, crash_first_dir=str(marks)), swing(800)]
        )
        rep = run_campaign(store, keys, workers=1, retries=1, progress=False)
        assert rep.complete, [store.get_runs([k])[0]["error"] for k in rep.failed]
        run = store.get_runs(keys[:1])[0]
        assert run["status"] == "done" and run["attempts"] == 2
        assert "worker process died" in store.attempts(keys[0])[0]["error"]
        assert all(r["status"] == "done" for r in store.get_runs(keys))


def test_a_failure_that_is_the_simulators_outcome_is_not_retried(tmp_path):
    # a response not reached is the model's outcome: every attempt would cost a whole FE run
    # and end the same, so the run fails at once, and a resumed campaign leaves it failed
    from flexparcel.calibration.execution import NOT_RETRIED
    from flexparcel.scenarios.simulators import ResponseNotReached

    assert ResponseNotReached.retryable is False
    with StudyStore(tmp_path / "s.sqlite") as store:
        keys = store.add_design("design", "e", [RunSpec("test-not-reached", "1", {}, {"a": 1.0})])
        rep = run_campaign(store, keys, workers=0, retries=2, progress=False)
        assert rep.failed == keys and rep.attempts == 1
        run = store.get_runs(keys)[0]
        assert run["status"] == "failed" and run["attempts"] == 1
        assert run["error"].startswith(NOT_RETRIED + "_Outcome: rebound_mm not reached")
        rep = run_campaign(store, keys, workers=0, retries=2, progress=False)
        assert rep.attempts == 0 and rep.failed == keys
        # asked to, a campaign runs it again (once: it is still the outcome)
        rep = run_campaign(store, keys, workers=0, retries=2, retry_failed=True, progress=False)
        assert rep.attempts == 1 and store.get_runs(keys)[0]["attempts"] == 2
