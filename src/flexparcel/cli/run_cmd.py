"""``flexparcel run``: a scenario of :mod:`flexparcel.scenarios.registry` (the paper's swing,
vertical or horizontal drop test, or a third-party one) on a consignment, from its snapshot
(assembled first when none is given), or the conveyor scene with several consignments. The
scenarios do the work and write the files; this module turns options into their parameters
and settings, finds the snapshots and prints what came out."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from flexparcel.cli.assemble_cmd import CONSIGNMENT_HELP, element_size_m

__all__ = ["register", "run", "run_and_write", "format_responses", "parse_consignment_list"]

TESTS = ("swing", "drop-vertical", "drop-horizontal")
"""The built-in scenarios on one consignment (any other registered one runs the same way)."""
SCENARIOS = (*TESTS, "conveyor")
_CONVEYOR_FLAGS = {"belt_speed": "--belt-speed", "deflector_angle": "--deflector-angle",
                   "start_speed": "--start-speed", "pair_reach": "--pair-reach",
                   "content_stiffness": "--content-stiffness",
                   "stick_stiffness": "--stick-stiffness",
                   "deflector_friction": "--deflector-friction"}  # fmt: skip
"""Conveyor scenario parameter -> the option that sets it."""
_CONVEYOR_ONLY = ("consignments", "belt_speed", "deflector_angle", "scene", "snapshot_dir",
                  "pair_reach", "start_speed", "preview", "content_stiffness",
                  "stick_stiffness", "deflector_friction", "workers")  # fmt: skip
_TEST_ONLY = ("consignment", "snapshot", "assignments")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run a scenario: the swing test, a drop test or the conveyor",
        description="Run the paper's swing test (20 mm clamped, released horizontal, 1.4 s) "
        "or drop test (200 mm onto a rigid plate standing on its edge or lying flat, 0.3 s) "
        "and write DIR/report.html (the report to open first: responses next to the paper's "
        "Table 7, pictures, the 3-D viewer DIR/view.html, wall time next to RecurDyn's), "
        "DIR/responses.json, DIR/results.npz, ParaView files DIR/paraview/*.pvd and "
        "the pictures DIR/frames.png and DIR/response.png. Parameters not set keep the "
        "consignment's own packaging modulus and damping ratio and the paper's Table 6 contact "
        "values. 'conveyor' runs the paper's bulk scene (consignments on a belt with two "
        "deflectors, 2 s) and writes DIR/report.html (jam verdict, exit table, speed, yaw "
        "and deflector force against time), DIR/responses.json, DIR/results.npz, "
        "DIR/paraview/conveyor.pvd, DIR/snapshots.png (top views at 0, 1, 2 s), "
        "DIR/trajectories.png, DIR/motion.png and DIR/animation.gif; snapshots are assembled into "
        "DIR/snapshots/ (reused when present) unless --snapshot-dir is given. Every run "
        "saves DIR/checkpoint.npz about once a minute: the same command resumes an "
        "interrupted run from it (the swing's jaws close again, the same way, first); the "
        "swing and the drops remove it once their results are written.",
    )
    # no argparse choices: the registry (with third-party entry points) is read when running,
    # so that --help imports no scenario
    names = ", ".join(SCENARIOS)
    p.add_argument("test", metavar="SCENARIO",
                   help=f"which test or scenario: {names}, or a registered one")  # fmt: skip
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
        "contact_damping_packaging_ground, friction_packaging_content=0.3 or "
        "friction_packaging_ground=0.3 (friction coefficients, not in the paper); repeatable",
    )
    p.add_argument("--t-end", type=float, default=None, metavar="S",
                   help="simulated time [s] (default 1.4 swing, 0.3 drops)")  # fmt: skip
    p.add_argument("--element-size", type=float, default=None, metavar="MM",
                   help="shell edge length [mm] (must match --snapshot's)")  # fmt: skip
    p.add_argument("--hold", action="store_true",
                   help="drop-vertical: hold the consignment by its top 20 mm under gravity "
                   "for 0.2 s before the release, instead of releasing the snapshot as "
                   "assembled (without gravity); see docs/scenarios.md")  # fmt: skip
    p.add_argument("--air-drag", type=float, default=None, metavar="CD",
                   help="swing and drops: drag coefficient of the envelope in still air "
                   "(a flat plate: 1.17); default none, as the paper's model")  # fmt: skip
    p.add_argument("--membrane", choices=("elastic", "tension-field"), default=None,
                   help="swing and drops: the packaging's membrane law in the test; "
                   "tension-field lets the film wrinkle (docs/physics.md); default: the "
                   "snapshot's (elastic for the shipped snapshots)")  # fmt: skip
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
        "--stick-stiffness",
        type=float,
        default=None,
        metavar="N_PER_MM",
        help="conveyor: stick-model stiffness k_t [N/mm] of every consignment's "
        "packaging-content friction, in [0.01, 10000] (default: k_t = c, the contact "
        "stiffness). This changes the physics: the content pre-slides mu_s F_N / k_t in its "
        "packaging before it slips; 6.49 (k_t = c / 100) took a quarter of the steps on "
        "the paper's four at 25 mm (docs/scenarios.md, 'Stick stiffness')",
    )
    g.add_argument(
        "--deflector-friction",
        type=float,
        default=None,
        metavar="MU",
        help="conveyor: friction coefficient (static = dynamic) of every consignment on the "
        "deflectors, in [0, 2] (default: the friction table's, by packaging surface)",
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
    p.set_defaults(func=run, out_is_dir=True)


def run(args: argparse.Namespace) -> int:
    from flexparcel.cli.outdir import report_failure
    from flexparcel.cli.snapshots import shipped_or_assembled
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.snapshot import check_snapshot_matches, load_snapshot
    from flexparcel.consignments.userfile import resolve_consignment
    from flexparcel.integrate.errors import ConvergenceError
    from flexparcel.scenarios.base import CHECKPOINT_FILE, T_END
    from flexparcel.scenarios.registry import get_scenario

    if args.test == "conveyor":
        if args.air_drag is not None:
            raise ValueError("--air-drag applies to the swing and the drops, not the conveyor")
        if args.membrane is not None:
            raise ValueError("--membrane applies to the swing and the drops, not the conveyor")
        if args.hold:
            raise ValueError("--hold applies to drop-vertical only, not conveyor")
        return _run_conveyor(args)
    options = {} if args.air_drag is None else {"air_drag": args.air_drag}
    if args.membrane is not None:
        options["membrane"] = args.membrane
    if args.hold:
        if args.test != "drop-vertical":
            raise ValueError(f"--hold applies to drop-vertical only, not {args.test}")
        from flexparcel.scenarios.holding import DropHold

        options["hold"] = DropHold()
    # an unknown name fails here, listing the known ones
    scenario = get_scenario(args.test, **options)
    given = [k for k in _CONVEYOR_ONLY if getattr(args, k, None) is not None]
    if given:
        opts = ", ".join("--" + k.replace("_", "-") for k in given)
        raise ValueError(f"{opts} only apply to 'flexparcel run conveyor', not {args.test}")
    if args.consignment is None and args.snapshot is None:
        raise ValueError("give --consignment (KPBW, PB, KP, BW or a .toml file) or --snapshot")
    if args.t_end is not None:
        T_END.check(args.t_end, "--t-end")
    size = element_size_m(args.element_size)
    build = None
    if args.consignment is not None:
        build = resolve_consignment(args.consignment, size)
    snap = None
    if args.snapshot is not None:
        snap = load_snapshot(args.snapshot)
        check_snapshot_matches(snap, build, size)
    # bad --set values fail here, before a (long) assembly
    check_set_bounds(args.assignments)
    params = scenario.resolve(args.assignments, snap.build if snap is not None else build)
    progress = not args.no_progress
    checkpoint = args.out / CHECKPOINT_FILE
    scenario.set_checkpoint(checkpoint)
    try:
        if snap is None:
            snap, source = shipped_or_assembled(build, args.out, progress=progress)
        else:
            source = str(args.snapshot)
        if checkpoint.exists():
            print(f"{args.test}: resuming from {checkpoint}", file=sys.stderr)
        result, files = run_and_write(scenario, snap, params, args.out, t_end=args.t_end,
                                      progress=progress, extra={"snapshot": source})  # fmt: skip
    except (AssemblyError, ConvergenceError) as exc:
        report_failure(f"flexparcel run: {args.test} failed: {exc}")
        return 1
    checkpoint.unlink(missing_ok=True)  # its frames are in results.npz now
    responses = format_responses(scenario.responses(result))
    simulated = float(result.simulation.time[-1] - result.simulation.time[0])
    print(f"{args.test} {snap.build.spec.id}: {responses}; {simulated:g} s simulated in "
          f"{result.wall_s:.1f} s wall")  # fmt: skip
    for key, path in files.items():
        print(f"{key + ':':<18}{path}")
    return 0


def set_bounds() -> dict[str, tuple[str, float, float, bool, bool, str]]:
    """``--set`` name -> (consignment-file key, low, high, low open, high open, unit): the
    bounds a consignment file puts on the same quantity
    (:data:`flexparcel.consignments.userfile.MATERIAL_KEYS`), in the same paper units."""
    from flexparcel.consignments.userfile import MATERIAL_KEYS

    by_field = {field: (key, lo, hi, unit) for key, (field, _f, lo, hi, unit)
                in MATERIAL_KEYS.items()}  # fmt: skip
    out = {}
    for name in ("youngs_modulus", "damping_ratio"):
        key, lo, hi, unit = by_field[name]
        out[name] = (key, float(lo[1:]), float(hi[:-1]), lo[0] == "(", hi[-1] == ")", unit)
    return out


def check_set_bounds(assignments: list[str]) -> None:
    """``ValueError`` for a ``--set NAME=VALUE`` outside the bounds a consignment file
    allows for the same quantity (e.g. ``damping_ratio`` in [0, 1] s); other names and
    values that are no numbers are left to the scenario's own check."""
    import math

    bounds = set_bounds()
    for text in assignments:
        name, sep, value = text.partition("=")
        name = name.strip()
        if not sep or name not in bounds:
            continue
        try:
            v = float(value)
        except ValueError:
            continue
        key, lo, hi, lo_open, hi_open, unit = bounds[name]
        ok = math.isfinite(v) and (v > lo if lo_open else v >= lo)
        ok = ok and (v < hi if hi_open else v <= hi)
        if not ok:
            span = f"{'(' if lo_open else '['}{lo:g}, {hi:g}{')' if hi_open else ']'} {unit}"
            raise ValueError(
                f"--set {text.strip()}: {name} must be in {span} (the bound of {key} in a "
                f"consignment file), got {v:g}"
            )


