"""The shipped KP/BW campaign (parsed and planned, never run), the dry run with measured costs,
budgets, a multi-fidelity study end to end, and bad input named by field."""

from __future__ import annotations

import io
import json
import shutil
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from flexparcel.calibration import Study, StudyConfigError, load_study
from flexparcel.calibration.study import scale_budget
from flexparcel.cli import main

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "examples" / "kpbw_campaign.toml"
MULTIFIDELITY = ROOT / "examples" / "calibration_multifidelity.toml"
TABLES = ROOT / "tests" / "data" / "reference" / "calibration-kpbw.toml"


def test_campaign_is_the_papers():
    import tomllib

    ref = tomllib.loads(TABLES.read_text())
    c = load_study(CAMPAIGN)
    swing, vert, hor = (c.experiments[e] for e in ("swing", "drop_vertical", "drop_horizontal"))
    assert (swing.simulator, vert.simulator, hor.simulator) == (
        "swing",
        "drop-vertical",
        "drop-horizontal",
    )
    # run counts: 100; 64 + 500; 64 + 100
    assert (swing.design_runs, vert.design_runs, hor.design_runs) == (100, 500, 100)
    assert swing.screening is None
    for e in (vert, hor):
        assert e.screening.design == "full-factorial" and e.screening.alpha == 0.05
        assert len(e.parameters) == 6
    # Table 4 (swing) and Table 5 (drops) ranges
    space = c.experiment_space("swing")
    for name, (lo, hi) in ref["ranges"]["swing"].items():
        assert (space[name].lower, space[name].upper) == (lo, hi), name
    for e in ("drop_vertical", "drop_horizontal"):
        space = c.experiment_space(e)
        for name, (lo, hi) in ref["ranges"]["drop"].items():
            assert (space[name].lower, space[name].upper) == (lo, hi), (e, name)
    # targets: the real-world measurements, weights 1/range (none given)
    targets = {t.key: t for e in c.experiments.values() for t in e.targets}
    assert {k: t.value for k, t in targets.items()} == {
        "swing.first_swing_mm": 127,
        "swing.second_swing_mm": 32,
        "drop_vertical.rebound_mm": 7,
        "drop_horizontal.rebound_mm": 4,
    }
    assert ref["experiments"]["swing"]["targets_mm"] == [127, 32]
    assert all(t.weight is None for t in targets.values())
    assert targets["swing.second_swing_mm"].transform == "log"
    assert (c.cv_folds, c.holdout_fraction, c.validate) == (5, 0.1, True)
    # the optimiser searches where the swing's and the drops' E ranges overlap
    with Study(c, progress=False) as st:
        box = st.optimisation_space(["youngs_modulus"])["youngs_modulus"]
        assert (box.lower, box.upper) == (500.0, 2000.0)


