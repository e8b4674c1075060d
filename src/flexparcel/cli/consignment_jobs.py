"""What ``flexparcel assemble``, ``flexparcel run`` and the demo do with a consignment: assemble
it or run one of the paper's tests, and write the files a user opens (snapshot, results,
ParaView series, pictures, JSON summaries). No physics here: the work is done by
:mod:`flexparcel.consignments` and :mod:`flexparcel.scenarios.consignment_tests`; this module
only post-processes recorded results into curves and pictures.

Files of an assembly (in ``out``): ``snapshot.npz``, ``assembly.json``, ``assembled.png`` and
``paraview/assembled.pvd`` (+ ``paraview/assembled_content.pvd`` for a rigid content).
Files of a test run: ``responses.json``, ``results.npz``, ``frames.png``, ``response.png`` and
``paraview/packaging.pvd`` (+ ``paraview/content.pvd``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from flexparcel.consignments.build import Consignment, ConsignmentBuild, add_consignment
from flexparcel.consignments.snapshot import Snapshot
from flexparcel.io.atomic import write_atomic

__all__ = [
    "TESTS",
    "DEFAULT_T_END",
    "UNSETTLED_FILES",
    "default_parameters",
    "run_parameters",
    "check_snapshot_matches",
    "assemble_job",
    "run_job",
    "swing_curve",
    "drop_curve",
    "JobFiles",
]

TESTS = ("swing", "drop-vertical", "drop-horizontal")
DEFAULT_T_END = {"swing": 1.4, "drop-vertical": 0.3, "drop-horizontal": 0.3}
"""Simulated time [s] of each test (paper 3.2)."""
_DT_OUT = {"swing": 0.005, "drop-vertical": 0.001, "drop-horizontal": 0.001}
"""Output interval [s]: the drop's impact lasts a few ms, the swing ~1 s."""
MIN_FRAMES = 10  # short runs still get enough recorded frames for the pictures
DROP_HEIGHT = 0.200  # paper 3.2 [m]
UNSETTLED_FILES = ("unsettled.npz", "unsettled.png")
"""What :func:`assemble_job` leaves in its directory when the consignment does not come to
rest: the last state (a snapshot file) and its picture."""
CLAMPED_LENGTH = 0.020  # swing_test's default clamp [m] (paper 3.2), which the curve refers to


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


def default_parameters(build: ConsignmentBuild) -> dict[str, float]:
    """Table 3 parameters (paper units) for ``build``: the packaging's own Young's modulus
    [MPa] and damping ratio [s] (the values it was assembled with; for KP/BW the Table 6
    ones), and the Table 6 contact parameters.

    Why not Table 6 throughout: the test functions default to KP/BW's calibration, which
    would silently give a bubble-wrap pouch kraft paper's 926 MPa and ignore a user file's
    ``[material]`` table.
    """
    from flexparcel.scenarios.consignment_tests import TABLE6_VALUES

    p = dict(TABLE6_VALUES)
    p["youngs_modulus"] = build.material.youngs_modulus / 1e6
    p["damping_ratio"] = build.material.damping_ratio
    return p


def run_parameters(build: ConsignmentBuild, assignments: Sequence[str] | None) -> dict[str, float]:
    """:func:`default_parameters` overridden by ``name=value`` strings (paper units).

    Raises ``ValueError`` naming an unknown name or a bad value.
    """
    from flexparcel.scenarios.consignment_tests import parse_assignments

    items = list(assignments or [])
    checked = parse_assignments(items)  # validates names, numbers and signs
    params = default_parameters(build)
    for item in items:
        name = item.split("=", 1)[0].strip()
        params[name] = checked[name]
    return params


