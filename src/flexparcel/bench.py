"""Named benchmark cases for ``flexparcel bench``.

Each case runs a full simulation and returns a JSON-ready dict with at least ``case``,
``simulated_s``, ``wall_s``, ``dof_count``, ``steps``, ``newton_iterations``; speed is reported as
simulated seconds per wall second and as the ratio to the paper's RecurDyn time (4 cores).
"""

from __future__ import annotations

import json
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np

from flexparcel.integrate.dynamic import WALL_PHASES

__all__ = [
    "CASES",
    "DEFAULT_CASES",
    "RECURDYN_CONVEYOR_WALL_S",
    "run_case",
    "run_benchmarks",
    "conveyor_scaling",
    "plot_scaling",
]


def _solver_name() -> str:
    """The linear solver backend the default options pick on this installation."""
    from flexparcel.integrate.linear import make_linear_solver

    return make_linear_solver("auto").name


def _phases(stats: dict) -> dict:
    """Wall time [s] per phase of the Newton iterations (WALL_PHASES), and the rest ("other":
    predictor, step control, recording) as measured against the total: the run's wall time,
    or for a grouped run (phases summed over its worker processes) the workers' busy time."""
    w = stats["wall_s"]
    phases = {k: float(w.get(k, 0.0)) for k in WALL_PHASES}
    busy = (stats.get("groups") or {}).get("worker_busy_s")
    total = sum(busy) if busy else w.get("total")
    if total is not None:
        phases["other"] = float(total) - sum(phases.values())
    return phases


def _sheet_swing(quick: bool = False, progress=None) -> dict:
    from flexparcel.scenarios.sheet_swing import SheetSwing, sheet_swing_model
    from flexparcel.simulate import simulate

    case = SheetSwing(t_end=0.1) if quick else SheetSwing()
    model, _ = sheet_swing_model(case)
    # JIT compilation is a one-off per installation (numba caches it); measure warm
    warm_model, _ = sheet_swing_model(SheetSwing(element_size=0.1, t_end=0.01))
    simulate(warm_model, 0.01)
    t0 = time.perf_counter()
    res = simulate(model, case.t_end, dt_out=case.t_end / 140, progress=progress)
    wall = time.perf_counter() - t0
    st = res.stats
    recurdyn_s = 384.0 * case.t_end / 1.4
    return {
        "case": "sheet-swing",
        "element_size_mm": case.element_size * 1e3,
        "linear_solver": _solver_name(),
        "description": "275x200 mm sheet, 10 mm quads, E=926 MPa, nu=0.1, beta=1.71e-3 s, "
        "t=0.3 mm, 40 g, 20 mm clamped, released horizontal under gravity",
        "simulated_s": case.t_end,
        "wall_s": wall,
        "dof_count": model.dof_count,
        "node_count": model.node_count,
        "triangle_count": sum(len(g.triangles) for g in model.element_groups if g.kind == "shell"),
        "steps": st["steps"],
        "rejected_steps": st["rejected_steps"],
        "newton_iterations": st["newton_iterations"],
        "tangent_assemblies": st["tangent_assemblies"],
        "factorizations": st["factorizations"],
        "symbolic_analyses": st["symbolic_analyses"],
        "phase_wall_s": _phases(st),
        "simulated_s_per_wall_s": case.t_end / wall,
        "recurdyn_wall_s": recurdyn_s,
        "speedup_vs_recurdyn": recurdyn_s / wall,
    }


_FRICTION_MODEL = "stick model, k_t = c (ContactLaw.with_stick_model)"


