"""``flexparcel run``: one of the paper's tests (swing, vertical or horizontal drop) on a
consignment, from its snapshot (assembled first when none is given)."""

from __future__ import annotations

import argparse
from pathlib import Path

from flexparcel.cli.assemble_cmd import CONSIGNMENT_HELP, element_size_m

__all__ = ["register", "run"]

TESTS = ("swing", "drop-vertical", "drop-horizontal")  # as cli.consignment_jobs.TESTS


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run the swing or a drop test on a consignment",
        description="Run the paper's swing test (20 mm clamped, released horizontal, 1.4 s) "
        "or drop test (200 mm onto a rigid plate standing on its edge or lying flat, 0.3 s) "
        "and write DIR/responses.json, DIR/results.npz, ParaView files DIR/paraview/*.pvd and "
        "the pictures DIR/frames.png and DIR/response.png. Parameters not set keep the "
        "consignment's own packaging modulus and damping ratio and the paper's Table 6 contact "
        "values.",
    )
    p.add_argument("test", choices=TESTS, help="which test")
    p.add_argument(
        "--consignment",
        help=CONSIGNMENT_HELP + "; may be left out with --snapshot",
    )
    p.add_argument(
        "--snapshot",
        type=Path,
        default=None,
        help="start from this snapshot (from flexparcel assemble); default: assemble first "
        "and save DIR/snapshot.npz",
    )
    p.add_argument(
        "--set",
        dest="assignments",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a parameter of the paper's Table 3 in its units, e.g. youngs_modulus=926 (MPa), "
        "damping_ratio=1.71e-3 (s), contact_stiffness_packaging_content=649 (N/mm), "
        "contact_damping_packaging_content=0.579 (Ns/mm), contact_stiffness_packaging_ground, "
        "contact_damping_packaging_ground; repeatable",
    )
    p.add_argument("--t-end", type=float, default=None, metavar="S",
                   help="simulated time [s] (default 1.4 swing, 0.3 drops)")  # fmt: skip
    p.add_argument("--element-size", type=float, default=None, metavar="MM",
                   help="shell edge length [mm] (must match --snapshot's)")  # fmt: skip
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from flexparcel.cli.consignment_jobs import (
        assemble_job,
        check_snapshot_matches,
        run_job,
        run_parameters,
    )
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.snapshot import load_snapshot
    from flexparcel.consignments.userfile import resolve_consignment
    from flexparcel.integrate.errors import ConvergenceError

    if args.consignment is None and args.snapshot is None:
        raise ValueError("give --consignment (KPBW, PB, KP, BW or a .toml file) or --snapshot")
    if args.t_end is not None and not 0.0 < args.t_end <= 10.0:
        raise ValueError(f"--t-end must be in (0, 10] s, got {args.t_end:g}")
    size = element_size_m(args.element_size)
    build = None
    if args.consignment is not None:
        build = resolve_consignment(args.consignment, size)
    snap = None
    if args.snapshot is not None:
        snap = load_snapshot(args.snapshot)
        check_snapshot_matches(snap, build, size)
    # bad --set values fail here, before a (long) assembly
    params = run_parameters(snap.build if snap is not None else build, args.assignments)
    progress = not args.no_progress
    try:
        if snap is None:
            snap, files = assemble_job(build, args.out, progress=progress)
            source = str(files.snapshot)
        else:
            source = str(args.snapshot)
        run_, summary, files = run_job(
            args.test, snap, params, args.out, t_end=args.t_end, progress=progress,
            extra={"snapshot": source},
        )  # fmt: skip
    except (AssemblyError, ConvergenceError) as exc:
        print(f"flexparcel run: {args.test} failed: {exc}", file=sys.stderr)
        return 1
    responses = ", ".join(f"{k} = {v:.2f}" for k, v in run_.responses.items())
    print(
        f"{args.test} {snap.build.spec.id}: {responses}; {summary['simulated_s']:g} s simulated "
        f"in {summary['wall_s']:.1f} s wall"
    )
    for key, path in files.as_dict().items():
        print(f"{key + ':':<18}{path}")
    return 0
