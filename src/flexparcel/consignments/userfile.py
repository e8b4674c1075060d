"""User-defined consignments from a TOML file, and the lookup of a consignment by name or path.

The file is the consignment TOML of :func:`flexparcel.consignments.spec.read_consignment_toml`
(``format_version = 1``, flat keys, lengths in mm, mass in g) with two optional additions::

    format_version = 1
    id = "small"
    packaging_material = "bubble_wrap"    # kraft_paper_bubble_wrap | polybag | kraft_paper | ...
    length_mm = 120
    width_mm = 90
    height_mm = 10
    content_kind = "rigid"                # | flexible
    content_length_mm = 60
    content_width_mm = 45
    content_height_mm = 10
    mass_g = 40                           # total: packaging + content
    content_fixed_to_packaging = false    # optional
    construction = "envelope"             # optional: | gusseted (side walls from gussets)
    element_size_mm = 20                  # optional: shell edge length (default: 10 mm)

    [material]                            # optional: overrides of the packaging material preset
    youngs_modulus_mpa = 60
    poisson_ratio = 0.4
    thickness_mm = 0.5
    areal_density_g_m2 = 80
    damping_ratio_s = 1.71e-3             # RecurDyn's damping ratio: Rayleigh beta [s], C = beta K

Every value is checked when the file is read; an error names the file, the key and the allowed
range. The plain consignment keys are validated exactly as :func:`read_consignment_toml` does
(:class:`ConsignmentSpec` carries the range checks), so a file written by ``flexparcel select``
loads here unchanged.
"""

from __future__ import annotations

import math
from dataclasses import fields, replace
from pathlib import Path

from flexparcel.consignments.build import (
    GLUED_STRIP_WIDTH,
    PRESETS,
    ConsignmentBuild,
    preset,
)
from flexparcel.consignments.materials import PackagingMaterial, packaging_material
from flexparcel.consignments.spec import (
    CONSIGNMENT_FORMAT_VERSION,
    ConsignmentFileError,
    ConsignmentSpec,
)
from flexparcel.io.tomlfile import read_toml
from flexparcel.model.materials import MEMBRANE_LAWS

__all__ = [
    "MATERIAL_KEYS",
    "ELEMENT_SIZE_RANGE_MM",
    "load_consignment_file",
    "resolve_consignment",
]

ELEMENT_SIZE_RANGE_MM = (1.0, 100.0)
"""Allowed shell edge length [mm] (the range :meth:`ConsignmentBuild.of` accepts)."""

MATERIAL_KEYS: dict[str, tuple[str, float, str, str, str]] = {
    # key: (PackagingMaterial field, factor to SI, low bound, high bound, unit); "(" and "]"
    # mark open and closed bounds. The upper bounds catch unit slips (Pa written as MPa, um as
    # mm, kg/m^2 as g/m^2) rather than physics: stiff board is ~10 GPa, corrugated board ~7 mm
    # thick, heavy board ~1000 g/m^2. poisson_ratio stops short of 0.5 (incompressible).
    "youngs_modulus_mpa": ("youngs_modulus", 1e6, "(0", "1e5]", "MPa"),
    "poisson_ratio": ("poisson_ratio", 1.0, "[0", "0.5)", ""),
    "thickness_mm": ("thickness", 1e-3, "(0", "20]", "mm"),
    "areal_density_g_m2": ("areal_density", 1e-3, "(0", "5000]", "g/m^2"),
    "damping_ratio_s": ("damping_ratio", 1.0, "[0", "1]", "s"),
}
"""The ``[material]`` keys: paper-style units in the file, converted to SI."""
MEMBRANE_KEY = "membrane"
"""The ``[material]`` key of the membrane law, a string (``MEMBRANE_LAWS``)."""

