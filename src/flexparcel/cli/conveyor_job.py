"""What ``flexparcel run conveyor`` does: get the consignments' snapshots (given, cached or
assembled), run the scene of :mod:`flexparcel.scenarios.conveyor_scene` and write the files a
user opens. No physics here.

Files (in ``out``): ``responses.json``, ``results.npz``, ``paraview/conveyor.pvd`` (all nodes:
packaging and deflector faces) + ``paraview/contents.pvd`` (rigid contents as boxes),
``snapshots.png`` (top views at 0, 1 and 2 s, or at 0, t_end / 2 and t_end for shorter runs),
``trajectories.png``, ``animation.gif`` and the assembled snapshots in ``snapshots/``.
While it runs, ``checkpoint.npz`` (:mod:`flexparcel.io.checkpoint`): the same command after an
interruption resumes from it; it is refused if the scene or options changed. With ``preview``
the same files are made from the frames the checkpoint holds so far, in ``preview/``.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from flexparcel.consignments.build import ConsignmentBuild
from flexparcel.consignments.snapshot import Snapshot
from flexparcel.contact.law import ContactLaw
from flexparcel.scenarios.conveyor_groups import GroupSettings
from flexparcel.scenarios.conveyor_scene import ConveyorRun, SceneLayout

__all__ = [
    "CHECKPOINT_FILE",
    "content_law_for",
    "snapshot_for",
    "conveyor_job",
    "snapshot_times",
    "parse_consignment_list",
    "group_settings",
    "DEFAULT_WORKERS",
]

CHECKPOINT_FILE = "checkpoint.npz"
DEFAULT_WORKERS = 2
"""``--workers`` default: the consignments on two worker processes (the CI-class machine's
two cores)."""


def content_law_for(stiffness_n_per_mm: float | None) -> ContactLaw | None:
    """The packaging-content contact law with stiffness c = ``stiffness_n_per_mm`` [N/mm] in
    [1, 1e4] (stick stiffness k_t = c, damping kept), or None (Table 6's law, as assembled)
    when not given; the ``--content-stiffness`` option of ``run conveyor`` and the bench."""
    if stiffness_n_per_mm is None:
        return None
    from dataclasses import replace

    from flexparcel.consignments.build import default_packaging_content_law

    v = float(stiffness_n_per_mm)
    if not 1.0 <= v <= 1e4:
        raise ValueError(f"--content-stiffness must be in [1, 10000] N/mm, got {v:g}")
    c = v * 1e3
    return replace(default_packaging_content_law(), stiffness=c, stick_stiffness=c)


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
    the cache ``out/snapshots/KEY_SIZEmm/snapshot.npz`` when it matches ``build``, else
    assembled now into that cache directory."""
    from flexparcel.cli.consignment_jobs import assemble_job, check_snapshot_matches
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
    log(f"{key}: assembling ({build.element_size * 1e3:g} mm elements) into {cache.parent}")
    snap, files = assemble_job(build, cache.parent, progress=progress)
    return snap, str(files.snapshot)


def snapshot_times(t_end: float) -> list[float]:
    """Times [s] of the snapshot picture: the paper's 0, 1, 2 s where the run reaches
    them, else 0, t_end / 2, t_end."""
    if t_end >= 2.0 - 1e-9:
        return [0.0, 1.0, 2.0]
    return [0.0, 0.5 * t_end, t_end]


def _boxes(run: ConveyorRun) -> list[list]:
    """Rigid contents as drawable boxes per frame, shape [k][b]."""
    from scipy.spatial.transform import Rotation

    from flexparcel.viz.consignment import Box

    res = run.result
    out = [[] for _ in res.time]
    for c in run.conveyor_model.consignments.values():
        if c.content_body is None:
            continue
        rot = Rotation.from_rotvec(res.rotation_vectors[:, c.content_body]).as_matrix()
        for k in range(len(res.time)):
            out[k].append(Box(res.positions[k, c.content_body], rot[k], c.content_box))
    return out


def _consignment_cells(run: ConveyorRun) -> list:
    """Cells of the consignments only (no deflector face meshes)."""
    nodes = np.zeros(run.conveyor_model.model.node_count, bool)
    for c in run.conveyor_model.consignments.values():
        nodes[c.node_ids] = True
    out = []
    for ctype, conn in run.conveyor_model.model.cells:
        conn = np.asarray(conn)
        keep = nodes[conn].all(axis=1)
        if keep.any():
            out.append((ctype, conn[keep]))
    return out


def conveyor_job(
    snapshots: dict[str, Snapshot],
    layout: SceneLayout,
    out: Path,
    *,
    t_end: float = 2.0,
    pair_reach: float | None = None,
    progress: bool = True,
    extra: dict | None = None,
    animation_frames: int = 60,
    preview: bool = False,
    content_law: ContactLaw | None = None,
    workers: int = DEFAULT_WORKERS,
) -> tuple[ConveyorRun, dict, dict[str, str]]:
    """Run the scene and write the files of the module docstring. Returns the run, the
    ``responses.json`` content and the written paths (name -> path).

    ``preview``: no stepping; the files of the frames that ``out/checkpoint.npz`` holds so far
    (a run going on in another process, or an interrupted one) go to ``out/preview/``.
    ``workers``: integrate consignments that cannot touch as separate models on that many
    worker processes (:mod:`flexparcel.scenarios.conveyor_groups`); 0: the scene as one
    model."""
    from flexparcel.cli.consignment_jobs import _write_json
    from flexparcel.cli.progress import ProgressLine
    from flexparcel.io.paraview import write_paraview, write_paraview_boxes
    from flexparcel.io.results import save_result
    from flexparcel.scenarios.conveyor_scene import run_conveyor
    from flexparcel.viz.conveyor import (
        animate_conveyor,
        plot_conveyor_snapshots,
        plot_trajectories,
    )

    out = Path(out)
    checkpoint = out / CHECKPOINT_FILE
    if preview and not checkpoint.is_file():
        raise ValueError(f"--preview: no checkpoint {checkpoint} (start the run first)")
    out.mkdir(parents=True, exist_ok=True)
    dt_out = min(0.01, t_end / 20.0)
    bar = ProgressLine(f"conveyor ({len(layout.placements)} consignments)",
                       enabled=progress and not preview)  # fmt: skip
    if checkpoint.exists() and not preview:
        print(f"conveyor: resuming from {checkpoint}", file=sys.stderr)
    try:
        run = run_conveyor(snapshots, layout, t_end, dt_out=dt_out, pair_reach=pair_reach,
                           progress=bar, checkpoint=checkpoint, checkpoint_only=preview,
                           content_law=content_law, groups=group_settings(workers))  # fmt: skip
    finally:
        bar.done()
    if preview:
        out = out / "preview"
        out.mkdir(exist_ok=True)
    summary = run.summary()
    summary["parameters"] = {
        "belt_speed_m_s": layout.conveyor.belt_speed,
        "deflector_angle_deg": layout.conveyor.deflector_angle_deg,
        "t_end_s": t_end,
        "dt_out_s": dt_out,
        "pair_reach_m": pair_reach,
        "workers": workers,
        "content_stiffness_N_per_mm": None if content_law is None else content_law.stiffness * 1e-3,
        "element_size_mm": {k: s.build.element_size * 1e3 for k, s in snapshots.items()},
    }
    summary.update(extra or {})
    files: dict[str, str] = {}
    json_path = out / "responses.json"
    _write_json(json_path, summary)  # the numbers first: they survive a failing picture
    files["json"] = str(json_path)
    res, cm = run.result, run.conveyor_model
    files["results"] = str(save_result(out / "results.npz", res, cm.model, {
        "scenario": "conveyor", "layout": layout.to_dict(),
        "consignments": {k: c.node_ids.tolist() for k, c in cm.consignments.items()},
    }))  # fmt: skip
    files["paraview"] = str(write_paraview(out / "paraview", res, cm.model, name="conveyor"))
    bodies = [c for c in cm.consignments.values() if c.content_body is not None]
    boxes = _boxes(run)
    if bodies:
        from scipy.spatial.transform import Rotation

        ids = [c.content_body for c in bodies]
        rv = res.rotation_vectors[:, ids]
        rot = Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(*rv.shape[:2], 3, 3)
        files["paraview_contents"] = str(write_paraview_boxes(
            out / "paraview", res.time, res.positions[:, ids], rot,
            [c.content_box for c in bodies], name="contents",
        ))  # fmt: skip
    cells = _consignment_cells(run)
    frames = []
    for t in snapshot_times(float(res.time[-1]) if preview else t_end):
        k = int(np.argmin(np.abs(res.time - t)))
        frames.append((float(res.time[k]), res.positions[k], boxes[k]))
    scene = layout.conveyor
    label = (f"belt {scene.belt_speed:g} m/s, deflectors {scene.deflector_angle_deg:g} deg, "
             f"{len(layout.placements)} consignments")  # fmt: skip
    pic = plot_conveyor_snapshots(
        out / "snapshots.png", frames, cells, scene, title=f"Conveyor, top view ({label})"
    )
    files["snapshots"] = str(pic)
    pic = plot_trajectories(
        out / "trajectories.png", run.responses, scene, title=f"Trajectories ({label})"
    )
    files["trajectories"] = str(pic)
    files["animation"] = str(animate_conveyor(
        out / "animation.gif", res.time, res.positions, cells, scene, boxes,
        max_frames=animation_frames, title=f"Conveyor ({label})",
    ))  # fmt: skip
    summary["files"] = files
    _write_json(json_path, summary)
    return run, summary, files


def group_settings(workers: int) -> GroupSettings | None:
    """The ``--workers`` option: None (one model) for 0, else that many worker processes
    (numba 1 thread each) for :func:`~flexparcel.scenarios.conveyor_groups.integrate_by_groups`.
    Raises ``ValueError`` outside [0, 64]."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not 0 <= workers <= 64:
        raise ValueError(f"--workers must be an integer in [0, 64], got {workers!r}")
    return None if workers == 0 else GroupSettings(workers=workers)


def parse_consignment_list(text: str) -> list[str]:
    """``"KPBW,PB,KP,BW"`` -> names; empty entries and duplicates raise ``ValueError``."""
    names = [s.strip() for s in text.split(",")]
    if not names or any(not n for n in names):
        raise ValueError(f"--consignments must be a comma-separated list of names, got {text!r}")
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"--consignments: {dup} given twice; use --scene for copies")
    return names
