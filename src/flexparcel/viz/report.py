"""HTML reports of results folders: ``report.html``, the page a user opens after a run.

* swing and drop tests (and a third-party scenario on one consignment): the responses
  next to the paper's Table 7 and the real-world tests, the response curve with its
  reference lines, the frames, the 3-D viewer, the wall time next to RecurDyn's and the
  parameters;
* the conveyor: the jam verdict, the exit table (exit, deflector contact, peak deflector
  force, jam and crossing per consignment), trajectories, speed, yaw and deflector force
  against time, top-view snapshots, the animation, the viewer and the wall time next to
  RecurDyn's 24 h;
* the demo (:func:`write_demo_report`): the assembly and the three tests on one page.

Everything is read back from the folder (``responses.json``, the pictures, ``view.html``),
so :func:`write_report` (re)writes a report at any time after a run. Pictures are embedded
(:mod:`flexparcel.viz.html`); the viewer is embedded as an iframe of the folder's own
``view.html``. A quantity the run did not measure reads "not reached in this run" with the
reason, never 0.
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from flexparcel.viz.html import NOT_REACHED, esc, number, page, picture, table, viewer_frame

__all__ = [
    "REPORT_FILE",
    "ReportError",
    "read_summary",
    "write_report",
    "report_writer",
    "write_demo_report",
    "responses_table",
    "wall_time_table",
]

REPORT_FILE = "report.html"


class ReportError(ValueError):
    """A folder without readable results to report on; the message names the file."""


def read_summary(folder: str | Path) -> dict:
    """``folder/responses.json`` as a dict; :class:`ReportError` naming the file if it is
    missing or not a results summary."""
    path = Path(folder) / "responses.json"
    if not path.is_file():
        raise ReportError(f"{path}: not found (flexparcel run writes it)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ReportError(f"{path}: not readable as JSON ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("responses"), dict):
        raise ReportError(f"{path}: not a flexparcel responses file (no 'responses')")
    return data


def _version() -> str:
    from flexparcel import __version__

    return __version__


def _stamp() -> str:
    return f"flexparcel {_version()}, report written {time.strftime('%Y-%m-%d %H:%M')}"


# --------------------------------------------------------------------------- swing and drops
def _response(summary: dict | str | None, key: str) -> tuple[float | None, str]:
    """(value, why not) of response ``key`` in a test's ``responses.json``; a failed test
    (a message) or a missing response give None and why."""
    if summary is None:
        return None, "not run"
    if isinstance(summary, str):
        return None, f"the test failed: {summary}"
    r = summary.get("responses", {}).get(key)
    if r is None:
        return None, "not in this run's responses"
    return r.get("value"), r.get("note", "")


def responses_table(tests: Mapping[str, dict | str], consignment: str) -> str:
    """The responses of ``tests`` (scenario name -> its ``responses.json`` content, or the
    message of its failure) next to the paper's Table 7 and the real-world tests."""
    from flexparcel.scenarios.paper_reference import REFERENCE_CONSIGNMENT, TEST_REFERENCES

    own = consignment == REFERENCE_CONSIGNMENT
    rows = []
    for ref in TEST_REFERENCES:
        if ref.test not in tests:
            continue
        value, why = _response(tests[ref.test], ref.response)
        ratio = value / ref.table7 if own and value is not None else None
        rows.append([esc(ref.label), number(value, 1, why=why), f"{ref.table7:g}",
                     number(ratio, 2) if own and value is not None else "–",
                     f"{ref.real:g}"])  # fmt: skip
    caption = "Ratio = flexparcel / paper Table 7."
    if not own:
        caption = (f"Table 7 and the real-world tests are KP/BW's; this run is "
                   f"{esc(consignment)}: shown for orientation, no ratio.")  # fmt: skip
    header = ["response", "flexparcel [mm]", "paper Table 7, RecurDyn [mm]", "ratio",
              "real-world test [mm]"]  # fmt: skip
    return table(header, rows, caption=caption, numeric=(1, 2, 3, 4))


def wall_time_table(tests: Mapping[str, dict | str]) -> str:
    """Wall times of ``tests`` next to RecurDyn's (paper Table 7, 4 cores), scaled
    linearly to each run's simulated time."""
    from flexparcel.scenarios.paper_reference import recurdyn_wall_s

    rows = []
    for test, s in tests.items():
        if isinstance(s, str):
            rows.append([esc(test), "–", '<span class="missing">failed</span>', "–", "–"])
            continue
        sim, wall = float(s["simulated_s"]), float(s["wall_s"])
        rd = recurdyn_wall_s(test, sim)
        rows.append([esc(test), f"{sim:g}", f"{wall:.1f}",
                     "–" if rd is None else f"{rd:.0f}",
                     "–" if rd is None or rd <= 0 else f"{wall / rd:.2f}"])  # fmt: skip
    header = ["test", "simulated [s]", "flexparcel wall [s]",
              "RecurDyn wall [s] (4 cores, scaled)", "ratio"]  # fmt: skip
    caption = ("Ratio = flexparcel / RecurDyn (below 1: faster). RecurDyn: Intel i9-13900H, "
               "4 cores (paper Table 7: swing 384 s for 1.4 s, vertical drop 125 s and "
               "horizontal drop 76 s for 0.3 s), scaled linearly to the simulated time; "
               "flexparcel: this machine, the time integration alone.")  # fmt: skip
    return table(header, rows, caption=caption, numeric=(1, 2, 3, 4))


