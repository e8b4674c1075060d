"""Output files of a selection: centroid tables, selection, labels, and consignment TOML files.

The consignment TOML is the bridge from a selected cluster centroid to the simulation: the
consignment builders read it with :func:`read_consignment_toml`. It mirrors the columns of the
paper's Table 2 with lengths in mm and mass in g, one flat key per column. The specification and
its file format live in :mod:`flexparcel.consignments.spec` (standard library only) and are
re-exported here; see :func:`write_consignment_toml` for the format and ``docs/selection.md``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np

from flexparcel.consignments.spec import (
    CONSIGNMENT_FORMAT_VERSION,
    CONTENT_KINDS,
    PACKAGING_MATERIALS,
    ConsignmentFileError,
    ConsignmentSpec,
    read_consignment_toml,
    write_consignment_toml,
)
from flexparcel.io.atomic import write_atomic
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
    "write_csv",
]

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


def write_csv(path: str | Path, header: Sequence[object], rows: Iterable[Sequence[object]]) -> Path:
    """Write a CSV file (UTF-8, the csv module's dialect) atomically: a temporary file in the
    same folder, then ``os.replace``, so a reader never sees half a table."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(header)
    w.writerows(rows)
    return write_atomic(Path(path), buf.getvalue())


def write_centroid_csv(table: CentroidTable, path: str | Path) -> Path:
    """Write the centroid table as CSV: cluster, cluster_size, feature columns, medoid_id."""
    rows = (
        [k, size, *(_fmt(vals[n]) for n in table.schema.names), med]
        for k, size, vals, med in zip(
            table.cluster_ids, table.sizes, table.values, table.medoid_ids, strict=True
        )
    )
    return write_csv(path, ["cluster", "cluster_size", *table.schema.names, "medoid_id"], rows)


def write_selection_csv(
    table: CentroidTable, selection: DiverseSelection, path: str | Path
) -> Path:
    """Write the selection as CSV: cluster, cluster_size, kept, drop_order (1 = dropped first),
    mean_distance_at_drop (Gower, the redundancy that made it go), medoid_id."""
    rows = []
    for k, size, med in zip(table.cluster_ids, table.sizes, table.medoid_ids, strict=True):
        if k in selection.dropped:
            i = selection.dropped.index(k)
            rows.append([k, size, "false", i + 1, f"{selection.mean_distance_at_drop[i]:.6f}", med])
        else:
            rows.append([k, size, "true", "", "", med])
    header = ["cluster", "cluster_size", "kept", "drop_order", "mean_distance_at_drop", "medoid_id"]
    return write_csv(path, header, rows)


def write_labels_csv(result: SurveyClustering, path: str | Path) -> Path:
    """Write per-row cluster labels as CSV: id, cluster (-1 = noise), probability."""
    rows = (
        [rid, int(lab), f"{p:.4f}"]
        for rid, lab, p in zip(result.survey.ids, result.labels, result.probabilities, strict=True)
    )
    return write_csv(path, ["id", "cluster", "probability"], rows)
