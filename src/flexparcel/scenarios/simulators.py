"""The physical tests as calibration simulators: ``swing``, ``drop-vertical``,
``drop-horizontal`` and ``conveyor``.

Each is a plain function ``simulator(params, **setup) -> {response: value}`` registered
through the entry-point group ``flexparcel.simulators`` (``pyproject.toml``), so a study names
it (``simulator = "swing"``) and :mod:`flexparcel.calibration` finds it without importing any
finite-element code itself. Each runs its scenario (:mod:`flexparcel.scenarios.registry`):

* ``params``: the scenario's parameters in the paper's units, by the names of Table 3
  (``youngs_modulus`` [MPa], ``damping_ratio`` [s], ``contact_stiffness`` [N/mm],
  ``contact_damping`` [Ns/mm], ...; see ``flexparcel run SCENARIO --help`` or
  ``get_scenario(name).parameters``); a name the scenario does not have is refused by name.
* ``setup`` (the study's ``[experiments.X.setup]`` table): ``consignment`` (a preset: KPBW,
  PB, KP, BW, or a consignment TOML file), ``element_size_mm`` (default: the consignment's),
  ``snapshot`` (a snapshot ``.npz`` to start from; default: the cached assembly in
  ``snapshot_dir``, assembled on first use), ``snapshot_dir`` (default ``snapshots``),
  ``t_end_s`` (simulated time; default: the scenario's), ``air_drag`` (the envelope's drag
  coefficient in still air; default 0, none, as the paper's model), ``membrane`` (the
  packaging's membrane law in the test, "elastic" or "tension-field"; default: the
  snapshot's, elastic for the shipped ones). Relative paths are taken from the working
  directory of ``flexparcel calibrate``.
* returns the scenario's responses in mm (``first_swing_mm``, ``second_swing_mm``;
  ``rebound_mm`` and ``com_rise_mm``; for the conveyor per consignment exit times and
  positions). A paper response the run did not reach fails the run with the scenario's
  reason: a calibration must not fit a number that was not measured; a second response not
  reached is left out (a study targeting it then fails the run as missing). The study store
  records each run's wall time.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

__all__ = [
    "swing", "drop_vertical", "drop_horizontal", "conveyor", "scenario_snapshot",
    "ResponseNotReached",
]  # fmt: skip


class ResponseNotReached(ValueError):
    """A paper response the run did not reach. It is the model's outcome at these
    parameters, the same on every attempt, so a campaign does not retry the run
    (``retryable``, read by :mod:`flexparcel.calibration.execution`)."""

    retryable = False


def scenario_snapshot(
    consignment: str,
    element_size_mm: float | None = None,
    snapshot: str | None = None,
    snapshot_dir: str = "snapshots",
):
    """The settled snapshot a test starts from: ``snapshot`` if given (checked against the
    consignment and element size), else ``snapshot_dir/KEY_SIZEmm.npz``, else the shipped
    snapshot where one fits (:func:`~flexparcel.consignments.snapshot.shipped_snapshot`), else
    assembled and written to ``snapshot_dir/KEY_SIZEmm.npz`` (atomically) on first use."""
    from flexparcel.consignments.assembly import assemble
    from flexparcel.consignments.snapshot import (
        check_snapshot_matches,
        load_snapshot,
        save_snapshot,
        shipped_snapshot,
    )
    from flexparcel.consignments.userfile import resolve_consignment

    size = None if element_size_mm is None else float(element_size_mm) * 1e-3
    build = resolve_consignment(consignment, size)
    if snapshot is not None:
        snap = load_snapshot(snapshot)
        check_snapshot_matches(snap, build, size)
        return snap
    key = Path(str(consignment)).stem.replace("/", "").upper()
    path = Path(snapshot_dir) / f"{key}_{build.element_size * 1e3:g}mm.npz"
    if path.is_file():
        snap = load_snapshot(path)
        check_snapshot_matches(snap, build, build.element_size)
        return snap
    shipped = shipped_snapshot(build)
    if shipped is not None:
        return shipped[0]
    snap = assemble(build)
    save_snapshot(snap, path)  # atomic: two workers assembling at once both write whole files
    return snap


_SETUP = {
    "consignment", "element_size_mm", "snapshot", "snapshot_dir", "t_end_s", "air_drag",
    "membrane",
}  # fmt: skip
_CONVEYOR_SETUP = {"consignments", "scene", "element_size_mm", "snapshot_dir", "t_end_s", "workers"}


def _check_setup(name: str, setup: Mapping[str, object], allowed: set[str]) -> None:
    unknown = sorted(set(setup) - allowed)
    if unknown:
        raise ValueError(
            f"{name}: unknown setup option(s) {', '.join(unknown)}; allowed: {sorted(allowed)}"
        )


def _check_parameters(name: str, scenario, params: Mapping[str, float]) -> None:
    known = {p.name for p in scenario.parameters}
    bad = sorted(set(params) - known)
    if bad:
        raise ValueError(
            f"{name}: unknown parameter(s) {', '.join(bad)}; this simulator takes "
            f"{', '.join(sorted(known))} (paper units)"
        )


def _run(
    name: str, params: Mapping[str, float], setup: Mapping[str, object], checkpoint=None
) -> dict:
    from flexparcel.scenarios.registry import get_scenario

    _check_setup(name, setup, _SETUP)
    if "consignment" not in setup and "snapshot" not in setup:
        raise ValueError(f"{name}: the setup needs 'consignment' (a preset or a TOML file)")
    options = {k: setup[k] for k in ("air_drag", "membrane") if k in setup}
    if "air_drag" in options:
        options["air_drag"] = float(options["air_drag"])
    scenario = get_scenario(name, checkpoint=checkpoint, **options)
    _check_parameters(name, scenario, params)
    scenario.resolve(dict(params))  # values against their ranges, before any assembly
    snap = scenario_snapshot(
        str(setup.get("consignment", "")) or _consignment_of(setup["snapshot"]),
        setup.get("element_size_mm"),
        setup.get("snapshot"),
        str(setup.get("snapshot_dir", "snapshots")),
    )
    result = scenario.run(snap, dict(params), t_end=setup.get("t_end_s"))
    out = {}
    for rname, r in scenario.responses(result).items():
        if r.reached:
            out[rname] = float(r.value)
        elif rname in _PAPER_RESPONSES:
            raise ResponseNotReached(f"{name}: {rname} not reached: {r.note}")
    return out


# what the paper measured: a run that does not reach one of them fails; a second response
# (the drops' com_rise_mm: a consignment that tips over keeps sinking) is left out instead
_PAPER_RESPONSES = {"first_swing_mm", "second_swing_mm", "rebound_mm"}


def _consignment_of(snapshot: object) -> str:
    from flexparcel.consignments.snapshot import load_snapshot

    return load_snapshot(str(snapshot)).build.spec.id


def _test_simulator(name: str, what: str):
    """The simulator of the consignment test ``name``: ``f(params, run_checkpoint=None,
    **setup) -> {response: mm}``; ``run_checkpoint`` is a ``.npz`` the run saves itself to and
    resumes from (a campaign gives one per run, see :mod:`flexparcel.calibration.execution`),
    not part of the run's identity."""

    def simulator(
        params: Mapping[str, float], run_checkpoint: str | None = None, **setup: object
    ) -> dict[str, float]:
        return _run(name, params, setup, run_checkpoint)

    simulator.__name__ = simulator.__qualname__ = name.replace("-", "_")
    simulator.__doc__ = f"{what} ``run_checkpoint``: see :func:`_test_simulator`."
    simulator.resumable = True  # takes run_checkpoint (read by flexparcel.calibration.execution)
    return simulator


