"""The Scenario protocol and registry (flexparcel.scenarios.base, .registry).

A scenario defined here in a few lines (a flat sheet settling on a plane, 3 x 3 shells,
0.01 s) is registered and run through the registry: adding a scenario is one module plus one
registration. The built-ins are registered, declare their parameters with units and ranges,
and reject out-of-range values naming the field and the range; third-party scenarios are
found through the ``flexparcel.scenarios`` entry points.
"""

from __future__ import annotations

import json
import math
import sys
from importlib.metadata import EntryPoint
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from flexparcel.scenarios import registry
from flexparcel.scenarios.base import (
    Parameter,
    Response,
    Scenario,
    ScenarioBase,
    ScenarioResult,
    write_json,
)
from flexparcel.scenarios.registry import (
    BUILTINS,
    UnknownScenarioError,
    get_scenario,
    register_scenario,
    scenario_names,
)


@pytest.fixture(autouse=True)
def _own_registry(monkeypatch):
    # each test registers into a copy: nothing leaks into the other tests
    monkeypatch.setattr(registry, "_FACTORIES", dict(registry._FACTORIES))


# --------------------------------------------------------------------------------------------
# a scenario in one class: a 60 mm sheet resting on a plane


class SheetRest(ScenarioBase):
    """A 60 x 60 mm, 0.3 mm sheet (3 x 3 quads) released touching a rigid plane."""

    name = "sheet-rest"
    description = "flat sheet settling on a plane"
    parameters = (
        Parameter("youngs_modulus", "MPa", 926.0, 0.0, 1e5, "sheet modulus", low_open=True),
        Parameter("contact_stiffness", "N/mm", 611.0, 0.0, 1e4, "sheet-plane stiffness c",
                  low_open=True),
    )  # fmt: skip
    thickness = 0.3e-3

    def build(self, consignment, parameters):
        import flexparcel as fp
        from flexparcel.contact.law import ContactLaw

        p = self.resolve(parameters)
        h = self.thickness
        pts, quads = fp.mesh.rectangle(0.06, 0.06, 3, 3, origin=(-0.03, -0.03, h / 2))
        b = fp.ModelBuilder(gravity=(0.0, 0.0, -9.81))
        mat = fp.ShellMaterial(p["youngs_modulus"] * 1e6, 0.1, 2424.0, h, 1.71e-3)
        ids = b.add_shell_mesh(pts, quads, material=mat)
        plane = b.add_plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        law = ContactLaw.from_paper_units(c_N_per_mm=p["contact_stiffness"], d_Ns_per_mm=0.5,
                                          s_max_mm=0.1, mu_static=0.3, mu_dynamic=0.3)  # fmt: skip
        b.add_contact(ids, plane, law, radius=h / 2)
        return b.finalize()

    def run(self, consignment, parameters=None, *, t_end=None, progress=None):
        import time

        import flexparcel as fp

        p = self.resolve(parameters)
        model = self.build(consignment, p)
        t = 0.01 if t_end is None else t_end
        wall = time.perf_counter()
        res = fp.simulate(model, t, dt_out=t / 5, progress=progress)
        return ScenarioResult(self.name, p, res, time.perf_counter() - wall, model, {"t_end_s": t})

    def responses(self, result):
        z = result.simulation.positions[:, :, 2]  # (k, n)
        gap = z - self.thickness / 2
        lifted = np.flatnonzero(np.diff((gap > 2e-4).astype(int)) > 0)
        return {
            "final_gap_mm": Response(float(gap[-1].mean()) * 1e3, "mm", "mean gap at the end"),
            "lift_off_time": Response(
                float(result.simulation.time[lifted[0] + 1]) if lifted.size else None, "s",
                "first time the sheet leaves the plane again",
                "" if lifted.size else "the sheet did not leave the plane within the run",
            ),
        }  # fmt: skip

    def write(self, result, out_dir, *, extra=None, pictures=None):
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        resp = {k: r.to_dict() for k, r in self.responses(result).items()}
        path = write_json(out / "responses.json", {"responses": resp, **(extra or {})})
        return {"json": path}


