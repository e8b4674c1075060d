"""The HTML reports (flexparcel.viz.report): one self-contained ``report.html`` per results
folder and one for the demo, with the responses next to the paper's Table 7 and the
real-world tests, the pictures embedded, the 3-D viewer, the wall times next to RecurDyn's,
and "not reached in this run" (never 0) for what a run did not measure.

A real drop run (the small example consignment, not assembled, 4 ms: seconds) checks the
writer chain of a run; the swing, conveyor and demo reports are written from hand-made
``responses.json`` files with known numbers, so that every cell can be checked.
"""

from __future__ import annotations

import base64
import json
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from raw_snapshots import SMALL, raw_snapshot

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def drop_report(tmp_path_factory):
    from flexparcel.consignments.userfile import load_consignment_file
    from flexparcel.scenarios.registry import get_scenario
    from flexparcel.viz.scenario_pictures import pictures_for

    scenario = get_scenario("drop-horizontal")
    result = scenario.run(raw_snapshot(load_consignment_file(SMALL)), t_end=0.004)
    out = tmp_path_factory.mktemp("report") / "drop"
    files = scenario.write(result, out, pictures=pictures_for("drop-horizontal"))
    return out, files


def _embedded(text: str, mime: str = "image/png") -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(rf'src="data:{mime};base64,([^"]+)"', text)]


def test_a_run_writes_its_report_after_pictures_and_viewer(drop_report):
    out, files = drop_report
    assert files["report"] == out / "report.html"
    assert json.loads((out / "responses.json").read_text())["files"]["report"] == str(
        out / "report.html"
    )
    text = (out / "report.html").read_text()
    # self-contained: no script, nothing fetched; the pictures are the run's own PNGs
    assert "<script" not in text and "http://" not in text and "https://" not in text
    pictures = _embedded(text)
    assert (out / "response.png").read_bytes() in pictures
    assert (out / "frames.png").read_bytes() in pictures
    assert '<iframe src="view.html"' in text and (out / "view.html").is_file()
    assert not list(out.glob(".report.html.*"))  # written atomically


def test_drop_report_says_not_reached_never_zero(drop_report):
    # 4 ms of a 200 mm drop: the consignment never reaches the plate, so no rebound
    out, _ = drop_report
    summary = json.loads((out / "responses.json").read_text())
    assert summary["rebound_mm"] is None  # the flat key too: null, not 0.0
    text = (out / "report.html").read_text()
    row = re.search(r"<tr><td>horizontal drop rebound</td>(.*?)</tr>", text).group(1)
    assert "not reached in this run (the consignment did not touch the plate" in row
    assert ">4.5<" in row and ">4<" in row  # Table 7 and the real-world test
    assert "no ratio" in text  # the small example is not KP/BW
    assert "This run simulated 0.004 s, the paper 0.3 s" in text
    assert "<td>drop-horizontal</td>" in text  # the wall-time row next to RecurDyn's


def _swing_folder(folder: Path, first: float | None, second: float | None) -> Path:
    """A swing results folder of KP/BW with the given responses [mm] (None: not reached)."""
    folder.mkdir(parents=True)

    def resp(value, why):
        return {"value": value, "unit": "mm", "description": "swing",
                **({} if value is not None else {"note": why})}  # fmt: skip

    summary = {
        "test": "swing", "consignment": "KPBW", "first_swing_mm": first,
        "second_swing_mm": second, "simulated_s": 1.4, "wall_s": 96.0, "steps": 300,
        "newton_iterations": 900, "element_size_mm": 25.0,
        "parameters": {"youngs_modulus": 926.0}, "parameter_units": {"youngs_modulus": "MPa"},
        "responses": {"first_swing_mm": resp(first, "did not swing past"),
                      "second_swing_mm": resp(second, "did not swing back past")},
    }  # fmt: skip
    (folder / "responses.json").write_text(json.dumps(summary))
    return folder


