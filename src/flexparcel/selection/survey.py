"""Consignment surveys: column schema, reading (CSV / Parquet), validation and encoding.

A *survey* is a table of real consignments, one row each, with columns of four kinds:

``numeric``
    a measured quantity (length [cm], mass [g], ...), optionally bounded by ``min``/``max``;
``ordinal``
    an ordered class (filling level 1..4, flexibility 1..3), declared by its ordered ``levels``;
``categorical``
    an unordered label (packaging material, shape), optionally restricted to ``levels``;
``boolean``
    true/false (content movable, multi-part content).

The schema is declared in TOML (see :func:`read_schema` and ``docs/selection.md``) or inferred
from the file (:func:`infer_schema`, printed with :func:`describe_schema`). Files are treated as
data only: CSV through :mod:`csv`, Parquet through ``pyarrow`` when it is installed, TOML through
:mod:`tomllib`; nothing is evaluated or unpickled.

Encoded form (what :mod:`flexparcel.selection.gower` consumes): numeric and ordinal columns go to a
float matrix (ordinal values as their 0-based level rank), categorical and boolean columns to an
integer code matrix; missing values are NaN and -1 respectively.
"""

from __future__ import annotations

import csv
import io
import math
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "COLUMN_KINDS",
    "ColumnSpec",
    "SurveySchema",
    "Survey",
    "SurveyError",
    "read_schema",
    "write_schema",
    "infer_schema",
    "describe_schema",
    "read_survey",
    "survey_from_records",
    "write_survey_csv",
]

COLUMN_KINDS = ("numeric", "ordinal", "categorical", "boolean")
_NUMERIC_KINDS = ("numeric", "ordinal")
_SCHEMA_FORMAT_VERSION = 1

# Tokens read as "value not recorded". Case-insensitive; the empty cell is the common one.
_MISSING_TOKENS = frozenset({"", "na", "n/a", "nan", "null", "none", "?"})
_TRUE_TOKENS = frozenset({"true", "t", "yes", "y", "1"})
_FALSE_TOKENS = frozenset({"false", "f", "no", "n", "0"})

# Inference: an integer-valued column spanning at most this many consecutive values is taken
# as an ordinal class (filling level, flexibility class); anything wider stays numeric.
_MAX_INFERRED_ORDINAL_SPAN = 10


class SurveyError(ValueError):
    """A survey or schema file is malformed; the message names file, line, column and rule."""


Level = int | float | str


@dataclass(frozen=True)
class ColumnSpec:
    """One survey column.

    Attributes
    ----------
    name : column header in the survey file.
    kind : one of :data:`COLUMN_KINDS`.
    minimum, maximum : inclusive bounds of a ``numeric`` column, in ``unit`` (``None`` = open).
    levels : ordered levels of an ``ordinal`` column (required), allowed labels of a
        ``categorical`` column (optional; ``None`` accepts any label). Unused for ``boolean``.
    weight : Gower weight of the column (>= 0; 0 ignores it). Dimensionless.
    unit : unit of a numeric column as written in the file (``"cm"``, ``"g"``); informative,
        also used to convert a centroid into a consignment file.
    """

    name: str
    kind: str
    minimum: float | None = None
    maximum: float | None = None
    levels: tuple[Level, ...] | None = None
    weight: float = 1.0
    unit: str = ""

    def __post_init__(self) -> None:
        where = f"schema column {self.name!r}"
        if not self.name:
            raise SurveyError("schema: column names must be non-empty")
        if self.kind not in COLUMN_KINDS:
            raise SurveyError(
                f"{where}: kind {self.kind!r} is not one of {', '.join(COLUMN_KINDS)}"
            )
        if not (math.isfinite(self.weight) and self.weight >= 0.0):
            raise SurveyError(f"{where}: weight {self.weight!r} must be a finite number >= 0")
        if self.kind == "numeric":
            for label, bound in (("min", self.minimum), ("max", self.maximum)):
                if bound is not None and not math.isfinite(bound):
                    raise SurveyError(f"{where}: {label} = {bound!r} must be finite")
            if (
                self.minimum is not None
                and self.maximum is not None
                and not self.minimum < self.maximum
            ):
                raise SurveyError(
                    f"{where}: min ({self.minimum}) must be smaller than max ({self.maximum})"
                )
        elif self.minimum is not None or self.maximum is not None:
            raise SurveyError(f"{where}: min/max only apply to numeric columns, not {self.kind}")
        if self.kind == "ordinal" and not self.levels:
            raise SurveyError(f"{where}: an ordinal column needs its ordered 'levels'")
        if self.kind == "boolean" and self.levels is not None:
            raise SurveyError(f"{where}: a boolean column takes no 'levels'")
        if self.levels is not None:
            keys = [_level_key(v) for v in self.levels]
            if len(set(keys)) != len(keys):
                raise SurveyError(f"{where}: levels {list(self.levels)} contain duplicates")

    @property
    def is_numeric(self) -> bool:
        """True for numeric and ordinal columns (range-normalised Manhattan in Gower)."""
        return self.kind in _NUMERIC_KINDS

    def allowed(self) -> str:
        """Human-readable allowed range of values, for error messages and summaries."""
        if self.kind == "numeric":
            lo = "-inf" if self.minimum is None else f"{self.minimum:g}"
            hi = "inf" if self.maximum is None else f"{self.maximum:g}"
            unit = f" {self.unit}" if self.unit else ""
            return f"a number in [{lo}, {hi}]{unit}"
        if self.kind == "boolean":
            return "true/false (also yes/no, 1/0)"
        if self.levels is None:
            return "any label"
        return "one of " + ", ".join(repr(v) if isinstance(v, str) else f"{v}" for v in self.levels)


