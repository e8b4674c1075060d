"""The consignment specification (one row of the paper's Table 2) and its TOML file format.

:class:`ConsignmentSpec` is what the consignment builders take and what ``flexparcel select``
writes for a selected cluster centroid; :func:`write_consignment_toml` and
:func:`read_consignment_toml` are the file format between the two (see ``docs/selection.md``).
Lengths are in mm and masses in g, as in the paper's tables and the survey; the builders convert
to SI (m, kg). This module needs only the standard library and :mod:`flexparcel.io.tomlfile`, so
the selection toolkit uses it without loading the finite-element code of the consignment builders.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from pathlib import Path

from flexparcel.io.tomlfile import read_toml

__all__ = [
    "CONSIGNMENT_FORMAT_VERSION",
    "PACKAGING_MATERIALS",
    "CONTENT_KINDS",
    "PACKAGING_CONSTRUCTIONS",
    "MAX_EDGE_MM",
    "MAX_MASS_G",
    "ConsignmentSpec",
    "ConsignmentFileError",
    "write_consignment_toml",
    "read_consignment_toml",
]

CONSIGNMENT_FORMAT_VERSION = 1
PACKAGING_MATERIALS = ("kraft_paper_bubble_wrap", "polybag", "kraft_paper", "bubble_wrap")
CONTENT_KINDS = ("rigid", "flexible")
PACKAGING_CONSTRUCTIONS = ("envelope", "gusseted")
# Upper bounds that catch unit mistakes (cm or m written as mm, kg as g) for small consignments:
# 2 m edge, 31.5 kg (the usual parcel mass limit).
MAX_EDGE_MM = 2000.0
MAX_MASS_G = 31500.0

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
    construction : how the flat packaging is made (:data:`PACKAGING_CONSTRUCTIONS`):
        ``"envelope"`` (two layers joined at their border; default) or ``"gusseted"`` (a bag
        with a W-gusset along each long side and sealed ends, whose side walls give the
        content's height: KP in the paper; see :mod:`flexparcel.consignments.build`).
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
    construction: str = "envelope"

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
        if self.construction not in PACKAGING_CONSTRUCTIONS:
            raise bad("construction", self.construction, "|".join(PACKAGING_CONSTRUCTIONS))
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
        construction = "gusseted"                        # optional: | envelope (default)
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
    if spec.construction != "envelope":  # files of envelopes read as they always did
        lines.append(f'construction = "{spec.construction}"')
    from flexparcel.io.atomic import write_atomic

    # atomic: a reader never meets half a consignment file
    return write_atomic(Path(path), "\n".join(lines) + "\n")


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
    optional = {"content_fixed_to_packaging", "based_on_cluster", "construction"}
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
        elif key in ("id", "packaging_material", "content_kind", "construction") and not isinstance(
            value, str
        ):
            raise ConsignmentFileError(f"{path}: {key} = {value!r} must be a string")
    try:
        return ConsignmentSpec(**doc)
    except ConsignmentFileError as exc:
        raise ConsignmentFileError(f"{path}: {exc}") from None