def test_swing_report_compares_with_table7_and_recurdyn(tmp_path):
    from flexparcel.viz.report import write_report

    folder = _swing_folder(tmp_path / "swing", 64.0, None)
    text = write_report(folder).read_text()
    first = re.search(r"<tr><td>first swing</td>(.*?)</tr>", text).group(1)
    # ours, Table 7 (RecurDyn), ours / Table 7 = 64 / 128, the real-world test
    cells = re.findall(r'<td class="num">(.*?)</td>', first)
    assert cells == ["64.0", "128", "0.50", "127"]
    second = re.search(r"<tr><td>second swing</td>(.*?)</tr>", text).group(1)
    assert "not reached in this run (did not swing back past)" in second
    assert re.findall(r'<td class="num">(.*?)</td>', second)[1:] == ["27", "–", "32"]
    # wall time: 96 s against RecurDyn's 384 s for the same 1.4 s
    wall = re.search(r"<tr><td>swing</td>(.*?)</tr>", text).group(1)
    assert re.findall(r'<td class="num">(.*?)</td>', wall) == ["1.4", "96.0", "384", "0.25"]
    # pictures the folder lacks are said to be missing; no viewer, no iframe
    assert "response.png: not written by this run" in text
    assert "<iframe" not in text and "view.html: not written" in text


def _conveyor_folder(folder: Path) -> Path:
    """A conveyor results folder: ``a`` runs off the belt end (x = 3 m at 0.3125 s), ``b``
    stops dead at 0.2 s beside the first deflector's face."""
    from flexparcel.scenarios.conveyor import ConveyorScene
    from flexparcel.scenarios.conveyor_responses import conveyor_responses

    t = np.round(np.arange(0.0, 0.6 + 1e-9, 0.01), 10)
    scene = ConveyorScene()
    g = scene.deflectors()[0]
    pos = np.zeros((len(t), 8, 3))
    corners = np.array([[-0.05, -0.03, 0], [0.05, -0.03, 0], [0.05, 0.03, 0], [-0.05, 0.03, 0]])
    pos[:, :4] = corners + np.column_stack([2.5 + 1.6 * t, 0 * t, 0.01 + 0 * t])[:, None]
    near = g.root + 0.1 * g.tangent + 0.001 * g.normal + [0.0, 0.0, 0.02]
    pos[:, 4:] = near + 0.01 * corners[None] + np.minimum(1.6 * t, 0.32)[:, None, None] * 0.0
    force = np.where(t >= 0.2, 2.5, 0.0)
    r = conveyor_responses(SimpleNamespace(time=t, positions=pos),
                           {"a": np.arange(4), "b": np.arange(4, 8)}, scene,
                           contact_forces={"b": force})  # fmt: skip
    folder.mkdir(parents=True)
    summary = {"scenario": "conveyor", "consignments": {k: v.to_dict() for k, v in r.items()},
               "simulated_s": 0.6, "wall_s": 30.0, "steps": 100, "dof_count": 48,
               "parameters": {"belt_speed_m_s": 1.6, "deflector_angle_deg": 45.0,
                              "workers": 0},
               "deflector_crossings": {"a": None, "b": 0.45}, "responses": {}}  # fmt: skip
    (folder / "responses.json").write_text(json.dumps(summary))
    return folder


def test_conveyor_report_verdict_exit_table_and_motion(tmp_path):
    from flexparcel.viz.report import write_report

    folder = _conveyor_folder(tmp_path / "conveyor")
    text = write_report(folder).read_text()
    # b never moves: jammed from the first frame; it went behind a deflector at 0.45 s
    assert "Jam: b from t = 0.000 s" in text
    assert "Packaging went behind a deflector: b" in text
    a = re.search(r"<tr><td>a</td>(.*?)</tr>", text).group(1)
    assert '<td class="num">0.312</td>' in a  # exit at 3 m / ... = 0.3125 s
    assert "no jam: left the belt at t = 0.312 s" in a
    # a never touches a deflector: "never", not 0.000 (which reads as contact at t = 0)
    assert a.count("never") == 2 and "0.000 (from" not in a
    assert "not reached in this run (no contact force recorded)" in a
    b = re.search(r"<tr><td>b</td>(.*?)</tr>", text).group(1)
    assert "2.50 at 0.200 s" in b and "(from 0.000)" in b
    # speed, yaw and force against time: drawn from responses.json for this folder
    assert (folder / "motion.png").read_bytes() in _embedded(text)
    assert "24 h for 2 s" in text and "<td>conveyor</td>" in text


