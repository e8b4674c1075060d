"""``flexparcel verify``: run the structural verification cases and report their errors."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from flexparcel.data import VERIFICATION_DIR


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "verify",
        help="run the verification cases (Sze 2004, frequencies)",
        description="Run the structural verification cases against the "
        "published references and print the maximum errors as JSON.",
    )
    p.add_argument(
        "--reference",
        type=Path,
        default=VERIFICATION_DIR,
        help="folder with the Sze 2004 CSV tables (default: the copy shipped with the package)",
    )
    p.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from flexparcel.io.atomic import write_atomic
    from flexparcel.verification import run_all

    if not (args.reference / "sze2004_cantilever_end_shear.csv").is_file():
        raise FileNotFoundError(f"--reference {args.reference}: sze2004 tables not found")
    text = json.dumps(run_all(args.reference), indent=2)
    print(text)
    if args.out:
        write_atomic(args.out, text)
    return 0