@dataclass(frozen=True)
class SurveySchema:
    """Ordered survey columns used as features, plus the optional row-identifier column."""

    columns: tuple[ColumnSpec, ...]
    id_column: str | None = None

    def __post_init__(self) -> None:
        if not self.columns:
            raise SurveyError("schema: at least one feature column is required")
        names = [c.name for c in self.columns]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise SurveyError(f"schema: columns declared twice: {', '.join(dupes)}")
        if self.id_column is not None and self.id_column in names:
            raise SurveyError(f"schema: id column {self.id_column!r} cannot also be a feature")

    @property
    def names(self) -> tuple[str, ...]:
        """Feature column names in schema order."""
        return tuple(c.name for c in self.columns)

    @property
    def numeric_columns(self) -> tuple[ColumnSpec, ...]:
        """Numeric and ordinal columns, in schema order (columns of ``Survey.numeric``)."""
        return tuple(c for c in self.columns if c.is_numeric)

    @property
    def categorical_columns(self) -> tuple[ColumnSpec, ...]:
        """Categorical and boolean columns, in schema order (columns of ``Survey.categorical``)."""
        return tuple(c for c in self.columns if not c.is_numeric)

    def column(self, name: str) -> ColumnSpec:
        """The spec of column ``name`` (``KeyError`` naming the known columns otherwise)."""
        for c in self.columns:
            if c.name == name:
                return c
        raise KeyError(f"no column {name!r} in the schema (columns: {', '.join(self.names)})")