def test_report_of_a_folder_without_results_names_the_file(tmp_path):
    from flexparcel.viz.report import ReportError, report_writer, write_report

    with pytest.raises(ReportError, match=r"responses\.json: not found"):
        write_report(tmp_path)
    (tmp_path / "responses.json").write_text("{")
    with pytest.raises(ReportError, match=r"responses\.json: not readable as JSON"):
        write_report(tmp_path)
    with pytest.warns(UserWarning, match="report.html not written"):
        assert report_writer(None, tmp_path) == {}  # a run's files never fail on it


def test_curves_draw_their_reference_lines(monkeypatch, tmp_path):
    from flexparcel.viz import consignment
    from flexparcel.viz.scenario_pictures import paper_lines

    figures = []
    monkeypatch.setattr(consignment, "_save", lambda fig, path, dpi=None: figures.append(fig))
    from flexparcel.scenarios.drop import DropCurve

    t = np.linspace(0.0, 0.3, 31)
    z = 0.1 - 0.5 * t
    gap = np.abs(z - 0.05)  # touches at 0.1 s, lifts off the plate again after it
    curve = DropCurve(gap=gap, gap_peak=20, z_centre=z, touch=(0.1, 0.05), deepest=10,
                      centre_peak=None)  # fmt: skip
    refs = [(label, mm * 1e-3, kind) for label, _, mm, kind in paper_lines("drop-vertical",
                                                                              "KPBW")]  # fmt: skip
    consignment.plot_drop_curve(tmp_path / "d.png", t, curve, rebound=0.005,
                                references=refs)  # fmt: skip
    top, bottom = figures[-1].axes
    lines = {ln.get_label(): ln.get_ydata()[0] for ln in top.get_lines()}
    # the rebound is a clearance above the plate [mm]: the plate at 0, Table 7's 6.2 mm, the
    # real 7 mm and ours above it
    assert lines["plate (rebound measured from here)"] == pytest.approx(0.0)
    assert lines["paper Table 7 (RecurDyn)"] == pytest.approx(6.2)
    assert lines["real-world test"] == pytest.approx(7.0)
    assert lines["rebound peak"] == pytest.approx(5.0)
    # the centre of mass's rise, the second response, is measured from the touch height
    below = {ln.get_label(): ln.get_ydata()[0] for ln in bottom.get_lines()}
    assert below["height at first contact (rise measured from here)"] == pytest.approx(50.0)
    consignment.plot_drop_curve(tmp_path / "d.png", t, curve, rebound=None)
    ax = figures[-1].axes[0]
    assert "rebound peak" not in [ln.get_label() for ln in ax.get_lines()]
    assert not [a for a in ax.texts if "rebound" in a.get_text()]  # no "rebound 0.0 mm"
    assert paper_lines("swing", "small") == []  # Table 7 is KP/BW's
    swing = [(label, (-mm if key == "first_swing_mm" else mm) * 1e-3, kind)
             for label, key, mm, kind in paper_lines("swing", "KPBW")]  # fmt: skip
    consignment.plot_swing_curve(tmp_path / "s.png", t, 0.1 - t, first=None, second=None,
                                 references=swing)  # fmt: skip
    ys = sorted(ln.get_ydata()[0] for ln in figures[-1].axes[0].get_lines()[2:])
    assert ys == pytest.approx([-128.0, -127.0, 27.0, 32.0])


