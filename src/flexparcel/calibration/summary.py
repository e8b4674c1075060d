"""A campaign's outcome in one small JSON file, ``summary.json``: what a reader of the
campaign wants first, next to the full ``results.json`` and ``report.html``.

* ``optimum``: the calibrated parameters (name -> value, in the study's units, the paper's
  for the shipped campaigns), ``frozen``: the others at their nominal values, and
  ``parameter_units``;
* ``validation``: per target response (its summary name, see
  :func:`summary_names`) the FE re-run at the optimum against the
  target: ``simulated``, ``target``, ``rel_error`` = (simulated - target) / |target|, the
  published model's value under the study's ``[validation] reference_name`` where the target
  gives a ``reference``, and ``unit``; ``simulated`` is null with ``error`` where the
  validation run failed;
* ``run_counts``: finished runs per fidelity level ("single" in a single-fidelity study) and
  stage, and per status over the whole store;
* ``multifidelity`` (a study with fidelity levels): per experiment and target response the
  fused surrogate against a high-only GP trained on the same high runs, both on the held-out
  high runs (``holdout_rmse``, ``high_only_holdout_rmse``, ``n_holdout``) and leaving each high
  run out once (``loo_rmse``, ``high_only_loo_rmse``, ``n_high``), in the response's unit;
  null before the fit stage;
* ``reach``: per experiment whose design has runs that did not reach their responses, the
  probability that a run at the optimum reaches them (:mod:`flexparcel.calibration.reach`),
  with the runs of each outcome, and the optimiser's ``min_reach_probability``; null before the
  optimisation or where every run reached them;
* ``wall_s``: ``runs`` (the simulators' wall times added up, what one worker would have
  spent) and ``elapsed`` (first run started to last run finished, breaks between sittings
  included).
"""

from __future__ import annotations

import json
from pathlib import Path

from flexparcel.io.atomic import write_atomic

__all__ = ["campaign_summary", "write_summary", "summary_names", "SUMMARY_ROW_KEYS"]

SUMMARY_ROW_KEYS = ("experiment", "response", "simulated", "target", "rel_error", "unit", "error")
"""The keys of a response's row in ``validation``: the reference's name must not be one."""


def campaign_summary(study) -> dict:
    """The summary of ``study`` (a :class:`~flexparcel.calibration.study.Study`) from its
    store; stages not run yet are null."""
    from flexparcel._version import __version__

    c, store = study.config, study.store
    opt = store.get_result("optimise", "")
    val = store.get_result("validation", "")
    runs = store.all_runs()
    units = {p.name: p.unit for p in c.parameters.parameters}
    calibrated = list(opt["calibrated"]) if opt else []
    summary = {
        "study": c.name,
        "flexparcel_version": __version__,
        "optimum": {n: opt["optimum"][n] for n in calibrated} if opt else None,
        "frozen": {n: v for n, v in opt["optimum"].items() if n not in calibrated} if opt else None,
        "parameter_units": units,
        "validation": _validation(c, val, summary_names(c.experiments.values())) if val else None,
        "run_counts": _run_counts(c, store, runs),
        "multifidelity": _multifidelity(c, store) if c.fidelity is not None else None,
        "reach": _reach(opt),
        "wall_s": _wall(runs),
    }
    return summary


def _multifidelity(c, store) -> dict | None:
    """Fused against high-only RMSEs per experiment and response, from the stored fits (a
    figure not finite, e.g. no hold-out, as null: JSON has no NaN)."""
    from flexparcel.calibration.report import _finite

    out = {}
    for name in c.experiments:
        fit = store.get_result("fit", name)
        if not fit:
            return None
        out[name] = {
            r: {
                "rho": g.get("rho"),
                "n_high": g.get("n_high"),
                "n_holdout": len(g.get("high_holdout_index", [])),
                **_finite({k: g.get(k) for k in _MF_KEYS}),
            }
            for r, g in fit["responses"].items()
        }
    return out


def _reach(opt: dict | None) -> dict | None:
    if not opt or not opt.get("reach"):
        return None
    return {"min_reach_probability": opt["min_reach_probability"], **opt["reach"]}


_MF_KEYS = ("holdout_rmse", "high_only_holdout_rmse", "loo_rmse", "high_only_loo_rmse")


def summary_names(experiments) -> dict[tuple[str, str], str]:
    """(experiment, response) -> the target's name in ``summary.json``: its ``label``; else the
    response's name where no other experiment targets it, else ``experiment.response``."""
    targets = [t for e in experiments for t in e.targets]
    count: dict[str, int] = {}
    for t in targets:
        count[t.response] = count.get(t.response, 0) + 1
    names: dict[tuple[str, str], str] = {}
    for t in targets:
        if t.label:
            name = t.label
        else:
            name = t.response if count[t.response] == 1 else f"{t.experiment}.{t.response}"
        if name in names.values():
            raise ValueError(f"two targets are named {name!r} in the summary; label one of them")
        names[(t.experiment, t.response)] = name
    return names


def write_summary(study) -> Path:
    """Write ``summary.json`` into the study's output folder (atomically); returns its path."""
    out = Path(study.output)
    text = json.dumps(campaign_summary(study), indent=2, allow_nan=False)
    return write_atomic(out / "summary.json", text)


def _validation(c, val: dict, names: dict[tuple[str, str], str]) -> dict:
    refs = {(t.experiment, t.response): t.reference for e in c.experiments.values()
            for t in e.targets}  # fmt: skip
    rows = {}
    for r in val["rows"]:
        key = (r["experiment"], r["response"])
        sim, target = r["simulated"], r["target"]
        row = {
            "experiment": r["experiment"],
            "response": r["response"],
            "simulated": sim,
            "target": target,
            "rel_error": None if sim is None or target == 0 else (sim - target) / abs(target),
            "unit": r["unit"],
        }
        if refs.get(key) is not None:
            row[c.reference_name] = refs[key]
        if sim is None:
            row["error"] = r["error"]
        rows[names[key]] = row
    return rows


def _level(c, setup: dict) -> str:
    if c.fidelity is None:
        return "single"
    for name, level_setup in c.fidelity.items():
        if all(setup.get(k) == v for k, v in level_setup.items()):
            return name
    return "other"


def _run_counts(c, store, runs: list[dict]) -> dict:
    """Finished runs per level and stage, and the store's runs per status."""
    done_runs = {r["run_key"]: _level(c, r["setup"]) for r in runs if r["status"] == "done"}
    done: dict[str, dict[str, int]] = {}
    for stage, key in store.stage_keys():
        if key in done_runs:
            per = done.setdefault(done_runs[key], {})
            per[stage] = per.get(stage, 0) + 1
    return {"done_by_level_and_stage": done, "by_status": store.status_counts()}


def _wall(runs: list[dict]) -> dict:
    done = [r for r in runs if r["status"] == "done"]
    starts = [r["started"] for r in runs if r["started"] is not None]
    ends = [r["finished"] for r in runs if r["finished"] is not None]
    return {
        "runs": sum(float(r["wall_s"] or 0.0) for r in done),
        "elapsed": (max(ends) - min(starts)) if starts and ends else 0.0,
    }
