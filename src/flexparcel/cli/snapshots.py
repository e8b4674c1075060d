"""The command line's consignment snapshots: assemble a consignment and write the files a user
opens, check that a given snapshot fits the consignment and element size asked for, and find
or assemble the snapshots of a conveyor run (cached per consignment and element size). No
physics here: the work is done by :mod:`flexparcel.consignments`.

Files of an assembly (in ``out``): ``snapshot.npz``, ``assembly.json``, ``assembled.png`` and
``paraview/assembled.pvd`` (+ ``paraview/assembled_content.pvd`` for a rigid content).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexparcel.consignments.build import Consignment, ConsignmentBuild, add_consignment
from flexparcel.consignments.snapshot import Snapshot, check_snapshot_matches
from flexparcel.scenarios.base import write_json

__all__ = [
    "ASSEMBLY_CHECKPOINT",
    "UNSETTLED_FILES",
    "JobFiles",
    "check_snapshot_matches",
    "assemble_job",
    "write_assembled",
    "shipped_or_assembled",
    "snapshot_for",
]

ASSEMBLY_CHECKPOINT = "assembly-checkpoint.npz"
"""The checkpoint an assembly in ``out`` saves after every chunk and resumes from
(:mod:`flexparcel.consignments.assembly_checkpoint`); removed when the assembly ends."""

UNSETTLED_FILES = ("unsettled.npz", "unsettled.png")
"""What :func:`assemble_job` leaves in its directory when the consignment does not come to
rest: the last state (a snapshot file) and its picture."""


@dataclass
class JobFiles:
    """Paths written by a job (``None`` where not applicable)."""

    directory: Path
    json: Path
    snapshot: Path | None = None
    results: Path | None = None
    paraview: Path | None = None
    paraview_content: Path | None = None
    picture: Path | None = None
    curve: Path | None = None

    def as_dict(self) -> dict[str, str]:
        """Non-empty entries as strings (for JSON and printing)."""
        return {k: str(v) for k, v in self.__dict__.items() if v is not None and k != "directory"}


def _consignment_model(build: ConsignmentBuild):
    """The consignment alone (no contact) as a model: its cells for output."""
    from flexparcel.builder import ModelBuilder

    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    c = add_consignment(b, build, self_contact=False)
    return b.finalize(), c


def _content_boxes(c: Consignment, snap: Snapshot) -> list:
    """The rigid content of ``snap`` as a drawable box (empty for a flexible content)."""
    from flexparcel.viz.consignment import Box

    if c.content_body is None:
        return []
    return [Box(snap.positions[c.content_body], snap.rotations[c.content_body], c.content_box)]


def _snapshot_picture(path: Path, snap: Snapshot, state: str, model, c: Consignment) -> Path:
    """Top and side views of ``snap`` (the cells of ``model``, the content of ``c``, from
    :func:`_consignment_model`) titled "<id> <state> (<size> mm elements)"; returns ``path``."""
    from flexparcel.viz.consignment import plot_consignment_views

    build = snap.build
    return plot_consignment_views(
        path, snap.positions, model.cells, boxes=_content_boxes(c, snap),
        title=f"{build.spec.id} {state} ({build.element_size * 1e3:g} mm elements)",
    )  # fmt: skip


def assemble_job(
    build: ConsignmentBuild, out: Path, *, progress: bool = True
) -> tuple[Snapshot, JobFiles]:
    """Assemble ``build`` and write the snapshot, ``assembly.json``, a picture and ParaView
    files of the settled state into ``out``. A consignment that does not come to rest raises
    :class:`AssemblyError` after its last state and picture are written to ``out``
    (:data:`UNSETTLED_FILES`; for diagnosis, no test starts from it). An interrupted
    assembly, run again into the same ``out``, resumes from :data:`ASSEMBLY_CHECKPOINT`."""
    from flexparcel.cli.progress import PhaseProgress
    from flexparcel.consignments.assembly import AssemblyError, assemble
    from flexparcel.consignments.snapshot import save_snapshot

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    line = PhaseProgress(f"assemble {build.spec.id}", enabled=progress)
    try:
        # an interrupted assembly (hours at 10 mm) resumes from its checkpoint in ``out``
        snap = assemble(build, progress=line, checkpoint=out / ASSEMBLY_CHECKPOINT)
    except AssemblyError as exc:
        if exc.unsettled is not None:
            npz, png = UNSETTLED_FILES
            save_snapshot(exc.unsettled, out / npz)
            model, c = _consignment_model(build)
            state = "not at rest" if not exc.unsettled.info["at_rest"] else "in a wrong shape"
            _snapshot_picture(out / png, exc.unsettled, state, model, c)
        raise
    finally:
        line.done()
    return snap, write_assembled(snap, out)


def write_assembled(snap: Snapshot, out: Path) -> JobFiles:
    """Write ``snap`` as an assembly's files into ``out``: ``snapshot.npz``,
    ``assembly.json``, ``assembled.png`` and ParaView files."""
    from flexparcel.consignments.snapshot import save_snapshot
    from flexparcel.elements.rotations import rotation_vectors
    from flexparcel.io.paraview import write_paraview, write_paraview_boxes
    from flexparcel.simulate import SimulationResult

    build = snap.build
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = JobFiles(out, out / "assembly.json")
    files.snapshot = save_snapshot(snap, out / "snapshot.npz")
    model, c = _consignment_model(build)
    n = len(snap.positions)
    # one recorded frame of the settled state, for the ParaView writer
    frame = SimulationResult(
        time=np.zeros(1),
        positions=snap.positions[None],
        rotation_vectors=rotation_vectors(snap.rotations)[None],
        velocities=np.zeros((1, n, 6)),
        energies={},
        final_state=snap.state(),
    )
    files.paraview = write_paraview(out / "paraview", frame, model, name="assembled")
    boxes = _content_boxes(c, snap)
    if boxes:
        files.paraview_content = write_paraview_boxes(
            out / "paraview", [0.0], [[boxes[0].centre]], [[boxes[0].rotation]],
            [c.content_box], name="assembled_content",
        )  # fmt: skip
    files.picture = _snapshot_picture(out / "assembled.png", snap, "assembled", model, c)
    extent = snap.positions[c.packaging].max(axis=0) - snap.positions[c.packaging].min(axis=0)
    summary = {
        "consignment": build.spec.id,
        "build": build.to_dict(),
        "node_count": n,
        "dof_count": model.dof_count,
        "extent_mm": (1e3 * extent).tolist(),
        "info": snap.info,
        "files": files.as_dict(),
    }
    write_json(files.json, summary)
    return files


def _cache_dir(out: Path, key: str, build: ConsignmentBuild) -> Path:
    return out / "snapshots" / f"{key}_{build.element_size * 1e3:g}mm"


def snapshot_for(
    key: str,
    build: ConsignmentBuild,
    out: Path,
    *,
    snapshot_dir: Path | None = None,
    element_size_given: bool = False,
    progress: bool = True,
    log: Callable[[str], None] = print,
) -> tuple[Snapshot, str]:
    """The snapshot of ``build`` and where it came from: from ``snapshot_dir`` (a file
    ``KEY.npz`` or ``KEY/snapshot.npz``, or the cache layout below; it must have been
    assembled from ``build``, and with its element size when ``element_size_given``), else
    the cache ``out/snapshots/KEY_SIZEmm/snapshot.npz`` when it matches ``build``, else the
    shipped one where it fits, else assembled now into that cache directory
    (:func:`shipped_or_assembled`)."""
    from flexparcel.consignments.snapshot import load_snapshot

    size = build.element_size if element_size_given else None
    if snapshot_dir is not None:
        names = [f"{key}.npz", f"{key}/snapshot.npz", f"{build.spec.id}.npz",
                 f"{build.spec.id}/snapshot.npz",
                 f"{_cache_dir(Path(), key, build).name}/snapshot.npz"]  # fmt: skip
        for name in names:
            p = Path(snapshot_dir) / name
            if p.is_file():
                snap = load_snapshot(p)
                check_snapshot_matches(snap, build, size)
                return snap, str(p)
        raise FileNotFoundError(
            f"no snapshot of {key!r} in {snapshot_dir} (looked for {', '.join(names)})"
        )
    cache = _cache_dir(Path(out), key, build) / "snapshot.npz"
    if cache.is_file():
        snap = load_snapshot(cache)
        try:
            check_snapshot_matches(snap, build, build.element_size)
        except ValueError as exc:
            log(f"cached snapshot {cache} does not fit ({exc}); assembling again")
        else:
            log(f"{key}: reusing {cache}")
            return snap, str(cache)
    return shipped_or_assembled(build, cache.parent, progress=progress, log=log, key=key)


def shipped_or_assembled(
    build: ConsignmentBuild,
    out: Path,
    *,
    progress: bool = True,
    log: Callable[[str], None] = print,
    key: str | None = None,
) -> tuple[Snapshot, str]:
    """The shipped snapshot of ``build`` where one fits
    (:func:`~flexparcel.consignments.snapshot.shipped_snapshot`), else ``build`` assembled
    into ``out`` (:func:`assemble_job`); with where it came from. Says which on ``log``."""
    from flexparcel.consignments.snapshot import shipped_snapshot

    name = key or build.spec.id
    shipped = shipped_snapshot(build)
    if shipped is not None:
        snap, path = shipped
        wall = snap.info.get("wall_s")
        made = f", its assembly took {wall:.0f} s" if isinstance(wall, int | float) else ""
        log(f"{name}: using the shipped snapshot {path} ({build.element_size * 1e3:g} mm"
            f"{made})")  # fmt: skip
        write_assembled(snap, out)  # the assembly's files, as if assembled here
        return snap, str(path)
    log(f"{name}: assembling ({build.element_size * 1e3:g} mm elements) into {out}")
    snap, files = assemble_job(build, out, progress=progress)
    return snap, str(files.snapshot)
