"""Every bad input a user can give, and the message it gets: none ends in a traceback.

``CASES`` is the table: the input (as docs/bad-input.md lists it), a regular expression the
message must match, and a function that makes the input in a temporary folder and returns
the message flexparcel gave (from a command's stderr with its exit status, an exception or
a warning). ``test_docs_list_every_case`` keeps docs/bad-input.md in step with it;
``python tests/test_bad_input_table.py`` prints the table as Markdown with the real messages.
"""

from __future__ import annotations

import os
import re
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import flexparcel as fp
from flexparcel.cli import main
from flexparcel.io import FileFormatError, load_result
from flexparcel.io.checkpoint import CheckpointError, load_checkpoint

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "bad-input.md"


@dataclass
class Case:
    input: str
    """The bad input, as the docs list it."""
    message: str
    """A regular expression the message must match."""
    make: Callable[[Path], str]
    """Makes the input in a temporary folder; returns the message."""
    exit_code: int | None = None
    """The command's exit status (None: not a command)."""


def _cli(argv: list[str], capsys) -> tuple[int, str]:
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "error" in line]
    return code, "\n".join(lines) or err


def _results_file(path: Path) -> Path:
    meta = '{"format": "flexparcel-results", "version": 1}'
    np.savez_compressed(path, time=np.arange(50.0), positions=np.ones((50, 20, 3)),
                        meta_json=np.array(meta))  # fmt: skip
    return path


