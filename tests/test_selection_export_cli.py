"""Consignment TOML bridge, output tables and the ``flexparcel select`` command."""

from __future__ import annotations

import csv
import math
from dataclasses import replace

import numpy as np
import pytest

from conftest import reference_file
from flexparcel.cli import main
from flexparcel.selection import (
    centroid_table,
    make_synthetic_survey,
    paper_centroid_survey,
    write_schema,
    write_survey_csv,
)
from flexparcel.selection.export import (
    ConsignmentFileError,
    ConsignmentSpec,
    centroid_table_markdown,
    consignment_from_centroid,
    read_consignment_toml,
    write_consignment_toml,
)

# The paper's Table 2 (tests/data/reference/consignments.csv) converted from cm to mm.
TABLE2 = [
    ConsignmentSpec("KPBW", "kraft_paper_bubble_wrap", 275, 200, 20, "rigid", 165, 125, 20, 140,
                    False, 1),
    ConsignmentSpec("PB", "polybag", 315, 225, 20, "flexible", 310, 225, 20, 180, False, 3),
    ConsignmentSpec("KP", "kraft_paper", 320, 250, 30, "rigid", 310, 225, 30, 380, True, 4),
    ConsignmentSpec("BW", "bubble_wrap", 200, 150, 20, "rigid", 165, 125, 20, 80, False, 6),
]  # fmt: skip


_TABLE2_PACKAGING = {
    "KPBW": "kraft_paper_bubble_wrap",
    "PB": "polybag",
    "KP": "kraft_paper",
    "BW": "bubble_wrap",
}


def test_table2_matches_reference_csv_and_presets():
    # The embedded Table 2 (here and in the consignment presets) against the reference table
    # (cm and g as printed; the packaging material follows from the id).
    from flexparcel.consignments.build import PRESETS

    text = reference_file("consignments.csv").read_text(encoding="utf-8")
    rows = list(csv.DictReader(line for line in text.splitlines() if not line.startswith("#")))
    cm = ("length", "width", "height", "content_length", "content_width", "content_height")
    specs = [
        ConsignmentSpec(
            r["id"],
            _TABLE2_PACKAGING[r["id"]],
            *(10.0 * float(r[f"{k}_cm"]) for k in cm[:3]),
            r["content_kind"],
            *(10.0 * float(r[f"{k}_cm"]) for k in cm[3:]),
            float(r["mass_g"]),
            content_fixed_to_packaging=r["content_fixed_to_packaging"] == "true",
            based_on_cluster=int(r["based_on_cluster"]),
        )
        for r in rows
    ]
    assert specs == TABLE2
    # the presets are Table 2's rows; how the packaging is made is ours (KP: gusseted)
    presets = [PRESETS[s.id] for s in specs]
    assert [replace(p, construction="envelope") for p in presets] == specs
    assert [p.construction for p in presets] == ["envelope", "envelope", "gusseted", "envelope"]


@pytest.mark.parametrize("spec", TABLE2, ids=lambda s: s.id)
def test_consignment_toml_roundtrip(tmp_path, spec):
    path = write_consignment_toml(spec, tmp_path / f"{spec.id}.toml")
    assert read_consignment_toml(path) == spec


def _paper_table():
    survey = paper_centroid_survey()
    labels = np.arange(1, len(survey) + 1)  # each Table 1 centroid is its own cluster
    table, _ = centroid_table(survey, labels)
    return table


def test_consignment_from_table1_centroids():
    table = _paper_table()
    pb = consignment_from_centroid(table, 3)
    # Cluster 3: polybag 29 x 22 x 2 cm, 180 g, flexibility 2 -> flexible content (as in the
    # paper); filling level 4 -> fraction 0.875 -> content edges scaled by sqrt(0.875).
    assert (pb.id, pb.packaging_material, pb.content_kind) == ("C3", "polybag", "flexible")
    assert (pb.length_mm, pb.width_mm, pb.height_mm, pb.mass_g) == (290.0, 220.0, 20.0, 180.0)
    assert pb.content_length_mm == pytest.approx(290 * math.sqrt(0.875), abs=0.05)
    assert pb.content_height_mm == 20.0 and pb.based_on_cluster == 3
    kpbw = consignment_from_centroid(table, 1, consignment_id="KPBW")
    assert kpbw.packaging_material == "kraft_paper_bubble_wrap" and kpbw.content_kind == "rigid"
    assert kpbw.content_width_mm == pytest.approx(190 * math.sqrt(0.625), abs=0.05)
    kp = consignment_from_centroid(
        table, 4, content_dims_mm=(310, 225, 30), content_fixed_to_packaging=True
    )
    assert kp.content_fixed_to_packaging and kp.content_length_mm == 310.0
    with pytest.raises(ValueError, match="no column 'len' for the consignment's length"):
        consignment_from_centroid(table, 1, columns={"length": "len"})


