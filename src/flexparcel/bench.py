"""Named benchmark cases for ``flexparcel bench``.

Each case runs a full simulation and returns a JSON-ready dict with at least ``case``,
``simulated_s``, ``wall_s``, ``dof_count``, ``steps``, ``newton_iterations``; speed is reported as
simulated seconds per wall second and as the ratio to the paper's RecurDyn time (4 cores).
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["CASES", "run_case", "run_benchmarks"]


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
        "description": "275x200 mm sheet, 10 mm quads, E=926 MPa, nu=0.1, beta=1.71e-3 s, "
        "t=0.3 mm, 40 g, 20 mm clamped, released horizontal under gravity",
        "simulated_s": case.t_end,
        "wall_s": wall,
        "dof_count": model.dof_count,
        "node_count": model.node_count,
        "triangle_count": int(model.triangles.shape[0]),
        "steps": st["steps"],
        "rejected_steps": st["rejected_steps"],
        "newton_iterations": st["newton_iterations"],
        "tangent_assemblies": st["tangent_assemblies"],
        "factorizations": st["factorizations"],
        "phase_wall_s": {k: v for k, v in st["wall_s"].items() if k != "total"},
        "simulated_s_per_wall_s": case.t_end / wall,
        "recurdyn_wall_s": recurdyn_s,
        "speedup_vs_recurdyn": recurdyn_s / wall,
    }


def _envelope_drop(quick: bool = False, progress=None) -> dict:
    from flexparcel.scenarios.envelope_drop import EnvelopeDrop, envelope_drop_model
    from flexparcel.simulate import simulate

    case = EnvelopeDrop(drop_height=0.02, t_end=0.1) if quick else EnvelopeDrop()
    model, box, _ = envelope_drop_model(case)
    warm, _, _ = envelope_drop_model(EnvelopeDrop(element_size=0.1, drop_height=0.005))
    simulate(warm, 0.02)
    # phases: free flight until the envelope's bottom reaches the plate, the impact (50 ms),
    # then settling; each phase continues from the previous state
    t_touch = float(np.sqrt(2.0 * case.drop_height / 9.81))
    bounds = [0.0, min(t_touch, case.t_end), min(t_touch + 0.05, case.t_end), case.t_end]
    names = ["free_flight", "impact", "settling"]
    phases = {}
    state = None
    total = {"steps": 0, "rejected_steps": 0, "newton_iterations": 0, "factorizations": 0}
    wall = 0.0
    for name, t0, t1 in zip(names, bounds[:-1], bounds[1:], strict=True):
        if t1 <= t0:
            continue
        w0 = time.perf_counter()
        res = simulate(model, t1, dt_out=(t1 - t0) / 10, state=state, progress=progress)
        w = time.perf_counter() - w0
        wall += w
        state = res.final_state
        phases[name] = {
            "simulated_s": t1 - t0,
            "wall_s": w,
            "steps": res.stats["steps"],
            "newton_iterations": res.stats["newton_iterations"],
            "rejected_steps": res.stats["rejected_steps"],
        }
        for k in total:
            total[k] += res.stats[k]
    recurdyn_s = 76.0 * case.t_end / 0.3
    return {
        "case": "envelope-drop",
        "description": "rigid 100 g box (165x125x20 mm) in a 275x200 mm two-layer shell "
        "envelope, 10 mm quads, dropped flat from 200 mm onto a rigid plate",
        "simulated_s": case.t_end,
        "wall_s": wall,
        "dof_count": model.dof_count,
        **total,
        "phases": phases,
        "final_box_height_m": float(state.positions[box, 2]),
        "simulated_s_per_wall_s": case.t_end / wall,
        "recurdyn_wall_s": recurdyn_s,
        "speedup_vs_recurdyn": recurdyn_s / wall,
    }


CASES: dict[str, Callable[..., dict]] = {
    "sheet-swing": _sheet_swing,
    "envelope-drop": _envelope_drop,
}


def run_case(name: str, quick: bool = False, progress=None) -> dict:
    if name not in CASES:
        raise ValueError(f"unknown benchmark case {name!r}; known: {sorted(CASES)}")
    return CASES[name](quick=quick, progress=progress)


def run_benchmarks(
    names: list[str], out: Path, quick: bool = False, progress_factory=None
) -> list[dict]:
    from flexparcel import __version__
    from flexparcel.io.atomic import write_atomic

    results = []
    for name in names:
        prog = progress_factory(name) if progress_factory else None
        results.append(run_case(name, quick=quick, progress=prog))
    doc = {
        "flexparcel_version": __version__,
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor(),
            "machine": platform.machine(),
            "numpy": np.__version__,
        },
        "quick": quick,
        "results": results,
    }
    write_atomic(out, json.dumps(doc, indent=2))
    return results
