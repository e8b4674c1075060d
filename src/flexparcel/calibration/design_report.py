"""The report of a design study (``purpose = "design"``): what each run gave, which parameters
matter, and maps of the outcomes over two parameters.

A design study has no targets. It runs the screen (a two-level factorial, its ANOVA ranks the
parameters) and a Latin hypercube over every parameter, and this report shows, from the store:

* the runs: parameters and outcomes of every finished run of both stages, an outcome the run
  did not reach shown as "not reached" (a consignment that never left the belt has no exit
  time);
* the screening tables and charts (:func:`~flexparcel.calibration.report.screening_section`);
* a **map** per 0/1 outcome (``[maps] flags``, e.g. ``jammed``; default: every outcome whose
  values are all 0 or 1): every run as a point over the two map axes (``[maps] axes``),
  filled where the outcome is 1, open where 0, a cross where not reached, its colour the third
  parameter;
* a **contour** per other outcome (``[maps] contours``, default all): a Gaussian-process
  surrogate (:class:`~flexparcel.calibration.surrogates.GPRSurrogate`, kernel by k-fold CV over
  all runs that reached the outcome, no hold-out: a design study's runs are few) predicted on a
  grid over the two axes, the other parameters at their nominal values, with the runs on top;
  only inside the convex hull of the runs that reached the outcome (no extrapolation).
  Its title gives the chosen kernel's out-of-fold RMSE, so a map drawn from too few runs says
  so. Fewer than 4 runs with the outcome: no contour, a note instead.

Files (atomically, in the study's output folder): ``results.json`` (runs, screening, maps),
``figures/*.png`` and a self-contained ``report.html``.
"""

from __future__ import annotations

import html
import json
import time
from pathlib import Path

import numpy as np

from flexparcel.calibration.report import (
    _CSS,
    _Figures,
    _finite,
    _fmt,
    _table,
    screening_section,
    write_atomic,
)

__all__ = ["write_design_report", "design_runs", "binary_outcomes"]

#: Fewest runs with an outcome for its contour (2-fold CV of a GP needs 4).
MIN_CONTOUR_RUNS = 4


def design_runs(study, experiment: str) -> list[dict]:
    """The finished runs of ``experiment`` in the screen and the hypercube, each run once:
    ``{"stage", "run_key", "params", "outcomes", "wall_s"}`` (``outcomes``: the experiment's
    outcomes the run reached)."""
    exp = study.config.experiments[experiment]
    seen, out = set(), []
    for stage in ("screening", "design"):
        for row in study.store.get_runs(study.store.design_keys(stage, experiment)):
            if row["status"] != "done" or row["run_key"] in seen:
                continue
            seen.add(row["run_key"])
            got = row["responses"] or {}
            out.append(
                {
                    "stage": stage,
                    "run_key": row["run_key"],
                    "params": dict(row["params"]),
                    "outcomes": {o: got[o] for o in exp.outcomes if o in got},
                    "wall_s": row["wall_s"],
                }
            )
    return out


def binary_outcomes(runs: list[dict], outcomes) -> list[str]:
    """The outcomes whose every reached value is 0 or 1 (flags such as ``jammed``)."""
    out = []
    for o in outcomes:
        vals = [r["outcomes"][o] for r in runs if o in r["outcomes"]]
        if vals and all(v in (0.0, 1.0) for v in vals):
            out.append(o)
    return out


def _axes_data(study, e: str, runs, axes):
    space = study.config.experiment_space(e)
    names = list(space.names)
    third = [n for n in names if n not in axes]
    X = np.array([[r["params"][a] for a in axes] for r in runs], dtype=float)
    colour = np.array([r["params"][third[0]] for r in runs]) if third else None
    labels = [f"{a} [{space[a].unit}]" if space[a].unit else a for a in axes]
    return X, colour, (third[0] if third else None), labels


def _binary_map(figs, study, e: str, runs, o: str, axes) -> tuple[str, dict]:
    import matplotlib.pyplot as plt

    X, colour, third, labels = _axes_data(study, e, runs, axes)
    v = np.array([r["outcomes"].get(o, np.nan) for r in runs], dtype=float)
    one, zero, missing = v == 1.0, v == 0.0, np.isnan(v)
    if colour is None:  # one parameter only: black rims
        colour = np.zeros(len(runs))
    norm = plt.Normalize(float(colour.min()), float(colour.max()))
    rims = plt.cm.viridis(norm(colour))
    fig, ax = plt.subplots(figsize=(5.8, 4.4))
    ax.scatter(X[one, 0], X[one, 1], c=rims[one], s=110, edgecolors="k")
    ax.scatter(X[zero, 0], X[zero, 1], s=110, facecolors="none", edgecolors=rims[zero],
               linewidths=2)  # fmt: skip
    ax.scatter(X[missing, 0], X[missing, 1], marker="x", s=60, color="0.4")
    if third is not None:
        fig.colorbar(plt.cm.ScalarMappable(cmap="viridis", norm=norm), ax=ax, label=third)
    counts = {"1": int(one.sum()), "0": int(zero.sum()), "not reached": int(missing.sum())}
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_title(f"{o}: filled = 1 ({counts['1']}), open = 0 ({counts['0']}), "
                 f"x = not reached ({counts['not reached']})", fontsize=9)  # fmt: skip
    fig.suptitle(f"{e}: map of {o}", fontsize=10)
    return figs.add(fig, f"map_{e}_{o}"), {"kind": "binary", "counts": counts}