def _bad_toml(tmp_path, **changes):
    path = write_consignment_toml(TABLE2[0], tmp_path / "c.toml")
    text = path.read_text(encoding="utf-8")
    for key, value in changes.items():
        lines = [ln for ln in text.splitlines() if not ln.startswith(f"{key} =")]
        if value is not None:
            lines.append(f"{key} = {value}")
        text = "\n".join(lines) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"mass_g": "-3.0"}, r"mass_g = -3.0 is invalid \(allowed: 0 < mass_g <= 31500 g\)"),
        ({"length_mm": "2750.0"}, r"length_mm = 2750.0 .*\(allowed: 0 < length_mm <= 2000"),
        ({"content_width_mm": "250.0"}, r"content_width_mm = 250.0 .*<= width_mm = 200 mm"),
        ({"packaging_material": '"cardboard"'}, r"kraft_paper_bubble_wrap\|polybag\|kraft_paper"),
        ({"content_kind": '"liquid"'}, r"content_kind = 'liquid' .*\(allowed: rigid\|flex"),
        ({"height_mm": '"20"'}, r"height_mm = '20' must be a number"),
        ({"colour": '"red"'}, r"unknown key\(s\) colour"),
        ({"mass_g": None}, r"missing key\(s\) mass_g"),
        ({"format_version": "2"}, r"format_version = 2 \(allowed: 1\)"),
    ],
)  # fmt: skip
def test_consignment_toml_errors_name_key_and_range(tmp_path, changes, message):
    with pytest.raises(ConsignmentFileError, match=message):
        read_consignment_toml(_bad_toml(tmp_path, **changes))


def test_centroid_markdown_layout():
    md = centroid_table_markdown(_paper_table())
    lines = md.splitlines()
    assert lines[0].startswith("| cluster | cluster_size | packaging | shape |")
    assert lines[2] == (
        "| 1 | 1 | kraft paper w/ bubble wrap | flat | true | false | 1 | 3 | 27 | 19 | 2 | 140 "
        "| cluster1 |"
    )
    assert "6 clusters; 0 of 6 rows are noise." in md


def _csv(path):
    with path.open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_cli_select_synthetic_writes_outputs(tmp_path, capsys):
    out = tmp_path / "sel"
    assert main(["select", "--synthetic", "--keep", "4", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    assert "| cluster | cluster_size |" in stdout and "kept clusters: 1, 3, 4, 6" in stdout
    for name in ("survey.csv", "schema.toml", "labels.csv", "centroids.csv", "centroids.md",
                 "centroid_distances.csv", "selection.csv", "embedding.png"):  # fmt: skip
        assert (out / name).stat().st_size > 0, name
    selection = _csv(out / "selection.csv")
    assert [r["cluster"] for r in selection if r["kept"] == "true"] == ["1", "3", "4", "6"]
    assert [r["drop_order"] for r in selection if r["kept"] == "false"] == ["1", "2"]
    specs = sorted(read_consignment_toml(p).id for p in (out / "consignments").glob("*.toml"))
    assert specs == ["C1", "C3", "C4", "C6"]
    assert len(_csv(out / "labels.csv")) == 203
    assert (out / "embedding.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_select_reads_file_with_schema(tmp_path, capsys):
    survey, _ = make_synthetic_survey(scale=0.5, random_state=2)
    write_survey_csv(survey, tmp_path / "s.csv")
    write_schema(survey.schema, tmp_path / "schema.toml")
    out = tmp_path / "o"
    argv = ["select", str(tmp_path / "s.csv"), "--schema", str(tmp_path / "schema.toml"),
            "--min-cluster-size", "5", "--weight", "mass_g=2", "--out", str(out),
            "--no-plot"]  # fmt: skip
    assert main(argv) == 0
    assert len(_csv(out / "centroids.csv")) >= 4
    assert not (out / "embedding.png").exists()


def test_cli_select_bad_file_reports_error(tmp_path, capsys):
    p = tmp_path / "bad.csv"
    p.write_text("id,mass_g\na,100\nb,heavy\n", encoding="utf-8")
    schema = tmp_path / "schema.toml"
    schema.write_text(
        'id_column = "id"\n[columns.mass_g]\nkind = "numeric"\nmin = 1\nmax = 31500\nunit = "g"\n',
        encoding="utf-8",
    )
    assert main(["select", str(p), "--schema", str(schema), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "line 3, column 'mass_g': 'heavy' is not a number" in err
    assert "[1, 31500] g" in err
    assert main(["select", "--out", str(tmp_path / "o")]) == 2
    assert "give either a survey file or --synthetic" in capsys.readouterr().err


def test_example_script_runs(tmp_path, capsys):
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "selection_synthetic.py"
    runpy.run_path(str(script))["main"](tmp_path)
    assert "kept (1, 3, 4, 6), dropped (2, 5)" in capsys.readouterr().out
    assert sorted(p.name for p in tmp_path.glob("*.toml")) == [f"C{k}.toml" for k in (1, 3, 4, 6)]
