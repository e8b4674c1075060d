"""``flexparcel run``: one of the paper's tests (swing, vertical or horizontal drop) on a
consignment, from its snapshot (assembled first when none is given), or the conveyor scene
with several consignments (:mod:`flexparcel.cli.conveyor_job`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from flexparcel.cli.assemble_cmd import CONSIGNMENT_HELP, element_size_m

__all__ = ["register", "run"]

TESTS = ("swing", "drop-vertical", "drop-horizontal")  # as cli.consignment_jobs.TESTS
SCENARIOS = (*TESTS, "conveyor")
_CONVEYOR_ONLY = ("consignments", "belt_speed", "deflector_angle", "scene", "snapshot_dir",
                  "pair_reach", "start_speed", "preview", "content_stiffness",
                  "workers")  # fmt: skip
_TEST_ONLY = ("consignment", "snapshot", "assignments")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run the swing or a drop test on a consignment",
        description="Run the paper's swing test (20 mm clamped, released horizontal, 1.4 s) "
        "or drop test (200 mm onto a rigid plate standing on its edge or lying flat, 0.3 s) "
        "and write DIR/responses.json, DIR/results.npz, ParaView files DIR/paraview/*.pvd and "
        "the pictures DIR/frames.png and DIR/response.png. Parameters not set keep the "
        "consignment's own packaging modulus and damping ratio and the paper's Table 6 contact "
        "values. 'conveyor' runs the paper's bulk scene (consignments on a belt with two "
        "deflectors, 2 s) and writes DIR/responses.json, DIR/results.npz, "
        "DIR/paraview/conveyor.pvd, DIR/snapshots.png (top views at 0, 1, 2 s), "
        "DIR/trajectories.png and DIR/animation.gif; snapshots are assembled into "
        "DIR/snapshots/ (reused when present) unless --snapshot-dir is given. A conveyor "
        "run saves DIR/checkpoint.npz about once a minute: the same command resumes an "
        "interrupted run from it.",
    )
    p.add_argument("test", choices=SCENARIOS, help="which test or scenario")
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
    g = p.add_argument_group("conveyor")
    g.add_argument(
        "--consignments",
        default=None,
        metavar="A,B,...",
        help="conveyor: consignments queued upstream of the first deflector, "
        "first = leading (default KPBW,PB,KP,BW); presets or .toml files",
    )
    g.add_argument(
        "--belt-speed",
        type=float,
        default=None,
        metavar="M/S",
        help="conveyor: belt speed [m/s] (default 1.6)",
    )
    g.add_argument(
        "--deflector-angle",
        type=float,
        default=None,
        metavar="DEG",
        help="conveyor: deflector angle to the belt direction [deg] (default 45)",
    )
    g.add_argument(
        "--start-speed",
        type=float,
        default=None,
        metavar="M/S",
        help="conveyor: initial velocity of the queued consignments along the "
        "belt [m/s] (default 0: at rest on the running belt)",
    )
    g.add_argument(
        "--scene",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="conveyor: scene file (belt, deflectors, placements; see "
        "examples/conveyor_scene.toml); options given on the command line win",
    )
    g.add_argument(
        "--snapshot-dir",
        type=Path,
        default=None,
        metavar="DIR",
        help="conveyor: take snapshots from DIR (NAME.npz or NAME/snapshot.npz, "
        "e.g. from flexparcel assemble NAME --out DIR/NAME) instead of assembling",
    )
    g.add_argument(
        "--pair-reach",
        type=float,
        default=None,
        metavar="M",
        help="conveyor: give consignment-consignment contact only to pairs that "
        "start closer than this [m] (default: every pair)",
    )
    g.add_argument(
        "--content-stiffness",
        type=float,
        default=None,
        metavar="N_PER_MM",
        help="conveyor: packaging-content contact stiffness c [N/mm] (and stick stiffness "
        "k_t = c) of every consignment (default: Table 6's 649, as assembled); softer is "
        "faster and lets the film settle deeper on its content",
    )
    g.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="conveyor: integrate consignments that cannot touch as separate models, each "
        "with its own time steps, on N worker processes, merged when they come close "
        "(default 2; 0: the whole scene as one model)",
    )
    g.add_argument(
        "--preview",
        action="store_true",
        default=None,
        help="conveyor: no stepping; write the files of the frames DIR/checkpoint.npz holds "
        "so far (a run going on in another process, or an interrupted one) to DIR/preview/",
    )
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

    if args.test == "conveyor":
        return _run_conveyor(args)
    given = [k for k in _CONVEYOR_ONLY if getattr(args, k, None) is not None]
    if given:
        opts = ", ".join("--" + k.replace("_", "-") for k in given)
        raise ValueError(f"{opts} only apply to 'flexparcel run conveyor', not {args.test}")
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


def _run_conveyor(args: argparse.Namespace) -> int:
    import sys

    from flexparcel.cli.conveyor_job import (
        DEFAULT_WORKERS,
        content_law_for,
        conveyor_job,
        group_settings,
        parse_consignment_list,
        snapshot_for,
    )
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.userfile import resolve_consignment
    from flexparcel.integrate.errors import ConvergenceError
    from flexparcel.scenarios.conveyor_scene import (
        PAPER_CONSIGNMENTS,
        SceneLayout,
        check_layout,
        default_layout,
        load_scene_file,
        paper_conveyor,
    )

    bad = [k for k in _TEST_ONLY if getattr(args, k, None) not in (None, [])]
    if bad:
        opts = ", ".join("--" + ("set" if k == "assignments" else k) for k in bad)
        raise ValueError(f"{opts} do not apply to the conveyor (use --consignments, --scene, "
                         "--snapshot-dir)")  # fmt: skip
    scene = load_scene_file(args.scene) if args.scene is not None else None
    if scene is not None and scene.placements and args.consignments is not None:
        raise ValueError("--consignments cannot replace the placements of --scene's "
                         "[[consignment]] tables")  # fmt: skip
    t_end = args.t_end if args.t_end is not None else (scene.t_end if scene and scene.t_end
                                                       else 2.0)  # fmt: skip
    if not 0.0 < t_end <= 10.0:
        raise ValueError(f"--t-end must be in (0, 10] s, got {t_end:g}")
    size = element_size_m(args.element_size)
    if size is None and scene is not None:
        size = scene.element_size
    for opt, v, lo, hi, unit in (("--belt-speed", args.belt_speed, 0.0, 10.0, "m/s"),
                                 ("--deflector-angle", args.deflector_angle, 10.0, 90.0, "deg"),
                                 ("--start-speed", args.start_speed, 0.0, 10.0, "m/s"),
                                 ("--pair-reach", args.pair_reach, 0.0, 1e3, "m")):  # fmt: skip
        if v is not None and not lo <= v <= hi:
            raise ValueError(f"{opt} must be in [{lo:g}, {hi:g}] {unit}, got {v:g}")
    conveyor = scene.conveyor if scene is not None else paper_conveyor()
    if args.belt_speed is not None or args.deflector_angle is not None:
        from dataclasses import replace

        speed = conveyor.belt_speed if args.belt_speed is None else args.belt_speed
        angle = conveyor.deflector_angle_deg if args.deflector_angle is None else (
            args.deflector_angle)  # fmt: skip
        if scene is None:
            conveyor = paper_conveyor(speed, angle)
        else:
            conveyor = replace(conveyor, belt_speed=speed, deflector_angle_deg=angle)
    if scene is not None and args.consignments is None:
        refs = dict(scene.consignments)
    else:
        names = parse_consignment_list(args.consignments or ",".join(PAPER_CONSIGNMENTS))
        refs = {}
        for n in names:
            key = Path(n).stem if n.lower().endswith(".toml") else n.replace("/", "").upper()
            refs[key] = n
    builds = {k: resolve_consignment(ref, size) for k, ref in refs.items()}
    if scene is not None and scene.placements:
        layout = SceneLayout(conveyor, scene.placements, scene.gap_above_belt)
        if args.start_speed is not None:
            from dataclasses import replace

            layout = SceneLayout(conveyor, tuple(replace(p, speed=args.start_speed)
                                                 for p in scene.placements),
                                 scene.gap_above_belt)  # fmt: skip
    else:
        start = args.start_speed if args.start_speed is not None else (
            scene.start_speed if scene is not None else 0.0)  # fmt: skip
        gap = scene.gap_above_belt if scene is not None else None
        kw = {} if gap is None else {"gap_above_belt": gap}
        layout = default_layout(builds, conveyor, speed=start, **kw)
    check_layout(layout, builds)  # before any (long) assembly
    content_law = content_law_for(args.content_stiffness)
    workers = DEFAULT_WORKERS if args.workers is None else args.workers
    group_settings(workers)  # its range, before any assembly
    progress = not args.no_progress
    try:
        snaps, sources = {}, {}
        for key, build in builds.items():
            snaps[key], sources[key] = snapshot_for(
                key, build, args.out, snapshot_dir=args.snapshot_dir,
                element_size_given=size is not None, progress=progress,
            )  # fmt: skip
        run_, summary, files = conveyor_job(
            snaps, layout, args.out, t_end=t_end, pair_reach=args.pair_reach,
            progress=progress, preview=bool(args.preview), content_law=content_law,
            workers=workers,
            extra={"snapshots": sources,
                                      "scene_file": None if args.scene is None
                                      else str(args.scene)},
        )  # fmt: skip
    except (AssemblyError, ConvergenceError) as exc:
        print(f"flexparcel run: conveyor failed: {exc}", file=sys.stderr)
        return 1
    print(
        f"conveyor{' (preview of the checkpoint)' if args.preview else ''}: "
        f"{len(layout.placements)} consignments, {summary['simulated_s']:g} s "
        f"simulated in {summary['wall_s']:.1f} s wall ({summary['steps']} steps)"
    )
    for name, r in run_.responses.items():
        c0, c1 = r.centroid[0], r.centroid[-1]
        exit_ = "-" if r.exit_time is None else f"{r.exit_time:.2f} s"
        contact = ", ".join(f"{v:.3f}" for v in r.deflector_contact_time)
        print(f"  {name}: x {c0[0]:.3f} -> {c1[0]:.3f} m, y {c0[1]:.3f} -> {c1[1]:.3f} m, "
              f"exit {exit_}, deflector contact [{contact}] s")  # fmt: skip
    for key, path in files.items():
        print(f"{key + ':':<18}{path}")
    return 0
