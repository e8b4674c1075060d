"""study.toml validation, the `flexparcel calibrate` pipeline end to end, and stage handling."""

from __future__ import annotations

import json
import math
import shutil
import sqlite3
from pathlib import Path

import pytest

from flexparcel.calibration import Study, StudyConfigError, StudyStore, load_study
from flexparcel.cli import main

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "calibration_study.toml"

# The example's targets are the analytic model's noise-free responses at the paper's Table 6.
TRUTH = {
    "youngs_modulus": 926.0,
    "damping_ratio": 1.71e-3,
    "contact_stiffness": 649.0,
    "contact_damping": 0.579,
}

BASE = """
version = 1
name = "small"
store = "small.sqlite"
output = "report"

[execution]
workers = 0

[parameters.youngs_modulus]
bounds = [200, 2000]
unit = "MPa"
scale = "log"

[parameters.damping_ratio]
bounds = [1e-4, 5e-3]
unit = "s"

[experiments.swing]
simulator = "analytic"
setup = { mode = "swing" }
parameters = ["youngs_modulus", "damping_ratio"]

[experiments.swing.design]
runs = 6

[experiments.swing.targets]
first_swing_mm = { value = 97.2, unit = "mm" }
second_swing_mm = 35.0
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.toml"
    path.write_text(text)
    return path


# -- bad study files -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "old, new, message",
    [
        (
            'parameters = ["youngs_modulus", "damping_ratio"]',
            'parameters = ["youngs_modulus", "damping_rate"]',
            r"\[experiments\.swing\] parameters: unknown parameter 'damping_rate'",
        ),
        (
            "bounds = [200, 2000]",
            "bounds = [2000, 200]",
            r"\[parameters\.youngs_modulus\] bounds: lower bound 2000 must be below upper "
            r"bound 200",
        ),
        (
            '[experiments.swing.targets]\nfirst_swing_mm = { value = 97.2, unit = "mm" }\n'
            "second_swing_mm = 35.0",
            "",
            r"\[experiments\.swing\] targets: missing",
        ),
        (
            "version = 1",
            "version = 2",
            r"top level version: this flexparcel reads study format version 1, the file says 2",
        ),
        ("version = 1", "", r"top level version: missing"),
        ("runs = 6", "runz = 6", r"\[experiments\.swing\.design\] runz: unknown key"),
        ("runs = 6", "runs = 'six'", r"\[experiments\.swing\.design\] runs: must be an integer"),
        (
            "second_swing_mm = 35.0",
            "second_swing_mm = { weight = 1.0 }",
            r"\[experiments\.swing\.targets\.second_swing_mm\] value: missing",
        ),
        (
            'scale = "log"',
            'scale = "logarithmic"',
            r"\[parameters\.youngs_modulus\].*scale must be one of",
        ),
        (
            'simulator = "analytic"',
            "",
            r"\[experiments\.swing\] simulator: missing",
        ),
        ("bounds = [1e-4, 5e-3]", "bounds = [1e-4, 5e-3", r"malformed TOML"),
        (
            "second_swing_mm = 35.0",
            'second_swing_mm = { value = 35.0, label = "2nd swing" }',
            r"\[experiments\.swing\.targets\.second_swing_mm\] label: must be a name",
        ),
        (
            "second_swing_mm = 35.0",
            'second_swing_mm = { value = 35.0, label = "first_swing_mm" }',
            r"targets: two targets are named 'first_swing_mm' in the summary",
        ),
        (
            "second_swing_mm = 35.0",
            'second_swing_mm = { value = 35.0, reference = "27" }',
            r"\[experiments\.swing\.targets\.second_swing_mm\] reference: must be a number",
        ),
        (
            "second_swing_mm = 35.0",
            "second_swing_mm = { value = 35.0, weight = -1 }",
            r"\[experiments\.swing\.targets\.second_swing_mm\] weight: must be >= 0",
        ),
        (
            'first_swing_mm = { value = 97.2, unit = "mm" }\nsecond_swing_mm = 35.0',
            "first_swing_mm = { value = 97.2, weight = 0 }\nsecond_swing_mm = { value = 35.0, "
            "weight = 0 }",
            r"targets: every target has weight = 0",
        ),
    ],
)
def test_bad_study_files_name_the_field(tmp_path, old, new, message):
    assert old in BASE
    path = write(tmp_path, BASE.replace(old, new, 1))
    with pytest.raises(StudyConfigError, match=message) as info:
        load_study(path)
    assert str(path) in str(info.value)


def test_a_target_of_weight_zero_is_validated_but_not_fitted(tmp_path):
    # the analytic swing at 16 design runs: with the second swing's weight 0 the optimum
    # answers the first swing alone, whose surrogate it meets to the optimiser's tolerance;
    # the second swing is still predicted and re-run at the optimum
    text = BASE.replace("second_swing_mm = 35.0", "second_swing_mm = { value = 35.0, weight = 0 }")
    text = text.replace("runs = 6", "runs = 16")
    fast = '[surrogate]\nkernels = ["matern52"]\nrestarts = 0\n\n[execution]'
    text = text.replace("[execution]", fast)
    out = Study(load_study(write(tmp_path, text)), progress=False).run()
    first, second = out["optimise"]["targets"]
    assert second["weight"] == 0.0 and second["weight_source"] == "given"
    assert abs(first["predicted"] - 97.2) < 1e-3 * (first["design_range"][1] - 97.2)
    assert out["optimise"]["error"] == pytest.approx(
        (first["weight"] * (97.2 - first["predicted"])) ** 2, abs=1e-15
    )
    rows = {r["response"]: r for r in out["validate"]["rows"]}
    assert rows["second_swing_mm"]["simulated"] is not None


def test_unknown_simulator_and_unused_parameter(tmp_path):
    path = write(tmp_path, BASE + "\n[parameters.friction]\nbounds = [0.1, 0.6]\n")
    with pytest.raises(StudyConfigError, match=r"\[parameters\.friction\]: not used"):
        load_study(path)
    path = write(tmp_path, BASE.replace('simulator = "analytic"', 'simulator = "recurdyn"'))
    with Study(path, progress=False) as study, pytest.raises(ValueError, match="recurdyn"):
        study.design()


def test_cli_reports_bad_files_and_foreign_stores(tmp_path, capsys):
    path = write(tmp_path, BASE.replace("bounds = [200, 2000]", "bounds = [2000, 200]"))
    assert main(["calibrate", str(path)]) == 2
    assert "[parameters.youngs_modulus] bounds" in capsys.readouterr().err
    path = write(tmp_path, BASE)
    StudyStore(tmp_path / "small.sqlite").close()
    con = sqlite3.connect(tmp_path / "small.sqlite")
    con.execute("UPDATE meta SET value='0' WHERE key='schema_version'")
    con.commit()
    con.close()
    assert main(["calibrate", str(path), "--stage", "design"]) == 2
    assert "schema version 0" in capsys.readouterr().err


# -- stages ----------------------------------------------------------------------------------


def test_stages_alone_need_their_inputs(tmp_path, capsys):
    path = write(tmp_path, BASE)
    assert main(["calibrate", str(path), "--stage", "fit", "--no-progress"]) == 2
    assert "needs the results of stage 'design'" in capsys.readouterr().err
    text = BASE.replace(
        "[experiments.swing.design]",
        "[experiments.swing.screening]\nalpha = 0.05\n\n[experiments.swing.design]",
    )
    path = write(tmp_path, text)
    assert main(["calibrate", str(path), "--stage", "design", "--no-progress"]) == 2
    assert "needs the results of stage 'screen'" in capsys.readouterr().err


def test_design_is_extended_not_redrawn(tmp_path):
    path = write(tmp_path, BASE)
    with Study(path, progress=False) as st:
        st.design()
        first = st.store.design_keys("design", "swing")
        assert st.campaigns["design"].succeeded == 6
        st.design()  # again: nothing to do
        assert st.campaigns["design"].already_done == 6
        assert st.campaigns["design"].attempts == 0
    path = write(tmp_path, BASE.replace("runs = 6", "runs = 10"))
    with Study(path, progress=False) as st:
        st.design()
        keys = st.store.design_keys("design", "swing")
        assert keys[:6] == first and len(keys) == 10
        assert st.campaigns["design"].succeeded == 4  # only the new runs
    # Changing a bound invalidates the design: a clear error, and --reset redoes it.
    path = write(tmp_path, BASE.replace("bounds = [200, 2000]", "bounds = [300, 2000]"))
    with Study(path, progress=False) as st:
        with pytest.raises(StudyConfigError, match="--reset design"):
            st.design()
        st.reset("design")
        st.design()
        assert st.campaigns["design"].succeeded == 6


# -- the example study, end to end through the CLI --------------------------------------------


@pytest.fixture(scope="module")
def example_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("example")
    study = tmp / "calibration_study.toml"
    shutil.copy(EXAMPLE, study)
    args = ["calibrate", str(study), "--store", str(tmp / "s.sqlite"), "--out", str(tmp / "out")]
    assert main([*args, "--no-progress"]) == 0
    results = json.loads((tmp / "out" / "results.json").read_text())
    return tmp, args, results


def test_example_screening_passes_on_exactly_the_active_parameters(example_run):
    _, _, results = example_run
    scr = results["screening"]["drop"]
    assert scr["significant"] == ["youngs_modulus", "contact_stiffness", "contact_damping"]
    assert set(scr["frozen"]) == {"damping_ratio", "friction", "label_mass"}
    assert len(scr["coded"]) == 64
    assert results["design"]["drop"]["active"] == scr["significant"]


def test_example_surrogates_are_accurate_on_the_holdout(example_run):
    """Hold-out RMSE below 2 % of each response's range (see test_calibration_surrogates)."""
    _, _, results = example_run
    fit = results["fit"]
    n = 0
    for exp, res in fit.items():
        for r, g in res["responses"].items():
            lo, hi = res["range"][r]
            assert g["holdout_rmse"] < 0.02 * (hi - lo), (exp, r, g)
            assert set(g["cv_rmse"]) == {"matern12", "matern32", "matern52", "rbf"}
            n += 1
    assert n == 4