def _envelope_drop(quick: bool = False, progress=None) -> dict:
    from flexparcel.scenarios.consignment_tests import consignment_options
    from flexparcel.scenarios.envelope_drop import EnvelopeDrop, envelope_drop_model
    from flexparcel.simulate import ModelStepper, simulate

    case = EnvelopeDrop(drop_height=0.02, t_end=0.1) if quick else EnvelopeDrop()
    model, box, _ = envelope_drop_model(case)
    warm, _, _ = envelope_drop_model(EnvelopeDrop(element_size=0.1, drop_height=0.005))
    simulate(warm, 0.02)
    # phases: free flight until the envelope's bottom reaches the plate, the impact (50 ms),
    # then settling; one stepper goes on through them (a fresh integrator per phase would
    # start each from consistent accelerations and dt_initial, which the test does not do),
    # so its statistics run on and each phase's are differences
    t_touch = float(np.sqrt(2.0 * case.drop_height / 9.81))
    bounds = [0.0, min(t_touch, case.t_end), min(t_touch + 0.05, case.t_end), case.t_end]
    names = ["free_flight", "impact", "settling"]
    stepper = ModelStepper(model, consignment_options())
    phases = {}
    state = None
    counts = ("steps", "rejected_steps", "newton_iterations", "factorizations",
              "symbolic_analyses")  # fmt: skip
    seen = dict.fromkeys(counts, 0)
    seen_wall = dict.fromkeys(WALL_PHASES, 0.0)
    wall = 0.0
    for name, t0, t1 in zip(names, bounds[:-1], bounds[1:], strict=True):
        if t1 <= t0:
            continue
        w0 = time.perf_counter()
        res = simulate(model, t1, dt_out=(t1 - t0) / 10, state=state, progress=progress,
                       stepper=stepper)  # fmt: skip
        w = time.perf_counter() - w0
        wall += w
        state, st = res.final_state, res.stats
        phase_wall = {k: float(st["wall_s"].get(k, 0.0)) - seen_wall[k] for k in WALL_PHASES}
        phases[name] = {
            "simulated_s": t1 - t0,
            "wall_s": w,
            **{k: st[k] - seen[k] for k in counts if k != "symbolic_analyses"},
            "phase_wall_s": {**phase_wall, "other": w - sum(phase_wall.values())},
        }
        seen = {k: st[k] for k in counts}
        seen_wall = {k: float(st["wall_s"].get(k, 0.0)) for k in WALL_PHASES}
    total, phase_wall = seen, seen_wall
    recurdyn_s = 76.0 * case.t_end / 0.3
    return {
        "case": "envelope-drop",
        "element_size_mm": case.element_size * 1e3,
        "linear_solver": _solver_name(),
        "description": "rigid 100 g box (165x125x20 mm) in a 275x200 mm two-layer shell "
        "envelope, 10 mm quads, dropped flat from 200 mm onto a rigid plate",
        "friction_model": _FRICTION_MODEL if case.stick_model else "regularised (paper eq. 8)",
        "integrator": "rho_inf 0.5, impact limit on rigid bodies, smooth error estimate, Newton "
        "relaxation (as the consignment tests)",
        "simulated_s": case.t_end,
        "wall_s": wall,
        "dof_count": model.dof_count,
        **total,
        "phases": phases,
        "phase_wall_s": {**phase_wall, "other": wall - sum(phase_wall.values())},
        "final_box_height_m": float(state.positions[box, 2]),
        "simulated_s_per_wall_s": case.t_end / wall,
        "recurdyn_wall_s": recurdyn_s,
        "speedup_vs_recurdyn": recurdyn_s / wall,
    }


RECURDYN_CONVEYOR_WALL_S = 24 * 3600.0
"""The paper's RecurDyn bulk run: 24 h (4 cores) for 2 s simulated."""


def _conveyor_snapshots(
    consignments, element_size_mm: float | None, snapshot_dir: str | Path | None, work: Path
) -> tuple[dict, float]:
    """Snapshots of ``consignments`` (presets or .toml files): from ``snapshot_dir`` or
    assembled (cached under ``work``); returns them and the assembly wall time [s]."""
    from flexparcel.cli.snapshots import snapshot_for
    from flexparcel.consignments.userfile import resolve_consignment

    size = None if element_size_mm is None else element_size_mm * 1e-3
    snaps = {}
    t0 = time.perf_counter()
    for ref in consignments:
        key = Path(ref).stem if str(ref).lower().endswith(".toml") else str(ref).upper()
        build = resolve_consignment(str(ref), size)
        snaps[key], _ = snapshot_for(key, build, work, snapshot_dir=snapshot_dir,
                                     element_size_given=size is not None, progress=False,
                                     log=lambda _m: None)  # fmt: skip
    return snaps, time.perf_counter() - t0