_SPEC_KEYS = {f.name for f in fields(ConsignmentSpec)}
_SPEC_OPTIONAL = {"content_fixed_to_packaging", "based_on_cluster", "construction"}
_EXTRA_KEYS = {"element_size_mm", "material"}


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def load_consignment_file(path: str | Path) -> ConsignmentBuild:
    """Read and validate a user consignment TOML (format in the module docstring).

    Returns the :class:`ConsignmentBuild` (spec, packaging material with the file's overrides,
    element size [m]). Raises :class:`ConsignmentFileError` (a ``ValueError``) naming the file,
    the key and its allowed range for malformed TOML and for a missing, unknown, mistyped or
    out-of-range key; ``FileNotFoundError`` for a missing file.
    """
    path = Path(path)
    doc = read_toml(path, ConsignmentFileError, "consignment file")

    def fail(msg: str) -> ConsignmentFileError:
        return ConsignmentFileError(f"{path}: {msg}")

    version = doc.pop("format_version", None)
    if version != CONSIGNMENT_FORMAT_VERSION or isinstance(version, bool):
        raise fail(f"format_version = {version!r} (allowed: {CONSIGNMENT_FORMAT_VERSION})")
    unknown = sorted(set(doc) - _SPEC_KEYS - _EXTRA_KEYS)
    if unknown:
        allowed = ", ".join(["format_version", *sorted(_SPEC_KEYS), *sorted(_EXTRA_KEYS)])
        raise fail(f"unknown key(s) {', '.join(unknown)} (allowed: {allowed})")
    absent = sorted(k for k in _SPEC_KEYS - _SPEC_OPTIONAL if k not in doc)
    if absent:
        raise fail(f"missing key(s) {', '.join(absent)}")

    element_size_mm = doc.pop("element_size_mm", None)
    material_table = doc.pop("material", None)
    for key, value in doc.items():
        if key.endswith("_mm") or key == "mass_g":
            if not _is_number(value):
                raise fail(f"{key} = {value!r} must be a number")
            doc[key] = float(value)  # TOML integers are fine for lengths and masses
        elif key in ("id", "packaging_material", "content_kind", "construction") and not isinstance(
            value, str
        ):
            raise fail(f"{key} = {value!r} must be a string")
    try:
        spec = ConsignmentSpec(**doc)  # range checks, e.g. the content must fit
    except ConsignmentFileError as exc:
        raise fail(str(exc)) from None

    element_size = None
    if element_size_mm is not None:
        lo, hi = ELEMENT_SIZE_RANGE_MM
        if not _is_number(element_size_mm) or not lo <= element_size_mm <= hi:
            raise fail(
                f"element_size_mm = {element_size_mm!r} is invalid "
                f"(allowed: {lo:g} <= element_size_mm <= {hi:g} mm)"
            )
        element_size = float(element_size_mm) * 1e-3

    material = packaging_material(spec.packaging_material)
    if material_table is not None:
        material = _material_overrides(material, material_table, path)
    try:
        build = ConsignmentBuild.of(spec, element_size=element_size, material=material)
        _check_build(build)
    except ValueError as exc:
        raise fail(str(exc)) from None
    return build


def _material_overrides(base: PackagingMaterial, table: object, path: Path) -> PackagingMaterial:
    """``base`` with the ``[material]`` table's values (file units) converted to SI."""
    allowed = [*MATERIAL_KEYS, MEMBRANE_KEY]
    if not isinstance(table, dict):
        raise ConsignmentFileError(
            f"{path}: material must be a table ([material] with {', '.join(allowed)})"
        )
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise ConsignmentFileError(
            f"{path}: unknown key(s) {', '.join('material.' + k for k in unknown)} "
            f"(allowed: {', '.join(allowed)})"
        )
    changes: dict[str, float | str] = {}
    if MEMBRANE_KEY in table:
        law = table[MEMBRANE_KEY]
        if law not in MEMBRANE_LAWS:
            raise ConsignmentFileError(
                f"{path}: material.{MEMBRANE_KEY} = {law!r} is invalid "
                f"(allowed: {' | '.join(MEMBRANE_LAWS)})"
            )
        changes["membrane"] = law
    for key, value in table.items():
        if key == MEMBRANE_KEY:
            continue
        field_name, factor, low, high, unit = MATERIAL_KEYS[key]
        lo, hi = float(low[1:]), float(high[:-1])
        ok = _is_number(value)
        ok = ok and (lo <= value if low[0] == "[" else lo < value)
        ok = ok and (value <= hi if high[-1] == "]" else value < hi)
        if not ok:
            lo_op = "<=" if low[0] == "[" else "<"
            hi_op = "<=" if high[-1] == "]" else "<"
            raise ConsignmentFileError(
                f"{path}: material.{key} = {value!r} is invalid "
                f"(allowed: {lo:g} {lo_op} {key} {hi_op} {hi:g}{' ' + unit if unit else ''})"
            )
        changes[field_name] = float(value) * factor
    if not changes:
        return base
    source = (
        f"{path.name} [material] sets {', '.join(sorted(table))}; preset {base.name}: {base.source}"
    )
    return replace(base, source=source, **changes)


