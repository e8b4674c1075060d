"""``flexparcel verify``: run the structural verification cases and report their errors."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from flexparcel.data import VERIFICATION_DIR

FINE_MESHES = {
    "cook": (4, 8, 16, 32),
    "macneal": ((6, 1), (12, 2), (24, 4)),
    "scordelis": (8, 16, 24, 32),
    "pinched": (4, 8, 16, 24, 32),
}
"""Meshes of ``flexparcel verify --table --fine`` (docs/shell-verification.md)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "verify",
        help="run the verification cases (Sze 2004, frequencies, shell benchmarks)",
        description="Run the structural verification cases against the "
        "published references and print the maximum errors as JSON; with --table, print "
        "the linear shell benchmarks (Cook's membrane, MacNeal-Harder cantilever, "
        "Scordelis-Lo roof, pinched cylinder) as a Markdown table.",
    )
    p.add_argument(
        "--reference",
        type=Path,
        default=VERIFICATION_DIR,
        help="folder with the Sze 2004 CSV tables (default: the copy shipped with the package)",
    )
    p.add_argument(
        "--table",
        action="store_true",
        help="print only the shell benchmarks, as a Markdown table (result, reference, error)",
    )
    p.add_argument(
        "--fine",
        action="store_true",
        help="with --table: add the finer meshes of docs/shell-verification.md (slower)",
    )
    p.add_argument("--out", type=Path, default=None, help="also write the output here")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from flexparcel.io.atomic import write_atomic
    from flexparcel.verification import benchmark_table, run_all, shell_benchmarks

    if args.table:
        text = benchmark_table(shell_benchmarks(FINE_MESHES if args.fine else None))
    else:
        if args.fine:
            raise ValueError("--fine goes with --table")
        if not (args.reference / "sze2004_cantilever_end_shear.csv").is_file():
            raise FileNotFoundError(f"--reference {args.reference}: sze2004 tables not found")
        text = json.dumps(run_all(args.reference), indent=2)
    print(text)
    if args.out:
        write_atomic(args.out, text)
    return 0