def _conveyor(
    quick: bool = False,
    progress=None,
    *,
    consignments=("KPBW", "PB", "KP", "BW"),
    element_size_mm: float | None = 25.0,
    t_end: float | None = None,
    snapshot_dir: str | Path | None = None,
    work: str | Path = "out/bench-conveyor",
    start_speed: float = 0.0,
    content_stiffness_n_per_mm: float | None = None,
    workers: int = 2,
    stick_stiffness_n_per_mm: float | None = None,
) -> dict:
    """The paper's bulk scene (:func:`~flexparcel.scenarios.conveyor_scene.default_layout`
    on :func:`~flexparcel.scenarios.conveyor_scene.paper_conveyor`, 1.6 m/s, 45 deg) for
    ``t_end`` [s] (default 2, quick 0.005) at ``element_size_mm``; snapshots from
    ``snapshot_dir`` or assembled into ``work`` (assembly time reported apart). The run
    writes what ``flexparcel run conveyor`` writes (responses, snapshots picture, animation,
    trajectories, ParaView) to ``work/run``, so the benchmarked run is the one people look
    at; the files' time is not in ``wall_s``. ``content_stiffness_n_per_mm``: the
    packaging-content contact (the conveyor scenario's ``content_stiffness``; None: Table
    6's); ``stick_stiffness_n_per_mm``: its stick-model stiffness (``stick_stiffness``;
    None: k_t = c). ``workers``: as ``run conveyor --workers`` (0: one model). Run through the
    scenario registry's ``conveyor``."""
    from flexparcel.cli.progress import ProgressLine
    from flexparcel.io.checkpoint import CheckpointError, load_checkpoint
    from flexparcel.scenarios.conveyor_scenario import CHECKPOINT_FILE
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.viz.scenario_pictures import pictures_for

    t_end = (0.005 if quick else 2.0) if t_end is None else float(t_end)
    # an interrupted benchmark resumes from its checkpoint (its wall time counts), a finished
    # one is measured again
    ckpt = Path(work) / "run" / CHECKPOINT_FILE
    scenario = get_scenario("conveyor", workers=workers, checkpoint=ckpt)
    # bad values fail before any assembly
    params = scenario.resolve({"start_speed": start_speed,
                               "content_stiffness": content_stiffness_n_per_mm,
                               "stick_stiffness": stick_stiffness_n_per_mm})  # fmt: skip
    snaps, assembly_wall = _conveyor_snapshots(consignments, element_size_mm, snapshot_dir,
                                               Path(work))  # fmt: skip
    shown = progress is not None and getattr(progress, "enabled", True)
    try:
        resumed = not load_checkpoint(ckpt).header["complete"]
    except (FileNotFoundError, CheckpointError):  # none, or unreadable: start over
        resumed = False
    if not resumed:
        ckpt.unlink(missing_ok=True)
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    bar = ProgressLine(f"conveyor ({len(snaps)} consignments)", enabled=shown)
    try:
        result = scenario.run(snaps, params, t_end=t_end, progress=bar)
    finally:
        bar.done()
    files = scenario.write(result, Path(work) / "run", pictures=pictures_for("conveyor"))
    run = result.record
    summary = scenario.summary(result)
    st = run.result.stats
    recurdyn_s = RECURDYN_CONVEYOR_WALL_S * t_end / 2.0
    return {
        "case": "conveyor",
        "description": "paper bulk scene: consignments queued on the centre line of a 1.6 m/s "
        "belt upstream of two 45 deg deflectors (paper_conveyor, default_layout)",
        "consignments": list(snaps),
        "element_size_mm": {k: s.build.element_size * 1e3 for k, s in snaps.items()},
        "start_speed_m_s": start_speed,
        "content_stiffness_N_per_mm": content_stiffness_n_per_mm,
        "stick_stiffness_N_per_mm": stick_stiffness_n_per_mm,
        "simulated_s": t_end,
        "wall_s": run.wall_s,
        "resumed_from_checkpoint": resumed,
        "build_wall_s": run.build_wall_s,
        "assembly_wall_s": assembly_wall,
        "dof_count": run.conveyor_model.model.dof_count,
        "node_count": run.conveyor_model.model.node_count,
        "steps": st["steps"],
        "rejected_steps": st["rejected_steps"],
        "rejected_by_cause": {
            cause: st[f"rejected_{cause}"] for cause in ("newton", "error", "impact", "penetration")
        },
        "newton_iterations": st["newton_iterations"],
        "newton_iterations_rejected": st["newton_iterations_rejected"],
        "factorizations": st.get("factorizations"),
        "phase_wall_s": _phases(st),
        # grouped runs time each phase inside the worker processes and add them up, so with
        # several workers busy at once the phases together exceed wall_s
        "phase_wall_basis": (
            "summed over the worker processes (worker-seconds)"
            if st.get("groups")
            else "wall time of the integrating process"
        ),
        "workers": workers,
        "groups": st.get("groups"),
        "simulated_s_per_wall_s": t_end / run.wall_s,
        "wall_s_for_2s_extrapolated": run.wall_s * 2.0 / t_end,
        "recurdyn_wall_s": recurdyn_s,
        "speedup_vs_recurdyn": recurdyn_s / run.wall_s,
        "responses": summary["consignments"],
        "deflector_crossings": summary["deflector_crossings"],
        "deflector_edge_depths": summary["deflector_edge_depths"],
        "files": {k: str(v) for k, v in files.items()},
        "note": "RecurDyn: 24 h on 4 cores for 2 s; recurdyn_wall_s is scaled to simulated_s. "
        "A short run extrapolates badly: the start (before the deflectors) is cheaper or "
        "dearer than the rest.",
    }


