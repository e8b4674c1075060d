"""Progress bars: the ETA after a resume and while a step is stuck, the cold-cache notice,
and the atomic writes of pictures and tables."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from flexparcel.cli.progress import (
    PhaseProgress,
    RateWindow,
    SimulationProgress,
    cold_kernels,
    compile_minutes,
    format_duration,
)


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_eta_after_a_resume_counts_only_this_process():
    # a 2 s run resumed at t = 1.9 s: 0.01 s simulated per wall second from here on
    w = RateWindow(window_s=30.0)
    wall = 0.0
    t = 1.9
    for _ in range(100):
        wall += 1.0
        t += 0.001
        w.add(wall, t)
    eta = w.eta(2.0, wall)
    left = (2.0 - t) / 0.001  # 0.1 s left at 1 ms per wall second
    assert eta == pytest.approx(left, rel=1e-6)  # not (2.0 - 1.9) * wall / t, the naive one


def test_eta_grows_while_a_step_is_stuck():
    w = RateWindow(window_s=10.0)
    for k in range(1, 21):
        w.add(float(k), 0.01 * k)  # 0.01 s per wall second
    assert w.eta(1.0, 20.0) == pytest.approx(80.0)
    # the next step does not finish: 60 s later the rate is what the last 60 s gave
    stuck = w.eta(1.0, 80.0)
    assert stuck > 4 * 80.0
    assert w.idle(80.0) == pytest.approx(60.0)


def test_window_forgets_an_old_fast_start():
    w = RateWindow(window_s=10.0)
    w.add(0.0, 0.0)
    w.add(1.0, 0.5)  # fast at first (e.g. before contact)
    for k in range(2, 40):
        w.add(float(k), 0.5 + 0.001 * (k - 1))  # then slow
    assert w.rate(39.0) == pytest.approx(0.001, rel=0.05)


def test_simulation_progress_bar_shows_eta_and_a_stuck_step():
    pytest.importorskip("tqdm")
    clock = Clock()
    out = io.StringIO()
    bar = SimulationProgress("swing KPBW", file=out, refresh_s=0, clock=clock)
    for k in range(1, 11):
        clock.now += 1.0
        bar(0.7 + 0.01 * k, 1.4)
    clock.now += 30.0
    text = bar.status()
    assert "t = 0.8000/1.4 s" in text and "step running for 0:30" in text
    bar.done()
    assert "swing KPBW" in out.getvalue() and "ETA" in out.getvalue()
    bar.done()  # idempotent


def test_phase_progress_one_bar_per_phase_with_an_upper_bound():
    pytest.importorskip("tqdm")
    from flexparcel.consignments.assembly import AssemblySettings

    clock = Clock()
    out = io.StringIO()
    bar = PhaseProgress("assemble BW", settings=AssemblySettings(), file=out, refresh_s=0,
                        clock=clock)  # fmt: skip
    for k in range(1, 5):
        clock.now += 1.0
        bar("opening", 0.005 * k)
    assert bar.t_end == AssemblySettings().max_opening_time
    assert "ETA <= " in bar.status()
    clock.now += 5.0
    bar("closing", 0.05)
    clock.now += 1.0
    bar("settling", 0.1)
    assert bar.t_end == pytest.approx(0.05 + AssemblySettings().max_settle_time)
    bar.done()
    text = out.getvalue()
    assert "assemble BW opening" in text and "assemble BW settling" in text


def test_disabled_bar_prints_nothing():
    out = io.StringIO()
    bar = SimulationProgress("x", enabled=False, file=out)
    bar(0.5, 1.0)
    bar.done()
    assert out.getvalue() == ""


def test_format_duration():
    assert format_duration(75) == "1:15"
    assert format_duration(3725) == "1:02:05"
    assert format_duration(None) == "?"


def test_cold_cache_is_found_by_missing_index_files(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "kern.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef a(x):\n    return x\n\n"
        "@njit(cache=True, fastmath=True)\ndef b(x):\n    return x\n"
    )
    assert cold_kernels(pkg) == (2, 2)
    (pkg / "__pycache__").mkdir()
    (pkg / "__pycache__" / "kern.a-3.py311.nbi").write_bytes(b"")
    assert cold_kernels(pkg) == (1, 2)
    cache = tmp_path / "cache"
    (cache / "x").mkdir(parents=True)
    (cache / "x" / "kern.b-7.py311.nbi").write_bytes(b"")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    assert cold_kernels(pkg) == (1, 2)
    assert compile_minutes(95) >= 3 and compile_minutes(1) == 1


def test_first_run_says_it_compiles(tmp_path, monkeypatch, capsys):
    from flexparcel.cli import progress

    monkeypatch.setattr(progress, "cold_kernels", lambda package=None: (90, 95))
    assert progress.announce_compilation()
    assert "compiling kernels (first run, about" in capsys.readouterr().out
    monkeypatch.setattr(progress, "cold_kernels", lambda package=None: (0, 95))
    assert not progress.announce_compilation()


def _leftovers(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if p.name.startswith(".")]


def test_pictures_are_written_atomically(tmp_path):
    pytest.importorskip("matplotlib")
    import numpy as np

    from flexparcel.viz import plot_time_series

    path = plot_time_series(tmp_path / "curve.png", np.arange(3.0), {"x": np.arange(3.0)},
                            ylabel="x [m]", title="x")  # fmt: skip
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not _leftovers(tmp_path)


def test_atomic_path_keeps_the_old_file_when_the_writer_fails(tmp_path):
    from flexparcel.io.atomic import atomic_path

    target = tmp_path / "animation.gif"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        assert tmp.suffix == ".gif" and tmp.parent == tmp_path
        tmp.write_bytes(b"half")
        raise RuntimeError("writer failed")
    assert target.read_bytes() == b"old"
    assert not _leftovers(tmp_path)
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new"


def test_select_tables_are_written_atomically(tmp_path, monkeypatch):
    from flexparcel.selection import export

    calls = []
    real = export.write_atomic
    monkeypatch.setattr(export, "write_atomic",
                        lambda p, data: calls.append(Path(p).name) or real(p, data))  # fmt: skip
    export.write_csv(tmp_path / "t.csv", ["a", "b"], [[1, 2]])
    assert calls == ["t.csv"]
    assert (tmp_path / "t.csv").read_bytes() == b"a,b\r\n1,2\r\n"


def test_survey_schema_and_consignment_files_are_written_atomically(tmp_path, monkeypatch):
    # the Python API's writers too, not only the select command's wrapping of them
    from flexparcel.consignments.spec import (
        ConsignmentSpec,
        read_consignment_toml,
        write_consignment_toml,
    )
    from flexparcel.io import atomic
    from flexparcel.selection import make_synthetic_survey, write_schema, write_survey_csv

    calls = []
    real = atomic.write_atomic
    monkeypatch.setattr(atomic, "write_atomic",
                        lambda p, data: calls.append(Path(p).name) or real(p, data))  # fmt: skip
    survey, _ = make_synthetic_survey(random_state=1)
    write_survey_csv(survey, tmp_path / "survey.csv")
    write_schema(survey.schema, tmp_path / "schema.toml")
    spec = ConsignmentSpec("C1", "polybag", 300.0, 200.0, 40.0, "rigid", 200.0, 150.0, 30.0,
                           500.0)  # fmt: skip
    write_consignment_toml(spec, tmp_path / "c.toml")
    assert calls == ["survey.csv", "schema.toml", "c.toml"]
    assert read_consignment_toml(tmp_path / "c.toml") == spec
    rows = (tmp_path / "survey.csv").read_text().splitlines()
    assert len(rows) == len(survey) + 1
    assert not _leftovers(tmp_path)