def _truncated(path: Path) -> Path:
    data = _results_file(path).read_bytes()
    path.write_bytes(data[: len(data) // 2])
    return path


def _bit_flipped(path: Path) -> Path:
    data = bytearray(_results_file(path).read_bytes())
    data[60] ^= 0xFF  # inside the first member's compressed data (it starts at byte 38)
    path.write_bytes(bytes(data))
    return path


def _empty(path: Path) -> Path:
    path.write_bytes(b"")
    return path


def _foreign(path: Path) -> Path:
    np.savez(path, something=np.arange(3))
    return path


def _raises(fn, *args, **kwargs) -> str:
    try:
        fn(*args, **kwargs)
    except Exception as exc:  # the message is what the table checks
        return f"{type(exc).__name__}: {exc}"
    raise AssertionError("no error raised")


def _warns(fn, *args, **kwargs) -> str:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    assert caught, "no warning"
    return f"{caught[0].category.__name__}: {caught[0].message}"


_SHELL = dict(youngs_modulus=1e9, poisson_ratio=0.3, density=1000.0, thickness=1e-3)
_SOLID = dict(youngs_modulus=1e6, poisson_ratio=0.3, density=1000.0)


def _shell(**kw):
    return fp.ShellMaterial(**{**_SHELL, **kw})


def _solid(**kw):
    from flexparcel.elements.solid import SolidMaterial

    return SolidMaterial(**{**_SOLID, **kw})


def _contact(law):
    """A square sheet on a plane with ``law`` through the builder (where laws are checked)."""
    b, ids = _builder_with_square()
    b.add_contact(ids, b.add_plane((0, 0, 0), (0, 0, 1)), law)


def _load_snapshot(path):
    from flexparcel.consignments.snapshot import load_snapshot

    return load_snapshot(path)


def _builder_with_square():
    b = fp.ModelBuilder()
    ids = b.add_shell_mesh(*fp.mesh.rectangle(1.0, 1.0, 2, 2), material=_shell())
    return b, ids


def _cli_case(argv_of: Callable[[Path], list[str]], capsys_box: dict) -> Callable[[Path], str]:
    def make(tmp: Path) -> str:
        argv = argv_of(tmp)
        code, msg = _cli(argv, capsys_box["capsys"])
        capsys_box["code"] = code
        if argv_of is _missing_survey_folder:
            out = Path(argv[argv.index("--out") + 1])
            msg += f" (the folder out is {'kept' if out.exists() else 'removed'})"
        return msg

    return make


CAPSYS: dict = {}


def _snapshot_cli(kind: Callable[[Path], Path]) -> Callable[[Path], list[str]]:
    return lambda tmp: ["run", "swing", "--snapshot", str(kind(tmp / "snapshot.npz")),
                        "--out", str(tmp / "out")]  # fmt: skip


def _set(assignment: str) -> Callable[[Path], list[str]]:
    return lambda tmp: ["run", "swing", "--consignment", "BW", "--set", assignment,
                        "--out", str(tmp / "out")]  # fmt: skip


def _bad_toml(tmp: Path) -> list[str]:
    (tmp / "bag.toml").write_text("format_version = 1\nid = [unclosed\n")
    return ["assemble", str(tmp / "bag.toml"), "--out", str(tmp / "out")]


def _bad_scene(tmp: Path) -> list[str]:
    (tmp / "scene.toml").write_text("[belt\n")
    return ["run", "conveyor", "--scene", str(tmp / "scene.toml"), "--out", str(tmp / "out")]


def _out_is_file(tmp: Path) -> list[str]:
    (tmp / "taken.txt").write_text("not a folder")
    return ["assemble", "BW", "--out", str(tmp / "taken.txt")]


def _select_out_is_file(tmp: Path) -> list[str]:
    (tmp / "taken.txt").write_text("not a folder")
    return ["select", "--synthetic", "--out", str(tmp / "taken.txt")]


def _missing_survey(tmp: Path) -> list[str]:
    return ["select", str(tmp / "nowhere.csv"), "--out", str(tmp / "out")]


def _missing_survey_folder(tmp: Path) -> list[str]:
    return _missing_survey(tmp)  # its message also says what became of the folder


def _unreadable_scene(tmp: Path) -> list[str]:
    (tmp / "scene.toml").mkdir()
    return ["run", "conveyor", "--scene", str(tmp / "scene.toml"), "--out", str(tmp / "out")]


def _damaged_checkpoint(tmp: Path) -> str:
    return _raises(load_checkpoint, _truncated(tmp / "checkpoint.npz"))


C = CAPSYS
CASES: list[Case] = [
    # ---- files given to the command line
    Case("`flexparcel run swing --snapshot S.npz` with S.npz truncated",
         r"run: error: snapshot .*snapshot\.npz: not a readable \.npz file: truncated or damaged",
         _cli_case(_snapshot_cli(_truncated), C), 2),
    Case("`--snapshot S.npz` with S.npz empty (0 bytes)",
         r"error: snapshot .*snapshot\.npz: the file is empty",
         _cli_case(_snapshot_cli(_empty), C), 2),
    Case("`--snapshot S.npz` with one byte of S.npz flipped",
         r"error: snapshot .*snapshot\.npz: not a readable \.npz file: truncated or damaged",
         _cli_case(_snapshot_cli(_bit_flipped), C), 2),
    Case("`--snapshot S.npz` with S.npz an .npz of something else",
         r"error: snapshot .*snapshot\.npz: not a flexparcel snapshot \(no 'meta'",
         _cli_case(_snapshot_cli(_foreign), C), 2),
    Case("`--snapshot S.npz` with S.npz missing",
         r"error: snapshot not found: .*snapshot\.npz",
         _cli_case(lambda tmp: ["run", "swing", "--snapshot", str(tmp / "snapshot.npz"),
                                "--out", str(tmp / "out")], C), 2),  # fmt: skip
    Case("`flexparcel run swing --air-drag -1`",
         r"run: error: air_drag \(drag coefficient C_d\) must be in \[0, 5\] \(a flat plate: "
         r"1\.17\), got -1\.0",
         _cli_case(lambda tmp: ["run", "swing", "--consignment", "KPBW", "--air-drag", "-1",
                                "--out", str(tmp / "out")], C), 2),  # fmt: skip
    Case("`flexparcel run conveyor --membrane tension-field` (the tests' option)",
         r"run: error: --membrane applies to the swing and the drops, not the conveyor",
         _cli_case(lambda tmp: ["run", "conveyor", "--membrane", "tension-field",
                                "--out", str(tmp / "out")], C), 2),  # fmt: skip
    Case("`flexparcel run swing --hold` (the hold is the vertical drop's)",
         r"run: error: --hold applies to drop-vertical only, not swing",
         _cli_case(lambda tmp: ["run", "swing", "--consignment", "KPBW", "--hold",
                                "--out", str(tmp / "out")], C), 2),  # fmt: skip
    Case("a consignment file that is not valid TOML",
         r"assemble: error: .*bag\.toml: not valid TOML", _cli_case(_bad_toml, C), 2),
    Case("`--scene FILE.toml` that is not valid TOML",
         r"run: error: .*scene\.toml: .*(TOML|toml)", _cli_case(_bad_scene, C), 2),
    Case("`--scene FILE.toml` that is a folder",
         r"run: error: .*scene\.toml", _cli_case(_unreadable_scene, C), 2),
    Case("`flexparcel select FILE.csv` with FILE.csv missing",
         r"select: error: .*nowhere\.csv", _cli_case(_missing_survey, C), 2),
    Case("`--out FILE` naming an existing file (assemble, run, demo)",
         r"assemble: error: --out .*taken\.txt: is an existing file, not a folder",
         _cli_case(_out_is_file, C), 2),
    Case("`flexparcel select --out FILE` naming an existing file",
         r"select: error: --out .*taken\.txt: is an existing file, not a folder",
         _cli_case(_select_out_is_file, C), 2),
    Case("a failed run whose `--out` folder it created and left empty",
         r"select: error: survey file not found: .*nowhere\.csv \(the folder out is removed\)",
         _cli_case(_missing_survey_folder, C), 2),
    # ---- parameters on the command line
    Case("`--set damping_ratio=1e9`",
         r"error: --set damping_ratio=1e9: damping_ratio must be in \[0, 1\] s \(the bound "
         r"of damping_ratio_s in a consignment file\), got 1e\+09",
         _cli_case(_set("damping_ratio=1e9"), C), 2),
    Case("`--set youngs_modulus=9.26e8` (Pa where MPa is asked)",
         r"error: --set youngs_modulus=9.26e8: youngs_modulus must be in \(0, 100000\] MPa",
         _cli_case(_set("youngs_modulus=9.26e8"), C), 2),
    Case("`--set friction_packaging_content=5` (a packaging friction coefficient)",
         r"run: error: friction_packaging_content must be in \[0, 2\] -, got 5",
         _cli_case(_set("friction_packaging_content=5"), C), 2),
    Case("`--set damping_ratio=-1`",
         r"error: --set damping_ratio=-1: damping_ratio must be in \[0, 1\] s",
         _cli_case(_set("damping_ratio=-1"), C), 2),
    # ---- flexparcel.io.load_result and the checkpoint loader
    Case("`load_result` on a truncated .npz",
         r"FileFormatError: results file .*r\.npz: not a readable \.npz file: truncated or damaged",
         lambda tmp: _raises(load_result, _truncated(tmp / "r.npz"))),
    Case("`load_result` on a bit-flipped .npz",
         r"FileFormatError: results file .*r\.npz: not a readable \.npz file: truncated or "
         r"damaged",
         lambda tmp: _raises(load_result, _bit_flipped(tmp / "r.npz"))),
    Case("`load_result` on an empty file",
         r"FileFormatError: results file .*r\.npz: the file is empty",
         lambda tmp: _raises(load_result, _empty(tmp / "r.npz"))),
    Case("`load_result` on an .npz of something else",
         r"FileFormatError: results file .*r\.npz: not a flexparcel results file \(no "
         r"'meta_json' entry",
         lambda tmp: _raises(load_result, _foreign(tmp / "r.npz"))),
    Case("`load_result` on a text file",
         r"FileFormatError: results file .*r\.npz: not a readable \.npz file \(not a flexparcel "
         r"results file: a file of another kind",
         lambda tmp: _raises(load_result, (tmp / "r.npz").write_text("hello") and tmp / "r.npz")),
    Case("`load_result` on a missing file",
         r"FileNotFoundError: results file not found: .*r\.npz",
         lambda tmp: _raises(load_result, tmp / "r.npz")),
    Case("a truncated checkpoint (`load_checkpoint`, a resumed conveyor run)",
         r"CheckpointError: checkpoint .*checkpoint\.npz: not a readable \.npz file: truncated",
         _damaged_checkpoint),
    Case("an empty checkpoint (`load_checkpoint`)",
         r"CheckpointError: checkpoint .*checkpoint\.npz: the file is empty",
         lambda tmp: _raises(load_checkpoint, _empty(tmp / "checkpoint.npz"))),
    Case("an .npz of something else as a checkpoint (`load_checkpoint`)",
         r"CheckpointError: checkpoint .*checkpoint\.npz: not a flexparcel checkpoint \(no "
         r"'header' entry; it holds something\)",
         lambda tmp: _raises(load_checkpoint, _foreign(tmp / "checkpoint.npz"))),
    Case("`load_snapshot` on a truncated .npz (the Python API)",
         r"SnapshotError: snapshot .*s\.npz: not a readable \.npz file: truncated or damaged",
         lambda tmp: _raises(_load_snapshot, _truncated(tmp / "s.npz"))),
    Case("`load_snapshot` on an .npz of something else",
         r"SnapshotError: snapshot .*s\.npz: not a flexparcel snapshot \(no 'meta'",
         lambda tmp: _raises(_load_snapshot, _foreign(tmp / "s.npz"))),
    Case("`flexparcel view DIR` with no results in DIR",
         r"view: error: .*empty: not a results folder \(no results\.npz",
         _cli_case(lambda tmp: (tmp / "empty").mkdir() or ["view", str(tmp / "empty")], C), 2),
    # ---- the SI Python API: values plausible only in the paper's units
    Case("`ShellMaterial(youngs_modulus=926)` (MPa typed into the SI API)",
         r"UnitWarning: ShellMaterial\.youngs_modulus = 926 Pa is implausibly low for SI units"
         r".*did you mean 926 MPa = 9\.26e8 Pa\?",
         lambda tmp: _warns(_shell, youngs_modulus=926)),
    Case("`SolidMaterial(youngs_modulus=5)` (MPa typed into the SI API)",
         r"UnitWarning: SolidMaterial\.youngs_modulus = 5 Pa .*did you mean 5 MPa = 5e6 Pa\?",
         lambda tmp: _warns(_solid, youngs_modulus=5)),
    Case("`ContactLaw(stiffness=649)` given to the builder (N/mm typed into the per-area SI "
         "law)",
         r"UnitWarning: add_contact: ContactLaw\.stiffness = 649 N/m\^3 \(per unit area\) is "
         r"implausibly low .*did you mean 649 N/mm per 10 mm node.*"
         r"from_paper_units\(c_N_per_mm=649\) = 6\.49e9 N/m\^3",
         lambda tmp: _warns(_contact, fp.ContactLaw(stiffness=649.0))),
    Case("`ContactLaw(mu_static=0.3, mu_dynamic=0.5)` given to the builder",
         r"PlausibilityWarning: add_contact: ContactLaw\.mu_dynamic = 0\.5 > mu_static = 0\.3: "
         r"friction then grows with the slip speed",
         lambda tmp: _warns(_contact, fp.ContactLaw(stiffness=1e8, mu_static=0.3,
                                                    mu_dynamic=0.5))),
    Case("`ContactLaw(stiffness=1e8, mu_dynamic=0.3)` (mu_static left at 0)",
         r"PlausibilityWarning: .*mu_dynamic = 0\.3 > mu_static = 0 \(mu_static was left at "
         r"its default 0\?\)",
         lambda tmp: _warns(_contact, fp.ContactLaw(stiffness=1e8, mu_dynamic=0.3))),
    # ---- the existing checks of tests/test_bad_input.py
    Case("`ShellMaterial(youngs_modulus=-1)`", r"youngs_modulus must be > 0 Pa",
         lambda tmp: _raises(_shell, youngs_modulus=-1.0)),
    Case("`ShellMaterial(youngs_modulus=nan)`", r"youngs_modulus must be finite",
         lambda tmp: _raises(_shell, youngs_modulus=float("nan"))),
    Case("`ShellMaterial(poisson_ratio=0.5)`", r"poisson_ratio must be in \[0, 0.5\)",
         lambda tmp: _raises(_shell, poisson_ratio=0.5)),
    Case("`ShellMaterial(membrane=\"wrinkly\")`",
         r"ShellMaterial\.membrane must be one of elastic\|tension-field, got 'wrinkly'",
         lambda tmp: _raises(_shell, membrane="wrinkly")),
    Case("`ShellMaterial(density=0)`", r"density must be > 0 kg/m\^3",
         lambda tmp: _raises(_shell, density=0.0)),
    Case("`ShellMaterial(density=\"heavy\")`", r"density must be a number",
         lambda tmp: _raises(_shell, density="heavy")),
    Case("`ShellMaterial(thickness=-1e-3)`", r"thickness must be > 0 m",
         lambda tmp: _raises(_shell, thickness=-1e-3)),
    Case("`ShellMaterial(damping_ratio=-1e-3)`", r"damping_ratio .* must be >= 0 s",
         lambda tmp: _raises(_shell, damping_ratio=-1e-3)),
    Case("a quad with a node out of range", r"outside \[0, 8\]",
         lambda tmp: _raises(_bad_quad_ids)),
    Case("a node that belongs to no element", r"node 9 belongs to no element",
         lambda tmp: _raises(_orphan_node)),
    Case("`fp.simulate(model, -1.0)`", r"t_end must be > 0 s",
         lambda tmp: _raises(_negative_t_end)),
    Case("`IntegratorOptions(rho_inf=1.5)`", r"rho_inf must be in \[0, 1\]",
         lambda tmp: _raises(fp.IntegratorOptions, rho_inf=1.5)),
    Case("`JawClosing(hold_time=0)` (the swing clamp's closing)",
         r"JawClosing.hold_time must be in \(0, 1\] s, got 0",
         lambda tmp: _raises(_jaws, hold_time=0)),
    Case("`IntegratorOptions(error_estimate='rms')`",
         r"error_estimate must be 'full', 'smooth' or 'balanced', got 'rms'",
         lambda tmp: _raises(fp.IntegratorOptions, error_estimate="rms")),
    Case("`ModelBuilder(gravity=(0, 0, nan))`", r"gravity must be 3 finite numbers",
         lambda tmp: _raises(fp.ModelBuilder, gravity=(0, 0, np.nan))),
    Case("`mesh.rectangle(0, 1, 2, 2)`", r"length must be > 0 m",
         lambda tmp: _raises(fp.mesh.rectangle, 0.0, 1.0, 2, 2)),
]  # fmt: skip


def _jaws(**kw):
    from flexparcel.scenarios.swing_jaws import JawClosing

    return JawClosing(**kw)


def _bad_quad_ids():
    pts, q = fp.mesh.rectangle(1.0, 1.0, 2, 2)
    q[0, 0] = 99
    fp.ModelBuilder().add_shell_mesh(pts, q, material=_shell())


def _orphan_node():
    pts, q = fp.mesh.rectangle(1.0, 1.0, 2, 2)
    b = fp.ModelBuilder()
    b.add_shell_mesh(np.vstack([pts, [[5.0, 5.0, 0.0]]]), q, material=_shell())
    b.finalize()


def _negative_t_end():
    b, ids = _builder_with_square()
    b.clamp(ids[:3])
    fp.simulate(b.finalize(), -1.0)


@pytest.mark.parametrize("case", CASES, ids=lambda c: re.sub(r"\W+", "-", c.input)[:60])
def test_bad_input_gets_its_message(case, tmp_path, capsys):
    CAPSYS.clear()
    CAPSYS["capsys"] = capsys
    message = case.make(tmp_path)
    assert "Traceback" not in message
    assert re.search(case.message, message), f"{case.input}: got {message!r}"
    if case.exit_code is not None:
        assert CAPSYS["code"] == case.exit_code, message


def test_failed_run_removes_the_empty_folder_it_created(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["select", str(tmp_path / "nowhere.csv"), "--out", str(out)]) == 2
    assert not out.exists()  # select made it before reading the survey
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "mine.txt").write_text("a user's file")
    os.utime(kept / "mine.txt", (1e9, 1e9))  # written long before this run
    assert main(["select", str(tmp_path / "nowhere.csv"), "--out", str(kept)]) == 2
    assert (kept / "mine.txt").is_file() and not (kept / "FAILED.txt").exists()


def test_failed_run_that_wrote_files_is_marked(tmp_path):
    from flexparcel.cli.outdir import FAILED_FILE, OutputFolder, report_failure

    out = tmp_path / "run"
    folder = OutputFolder(out, "run", ["run", "conveyor", "--out", str(out)])
    out.mkdir()
    (out / "checkpoint.npz").write_bytes(b"partial")
    report_failure("flexparcel run: conveyor failed: step size below the minimum")
    done = folder.failed(1)
    text = (out / FAILED_FILE).read_text()
    assert "partial results kept" in done
    assert "flexparcel run conveyor --out" in text and "exit status 1" in text
    assert "step size below the minimum" in text
    assert (out / "checkpoint.npz").is_file()
    OutputFolder(out, "run").succeeded()  # a later successful run removes the mark
    assert not (out / FAILED_FILE).exists()


def test_all_file_errors_are_one_type():
    from flexparcel.consignments.snapshot import SnapshotError

    assert issubclass(SnapshotError, FileFormatError)
    assert issubclass(CheckpointError, FileFormatError)
    assert issubclass(FileFormatError, ValueError)


def test_describe_error_names_the_file():
    import json
    import tomllib

    from flexparcel.cli import describe_error

    e = PermissionError(13, "Permission denied", "/data/results.npz")
    assert describe_error(e) == "/data/results.npz: Permission denied"
    with pytest.raises(json.JSONDecodeError) as j:
        json.loads("{")
    assert describe_error(j.value).startswith("not valid JSON")
    with pytest.raises(tomllib.TOMLDecodeError) as t:
        tomllib.loads("[x")
    assert describe_error(t.value).startswith("not valid TOML")
    assert describe_error(KeyError("info")) == "missing key 'info'"


def test_docs_list_every_case():
    text = DOC.read_text(encoding="utf-8")
    missing = [c.input for c in CASES if c.input.replace("|", "\\|") not in text]
    assert not missing, f"docs/bad-input.md lacks: {missing}"


def markdown_table(tmp: Path) -> str:
    """The table with the messages flexparcel gives now (temporary paths shortened)."""
    import contextlib
    import io

    class _Capsys:
        def __init__(self):
            self.err = io.StringIO()

        def readouterr(self):
            out = type("R", (), {"err": self.err.getvalue(), "out": ""})()
            self.err.seek(0)
            self.err.truncate()
            return out

    rows = ["| input | message |", "|---|---|"]
    for k, case in enumerate(CASES):
        folder = tmp / f"c{k}"
        folder.mkdir()
        cap = _Capsys()
        CAPSYS.clear()
        CAPSYS["capsys"] = cap
        with contextlib.redirect_stderr(cap.err), contextlib.redirect_stdout(io.StringIO()):
            msg = case.make(folder)
        msg = msg.replace(str(folder) + "/", "").replace(str(folder), ".").strip()
        msg = " / ".join(line for line in msg.splitlines() if line.strip())
        cell = case.input.replace("|", "\\|")
        rows.append(f"| {cell} | `{msg.replace('`', '')}` |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":  # pragma: no cover
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        sys.stdout.write(markdown_table(Path(d)))
