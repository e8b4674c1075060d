"""Design studies (``purpose = "design"``): no targets, a screen and a hypercube over every
parameter, outcomes a run may not reach, and the report's maps and contours.

The simulator is a closed-form stand-in for a sorter (``sorter.py`` next to the study): a
consignment jams where the belt is slow and the deflector steep, and then has no exit time;
the exit spread is smooth in speed and angle and does not depend on friction. So the truth of
every map is known."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from flexparcel.calibration import Study, StudyConfigError, load_study
from flexparcel.cli import main

ROOT = Path(__file__).resolve().parents[1]

SORTER = """
def sorter(params, **setup):
    v, a, mu = params["speed"], params["angle"], params["friction"]
    jammed = 1.0 if a > 30.0 + 20.0 * v else 0.0
    out = {"jammed": jammed, "spread": 0.05 * v + 0.002 * a + 0.0005 * v * a}
    if not jammed:
        out["exit_time"] = 1.0 / v + 0.3 * mu
    return out
"""

STUDY = """
version = 1
purpose = "design"
name = "sorter"
store = "sorter.sqlite"
output = "report"
random_state = 7

[execution]
workers = 0

[parameters.speed]
bounds = [1.0, 2.5]
unit = "m/s"

[parameters.angle]
bounds = [30, 60]
unit = "deg"

[parameters.friction]
bounds = [0.1, 0.5]

[experiments.line]
simulator = "sorter.py:sorter"
outcomes = ["jammed", "spread", "exit_time"]
screening = { design = "full-factorial" }
design = { runs = 14 }