def _parameters_table(s: dict) -> str:
    units = s.get("parameter_units", {})
    rows = [[esc(k), "–" if v is None else esc(f"{v:g}"), esc(units.get(k, ""))]
            for k, v in s.get("parameters", {}).items()]  # fmt: skip
    return table(["parameter", "value", "unit"], rows, numeric=(1,))


def _all_responses_table(s: dict) -> str:
    rows = []
    for name, r in s["responses"].items():
        value = r.get("value")
        shown = number(value, 2, why=r.get("note", "")) if value is None else f"{value:.2f}"
        rows.append([esc(name), shown, esc(r.get("unit", "")), esc(r.get("description", ""))])
    return table(["response", "value", "unit", "meaning"], rows, numeric=(1,))


def _test_facts(s: dict) -> str:
    facts = [f"consignment {esc(s.get('consignment', '?'))}"]
    if "element_size_mm" in s:
        facts.append(f"{s['element_size_mm']:g} mm shells")
    if "drop_height_mm" in s:
        facts.append(f"dropped from {s['drop_height_mm']:g} mm")
    facts.append(f"{s['simulated_s']:g} s simulated in {s['wall_s']:.1f} s wall "
                 f"({s.get('steps', '?')} steps, {s.get('newton_iterations', '?')} Newton "
                 "iterations)")  # fmt: skip
    return ", ".join(facts)


def _short_run_note(test: str, s: dict) -> str:
    """A note when the run is shorter than the paper's test (its responses may lie beyond)."""
    from flexparcel.scenarios.paper_reference import PAPER_SIMULATED_S

    paper = PAPER_SIMULATED_S.get(test)
    if paper is None or isinstance(s, str) or s["simulated_s"] >= paper - 1e-9:
        return ""
    return (f'<p class="note">This run simulated {s["simulated_s"]:g} s, the paper '
            f"{paper:g} s: responses after its end are {NOT_REACHED}.</p>")  # fmt: skip


def test_section(folder: Path, s: dict, link: str = "") -> str:
    """The pictures of one test folder: the response curve, the frames and the viewer
    (``link``: the folder relative to the page, with a trailing slash)."""
    return "".join([
        "<h3>Response curve</h3>",
        "<p>With the paper's Table 7 (purple, dashed) and the real-world test (black, dotted) "
        "where the consignment is KP/BW.</p>",
        picture(folder / "response.png", "response curve"),
        "<h3>Frames</h3>", picture(folder / "frames.png", "frames"),
        "<h3>3-D viewer</h3>", viewer_frame(folder, f"{link}view.html"),
    ])  # fmt: skip


def _test_body(folder: Path, s: dict) -> tuple[str, str]:
    """(title, body) of a single test's report."""
    test = str(s.get("test") or s.get("scenario") or folder.name)
    title = f"{test.replace('-', ' ').capitalize()} test, {s.get('consignment', '?')}"
    body = [f"<p>{_test_facts(s)}.</p>", _short_run_note(test, s), "<h2>Responses</h2>"]
    if test in ("swing", "drop-vertical", "drop-horizontal"):
        body.append(responses_table({test: s}, str(s.get("consignment", ""))))
    else:  # another scenario: its own responses, nothing to compare with
        body.append(_all_responses_table(s))
    body += [test_section(folder, s),
             "<h2>Wall time next to RecurDyn</h2>", wall_time_table({test: s}),
             "<h2>Parameters</h2>", _parameters_table(s), _files(folder)]  # fmt: skip
    return title, "".join(body)


def _files(folder: Path) -> str:
    names = ("responses.json", "results.npz", "contact_forces.npz", "view.html",
             "paraview/packaging.pvd", "paraview/conveyor.pvd", "checkpoint.npz")  # fmt: skip
    have = [n for n in names if (folder / n).is_file()]
    items = "".join(f'<li><a href="{esc(n)}">{esc(n)}</a></li>' for n in have)
    return (f"<h2>Files</h2><ul>{items}</ul><p>ParaView: open the <code>.pvd</code> files "
            "in <code>paraview/</code> together and press Play.</p>")  # fmt: skip