def _check_build(build: ConsignmentBuild) -> None:
    """Checks that need the spec, the material and the mesh size together (ValueError)."""
    spec = build.spec
    h_mm = build.element_size * 1e3
    # the assembly decides that the packaging is open from the nodes over the content: a mesh
    # coarser than half the content's smaller side would leave none (or one) there
    limit = 0.5 * min(spec.content_length_mm, spec.content_width_mm)
    if h_mm > limit + 1e-9:
        raise ValueError(
            f"element_size_mm = {h_mm:g} is too coarse for the {spec.content_length_mm:g} x "
            f"{spec.content_width_mm:g} mm content (allowed: element_size_mm <= {limit:g} mm, "
            "half its smaller side)"
        )
    # the content gets the total mass minus the packaging's: the packaging alone must be lighter
    # (both layers of the flat packaging; the exact mesh area is checked again when it is built)
    length, width = build.flat_size
    area = 2.0 * length * width
    if build.has_glued_strip:
        area += 2.0 * GLUED_STRIP_WIDTH * width
    packaging_g = build.material.areal_density * area * 1e3
    if packaging_g >= spec.mass_g:
        raise ValueError(
            f"mass_g = {spec.mass_g:g} is invalid: the packaging alone weighs about "
            f"{packaging_g:.1f} g ({build.material.areal_density * 1e3:g} g/m^2 over "
            f"{area * 1e4:.0f} cm^2; allowed: mass_g > {packaging_g:.1f} g, or lower "
            "material.areal_density_g_m2)"
        )


def resolve_consignment(
    name_or_path: str | Path, element_size: float | None = None
) -> ConsignmentBuild:
    """The build of a preset (``KPBW``, ``KP/BW``, ``PB``, ``KP``, ``BW``, any case) or of a
    consignment TOML file (a path ending in ``.toml`` or an existing file).

    ``element_size`` [m], if given, overrides the preset's (10 mm; 5 mm for BW) or the file's
    ``element_size_mm``. Raises ``ValueError`` naming the allowed names for an unknown name.
    """
    text = str(name_or_path)
    path = Path(text)
    if text.lower().endswith(".toml") or path.is_file():
        build = load_consignment_file(path)
        if element_size is not None:
            build = _with_element_size(build, element_size)
            _check_build(build)
        return build
    key = text.replace("/", "").upper()
    if key not in PRESETS:
        raise ValueError(
            f"unknown consignment {text!r}; allowed: {', '.join(PRESETS)} (KP/BW for KPBW) "
            "or a consignment .toml file"
        )
    build = ConsignmentBuild.of(preset(key), element_size=_checked_size(element_size))
    _check_build(build)
    return build


def _checked_size(element_size: float | None) -> float | None:
    """``element_size`` [m] if within :data:`ELEMENT_SIZE_RANGE_MM`, else ValueError."""
    if element_size is None:
        return None
    lo, hi = ELEMENT_SIZE_RANGE_MM
    if not (_is_number(element_size) and lo <= element_size * 1e3 <= hi):
        shown = f"{element_size * 1e3:g} mm" if _is_number(element_size) else repr(element_size)
        raise ValueError(f"element size must be in [{lo:g}, {hi:g}] mm, got {shown}")
    return float(element_size)


def _with_element_size(build: ConsignmentBuild, element_size: float) -> ConsignmentBuild:
    return ConsignmentBuild.of(
        build.spec, element_size=_checked_size(element_size), material=build.material
    )