def test_a_scenario_defined_here_runs_through_the_registry(tmp_path):
    register_scenario("sheet-rest", SheetRest)
    assert "sheet-rest" in scenario_names()
    scenario = get_scenario("sheet-rest")
    assert isinstance(scenario, Scenario)
    result = scenario.run({}, {"youngs_modulus": 500.0}, t_end=0.01)
    assert result.parameters == {"youngs_modulus": 500.0, "contact_stiffness": 611.0}
    assert result.wall_s > 0.0 and result.simulation.time[-1] == pytest.approx(0.01)
    r = scenario.responses(result)
    # it rests on the plane: its static sink m g / c per node is below a micrometre
    assert r["final_gap_mm"].unit == "mm" and abs(r["final_gap_mm"].value) < 1e-3
    # a response the run does not reach says so instead of being 0
    assert r["lift_off_time"].unit == "s" and not r["lift_off_time"].reached
    assert "did not leave" in r["lift_off_time"].note
    files = scenario.write(result, tmp_path / "out", extra={"note": "test"})
    data = json.loads(files["json"].read_text())
    assert data["responses"]["lift_off_time"]["value"] is None
    assert data["responses"]["final_gap_mm"]["unit"] == "mm" and data["note"] == "test"
    with pytest.raises(ValueError, match="already registered"):
        register_scenario("sheet-rest", lambda: SheetRest())


# --------------------------------------------------------------------------------------------
# the built-ins


@pytest.mark.parametrize("name", list(BUILTINS))
def test_builtins_are_registered_and_declare_parameters_with_units(name):
    assert name in scenario_names()
    scenario = get_scenario(name)
    assert isinstance(scenario, Scenario) and scenario.name == name
    assert scenario.parameters
    for p in scenario.parameters:
        assert p.unit and p.description, p.name
        assert p.default is None or p.low <= p.default <= p.high, p.name
    defaults = scenario.resolve()
    assert list(defaults) == [p.name for p in scenario.parameters]


@pytest.mark.parametrize(
    ("name", "field", "value", "message"),
    [
        ("swing", "youngs_modulus", -1, "youngs_modulus must be > 0 MPa, got -1"),
        ("drop-vertical", "damping_ratio", 0, "damping_ratio must be > 0 s, got 0"),
        ("drop-horizontal", "contact_stiffness_packaging_ground", -5,
         "contact_stiffness_packaging_ground must be > 0 N/mm, got -5"),
        ("conveyor", "belt_speed", 12, "belt_speed must be in [0, 10] m/s, got 12"),
        ("conveyor", "content_stiffness", 0.5,
         "content_stiffness must be in [1, 10000] N/mm, got 0.5"),
        ("conveyor", "deflector_friction", 3, "deflector_friction must be in [0, 2] -, got 3"),
    ],
)  # fmt: skip
def test_builtins_reject_out_of_range_naming_field_and_range(name, field, value, message):
    scenario = get_scenario(name)
    with pytest.raises(ValueError) as err:
        scenario.resolve({field: value})
    assert message in str(err.value)
    with pytest.raises(ValueError, match=f"got {value:g}"):
        scenario.resolve([f"{field}={value}"])  # the command line's NAME=VALUE form
    with pytest.raises(ValueError, match=r"unknown parameter 'stiffness'; settable: "):
        scenario.resolve({"stiffness": 1.0})


def test_unknown_scenario_lists_the_known_ones():
    with pytest.raises(UnknownScenarioError) as err:
        get_scenario("swings")
    msg = str(err.value)
    assert "unknown scenario 'swings'" in msg
    assert all(name in msg for name in BUILTINS)