def test_example_calibration_recovers_the_truth(example_run):
    """Tolerance: 2 % of each parameter's range in unit coordinates (log scale for E).

    The surrogates' errors (~0.5 % of the response ranges, at the optimum GP std ~0.3 %) move the
    optimum by about that much relative to the range, since each response changes by O(range)
    across the box; 2 % is four times the observed error and far below the spread of the
    random starts (several end in a local minimum away from the truth).
    """
    tmp, _, results = example_run
    opt = results["optimise"]
    assert set(opt["calibrated"]) == set(TRUTH)
    assert opt["optimum"]["friction"] == 0.3 and opt["optimum"]["label_mass"] == 5.0
    study = load_study(EXAMPLE)
    for name, truth in TRUTH.items():
        p = study.parameters[name]
        err = abs(float(p.to_unit(opt["optimum"][name])) - float(p.to_unit(truth)))
        assert err < 0.02, (name, opt["optimum"][name], truth)
    for t in opt["targets"]:
        assert t["weight_source"] == "1/range"
        assert math.isfinite(t["std"]) and t["std"] > 0
    # Validation re-ran the simulators at the optimum; every target within its spread.
    rows = results["validation"]["rows"]
    assert len(rows) == 4 and all(r["status"] == "done" for r in rows)
    assert all(r["within_spread"] for r in rows), rows