def check_snapshot_matches(
    snapshot: Snapshot, build: ConsignmentBuild | None, element_size: float | None
) -> None:
    """Raise ``ValueError`` unless ``snapshot`` was assembled from ``build`` (same spec and
    material, where given) with ``element_size`` [m] (where given)."""
    sb = snapshot.build
    if build is not None:
        if sb.spec != build.spec:
            raise ValueError(
                f"the snapshot holds consignment {sb.spec.id!r} ({sb.spec.packaging_material}, "
                f"{sb.spec.length_mm:g} x {sb.spec.width_mm:g} mm), not the given "
                f"{build.spec.id!r}; leave out --consignment or assemble it again"
            )
        # the provenance text may differ (a renamed file); the numbers must not
        if replace(sb.material, source="") != replace(build.material, source=""):
            raise ValueError(
                f"the snapshot of {sb.spec.id!r} was assembled with another packaging "
                "material; leave out --consignment or assemble it again"
            )
    if element_size is not None and not np.isclose(sb.element_size, element_size):
        raise ValueError(
            f"the snapshot was assembled with {sb.element_size * 1e3:g} mm elements, not "
            f"{element_size * 1e3:g} mm; leave out --element-size or assemble it again"
        )


def _consignment_model(build: ConsignmentBuild):
    """The consignment alone (no contact) as a model: its cells for output."""
    from flexparcel.model.builder import ModelBuilder

    b = ModelBuilder(gravity=(0.0, 0.0, 0.0))
    c = add_consignment(b, build, self_contact=False)
    return b.finalize(), c


def _write_json(path: Path, data: dict) -> Path:
    text = json.dumps(data, indent=2, default=float) + "\n"
    return write_atomic(path, text)