swing = _test_simulator("swing", "The paper's swing test: first and second swing [mm].")
drop_vertical = _test_simulator(
    "drop-vertical",
    "The paper's vertical drop (standing on its edge, 200 mm): rebound (the camera's "
    "clearance) and centre-of-mass rise [mm] (see :mod:`flexparcel.scenarios.drop`).",
)
drop_horizontal = _test_simulator(
    "drop-horizontal",
    "The paper's horizontal drop (lying flat, 200 mm): rebound (the camera's clearance) and "
    "centre-of-mass rise [mm] (see :mod:`flexparcel.scenarios.drop`).",
)


def conveyor(params: Mapping[str, float], **setup: object) -> dict[str, float]:
    """The conveyor scene (``scene``: a scene TOML file, see ``examples/conveyor_scene.toml``,
    taken from the working directory; its belt, deflectors, placements and simulated time,
    with the study's parameters replacing its belt speed, deflector angle and friction;
    ``consignments``: a list of presets or TOML files for the default queue, default the
    paper's four; ``workers``: as for ``flexparcel run conveyor``): the scalar responses per
    consignment and for the group that the run reached. A consignment that never leaves the
    belt has no exit response (that is the outcome, not a failure); a calibration study naming
    it as a target gets the run reported as missing that response, a design study records it
    as absent. The run key holds the scene's path, not its content: a study whose scene file
    changed needs a new store."""
    from flexparcel.scenarios.conveyor_scene import PAPER_CONSIGNMENTS, load_scene_file
    from flexparcel.scenarios.registry import get_scenario

    _check_setup("conveyor", setup, _CONVEYOR_SETUP)
    scene = None if setup.get("scene") is None else load_scene_file(str(setup["scene"]))
    if scene is not None and scene.placements and "consignments" in setup:
        raise ValueError("conveyor: the setup gives 'consignments' and a 'scene' with "
                         "[[consignment]] placements; give one of them")  # fmt: skip
    scenario = get_scenario("conveyor", scene=scene, workers=int(setup.get("workers", 2)))
    _check_parameters("conveyor", scenario, params)
    scenario.resolve(dict(params))
    if scene is not None and "consignments" not in setup:
        refs = dict(scene.consignments)
    else:
        names = [str(n) for n in setup.get("consignments", PAPER_CONSIGNMENTS)]
        refs = {Path(n).stem.replace("/", "").upper(): n for n in names}
    size_mm = setup.get("element_size_mm")
    if size_mm is None and scene is not None and scene.element_size is not None:
        size_mm = scene.element_size * 1e3
    snap_dir = str(setup.get("snapshot_dir", "snapshots"))
    snaps = {key: scenario_snapshot(ref, size_mm, None, snap_dir) for key, ref in refs.items()}
    result = scenario.run(snaps, dict(params), t_end=setup.get("t_end_s"))
    return {k: float(r.value) for k, r in scenario.responses(result).items() if r.reached}