def test_example_summary_holds_the_optimum_and_the_validation(example_run):
    tmp, _, results = example_run
    summary = json.loads((tmp / "out" / "summary.json").read_text())
    opt = results["optimise"]
    assert summary["optimum"] == {n: opt["optimum"][n] for n in opt["calibrated"]}
    assert summary["frozen"] == {"friction": 0.3, "label_mass": 5.0}
    assert summary["parameter_units"]["youngs_modulus"] == "MPa"
    val = summary["validation"]
    # each target once, by its response's name (no two experiments share one here)
    assert set(val) == {"first_swing_mm", "second_swing_mm", "rebound_mm", "peak_force_N"}
    for row in results["validation"]["rows"]:
        v = val[row["response"]]
        assert (v["simulated"], v["target"]) == (row["simulated"], row["target"])
        assert math.isclose(v["rel_error"], (v["simulated"] - v["target"]) / v["target"])
        assert "reference" not in v  # the example's targets give none
    counts = summary["run_counts"]
    with StudyStore(tmp / "s.sqlite") as store:
        assert counts["by_status"] == store.status_counts()
        runs = store.all_runs()
    done = counts["done_by_level_and_stage"]["single"]
    assert done["validation"] == 2 and done["screening"] == 64 and done["design"] == 30 + 40
    walls = [r["wall_s"] for r in runs if r["status"] == "done"]
    assert math.isclose(summary["wall_s"]["runs"], sum(walls))
    assert summary["wall_s"]["elapsed"] > 0


def test_summary_names_tell_equal_responses_apart():
    from flexparcel.calibration.summary import summary_names

    study = load_study(ROOT / "examples" / "kpbw_campaign.toml")
    names = summary_names(study.experiments.values())
    assert sorted(names.values()) == [
        "first_swing_mm", "rebound_horizontal_mm", "rebound_vertical_mm", "second_swing_mm"
    ]  # fmt: skip
    assert study.reference_name == "table7"
    refs = {names[(t.experiment, t.response)]: t.reference
            for e in study.experiments.values() for t in e.targets}  # fmt: skip
    # Table 7 of the paper: the RecurDyn model's responses at Table 6
    assert refs == {"first_swing_mm": 128.0, "second_swing_mm": 27.0,
                    "rebound_vertical_mm": 6.2, "rebound_horizontal_mm": 4.5}  # fmt: skip


def test_example_report_and_resumed_stages(example_run, capsys):
    tmp, args, _ = example_run
    html = (tmp / "out" / "report.html").read_text()
    for needle in ("ANOVA", "mean CV RMSE", "hold-out RMSE", "Calibration", "Validation"):
        assert needle in html
    assert html.count("data:image/png;base64,") == 10  # 2 screening, 4 residual, 4 contour
    assert len(list((tmp / "out" / "figures").glob("*.png"))) == 10
    capsys.readouterr()
    # Running the design stage again finds every run in the store: nothing is re-simulated.
    assert main([*args, "--stage", "screen,design", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "64 requested, 64 already done, 0 run now" in out
    assert "70 requested, 70 already done, 0 run now" in out
    with StudyStore(tmp / "s.sqlite") as store:
        assert store.status_counts() == {"pending": 0, "running": 0, "done": 136, "failed": 0}