def test_campaign_dry_run_prints_the_plan(tmp_path, capsys):
    # the store is put in tmp_path, so the plan does not read a store a real campaign left
    args = ["calibrate", str(CAMPAIGN), "--dry-run", "--store", str(tmp_path / "s.sqlite")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "design    swing            -       100" in out
    assert "screen    drop_vertical    -        64" in out
    assert "design    drop_vertical    -       500" in out
    assert "design    drop_horizontal  -       100" in out
    assert "total: 831 runs" in out
    assert "unknown \u2014 run one" in out  # the vertical drop: no estimate stated
    # the swing and the horizontal drop at 10 mm: their measured wall times, stated
    assert "design    swing            -       100     0   80.5 min" in out  # 4,833 s
    assert not (tmp_path / "s.sqlite").exists()  # a dry run creates nothing
    assert main([*args, "--budget", "0.1"]) == 0
    out = capsys.readouterr().out
    # 10 % of each hypercube, at least 2 x 5 + 1 runs; the 2^6 screens stay whole
    assert "design    swing            -        11" in out
    assert "design    drop_vertical    -        50" in out
    assert "screen    drop_vertical    -        64" in out
    assert main([*args, "--runs", "drop_vertical=200"]) == 0
    assert "design    drop_vertical    -       200" in capsys.readouterr().out


def test_dry_run_cost_comes_from_measured_runs(tmp_path, capsys):
    study = tmp_path / "mf.toml"
    shutil.copy(MULTIFIDELITY, study)
    text = study.read_text().replace('"../out/calibration-multifidelity', f'"{tmp_path}/o')
    study.write_text(text)
    assert main(["calibrate", str(study), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "screen    drop             low      16" in out
    assert "design    swing            high      8" in out
    assert "total: 114 runs" in out  # 16 + 2 x (40 + 8) + 2 validation runs
    assert "left: 114 runs" in out  # nothing run yet
    with Study(study, progress=False) as st:
        st.screen()
    assert main(["calibrate", str(study), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "measured (16 runs in the store)" in out  # the drop at the low level
    assert "design    swing            low      40     0          ?" in out  # not yet measured
    # the screen is done: a resume runs the other 98 (2 x (40 + 8) + 2 validation runs)
    assert "screen    drop             low      16    16" in out
    assert "left: 98 runs" in out


def test_stated_cost_by_fidelity_level(tmp_path, capsys):
    # a 10 mm run costs ten times a 25 mm one: the plan takes each level's own figure
    study = tmp_path / "mf.toml"
    text = MULTIFIDELITY.read_text().replace('"../out/calibration-multifidelity', f'"{tmp_path}/o')
    study.write_text(
        text.replace(
            "design = { runs = 40, high_runs = 8 }",
            "design = { runs = 40, high_runs = 8 }\nestimated_run_s = { low = 30, high = 600 }",
            1,
        )
    )
    assert main(["calibrate", str(study), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "design    swing            low      40     0       30 s   20.0 min" in out  # 40 x 30 s
    assert "design    swing            high      8     0   10.0 min   80.0 min" in out  # 8 x 600 s
    assert "validate  swing            high      1     0   10.0 min   10.0 min" in out
    bad = study.read_text().replace("{ low = 30, high = 600 }", "{ low = 30, medium = 600 }")
    study.write_text(bad)
    with pytest.raises(StudyConfigError, match=r"\[experiments\.swing\.estimated_run_s\] "
                       r"medium: unknown key \(allowed here: high, low\)"):  # fmt: skip
        load_study(study)
    study.write_text(bad.replace("medium = 600", "high = -1"))
    with pytest.raises(StudyConfigError, match=r"estimated_run_s\] high: must be > 0"):
        load_study(study)


def test_estimated_cost_by_level_needs_fidelity_levels(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(
        BASE.replace("parameters = [", "estimated_run_s = { low = 3 }\nparameters = [", 1)
    )
    message = r"\[experiments\.\w+\] estimated_run_s: a table by fidelity level needs \[fidelity"
    with pytest.raises(StudyConfigError, match=message):
        load_study(path)


def test_the_running_campaign_is_what_its_comments_say():
    # docs/campaigns/kpbw/study.toml, the campaign whose store is committed next to it: the
    # tension-field membrane in all three tests, 0.5 s drops, 2^(6-1) screens of resolution
    # VI, 25 mm low / 10 mm high, the real-world targets of the shipped example
    c = load_study(ROOT / "docs" / "campaigns" / "kpbw" / "study.toml")
    paper = load_study(CAMPAIGN)
    assert c.fidelity == {"low": {"element_size_mm": 25}, "high": {"element_size_mm": 10}}
    for name, e in c.experiments.items():
        assert e.setup["membrane"] == "tension-field" and e.setup["consignment"] == "KPBW"
        assert e.parameters == paper.experiments[name].parameters
        assert {t.key: t.value for t in e.targets} == {
            t.key: t.value for t in paper.experiments[name].targets
        }
        assert e.high_runs == 4
    for name in ("drop_vertical", "drop_horizontal"):
        e = c.experiments[name]
        assert e.setup["t_end_s"] == 0.5
        assert e.screening.design == "fractional-factorial"
        assert e.screening.generators == ("F = ABCDE",)
    assert (c.experiments["swing"].design_runs, c.experiments["drop_vertical"].design_runs,
            c.experiments["drop_horizontal"].design_runs) == (40, 60, 40)  # fmt: skip


@pytest.fixture(scope="module")
def multifidelity_run(tmp_path_factory):
    from threadpoolctl import threadpool_limits

    tmp = tmp_path_factory.mktemp("mf")
    study = tmp / "mf.toml"
    shutil.copy(MULTIFIDELITY, study)
    args = ["calibrate", str(study), "--store", str(tmp / "s.sqlite"), "--out", str(tmp / "o")]
    out = io.StringIO()
    with threadpool_limits(1), redirect_stdout(out):
        assert main([*args, "--no-progress"]) == 0
    return json.loads((tmp / "o" / "results.json").read_text()), tmp, out.getvalue()


def _relative_rmse(results: dict, key: str) -> float:
    """The fit's RMSE ``key`` summed over every experiment's responses, each over its range."""
    total = 0.0
    for res in results["fit"].values():
        for r, g in res["responses"].items():
            total += g[key] / (res["range"][r][1] - res["range"][r][0])
    return total


def test_multifidelity_study_recovers_the_truth(multifidelity_run):
    """Tolerance 3 % of each range in unit coordinates: the example's single-fidelity
    counterpart reaches 2 % with 30-40 runs at the true level; here 8 true-level runs per
    experiment correct 40 biased ones (at 25 mm the responses are 7.5 % low, times an
    E-dependent factor of +-7.5 %, so a calibration on the low level alone lands far off)."""
    results, _, _ = multifidelity_run
    truth = {
        "youngs_modulus": 926.0,
        "damping_ratio": 1.71e-3,
        "contact_stiffness": 649.0,
        "contact_damping": 0.579,
    }
    c = load_study(MULTIFIDELITY)
    opt = results["optimise"]
    for name, value in truth.items():
        p = c.parameters[name]
        err = abs(float(p.to_unit(opt["optimum"][name])) - float(p.to_unit(value)))
        assert err < 0.03, (name, opt["optimum"][name], value)
    # Fused against high-only on the held-out high run of each response. One run per response
    # (10 % of 8) is a noisy figure (here the first swing, smooth enough for 7 high runs in
    # 2-D, goes to high-only), so the claim is on the sum over the four responses relative to
    # their ranges; the clean comparison with a margin is the Forrester test
    # (test_calibration_multifidelity). Measured: 0.041 against 0.104.
    fused, high = (
        _relative_rmse(results, "holdout_rmse"),
        _relative_rmse(results, "high_only_holdout_rmse"),
    )
    assert fused < 0.7 * high, (fused, high)
    # Leaving each of the 8 high runs out once compares the two on all of them, per response
    # (measured: 0.099 against 0.382 relative to the ranges)
    fused_loo = _relative_rmse(results, "loo_rmse")
    high_loo = _relative_rmse(results, "high_only_loo_rmse")
    assert fused_loo < 0.7 * high_loo, (fused_loo, high_loo)
    rows = results["validation"]["rows"]
    assert all(r["status"] == "done" and r["within_spread"] for r in rows), rows
    # validation ran at the high level
    assert results["design"]["swing"]["runs"] == 40


def test_multifidelity_report_shows_both_rmses(multifidelity_run):
    _, tmp, printed = multifidelity_run
    # the fit stage prints both comparisons of every fused response
    assert printed.count("high-only GP on the same high runs") == 4
    assert printed.count("leave-one-out over 8 high runs: fused") == 4
    html = (tmp / "o" / "report.html").read_text()
    assert "co-kriging" in html and "high-only" in html
    assert "Leaving each of the 8 high runs out once" in html
    assert "log" in html  # the second swing's transform is stated
    # summary.json counts the finished runs per fidelity level: 16 screening and 2 x 40
    # design runs low, 2 x 8 design runs and the 2 validation runs high
    counts = json.loads((tmp / "o" / "summary.json").read_text())["run_counts"]
    done = counts["done_by_level_and_stage"]
    assert done["low"] == {"screening": 16, "design": 80}
    assert done["high"] == {"design-high": 16, "validation": 2}
    # and the fused-against-high-only figures of every fitted response
    mf = json.loads((tmp / "o" / "summary.json").read_text())["multifidelity"]
    results = json.loads((tmp / "o" / "results.json").read_text())
    for e, res in results["fit"].items():
        for r, g in res["responses"].items():
            row = mf[e][r]
            assert row["n_high"] == 8 and row["n_holdout"] == 1
            assert row["loo_rmse"] == pytest.approx(g["loo_rmse"])
            assert row["high_only_holdout_rmse"] == pytest.approx(g["high_only_holdout_rmse"])


BASE = (ROOT / "tests" / "test_calibration_study.py").read_text().split('BASE = """')[1]
BASE = BASE.split('"""')[0]


@pytest.mark.parametrize(
    "old, new, message",
    [
        (
            'simulator = "analytic"',
            'simulator = "recurdyn"',
            r"\[experiments\.swing\] simulator: unknown simulator 'recurdyn'",
        ),
        (
            'unit = "MPa"',
            'unit = "GPa"',
            r"\[parameters\.youngs_modulus\] unit: 'GPa', but simulator 'analytic' "
            r"\(experiment 'swing'\) takes youngs_modulus in 'MPa'",
        ),
        (
            "[parameters.damping_ratio]",
            "[parameters.damping]",
            r"\[experiments\.swing\] parameters: 'damping' is not a parameter of simulator "
            r"'analytic'",
        ),
        (
            "[execution]",
            "[fidelity.low]\nsetup = { noise = 0.01 }\n[fidelity.high]\nsetup = { noise = 0.0 }"
            "\n\n[execution]",
            r"\[fidelity\.low\] setup: element_size_mm missing; simulator 'analytic'",
        ),
    ],
)
def test_bad_input_is_named_at_run_time(tmp_path, old, new, message, capsys):
    text = BASE.replace(old, new).replace('"damping_ratio"]', '"damping"]')
    if "[fidelity" in new:
        text = BASE.replace(old, new).replace("runs = 6", "runs = 12\nhigh_runs = 3")
    elif "damping]" not in new:
        text = BASE.replace(old, new)
    path = tmp_path / "study.toml"
    path.write_text(text)
    with Study(path, progress=False) as st, pytest.raises(StudyConfigError, match=message):
        st.check()
    assert main(["calibrate", str(path), "--dry-run"]) == 2
    assert str(path) in capsys.readouterr().err


@pytest.mark.parametrize(
    "fidelity, message",
    [
        ("[fidelity.low]\n[fidelity.high]\nsetup = { element_size_mm = 10 }",
         r"\[fidelity\.low\] setup: missing"),
        ("[fidelity.low]\nsetup = { element_size_mm = 25 }",
         r"\[fidelity\] high: missing"),
        ("[fidelity.low]\nsetup = {}\n[fidelity.high]\nsetup = { element_size_mm = 10 }",
         r"\[fidelity\.low\] setup: missing"),
    ],
)  # fmt: skip
def test_fidelity_level_without_setup_is_refused(tmp_path, fidelity, message):
    text = BASE.replace("[execution]", fidelity + "\n\n[execution]").replace(
        "runs = 6", "runs = 12\nhigh_runs = 3"
    )
    path = tmp_path / "study.toml"
    path.write_text(text)
    with pytest.raises(StudyConfigError, match=message):
        load_study(path)


def test_budget_is_checked():
    c = load_study(CAMPAIGN)
    with pytest.raises(ValueError, match="positive factor"):
        scale_budget(c, 0.0)
    with pytest.raises(ValueError, match="no experiment 'drop'"):
        scale_budget(c, None, {"drop": 10})


def test_simulator_metadata_matches_the_scenarios():
    """The literal units in scenarios.simulators (read without FE imports) are the scenarios'."""
    from flexparcel.scenarios import simulators
    from flexparcel.scenarios.registry import get_scenario

    for name, func in (
        ("swing", simulators.swing),
        ("drop-vertical", simulators.drop_vertical),
        ("drop-horizontal", simulators.drop_horizontal),
        ("conveyor", simulators.conveyor),
    ):
        declared = {p.name: p.unit for p in get_scenario(name).parameters}
        assert func.simulator_parameters == declared, name
