"""Pictures of the built-in scenarios' results, as the picture writers
(:data:`~flexparcel.scenarios.base.PictureWriter`) their ``write`` takes: the physics modules
do not import the plotting layer, the caller passes these in.

* swing and drops: ``frames.png`` (side views at the start, the events of the response curve
  and the end) and ``response.png`` (the free end's position relative to the clamp edge with
  both swings marked; the centre-of-mass height with the touch and the rebound peak marked);
* conveyor: ``snapshots.png`` (top views at 0, 1 and 2 s, or at 0, t_end / 2 and t_end for
  shorter runs), ``trajectories.png`` and ``animation.gif``;
* every scenario (:func:`pictures_for`, unless ``viewer=False``): ``view.html``, the 3-D
  viewer in the browser (:mod:`flexparcel.viz.viewer`), from the ``results.npz`` the
  scenario's ``write`` saved just before. The command line (``run``, ``demo``, ``bench``)
  passes these writers, so every run through it leaves a ``view.html``; a scenario run from
  Python gets one by passing ``pictures=pictures_for(name)`` to its ``write`` (or later with
  ``flexparcel view DIR``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from flexparcel.scenarios.base import ScenarioResult
from flexparcel.viz.consignment import Box

__all__ = [
    "PICTURES",
    "pictures_for",
    "with_viewer",
    "swing_pictures",
    "drop_pictures",
    "conveyor_pictures",
    "snapshot_times",
]


def _test_frames(result: ScenarioResult, path: Path, events: dict[int, str], **options) -> Path:
    """Side views of a swing or drop run at the start, the ``events`` (frame -> caption) and
    the end."""
    from flexparcel.scenarios.consignment_scenario import content_rotations, frame_indices
    from flexparcel.viz.consignment import plot_frames

    run = result.record
    res, c = run.result, run.consignment
    rotations = content_rotations(run)
    frames, labels = [], []
    for k in frame_indices(len(res.time), list(events)):
        boxes = [] if rotations is None else [
            Box(res.positions[k, c.content_body], rotations[k], c.content_box)]  # fmt: skip
        frames.append((float(res.time[k]), res.positions[k], boxes))
        labels.append(events.get(k, ""))
    return plot_frames(path, frames, run.model.cells, labels=labels,
                       title=f"{result.scenario} test, {c.build.spec.id} (side view)",
                       **options)  # fmt: skip


def swing_pictures(result: ScenarioResult, out: Path) -> dict[str, Path]:
    """``frames.png`` and ``response.png`` of a swing run."""
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.scenarios.swing import swing_curve
    from flexparcel.viz.consignment import plot_swing_curve

    run = result.record
    res, c = run.result, run.consignment
    clamped = result.settings.get("clamped_length_m", 0.020)
    x_rel, first, second = swing_curve(run, clamped)
    resp = get_scenario("swing", clamped_length=clamped).responses(result)
    shown = ", ".join(f"{k.split('_')[0]} {r.format(1)}" for k, r in resp.items())
    title = f"Swing test, {c.build.spec.id}: free end ({shown})"
    curve = plot_swing_curve(Path(out) / "response.png", res.time, x_rel, first=first,
                             second=second, title=title)  # fmt: skip
    events = {m[0]: caption for m, caption in ((first, "first swing"), (second, "second swing"))
              if m is not None}  # fmt: skip
    clamp_x = float(res.positions[0, c.packaging, 0].min() + clamped)
    picture = _test_frames(result, Path(out) / "frames.png", events, plate_z=None,
                           clamp_x=clamp_x, shared_axes=True)  # fmt: skip
    return {"picture": picture, "curve": curve}


def drop_pictures(result: ScenarioResult, out: Path) -> dict[str, Path]:
    """``frames.png`` and ``response.png`` of a drop run."""
    from flexparcel.scenarios.drop import drop_curve
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.viz.consignment import plot_drop_curve

    run = result.record
    res = run.result
    zc, touch, kmin, peak = drop_curve(run)
    r = get_scenario(result.scenario).responses(result)["rebound_mm"]
    curve = plot_drop_curve(
        Path(out) / "response.png", res.time, zc, touch=touch, peak=peak,
        rebound=(r.value or 0.0) * 1e-3,
        title=f"{result.scenario.replace('-', ' ').capitalize()} test, "
        f"{run.consignment.build.spec.id}: centre of mass (rebound {r.format(1)})",
    )  # fmt: skip
    events: dict[int, str] = {}
    if touch is not None:
        events[min(int(np.searchsorted(res.time, touch[0])), len(res.time) - 1)] = "first contact"
        events.setdefault(kmin, "deepest")
    if peak is not None:
        events.setdefault(peak, "rebound peak")
    # each frame centred on the consignment: a 200 mm fall would leave it a speck
    picture = _test_frames(result, Path(out) / "frames.png", events, plate_z=0.0,
                           clamp_x=None, shared_axes=False)  # fmt: skip
    return {"picture": picture, "curve": curve}


def snapshot_times(t_end: float) -> list[float]:
    """Times [s] of the conveyor's snapshot picture: the paper's 0, 1, 2 s where the run
    reaches them, else 0, t_end / 2, t_end."""
    if t_end >= 2.0 - 1e-9:
        return [0.0, 1.0, 2.0]
    return [0.0, 0.5 * t_end, t_end]


def _conveyor_boxes(run) -> list[list[Box]]:
    """Rigid contents of a conveyor run as drawable boxes per frame, shape [k][b]."""
    from scipy.spatial.transform import Rotation

    res = run.result
    out: list[list[Box]] = [[] for _ in res.time]
    for c in run.conveyor_model.consignments.values():
        if c.content_body is None:
            continue
        rot = Rotation.from_rotvec(res.rotation_vectors[:, c.content_body]).as_matrix()
        for k in range(len(res.time)):
            out[k].append(Box(res.positions[k, c.content_body], rot[k], c.content_box))
    return out


def _consignment_cells(run) -> list:
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


def conveyor_pictures(
    result: ScenarioResult, out: Path, *, animation_frames: int = 60
) -> dict[str, Path]:
    """``snapshots.png``, ``trajectories.png`` and ``animation.gif`` of a conveyor run."""
    from flexparcel.viz.conveyor import animate_conveyor, plot_conveyor_snapshots, plot_trajectories

    run = result.record
    res, out = run.result, Path(out)
    scene = run.conveyor_model.layout.conveyor
    boxes = _conveyor_boxes(run)
    cells = _consignment_cells(run)
    frames = []
    for t in snapshot_times(float(res.time[-1])):
        k = int(np.argmin(np.abs(res.time - t)))
        frames.append((float(res.time[k]), res.positions[k], boxes[k]))
    count = len(run.conveyor_model.layout.placements)
    label = (f"belt {scene.belt_speed:g} m/s, deflectors {scene.deflector_angle_deg:g} deg, "
             f"{count} consignments")  # fmt: skip
    return {
        "snapshots": plot_conveyor_snapshots(out / "snapshots.png", frames, cells, scene,
                                             title=f"Conveyor, top view ({label})"),
        "trajectories": plot_trajectories(out / "trajectories.png", run.responses, scene,
                                          title=f"Trajectories ({label})"),
        "animation": animate_conveyor(out / "animation.gif", res.time, res.positions, cells,
                                      scene, boxes, max_frames=animation_frames,
                                      title=f"Conveyor ({label})"),
    }  # fmt: skip


PICTURES: dict[str, Callable[[ScenarioResult, Path], Mapping[str, Path]]] = {
    "swing": swing_pictures,
    "drop-vertical": drop_pictures,
    "drop-horizontal": drop_pictures,
    "conveyor": conveyor_pictures,
}
"""Picture writer of each built-in scenario."""


def with_viewer(
    pictures: Callable[[ScenarioResult, Path], Mapping[str, Path]] | None,
) -> Callable[[ScenarioResult, Path], Mapping[str, Path]]:
    """``pictures`` (or none) followed by the viewer page ``view.html``
    (:func:`flexparcel.viz.viewer.viewer_writer`); returns name -> path of both."""

    def write(result: ScenarioResult, out: Path) -> dict[str, Path]:
        from flexparcel.viz.viewer import viewer_writer

        files = dict(pictures(result, out)) if pictures is not None else {}
        files.update(viewer_writer(result, Path(out)))
        return files

    return write


def pictures_for(
    name: str, *, viewer: bool = True
) -> Callable[[ScenarioResult, Path], Mapping[str, Path]] | None:
    """The picture writer of scenario ``name`` with the viewer page ``view.html`` (any
    scenario, built-in or not); with ``viewer=False`` the pictures alone, or None for a
    scenario without pictures."""
    pictures = PICTURES.get(name)
    if not viewer:
        return pictures
    return with_viewer(pictures)
