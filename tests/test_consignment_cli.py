"""User consignment TOML files, ``flexparcel assemble`` / ``flexparcel run`` smoke tests on the
small example consignment, the response-curve marks and the demo report."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from flexparcel.cli import main
from flexparcel.consignments.userfile import load_consignment_file, resolve_consignment
from flexparcel.selection.export import ConsignmentFileError

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "consignment_small.toml"

SMALL = """format_version = 1
id = "small"
packaging_material = "bubble_wrap"
length_mm = 120
width_mm = 90
height_mm = 10
content_kind = "rigid"
content_length_mm = 60
content_width_mm = 45
content_height_mm = 10
mass_g = 40
"""


def _write(tmp_path: Path, text: str, name: str = "c.toml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _replace(text: str, key: str, line: str) -> str:
    """``text`` with the line of ``key`` replaced by ``line``."""
    return "\n".join(line if ln.startswith(f"{key} =") else ln for ln in text.splitlines()) + "\n"


# --------------------------------------------------------------------------------------------
# TOML files


def test_example_file_in_si_units():
    b = load_consignment_file(EXAMPLE)
    s = b.spec
    assert (s.id, s.packaging_material, s.content_kind) == ("small", "bubble_wrap", "rigid")
    assert (s.length_mm, s.width_mm, s.content_height_mm, s.mass_g) == (120, 90, 10, 40)
    assert b.element_size == pytest.approx(0.020)
    m = b.material
    assert m.youngs_modulus == pytest.approx(60e6)  # 60 MPa
    assert m.thickness == pytest.approx(0.5e-3)  # 0.5 mm
    assert m.areal_density == pytest.approx(0.080)  # 80 g/m^2
    assert m.damping_ratio == pytest.approx(1.71e-3)


def test_material_overrides_only_what_is_given(tmp_path):
    path = _write(tmp_path, SMALL + "[material]\nyoungs_modulus_mpa = 150\nthickness_mm = 0.25\n")
    b = load_consignment_file(path)
    assert b.material.youngs_modulus == pytest.approx(150e6)
    assert b.material.thickness == pytest.approx(0.25e-3)
    preset = load_consignment_file(_write(tmp_path, SMALL, "plain.toml")).material
    assert b.material.poisson_ratio == preset.poisson_ratio
    assert b.material.areal_density == preset.areal_density
    assert b.element_size == pytest.approx(0.010)  # no element_size_mm: the 10 mm default
    assert "c.toml" in b.material.source
    assert b.material.membrane == "elastic"
    law = _write(tmp_path, SMALL + "[material]\nmembrane = 'tension-field'\n", "law.toml")
    assert load_consignment_file(law).material.membrane == "tension-field"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t + "colour = 'red'\n", r"unknown key\(s\) colour"),
        (lambda t: t + "[material]\nstiffness = 3\n", r"unknown key\(s\) material\.stiffness"),
        (
            lambda t: t + "[material]\nmembrane = 'wrinkly'\n",
            r"material\.membrane = 'wrinkly' is invalid \(allowed: elastic \| tension-field\)",
        ),
        (
            lambda t: t + "[material]\nthickness_mm = -0.1\n",
            r"material\.thickness_mm = -0\.1 is invalid \(allowed: 0 < thickness_mm <= 20 mm\)",
        ),
        (
            lambda t: t + "[material]\npoisson_ratio = 0.5\n",
            r"material\.poisson_ratio = 0\.5 is invalid \(allowed: 0 <= poisson_ratio < 0\.5\)",
        ),
        (
            lambda t: _replace(t, "content_length_mm", "content_length_mm = 130"),
            r"content_length_mm = 130\.0 is invalid \(allowed: 0 < content_length_mm <= "
            r"length_mm = 120 mm, the content must fit\)",
        ),
        (
            lambda t: _replace(t, "length_mm", "length_mm = -5"),
            r"length_mm = -5\.0 is invalid \(allowed: 0 < length_mm <= 2000 mm\)",
        ),
        (
            lambda t: t + "element_size_mm = 0.5\n",
            r"element_size_mm = 0\.5 is invalid \(allowed: 1 <= element_size_mm <= 100 mm\)",
        ),
        (
            lambda t: t + "element_size_mm = 30\n",
            r"element_size_mm = 30 is too coarse .*allowed: element_size_mm <= 22\.5 mm",
        ),
        (lambda t: _replace(t, "mass_g", "mass_g = 1"), r"mass_g = 1 is invalid: the packaging"),
        (lambda t: _replace(t, "mass_g", 'mass_g = "40"'), r"mass_g = '40' must be a number"),
        (lambda t: _replace(t, "width_mm", "# no width"), r"missing key\(s\) width_mm"),
        (
            lambda t: _replace(t, "format_version", "format_version = 2"),
            r"format_version = 2 \(allowed: 1\)",
        ),
        (lambda t: t + "[material\n", r"not valid TOML"),
        (lambda t: t.replace("= 120", "= = 120"), r"not valid TOML"),
    ],
    ids=[
        "unknown-key",
        "unknown-material-key",
        "unknown-membrane-law",
        "negative-thickness",
        "poisson-0.5",
        "content-larger-than-packaging",
        "negative-length",
        "element-size-range",
        "element-size-coarse",
        "packaging-heavier-than-total",
        "string-number",
        "missing-key",
        "format-version",
        "malformed-table",
        "malformed-value",
    ],
)
def test_bad_files_name_file_key_and_range(tmp_path, change, message):
    path = _write(tmp_path, change(SMALL))
    with pytest.raises(ConsignmentFileError, match=message) as info:
        load_consignment_file(path)
    assert str(path) in str(info.value)


def test_resolve_presets_and_files(tmp_path):
    kpbw = resolve_consignment("KP/BW")
    assert kpbw.spec.id == "KPBW" and kpbw.element_size == pytest.approx(0.010)
    assert resolve_consignment("bw").element_size == pytest.approx(0.005)  # paper: 5 mm for BW
    assert resolve_consignment("PB", 0.025).element_size == pytest.approx(0.025)
    small = resolve_consignment(str(EXAMPLE), 0.015)  # overrides the file's 20 mm
    assert small.spec.id == "small" and small.element_size == pytest.approx(0.015)
    with pytest.raises(ValueError, match=r"unknown consignment 'XYZ'; allowed: KPBW, PB, KP, BW"):
        resolve_consignment("XYZ")
    with pytest.raises(FileNotFoundError, match="nothere.toml"):
        resolve_consignment(str(tmp_path / "nothere.toml"))
    with pytest.raises(ValueError, match=r"element size must be in \[1, 100\] mm, got 200 mm"):
        resolve_consignment("KPBW", 0.2)


# --------------------------------------------------------------------------------------------
# CLI on the small example (one assembly shared by the module; runs of 0.01 s simulated)


@pytest.fixture(scope="module")
def assembled(small_assembly) -> Path:
    return small_assembly  # conftest: the CLI's assemble of the example, once per session


def test_assemble_writes_snapshot_json_paraview_and_picture(assembled):
    from flexparcel.consignments.snapshot import load_snapshot

    for name in ("snapshot.npz", "assembly.json", "assembled.png", "paraview/assembled.pvd",
                 "paraview/assembled_0000.vtu", "paraview/assembled_content.pvd"):  # fmt: skip
        assert (assembled / name).is_file(), name
    info = json.loads((assembled / "assembly.json").read_text())
    assert info["consignment"] == "small" and info["build"]["element_size"] == pytest.approx(0.02)
    # settled: the assembly's own rest criterion, and the packaging wraps the 10 mm content
    assert info["info"]["kinetic_energy_J"] < info["info"]["settings"]["kinetic_tolerance"]
    assert info["extent_mm"][2] > 10.0
    # the rigid box's surface checked against the film (shape.content_surface_outside)
    surface = info["info"]["shape"]["content_surface"]
    assert surface["points"] > 0 and 0.0 <= surface["depth_mm"] <= surface["bound_mm"]
    snap = load_snapshot(assembled / "snapshot.npz")
    assert snap.build == load_consignment_file(EXAMPLE)


def test_run_swing_from_snapshot(assembled, tmp_path, capsys):
    out = tmp_path / "swing"
    args = ["run", "swing", "--consignment", str(EXAMPLE), "--snapshot",
            str(assembled / "snapshot.npz"), "--t-end", "0.01", "--out", str(out),
            "--set", "youngs_modulus=926"]  # fmt: skip
    assert main(args) == 0
    err = capsys.readouterr().err
    assert "swing small:" in err and "ETA" in err  # the progress bar
    r = json.loads((out / "responses.json").read_text())
    for key in ("first_swing_mm", "second_swing_mm", "simulated_s", "wall_s", "parameters"):
        assert key in r, key
    assert r["simulated_s"] == pytest.approx(0.01)
    # set: Table 6's modulus (the file's own 60 MPa film takes the jaws 1,384 steps to close
    # against 566; the drop below checks the file's value); not set: Table 6 contact values
    assert r["parameters"]["youngs_modulus"] == pytest.approx(926.0)
    assert r["parameters"]["contact_stiffness_packaging_content"] == pytest.approx(649.0)
    # the jaw closing before the release, its wall time part of wall_s
    jaws = r["preparation"]["jaw_closing"]
    assert isinstance(jaws["steps"], int) and jaws["steps"] > 0
    assert 0.0 < jaws["wall_s"] <= r["wall_s"] and jaws["kinetic_end_j"] < 1e-6
    assert not (out / "snapshot.npz").exists()  # started from the given one
    assert not (out / "checkpoint.npz").exists()  # saved while it ran, removed at its end
    for name in ("results.npz", "frames.png", "response.png", "paraview/packaging.pvd",
                 "paraview/packaging_0000.vtu", "paraview/content.pvd"):  # fmt: skip
        assert (out / name).is_file(), name
    from flexparcel.io.results import load_result

    data = load_result(out / "results.npz")
    assert data["time"][-1] == pytest.approx(0.01) and data["meta"]["test"] == "swing"


def test_run_drop_assembles_first_and_takes_set(tmp_path, capsys):
    out = tmp_path / "drop"
    args = ["run", "drop-vertical", "--consignment", str(EXAMPLE), "--t-end", "0.01",
            "--set", "contact_stiffness_packaging_ground=500", "--out", str(out),
            "--no-progress"]  # fmt: skip
    assert main(args) == 0
    assert (out / "snapshot.npz").is_file() and (out / "assembly.json").is_file()
    r = json.loads((out / "responses.json").read_text())
    assert r["test"] == "drop-vertical" and "rebound_mm" in r
    assert r["parameters"]["contact_stiffness_packaging_ground"] == 500.0
    assert r["parameters"]["youngs_modulus"] == pytest.approx(60.0)  # not set: the file's own
    assert r["snapshot"] == str(out / "snapshot.npz")
    assert (out / "frames.png").is_file() and (out / "response.png").is_file()


def _error(capsys, args) -> str:
    """Run the CLI expecting a usage error: exit code 2 and one line on stderr."""
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


def test_run_rejects_bad_input_before_assembling(tmp_path, capsys, assembled):
    out = tmp_path / "bad"
    base = ["run", "swing", "--consignment", str(EXAMPLE), "--out", str(out)]
    err = _error(capsys, [*base, "--set", "stiffness=3"])
    assert "unknown parameter 'stiffness'" in err and "youngs_modulus" in err
    err = _error(capsys, [*base, "--set", "youngs_modulus=-1"])
    assert "youngs_modulus must be in (0, 100000] MPa" in err
    err = _error(capsys, [*base, "--set", "youngs_modulus"])
    assert "expected name=value, got 'youngs_modulus'" in err
    err = _error(capsys, [*base, "--t-end", "-1"])
    assert "--t-end must be in (0, 10] s" in err
    assert not (out / "snapshot.npz").exists()  # failed before any assembly
    err = _error(capsys, ["run", "swing", "--consignment", "XYZ", "--out", str(out)])
    assert "unknown consignment 'XYZ'" in err
    bad = _write(tmp_path, SMALL + "[material\n", "broken.toml")
    err = _error(capsys, ["assemble", str(bad), "--out", str(out)])
    assert str(bad) in err and "not valid TOML" in err
    err = _error(capsys, ["run", "drop-horizontal", "--consignment", "KPBW", "--snapshot",
                          str(assembled / "snapshot.npz"), "--out", str(out)])  # fmt: skip
    assert "the snapshot holds consignment 'small'" in err
    err = _error(capsys, ["run", "swing", "--snapshot", str(assembled / "snapshot.npz"),
                          "--element-size", "15", "--out", str(out)])  # fmt: skip
    assert "assembled with 20 mm elements, not 15 mm" in err
    err = _error(capsys, ["run", "swing", "--out", str(out)])
    assert "--consignment" in err


def test_run_command_lists_the_jobs_tests():
    from flexparcel.cli import run_cmd
    from flexparcel.scenarios.registry import scenario_names

    assert set(run_cmd.SCENARIOS) <= set(scenario_names())


# --------------------------------------------------------------------------------------------
# Curves, marks and the demo report (no simulation)


def _fake_run(x_free: np.ndarray, first: float | None, second: float | None):
    """A swing run whose free edge (node 1) follows ``x_free`` [m]; node 0 is the packaging's
    -x end at 0, so the clamp edge is at 20 mm."""
    pos = np.zeros((len(x_free), 2, 3))
    pos[:, 1, 0] = x_free
    c = SimpleNamespace(packaging=np.array([0, 1]), edge=np.array([1]))
    return SimpleNamespace(
        result=SimpleNamespace(positions=pos),
        consignment=c,
        responses={"first_swing_mm": None if first is None else first * 1e3,
                   "second_swing_mm": None if second is None else second * 1e3},
    )  # fmt: skip


def test_swing_curve_marks_sit_on_the_reported_peaks():
    from flexparcel.scenarios.consignment_tests import swing_peaks
    from flexparcel.scenarios.swing import swing_curve

    t = np.linspace(0.0, 1.4, 281)
    # a damped pendulum-like free end: starts 0.25 m beyond the clamp edge (at 0.02 m)
    x = 0.02 + 0.25 * np.cos(2 * np.pi * t / 0.9) * np.exp(-1.2 * t)
    first, second = swing_peaks(x - 0.02)
    x_rel, m1, m2 = swing_curve(_fake_run(x, first, second))
    assert np.allclose(x_rel, x - 0.02)
    assert m1 is not None and m2 is not None
    assert m1[0] == int(np.argmin(x_rel[: len(t) // 2 + 20])) and m1[1] == first
    assert -x_rel[m1[0]] == pytest.approx(first) and x_rel[m2[0]] == pytest.approx(second)
    assert m2[0] > m1[0] and 0 < second < first
    assert swing_peaks(np.full(5, 0.3)) == (None, None)  # never swings past: not reached
    _, n1, n2 = swing_curve(_fake_run(np.full(5, 0.3), None, None))
    assert n1 is None and n2 is None


def test_demo_report_table():
    from flexparcel.cli.demo_cmd import report_markdown

    build = resolve_consignment("KPBW", 0.025)
    info = {"opening_time_s": 0.05, "end_time_s": 0.2, "kinetic_energy_J": 1e-7, "steps": 10,
            "wall_s": 3.0, "packaging_mass_kg": 0.016, "content_mass_kg": 0.124}  # fmt: skip
    results = {
        "swing": {
            "first_swing_mm": 64.0,
            "second_swing_mm": 27.0,
            "simulated_s": 1.4,
            "wall_s": 96.0,
        },  # fmt: skip
        "drop-vertical": {"rebound_mm": 3.1, "simulated_s": 0.3, "wall_s": 250.0},
        "drop-horizontal": "no convergence at t = 0.1 s",
    }
    text = report_markdown(build, info, results, quick=False, total_wall=400.0)
    assert "| first swing [mm] | 64.0 | 128 | 0.50 | 127 |" in text
    assert "| second swing [mm] | 27.0 | 27 | 1.00 | 32 |" in text
    assert "| vertical drop rebound [mm] | 3.1 | 6.2 | 0.50 | 7 |" in text
    assert "| horizontal drop rebound [mm] | – | 4.5 | – | 4 |" in text
    assert "| swing | 1.4 | 96.0 | 384 | 0.25 |" in text
    assert "| drop-vertical | 0.3 | 250.0 | 125 | 2.00 |" in text
    assert "| drop-horizontal | – | failed | 76 | – |" in text
    assert "![swing frames](swing/frames.png)" in text
    assert "Failed: no convergence at t = 0.1 s" in text
    quick = report_markdown(build, info, {"swing": {**results["swing"], "simulated_s": 0.7}},
                            quick=True, total_wall=1.0)  # fmt: skip
    assert "Quick mode" in quick and "| swing | 0.7 | 96.0 | 192 | 0.50 |" in quick


def test_paraview_boxes_have_the_content_size_and_rotation(tmp_path):
    import meshio

    from flexparcel.io.paraview import write_paraview_boxes

    size = (0.165, 0.125, 0.02)
    quarter = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # 90 deg about y
    rot = np.stack([np.eye(3), quarter])[:, None]  # (k=2, b=1, 3, 3)
    centre = np.array([[[0.0, 0.0, 0.1]], [[0.0, 0.0, 0.2]]])
    pvd = write_paraview_boxes(tmp_path, [0.0, 0.1], centre, rot, [size])
    assert 'file="content_0001.vtu"' in pvd.read_text()
    for k, extent in ((0, size), (1, (size[2], size[1], size[0]))):
        mesh = meshio.read(tmp_path / f"content_{k:04d}.vtu")
        assert mesh.cells[0].type == "hexahedron"
        assert np.allclose(np.ptp(mesh.points, axis=0), extent)
        assert np.allclose(mesh.points.mean(axis=0), centre[k, 0])
    with pytest.raises(ValueError, match="must be"):
        write_paraview_boxes(tmp_path, [0.0], centre, rot, [size])


def test_unsettled_assembly_writes_its_last_state_and_fails(assembled, tmp_path, monkeypatch,
                                                            capsys):  # fmt: skip
    # an assembly that does not come to rest ends with exit code 1 and leaves its last state
    # (unsettled.npz, unsettled.png) for diagnosis, but no snapshot.npz a test could start from
    from dataclasses import replace

    import flexparcel.consignments.assembly as asm_mod
    from flexparcel.consignments.snapshot import load_snapshot

    snap = load_snapshot(assembled / "snapshot.npz")
    last = replace(snap, info={**snap.info, "at_rest": False})

    def not_at_rest(build, *a, **k):
        raise asm_mod.AssemblyError("small: not at rest", unsettled=last)

    monkeypatch.setattr(asm_mod, "assemble", not_at_rest)
    out = tmp_path / "a"
    assert main(["assemble", str(EXAMPLE), "--out", str(out), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "not at rest" in err and str(out / "unsettled.npz") in err  # says where it is
    assert (out / "unsettled.png").stat().st_size > 0 and not (out / "snapshot.npz").exists()
    back = load_snapshot(out / "unsettled.npz")
    assert np.array_equal(back.positions, snap.positions) and back.info["at_rest"] is False


def test_demo_starts_from_a_named_snapshot_folder_only_when_it_fits(tmp_path):
    from flexparcel.cli.demo_cmd import given_snapshot
    from flexparcel.consignments.userfile import resolve_consignment

    shipped = Path(__file__).resolve().parents[1] / "data" / "paper-snapshots-25mm"
    snap, path = given_snapshot(resolve_consignment("KPBW", 0.025), shipped)
    assert path.endswith("KPBW.npz") and snap.build.element_size == pytest.approx(0.025)
    # assembled at 25 mm: a 10 mm demo must not start from it
    with pytest.raises(ValueError):
        given_snapshot(resolve_consignment("KPBW", 0.010), shipped)
    with pytest.raises(FileNotFoundError, match="no snapshot of 'KPBW' in"):
        given_snapshot(resolve_consignment("KPBW", 0.025), tmp_path)


def test_shipped_snapshots_are_taken_only_when_they_fit_and_passed_the_checks(
    assembled, tmp_path, monkeypatch, capsys
):
    # run, demo, bench and the conveyor take a shipped snapshot (data/paper-snapshots-*/)
    # instead of assembling, where one was assembled from the same build on today's mesh and
    # passed the rest and shape checks; the command line says so
    from dataclasses import replace

    import flexparcel.consignments.snapshot as snapshot_mod
    from flexparcel.cli.snapshots import shipped_or_assembled
    from flexparcel.consignments.snapshot import load_snapshot, save_snapshot, shipped_snapshot

    snap = load_snapshot(assembled / "snapshot.npz")
    folder = tmp_path / "shipped"
    folder.mkdir()
    monkeypatch.setattr(snapshot_mod, "SHIPPED_SNAPSHOT_DIRS", (folder,))
    path = folder / f"{snap.build.spec.id}.npz"
    assert shipped_snapshot(snap.build) is None  # none shipped
    save_snapshot(snap, path)
    found, where = shipped_snapshot(snap.build)
    assert where == path and np.array_equal(found.positions, snap.positions)
    # another element size, an old snapshot without the shape check, a failed shape: not taken
    coarser = replace(snap.build, element_size=2 * snap.build.element_size)
    assert shipped_snapshot(coarser) is None
    for info in (
        {k: v for k, v in snap.info.items() if k != "shape"},
        {**snap.info, "shape": {**snap.info["shape"], "failures": ["balloon"]}},
    ):
        save_snapshot(replace(snap, info=info), path)
        assert shipped_snapshot(snap.build) is None
    save_snapshot(snap, path)
    out = tmp_path / "out"
    got, source = shipped_or_assembled(snap.build, out, progress=False)
    assert source == str(path) and "using the shipped snapshot" in capsys.readouterr().out
    assert (out / "assembled.png").is_file()  # the assembly's files, as if assembled there
