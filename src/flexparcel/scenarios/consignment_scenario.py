"""What the swing and drop scenarios share: one consignment from its snapshot, the paper's
Table 3 parameters and the packaging's friction coefficient (paper units, defaults: the
packaging's own modulus and damping ratio, Table 6's contact values and friction 0.3), and the
files a user opens.

Files of a run (in ``out_dir``): ``responses.json``, ``results.npz`` (with the scene's
``parts`` in its metadata, :func:`flexparcel.io.paraview.scene_parts`),
``paraview/packaging.pvd`` (+ ``paraview/content.pvd``, the rigid content's rounded box, and
``paraview/plate.pvd`` for a drop test; fields: :mod:`flexparcel.io.paraview`), and what the
caller's picture writer draws (:mod:`flexparcel.viz.scenario_pictures`: ``frames.png``, side
views at the start, the events of the response curve and the end, ``response.png``, the
curve, and ``view.html``, the 3-D viewer in the browser).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from flexparcel.model.materials import MEMBRANE_LAWS, CoarseMeshWarning
from flexparcel.scenarios.base import (
    T_END,
    PictureWriter,
    Response,
    ScenarioBase,
    ScenarioResult,
    single_snapshot,
    write_json,
)
from flexparcel.scenarios.consignment_tests import (
    TABLE6_VALUES,
    TEST_PARAMETERS,
    TestModel,
    TestRun,
)

if TYPE_CHECKING:
    from flexparcel.consignments.build import ConsignmentBuild
    from flexparcel.consignments.snapshot import Snapshot

__all__ = ["ConsignmentTest", "MIN_FRAMES", "frame_indices", "content_rotations", "mm_response"]

MIN_FRAMES = 10  # short runs still get enough recorded frames for the pictures


def content_rotations(run: TestRun) -> np.ndarray | None:
    """Rotation matrices of the rigid content over the frames, shape (k, 3, 3); None for a
    flexible content."""
    from scipy.spatial.transform import Rotation

    body = run.consignment.content_body
    if body is None:
        return None
    return Rotation.from_rotvec(run.result.rotation_vectors[:, body]).as_matrix()


def frame_indices(count: int, events: Sequence[int], want: int = 4) -> list[int]:
    """Frame indices out of ``count`` for a picture: the first, the ``events``, the last,
    filled up with evenly spaced ones to ``want`` where events coincide or are missing."""
    chosen = {0, count - 1} | {int(e) for e in events if 0 <= e < count}
    for k in np.linspace(0, count - 1, want).round().astype(int):
        if len(chosen) >= want:
            break
        chosen.add(int(k))
    return sorted(chosen)


PAPER_ELEMENT_SIZE_MM = 10.0
"""The paper's shell mesh (RecurDyn, 10 mm nodes)."""

COARSE_ELEMENT_SIZE_MM = 15.0
"""Consignment tests on shells coarser than this are warned about (CoarseMeshWarning)."""


def warn_if_coarse(test: str, element_size_mm: float) -> None:
    """Warn when a consignment test runs on shells coarser than :data:`COARSE_ELEMENT_SIZE_MM`:
    measured on KP/BW with Table 6 at 25 mm (``flexparcel run swing --consignment KPBW
    --element-size 25``), only the end seam lies within the clamp's 20 mm, so the clamp is a
    line hinge, the bend next to it spans one element row, and the first/second swing came
    out 108/253 mm (jaws closed first; 99/253 with the seam clamped where it settled)
    against the paper's 128/27 at 10 mm: passing under the clamp, the film held 70 % of the
    energy gravity gave up as strain (kinetic 27 %; measured with the settled seam), and the
    consignment springs back almost to horizontal."""
    if element_size_mm <= COARSE_ELEMENT_SIZE_MM:
        return
    warnings.warn(
        CoarseMeshWarning(
            f"{test}: {element_size_mm:g} mm shells are coarser than the paper's "
            f"{PAPER_ELEMENT_SIZE_MM:g} mm: folds and the bend next to the swing clamp are "
            "not resolved (KP/BW with Table 6 at 25 mm: swing 108/253 mm against the paper's "
            "128/27), so take the responses as a low-fidelity level, not as the paper's test"
        ),
        stacklevel=3,
    )


