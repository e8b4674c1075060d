"""``flexparcel bench``: run named benchmark cases and write JSON."""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    from flexparcel.bench import CASES

    p = sub.add_parser(
        "bench",
        help="run benchmark cases and write a JSON report",
        description="Run named benchmark cases; report simulated seconds per "
        "wall second and the ratio to the paper's RecurDyn times.",
    )
    p.add_argument(
        "cases",
        nargs="*",
        default=list(CASES),
        metavar="CASE",
        help=f"cases to run (default: all): {', '.join(CASES)}",
    )
    p.add_argument("--out", type=Path, default=Path("out/bench.json"), help="JSON file to write")
    p.add_argument("--quick", action="store_true", help="short simulated times (smoke test)")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from flexparcel.bench import run_benchmarks
    from flexparcel.cli.progress import ProgressLine

    results = run_benchmarks(
        args.cases,
        args.out,
        quick=args.quick,
        progress_factory=lambda n: ProgressLine(n, enabled=not args.no_progress),
    )
    for r in results:
        print(
            json.dumps(
                {
                    k: r[k]
                    for k in (
                        "case",
                        "simulated_s",
                        "wall_s",
                        "dof_count",
                        "steps",
                        "newton_iterations",
                        "speedup_vs_recurdyn",
                    )
                }
            )
        )
    print(f"wrote {args.out}")
    return 0
