"""``flexparcel assemble``: open, fill, close and settle a consignment; write its snapshot."""

from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["register", "run", "shape_line", "CONSIGNMENT_HELP"]

CONSIGNMENT_HELP = (
    "a paper consignment (KPBW or KP/BW, PB, KP, BW) or a consignment .toml file "
    "(see examples/consignment_small.toml)"
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "assemble",
        help="assemble a consignment and save its settled snapshot",
        description="Assemble a consignment as in the paper (opening forces, content placed, "
        "contact on, forces released, settled to rest) and write DIR/snapshot.npz (the start "
        "of every test), DIR/assembly.json, DIR/assembled.png and ParaView files "
        "DIR/paraview/assembled.pvd. An interrupted assembly, run again with the same --out, "
        "resumes from DIR/assembly-checkpoint.npz.",
    )
    p.add_argument("consignment", help=CONSIGNMENT_HELP)
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument(
        "--element-size",
        type=float,
        default=None,
        metavar="MM",
        help="shell edge length [mm] (default: the preset's 10 mm, 5 mm for BW, or the file's)",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress line on stderr")
    p.set_defaults(func=run, out_is_dir=True)


def element_size_m(mm: float | None) -> float | None:
    """``--element-size`` [mm] as metres (None stays None)."""
    return None if mm is None else mm * 1e-3


def shape_line(shape: dict) -> str:
    """One line on the assembled shape (:mod:`flexparcel.consignments.shape`)."""
    outer = " x ".join(f"{v:.0f}" for v in shape["outer_mm"])
    table2 = " x ".join(f"{v:g}" for v in shape["table2_mm"])
    gap = shape["gap_mm"]
    line = (
        f"shape: {outer} mm (Table 2: {table2} mm), film on the content within "
        f"{gap['max']:.2f} mm (bound {shape['gap_bound_mm']:.1f} mm), "
        f"{shape['content_outside']} content node(s) outside"
    )
    surface = shape.get("content_surface")  # absent in snapshots of older assemblies
    if surface:
        line += (
            f", the box's surface outside by at most {surface['depth_mm']:.1f} mm "
            f"(chord bound {surface['bound_mm']:.1f} mm)"
        )
    return line


def run(args: argparse.Namespace) -> int:
    from flexparcel.cli.outdir import report_failure
    from flexparcel.cli.snapshots import ASSEMBLY_CHECKPOINT, UNSETTLED_FILES, assemble_job
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.userfile import resolve_consignment

    build = resolve_consignment(args.consignment, element_size_m(args.element_size))
    print(
        f"assembling {build.spec.id}: {build.spec.length_mm:g} x {build.spec.width_mm:g} mm "
        f"{build.spec.packaging_material} (flat {build.flat_size[0] * 1e3:.0f} x "
        f"{build.flat_size[1] * 1e3:.0f} mm), {build.element_size * 1e3:g} mm elements"
    )
    checkpoint = args.out / ASSEMBLY_CHECKPOINT
    if checkpoint.exists():
        print(f"resuming from {checkpoint} (an interrupted assembly of the same consignment)")
    try:
        snap, files = assemble_job(build, args.out, progress=not args.no_progress)
    except AssemblyError as exc:
        report_failure(f"flexparcel assemble: assembly failed: {exc}")
        if exc.unsettled is not None:
            paths = ", ".join(str(args.out / name) for name in UNSETTLED_FILES)
            report_failure(f"its last state: {paths}")
        return 1
    info = snap.info
    print(
        f"settled at t = {info['end_time_s']:.3f} s after {info['steps']} steps, "
        f"{info['wall_s']:.1f} s wall (kinetic energy {info['kinetic_energy_J']:.2g} J)"
    )
    print(shape_line(info["shape"]))
    for key, path in files.as_dict().items():
        print(f"{key + ':':<18}{path}")
    return 0
