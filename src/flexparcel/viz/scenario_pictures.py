"""Pictures of the built-in scenarios' results, as the picture writers
(:data:`~flexparcel.scenarios.base.PictureWriter`) their ``write`` takes: the physics modules
do not import the plotting layer, the caller passes these in.

* swing and drops: ``frames.png`` (side views at the start, the events of the response curve
  and the end) and ``response.png`` (the free end's position relative to the clamp edge with
  both swings marked; the centre-of-mass height with the touch and the rebound peak marked);
* conveyor: ``snapshots.png`` (top views at 0, 1 and 2 s, or at 0, t_end / 2 and t_end for
  shorter runs), ``trajectories.png``, ``motion.png`` (speed, yaw and deflector force
  against time) and ``animation.gif``;
* every scenario (:func:`pictures_for`, unless ``viewer=False``): ``view.html``, the 3-D
  viewer in the browser (:mod:`flexparcel.viz.viewer`), from the ``results.npz`` the
  scenario's ``write`` saved just before; then (unless ``report=False``) ``report.html``,
  the HTML report (:mod:`flexparcel.viz.report`) that embeds the pictures and the viewer.
  The command line (``run``, ``demo``, ``bench``) passes these writers, so every run
  through it leaves a ``view.html`` and a ``report.html``; a scenario run from Python gets
  them by passing ``pictures=pictures_for(name)`` to its ``write`` (or later with
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
    "with_report",
    "swing_pictures",
    "drop_pictures",
    "conveyor_pictures",
    "snapshot_times",
    "paper_lines",
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
    shown = ", ".join(f"{k.split('_')[0]} {_short(r)}" for k, r in resp.items())
    title = f"Swing test, {c.build.spec.id}: free end ({shown})"
    refs = [(label, -mm * 1e-3 if key == "first_swing_mm" else mm * 1e-3, kind)
            for label, key, mm, kind in paper_lines("swing", c.build.spec.id)]  # fmt: skip
    curve = plot_swing_curve(Path(out) / "response.png", res.time, x_rel, first=first,
                             second=second, title=title, references=refs)  # fmt: skip
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
    curve_data = drop_curve(run)
    responses = get_scenario(result.scenario).responses(result)
    r, rise = responses["rebound_mm"], responses["com_rise_mm"]
    cid = run.consignment.build.spec.id
    curve = plot_drop_curve(
        Path(out) / "response.png", res.time, curve_data,
        rebound=None if r.value is None else r.value * 1e-3,
        com_rise=None if rise.value is None else rise.value * 1e-3,
        title=f"{result.scenario.replace('-', ' ').capitalize()} test, {cid}: rebound "
        f"{_short(r)}",
        references=[(label, mm * 1e-3, kind)
                    for label, _, mm, kind in paper_lines(result.scenario, cid)],
    )  # fmt: skip
    events: dict[int, str] = {}
    if curve_data.touch is not None:
        t_touch = curve_data.touch[0]
        events[min(int(np.searchsorted(res.time, t_touch)), len(res.time) - 1)] = "first contact"
        if curve_data.deepest is not None:
            events.setdefault(curve_data.deepest, "deepest")
    if r.value is not None and curve_data.gap_peak is not None:
        events.setdefault(curve_data.gap_peak, "rebound peak")
    # each frame centred on the consignment: a 200 mm fall would leave it a speck
    picture = _test_frames(result, Path(out) / "frames.png", events, plate_z=0.0,
                           clamp_x=None, shared_axes=False)  # fmt: skip
    return {"picture": picture, "curve": curve}


def _short(response) -> str:
    """``"58.5 mm"`` or ``"not reached"`` (a title has no room for the why)."""
    return "not reached" if response.value is None else f"{response.format(1)}"


def paper_lines(test: str, consignment: str) -> list[tuple[str, str, float, str]]:
    """Reference lines of a response curve: ``(label, response key, value [mm], kind)`` of
    paper Table 7 (kind ``"table7"``) and the real-world test (``"real"``) for ``test``;
    none unless ``consignment`` is KP/BW, the one they were measured on."""
    from flexparcel.scenarios.paper_reference import REFERENCE_CONSIGNMENT, TEST_REFERENCES

    if consignment != REFERENCE_CONSIGNMENT:
        return []
    out = []
    for ref in TEST_REFERENCES:
        if ref.test == test:
            out.append(("paper Table 7 (RecurDyn)", ref.response, ref.table7, "table7"))
            out.append(("real-world test", ref.response, ref.real, "real"))
    return out


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
    """``snapshots.png``, ``trajectories.png``, ``motion.png`` and ``animation.gif`` of a
    conveyor run."""
    from flexparcel.viz.conveyor import (
        animate_conveyor,
        plot_conveyor_motion,
        plot_conveyor_snapshots,
        plot_trajectories,
    )

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
        "motion": plot_conveyor_motion(out / "motion.png",
                                       {k: r.to_dict() for k, r in run.responses.items()},
                                       scene.belt_speed,
                                       title=f"Speed, yaw and deflector force ({label})"),
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


def with_report(
    pictures: Callable[[ScenarioResult, Path], Mapping[str, Path]] | None,
) -> Callable[[ScenarioResult, Path], Mapping[str, Path]]:
    """``pictures`` (or none) followed by the HTML report ``report.html``
    (:func:`flexparcel.viz.report.report_writer`), which embeds what they drew; returns
    name -> path of all."""

    def write(result: ScenarioResult, out: Path) -> dict[str, Path]:
        from flexparcel.viz.report import report_writer

        files = dict(pictures(result, out)) if pictures is not None else {}
        files.update(report_writer(result, Path(out)))
        return files

    return write


def pictures_for(
    name: str, *, viewer: bool = True, report: bool = True
) -> Callable[[ScenarioResult, Path], Mapping[str, Path]] | None:
    """The picture writer of scenario ``name`` with the viewer page ``view.html`` and the
    report ``report.html`` (any scenario, built-in or not); ``viewer=False`` and
    ``report=False`` leave those out (with both, the pictures alone, or None for a scenario
    without pictures)."""
    pictures = PICTURES.get(name)
    if viewer:
        pictures = with_viewer(pictures)
    return with_report(pictures) if report else pictures