def test_conveyor_settings_are_checked_by_name():
    with pytest.raises(ValueError, match=r"workers must be an integer in \[0, 64\], got 65"):
        get_scenario("conveyor", workers=65)
    with pytest.raises(ValueError, match=r"drop_height must be in \(0, 10\] m"):
        get_scenario("drop-vertical", drop_height=-0.1)


# --------------------------------------------------------------------------------------------
# third-party scenarios through entry points


def test_entry_point_scenarios_are_found_and_loaded_on_first_use(tmp_path, monkeypatch):
    module = "fp_thirdparty_scenario"
    (tmp_path / f"{module}.py").write_text(
        "from flexparcel.scenarios.base import Parameter, ScenarioBase\n"
        "class Tilt(ScenarioBase):\n"
        "    name = 'tilt-table'\n"
        "    parameters = (Parameter('angle', 'deg', 10.0, 0.0, 90.0, 'table tilt'),)\n"
        "    def build(self, consignment, parameters): return None\n"
        "    def run(self, consignment, parameters=None, *, t_end=None, progress=None): ...\n"
        "    def responses(self, result): return {}\n"
        "    def write(self, result, out_dir, *, extra=None, pictures=None): return {}\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    points = [
        EntryPoint("tilt-table", f"{module}:Tilt", registry.ENTRY_POINT_GROUP),
        EntryPoint("swing", f"{module}:Tilt", registry.ENTRY_POINT_GROUP),  # taken: ignored
    ]

    def entry_points(group=None):
        return [ep for ep in points if ep.group == group]

    monkeypatch.setattr("importlib.metadata.entry_points", entry_points)
    monkeypatch.setattr(registry, "_discovered", False)
    monkeypatch.delitem(sys.modules, module, raising=False)
    with pytest.warns(UserWarning, match="'swing' is already registered"):
        names = scenario_names()
    assert names[: len(BUILTINS)] == list(BUILTINS) and "tilt-table" in names
    assert module not in sys.modules  # listed, not loaded
    tilt = get_scenario("tilt-table")
    assert module in sys.modules and isinstance(tilt, Scenario)
    with pytest.raises(ValueError, match=r"angle must be in \[0, 90\] deg, got 95"):
        tilt.resolve({"angle": 95})
    assert type(get_scenario("swing")).__name__ == "SwingScenario"


# --------------------------------------------------------------------------------------------
# responses and parameters


def test_a_response_is_a_number_or_not_reached_with_a_reason():
    assert Response(4.5, "mm", "rebound").reached
    assert Response(None, "s", "exit time", "did not reach the belt end").format() == (
        "not reached (did not reach the belt end)"
    )
    with pytest.raises(ValueError, match="needs a note"):
        Response(None, "mm", "rebound")
    with pytest.raises(ValueError, match="use value=None"):
        Response(math.nan, "mm", "rebound")


def test_parameter_ranges_and_integers():
    p = Parameter("t_end", "s", None, 0.0, 10.0, "simulated time", low_open=True)
    assert p.range_text() == "in (0, 10] s" and p.check("2.5") == 2.5
    with pytest.raises(ValueError, match=r"--t-end must be in \(0, 10\] s, got 0"):
        p.check(0.0, "--t-end")
    with pytest.raises(ValueError, match="'x' is not a number"):
        p.check("x")
    n = Parameter("workers", "", 2, 0, 64, "processes", integer=True)
    assert n.check(3) == 3 and isinstance(n.check(3.0), int)
    for bad in (1.5, True, math.inf):
        with pytest.raises(ValueError, match=r"workers must be an integer in \[0, 64\]"):
            n.check(bad)


