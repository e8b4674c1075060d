"""``flexparcel calibrate STUDY.toml``: run a calibration study (all stages or some), or a
design study (``purpose = "design"``: no targets; stages screen, design, report, with maps and
contours of its outcomes).

Stages: screen, design, fit, optimise, validate, report (see ``docs/calibration.md``). Every stage
records its runs and results in the study store, so an interrupted command resumes where it
stopped when run again, and a single stage can be run later with ``--stage``.

``--dry-run`` checks the study against its simulators and prints the plan (stages, run counts,
the cost of a run measured in the store or stated in the study, the total) without running
anything. ``--budget 0.2`` runs every Latin hypercube at a fifth of its size (a pilot campaign
the full one later extends); ``--runs EXPERIMENT=N`` sets one experiment's design runs.

Stopping: Ctrl-C stops at once; the runs in flight go back to pending and start over next
time. ``kill -USR1 PID`` (POSIX) drains instead: no new run starts, the runs in flight finish
and are recorded, and the command exits with status 75; the same command goes on.
``--time-limit 3h`` drains the same way before the first run that would end after 3 h.
"""

from __future__ import annotations

import argparse
import re
import sys

__all__ = ["register", "run"]

_STAGES = ("screen", "design", "fit", "optimise", "validate", "report")
DRAINED_STATUS = 75
"""Exit status of a campaign drained by SIGUSR1 (sysexits' EX_TEMPFAIL: stopped cleanly,
not complete; the same command goes on)."""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "calibrate",
        help="parameterise a model (DoE, ANOVA screening, GPR surrogates, Nelder-Mead, "
        "validation), or map a design space (purpose = 'design')",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("study", help="study file (study.toml, format in docs/calibration.md)")
    p.add_argument(
        "--stage",
        action="append",
        metavar="STAGE",
        help=f"run only this stage (repeatable or comma separated): {', '.join(_STAGES)}, all",
    )
    p.add_argument(
        "--reset",
        metavar="STAGE",
        choices=_STAGES,
        help="forget the results of STAGE and all later stages first (simulated runs are kept)",
    )
    p.add_argument("--workers", type=int, help="local worker processes (0: run in this process)")
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="run on a Dask cluster, e.g. tcp://host:8786"
    )
    p.add_argument("--retries", type=int, help="extra attempts for a failed run")
    p.add_argument(
        "--retry-failed",
        action="store_true",
        help="give runs that failed in earlier campaigns a fresh retry budget",
    )
    p.add_argument("--store", metavar="PATH", help="study store file (overrides the study file)")
    p.add_argument("--out", metavar="DIR", help="report folder (overrides the study file)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument(
        "--dry-run",
        action="store_true",
        help="check the study and print the plan (stages, runs, estimated cost); run nothing",
    )
    p.add_argument(
        "--budget",
        type=float,
        metavar="FACTOR",
        help="scale every Latin hypercube's runs by FACTOR (e.g. 0.1; at least 2 x cv_folds + 1 "
        "runs; screening factorials are not scaled)",
    )
    p.add_argument(
        "--runs",
        action="append",
        metavar="EXPERIMENT=N",
        help="design runs of one experiment (repeatable; applied after --budget)",
    )
    p.add_argument(
        "--time-limit",
        metavar="DURATION",
        help="start no run that would end later than DURATION from now (e.g. 2h, 90m, "
        "1h30m, 600s; a run's cost: the median wall time of the store's finished runs of "
        "its kind); the runs in flight finish, exit status 75",
    )
    p.set_defaults(func=run)


def _stages(arg: list[str] | None) -> list[str] | None:
    """The stages asked for, or None for all of the study's own."""
    if not arg:
        return None
    names = [s.strip() for a in arg for s in a.split(",") if s.strip()]
    if "all" in names:
        return None
    bad = [s for s in names if s not in _STAGES]
    if bad:
        raise ValueError(f"unknown stage {bad[0]!r}; stages: {', '.join(_STAGES)}, all")
    return names


def _runs(items: list[str] | None) -> dict[str, int]:
    out = {}
    for item in items or []:
        name, sep, n = item.partition("=")
        try:
            out[name.strip()] = int(n)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ValueError(f"--runs {item!r}: expected EXPERIMENT=N, e.g. swing=20")
    return out


_NUMBER = r"\d+(?:\.\d*)?"
_DURATION = re.compile(rf"(?P<n>{_NUMBER})|(?:(?P<h>{_NUMBER})h)?(?:(?P<m>{_NUMBER})m)?"
                       rf"(?:(?P<s>{_NUMBER})s)?")  # fmt: skip


def parse_duration(text: str) -> float:
    """Seconds in ``text``: amounts in the order h, m, s (``2h``, ``1h30m``, ``90m``, ``45s``)
    or a number of seconds; > 0, else a ValueError naming ``--time-limit``."""
    match = _DURATION.fullmatch(text.strip().lower())
    total = 0.0
    if match:
        total = sum(float(v) * f for v, f in zip(match.group("h", "m", "s", "n"),
                                                (3600, 60, 1, 1), strict=True) if v)  # fmt: skip
    if not total > 0.0:
        raise ValueError(
            f"--time-limit {text!r}: expected a duration > 0, e.g. 2h, 90m, 1h30m or 600 (s)"
        )
    return total


def _duration(s: float) -> str:
    if s < 120:
        return f"{s:.0f} s"
    if s < 7200:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"


