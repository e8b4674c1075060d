"""A miniature calibration study on the finite-element tests, end to end: the real drop
simulator on the 20 mm example consignment, a real SIGKILL of the campaign mid-way, no worker
left behind, and a resume that redoes no finished run and ends in ``summary.json``.

Marked slow: each 0.3 s drop of the example costs about 90 s (7,500 steps: the box rattles
in its pouch after the release), and the study runs six of them (``make slow``)."""

from __future__ import annotations

import json
import math
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flexparcel.calibration import StudyStore
from test_worker_lifetime import kill_controller_and_check_workers

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"

STUDY = """
version = 1
name = "mini-fe"
store = "study.sqlite"
output = "report"
random_state = 3

[execution]
workers = 2
retries = 1

[surrogate]
kernels = ["matern52"]
cv_folds = 2
holdout_fraction = 0.2
restarts = 1

[optimisation]
starts = 2

[validation]
reference_name = "table7"

[parameters.youngs_modulus]
bounds = [30, 300]
unit = "MPa"
scale = "log"

[experiments.drop]
simulator = "drop-horizontal"
setup = {{ consignment = "{example}", snapshot = "{snapshot}", t_end_s = 0.3 }}
parameters = ["youngs_modulus"]
design = {{ runs = 5 }}

[experiments.drop.targets]
rebound_mm = {{ value = 5.0, unit = "mm", reference = 4.5, label = "rebound_horizontal_mm" }}
"""


def _counts(store: Path) -> dict[str, int]:
    """Runs per status, read-only while the campaign writes (empty before the store exists)."""
    if not store.exists():
        return {}
    con = sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=5.0)
    try:
        return dict(con.execute("SELECT status, COUNT(*) FROM runs GROUP BY status").fetchall())
    except sqlite3.OperationalError:  # the schema is not written yet
        return {}
    finally:
        con.close()


@pytest.mark.slow
def test_fe_study_survives_sigkill_and_resumes_to_its_summary(tmp_path, snapshot_dir):
    snap = snapshot_dir / "consignment_small" / "snapshot.npz"
    study = tmp_path / "study.toml"
    study.write_text(STUDY.format(example=EXAMPLE, snapshot=snap))
    store = tmp_path / "study.sqlite"
    cmd = [sys.executable, "-m", "flexparcel.cli", "calibrate", str(study), "--no-progress"]
    proc = subprocess.Popen(cmd, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)  # fmt: skip
    try:
        # kill when a first run has finished and others are in flight (two workers)
        deadline = time.time() + 600
        while time.time() < deadline and proc.poll() is None:
            c = _counts(store)
            if c.get("done", 0) >= 1 and c.get("running", 0) >= 1:
                break
            time.sleep(0.5)
        assert proc.poll() is None, proc.stderr.read().decode()[-2000:]
    finally:
        kill_controller_and_check_workers(proc)  # the controller alone: its workers follow

    with StudyStore(store) as s:
        done_before = {r["run_key"] for r in s.all_runs() if r["status"] == "done"}
        in_flight = {r["run_key"] for r in s.all_runs() if r["status"] == "running"}
    assert done_before and in_flight

    res = subprocess.run(cmd, capture_output=True, text=True, timeout=1500)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "interrupted runs resumed" in res.stdout

    with StudyStore(store) as s:
        runs = {r["run_key"]: r for r in s.all_runs()}
        design = s.design_keys("design", "drop")
        assert len(design) == 5 and all(runs[k]["status"] == "done" for k in design)
        # nothing finished was redone; the runs killed in flight were, after an interrupted try
        assert all(len(s.attempts(k)) == 1 for k in done_before)
        for k in in_flight:
            assert [a["status"] for a in s.attempts(k)][0] == "interrupted"
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert 30.0 <= summary["optimum"]["youngs_modulus"] <= 300.0
    v = summary["validation"]["rebound_horizontal_mm"]
    assert math.isfinite(v["simulated"]) and v["simulated"] >= 0.0
    assert (v["target"], v["table7"]) == (5.0, 4.5)
    assert math.isclose(v["rel_error"], (v["simulated"] - 5.0) / 5.0)
    assert summary["run_counts"]["done_by_level_and_stage"]["single"] == {
        "design": 5, "validation": 1
    }  # fmt: skip
    assert summary["wall_s"]["runs"] > 0