def test_swing_that_never_swings_past_reports_not_reached():
    # a free end that stays on its starting side: neither swing is reached (not 0 mm)
    swing = get_scenario("swing")
    pos = np.zeros((5, 2, 3))
    pos[:, 1, 0] = 0.3  # node 0: the -x end at 0 (clamp edge at 20 mm); node 1 the free end
    run = SimpleNamespace(
        result=SimpleNamespace(positions=pos),
        consignment=SimpleNamespace(packaging=np.array([0, 1]), edge=np.array([1])),
        responses={"first_swing_mm": 0.0, "second_swing_mm": 0.0},
    )
    r = swing.responses(ScenarioResult("swing", {}, run.result, 0.0, run))
    assert not r["first_swing_mm"].reached and not r["second_swing_mm"].reached
    assert r["first_swing_mm"].unit == "mm" and "did not swing past" in r["first_swing_mm"].note


def test_consignment_tests_warn_on_shells_coarser_than_15_mm(capsys):
    import warnings

    from flexparcel.cli import _plain_warnings
    from flexparcel.model.materials import CoarseMeshWarning
    from flexparcel.scenarios.consignment_scenario import warn_if_coarse

    with pytest.warns(CoarseMeshWarning, match="25 mm shells are coarser than the paper's 10"):
        warn_if_coarse("swing", 25.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_if_coarse("swing", 10.0)  # the paper's mesh: silent
        warn_if_coarse("drop-vertical", 15.0)
    # the CLI shows a warning as one plain line
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        _plain_warnings("run")
        warn_if_coarse("swing", 25.0)
    err = capsys.readouterr().err
    assert err.startswith("flexparcel run: warning: swing: 25 mm shells are coarser")
    assert err.count("\n") == 1


def _drop_record(low_gaps_m, com_m):
    """A drop record of two packaging nodes whose lower one is ``low_gaps_m`` above its
    contact surface per frame, and a centre of mass at ``com_m``: (model, result, consignment)
    for the response functions (contact radius 1 mm)."""
    low = np.asarray(low_gaps_m) + 1e-3
    pos = np.zeros((low.size, 2, 3))
    pos[:, 0, 2] = low
    pos[:, 1, 2] = 2.0 * np.asarray(com_m) - low  # equal masses: the centre is the mean
    model = SimpleNamespace(mass=np.ones((2, 6)))
    res = SimpleNamespace(positions=pos)
    c = SimpleNamespace(packaging=np.array([0, 1]), node_ids=np.array([0, 1]),
                        contact_radius=1e-3)  # fmt: skip
    return model, res, c


def test_camera_clearance_is_the_gap_under_the_lowest_point_not_the_centre_rise():
    from flexparcel.scenarios.consignment_tests import camera_clearance, com_rise_outcome

    # falls, touches, its lowest point leaves the plate by 3 mm and lands again, while the
    # centre of mass keeps sinking (a consignment tipping over): the camera sees 3 mm
    gaps = [0.02, 0.0, 0.001, 0.003, 0.002, 0.0, 0.0]
    com = [0.05, 0.03, 0.029, 0.028, 0.027, 0.026, 0.025]
    gap, why = camera_clearance(*_drop_record(gaps, com))
    assert gap == pytest.approx(0.003) and why == ""
    rise, _ = com_rise_outcome(*_drop_record(gaps, com))
    assert not rise  # the centre-of-mass rebound sees no bounce at all
    # a box bouncing inside an envelope that stays on the plate: the centre rises, the gap
    # under the lowest point stays 0
    com_box = [0.05, 0.03, 0.032, 0.034, 0.032, 0.03, 0.03]
    assert camera_clearance(*_drop_record([0.02] + [0.0] * 6, com_box))[0] == 0.0
    assert com_rise_outcome(*_drop_record([0.02] + [0.0] * 6, com_box))[0] == pytest.approx(0.004)
    # not reached: no touch, or the gap still growing at the end of the record
    assert camera_clearance(*_drop_record([0.03, 0.02, 0.01], [0.1] * 3)) == (
        None, "the consignment did not touch the plate within the run")  # fmt: skip
    gap, why = camera_clearance(*_drop_record([0.01, 0.0, 0.001, 0.002], [0.1] * 4))
    assert gap is None and "still growing" in why