def run_and_write(scenario, snapshot, parameters, out: Path, *, t_end: float | None = None,
                  progress: bool = True, extra: dict | None = None):  # fmt: skip
    """Run ``scenario`` on one consignment's ``snapshot`` with a progress bar on stderr and
    write its files (with its pictures) into ``out``; returns the result and name -> path."""
    from flexparcel.cli.progress import SimulationProgress
    from flexparcel.viz.scenario_pictures import pictures_for

    with SimulationProgress(f"{scenario.name} {snapshot.build.spec.id}", enabled=progress) as bar:
        result = scenario.run(snapshot, parameters, t_end=t_end, progress=bar)
    files = scenario.write(result, out, extra=extra, pictures=pictures_for(scenario.name))
    return result, files


def format_responses(responses) -> str:
    """``"name = 12.34, other = not reached (why)"`` of named Responses (values in their
    units, two decimals)."""
    return ", ".join(
        f"{k} = {r.value:.2f}" if r.reached else f"{k} = not reached ({r.note})"
        for k, r in responses.items()
    )


def parse_consignment_list(text: str) -> list[str]:
    """``"KPBW,PB,KP,BW"`` -> names; empty entries and duplicates raise ``ValueError``."""
    names = [s.strip() for s in text.split(",")]
    if not names or any(not n for n in names):
        raise ValueError(f"--consignments must be a comma-separated list of names, got {text!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"--consignments: {dup} given twice; use --scene for copies")
    return names


def _conveyor_refs(args: argparse.Namespace, scene) -> dict[str, str]:
    """Consignment key -> preset name or file: the scene file's, else --consignments (default
    the paper's four)."""
    from flexparcel.scenarios.conveyor_scene import PAPER_CONSIGNMENTS

    if scene is not None and args.consignments is None:
        return dict(scene.consignments)
    refs = {}
    for n in parse_consignment_list(args.consignments or ",".join(PAPER_CONSIGNMENTS)):
        key = Path(n).stem if n.lower().endswith(".toml") else n.replace("/", "").upper()
        refs[key] = n
    return refs


def _run_conveyor(args: argparse.Namespace) -> int:
    from flexparcel.cli.outdir import report_failure
    from flexparcel.cli.progress import SimulationProgress
    from flexparcel.cli.snapshots import snapshot_for
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.userfile import resolve_consignment
    from flexparcel.integrate.errors import ConvergenceError
    from flexparcel.scenarios.base import T_END
    from flexparcel.scenarios.conveyor_scenario import CHECKPOINT_FILE, WORKERS, group_settings
    from flexparcel.scenarios.conveyor_scene import load_scene_file
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.viz.scenario_pictures import pictures_for

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
    T_END.check(t_end, "--t-end")
    size = element_size_m(args.element_size)
    if size is None and scene is not None:
        size = scene.element_size
    workers = WORKERS.default if args.workers is None else args.workers
    group_settings(workers, "--workers")  # its range, before any assembly
    out: Path = args.out
    checkpoint = out / CHECKPOINT_FILE
    scenario = get_scenario("conveyor", scene=scene, workers=workers,
                            checkpoint=checkpoint, preview=bool(args.preview))  # fmt: skip
    # each option checked against its parameter's range, named as the user typed it
    params = scenario.resolve({
        name: scenario.parameter(name).check(getattr(args, name), flag)
        for name, flag in _CONVEYOR_FLAGS.items() if getattr(args, name) is not None
    })  # fmt: skip
    builds = {k: resolve_consignment(ref, size) for k, ref in _conveyor_refs(args, scene).items()}
    layout = scenario.layout(builds, params)  # checked before any (long) assembly
    if args.preview and not checkpoint.is_file():
        raise ValueError(f"--preview: no checkpoint {checkpoint} (start the run first)")
    progress = not args.no_progress
    try:
        snaps, sources = {}, {}
        for key, build in builds.items():
            snaps[key], sources[key] = snapshot_for(
                key, build, out, snapshot_dir=args.snapshot_dir,
                element_size_given=size is not None, progress=progress,
            )  # fmt: skip
        out.mkdir(parents=True, exist_ok=True)
        if checkpoint.exists() and not args.preview:
            print(f"conveyor: resuming from {checkpoint}", file=sys.stderr)
        label = f"conveyor ({len(layout.placements)} consignments)"
        with SimulationProgress(label, enabled=progress and not args.preview) as bar:
            result = scenario.run(snaps, params, t_end=t_end, progress=bar)
        extra = {"snapshots": sources,
                 "scene_file": None if args.scene is None else str(args.scene)}  # fmt: skip
        files = scenario.write(result, out / "preview" if args.preview else out, extra=extra,
                               pictures=pictures_for("conveyor"))  # fmt: skip
    except (AssemblyError, ConvergenceError) as exc:
        report_failure(f"flexparcel run: conveyor failed: {exc}")
        return 1
    res = result.simulation
    print(
        f"conveyor{' (preview of the checkpoint)' if args.preview else ''}: "
        f"{len(layout.placements)} consignments, {res.time[-1] - res.time[0]:g} s "
        f"simulated in {result.wall_s:.1f} s wall ({int(res.stats.get('steps', 0))} steps)"
    )
    for name, r in result.record.responses.items():
        c0, c1 = r.centroid[0], r.centroid[-1]
        exit_ = "-" if r.exit_time is None else f"{r.exit_time:.2f} s"
        # a deflector never touched shows "-", not 0.000 (which reads as contact at t = 0)
        contact = ", ".join(f"{v:.3f}" if v > 0.0 else "-" for v in r.deflector_contact_time)
        print(f"  {name}: x {c0[0]:.3f} -> {c1[0]:.3f} m, y {c0[1]:.3f} -> {c1[1]:.3f} m, "
              f"exit {exit_}, deflector contact for [{contact}] s")  # fmt: skip
    for key, path in files.items():
        print(f"{key + ':':<18}{path}")
    return 0