def test_demo_writes_the_html_report_and_ends_with_its_path(tmp_path, monkeypatch, capsys):
    # the demo's runs replaced by finished folders with known numbers (the runs themselves
    # take minutes): the report pages and the last line printed are what is checked
    from flexparcel.cli import demo_cmd, main, snapshots
    from flexparcel.consignments.snapshot import load_snapshot

    def no_assembly(build, out, **kwargs):
        raise AssertionError("demo --quick assembled instead of taking the shipped snapshot")

    monkeypatch.setattr(snapshots, "assemble_job", no_assembly)

    def run_tests(snap, out, mode, progress):
        swing = _swing_folder(out / "swing", 64.0, None)
        (swing / "view.html").write_text("<html></html>")
        return {"swing": json.loads((swing / "responses.json").read_text()),
                "drop-vertical": "no convergence at t = 0.1 s"}  # fmt: skip

    monkeypatch.setattr(demo_cmd, "_run_tests", run_tests)
    out = tmp_path / "demo"
    assert main(["demo", "--quick", "--out", str(out), "--no-progress"]) == 1  # a test failed
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == f"report: {(out / 'report.html').resolve()}"
    text = (out / "report.html").read_text()
    assert "Quick mode" in text and "Failed: no convergence at t = 0.1 s" in text
    assert '<iframe src="swing/view.html"' in text and 'href="swing/report.html"' in text
    first = re.search(r"<tr><td>first swing</td>(.*?)</tr>", text).group(1)
    assert re.findall(r'<td class="num">(.*?)</td>', first) == ["64.0", "128", "0.50", "127"]
    # --quick is KP/BW at 25 mm, whose shipped snapshot is taken (data/paper-snapshots-25mm):
    # the demo says so, and the report shows that assembly's picture and its step count
    shipped = Path(__file__).resolve().parents[1] / "data" / "paper-snapshots-25mm" / "KPBW.npz"
    assert f"demo: KPBW: using the shipped snapshot {shipped}" in "\n".join(lines)
    assert (out / "assembly" / "assembled.png").is_file()
    assert "assembled.png: not written by this run" not in text
    steps = load_snapshot(shipped).info["steps"]
    assert f"{steps} steps" in text
    md = (out / "report.md").read_text()
    assert "| second swing [mm] | not reached in this run | 27 | – | 32 |" in md
    assert "| vertical drop rebound [mm] | – | 6.2 | – | 7 |" in md


def test_view_command_writes_the_report_again(drop_report, tmp_path, capsys):
    from flexparcel.cli import main

    src, _ = drop_report
    folder = tmp_path / "drop"
    shutil.copytree(src, folder)
    (folder / "report.html").unlink()
    assert main(["view", str(folder)]) == 0
    assert f"report: {folder / 'report.html'}" in capsys.readouterr().out
    assert '<iframe src="view.html"' in (folder / "report.html").read_text()


def test_drop_curve_touches_where_the_response_does():
    # standing on its edge, the consignment first touches with the edge's line contact
    # (radius 2 r with KP/BW's glued strip), not the nodes' r: the curve's touch height, the
    # line the rebound is measured from, must be the response's (drop_touch_radius)
    from flexparcel.scenarios.drop import drop_curve

    r = 1e-3
    t = np.linspace(0.0, 0.1, 101)
    z = 0.01 - 0.1 * t  # the lowest node, falling at 0.1 m/s through z = 2r and then r
    pos = np.zeros((len(t), 2, 3))
    pos[:, 0, 2], pos[:, 1, 2] = z, z + 0.02
    c = SimpleNamespace(node_ids=np.array([0, 1]), packaging=np.array([0, 1]), contact_radius=r,
                        build=SimpleNamespace(has_glued_strip=True))  # fmt: skip
    model = SimpleNamespace(mass=np.ones((2, 6)))
    for test, radius in (("drop-vertical", 2 * r), ("drop-horizontal", r)):
        res = SimpleNamespace(time=t, positions=pos)
        run = SimpleNamespace(test=test, result=res, consignment=c, model=model)
        touch = drop_curve(run).touch
        assert touch[0] == pytest.approx((0.01 - radius) / 0.1, abs=1e-12), test