def _rotations(rotation_vectors: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors [rad] (..., 3)."""
    from scipy.spatial.transform import Rotation

    rv = np.asarray(rotation_vectors, float)
    return Rotation.from_rotvec(rv.reshape(-1, 3)).as_matrix().reshape(*rv.shape[:-1], 3, 3)


def _boxes(c: Consignment, positions: np.ndarray, rotation: np.ndarray | None) -> list:
    """The rigid content as a drawable box at ``positions`` [m] (n, 3) with body rotation
    ``rotation`` (3, 3); empty for a flexible content (its cells are drawn instead)."""
    from flexparcel.viz.consignment import Box

    if c.content_body is None or rotation is None:
        return []
    return [Box(positions[c.content_body], rotation, c.content_box)]


def _content_boxes(c: Consignment, snap: Snapshot) -> list:
    """The rigid content of ``snap`` as a drawable box (empty for a flexible content)."""
    body = c.content_body
    return _boxes(c, snap.positions, None if body is None else snap.rotations[body])


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
    (:data:`UNSETTLED_FILES`; for diagnosis, no test starts from it)."""
    from flexparcel.cli.progress import PhaseLine
    from flexparcel.consignments.assembly import AssemblyError, assemble
    from flexparcel.consignments.snapshot import save_snapshot
    from flexparcel.elements.rotations import rotation_vectors
    from flexparcel.io.paraview import write_paraview, write_paraview_boxes
    from flexparcel.simulate import SimulationResult

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    line = PhaseLine(f"assemble {build.spec.id}", enabled=progress)
    try:
        snap = assemble(build, progress=line)
    except AssemblyError as exc:
        if exc.unsettled is not None:
            npz, png = UNSETTLED_FILES
            save_snapshot(exc.unsettled, out / npz)
            model, c = _consignment_model(build)
            _snapshot_picture(out / png, exc.unsettled, "not at rest", model, c)
        raise
    finally:
        line.done()
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
    _write_json(files.json, summary)
    return snap, files


def swing_curve(run) -> tuple[np.ndarray, tuple[int, float] | None, tuple[int, float] | None]:
    """The swing's free-end position relative to the clamp edge [m] (k,) and the frames of
    the first and second swing ``(index, response [m])`` (None where there is none).

    The same quantities as :func:`flexparcel.scenarios.consignment_tests.swing_test` (mean x
    of the free edge minus the clamp edge, clamp edge = lowest packaging x + 20 mm), so the
    marks sit exactly on the reported responses.
    """
    pos = run.result.positions
    c = run.consignment
    x_clamp = pos[0, c.packaging, 0].min() + CLAMPED_LENGTH
    x_rel = pos[:, c.edge, 0].mean(axis=1) - x_clamp
    first = run.responses["first_swing_mm"] * 1e-3
    second = run.responses["second_swing_mm"] * 1e-3
    marks: list[tuple[int, float] | None] = []
    start = 0
    for value, sign in ((first, -1.0), (second, 1.0)):
        hit = np.flatnonzero(np.isclose(sign * x_rel[start:], value, rtol=1e-9, atol=1e-12))
        if value > 0 and hit.size:
            k = start + int(hit[0])
            marks.append((k, value))
            start = k
        else:
            marks.append(None)
    return x_rel, marks[0], marks[1]


def drop_curve(run) -> tuple[np.ndarray, tuple[float, float] | None, int | None, int | None]:
    """The drop's centre-of-mass height [m] (k,), the first contact ``(time [s], centre
    height [m])``, the frame of deepest compression and the frame of the rebound peak (None
    where there is none), as in :func:`~flexparcel.scenarios.consignment_tests.rebound_height`.
    """
    res, c = run.result, run.consignment
    ids = c.node_ids
    m = run.model.mass[ids, 0]
    zc = res.positions[:, ids, 2] @ m / m.sum()
    low = res.positions[:, c.packaging, 2].min(axis=1) - c.contact_radius
    touch = np.flatnonzero(low <= 0.0)
    if touch.size == 0:
        return zc, None, None, None
    k = int(touch[0])
    if k > 0:
        w = low[k - 1] / (low[k - 1] - low[k])
        t_touch = res.time[k - 1] + w * (res.time[k] - res.time[k - 1])
        z_touch = zc[k - 1] + w * (zc[k] - zc[k - 1])
    else:
        t_touch, z_touch = res.time[0], zc[0]
    kmin = k + int(np.argmin(zc[k:]))
    peak = kmin + int(np.argmax(zc[kmin:]))
    return zc, (float(t_touch), float(z_touch)), kmin, (peak if zc[peak] > z_touch else None)


def _frame_indices(count: int, events: Sequence[int], want: int = 4) -> list[int]:
    """Frame indices out of ``count`` for a picture: the first, the ``events``, the last,
    filled up with evenly spaced ones to ``want`` where events coincide or are missing."""
    chosen = {0, count - 1} | {int(e) for e in events if 0 <= e < count}
    for k in np.linspace(0, count - 1, want).round().astype(int):
        if len(chosen) >= want:
            break
        chosen.add(int(k))
    return sorted(chosen)


def run_job(
    test: str,
    snapshot: Snapshot,
    parameters: dict[str, float],
    out: Path,
    *,
    t_end: float | None = None,
    drop_height: float = DROP_HEIGHT,
    progress: bool = True,
    extra: dict | None = None,
):
    """Run ``test`` (one of :data:`TESTS`) from ``snapshot`` with ``parameters`` (paper units)
    for ``t_end`` [s] (default the paper's) and write its files into ``out``. Drops start
    with the lowest point ``drop_height`` [m] above the plate.

    Returns ``(TestRun, summary dict, JobFiles)``; the summary is what ``responses.json``
    holds: :meth:`TestRun.summary` plus ``element_size_mm``, ``files`` and ``extra``.
    """
    from flexparcel.cli.progress import ProgressLine
    from flexparcel.io.paraview import write_paraview, write_paraview_boxes
    from flexparcel.io.results import save_result
    from flexparcel.scenarios.consignment_tests import drop_test, swing_test
    from flexparcel.viz.consignment import plot_drop_curve, plot_frames, plot_swing_curve

    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; allowed: {', '.join(TESTS)}")
    t_end = DEFAULT_T_END[test] if t_end is None else float(t_end)
    if not (np.isfinite(t_end) and 0.0 < t_end <= 10.0):
        raise ValueError(f"--t-end must be in (0, 10] s, got {t_end!r}")
    dt_out = min(_DT_OUT[test], t_end / MIN_FRAMES)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    bar = ProgressLine(f"{test} {snapshot.build.spec.id}", enabled=progress)
    kw = dict(t_end=t_end, dt_out=dt_out, progress=bar)
    try:
        if test == "swing":
            run = swing_test(snapshot, parameters, **kw)
        else:
            run = drop_test(snapshot, test.removeprefix("drop-"), parameters,
                            drop_height=drop_height, **kw)  # fmt: skip
    finally:
        bar.done()
    res, model, c = run.result, run.model, run.consignment
    files = JobFiles(out, out / "responses.json")
    summary = run.summary()
    summary["element_size_mm"] = snapshot.build.element_size * 1e3
    if test != "swing":
        summary["drop_height_mm"] = drop_height * 1e3
    summary.update(extra or {})
    # the responses first: a long run's numbers survive a failure while writing the pictures
    _write_json(files.json, summary)
    files.results = save_result(out / "results.npz", res, model, {
        "test": test, "consignment": snapshot.build.to_dict(), "responses": run.responses,
        "parameters": run.parameters,
    })  # fmt: skip
    files.paraview = write_paraview(out / "paraview", res, model, name="packaging")
    rotations = None
    if c.content_body is not None:
        i = c.content_body
        rotations = _rotations(res.rotation_vectors[:, i])  # (k, 3, 3)
        files.paraview_content = write_paraview_boxes(
            out / "paraview", res.time, res.positions[:, [i]], rotations[:, None],
            [c.content_box], name="content",
        )  # fmt: skip

    name = snapshot.build.spec.id
    events: dict[int, str] = {}  # frame index -> caption
    if test == "swing":
        x_rel, first, second = swing_curve(run)
        files.curve = plot_swing_curve(
            out / "response.png", res.time, x_rel, first=first, second=second,
            title=f"Swing test, {name}: free end (first {run.responses['first_swing_mm']:.1f} "
            f"mm, second {run.responses['second_swing_mm']:.1f} mm)",
        )  # fmt: skip
        for mark, caption in ((first, "first swing"), (second, "second swing")):
            if mark is not None:
                events[mark[0]] = caption
        clamp_x = float(res.positions[0, c.packaging, 0].min() + CLAMPED_LENGTH)
        plate_z, shared = None, True
    else:
        zc, touch, kmin, peak = drop_curve(run)
        files.curve = plot_drop_curve(
            out / "response.png", res.time, zc, touch=touch, peak=peak,
            rebound=run.responses["rebound_mm"] * 1e-3,
            title=f"{test.replace('-', ' ').capitalize()} test, {name}: centre of mass "
            f"(rebound {run.responses['rebound_mm']:.1f} mm)",
        )  # fmt: skip
        if touch is not None:
            events[min(int(np.searchsorted(res.time, touch[0])), len(res.time) - 1)] = (
                "first contact"
            )
            events.setdefault(kmin, "deepest")
        if peak is not None:
            events.setdefault(peak, "rebound peak")
        plate_z, clamp_x, shared = 0.0, None, False  # the drop: each frame centred on it
    frames, labels = [], []
    for k in _frame_indices(len(res.time), list(events)):
        rot = None if rotations is None else rotations[k]
        frames.append((float(res.time[k]), res.positions[k], _boxes(c, res.positions[k], rot)))
        labels.append(events.get(k, ""))
    files.picture = plot_frames(
        out / "frames.png", frames, model.cells, labels=labels, plate_z=plate_z,
        clamp_x=clamp_x, shared_axes=shared, title=f"{test} test, {name} (side view)",
    )  # fmt: skip
    summary["files"] = files.as_dict()
    _write_json(files.json, summary)
    return run, summary, files