def conveyor_scaling(
    snapshot,
    counts=(1, 2, 4, 8),
    *,
    t_end: float = 0.01,
    start_speed: float = 1.6,
    progress_factory=None,
    workers: int = 2,
) -> dict:
    """Wall time of :func:`~flexparcel.scenarios.conveyor_scene.run_conveyor` against the
    number of consignments: ``count`` copies of ``snapshot``'s consignment queued on a belt
    long enough for them (:func:`~flexparcel.scenarios.conveyor_scene.throughput_layout`),
    started at ``start_speed`` [m/s], for ``t_end`` [s]. Consignment contact only between
    neighbours that can meet (``pair_reach`` = belt speed * t_end + 5 cm). Returns a table
    (``rows``) and the least-squares exponent of wall ~ count**p (1 = linear). ``workers``:
    as ``run conveyor --workers`` (0: one model)."""
    from flexparcel.scenarios.conveyor_scenario import group_settings
    from flexparcel.scenarios.conveyor_scene import run_conveyor, throughput_layout

    rows = []
    key = "c"
    for n in counts:
        layout = throughput_layout(snapshot.build, int(n), name=key, speed=start_speed)
        prog = progress_factory(f"conveyor x{n}") if progress_factory else None
        reach = layout.conveyor.belt_speed * t_end + 0.05
        run = run_conveyor({key: snapshot}, layout, t_end, dt_out=t_end / 5, pair_reach=reach,
                           progress=prog, groups=group_settings(workers))  # fmt: skip
        st = run.result.stats
        rows.append({
            "count": int(n), "wall_s": run.wall_s, "build_wall_s": run.build_wall_s,
            "wall_s_per_consignment": run.wall_s / n, "steps": st["steps"],
            "newton_iterations": st["newton_iterations"],
            "wall_s_per_newton_iteration": run.wall_s / max(1, st["newton_iterations"]),
            "dof_count": run.conveyor_model.model.dof_count,
            "contact_pairs": len(run.conveyor_model.consignment_pairs),
        })  # fmt: skip
    n = np.array([r["count"] for r in rows], float)
    w = np.array([r["wall_s"] for r in rows], float)
    it = np.array([r["wall_s_per_newton_iteration"] for r in rows], float)
    fit = lambda y: float(np.polyfit(np.log(n), np.log(y), 1)[0]) if len(n) > 1 else None  # noqa: E731
    return {
        "case": "conveyor-scaling",
        "consignment": snapshot.build.spec.id,
        "element_size_mm": snapshot.build.element_size * 1e3,
        "simulated_s": t_end,
        "start_speed_m_s": start_speed,
        "workers": workers,
        "rows": rows,
        "wall_exponent": fit(w),
        "per_iteration_exponent": fit(it),
        "note": "wall ~ count**wall_exponent (least squares in log-log); per_iteration_exponent "
        "removes the effect of the step count (the adaptive step is shared by all "
        "consignments, so more consignments can mean more, smaller steps)",
    }