def print_plan(plan: dict) -> None:
    """The dry-run plan as a table: per row the runs, how many the store holds done (and
    failed), the cost; then the whole study and what a resume would still run."""
    print(f"plan of study '{plan['study']}' (nothing is run)")
    print(f"{'stage':9s} {'experiment':16s} {'level':5s} {'runs':>5s} {'done':>5s}  "
          f"{'per run':>9s}  {'total':>9s}  what; cost from")  # fmt: skip
    for r in plan["rows"]:
        each = "?" if r["run_s"] is None else _duration(r["run_s"])
        tot = "?" if r["total_s"] is None else _duration(r["total_s"])
        failed = f" ({r['failed']} failed)" if r["failed"] else ""
        print(
            f"{r['stage']:9s} {r['experiment']:16s} {r['level'] or '-':5s} {r['runs']:5d} "
            f"{r['done']:5d}  {each:>9s}  {tot:>9s}  {r['what']}; {r['cost_source']}{failed}"
        )
    print(f"surrogates: {plan['surrogate']}; optimiser: {plan['optimiser']}")
    workers = f"{plan['workers']} worker{'s' if plan['workers'] != 1 else ''}"
    for label, runs, known, unknown in (
        ("total", plan["runs"], plan["known_s"], plan["unknown_runs"]),
        ("left", plan["left_runs"], plan["left_known_s"], plan["left_unknown_runs"]),
    ):
        line = f"{label}: {runs} runs, {_duration(known)} of simulation where the cost is known"
        if unknown:
            line += f", plus {unknown} runs of unknown cost (run one of each to measure)"
        print(line)
        if known > 0:
            print(f"       about {_duration(known / plan['workers'])} of wall time on {workers} "
                  "(known part)")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from flexparcel.calibration.execution import CampaignDrained
    from flexparcel.calibration.study import Study, load_study, scale_budget

    stages = _stages(args.stage)
    config = load_study(args.study)
    if args.budget is not None or args.runs:
        config = scale_budget(config, args.budget, _runs(args.runs))
    study = Study(
        config,
        store=args.store,
        output=args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        retries=args.retries,
        retry_failed=args.retry_failed,
        progress=not args.no_progress and sys.stderr.isatty(),
        time_limit_s=None if args.time_limit is None else parse_duration(args.time_limit),
    )
    try:
        study.check()
        if args.dry_run:
            print_plan(study.plan())
            return 0
        if stages is None:
            stages = list(study.config.stages)
        study.check_stages(stages)
        if args.reset:
            study.reset(args.reset)
        for stage in _STAGES:
            if stage not in stages:
                continue
            if stage == "validate" and not study.config.validate:
                continue
            print(f"== {stage}", flush=True)
            try:
                result = getattr(study, stage)()
            except CampaignDrained as exc:
                print(f"flexparcel calibrate: {stage}: {exc}", file=sys.stderr)
                return DRAINED_STATUS
            except RuntimeError as exc:
                print(f"flexparcel calibrate: {stage} failed: {exc}", file=sys.stderr)
                return 1
            _summarise(study, stage, result)
        failed = sum(len(c.failed) for c in study.campaigns.values())
        if failed:
            print(f"warning: {failed} run(s) failed after all retries (see the report)")
    finally:
        study.close()
    return 0


def _summarise(study, stage: str, result) -> None:
    camp = study.campaigns.get({"screen": "screening", "validate": "validation"}.get(stage, stage))
    if camp is not None and stage in ("screen", "design", "validate"):
        print(
            f"   runs: {camp.requested} requested, {camp.already_done} already done, "
            f"{camp.succeeded} run now, {len(camp.failed)} failed"
            + (
                f" ({camp.interrupted_reset} interrupted runs resumed)"
                if camp.interrupted_reset
                else ""
            )
            + (f" on {camp.executor}" if camp.executor else "")
            + f", {camp.wall_s:.1f} s"
        )
    if stage == "screen":
        for exp, res in result.items():
            print(f"   {exp}: significant {', '.join(res['significant'])}")
            if res["frozen"]:
                frozen = ", ".join(f"{k} = {v:.4g}" for k, v in res["frozen"].items())
                print(f"   {exp}: frozen {frozen}")
    elif stage == "design":
        for exp, res in result.items():
            print(f"   {exp}: {res['runs']} runs over {', '.join(res['active'])}: {res['status']}")
            if "high_runs" in res:
                print(f"   {exp}: {res['high_runs']} high-fidelity runs: {res['high_status']}")
    elif stage == "fit":
        for exp, res in result.items():
            for r, g in res["responses"].items():
                line = (
                    f"   {exp}.{r}: kernel {g['kernel']}, CV RMSE {g['cv_rmse'][g['kernel']]:.4g}, "
                    f"hold-out RMSE {g['holdout_rmse']:.4g}"
                )
                if "high_only_holdout_rmse" in g:
                    line += (
                        f" (co-kriging, rho {g['rho']:.3g}; high-only GP on the same high runs: "
                        f"{g['high_only_holdout_rmse']:.4g})"
                    )
                if "loo_rmse" in g:  # a few high runs: each left out once (multifidelity.py)
                    line += (
                        f"; leave-one-out over {g['n_high']} high runs: fused "
                        f"{g['loo_rmse']:.4g}, high-only {g['high_only_loo_rmse']:.4g}"
                    )
                print(line)
    elif stage == "optimise":
        for n in result["calibrated"]:
            print(f"   {n} = {result['optimum'][n]:.6g}")
        print(f"   weighted error {result['error']:.4g}")
        for t in result["targets"]:
            print(
                f"   {t['experiment']}.{t['response']}: target {t['target']:.4g}, predicted "
                f"{t['predicted']:.4g} ± {t['std']:.2g}"
            )
    elif stage == "validate":
        for v in result["rows"]:
            sim = "failed" if v["simulated"] is None else f"{v['simulated']:.4g}"
            print(
                f"   {v['experiment']}.{v['response']}: target {v['target']:.4g}, surrogate "
                f"{v['predicted']:.4g}, simulated {sim}"
            )
    elif stage == "report":
        print(f"   {result}")
