"""The benchmark file (``flexparcel bench``): what it records besides the cases' figures."""

from __future__ import annotations

import json
import os

import numba
import pytest

from flexparcel import bench


def test_benchmark_file_records_the_thread_settings(tmp_path, monkeypatch):
    # timings depend on numba's thread count and the cores: the file says what they were
    monkeypatch.setitem(bench.CASES, "probe", lambda quick, progress: {"case": "probe"})
    out = tmp_path / "bench.json"
    bench.run_benchmarks(["probe"], out)
    doc = json.loads(out.read_text())
    assert doc["results"] == [{"case": "probe"}]
    machine = doc["machine"]
    assert machine["cpu_count"] == os.cpu_count()
    assert machine["numba_threads"] == numba.get_num_threads() >= 1
    assert machine["omp_num_threads"] == os.environ.get("OMP_NUM_THREADS")


def test_convergence_case_resumes_from_its_finished_tests(tmp_path, monkeypatch):
    # kpbw-convergence writes each finished test to WORK/SIZEmm/TEST.json and does not run it
    # again: here every test of two sizes is finished, so nothing runs (a run would need the
    # scenario registry, replaced by one that fails), and the table holds the files' numbers
    # next to Table 7 (rel_error_table7 = (value - table 7) / table 7)
    from types import SimpleNamespace

    import flexparcel.scenarios.registry as registry

    monkeypatch.setattr(bench, "_convergence_snapshot", lambda size, work: (None, f"s{size:g}"))
    monkeypatch.setattr(registry, "get_scenario", lambda *a, **k: 1 / 0)
    values = {
        "swing": {"first_swing_mm": 128.0 * 1.1, "second_swing_mm": None},
        "drop-vertical": {"rebound_mm": 6.2},
        "drop-horizontal": {"rebound_mm": 4.5 / 2},
    }
    for size in (25, 10):
        for test, responses in values.items():
            path = tmp_path / f"{size}mm" / f"{test}.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(
                json.dumps(
                    {
                        **responses,
                        "wall_s": 2.0,
                        "steps": 3,
                        "newton_iterations": 4,
                        "simulated_s": 0.3,
                    }
                )
            )
    r = bench.run_case("kpbw-convergence", sizes_mm=(25.0, 10.0), work=tmp_path)
    assert [row["element_size_mm"] for row in r["rows"]] == [25.0, 10.0]
    row = SimpleNamespace(
        **{k.replace("-", "_").replace(":", "__"): v for k, v in r["rows"][1].items()}
    )
    assert row.swing__first_swing_mm["rel_error_table7"] == pytest.approx(0.1)
    assert row.swing__second_swing_mm["simulated"] is None
    assert row.swing__second_swing_mm["rel_error_table7"] is None
    assert row.drop_vertical__rebound_mm["rel_error_table7"] == pytest.approx(0.0)
    assert row.drop_horizontal__rebound_mm["table7"] == 4.5
    assert row.drop_horizontal__rebound_mm["real"] == 4.0
    assert r["wall_s"] == pytest.approx(12.0) and r["steps"] == 18


def test_phases_other_is_measured_against_the_basis_of_the_phases():
    # one process: the rest of its wall time; a grouped run sums the phases over its worker
    # processes, so the rest is taken from the workers' busy time, never a negative number
    from flexparcel.bench import _phases

    phases = dict(elements=4.0, contact=1.0, matrix=1.0, factor=2.0, solve=1.0)
    one = _phases({"wall_s": {**phases, "total": 10.0}})
    assert one["other"] == pytest.approx(1.0) and one["elements"] == 4.0
    grouped = {"wall_s": {**phases, "total": 6.0}, "groups": {"worker_busy_s": [5.0, 4.5]}}
    assert _phases(grouped)["other"] == pytest.approx(0.5)
    assert "other" not in _phases({"wall_s": phases})