# --------------------------------------------------------------------------- conveyor
def _contact_cell(duration: float | None, first: float | None) -> str:
    """One deflector's contact: "never" (not 0.000, which reads as contact at t = 0) or
    the duration and the first contact time [s]."""
    if duration is None or first is None:
        return '<span class="missing">never</span>'
    return f"{duration:.3f} (from {first:.3f})"


def _exit_row(name: str, c: dict, crossing: float | None) -> list[str]:
    notes = c.get("notes", {})
    exit_t = c.get("exit_time_s")
    pos = c.get("exit_position_m")
    traj = c["trajectory"]
    force = c.get("peak_contact_force_N")
    force_cell = (number(None, why=notes.get("peak_contact_force_N", "")) if force is None
                  else f"{force:.2f} at {c['peak_contact_force_time_s']:.3f} s")  # fmt: skip
    contact = "; ".join(_contact_cell(d, f) for d, f in
                        zip(c["deflector_contact_duration_s"],
                            c["deflector_first_contact_s"], strict=True))  # fmt: skip
    return [esc(name), number(exit_t, 3, why=notes.get("exit_time_s", "")),
            "–" if pos is None else f"{1e3 * pos[1]:.0f}",
            f"{traj['x_m'][-1]:.3f}, {traj['y_m'][-1]:.3f}", contact, force_cell,
            esc(c.get("jam_verdict", "")),
            "none" if crossing is None else f"<b>at {crossing:.3f} s</b>"]  # fmt: skip


def _exit_table(s: dict) -> str:
    crossings = s.get("deflector_crossings", {})
    rows = [_exit_row(name, c, crossings.get(name)) for name, c in s["consignments"].items()]
    header = ["consignment", "exit time [s]", "exit y [mm]", "final x, y [m]",
              "deflector contact [s] (from t [s]), per deflector",
              "peak deflector force [N] (mean over a frame interval)", "jam",
              "behind a deflector"]  # fmt: skip
    caption = ("Exit: the centroid passes the belt end. Deflector contact: time any node "
               "spends within 2 mm of each deflector's face, and when it first did. Behind "
               "a deflector: a packaging node went through it (the contact failed).")  # fmt: skip
    return table(header, rows, caption=caption, numeric=(1, 2))


def _verdict(s: dict) -> str:
    """The scene's jam verdict and crossing check in a sentence or two."""
    cons = s["consignments"]
    jams = {n: c["jam_start_s"] for n, c in cons.items() if c.get("jam_start_s") is not None}
    unjudged = [n for n, c in cons.items()
                if str(c.get("jam_verdict", "")).startswith(NOT_REACHED)]  # fmt: skip
    if jams:
        text = "Jam: " + ", ".join(f"{esc(n)} from t = {t:.3f} s" for n, t in jams.items())
    elif len(unjudged) == len(cons):
        text = f"Jam verdict: {esc(cons[unjudged[0]]['jam_verdict'])}."
    else:
        text = "No jam: every consignment kept moving (or left the belt) within the run."
    crossed = [n for n, t in s.get("deflector_crossings", {}).items() if t is not None]
    text += (f" <b>Packaging went behind a deflector: {esc(', '.join(crossed))}</b> (contact "
             "failed; distrust those trajectories)." if crossed else
             " No packaging went behind a deflector.")  # fmt: skip
    return f'<p class="{"fail" if jams or crossed else "note"}">{text}</p>'


def _motion_picture(folder: Path, s: dict) -> str:
    """``motion.png`` (speed, yaw, deflector force against time), drawn from
    ``responses.json`` when the folder has none yet."""
    path = folder / "motion.png"
    if not path.is_file():
        from flexparcel.viz.conveyor import plot_conveyor_motion

        speed = s.get("parameters", {}).get("belt_speed_m_s", 0.0)
        plot_conveyor_motion(path, s["consignments"], float(speed or 0.0))
    return picture(path, "speed, yaw and deflector force against time")


def _conveyor_facts(s: dict) -> str:
    p = s.get("parameters", {})
    return (f"{len(s['consignments'])} consignments, belt {p.get('belt_speed_m_s', '?')} m/s, "
            f"deflectors at {p.get('deflector_angle_deg', '?')} deg; {s['simulated_s']:g} s "
            f"simulated in {s['wall_s']:.1f} s wall ({s.get('steps', '?')} steps, "
            f"{s.get('dof_count', '?')} DOF, {p.get('workers', '?')} workers)")  # fmt: skip