def plot_scaling(table: dict, path: str | Path) -> Path:
    """Wall time and wall time per Newton iteration against consignment count (log-log),
    with the linear reference."""
    from flexparcel.viz.consignment import _pyplot, save_figure

    plt = _pyplot()
    rows = table["rows"]
    n = np.array([r["count"] for r in rows], float)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for key, label in (
        ("wall_s", "wall time [s]"),
        ("wall_s_per_newton_iteration", "wall per Newton iteration [s]"),
    ):
        y = np.array([r[key] for r in rows], float)
        ax.loglog(n, y, "o-", label=label)
        ax.loglog(n, y[0] * n / n[0], ":", color="grey")
    ax.set_xlabel("consignments")
    p_exp = table["wall_exponent"]
    ax.set_title(
        f"conveyor scaling, {table['simulated_s']:g} s simulated (wall ~ N^"
        f"{p_exp if p_exp is None else round(p_exp, 2)}; dotted: linear)",
        fontsize=9,
    )
    ax.legend(fontsize=8)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    return save_figure(fig, path, dpi=100)


def _conveyor_scaling_case(
    quick: bool = False,
    progress=None,
    *,
    counts=(1, 2, 4, 8),
    t_end: float | None = None,
    consignment: str = "examples/consignment_small.toml",
    element_size_mm: float | None = None,
    snapshot_dir: str | Path | None = None,
    work: str | Path = "out/bench-conveyor",
    plot: str | Path | None = None,
    workers: int = 2,
) -> dict:
    """Bench case ``conveyor-scaling``: :func:`conveyor_scaling` on copies of
    ``consignment`` (default the small example), plot written to ``plot``."""
    t_end = (0.002 if quick else 0.01) if t_end is None else float(t_end)
    if quick:
        counts = tuple(c for c in counts if c <= 2) or (1,)
    snaps, assembly_wall = _conveyor_snapshots([consignment], element_size_mm, snapshot_dir,
                                               Path(work))  # fmt: skip
    table = conveyor_scaling(next(iter(snaps.values())), counts, t_end=t_end, workers=workers)
    table["assembly_wall_s"] = assembly_wall
    table["wall_s"] = sum(r["wall_s"] for r in table["rows"])
    table["dof_count"] = table["rows"][-1]["dof_count"]
    table["steps"] = sum(r["steps"] for r in table["rows"])
    table["newton_iterations"] = sum(r["newton_iterations"] for r in table["rows"])
    table["speedup_vs_recurdyn"] = None
    if plot is not None:
        table["plot"] = str(plot_scaling(table, plot))
    return table