def _contour(figs, study, e: str, runs, o: str, axes) -> tuple[str, dict]:
    import matplotlib.pyplot as plt

    from flexparcel.calibration.surrogates import GPRSurrogate

    c = study.config
    space = c.experiment_space(e)
    have = [r for r in runs if o in r["outcomes"]]
    y = np.array([r["outcomes"][o] for r in have], dtype=float)
    if len(have) < MIN_CONTOUR_RUNS or np.ptp(y) == 0.0:
        why = f"the same in every run ({y[0]:g})" if len(have) else ""
        if len(have) < MIN_CONTOUR_RUNS:
            why = f"{len(have)} runs reached it (a contour needs {MIN_CONTOUR_RUNS})"
        return f"<p class='note'>{html.escape(o)}: no contour, {html.escape(why)}.</p>", {
            "kind": "none",
            "reason": why,
            "n_runs": len(have),
        }
    X = space.from_dicts(r["params"] for r in have)
    folds = min(c.cv_folds, len(have) // 2)
    gp = GPRSurrogate(space, kernels=c.kernels, cv_folds=folds, holdout_fraction=0.0,
                      n_restarts_optimizer=c.gp_restarts, random_state=c.random_state,
                      name=o).fit(X, y)  # fmt: skip
    cv_rmse = gp.cv_rmse_[gp.kernel_name_]
    i, j = (list(space.names).index(a) for a in axes)
    n = 50
    U = np.tile(space.to_unit(space.nominal[None, :]), (n * n, 1))
    ui, uj = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    U[:, i], U[:, j] = ui.ravel(), uj.ravel()
    G = space.from_unit(U)
    Xr, _, _, labels = _axes_data(study, e, have, axes)
    m = gp.predict(G).reshape(n, n)
    inside = _within_runs(Xr, G[:, [i, j]], space, (i, j)).reshape(n, n)
    m = np.where(inside, m, np.nan)  # no colour where no run reached the outcome
    fig, ax = plt.subplots(figsize=(5.8, 4.4))
    cs = ax.contourf(G[:, i].reshape(n, n), G[:, j].reshape(n, n), m, levels=14, cmap="magma")
    fig.colorbar(cs, ax=ax, label=o)
    ax.scatter(
        Xr[:, 0], Xr[:, 1], c=y, cmap="magma", norm=cs.norm, edgecolors="w", s=60, clip_on=False
    )
    missing = [r for r in runs if o not in r["outcomes"]]
    if missing:
        Xm, _, _, _ = _axes_data(study, e, missing, axes)
        ax.scatter(
            Xm[:, 0], Xm[:, 1], marker="x", color="c", s=60, label="not reached", clip_on=False
        )
        ax.legend(fontsize=8, loc="upper right")
    others = [n for n in space.names if n not in axes]
    held = ", ".join(f"{p} = {_fmt(space[p].nominal_value)}" for p in others)
    ax.set_xlabel(labels[0])
    ax.set_ylabel(labels[1])
    ax.set_title(f"GPR ({gp.kernel_name_}), {folds}-fold CV RMSE {_fmt(cv_rmse)}; "
                 f"{held or 'no other parameter'}", fontsize=8)  # fmt: skip
    fig.suptitle(f"{e}: {o} over {axes[0]} and {axes[1]}", fontsize=10)
    info = {"kind": "contour", "n_runs": len(have), "kernel": gp.kernel_name_,
            "cv_folds": folds,
            "drawn_fraction": float(inside.mean()), "cv_rmse": cv_rmse,
            "range": [float(y.min()), float(y.max())],
            "held_at": {p: space[p].nominal_value for p in others}}  # fmt: skip
    return figs.add(fig, f"contour_{e}_{o}"), info


def _within_runs(X_runs, X_grid, space, cols) -> np.ndarray:
    """Which grid points (the two map axes) lie in the convex hull of the runs that reached the
    outcome, in unit coordinates: the contour is drawn there only, so it does not extrapolate
    into a corner where the outcome was never reached. All True if the runs span no area."""
    from matplotlib.path import Path as PolyPath
    from scipy.spatial import ConvexHull, QhullError

    pars = [space.parameters[c] for c in cols]

    def unit(X):
        return np.column_stack([p.to_unit(X[:, k]) for k, p in enumerate(pars)])

    U = unit(X_runs)
    try:
        hull = ConvexHull(U)
    except (QhullError, ValueError):
        return np.ones(len(X_grid), dtype=bool)
    return PolyPath(U[hull.vertices]).contains_points(unit(X_grid), radius=1e-9)


def _outcomes_only(sc: dict | None, outcomes) -> dict | None:
    """The screening result restricted to the study's current outcomes (an outcome taken out
    of the study file after its screen is not shown)."""
    if not sc:
        return sc
    keep = set(outcomes)
    out = dict(sc)
    for key in ("anova", "responses", "not_analysed"):
        out[key] = {k: v for k, v in (sc.get(key) or {}).items() if k in keep}
    return out


def _runs_table(runs: list[dict], params, outcomes) -> str:
    rows = [
        [k + 1, r["stage"], *(r["params"][p] for p in params)]
        + [r["outcomes"].get(o, "not reached") for o in outcomes]
        + [r["wall_s"]]
        for k, r in enumerate(runs)
    ]
    return _table(["#", "stage", *params, *outcomes, "wall [s]"], rows)


def write_design_report(study) -> Path:
    """Write ``results.json``, ``figures/*.png`` and ``report.html`` of the design ``study``
    (a :class:`~flexparcel.calibration.study.Study` with ``purpose = "design"``); returns the
    HTML path."""
    import matplotlib

    matplotlib.use("Agg", force=False)

    from flexparcel._version import __version__

    c = study.config
    out = Path(study.output)
    figs = _Figures(out / "figures")
    parts: list[str] = []
    add = parts.append
    counts = study.store.status_counts()
    axes = list(c.maps["axes"])
    add(f"<h1>Design study: {html.escape(c.name)}</h1>")
    if c.description:
        add(f"<p>{html.escape(c.description)}</p>")
    add(f"<p class='note'>study file {html.escape(str(c.path))}; store "
        f"{html.escape(str(study.store_path))}; flexparcel {__version__}; written "
        f"{time.strftime('%Y-%m-%d %H:%M:%S')}. Runs in store: "
        + ", ".join(f"{k} {v}" for k, v in counts.items()) + "</p>")  # fmt: skip
    add("<h2>Parameters</h2>")
    prow = [[p.name, p.unit, p.lower, p.upper, p.scale, p.nominal_value]
            for p in c.parameters.parameters]  # fmt: skip
    add(_table(["parameter", "unit", "lower", "upper", "scale", "nominal"], prow))
    results: dict = {"study": c.name, "purpose": "design", "flexparcel_version": __version__,
                     "run_counts": counts, "map_axes": axes, "experiments": {}}  # fmt: skip
    for exp in c.experiments.values():
        e = exp.name
        runs = design_runs(study, e)
        wall = sum(r["wall_s"] or 0.0 for r in runs)
        add(f"<h2>Experiment {html.escape(e)}</h2>")
        add(f"<p class='note'>simulator <b>{html.escape(exp.simulator)}</b>, setup "
            f"<code>{html.escape(json.dumps(dict(exp.setup)))}</code>; {len(runs)} finished "
            f"runs, {wall:.0f} s of simulation in all</p>")  # fmt: skip
        add("<h3>Runs</h3>")
        add(_runs_table(runs, list(exp.parameters), list(exp.outcomes)))
        sc = _outcomes_only(study.store.get_result("screening", e), exp.outcomes)
        if sc:
            add(screening_section(figs, e, sc))
        flags = c.maps["flags"]
        flags = binary_outcomes(runs, exp.outcomes) if flags is None else list(flags)
        flags = [o for o in flags if o in exp.outcomes]
        wanted = c.maps["contours"]
        rest = [o for o in exp.outcomes if o not in flags and (wanted is None or o in wanted)]
        maps = {}
        off = [a for a in axes if a not in exp.parameters]
        if off:
            add(f"<p class='note'>no maps: {html.escape(off[0])} is not a parameter of "
                f"{html.escape(e)}</p>")  # fmt: skip
        elif runs:
            add(f"<h3>Maps over {html.escape(axes[0])} and {html.escape(axes[1])}</h3>")
            for o in flags:
                img, maps[o] = _binary_map(figs, study, e, runs, o, axes)
                add(img)
            for o in rest:
                img, maps[o] = _contour(figs, study, e, runs, o, axes)
                add(img)
        results["experiments"][e] = {"parameters": list(exp.parameters),
                                     "outcomes": list(exp.outcomes), "runs": runs,
                                     "screening": sc, "maps": maps, "wall_s": wall}  # fmt: skip
    failed = [r for r in study.store.all_runs() if r["status"] == "failed"]
    if failed:
        add("<h2>Failed runs</h2>")
        for r in failed[:50]:
            add(f"<details><summary>{r['run_key'][:12]} ({r['attempts']} attempts)</summary>"
                f"<pre>{html.escape(r['error'] or '')}</pre></details>")  # fmt: skip
    results["figures"] = [str(p.relative_to(out)) for p in figs.files]
    page = ("<!DOCTYPE html><html><head><meta charset='utf-8'>"
            f"<title>{html.escape(c.name)} – flexparcel design study</title>"
            f"<style>{_CSS}</style></head><body>{''.join(parts)}</body></html>")  # fmt: skip
    write_atomic(out / "results.json", json.dumps(_finite(results), indent=2, allow_nan=False))
    return write_atomic(out / "report.html", page)
