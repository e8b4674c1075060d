"""Survey schema and file reading: validation errors name the column and the allowed range."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import reference_file
from flexparcel.selection import (
    PAPER_TABLE1,
    SurveyError,
    SurveySchema,
    describe_schema,
    make_synthetic_survey,
    read_schema,
    read_survey,
    synthetic_schema,
    write_schema,
    write_survey_csv,
)

HEADER = (
    "id,packaging,shape,content_movable,content_multipart,flexibility,filling_level,"
    "length_cm,width_cm,height_cm,mass_g"
)
GOOD = "A1,polybag,flat,false,false,2,4,29,22,2,180"


def _write(tmp_path: Path, *lines: str, name: str = "survey.csv") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return p


def _read(tmp_path: Path, *rows: str, header: str = HEADER):
    return read_survey(_write(tmp_path, header, *rows), synthetic_schema())


def test_reads_valid_csv_with_comments_case_and_missing(tmp_path):
    path = _write(
        tmp_path,
        "# a comment above the header",
        HEADER,
        GOOD,
        "",
        "A2,Kraft Paper  w/ Bubble Wrap,FLAT,yes,no,1,3,27.5,19,,140",
        "#3,polybag,flat,false,false,2,4,29,22,2,180",  # after the header: data, not a comment
    )
    s = read_survey(path, synthetic_schema())
    assert s.ids == ("A1", "A2", "#3")
    assert s.column_values("packaging")[:2] == ["polybag", "kraft paper w/ bubble wrap"]
    assert s.column_values("content_movable")[:2] == [False, True]
    assert s.column_values("filling_level")[:2] == [4, 3]
    assert s.column_values("height_cm")[:2] == [2.0, None]
    assert np.isnan(s.numeric[1, s.schema.numeric_columns.index(s.schema.column("height_cm"))])


def test_semicolon_csv(tmp_path):
    s = _read(tmp_path, GOOD.replace(",", ";"), header=HEADER.replace(",", ";"))
    assert s.column_values("mass_g") == [180.0]


def test_missing_column_is_named(tmp_path):
    header = HEADER.replace(",mass_g", "")
    with pytest.raises(SurveyError, match=r"column\(s\) 'mass_g' required by the schema"):
        _read(tmp_path, GOOD.rsplit(",", 1)[0], header=header)


@pytest.mark.parametrize(
    ("field", "bad", "message"),
    [
        ("mass_g", "heavy", r"line 2, column 'mass_g': 'heavy' is not a number .*\[1, 31500\] g"),
        ("mass_g", "50000", r"column 'mass_g': '50000' is out of range .*\[1, 31500\] g"),
        ("height_cm", "inf", r"column 'height_cm': 'inf' is not finite .*\[0.5, 80\] cm"),
        ("filling_level", "7", r"column 'filling_level': '7' is not a level .*one of 1, 2, 3, 4"),
        ("packaging", "cardboard", r"'packaging': 'cardboard' is not an allowed label .*'polybag'"),
        ("content_movable", "maybe", r"'content_movable': 'maybe' is not a boolean .*true/false"),
    ],
)
def test_bad_values_name_column_and_allowed_range(tmp_path, field, bad, message):
    cells = dict(zip(HEADER.split(","), GOOD.split(","), strict=True))
    cells[field] = bad
    with pytest.raises(SurveyError, match=message):
        _read(tmp_path, ",".join(cells.values()))


def test_structural_errors(tmp_path):
    with pytest.raises(SurveyError, match="line 3: 10 fields, but the header has 11"):
        _read(tmp_path, GOOD, GOOD.rsplit(",", 1)[0])
    with pytest.raises(SurveyError, match="line 3: id 'A1' repeats line 2"):
        _read(tmp_path, GOOD, GOOD)
    with pytest.raises(SurveyError, match="line 2: all feature columns are missing"):
        _read(tmp_path, "A9" + "," * 10)
    with pytest.raises(SurveyError, match="no data rows"):
        _read(tmp_path)
    with pytest.raises(SurveyError, match="unsupported file type '.xlsx'"):
        read_survey(_write(tmp_path, HEADER, GOOD, name="s.xlsx"))
    with pytest.raises(FileNotFoundError, match="survey file not found"):
        read_survey(tmp_path / "nope.csv")


def test_parquet_without_pyarrow_says_so(tmp_path, monkeypatch):
    # A None entry in sys.modules makes the import fail as if pyarrow were not installed.
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    p = tmp_path / "s.parquet"
    p.write_bytes(b"PAR1")
    with pytest.raises(SurveyError, match=r"Parquet needs pyarrow.*pip install pyarrow"):
        read_survey(p)


def test_parquet_roundtrip_when_pyarrow_present(tmp_path):
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    table = pa.table({"id": ["a", "b"], "mass_g": [100.0, None], "movable": [True, False]})
    pq.write_table(table, tmp_path / "s.parquet")
    s = read_survey(tmp_path / "s.parquet")
    assert s.column_values("mass_g") == [100.0, None]
    assert s.schema.column("movable").kind == "boolean"


def test_schema_toml_roundtrip_and_errors(tmp_path):
    path = write_schema(synthetic_schema(), tmp_path / "schema.toml")
    assert read_schema(path) == synthetic_schema()

    def bad(text: str, message: str) -> None:
        p = tmp_path / "bad.toml"
        p.write_text(text, encoding="utf-8")
        with pytest.raises(SurveyError, match=message):
            read_schema(p)

    bad('[columns.x]\nkind = "number"\n', r"'x'.*kind 'number' is not one of numeric, ordinal")
    bad('[columns.x]\nkind = "ordinal"\n', r"'x'.*ordinal column needs its ordered 'levels'")
    bad('[columns.x]\nkind = "numeric"\nmin = 5\nmax = 1\n', r"min \(5.0\) must be smaller")
    bad('[columns.x]\nkind = "numeric"\nmaximum = 1\n', r"unknown key\(s\) maximum")
    bad('[columns.x]\nkind = "numeric"\nweight = -1\n', r"weight -1.0 must be a finite number >= 0")
    bad("format_version = 2\n[columns.x]\nkind = 'numeric'\n", "only 1 is supported")
    bad("id_column = 'id'\n", r"\[columns.<name>\] table per feature column is required")


def test_infer_schema_kinds(tmp_path):
    survey, _ = make_synthetic_survey(scale=0.2, random_state=1)
    path = write_survey_csv(survey, tmp_path / "s.csv")
    s = read_survey(path)
    kinds = {c.name: c.kind for c in s.schema.columns}
    assert kinds == {
        "packaging": "categorical",
        "shape": "categorical",
        "content_movable": "boolean",
        "content_multipart": "boolean",
        "flexibility": "ordinal",
        "filling_level": "ordinal",
        "length_cm": "numeric",
        "width_cm": "numeric",
        "height_cm": "numeric",
        "mass_g": "numeric",
    }
    assert s.schema.id_column == "id" and s.ids == survey.ids
    summary = describe_schema(s.schema, s)
    assert "packaging" in summary and "levels seen" in summary
    # Excluding a column drops it from the inferred schema.
    assert "shape" not in read_survey(path, exclude=["shape"]).schema.names


def test_reference_table1_matches_embedded_copy():
    schema = SurveySchema(synthetic_schema().columns, id_column="cluster")
    s = read_survey(reference_file("cluster-centroids.csv"), schema)
    assert s.ids == tuple(str(r["cluster"]) for r in PAPER_TABLE1)
    for name in schema.names:
        assert s.column_values(name) == [r[name] for r in PAPER_TABLE1], name
