"""The benchmark file (``flexparcel bench``): what it records besides the cases' figures."""

from __future__ import annotations

import json
import os

import numba

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
