"""Output files of a selection: centroid tables, selection, labels, and consignment TOML files.

The consignment TOML is the bridge from a selected cluster centroid to the simulation: the
consignment builders read it with :func:`read_consignment_toml`. It mirrors the columns of
``reference/consignments.csv`` (the paper's Table 2) with lengths in mm and mass in g, one flat
key per column; see :func:`write_consignment_toml` for the format and ``docs/selection.md``.
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from flexparcel.io.tomlfile import read_toml
from flexparcel.selection.clustering import CentroidTable, DiverseSelection, SurveyClustering

__all__ = [
    "CONSIGNMENT_FORMAT_VERSION",
    "PACKAGING_MATERIALS",
    "CONTENT_KINDS",
    "ConsignmentSpec",
    "ConsignmentFileError",
    "consignment_from_centroid",
    "write_consignment_toml",
    "read_consignment_toml",
    "centroid_table_markdown",
    "write_centroid_csv",
    "write_selection_csv",
    "write_labels_csv",
]

CONSIGNMENT_FORMAT_VERSION = 1
PACKAGING_MATERIALS = ("kraft_paper_bubble_wrap", "polybag", "kraft_paper", "bubble_wrap")
CONTENT_KINDS = ("rigid", "flexible")
# Upper bounds that catch unit mistakes (cm or m written as mm, kg as g) for small consignments:
# 2 m edge, 31.5 kg (the usual parcel mass limit).
MAX_EDGE_MM = 2000.0
MAX_MASS_G = 31500.0

# Survey spellings of the packaging materials (matched case- and space-insensitively).
_PACKAGING_ALIASES = {
    "kraft paper w/ bubble wrap": "kraft_paper_bubble_wrap",
    "kraft paper with bubble wrap": "kraft_paper_bubble_wrap",
    "kp/bw": "kraft_paper_bubble_wrap",
    "kpbw": "kraft_paper_bubble_wrap",
    "polybag": "polybag",
    "poly bag": "polybag",
    "pb": "polybag",
    "kraft paper": "kraft_paper",
    "kp": "kraft_paper",
    "bubble wrap": "bubble_wrap",
    "bw": "bubble_wrap",
}
_LENGTH_TO_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}
_MASS_TO_G = {"g": 1.0, "kg": 1000.0}
_ID_PATTERN = re.compile(r"[A-Za-z0-9_.-]{1,64}")


class ConsignmentFileError(ValueError):
    """A consignment TOML or spec is invalid; the message names the key and its allowed range."""


@dataclass(frozen=True)
class ConsignmentSpec:
    """A consignment as the builders take it (one row of the paper's Table 2).

    Attributes
    ----------
    id : name, 1-64 characters of ``A-Z a-z 0-9 _ . -``.
    packaging_material : one of :data:`PACKAGING_MATERIALS`.
    length_mm, width_mm, height_mm : outer packaging dimensions [mm], in (0, 2000].
    content_kind : ``"rigid"`` (rounded box) or ``"flexible"`` (granulate in a bag, solid mesh).
    content_length_mm, content_width_mm, content_height_mm : content dimensions [mm], each in
        (0, matching outer dimension].
    mass_g : total mass, packaging + content [g], in (0, 31500].
    content_fixed_to_packaging : content glued to the bottom layer (KP in the paper).
    based_on_cluster : survey cluster number it represents (>= 1), or ``None``.
    """

    id: str
    packaging_material: str
    length_mm: float
    width_mm: float
    height_mm: float
    content_kind: str
    content_length_mm: float
    content_width_mm: float
    content_height_mm: float
    mass_g: float
    content_fixed_to_packaging: bool = False
    based_on_cluster: int | None = None

    def __post_init__(self) -> None:
        def bad(key: str, value: object, allowed: str) -> ConsignmentFileError:
            return ConsignmentFileError(
                f"consignment {self.id!r}: {key} = {value!r} is invalid (allowed: {allowed})"
            )

        if not isinstance(self.id, str) or not _ID_PATTERN.fullmatch(self.id):
            raise ConsignmentFileError(
                f"consignment id {self.id!r} is invalid "
                "(allowed: 1-64 characters of A-Z a-z 0-9 _ . -)"
            )
        if self.packaging_material not in PACKAGING_MATERIALS:
            raise bad("packaging_material", self.packaging_material, "|".join(PACKAGING_MATERIALS))
        if self.content_kind not in CONTENT_KINDS:
            raise bad("content_kind", self.content_kind, "|".join(CONTENT_KINDS))
        for key in ("length_mm", "width_mm", "height_mm"):
            v = getattr(self, key)
            if not _is_number(v) or not 0.0 < v <= MAX_EDGE_MM:
                raise bad(key, v, f"0 < {key} <= {MAX_EDGE_MM:g} mm")
        for key, outer in (
            ("content_length_mm", "length_mm"),
            ("content_width_mm", "width_mm"),
            ("content_height_mm", "height_mm"),
        ):
            v, limit = getattr(self, key), getattr(self, outer)
            if not _is_number(v) or not 0.0 < v <= limit:
                raise bad(key, v, f"0 < {key} <= {outer} = {limit:g} mm, the content must fit")
        if not _is_number(self.mass_g) or not 0.0 < self.mass_g <= MAX_MASS_G:
            raise bad("mass_g", self.mass_g, f"0 < mass_g <= {MAX_MASS_G:g} g")
        if not isinstance(self.content_fixed_to_packaging, bool):
            raise bad("content_fixed_to_packaging", self.content_fixed_to_packaging, "true|false")
        if self.based_on_cluster is not None and (
            isinstance(self.based_on_cluster, bool)
            or not isinstance(self.based_on_cluster, int)
            or self.based_on_cluster < 1
        ):
            raise bad("based_on_cluster", self.based_on_cluster, "an integer >= 1")


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def write_consignment_toml(spec: ConsignmentSpec, path: str | Path) -> Path:
    """Write ``spec`` as a consignment TOML file; returns the path.

    Format (``format_version = 1``; flat keys, lengths in mm, mass in g; ``based_on_cluster``
    optional; any other key is rejected by :func:`read_consignment_toml`)::

        format_version = 1
        id = "C1"
        based_on_cluster = 1
        packaging_material = "kraft_paper_bubble_wrap"   # | polybag | kraft_paper | bubble_wrap
        length_mm = 270.0
        width_mm = 190.0
        height_mm = 20.0
        content_kind = "rigid"                           # | flexible
        content_length_mm = 165.0
        content_width_mm = 125.0
        content_height_mm = 20.0
        mass_g = 140.0                                   # total: packaging + content
        content_fixed_to_packaging = false
    """
    lines = [
        "# flexparcel consignment (lengths in mm, mass in g); see docs/selection.md",
        f"format_version = {CONSIGNMENT_FORMAT_VERSION}",
        f"id = {_toml_string(spec.id)}",
    ]
    if spec.based_on_cluster is not None:
        lines.append(f"based_on_cluster = {spec.based_on_cluster}")
    lines += [
        f'packaging_material = "{spec.packaging_material}"',
        f"length_mm = {float(spec.length_mm)!r}",
        f"width_mm = {float(spec.width_mm)!r}",
        f"height_mm = {float(spec.height_mm)!r}",
        f'content_kind = "{spec.content_kind}"',
        f"content_length_mm = {float(spec.content_length_mm)!r}",
        f"content_width_mm = {float(spec.content_width_mm)!r}",
        f"content_height_mm = {float(spec.content_height_mm)!r}",
        f"mass_g = {float(spec.mass_g)!r}",
        f"content_fixed_to_packaging = {'true' if spec.content_fixed_to_packaging else 'false'}",
    ]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _toml_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def read_consignment_toml(path: str | Path) -> ConsignmentSpec:
    """Read and validate a consignment TOML (format of :func:`write_consignment_toml`).

    Raises :class:`ConsignmentFileError` naming the file, the key and its allowed range for a
    missing, unknown, mistyped or out-of-range key; ``FileNotFoundError`` for a missing file.
    """
    path = Path(path)
    doc = read_toml(path, ConsignmentFileError, "consignment file")
    version = doc.pop("format_version", None)
    if version != CONSIGNMENT_FORMAT_VERSION:
        raise ConsignmentFileError(
            f"{path}: format_version = {version!r} (allowed: {CONSIGNMENT_FORMAT_VERSION})"
        )
    known = {f.name: f for f in fields(ConsignmentSpec)}
    unknown = sorted(set(doc) - set(known))
    if unknown:
        raise ConsignmentFileError(
            f"{path}: unknown key(s) {', '.join(unknown)} (allowed: {', '.join(known)})"
        )
    optional = {"content_fixed_to_packaging", "based_on_cluster"}
    absent = [k for k in known if k not in doc and k not in optional]
    if absent:
        raise ConsignmentFileError(f"{path}: missing key(s) {', '.join(absent)}")
    for key, value in doc.items():
        if key.endswith("_mm") or key == "mass_g":
            # TOML integers (270) are fine for lengths; store them as float.
            if _is_number(value):
                doc[key] = float(value)
            else:
                raise ConsignmentFileError(f"{path}: {key} = {value!r} must be a number")
        elif key in ("id", "packaging_material", "content_kind") and not isinstance(value, str):
            raise ConsignmentFileError(f"{path}: {key} = {value!r} must be a string")
    try:
        return ConsignmentSpec(**doc)
    except ConsignmentFileError as exc:
        raise ConsignmentFileError(f"{path}: {exc}") from None


def consignment_from_centroid(
    table: CentroidTable,
    cluster: int,
    *,
    consignment_id: str | None = None,
    columns: Mapping[str, str] | None = None,
    content_kind: str | None = None,
    content_dims_mm: Sequence[float] | None = None,
    content_fixed_to_packaging: bool = False,
    packaging_materials: Mapping[str, str] | None = None,
) -> ConsignmentSpec:
    """Turn a cluster centroid into a :class:`ConsignmentSpec`.

    Parameters
    ----------
    table, cluster : the centroid table and the cluster number.
    consignment_id : default ``"C<cluster>"``.
    columns : survey column per role, overriding the defaults ``packaging``, ``length_cm``,
        ``width_cm``, ``height_cm``, ``mass_g``, ``filling_level``, ``flexibility`` (roles
        ``packaging, length, width, height, mass, filling_level, flexibility``). Units come from
        the column's declared unit, else from the name suffix (``_mm``, ``_cm``, ``_m``, ``_g``,
        ``_kg``).
    content_kind : default from the flexibility class: the lowest class -> ``"rigid"``, higher
        -> ``"flexible"`` (the paper's choice for its four consignments: only the polybag,
        flexibility 2, got a flexible content).
    content_dims_mm : (length, width, height) of the content [mm]. Default from the filling level
        class: the filled fraction f is the class midpoint (1..4 -> 0.125, 0.375, 0.625, 0.875;
        0.5 when unknown), content length and width are the outer ones times sqrt(f), content
        height equals the outer height (flat consignments: the content spans the thickness).
    content_fixed_to_packaging : the survey does not record how a non-movable content is held
        (tight fit or adhesive), so this is the caller's call.
    packaging_materials : extra survey label -> material key mappings.
    """
    role = {
        "packaging": "packaging",
        "length": "length_cm",
        "width": "width_cm",
        "height": "height_cm",
        "mass": "mass_g",
        "filling_level": "filling_level",
        "flexibility": "flexibility",
    }
    role.update(columns or {})
    values = table.row(cluster)
    schema = table.schema

    def required(r: str) -> object:
        name = role[r]
        if name not in values:
            raise ValueError(
                f"the survey has no column {name!r} for the consignment's {r}; pass "
                f"columns={{'{r}': <column>}} (columns: {', '.join(schema.names)})"
            )
        if values[name] is None:
            raise ValueError(f"cluster {cluster}: centroid {name!r} is missing")
        return values[name]

    def factor(r: str, table_: Mapping[str, float]) -> float:
        name = role[r]
        unit = schema.column(name).unit or name.rsplit("_", 1)[-1]
        if unit not in table_:
            raise ValueError(
                f"column {name!r}: unit {unit!r} unknown (allowed: {', '.join(table_)}); "
                "declare it as unit = ... in the schema"
            )
        return table_[unit]

    aliases = {
        **_PACKAGING_ALIASES,
        **{k.lower(): v for k, v in (packaging_materials or {}).items()},
    }
    label = " ".join(str(required("packaging")).split()).lower()
    material = aliases.get(label, label if label in PACKAGING_MATERIALS else None)
    if material is None:
        raise ValueError(
            f"packaging {label!r} has no consignment material (allowed: "
            f"{', '.join(PACKAGING_MATERIALS)}); map it with packaging_materials={{...}}"
        )
    outer = [
        round(float(required(r)) * factor(r, _LENGTH_TO_MM), 1)
        for r in ("length", "width", "height")
    ]
    mass = round(float(required("mass")) * factor("mass", _MASS_TO_G), 1)

    if content_kind is None:
        flex = values.get(role["flexibility"])
        if flex is None:
            content_kind = "rigid"
        else:
            levels = schema.column(role["flexibility"]).levels or (flex,)
            content_kind = "rigid" if list(levels).index(flex) == 0 else "flexible"
    if content_dims_mm is None:
        fill = values.get(role["filling_level"])
        fraction = 0.5
        if fill is not None:
            levels = schema.column(role["filling_level"]).levels or (fill,)
            fraction = (list(levels).index(fill) + 0.5) / len(levels)
        s = math.sqrt(fraction)
        content_dims_mm = (round(outer[0] * s, 1), round(outer[1] * s, 1), outer[2])
    if len(content_dims_mm) != 3:
        raise ValueError("content_dims_mm must be (length, width, height) in mm")
    return ConsignmentSpec(
        id=consignment_id or f"C{cluster}",
        packaging_material=material,
        length_mm=outer[0],
        width_mm=outer[1],
        height_mm=outer[2],
        content_kind=content_kind,
        content_length_mm=float(content_dims_mm[0]),
        content_width_mm=float(content_dims_mm[1]),
        content_height_mm=float(content_dims_mm[2]),
        mass_g=mass,
        content_fixed_to_packaging=content_fixed_to_packaging,
        based_on_cluster=int(cluster),
    )


# --------------------------------------------------------------------------------------------
# Tables


def _fmt(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, bool | np.bool_):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def centroid_table_markdown(table: CentroidTable, *, medoids: bool = True) -> str:
    """The centroid table as Markdown (Table 1 layout: cluster, size, one column per feature,
    then the medoid id), with a line counting noise rows."""
    head = ["cluster", "cluster_size", *table.schema.names] + (["medoid"] if medoids else [])
    lines = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    for k, size, vals, med in zip(
        table.cluster_ids, table.sizes, table.values, table.medoid_ids, strict=True
    ):
        cells = [str(k), str(size), *(_fmt(vals[n]) for n in table.schema.names)]
        if medoids:
            cells.append(med)
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(
        f"{len(table.cluster_ids)} clusters; {table.n_noise} of {table.n_rows} rows are noise."
    )
    return "\n".join(lines) + "\n"


def write_centroid_csv(table: CentroidTable, path: str | Path) -> Path:
    """Write the centroid table as CSV: cluster, cluster_size, feature columns, medoid_id."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["cluster", "cluster_size", *table.schema.names, "medoid_id"])
        for k, size, vals, med in zip(
            table.cluster_ids, table.sizes, table.values, table.medoid_ids, strict=True
        ):
            w.writerow([k, size, *(_fmt(vals[n]) for n in table.schema.names), med])
    return path


def write_selection_csv(
    table: CentroidTable, selection: DiverseSelection, path: str | Path
) -> Path:
    """Write the selection as CSV: cluster, cluster_size, kept, drop_order (1 = dropped first),
    mean_distance_at_drop (Gower, the redundancy that made it go), medoid_id."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(
            ["cluster", "cluster_size", "kept", "drop_order", "mean_distance_at_drop", "medoid_id"]
        )
        for k, size, med in zip(table.cluster_ids, table.sizes, table.medoid_ids, strict=True):
            if k in selection.dropped:
                i = selection.dropped.index(k)
                row = [k, size, "false", i + 1, f"{selection.mean_distance_at_drop[i]:.6f}", med]
            else:
                row = [k, size, "true", "", "", med]
            w.writerow(row)
    return path


def write_labels_csv(result: SurveyClustering, path: str | Path) -> Path:
    """Write per-row cluster labels as CSV: id, cluster (-1 = noise), probability."""
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "cluster", "probability"])
        for rid, lab, p in zip(result.survey.ids, result.labels, result.probabilities, strict=True):
            w.writerow([rid, int(lab), f"{p:.4f}"])
    return path