class ConsignmentTest(ScenarioBase):
    """Base of a test on one consignment. Subclasses set :attr:`name`, :attr:`t_end`,
    :attr:`dt_out` and implement :meth:`build`, :meth:`_test_run` and :meth:`responses`;
    they take the snapshot through :meth:`snapshot`, which applies :attr:`membrane`."""

    parameters = TEST_PARAMETERS
    t_end: float = 1.0
    """Default simulated time [s]."""
    dt_out: float = 0.01
    """Output interval [s] (at most t_end / :data:`MIN_FRAMES`)."""
    membrane: str | None = None
    """The packaging's membrane law for the test (one of
    :data:`~flexparcel.model.materials.MEMBRANE_LAWS`), or None: the law the snapshot was
    assembled with. "tension-field" lets the film wrinkle in the test while it starts from
    an elastic-settled snapshot (docs/scenarios.md, the swing at 10 mm)."""

    checkpoint: Path | None = None
    """A ``.npz`` the run saves itself to about once a minute and resumes from (None: none;
    ``flexparcel run`` keeps ``DIR/checkpoint.npz``). A checkpoint of another run (other
    parameters, snapshot or settings) is refused by name."""

    def set_checkpoint(self, checkpoint: str | Path | None) -> None:
        """Set :attr:`checkpoint`."""
        self.checkpoint = None if checkpoint is None else Path(checkpoint)

    def set_membrane(self, membrane: str | None) -> None:
        """Check and set :attr:`membrane`."""
        if membrane is not None and membrane not in MEMBRANE_LAWS:
            raise ValueError(f"membrane must be one of {'|'.join(MEMBRANE_LAWS)}, got {membrane!r}")
        self.membrane = membrane

    def snapshot(self, consignment: Snapshot | Mapping[str, Snapshot]) -> Snapshot:
        """The one snapshot of the test, its packaging given :attr:`membrane` where set."""
        snap = single_snapshot(consignment, self.name)
        if self.membrane is None or snap.build.material.membrane == self.membrane:
            return snap
        material = replace(snap.build.material, membrane=self.membrane)
        return replace(snap, build=replace(snap.build, material=material))

    def defaults(self, build: ConsignmentBuild | None = None) -> dict[str, float | None]:
        """Table 6's values; with ``build``, its packaging's own Young's modulus [MPa] and
        damping ratio [s] (for KP/BW Table 6's). Why not Table 6 throughout: that would
        silently give a bubble-wrap pouch kraft paper's 926 MPa and ignore a consignment
        file's ``[material]`` table."""
        p: dict[str, float | None] = dict(TABLE6_VALUES)
        if build is not None:
            p["youngs_modulus"] = build.material.youngs_modulus / 1e6
            p["damping_ratio"] = build.material.damping_ratio
        return p

    def build(self, consignment: Snapshot | Mapping[str, Snapshot],
              parameters: Mapping[str, float | None]) -> TestModel:  # fmt: skip
        raise NotImplementedError

    def _test_run(self, snapshot: Snapshot, parameters: dict, t_end: float, dt_out: float,
                  progress: Any) -> TestRun:  # fmt: skip
        """The test's run; :attr:`checkpoint` goes to its simulation."""
        raise NotImplementedError

    def run(
        self,
        consignment: Snapshot | Mapping[str, Snapshot],
        parameters: Mapping[str, object] | None = None,
        *,
        t_end: float | None = None,
        progress: Any = None,
    ) -> ScenarioResult:
        snap = self.snapshot(consignment)
        warn_if_coarse(self.name, snap.build.element_size * 1e3)
        p = self.resolve(parameters, snap.build)
        t = self.t_end if t_end is None else T_END.check(t_end)
        dt_out = min(self.dt_out, t / MIN_FRAMES)
        run = self._test_run(snap, p, t, dt_out, progress)
        size_mm = snap.build.element_size * 1e3
        settings = {"t_end_s": t, "dt_out_s": dt_out, "element_size_mm": size_mm,
                    "membrane": snap.build.material.membrane, **self._settings()}  # fmt: skip
        return ScenarioResult(self.name, dict(p), run.result, run.wall_s, run, settings)

    def summary(self, result: ScenarioResult) -> dict:
        """``responses.json`` content (without ``files``): the run's summary with its
        responses in mm under their names (null where the run did not reach one: never 0),
        ``element_size_mm``, and ``responses`` with units and notes."""
        run: TestRun = result.record
        out = run.summary()
        out["element_size_mm"] = result.settings["element_size_mm"]
        out.update(self._summary_settings(result))
        responses = self.responses(result)
        out.update({k: r.value for k, r in responses.items()})
        out["responses"] = {k: r.to_dict() for k, r in responses.items()}
        return out

    def _summary_settings(self, result: ScenarioResult) -> dict:
        """Keys the subclass adds to ``responses.json``."""
        return {}

    def _settings(self) -> dict:
        """The subclass's options, recorded in :attr:`ScenarioResult.settings`."""
        return {}

    def write(self, result: ScenarioResult, out_dir: str | Path, *,
              extra: Mapping[str, Any] | None = None,
              pictures: PictureWriter | None = None) -> dict[str, Path]:  # fmt: skip
        from flexparcel.consignments.materials import FLEXIBLE_CONTENT
        from flexparcel.io.paraview import scene_parts, write_scene_paraview
        from flexparcel.io.results import save_result

        run: TestRun = result.record
        res, model, c = run.result, run.model, run.consignment
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        summary = {**self.summary(result), **(extra or {})}
        files: dict[str, Path] = {"json": out / "responses.json"}
        # the responses first: a long run's numbers survive a failure while writing pictures
        write_json(files["json"], summary)
        parts = scene_parts(model, {c.build.spec.id: c}, content_material=FLEXIBLE_CONTENT,
                            plate_z=_plate_z(model))  # fmt: skip
        files["results"] = save_result(out / "results.npz", res, model, {
            "test": self.name, "consignment": c.build.to_dict(), "responses": run.responses,
            "parameters": run.parameters, "parts": parts,
        })  # fmt: skip
        files.update(write_scene_paraview(out / "paraview", res, model, parts, name="packaging",
                                          content_name="content"))  # fmt: skip
        if pictures is not None:
            files.update(pictures(result, out))
        summary["files"] = {k: str(v) for k, v in files.items()}
        write_json(files["json"], summary)
        return files


def _plate_z(model) -> float | None:
    """Height [m] of a rigid plate under the consignment (a plane with normal +z: the drop
    tests'), or None."""
    normals = np.asarray(model.plane_normal).reshape(-1, 3)
    up = np.flatnonzero(np.isclose(normals[:, 2], 1.0))
    return float(np.asarray(model.plane_point).reshape(-1, 3)[up[0], 2]) if up.size else None


def mm_response(value_m: float | None, description: str, note: str = "") -> Response:
    """A length response [m] reported in mm (None: not reached, ``note`` says why)."""
    if value_m is None or (isinstance(value_m, float) and math.isnan(value_m)):
        return Response(None, "mm", description, note or "not reached within the run")
    return Response(value_m * 1e3, "mm", description)