# Metadata a calibration study is checked against before any run (plain literals: reading them
# imports no finite-element code). Parameter name -> unit: the paper's Table 3 names and units
# (scenarios.consignment_tests.TABLE3_PARAMETERS) and the conveyor's CONVEYOR_PARAMETERS.
TABLE3_UNITS = {
    "youngs_modulus": "MPa",
    "damping_ratio": "s",
    "contact_stiffness_packaging_content": "N/mm",
    "contact_damping_packaging_content": "Ns/mm",
    "contact_stiffness_packaging_ground": "N/mm",
    "contact_damping_packaging_ground": "Ns/mm",
}
# and the packaging's two friction coefficients (consignment_tests.PACKAGING_FRICTION)
TEST_UNITS = {**TABLE3_UNITS, "friction_packaging_content": "-", "friction_packaging_ground": "-"}
CONVEYOR_UNITS = {
    "belt_speed": "m/s",
    "deflector_angle": "deg",
    "start_speed": "m/s",
    "content_stiffness": "N/mm",
    "stick_stiffness": "N/mm",
    "pair_reach": "m",
    "deflector_friction": "-",
}

# the study store hashes runs with the simulator's version: bump it when results change
# (drops "2": rebound_mm became the camera's clearance, the centre-of-mass rise com_rise_mm;
# swing "2": the clamp closes as flat jaws before the release, and its own step control;
# conveyor "2": the belt is a bounded slab, packaging beyond its edges and end falls;
# conveyor "3": the peak deflector force is in newtons, the per-area law times each node's
# tributary area; "2" summed the law's pressures [Pa]; conveyor "4": CHOLMOD where installed,
# whose step sequence differs from SuperLU's within the integrator's tolerance; conveyor "5":
# the peak deflector force is the largest mean over an output interval, from the recorded
# impulse, normal force and friction together; "4" took the largest normal-force sample;
# swing "3", drops "3", conveyor "6": Newton's momentum test (IntegratorOptions.
# newton_momentum_tol) ends steps only when no free body carries a net residual force;
# drop-vertical "4": the glued edge's line contact on the plate has the stick model)
for _f, _version, _responses, _units, _setup in (
    (swing, "3", ("first_swing_mm", "second_swing_mm"), TEST_UNITS, _SETUP),
    (drop_vertical, "4", ("rebound_mm", "com_rise_mm"), TEST_UNITS, _SETUP),
    (drop_horizontal, "3", ("rebound_mm", "com_rise_mm"), TEST_UNITS, _SETUP),
    (conveyor, "6", (), CONVEYOR_UNITS, _CONVEYOR_SETUP),
):
    _f.simulator_version = _version
    _f.simulator_responses = _responses
    _f.simulator_parameters = dict(_units)
    _f.simulator_setup = tuple(sorted(_setup))