[maps]
axes = ["speed", "angle"]
"""


def write(tmp_path: Path, text: str = STUDY) -> Path:
    (tmp_path / "sorter.py").write_text(SORTER)
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


def truth(p):
    ns: dict = {}
    exec(compile(SORTER, "sorter", "exec"), ns)  # the test's own stand-in, not a data file
    return ns["sorter"](p)


def test_design_study_runs_screen_and_hypercube_and_maps_its_outcomes(tmp_path):
    path = write(tmp_path)
    assert main(["calibrate", str(path)]) == 0
    res = json.loads((tmp_path / "report" / "results.json").read_text())
    assert res["purpose"] == "design"
    line = res["experiments"]["line"]
    # 2^3 factorial + 14 hypercube runs, each once, every outcome as the stand-in gives it
    assert len(line["runs"]) == 8 + 14
    for run in line["runs"]:
        assert run["outcomes"] == pytest.approx(truth(run["params"]))
    jams = sum(r["outcomes"]["jammed"] for r in line["runs"])
    assert 0 < jams < len(line["runs"])  # the design crosses the jam boundary
    # a jammed run has no exit time: recorded as absent, not a failure
    assert res["run_counts"].get("failed", 0) == 0
    assert line["maps"]["jammed"] == {
        "kind": "binary",
        "counts": {"1": jams, "0": len(line["runs"]) - jams, "not reached": 0},
    }
    # the screen ranks speed and angle (spread depends on them, not on friction) and leaves
    # out exit_time, which the jammed factorial corner did not reach
    sc = line["screening"]
    assert {"speed", "angle"} <= set(sc["significant"])
    assert "exit_time" in sc["not_analysed"]
    assert sc["frozen"] == {}
    # every parameter is varied in the hypercube (a design study freezes none)
    hyper = [r for r in line["runs"] if r["stage"] == "design"]
    for p in ("speed", "angle", "friction"):
        assert np.ptp([r["params"][p] for r in hyper]) > 0
    # the contour of the smooth spread: its GP's out-of-fold error is a few % of its range
    # (22 runs of a bilinear function in three inputs)
    spread = line["maps"]["spread"]
    assert spread["kind"] == "contour" and spread["n_runs"] == 22
    lo, hi = spread["range"]
    assert spread["cv_rmse"] < 0.05 * (hi - lo)
    assert line["maps"]["exit_time"]["n_runs"] == 22 - jams
    # drawn only where runs reached it: all of the plane for the spread, not the jam corner
    # (slow belt, steep deflector) for the exit time
    assert spread["drawn_fraction"] == 1.0
    assert 0.5 < line["maps"]["exit_time"]["drawn_fraction"] < 1.0
    html = (tmp_path / "report" / "report.html").read_text()
    assert "Design study: sorter" in html and "not reached" in html
    for fig in ("map_line_jammed.png", "contour_line_spread.png", "contour_line_exit_time.png"):
        assert (tmp_path / "report" / "figures" / fig).is_file()
    # run again: everything is in the store, nothing is simulated twice
    with Study(path, progress=False) as study:
        study.run()
        assert all(c.succeeded == 0 for c in study.campaigns.values())


@pytest.mark.parametrize(
    "edit, field",
    [
        (('outcomes = ["jammed", "spread", "exit_time"]',
          'outcomes = ["jammed"]\n[experiments.line.targets]\njammed = 0'), "targets"),
        (('outcomes = ["jammed", "spread", "exit_time"]', ""), "outcomes"),
        (('purpose = "design"', 'purpose = "explore"'), "purpose"),
        (('axes = ["speed", "angle"]', 'axes = ["speed", "speed"]'), "axes"),
        (('axes = ["speed", "angle"]', 'axes = ["speed", "angle"]\ncontours = ["nope"]'),
         "contours"),
        (('purpose = "design"', ""), "outcomes"),
        (('axes = ["speed", "angle"]', 'axes = ["speed", "angle"]\nflags = ["jam"]'), "flags"),
    ],
)  # fmt: skip
def test_bad_design_study_names_the_field(tmp_path, edit, field):
    path = write(tmp_path, STUDY.replace(*edit))
    with pytest.raises(StudyConfigError, match=rf"\b{field}\b"):
        load_study(path)


def test_flags_and_contours_are_what_the_study_names(tmp_path):
    """[maps] flags and contours choose the drawings: a listed flag is a map, an outcome in
    neither list is tabulated only."""
    text = STUDY.replace(
        'axes = ["speed", "angle"]',
        'axes = ["speed", "angle"]\nflags = ["jammed"]\ncontours = ["spread"]',
    )
    text = text.replace("runs = 14", "runs = 4")  # fmt: skip
    path = write(tmp_path, text)
    with Study(path, progress=False) as study:
        study.run()
    maps = json.loads((tmp_path / "report" / "results.json").read_text())["experiments"]["line"]
    assert set(maps["maps"]) == {"jammed", "spread"}
    assert maps["maps"]["jammed"]["kind"] == "binary"
    assert maps["maps"]["spread"]["kind"] == "contour"


def test_a_design_study_refuses_the_calibration_stages(tmp_path, capsys):
    path = write(tmp_path)
    with Study(path, progress=False) as study:
        for stage in ("fit", "optimise", "validate"):
            with pytest.raises(StudyConfigError, match="stages are screen, design, report"):
                getattr(study, stage)()
    assert main(["calibrate", str(path), "--stage", "fit"]) == 2
    assert "does not apply to a design study" in capsys.readouterr().err


def test_conveyor_design_example_plans_its_runs(capsys):
    """The shipped example: a 2^(3-1) screen and 8 hypercube runs over belt speed, deflector
    angle and deflector friction, on the conveyor simulator with its own scene."""
    example = ROOT / "examples" / "conveyor_design.toml"
    config = load_study(example)
    assert config.purpose == "design"
    assert main(["calibrate", str(example), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "screen" in out and "design" in out and "validate" not in out
    assert "Latin hypercube over 3 parameters" in out
    runs = [line.split() for line in out.splitlines() if line.startswith(("screen", "design"))]
    assert [int(r[3]) for r in runs] == [4, 8]
