"""``flexparcel bench``: run named benchmark cases and write JSON."""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    from flexparcel.bench import CASES, DEFAULT_CASES

    p = sub.add_parser(
        "bench",
        help="run benchmark cases and write a JSON report",
        description="Run named benchmark cases; report simulated seconds per "
        "wall second and the ratio to the paper's RecurDyn times.",
    )
    p.add_argument(
        "cases",
        nargs="*",
        default=list(DEFAULT_CASES),
        metavar="CASE",
        help=f"cases to run: {', '.join(CASES)} (default: {', '.join(DEFAULT_CASES)}; the "
        "conveyor cases are long, name them)",
    )
    p.add_argument("--out", type=Path, default=Path("out/bench.json"), help="JSON file to write")
    p.add_argument("--quick", action="store_true", help="short simulated times (smoke test)")
    p.add_argument("--no-progress", action="store_true")
    g = p.add_argument_group("conveyor cases (recorded in the JSON)")
    g.add_argument(
        "--conveyor-consignments",
        default="KPBW,PB,KP,BW",
        metavar="A,B,...",
        help="conveyor: consignments of the scene (default KPBW,PB,KP,BW)",
    )
    g.add_argument(
        "--element-size",
        type=float,
        default=None,
        metavar="MM",
        help="conveyor cases: shell edge length [mm] (default 25 for the conveyor; "
        "the scaling case keeps its consignment file's unless given)",
    )
    g.add_argument(
        "--t-end",
        type=float,
        default=None,
        metavar="S",
        help="conveyor cases: simulated time [s] (default 2 for conveyor, 0.01 for "
        "conveyor-scaling; --quick: 0.005 / 0.002)",
    )
    g.add_argument(
        "--start-speed",
        type=float,
        default=0.0,
        metavar="M/S",
        help="conveyor: initial speed of the consignments along the belt [m/s]",
    )
    g.add_argument(
        "--content-stiffness",
        type=float,
        default=None,
        metavar="N_PER_MM",
        help="conveyor: packaging-content contact stiffness [N/mm] in [1, 10000] (default: "
        "Table 6's 649), as in 'run conveyor'",
    )
    g.add_argument(
        "--stick-stiffness",
        type=float,
        default=None,
        metavar="N_PER_MM",
        help="conveyor: packaging-content stick-model stiffness k_t [N/mm] in [0.01, 10000] "
        "(default: k_t = c); changes the physics, as in 'run conveyor'",
    )
    g.add_argument(
        "--snapshot-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="conveyor and kpbw-tests cases: snapshots NAME.npz or NAME/snapshot.npz "
        "(else assembled and cached next to --out)",
    )
    g.add_argument(
        "--workers",
        type=int,
        default=2,
        metavar="N",
        help="conveyor cases: worker processes for the consignments, as in 'run conveyor' "
        "(default 2; 0: the whole scene as one model)",
    )
    g.add_argument(
        "--scaling-counts",
        default="1,2,4,8",
        metavar="N,N,...",
        help="conveyor-scaling: consignment counts (default 1,2,4,8)",
    )
    g.add_argument(
        "--scaling-consignment",
        default="examples/consignment_small.toml",
        metavar="NAME",
        help="conveyor-scaling: the copied consignment",
    )
    g.add_argument(
        "--sizes",
        default="25,15,10,7",
        metavar="MM,MM,...",
        help="kpbw-convergence: element sizes [mm] (default 25,15,10,7); finished tests in "
        "bench-kpbw-convergence/ next to --out are not run again",
    )
    p.set_defaults(func=run)


def _number_list(option: str, text: str, kind, lo: float, hi: float, unit: str) -> tuple:
    """``text``, numbers separated by commas, as a tuple of ``kind``; an error naming
    ``option`` and its range otherwise."""
    what = "integers" if kind is int else "numbers"
    try:
        values = tuple(kind(c) for c in text.split(","))
    except ValueError:
        raise ValueError(f"{option} must be {what} separated by commas, got {text!r}") from None
    if not values or min(values) < lo or max(values) > hi:
        raise ValueError(f"{option} must be in [{lo:g}, {hi:g}]{unit}, got {text!r}")
    return values


def run(args: argparse.Namespace) -> int:
    from flexparcel.bench import run_benchmarks
    from flexparcel.cli.progress import SimulationProgress

    counts = _number_list("--scaling-counts", args.scaling_counts, int, 1, 200, "")
    sizes = _number_list("--sizes", args.sizes, float, 1.0, 100.0, " mm")
    if args.t_end is not None and not 0.0 < args.t_end <= 10.0:
        raise ValueError(f"--t-end must be in (0, 10] s, got {args.t_end:g}")
    if args.element_size is not None and not 1.0 <= args.element_size <= 100.0:
        raise ValueError(f"--element-size must be in [1, 100] mm, got {args.element_size:g}")
    from flexparcel.scenarios.conveyor_scenario import content_law_for, group_settings

    content_law_for(args.content_stiffness, "--content-stiffness",
                    stick_n_per_mm=args.stick_stiffness,
                    stick_label="--stick-stiffness")  # before any run  # fmt: skip
    group_settings(args.workers, "--workers")
    work = Path(args.out).parent / "bench-conveyor"
    common = {"t_end": args.t_end, "snapshot_dir": args.snapshot_dir, "work": work,
              "workers": args.workers}  # fmt: skip
    options = {
        "conveyor": {
            **common,
            "consignments": [c.strip() for c in args.conveyor_consignments.split(",")],
            "element_size_mm": 25.0 if args.element_size is None else args.element_size,
            "start_speed": args.start_speed,
            "content_stiffness_n_per_mm": args.content_stiffness,
            "stick_stiffness_n_per_mm": args.stick_stiffness,
        },
        "consignment-assembly": {"element_size_mm": args.element_size},
        "kpbw-tests": {"element_size_mm": args.element_size, "snapshot_dir": args.snapshot_dir},
        "kpbw-convergence": {
            "sizes_mm": sizes,
            "work": Path(args.out).parent / "bench-kpbw-convergence",
        },
        "conveyor-scaling": {
            **common,
            "counts": counts,
            "consignment": args.scaling_consignment,
            "element_size_mm": args.element_size,
            "plot": Path(args.out).with_suffix("").as_posix() + "-scaling.png",
        },
    }
    results = run_benchmarks(
        args.cases,
        args.out,
        quick=args.quick,
        progress_factory=lambda n: SimulationProgress(n, enabled=not args.no_progress),
        case_options=options,
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