def _consignment_assembly(
    quick: bool = False,
    progress=None,
    *,
    consignments=("KPBW", "PB", "KP", "BW"),
    element_size_mm: float | None = None,
) -> dict:
    """Bench case ``consignment-assembly``: open, fill, close and settle each consignment
    (presets or .toml files) at its own mesh size (paper: 10 mm, 5 mm for BW), or at
    ``element_size_mm`` (``quick``: 25 mm), with its shape check
    (:mod:`flexparcel.consignments.shape`). A consignment that fails to assemble (or its shape
    check) is reported with its error, not dropped. The paper gives no RecurDyn time for the
    assembly."""
    from flexparcel.builder import ModelBuilder
    from flexparcel.consignments.assembly import AssemblyError, assemble
    from flexparcel.consignments.build import add_consignment
    from flexparcel.consignments.userfile import resolve_consignment

    if element_size_mm is None and quick:
        element_size_mm = 25.0
    size = None if element_size_mm is None else element_size_mm * 1e-3
    rows = []
    for ref in consignments:
        build = resolve_consignment(str(ref), size)
        b = ModelBuilder()
        add_consignment(b, build)
        dof = b.finalize().dof_count
        t0 = time.perf_counter()
        row = {"consignment": build.spec.id, "element_size_mm": build.element_size * 1e3,
               "dof_count": int(dof)}  # fmt: skip
        try:
            snap = assemble(build)
        except AssemblyError as exc:
            row.update(error=str(exc), wall_s=time.perf_counter() - t0)
        else:
            info = snap.info
            row.update(wall_s=time.perf_counter() - t0, simulated_s=info["end_time_s"],
                       steps=info["steps"], opening_time_s=info["opening_time_s"],
                       content_scale=info["content_scale"],
                       kinetic_energy_J=info["kinetic_energy_J"], shape=info["shape"])  # fmt: skip
        rows.append(row)
    done = [r for r in rows if "error" not in r]
    return {
        "case": "consignment-assembly",
        "description": "opening forces, content contact on, release (and content growth), "
        "settle to rest (flexparcel.consignments.assembly), per consignment",
        "rows": rows,
        "simulated_s": sum(r["simulated_s"] for r in done),
        "wall_s": sum(r["wall_s"] for r in rows),
        "dof_count": max(r["dof_count"] for r in rows),
        "steps": sum(r["steps"] for r in done),
        "newton_iterations": None,  # the assembly reports steps only
        "failed": [r["consignment"] for r in rows if "error" in r],
        "speedup_vs_recurdyn": None,
    }