def _conveyor_body(folder: Path, s: dict) -> tuple[str, str]:
    params = {k: v for k, v in s.get("parameters", {}).items() if not isinstance(v, dict)}
    rows = [[esc(k), esc("–" if v is None else v)] for k, v in params.items()]
    body = [
        f"<p>{_conveyor_facts(s)}.</p>", "<h2>Verdict</h2>", _verdict(s),
        "<h2>Exits, contacts and jams</h2>", _exit_table(s),
        "<h2>Trajectories</h2>", picture(folder / "trajectories.png", "trajectories"),
        "<h2>Speed, yaw and deflector force against time</h2>", _motion_picture(folder, s),
        "<h2>Top views</h2>", picture(folder / "snapshots.png", "snapshots"),
        "<h2>Animation</h2>", picture(folder / "animation.gif", "animation"),
        "<h2>3-D viewer</h2>", viewer_frame(folder, "view.html"),
        "<h2>Wall time next to RecurDyn</h2>", wall_time_table({"conveyor": s}),
        "<p>RecurDyn's bulk run (the paper's four consignments, 10 mm mesh) took 24 h for "
        "2 s on 4 cores; scaled linearly. Like for like only for that scene.</p>",
        "<h2>Settings</h2>", table(["setting", "value"], rows), _files(folder),
    ]  # fmt: skip
    return "Conveyor", "".join(body)


# --------------------------------------------------------------------------- writers
def write_report(folder: str | Path, out: str | Path | None = None) -> Path:
    """Write the report of the results folder ``folder`` (a swing, drop or conveyor run, or
    another scenario's ``responses.json``) to ``out`` (default ``folder/report.html``)
    atomically; returns its path. :class:`ReportError` for a folder without results."""
    from flexparcel.viz.html import write_page

    folder = Path(folder)
    s = read_summary(folder)
    if s.get("scenario") == "conveyor" and isinstance(s.get("consignments"), dict):
        title, body = _conveyor_body(folder, s)
    else:
        title, body = _test_body(folder, s)
    text = page(f"flexparcel: {title}", body, subtitle=esc(_stamp()))
    return write_page(Path(out) if out is not None else folder / REPORT_FILE, text)


def report_writer(result: Any, out: Path) -> dict[str, Path]:
    """A picture writer (:data:`~flexparcel.scenarios.base.PictureWriter`) that writes
    ``out/report.html`` after the other pictures and the viewer; a warning instead where it
    cannot (a run's files never fail on the report)."""
    try:
        return {"report": write_report(out)}
    except (ReportError, OSError, KeyError, TypeError, ValueError) as exc:
        warnings.warn(f"{Path(out) / REPORT_FILE} not written: {exc!r}", stacklevel=2)
        return {}


def write_demo_report(out: str | Path, *, facts: str, assembly: dict | None,
                      tests: Mapping[str, str], failures: Mapping[str, str] | None = None,
                      quick_note: str = "", explanation: str = "") -> Path:  # fmt: skip
    """The demo's ``out/report.html``: ``facts`` (a sentence, HTML), the ``assembly`` info
    (``assembly.json``'s, or None), ``tests``: name -> its folder relative to ``out`` (a
    finished test), ``failures``: name -> the message of a test that failed; ``quick_note``
    and ``explanation`` (HTML paragraphs) are shown as given. Returns the page's path."""
    from flexparcel.viz.html import write_page

    out = Path(out)
    summaries: dict[str, dict | str] = {t: read_summary(out / d) for t, d in tests.items()}
    summaries.update(failures or {})
    body = [f"<p>{facts}</p>", quick_note, _assembly_section(out, assembly),
            "<h2>Responses next to the paper's Table 7</h2>",
            responses_table(summaries, "KPBW"),
            "<h2>Wall times next to RecurDyn's</h2>", wall_time_table(summaries),
            explanation]  # fmt: skip
    for test, s in summaries.items():
        body.append(f"<h2>{esc(test)}</h2>")
        if isinstance(s, str):
            body.append(f'<p class="fail">Failed: {esc(s)}</p>')
            continue
        where = tests[test]
        body += [f'<p>{_test_facts(s)}. <a href="{esc(where)}/{REPORT_FILE}">Its own '
                 "report</a>.</p>", test_section(out / where, s, f"{where}/")]  # fmt: skip
    text = page("flexparcel demo: the paper's KP/BW consignment", "".join(body),
                subtitle=esc(_stamp()))  # fmt: skip
    return write_page(out / REPORT_FILE, text)


def _assembly_section(out: Path, info: dict | None) -> str:
    if info is None:
        return ""
    text = (f"Opened after {info['opening_time_s']:.3f} s, at rest at {info['end_time_s']:.3f} s "
            f"(kinetic energy {info['kinetic_energy_J']:.2g} J), {info['steps']} steps, "
            f"{info['wall_s']:.1f} s wall. Packaging {1e3 * info['packaging_mass_kg']:.1f} g, "
            f"content {1e3 * info['content_mass_kg']:.1f} g.")  # fmt: skip
    return (f"<h2>Assembly</h2><p>{text}</p>"
            + picture(out / "assembly" / "assembled.png", "assembled consignment"))  # fmt: skip
