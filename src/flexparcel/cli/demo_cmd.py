"""``flexparcel demo`` (``make demo``): assemble the paper's KP/BW consignment, run its swing,
vertical and horizontal drop tests with the calibrated parameters of Table 6, and write the
report: ``report.html`` (the user's: pictures embedded, the 3-D viewers, responses next to the
paper's Table 7 and the real-world tests, wall times next to RecurDyn's;
:func:`flexparcel.viz.report.write_demo_report`) and the same numbers as ``report.md``.

``--quick`` runs the same on a coarse mesh (25 mm shells) with shorter simulated times, as a
check of the pipeline (drops from 50 mm so that the shortened runs still hold the impact);
its numbers are not a comparison.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

from flexparcel.scenarios.paper_reference import RECURDYN_WALL_S, TEST_REFERENCES

__all__ = ["register", "run", "PAPER_TABLE7", "RECURDYN_WALL_S", "REAL_TEST_MM",
           "report_markdown", "given_snapshot"]  # fmt: skip

PAPER_TABLE7 = {ref.response if ref.test == "swing" else ref.test: ref.table7
                for ref in TEST_REFERENCES}  # fmt: skip
"""Paper Table 7: RecurDyn re-runs of KP/BW with the Table 6 parameters [mm]
(:data:`flexparcel.scenarios.paper_reference.TEST_REFERENCES`)."""
REAL_TEST_MM = {ref.response if ref.test == "swing" else ref.test: ref.real
                for ref in TEST_REFERENCES}  # fmt: skip
"""The real-world tests the calibration aimed at [mm] (paper Fig. 27 and section 4.3)."""

FULL = {"element_size_mm": 10.0, "drop_height": 0.200,
        "t_end": {"swing": 1.4, "drop-vertical": 0.3, "drop-horizontal": 0.3}}  # fmt: skip
# --quick: coarse shells; the swing's first 0.25 s (the fall towards the first swing); the drops
# from 50 mm instead of 200 mm, so that 0.15 s still holds the impact and the rebound
QUICK = {"element_size_mm": 25.0, "drop_height": 0.050,
         "t_end": {"swing": 0.25, "drop-vertical": 0.15, "drop-horizontal": 0.15}}  # fmt: skip

_RESPONSE_ROWS = (
    ("first swing [mm]", "swing", "first_swing_mm", "first_swing_mm"),
    ("second swing [mm]", "swing", "second_swing_mm", "second_swing_mm"),
    ("vertical drop rebound [mm]", "drop-vertical", "rebound_mm", "drop-vertical"),
    ("horizontal drop rebound [mm]", "drop-horizontal", "rebound_mm", "drop-horizontal"),
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="KP/BW: assemble, swing and drop tests, report against the paper",
        description="Assemble the paper's KP/BW consignment, run the swing, vertical and "
        "horizontal drop tests with the paper's Table 6 parameters and write DIR/report.html "
        "(pictures, 3-D viewers, responses next to the paper's Table 7 and the real-world "
        "tests, wall times next to RecurDyn's; the same numbers in DIR/report.md). The last "
        "line printed is the report's path.",
    )
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output directory")
    p.add_argument(
        "--quick",
        action="store_true",
        help="coarse 25 mm mesh and shorter simulated times (a few minutes; a pipeline "
        "check, not a comparison with the paper)",
    )
    p.add_argument("--element-size", type=float, default=None, metavar="MM",
                   help="shell edge length [mm] (default 10, or 25 with --quick)")  # fmt: skip
    p.add_argument("--snapshot-dir", type=Path, default=None, metavar="DIR",
                   help="start from KP/BW's snapshot in DIR (KPBW.npz or KPBW/snapshot.npz, "
                   "assembled at this element size) instead of assembling; it should come "
                   "from this version's assembly (flexparcel assemble KPBW)")  # fmt: skip
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run, out_is_dir=True)


def given_snapshot(build, snapshot_dir: Path):
    """KP/BW's snapshot from ``snapshot_dir`` and its path; an error naming the folder where
    it holds none assembled from ``build`` (at its element size). The shipped
    ``data/paper-snapshots-25mm`` set was assembled with an earlier core (constant-strain
    membrane, contact per point): a test started from it first settles into the current
    model, so the demo assembles anew unless a folder is named."""
    from flexparcel.cli.snapshots import snapshot_for

    return snapshot_for("KPBW", build, snapshot_dir, snapshot_dir=snapshot_dir,
                        element_size_given=True, progress=False, log=lambda _m: None)  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from flexparcel.cli.outdir import report_failure
    from flexparcel.cli.snapshots import shipped_or_assembled
    from flexparcel.consignments.assembly import AssemblyError
    from flexparcel.consignments.userfile import resolve_consignment

    mode = QUICK if args.quick else FULL
    size_mm = args.element_size if args.element_size is not None else mode["element_size_mm"]
    build = resolve_consignment("KPBW", size_mm * 1e-3)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    progress = not args.no_progress
    wall0 = time.perf_counter()
    print(f"demo: KP/BW with {size_mm:g} mm shells{' (quick)' if args.quick else ''} -> {out}")
    found = None if args.snapshot_dir is None else given_snapshot(build, args.snapshot_dir)
    if found is not None:
        snap, path = found
        made = snap.info.get("wall_s")
        print(f"demo: using the snapshot {path}" + (f" (its assembly took {made:.0f} s)"
              if isinstance(made, int | float) else ""))  # fmt: skip
    else:
        try:
            snap, source = shipped_or_assembled(build, out / "assembly", progress=progress,
                                                log=lambda m: print(f"demo: {m}"))  # fmt: skip
        except AssemblyError as exc:
            report_failure(f"flexparcel demo: assembly failed: {exc}")
            return 1
        if source == str(out / "assembly" / "snapshot.npz"):  # assembled here, not shipped
            print(f"assembled in {snap.info['wall_s']:.1f} s")
    results = _run_tests(snap, out, mode, progress)
    total = time.perf_counter() - wall0
    report = _write_reports(out, build, snap.info, results, quick=args.quick, total_wall=total)
    print(f"report: {report.resolve()}")  # the last line: what to open
    return 0 if all(isinstance(r, dict) for r in results.values()) else 1


def _run_tests(snap, out: Path, mode: dict, progress: bool) -> dict[str, dict | str]:
    """Swing, vertical and horizontal drop with Table 6 into ``out/TEST``: test -> its
    ``responses.json`` content, or the message of its failure (the others still run)."""
    from flexparcel.cli.outdir import report_failure
    from flexparcel.cli.run_cmd import TESTS, format_responses, run_and_write
    from flexparcel.integrate.errors import ConvergenceError
    from flexparcel.scenarios.consignment_tests import TABLE6_VALUES
    from flexparcel.scenarios.registry import get_scenario

    results: dict[str, dict | str] = {}
    for test in TESTS:
        options = {} if test == "swing" else {"drop_height": mode["drop_height"]}
        scenario = get_scenario(test, **options)
        try:
            result, _ = run_and_write(scenario, snap, dict(TABLE6_VALUES), out / test,
                                      t_end=mode["t_end"][test], progress=progress)  # fmt: skip
            results[test] = scenario.summary(result)
            shown = format_responses(scenario.responses(result))
            print(f"{test}: {shown}; {result.wall_s:.1f} s wall")
        except ConvergenceError as exc:  # report it and go on with the other tests
            results[test] = str(exc)
            report_failure(f"flexparcel demo: {test} failed: {exc}")
    return results


def _write_reports(out: Path, build, info: dict, results: dict, *, quick: bool,
                   total_wall: float) -> Path:  # fmt: skip
    """``out/report.md`` and ``out/report.html`` (returned: the user's report)."""
    from flexparcel.io.atomic import write_atomic
    from flexparcel.viz.html import esc
    from flexparcel.viz.report import write_demo_report

    write_atomic(out / "report.md", report_markdown(build, info, results, quick=quick,
                                                    total_wall=total_wall))  # fmt: skip
    print(f"report (Markdown): {(out / 'report.md').resolve()}")
    finished = {t: t for t, r in results.items() if isinstance(r, dict)}
    failed = {t: r for t, r in results.items() if isinstance(r, str)}
    note = f'<p class="note">{esc(_quick_text())}</p>' if quick else ""
    return write_demo_report(out, facts=esc(" ".join(_facts(build, quick, total_wall))),
                             assembly=info, tests=finished, failures=failed, quick_note=note,
                             explanation=f"<h2>Why the numbers differ</h2><p>"
                             f"{esc(_why_text(build))}</p>")  # fmt: skip


def _facts(build, quick: bool, total_wall: float) -> list[str]:
    """The report's opening sentences: version, machine, command, mesh, parameters."""
    from flexparcel import __version__

    threads = os.environ.get("OMP_NUM_THREADS", "unset")
    cpu = platform.processor() or platform.machine()
    return [
        f"flexparcel {__version__}, {time.strftime('%Y-%m-%d %H:%M')}, {cpu}, "
        f"{os.cpu_count()} CPU cores (OMP_NUM_THREADS={threads}).",
        f"Command: `flexparcel demo{' --quick' if quick else ''}`; "
        f"{build.element_size * 1e3:g} mm shells; parameters: the paper's Table 6 (E = 926 "
        "MPa, damping ratio 1.71e-3 s, packaging-content 649 N/mm / 0.579 Ns/mm, "
        f"packaging-ground 611 N/mm / 0.591 Ns/mm). Total wall time {total_wall:.0f} s.",
    ]


def _quick_text() -> str:
    return (f"Quick mode: coarse mesh, shortened simulated times and drops from "
            f"{QUICK['drop_height'] * 1e3:g} mm instead of 200 mm. A check that the pipeline "
            "runs, not a comparison with the paper: the swings need the full 1.4 s, and "
            "RecurDyn's wall times below are scaled linearly to our simulated times.")  # fmt: skip


def _why_text(build) -> str:
    return (
        "The parameters are the paper's calibrated ones, not tuned here. The paper does not "
        "print the packaging's measured thickness or density, nor the exact envelope "
        "geometry; ours are documented assumptions (flexparcel.consignments.materials: "
        f"{build.material.thickness * 1e3:g} mm, {build.material.areal_density * 1e3:g} "
        "g/m^2). With E fixed, the bending stiffness grows with the cube of the thickness, so "
        "the swing depends strongly on it; the drops depend on the contact parameters, the "
        "content's mass and the packaging's shape after assembly. Friction and the contact "
        "damping ramp are not given in the paper either (we use 0.3 and 0.1 mm)."
    )


def _fmt(v: float | None, digits: int = 1) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def _measured(r: dict | str | None, key: str) -> str:
    """A response of a test's ``responses.json`` content in the table: its value, "not
    reached in this run" where the run did not reach it (never 0), "–" for a failed test."""
    if not isinstance(r, dict):
        return "–"
    resp = r.get("responses", {}).get(key)
    value = resp.get("value") if resp is not None else r.get(key)
    return "not reached in this run" if value is None else f"{value:.1f}"


def report_markdown(build, assembly_info: dict, results: dict, *, quick: bool,
                    total_wall: float) -> str:  # fmt: skip
    """The demo report (Markdown) from the assembly info and each test's ``responses.json``
    content (a dict) or failure message (a str); picture paths relative to the report."""
    lines = ["# flexparcel demo: the paper's KP/BW consignment", "",
             *_facts(build, quick, total_wall), "", "The report with the pictures and the "
             "3-D viewers: report.html.", ""]  # fmt: skip
    if quick:
        lines += [f"> **{_quick_text().replace(':', ':**', 1)}", ""]
    lines += [
        "## Assembly",
        "",
        f"Opened after {assembly_info['opening_time_s']:.3f} s, at rest at "
        f"{assembly_info['end_time_s']:.3f} s (kinetic energy "
        f"{assembly_info['kinetic_energy_J']:.2g} J), {assembly_info['steps']} steps, "
        f"{assembly_info['wall_s']:.1f} s wall. Packaging "
        f"{assembly_info['packaging_mass_kg'] * 1e3:.1f} g, content "
        f"{assembly_info['content_mass_kg'] * 1e3:.1f} g.",
        "",
        "![assembled KP/BW](assembly/assembled.png)",
        "",
        "## Responses next to the paper's Table 7",
        "",
        "| response | flexparcel | paper Table 7 (RecurDyn) | ratio | real-world test |",
        "|---|---:|---:|---:|---:|",
    ]
    for label, test, key, ref in _RESPONSE_ROWS:
        shown = _measured(results.get(test), key)
        paper = PAPER_TABLE7[ref]
        ratio = f"{float(shown) / paper:.2f}" if shown[:1].isdigit() else "–"
        lines.append(f"| {label} | {shown} | {paper:g} | {ratio} | {REAL_TEST_MM[ref]:g} |")
    return "\n".join(lines + _markdown_tail(build, results))


def _markdown_tail(build, results: dict) -> list[str]:
    """The wall-time table, the why and each test's pictures."""
    from flexparcel.scenarios.paper_reference import recurdyn_wall_s

    lines = [
        "",
        "## Wall times next to RecurDyn's",
        "",
        "| test | simulated [s] | flexparcel wall [s] | RecurDyn wall [s] (4 cores) | ratio |",
        "|---|---:|---:|---:|---:|",
    ]
    for test in RECURDYN_WALL_S:
        r = results.get(test)
        if isinstance(r, dict):
            sim, wall = r["simulated_s"], r["wall_s"]
            recurdyn = recurdyn_wall_s(test, sim)
            lines.append(
                f"| {test} | {sim:g} | {wall:.1f} | {recurdyn:.0f} | {wall / recurdyn:.2f} |"
            )
        else:
            lines.append(f"| {test} | – | failed | {RECURDYN_WALL_S[test]:g} | – |")
    lines += [
        "",
        "Ratio = flexparcel / RecurDyn (below 1: faster). RecurDyn: Intel i9-13900H, 4 cores "
        "(paper Table 7); flexparcel: this machine, wall time of the test's time integration "
        "(the assembly is done once and shared by the three tests).",
        "",
        "## Why the numbers differ",
        "",
        _why_text(build),
        "",
    ]
    for test in RECURDYN_WALL_S:
        r = results.get(test)
        lines += [f"## {test}", ""]
        if isinstance(r, dict):
            lines += [f"![{test} frames]({test}/frames.png)", "",
                      f"![{test} response]({test}/response.png)", "",
                      f"Files: `{test}/responses.json`, `{test}/results.npz`, "
                      f"`{test}/paraview/packaging.pvd` (ParaView), `{test}/view.html` "
                      "(3-D viewer).", ""]  # fmt: skip
        else:
            lines += [f"Failed: {r}", ""]
    return lines