def _kpbw_tests(
    quick: bool = False,
    progress=None,
    *,
    element_size_mm: float | None = None,
    snapshot: str | Path | None = None,
    snapshot_dir: str | Path | None = None,
) -> dict:
    """Bench case ``kpbw-tests``: KP/BW from ``snapshot``, or ``KPBW.npz`` from
    ``snapshot_dir`` when it was assembled at this element size, or the shipped snapshot where
    one fits (:func:`~flexparcel.consignments.snapshot.shipped_snapshot`), else assembled;
    then its swing (1.4 s),
    vertical and horizontal drop (200 mm, 0.3 s) with the paper's Table 6 parameters; wall
    times next to RecurDyn's (384 / 125 / 76 s on 4 cores, scaled to the simulated time).
    ``quick``: 25 mm mesh, 0.1 s swing, 0.22 s drops (just past the impact)."""
    from flexparcel.consignments.assembly import assemble
    from flexparcel.consignments.snapshot import load_snapshot, shipped_snapshot
    from flexparcel.consignments.userfile import resolve_consignment
    from flexparcel.scenarios.consignment_tests import TABLE6_VALUES
    from flexparcel.scenarios.registry import get_scenario

    if element_size_mm is None and quick:
        element_size_mm = 25.0
    size = None if element_size_mm is None else element_size_mm * 1e-3
    t0 = time.perf_counter()
    if snapshot:
        snap, source = load_snapshot(snapshot), str(snapshot)
    elif snapshot_dir:
        from flexparcel.cli.snapshots import snapshot_for

        build = resolve_consignment("KPBW", size)
        snap, source = snapshot_for("KPBW", build, Path(snapshot_dir), snapshot_dir=snapshot_dir,
                                    element_size_given=size is not None, progress=False,
                                    log=lambda _m: None)  # fmt: skip
    else:
        build = resolve_consignment("KPBW", size)
        shipped = shipped_snapshot(build)
        snap, source = (shipped[0], str(shipped[1])) if shipped else (assemble(build), "assembled")
    assembly_wall = time.perf_counter() - t0
    recurdyn = {"swing": (384.0, 1.4), "drop-vertical": (125.0, 0.3),
                "drop-horizontal": (76.0, 0.3)}  # fmt: skip
    t_end = (
        {"swing": 0.1, "drop-vertical": 0.22, "drop-horizontal": 0.22}
        if quick
        else {k: v[1] for k, v in recurdyn.items()}
    )
    rows = []
    for test in recurdyn:
        scenario = get_scenario(test)
        result = scenario.run(snap, dict(TABLE6_VALUES), t_end=t_end[test], progress=progress)
        summ = scenario.summary(result)
        rd = recurdyn[test][0] * t_end[test] / recurdyn[test][1]
        rows.append({**{k: v for k, v in summ.items() if k not in ("parameters",
                     "parameter_units")}, "recurdyn_wall_s": rd,
                     "speedup_vs_recurdyn": rd / summ["wall_s"],
                     "simulated_s_per_wall_s": summ["simulated_s"] / summ["wall_s"]})  # fmt: skip
    return {
        "case": "kpbw-tests",
        "description": "KP/BW swing, vertical and horizontal drop, Table 6 parameters",
        "friction_model": _FRICTION_MODEL,
        "element_size_mm": snap.build.element_size * 1e3,
        "snapshot": source,
        "assembly_wall_s": assembly_wall,
        "rows": rows,
        "simulated_s": sum(r["simulated_s"] for r in rows),
        "wall_s": sum(r["wall_s"] for r in rows),
        "dof_count": int(6 * len(snap.positions)),
        "steps": sum(r["steps"] for r in rows),
        "newton_iterations": sum(r["newton_iterations"] for r in rows),
        "speedup_vs_recurdyn": sum(r["recurdyn_wall_s"] for r in rows)
        / sum(r["wall_s"] for r in rows),
    }


CONVERGENCE_SIZES_MM = (25.0, 15.0, 10.0, 7.0)
"""Element sizes of the ``kpbw-convergence`` case [mm] (issue: 25 / 15 / 10 / 7 mm)."""


def _convergence_snapshot(size_mm: float, work: Path):
    """KP/BW at ``size_mm``: the shipped snapshot where one fits, else the one cached in
    ``work``, else assembled and cached there; with where it came from."""
    from flexparcel.consignments.assembly import assemble
    from flexparcel.consignments.snapshot import load_snapshot, save_snapshot, shipped_snapshot
    from flexparcel.consignments.userfile import resolve_consignment

    build = resolve_consignment("KPBW", size_mm * 1e-3)
    shipped = shipped_snapshot(build)
    if shipped is not None:
        return shipped[0], str(shipped[1])
    cache = work / f"KPBW_{size_mm:g}mm.npz"
    if cache.is_file():
        snap = load_snapshot(cache)
        if snap.build == build:
            return snap, str(cache)
    snap = assemble(build)
    save_snapshot(snap, cache)
    return snap, str(cache)


