"""The paper's bulk conveyor run as a scenario (section 4.4, Fig. 35): consignments on a belt
with two deflectors, 2 s (:func:`~flexparcel.scenarios.conveyor_scene.run_conveyor`).

Parameters: belt speed, deflector angle, the queue's start speed, the packaging-content
contact stiffness and the consignment pairing reach; each defaults to the scene's (the paper
scene, or a scene file's). Settings (factory options): ``scene`` (a
:class:`~flexparcel.scenarios.conveyor_scene.SceneFile`), ``workers`` (worker processes, 0:
the scene as one model), ``checkpoint`` (a ``.npz`` the run saves itself to and resumes
from) and ``preview`` (no stepping: the frames the checkpoint holds so far).

Responses, per placement NAME: ``NAME.exit_time`` [s], ``NAME.final_x`` / ``NAME.final_y``
[m], ``NAME.deflector_contact_duration_I`` [s] (I = 1, 2, ...; not reached: never within
2 mm of that deflector), ``NAME.jam_start`` [s],
``NAME.peak_contact_force`` [N] (the largest mean deflector force over an output interval,
:func:`~flexparcel.scenarios.conveyor_scene.deflector_mean_forces`),
``NAME.deflector_crossing`` [s] (not reached: the wanted
outcome, no packaging node went behind a deflector).

Files (in ``out_dir``): ``responses.json`` (per-consignment trajectories and responses),
``results.npz`` (with the scene's ``parts`` in its metadata), ``contact_forces.npz`` (each
packaging node's deflector normal force per frame), ``paraview/conveyor.pvd`` (the
consignments: packaging and flexible contents) + ``paraview/contents.pvd`` (rigid contents,
rounded boxes) + ``paraview/deflectors.pvd`` + ``paraview/belt.pvd`` (fields:
:mod:`flexparcel.io.paraview`), and what the caller's picture writer draws
(:mod:`flexparcel.viz.scenario_pictures`: ``snapshots.png``, ``trajectories.png``,
``animation.gif`` and ``view.html``, the 3-D viewer in the browser).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from flexparcel.scenarios.base import (
    CHECKPOINT_FILE,
    T_END,
    Parameter,
    PictureWriter,
    Response,
    ScenarioBase,
    ScenarioResult,
    write_json,
)

if TYPE_CHECKING:
    from flexparcel.consignments.build import ConsignmentBuild
    from flexparcel.consignments.snapshot import Snapshot
    from flexparcel.contact.law import ContactLaw
    from flexparcel.scenarios.conveyor_groups import GroupSettings
    from flexparcel.scenarios.conveyor_scene import ConveyorModel, SceneFile, SceneLayout

__all__ = ["ConveyorScenario", "CONVEYOR_PARAMETERS", "WORKERS", "CHECKPOINT_FILE",
           "content_law_for", "group_settings", "deflector_friction_table"]  # fmt: skip


CONVEYOR_PARAMETERS: tuple[Parameter, ...] = (
    Parameter("belt_speed", "m/s", None, 0.0, 10.0, "belt speed (default the scene's, 1.6)"),
    Parameter("deflector_angle", "deg", None, 10.0, 90.0,
              "deflector angle to the belt direction (default the scene's, 45)"),
    Parameter("start_speed", "m/s", None, 0.0, 10.0,
              "initial velocity of the queued consignments along the belt (default the "
              "scene's, 0: at rest on the running belt)"),
    Parameter("content_stiffness", "N/mm", None, 1.0, 1e4,
              "packaging-content contact stiffness c and stick stiffness k_t = c of every "
              "consignment (default: as assembled, Table 6's 649)"),
    Parameter("pair_reach", "m", None, 0.0, 1e3,
              "consignment-consignment contact only for pairs that start closer than this "
              "(default: every pair)"),
    Parameter("deflector_friction", "-", None, 0.0, 2.0,
              "friction coefficient (static = dynamic) of every consignment's packaging on "
              "the deflectors (default: the friction table's, by packaging surface)"),
    Parameter("stick_stiffness", "N/mm", None, 0.01, 1e4,
              "stick-model stiffness k_t of every consignment's packaging-content contact "
              "(default: k_t = c, the contact stiffness); softer lets the time steps grow, "
              "and the content pre-slides mu_s F_N / k_t before it slips (docs/scenarios.md)"),
)  # fmt: skip
_PARAMETER = {q.name: q for q in CONVEYOR_PARAMETERS}

WORKERS = Parameter("workers", "", 2, 0, 64, "worker processes (0: the scene as one model)",
                    integer=True)  # fmt: skip
"""The ``workers`` setting: consignments that cannot touch are integrated as separate models
on that many processes (the default 2: the CI-class machine's two cores)."""


def content_law_for(
    stiffness_n_per_mm: float | None,
    label: str = "content_stiffness",
    *,
    stick_n_per_mm: float | None = None,
    stick_label: str = "stick_stiffness",
):
    """The packaging-content contact law with stiffness c = ``stiffness_n_per_mm`` [N/mm] in
    [1, 1e4] (default Table 6's 649) and stick stiffness k_t = ``stick_n_per_mm`` [N/mm] in
    [0.01, 1e4] (default k_t = c), damping kept; None (Table 6's law, as assembled) when
    neither is given. ``label`` and ``stick_label`` name the values in the errors. Like
    Table 6's 649, the values are per point of the paper's 10 mm nodes: the per-area law gets
    them divided by (10 mm)^2 [N/m^3]."""
    from flexparcel.contact.law import REFERENCE_AREA

    c, kt = (None if v is None else _PARAMETER[name].check(v, lab)
             for name, v, lab in (("content_stiffness", stiffness_n_per_mm, label),
                                  ("stick_stiffness", stick_n_per_mm, stick_label)))  # fmt: skip
    if c is None and kt is None:
        return None
    from flexparcel.consignments.build import default_packaging_content_law

    law = default_packaging_content_law()
    if c is not None:
        law = replace(law, stiffness=c * 1e3 / REFERENCE_AREA)
    per_area = law.stiffness if kt is None else kt * 1e3 / REFERENCE_AREA
    return replace(law, stick_stiffness=per_area)


def deflector_friction_table(mu: float | None):
    """The friction table with every packaging surface's friction on the deflectors set to
    ``mu`` [-] in [0, 2] (static = dynamic), or None (the default table) when not given."""
    if mu is None:
        return None
    from flexparcel.scenarios.friction_pairs import (
        DEFAULT_FRICTION_TABLE,
        DEFLECTOR,
        FrictionPair,
    )

    mu = _PARAMETER["deflector_friction"].check(mu)
    row = FrictionPair(mu, mu, "study parameter deflector_friction")
    table = dict(DEFAULT_FRICTION_TABLE)
    table.update({key: row for key in table if key[1] == DEFLECTOR})
    return table


def group_settings(workers: int, label: str = "workers") -> GroupSettings | None:
    """None (one model) for 0 workers, else that many worker processes (numba 1 thread
    each) for :func:`~flexparcel.scenarios.conveyor_groups.integrate_by_groups`."""
    from flexparcel.scenarios.conveyor_groups import GroupSettings

    if not isinstance(workers, int):  # 2.0 workers is a typo, not two processes
        raise ValueError(f"{label} must be an integer {WORKERS.range_text()}, got {workers!r}")
    n = WORKERS.check(workers, label)
    return None if n == 0 else GroupSettings(workers=n)


class ConveyorScenario(ScenarioBase):
    """The conveyor scene on consignments given by name -> snapshot."""

    name = "conveyor"
    description = "bulk conveyor: consignments on a belt with two deflectors (paper 4.4)"
    parameters = CONVEYOR_PARAMETERS

    def __init__(self, *, scene: SceneFile | None = None, workers: int = 2,
                 checkpoint: str | Path | None = None, preview: bool = False,
                 jam_time: float = 0.3):  # fmt: skip
        group_settings(workers)  # its range, before any run
        self.scene = scene
        self.workers = workers
        self.checkpoint = None if checkpoint is None else Path(checkpoint)
        self.preview = bool(preview)
        self.jam_time = float(jam_time)

    @property
    def t_end(self) -> float:
        """Default simulated time [s]: the scene file's, else the paper's 2 s."""
        return self.scene.t_end if self.scene is not None and self.scene.t_end else 2.0

    def layout(self, builds: Mapping[str, ConsignmentBuild],
               parameters: Mapping[str, float | None]) -> SceneLayout:  # fmt: skip
        """Where the consignments ``builds`` (name -> build) lie: the scene file's placements,
        else the default queue; belt speed, deflector angle and start speed from
        ``parameters`` where given. Checked for overlaps and fit (before any assembly)."""
        from flexparcel.scenarios.conveyor_scene import (
            SceneLayout,
            check_layout,
            default_layout,
            paper_conveyor,
        )

        scene, p = self.scene, parameters
        conveyor = scene.conveyor if scene is not None else paper_conveyor()
        speed, angle = p.get("belt_speed"), p.get("deflector_angle")
        if speed is not None or angle is not None:
            speed = conveyor.belt_speed if speed is None else speed
            angle = conveyor.deflector_angle_deg if angle is None else angle
            if scene is None:  # the paper scene's deflector positions follow the angle
                conveyor = paper_conveyor(speed, angle)
            else:
                conveyor = replace(conveyor, belt_speed=speed, deflector_angle_deg=angle)
        start = p.get("start_speed")
        if scene is not None and scene.placements:
            placements = scene.placements
            if start is not None:
                placements = tuple(replace(q, speed=start) for q in placements)
            layout = SceneLayout(conveyor, placements, scene.gap_above_belt)
        else:
            if start is None:
                start = scene.start_speed if scene is not None else 0.0
            kw = {} if scene is None else {"gap_above_belt": scene.gap_above_belt}
            layout = default_layout(builds, conveyor, speed=start, **kw)
        check_layout(layout, builds)
        return layout

    def _content_law(self, p: Mapping[str, float | None]) -> ContactLaw | None:
        return content_law_for(p.get("content_stiffness"),
                               stick_n_per_mm=p.get("stick_stiffness"))  # fmt: skip

    def build(self, consignment: Mapping[str, Snapshot],
              parameters: Mapping[str, float | None]) -> ConveyorModel:  # fmt: skip
        from flexparcel.scenarios.conveyor_scene import build_conveyor_model

        p = self.resolve(parameters)
        layout = self.layout({k: s.build for k, s in consignment.items()}, p)
        return build_conveyor_model(consignment, layout, pair_reach=p["pair_reach"],
                                    content_law=self._content_law(p),
                                    friction_table=deflector_friction_table(
                                        p.get("deflector_friction")))  # fmt: skip

    def run(
        self,
        consignment: Mapping[str, Snapshot],
        parameters: Mapping[str, object] | None = None,
        *,
        t_end: float | None = None,
        progress: Any = None,
    ) -> ScenarioResult:
        from flexparcel.scenarios.conveyor_scene import run_conveyor

        if not isinstance(consignment, Mapping):
            raise ValueError("the conveyor runs on consignments given by name -> snapshot")
        p = self.resolve(parameters)
        t = self.t_end if t_end is None else T_END.check(t_end)
        layout = self.layout({k: s.build for k, s in consignment.items()}, p)
        dt_out = min(0.01, t / 20.0)
        run = run_conveyor(consignment, layout, t, dt_out=dt_out, pair_reach=p["pair_reach"],
                           progress=progress, checkpoint=self.checkpoint,
                           checkpoint_only=self.preview, content_law=self._content_law(p),
                           groups=group_settings(self.workers),
                           jam_time=self.jam_time,
                           friction_table=deflector_friction_table(
                               p.get("deflector_friction")))  # fmt: skip
        settings = {
            "belt_speed_m_s": layout.conveyor.belt_speed,
            "deflector_angle_deg": layout.conveyor.deflector_angle_deg,
            "t_end_s": t,
            "dt_out_s": dt_out,
            "pair_reach_m": p["pair_reach"],
            "jam_time_s": self.jam_time,
            "workers": self.workers,
            "content_stiffness_N_per_mm": p["content_stiffness"],
            "stick_stiffness_N_per_mm": p.get("stick_stiffness"),
            "deflector_friction": p.get("deflector_friction"),
            "element_size_mm": {k: s.build.element_size * 1e3 for k, s in consignment.items()},
        }
        return ScenarioResult(self.name, dict(p), run.result, run.wall_s, run, settings)

    def responses(self, result: ScenarioResult) -> dict[str, Response]:
        from flexparcel.scenarios.conveyor_scene import deflector_crossings

        run = result.record
        crossings = deflector_crossings(run.conveyor_model, run.result)
        out: dict[str, Response] = {}
        for name, r in run.responses.items():
            out.update(_consignment_responses(name, r, crossings.get(name)))
        out.update(_group_responses(run.responses))
        return out

    def summary(self, result: ScenarioResult) -> dict:
        """``responses.json`` content (without ``files``): the run's summary, ``parameters``
        (the run's settings) and ``responses`` with units."""
        out = result.record.summary()
        out["parameters"] = dict(result.settings)
        out["responses"] = {k: r.to_dict() for k, r in self.responses(result).items()}
        return out

    def write(self, result: ScenarioResult, out_dir: str | Path, *,
              extra: Mapping[str, Any] | None = None,
              pictures: PictureWriter | None = None) -> dict[str, Path]:  # fmt: skip
        from flexparcel.consignments.materials import FLEXIBLE_CONTENT
        from flexparcel.io.paraview import scene_parts, write_scene_paraview
        from flexparcel.io.results import save_result

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        run = result.record
        res, cm = run.result, run.conveyor_model
        summary = {**self.summary(result), **(extra or {})}
        files: dict[str, Path] = {"json": out / "responses.json"}
        write_json(files["json"], summary)  # the numbers first: they survive a failing picture
        scene = cm.layout.conveyor
        parts = scene_parts(
            cm.model, cm.consignments, content_material=FLEXIBLE_CONTENT,
            belt={"length_m": scene.belt_length, "width_m": scene.belt_width,
                  "speed_m_s": scene.belt_speed, **_transfer_part(scene)},
            deflectors=cm.parts.deflector_vertices,
            deflector_thickness=scene.deflector_thickness,
        )  # fmt: skip
        files["results"] = save_result(out / "results.npz", res, cm.model, {
            "scenario": "conveyor", "layout": cm.layout.to_dict(),
            "consignments": {k: c.node_ids.tolist() for k, c in cm.consignments.items()},
            "parts": parts,
        })  # fmt: skip
        force = _deflector_node_forces(cm, res)
        files["contact_forces"] = _save_contact_forces(out / "contact_forces.npz", res.time, force)
        files.update(write_scene_paraview(out / "paraview", res, cm.model, parts, name="conveyor",
                                          content_name="contents",
                                          contact_force=force))  # fmt: skip
        if pictures is not None:
            files.update(pictures(result, out))
        summary["files"] = {k: str(v) for k, v in files.items()}
        write_json(files["json"], summary)
        return files


def _consignment_responses(name: str, r: Any, crossing: float | None) -> dict[str, Response]:
    """The scalar responses of one consignment's
    :class:`~flexparcel.scenarios.conveyor_responses.ConsignmentResponse`."""
    end = r.centroid[-1]
    out = {
        f"{name}.exit_time": Response(
            r.exit_time, "s", "time the centroid reaches the belt end",
            "" if r.exit_time is not None else "did not reach the belt end within the run"),
        f"{name}.final_x": Response(float(end[0]), "m", "centroid x at the end of the run"),
        f"{name}.final_y": Response(float(end[1]), "m", "centroid y at the end of the run"),
        f"{name}.jam_start": Response(
            r.jam_start, "s", "start of the first jam",
            "" if r.jam_start is not None else "no jam within the run"),
        f"{name}.peak_contact_force": Response(
            r.peak_contact_force, "N", "largest deflector force (normal and friction), the "
            "mean over an output interval",
            "" if r.peak_contact_force is not None else "no contact force recorded"),
        f"{name}.deflector_crossing": Response(
            crossing, "s", "first time a packaging node lies behind a deflector",
            "" if crossing is not None else "no packaging node behind a deflector"),
    }  # fmt: skip
    state, why = r.jam_verdict()
    judged = state != "not judged"
    stuck = float(r.time[-1]) - r.jam_start if r.jam_start is not None else 0.0
    exit_y = None if r.exit_position is None else float(r.exit_position[1])
    out.update({
        f"{name}.jammed": Response(
            float(state == "jam") if judged else None, "-",
            "1 if it jammed within the run, 0 if not", "" if judged else why),
        f"{name}.time_stuck": Response(
            stuck if judged else None, "s", "time from the jam's start to the end of the run "
            "(0 without a jam)", "" if judged else why),
        f"{name}.exit_y": Response(
            exit_y, "m", "centroid y where it reaches the belt end (lateral exit position)",
            "" if exit_y is not None else "did not reach the belt end within the run"),
    })  # fmt: skip
    for i, t in enumerate(r.deflector_contact_time, start=1):
        # never touched is not a contact of 0 s at some time: not reached, with the reason
        out[f"{name}.deflector_contact_duration_{i}"] = Response(
            float(t) if t > 0.0 else None, "s", f"time in contact with deflector {i}",
            "" if t > 0.0 else f"no node came within {1e3 * r.contact_distance:g} mm of "
            f"deflector {i}'s face within the run")  # fmt: skip
    return out


def _group_responses(responses: Mapping[str, Any]) -> dict[str, Response]:
    """The scalar responses of the whole group of consignments (``group.*``): whether any
    jammed, the last exit time, the spread (population standard deviation) of the exit y
    positions, and the largest deflector force of any consignment."""
    rs = list(responses.values())
    states = [r.jam_verdict()[0] for r in rs]
    judged = "not judged" not in states
    exits = [r.exit_time for r in rs]
    ys = [float(r.exit_position[1]) for r in rs if r.exit_position is not None]
    forces = [r.peak_contact_force for r in rs if r.peak_contact_force is not None]
    waiting = [n for n, t in zip(responses, exits, strict=True) if t is None]
    return {
        "group.jammed": Response(
            float("jam" in states) if judged else None, "-",
            "1 if any consignment jammed within the run, 0 if none did",
            "" if judged else "the run is shorter than the jam window"),
        "group.exit_time_last": Response(
            max(exits) if not waiting else None, "s", "time the last consignment reaches the "
            "belt end", "" if not waiting else f"{', '.join(waiting)} did not reach the belt "
            "end within the run"),
        "group.exit_spread": Response(
            float(np.std(ys)) if len(ys) >= 2 else None, "m", "spread (standard deviation) "
            "of the consignments' exit y positions", "" if len(ys) >= 2 else "fewer than two "
            "consignments reached the belt end within the run"),
        "group.peak_contact_force": Response(
            max(forces) if forces else None, "N", "largest deflector force (mean over an "
            "output interval) on any consignment", "" if forces else "no contact force "
            "recorded"),
    }  # fmt: skip


def _deflector_node_forces(cm: Any, res: Any) -> np.ndarray:
    """Deflector normal force on each packaging node at the recorded frames [N], shape
    (k, n, 3): :func:`~flexparcel.scenarios.conveyor_scene.deflector_node_forces` along each
    deflector's upstream normal."""
    from flexparcel.scenarios.conveyor_scene import deflector_node_forces

    normals = np.array([g.normal for g in cm.parts.deflectors], dtype=float).reshape(-1, 3)
    return np.einsum("dkn,dj->knj", deflector_node_forces(cm, res), normals)


def _save_contact_forces(path: Path, time: Any, force: np.ndarray) -> Path:
    """``contact_forces.npz``: the non-zero node forces as ``frame`` (m,), ``node`` (m,),
    ``force_N`` (m, 3) [N], and ``time`` (k,) [s] (docs/file-formats.md)."""
    from flexparcel.io.atomic import write_atomic

    frame, node = np.nonzero(np.any(force != 0.0, axis=2))
    arrays = {"time": np.asarray(time, float), "frame": frame.astype(np.int64),
              "node": node.astype(np.int64), "force_N": force[frame, node]}  # fmt: skip
    return write_atomic(path, lambda f: np.savez_compressed(f, **arrays))


def _transfer_part(scene) -> dict[str, float]:
    """The transfer belt's keys of the results' ``belt`` part (none without one)."""
    t = scene.transfer
    if t is None:
        return {}
    return {"transfer_gap_m": t.gap, "transfer_length_m": t.length, "transfer_speed_m_s": t.speed}