@dataclass(frozen=True, eq=False)
class Survey:
    """A validated, encoded survey.

    Attributes
    ----------
    schema : the columns, in the order used below.
    ids : row identifiers, length ``n``.
    numeric : float64, shape (n, len(schema.numeric_columns)); numeric values in their column unit,
        ordinal values as 0-based level rank; NaN = missing.
    categorical : int64, shape (n, len(schema.categorical_columns)); index into the column's
        levels (boolean: 0 = false, 1 = true); -1 = missing.
    categorical_levels : the levels per categorical column (declared, or collected from the data
        for categorical columns declared without levels; boolean: ``(False, True)``).
    source : where the rows came from, used in messages.
    """

    schema: SurveySchema
    ids: tuple[str, ...]
    numeric: np.ndarray
    categorical: np.ndarray
    categorical_levels: tuple[tuple[Level, ...], ...]
    source: str = "<survey>"
    _levels_by_name: dict[str, tuple[Level, ...]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = len(self.ids)
        if self.numeric.shape != (n, len(self.schema.numeric_columns)):
            raise ValueError(f"numeric block has shape {self.numeric.shape}, expected (n={n}, ..)")
        if self.categorical.shape != (n, len(self.schema.categorical_columns)):
            raise ValueError(
                f"categorical block has shape {self.categorical.shape}, expected (n={n}, ..)"
            )
        levels = {c.name: c.levels for c in self.schema.numeric_columns if c.kind == "ordinal"}
        for c, lv in zip(self.schema.categorical_columns, self.categorical_levels, strict=True):
            levels[c.name] = lv
        object.__setattr__(self, "_levels_by_name", levels)

    def __len__(self) -> int:
        return len(self.ids)

    def levels(self, name: str) -> tuple[Level, ...]:
        """Levels of an ordinal, categorical or boolean column."""
        if name not in self._levels_by_name:
            raise KeyError(f"column {name!r} has no levels (numeric or unknown)")
        return self._levels_by_name[name]

    def column_values(self, name: str) -> list[Level | bool | None]:
        """Decoded values of one column (``None`` = missing), in row order."""
        spec = self.schema.column(name)
        if spec.is_numeric:
            j = self.schema.numeric_columns.index(spec)
            col = self.numeric[:, j]
            if spec.kind == "numeric":
                return [None if math.isnan(v) else float(v) for v in col]
            return [None if math.isnan(v) else spec.levels[int(v)] for v in col]
        j = self.schema.categorical_columns.index(spec)
        lv = self.categorical_levels[j]
        return [None if v < 0 else lv[v] for v in self.categorical[:, j]]

    def records(self) -> list[dict[str, object]]:
        """Decoded rows as dicts (id column first when the schema has one)."""
        cols = {name: self.column_values(name) for name in self.schema.names}
        id_name = self.schema.id_column or "id"
        out = []
        for i, row_id in enumerate(self.ids):
            rec: dict[str, object] = {id_name: row_id}
            rec.update({name: cols[name][i] for name in self.schema.names})
            out.append(rec)
        return out

    def subset(self, rows: Sequence[int] | np.ndarray) -> Survey:
        """The survey restricted to ``rows`` (indices), keeping schema and levels."""
        idx = np.asarray(rows, dtype=np.intp)
        return Survey(
            schema=self.schema,
            ids=tuple(self.ids[i] for i in idx),
            numeric=self.numeric[idx],
            categorical=self.categorical[idx],
            categorical_levels=self.categorical_levels,
            source=self.source,
        )


# --------------------------------------------------------------------------------------------
# Schema TOML


_COLUMN_KEYS = {"kind", "min", "max", "levels", "weight", "unit"}


def read_schema(path: str | Path) -> SurveySchema:
    """Read a survey schema from TOML.

    Format (``format_version = 1``; tables keep the file order, which is the feature order)::

        format_version = 1
        id_column = "id"                 # optional
        [columns.length_cm]
        kind = "numeric"                 # numeric | ordinal | categorical | boolean
        min = 1.0                        # numeric only, optional, inclusive
        max = 120.0
        unit = "cm"                      # optional
        weight = 1.0                     # optional Gower weight, >= 0
        [columns.filling_level]
        kind = "ordinal"
        levels = [1, 2, 3, 4]            # ordered, required for ordinal
        [columns.packaging]
        kind = "categorical"
        levels = ["polybag", "kraft paper"]   # optional for categorical

    Raises :class:`SurveyError` naming the offending key and its allowed values.
    """
    path = Path(path)
    try:
        with path.open("rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SurveyError(f"{path}: not valid TOML: {exc}") from None
    return _schema_from_dict(doc, str(path))


def _schema_from_dict(doc: Mapping[str, object], where: str) -> SurveySchema:
    unknown = set(doc) - {"format_version", "id_column", "columns"}
    if unknown:
        raise SurveyError(
            f"{where}: unknown top-level key(s) {', '.join(sorted(unknown))} "
            "(allowed: format_version, id_column, columns)"
        )
    version = doc.get("format_version", _SCHEMA_FORMAT_VERSION)
    if version != _SCHEMA_FORMAT_VERSION:
        raise SurveyError(f"{where}: format_version = {version!r}; only 1 is supported")
    id_column = doc.get("id_column")
    if id_column is not None and not isinstance(id_column, str):
        raise SurveyError(f"{where}: id_column must be a string")
    cols = doc.get("columns")
    if not isinstance(cols, Mapping) or not cols:
        raise SurveyError(f"{where}: a [columns.<name>] table per feature column is required")
    specs = []
    for name, entry in cols.items():
        cwhere = f"{where}: [columns.{name}]"
        if not isinstance(entry, Mapping):
            raise SurveyError(f"{cwhere} must be a table")
        bad = set(entry) - _COLUMN_KEYS
        if bad:
            raise SurveyError(
                f"{cwhere}: unknown key(s) {', '.join(sorted(bad))} "
                f"(allowed: {', '.join(sorted(_COLUMN_KEYS))})"
            )
        if "kind" not in entry:
            raise SurveyError(f"{cwhere}: 'kind' is required ({', '.join(COLUMN_KINDS)})")
        levels = entry.get("levels")
        if levels is not None:
            if not isinstance(levels, list) or not all(
                isinstance(v, int | float | str) and not isinstance(v, bool) for v in levels
            ):
                raise SurveyError(f"{cwhere}: levels must be a list of numbers or strings")
            levels = tuple(levels)
        try:
            specs.append(
                ColumnSpec(
                    name=name,
                    kind=entry["kind"],
                    minimum=_opt_float(entry.get("min"), f"{cwhere}: min"),
                    maximum=_opt_float(entry.get("max"), f"{cwhere}: max"),
                    levels=levels,
                    weight=_opt_float(entry.get("weight", 1.0), f"{cwhere}: weight"),
                    unit=str(entry.get("unit", "")),
                )
            )
        except SurveyError as exc:
            raise SurveyError(f"{where}: {exc}") from None
    return SurveySchema(columns=tuple(specs), id_column=id_column)


def _opt_float(value: object, where: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SurveyError(f"{where} must be a number, got {value!r}")
    return float(value)


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    s = str(v).replace("\\", "\\\\").replace('"', '\\"')
    return f'"{s}"'


def _toml_key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _toml_value(name)


def write_schema(schema: SurveySchema, path: str | Path) -> Path:
    """Write ``schema`` as TOML in the format read by :func:`read_schema`; returns the path."""
    lines = [f"format_version = {_SCHEMA_FORMAT_VERSION}"]
    if schema.id_column is not None:
        lines.append(f"id_column = {_toml_value(schema.id_column)}")
    for c in schema.columns:
        lines += ["", f"[columns.{_toml_key(c.name)}]", f'kind = "{c.kind}"']
        if c.minimum is not None:
            lines.append(f"min = {c.minimum!r}")
        if c.maximum is not None:
            lines.append(f"max = {c.maximum!r}")
        if c.levels is not None:
            lines.append("levels = [" + ", ".join(_toml_value(v) for v in c.levels) + "]")
        if c.unit:
            lines.append(f"unit = {_toml_value(c.unit)}")
        if c.weight != 1.0:
            lines.append(f"weight = {c.weight!r}")
    from flexparcel.io.atomic import write_atomic

    return write_atomic(Path(path), "\n".join(lines) + "\n")  # never half a schema


def describe_schema(schema: SurveySchema, survey: Survey | None = None) -> str:
    """A plain-text summary: one line per column with kind, allowed values and missing count."""
    lines = [f"{'column':<22} {'kind':<12} {'weight':>6}  allowed / levels"]
    for c in schema.columns:
        extra = ""
        if survey is not None:
            vals = survey.column_values(c.name)
            n_missing = sum(v is None for v in vals)
            if c.kind == "categorical" and c.levels is None:
                extra = f"  (levels seen: {', '.join(map(str, survey.levels(c.name)))})"
            if n_missing:
                extra += f"  [{n_missing} missing]"
        lines.append(f"{c.name:<22} {c.kind:<12} {c.weight:>6g}  {c.allowed()}{extra}")
    if schema.id_column:
        lines.append(f"(row id column: {schema.id_column})")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Reading tables


def _read_table(path: Path) -> tuple[list[str], list[tuple[int, list[object]]]]:
    """Header and (line number, cells) rows of a CSV or Parquet file."""
    if not path.exists():
        raise FileNotFoundError(f"survey file not found: {path}")
    suffix = path.suffix.lower()
    if suffix in (".parquet", ".pq"):
        return _read_parquet(path)
    if suffix in (".csv", ".txt", ".tsv"):
        return _read_csv(path)
    raise SurveyError(f"{path}: unsupported file type {suffix!r} (use .csv, .tsv or .parquet)")


def _read_csv(path: Path) -> tuple[list[str], list[tuple[int, list[object]]]]:
    # utf-8-sig drops the byte-order mark that spreadsheet programs write.
    with path.open(newline="", encoding="utf-8-sig") as fh:
        text = fh.read()
    # Lines starting with '#' above the header are comments (the reference tables carry their
    # source that way).
    first = next(
        (ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")), None
    )
    if first is None:
        raise SurveyError(f"{path}: the file has no header line")
    # Delimiter: whichever of , ; TAB splits the header most (European exports use ';').
    delimiter = max((",", ";", "\t"), key=first.count)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    header: list[str] | None = None
    rows: list[tuple[int, list[object]]] = []
    for cells in reader:
        line = reader.line_num
        if not cells or all(not c.strip() for c in cells):
            continue
        if header is None:
            # Comments only before the header: after it, "#12" may well be a consignment id.
            if not cells[0].lstrip().startswith("#"):
                header = [c.strip() for c in cells]
            continue
        if len(cells) != len(header):
            raise SurveyError(
                f"{path}, line {line}: {len(cells)} fields, but the header has {len(header)}"
            )
        rows.append((line, list(cells)))
    assert header is not None
    return header, rows


def _read_parquet(path: Path) -> tuple[list[str], list[tuple[int, list[object]]]]:
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise SurveyError(
            f"{path}: reading Parquet needs pyarrow, which is not installed "
            "(pip install pyarrow), or export the survey as CSV"
        ) from None
    table = pq.read_table(path)
    header = [str(n) for n in table.column_names]
    columns = [table.column(i).to_pylist() for i in range(table.num_columns)]
    # "line" = 1-based row number + 1, so that messages read like CSV line numbers.
    rows = [(i + 2, [col[i] for col in columns]) for i in range(table.num_rows)]
    return header, rows


def _check_header(header: Sequence[str], where: str) -> None:
    seen: set[str] = set()
    for name in header:
        if not name:
            raise SurveyError(f"{where}: the header has an empty column name")
        if name in seen:
            raise SurveyError(f"{where}: column {name!r} appears twice in the header")
        seen.add(name)


# --------------------------------------------------------------------------------------------
# Cell parsing


def _level_key(v: object) -> object:
    """Matching key of a level: numbers by value, labels case- and space-insensitively."""
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, int | float):
        return float(v)
    return " ".join(str(v).split()).lower()


def _is_missing(v: object) -> bool:
    if v is None:
        return True
    if isinstance(v, float) and math.isnan(v):
        return True
    return isinstance(v, str) and v.strip().lower() in _MISSING_TOKENS


def _parse_number(v: object) -> float | None:
    if isinstance(v, bool):
        return None
    if isinstance(v, int | float):
        return float(v)
    try:
        return float(str(v).strip())
    except ValueError:
        return None


def _parse_bool(v: object) -> bool | None:
    if isinstance(v, bool):
        return v
    if isinstance(v, int | float) and v in (0, 1):
        return bool(v)
    token = str(v).strip().lower()
    if token in _TRUE_TOKENS:
        return True
    if token in _FALSE_TOKENS:
        return False
    return None


def _looks_boolean(v: object) -> bool:
    # For inference only words count: a column of 0/1 numbers stays numeric (same Gower distance).
    if isinstance(v, bool):
        return True
    if isinstance(v, int | float):
        return False
    token = str(v).strip().lower()
    return token in (_TRUE_TOKENS | _FALSE_TOKENS) - {"0", "1"}


def _level_lookup(levels: Iterable[Level]) -> dict[object, int]:
    return {_level_key(v): i for i, v in enumerate(levels)}


def _cell_level_key(v: object) -> object:
    # A CSV cell "3" or "3.0" must match the TOML level 3; labels match case-insensitively.
    num = _parse_number(v)
    if num is not None and math.isfinite(num):
        return num
    return _level_key(v)


def survey_from_records(
    records: Sequence[Mapping[str, object]] | Sequence[Sequence[object]],
    schema: SurveySchema,
    *,
    header: Sequence[str] | None = None,
    source: str = "<records>",
    lines: Sequence[int] | None = None,
) -> Survey:
    """Validate and encode rows into a :class:`Survey`.

    Parameters
    ----------
    records : rows as mappings column -> value, or as sequences aligned with ``header``. Values may
        be strings (as read from CSV) or Python numbers/bools/None.
    schema : the columns to use; other columns are ignored.
    header : column names when ``records`` are sequences.
    source, lines : file name and per-row line numbers used in error messages.

    Raises
    ------
    SurveyError
        naming source, line, column, the offending value and the allowed range, for a missing
        column, a value of the wrong kind, an out-of-range value, or a row with no feature values.
    """
    rows: list[Sequence[object]]
    if header is None:
        header = list(records[0].keys()) if records else list(schema.names)
        for r in records:  # mappings may come with differing keys
            for k in r:
                if k not in header:
                    header.append(k)
        rows = [[r.get(k) for k in header] for r in records]  # type: ignore[union-attr]
    else:
        rows = [list(r) for r in records]
    _check_header(header, source)
    if lines is None:
        lines = [i + 2 for i in range(len(rows))]
    position = {name: j for j, name in enumerate(header)}
    needed = list(schema.names) + ([schema.id_column] if schema.id_column else [])
    missing = [name for name in needed if name not in position]
    if missing:
        raise SurveyError(
            f"{source}: column(s) {', '.join(repr(m) for m in missing)} required by the schema "
            f"are missing (columns present: {', '.join(header)})"
        )
    if not rows:
        raise SurveyError(f"{source}: the survey has a header but no data rows")

    n = len(rows)
    num_specs = schema.numeric_columns
    cat_specs = schema.categorical_columns
    numeric = np.full((n, len(num_specs)), np.nan)
    categorical = np.full((n, len(cat_specs)), -1, dtype=np.int64)

    def fail(i: int, spec: ColumnSpec, value: object, why: str) -> SurveyError:
        return SurveyError(
            f"{source}, line {lines[i]}, column {spec.name!r}: {value!r} {why} "
            f"({spec.kind} column, allowed: {spec.allowed()})"
        )

    for j, spec in enumerate(num_specs):
        col = position[spec.name]
        lookup = _level_lookup(spec.levels) if spec.kind == "ordinal" else None
        for i, row in enumerate(rows):
            v = row[col]
            if _is_missing(v):
                continue
            if lookup is not None:
                rank = lookup.get(_cell_level_key(v))
                if rank is None:
                    raise fail(i, spec, v, "is not a level of this ordinal column")
                numeric[i, j] = rank
                continue
            x = _parse_number(v)
            if x is None:
                raise fail(i, spec, v, "is not a number")
            if not math.isfinite(x):
                raise fail(i, spec, v, "is not finite")
            if (spec.minimum is not None and x < spec.minimum) or (
                spec.maximum is not None and x > spec.maximum
            ):
                raise fail(i, spec, v, "is out of range")
            numeric[i, j] = x

    cat_levels: list[tuple[Level, ...]] = []
    for j, spec in enumerate(cat_specs):
        col = position[spec.name]
        if spec.kind == "boolean":
            cat_levels.append((False, True))
            for i, row in enumerate(rows):
                v = row[col]
                if _is_missing(v):
                    continue
                b = _parse_bool(v)
                if b is None:
                    raise fail(i, spec, v, "is not a boolean")
                categorical[i, j] = int(b)
            continue
        if spec.levels is not None:
            levels = spec.levels
            lookup = _level_lookup(levels)
            for i, row in enumerate(rows):
                v = row[col]
                if _is_missing(v):
                    continue
                code = lookup.get(_level_key(v)) if isinstance(v, str) else None
                if code is None:
                    code = lookup.get(_cell_level_key(v))
                if code is None:
                    raise fail(i, spec, v, "is not an allowed label")
                categorical[i, j] = code
        else:
            # Undeclared labels: collect them (sorted, so encoding is order-independent), keeping
            # the first spelling met for labels that differ only in case or spacing.
            spelling: dict[object, str] = {}
            for row in rows:
                v = row[col]
                if not _is_missing(v):
                    spelling.setdefault(_level_key(str(v).strip()), " ".join(str(v).split()))
            keys = sorted(spelling, key=str)
            levels = tuple(spelling[k] for k in keys)
            lookup = {k: c for c, k in enumerate(keys)}
            for i, row in enumerate(rows):
                v = row[col]
                if not _is_missing(v):
                    categorical[i, j] = lookup[_level_key(str(v).strip())]
        cat_levels.append(tuple(levels))

    empty = np.isnan(numeric).all(axis=1) & (categorical < 0).all(axis=1)
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise SurveyError(
            f"{source}, line {lines[i]}: all feature columns are missing; a row needs at least "
            "one value to have a Gower distance"
        )

    if schema.id_column:
        col = position[schema.id_column]
        ids = tuple(str(row[col]).strip() for row in rows)
        seen: dict[str, int] = {}
        for i, rid in enumerate(ids):
            if not rid:
                raise SurveyError(f"{source}, line {lines[i]}: empty id in {schema.id_column!r}")
            if rid in seen:
                raise SurveyError(
                    f"{source}, line {lines[i]}: id {rid!r} repeats line {lines[seen[rid]]}"
                )
            seen[rid] = i
    else:
        ids = tuple(f"row{line}" for line in lines)
    return Survey(schema, ids, numeric, categorical, tuple(cat_levels), source)


def infer_schema(
    header: Sequence[str],
    rows: Sequence[Sequence[object]],
    *,
    id_column: str | None = None,
    exclude: Iterable[str] = (),
) -> SurveySchema:
    """Guess a schema from the data.

    Rules, per column (missing cells ignored): all true/false/yes/no -> ``boolean``; all numbers,
    integer-valued and spanning at most 10 consecutive values -> ``ordinal`` with those levels;
    other numbers -> ``numeric`` (no bounds); anything else -> ``categorical`` (levels from
    data). A column named ``id`` (or ``id_column``) is the row identifier; ``exclude`` drops
    columns. Guesses can be wrong (a 1..4 cm height becomes ordinal; equivalent for Gower when
    the levels are consecutive): print :func:`describe_schema` and write a TOML when it matters.
    """
    excluded = set(exclude)
    if id_column is None and "id" in header:
        id_column = "id"
    specs = []
    for j, name in enumerate(header):
        if name == id_column or name in excluded:
            continue
        values = [r[j] for r in rows if not _is_missing(r[j])]
        if not values:
            raise SurveyError(f"column {name!r}: every value is missing, cannot infer its kind")
        if all(_looks_boolean(v) for v in values):
            specs.append(ColumnSpec(name, "boolean"))
            continue
        nums = [_parse_number(v) for v in values]
        if all(x is not None and math.isfinite(x) for x in nums):
            ints = all(float(x).is_integer() for x in nums)  # type: ignore[arg-type]
            lo, hi = min(nums), max(nums)  # type: ignore[type-var]
            if ints and hi - lo < _MAX_INFERRED_ORDINAL_SPAN:
                levels = tuple(range(int(lo), int(hi) + 1))
                specs.append(ColumnSpec(name, "ordinal", levels=levels))
            else:
                specs.append(ColumnSpec(name, "numeric"))
            continue
        specs.append(ColumnSpec(name, "categorical"))
    return SurveySchema(tuple(specs), id_column=id_column)


def read_survey(
    path: str | Path,
    schema: SurveySchema | str | Path | None = None,
    *,
    exclude: Iterable[str] = (),
) -> Survey:
    """Read and validate a survey file (``.csv``/``.tsv``, or ``.parquet`` with pyarrow).

    ``schema`` is a :class:`SurveySchema`, a path to a schema TOML, or ``None`` to infer one
    (:func:`infer_schema`; ``exclude`` names columns to leave out, e.g. known labels). CSV files
    may use ``,``, ``;`` or TAB; lines starting with ``#`` above the header are comments; empty
    cells and NA/NaN/null/none/? are missing values.
    """
    path = Path(path)
    header, numbered = _read_table(path)
    _check_header(header, str(path))
    rows = [cells for _, cells in numbered]
    if isinstance(schema, str | Path):
        schema = read_schema(schema)
    elif schema is None:
        if not rows:
            raise SurveyError(f"{path}: the survey has a header but no data rows")
        try:
            schema = infer_schema(header, rows, exclude=exclude)
        except SurveyError as exc:
            raise SurveyError(f"{path}: {exc}") from None
    return survey_from_records(
        rows, schema, header=header, source=str(path), lines=[ln for ln, _ in numbered]
    )


def _csv_cell(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.10g}"
    return str(v)


def write_survey_csv(survey: Survey, path: str | Path) -> Path:
    """Write ``survey`` as CSV (id column, then the schema columns; missing = empty cell)."""
    from flexparcel.io.atomic import write_atomic

    records = survey.records()
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(list(records[0].keys()))
    for rec in records:
        w.writerow([_csv_cell(v) for v in rec.values()])
    return write_atomic(Path(path), buf.getvalue())  # never half a table