def _kpbw_convergence(
    quick: bool = False,
    progress=None,
    *,
    sizes_mm: tuple[float, ...] = CONVERGENCE_SIZES_MM,
    work: str | Path = "out/bench-kpbw-convergence",
) -> dict:
    """Bench case ``kpbw-convergence``: KP/BW's swing (1.4 s) and drops (0.3 s) with Table
    6 at each element size of ``sizes_mm``, next to Table 7 and the real-world tests. Each
    finished test is written to ``work/SIZEmm/TEST.json`` (atomically) and not run again:
    an interrupted study resumes where it stopped. ``quick``: 0.05 s of each test (a check
    that the pipeline runs; its responses are not reached)."""
    from flexparcel.io.atomic import write_atomic
    from flexparcel.scenarios.consignment_tests import TABLE6_VALUES
    from flexparcel.scenarios.paper_reference import TEST_REFERENCES
    from flexparcel.scenarios.registry import get_scenario

    work = Path(work)
    t_end = {"swing": 1.4, "drop-vertical": 0.3, "drop-horizontal": 0.3}
    rows = []
    for size in sizes_mm:
        folder = work / f"{size:g}mm"
        folder.mkdir(parents=True, exist_ok=True)
        snap, source = _convergence_snapshot(size, work)
        row: dict = {"element_size_mm": size, "snapshot": source, "tests": {}}
        for test, t in t_end.items():
            path = folder / f"{test}.json"
            if path.is_file():
                summary = json.loads(path.read_text())
            else:
                scenario = get_scenario(test)
                result = scenario.run(snap, dict(TABLE6_VALUES), t_end=0.05 if quick else t,
                                      progress=progress)  # fmt: skip
                summary = scenario.summary(result)
                write_atomic(path, json.dumps(summary, indent=2))
            row["tests"][test] = {k: summary[k] for k in ("wall_s", "steps",
                                  "newton_iterations", "simulated_s")}  # fmt: skip
            for ref in TEST_REFERENCES:
                if ref.test == test:
                    value = summary.get(ref.response)
                    row[f"{test}:{ref.response}"] = {
                        "simulated": value, "table7": ref.table7, "real": ref.real,
                        "rel_error_table7": None if value is None
                        else (value - ref.table7) / ref.table7,
                    }  # fmt: skip
        rows.append(row)
    return {
        "case": "kpbw-convergence",
        "description": "KP/BW swing and drops with Table 6 at several element sizes, next to "
        "Table 7 (RecurDyn, 10 mm) and the real-world tests; rebound = the camera's clearance",
        "rows": rows,
        "simulated_s": sum(t["simulated_s"] for r in rows for t in r["tests"].values()),
        "wall_s": sum(t["wall_s"] for r in rows for t in r["tests"].values()),
        "dof_count": None,
        "steps": sum(t["steps"] for r in rows for t in r["tests"].values()),
        "newton_iterations": sum(
            t["newton_iterations"] for r in rows for t in r["tests"].values()
        ),  # fmt: skip
        "speedup_vs_recurdyn": None,
    }


CASES: dict[str, Callable[..., dict]] = {
    "sheet-swing": _sheet_swing,
    "envelope-drop": _envelope_drop,
    "conveyor": _conveyor,
    "conveyor-scaling": _conveyor_scaling_case,
    "consignment-assembly": _consignment_assembly,
    "kpbw-tests": _kpbw_tests,
    "kpbw-convergence": _kpbw_convergence,
}
DEFAULT_CASES = ("sheet-swing", "envelope-drop")
"""What ``flexparcel bench`` runs without names (the conveyor and consignment cases are long:
name them)."""


def run_case(name: str, quick: bool = False, progress=None, **options) -> dict:
    """Run case ``name``; ``options`` go to the case (only the conveyor cases take any)."""
    if name not in CASES:
        raise ValueError(f"unknown benchmark case {name!r}; known: {sorted(CASES)}")
    return CASES[name](quick=quick, progress=progress, **options)


def run_benchmarks(
    names: list[str],
    out: Path,
    quick: bool = False,
    progress_factory=None,
    case_options: dict[str, dict] | None = None,
) -> list[dict]:
    from flexparcel import __version__
    from flexparcel.io.atomic import write_atomic

    results = []
    for name in names:
        prog = progress_factory(name) if progress_factory else None
        opts = (case_options or {}).get(name, {})
        results.append(run_case(name, quick=quick, progress=prog, **opts))
    doc = {
        "flexparcel_version": __version__,
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor(),
            "machine": platform.machine(),
            "numpy": np.__version__,
            # the thread settings change the timings: numba's kernels run on
            # numba_threads, the block factorisations on one thread per CPU
            "cpu_count": os.cpu_count(),
            "numba_threads": numba.get_num_threads(),
            "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        },
        "quick": quick,
        "results": results,
    }
    write_atomic(out, json.dumps(doc, indent=2))
    return results
