"""Friction between consignment surfaces and the conveyor: belt (PU) and deflectors (steel).

The paper (section 4.4) takes the static and dynamic coefficients of its conveyor run from
Schadler et al. 2022 (its ref. [8]: cardboard, kraft paper and polybags on an X6Cr17 steel plate
and a polyurethane belt). Those measured values were NOT available to us and are not
reproduced here. The defaults below are typical dry-contact values of the kind quoted in
engineering friction tables and packaging/conveyor practice, each row with its range and the
reasoning for the chosen number in ``source``. They are placeholders for measurements: replace
them with your own through a TOML file (:func:`load_friction_table`) before drawing quantitative
conclusions. No citation is implied by a row.

Surface materials (the outer surface that touches the belt or a deflector):
``pe_film`` (polyethylene film: polybags), ``kraft_paper``, ``bubble_wrap`` (LDPE bubble film),
``cardboard`` (a bare cardboard box, e.g. a content that pokes out). Counterparts: ``pu`` (the
polyurethane belt cover) and ``steel_x6cr17`` (the deflector sheet, ferritic stainless steel
1.4016). :func:`surface_material` maps the packaging materials of
:data:`flexparcel.selection.export.PACKAGING_MATERIALS` to their outer surface.

Rule, documented and enforced: ``0 <= mu_dynamic <= mu_static``. RecurDyn's law (paper eqs.
8-10) rises to mu_s at the static threshold speed and falls to mu_d beyond the dynamic one;
mu_d > mu_s is legal in :class:`flexparcel.ContactLaw`, but in a friction *table* it almost
always means swapped columns, so a table with it is rejected (set both equal if your
measurement really shows no static peak).

TOML override format (any subset of rows; every row needs both coefficients)::

    [pe_film.pu]
    mu_static = 0.45
    mu_dynamic = 0.38
    source = "own inclined-plane test, 2024-05, 10 repetitions"   # optional
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from flexparcel.contact.law import ContactLaw
from flexparcel.io.tomlfile import read_toml

__all__ = [
    "BELT",
    "DEFLECTOR",
    "SURFACE_MATERIALS",
    "COUNTERPARTS",
    "PACKAGING_SURFACES",
    "FrictionPair",
    "FrictionTableError",
    "DEFAULT_FRICTION_TABLE",
    "friction_pair",
    "surface_material",
    "load_friction_table",
    "with_friction",
]

BELT = "pu"
"""Counterpart name of the belt cover (polyurethane)."""
DEFLECTOR = "steel_x6cr17"
"""Counterpart name of the deflector sheet (X6Cr17 / 1.4016 stainless steel)."""
SURFACE_MATERIALS = ("pe_film", "kraft_paper", "bubble_wrap", "cardboard")
COUNTERPARTS = (BELT, DEFLECTOR)

PACKAGING_SURFACES: Mapping[str, str] = MappingProxyType(
    {
        # KP/BW: bubble wrap lines a kraft-paper envelope; kraft paper is the outside
        "kraft_paper_bubble_wrap": "kraft_paper",
        "polybag": "pe_film",
        "kraft_paper": "kraft_paper",
        "bubble_wrap": "bubble_wrap",
    }
)
"""Outer surface material of each packaging material of
:data:`flexparcel.selection.export.PACKAGING_MATERIALS`."""

# Coefficients far above 1 are rare for these dry pairs; anything above this bound is almost
# certainly a percentage or a typo (40 for 0.40).
_MU_MAX = 2.0
_FIELDS = ("mu_static", "mu_dynamic", "source")


class FrictionTableError(ValueError):
    """A friction table file or row is invalid (the message names the file and the key)."""


@dataclass(frozen=True)
class FrictionPair:
    """Static and dynamic friction coefficients [-] of one surface pair and where they come
    from. Validated: ``0 <= mu_dynamic <= mu_static <= 2``."""

    mu_static: float
    mu_dynamic: float
    source: str

    def __post_init__(self) -> None:
        for name in ("mu_static", "mu_dynamic"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise FrictionTableError(f"{name} must be a finite number, got {v!r}")
            if not 0.0 <= v <= _MU_MAX:
                raise FrictionTableError(f"{name} must be in [0, {_MU_MAX:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.mu_dynamic > self.mu_static:
            raise FrictionTableError(
                f"mu_dynamic = {self.mu_dynamic:g} must be <= mu_static = {self.mu_static:g} "
                "(swapped columns? set them equal if there is no static peak)"
            )
        if not isinstance(self.source, str) or not self.source.strip():
            raise FrictionTableError(f"source must be a non-empty string, got {self.source!r}")


def _row(mu_s: float, mu_d: float, source: str) -> FrictionPair:
    return FrictionPair(mu_s, mu_d, source)


_NO_DATA = "typical value, not measured (Schadler et al. 2022 not available): "
DEFAULT_FRICTION_TABLE: Mapping[tuple[str, str], FrictionPair] = MappingProxyType(
    {
        ("pe_film", BELT): _row(
            0.50,
            0.40,
            _NO_DATA + "dry polyethylene film on a smooth PU belt cover (an elastomer, grippier "
            "than metal), usually 0.4-0.6 static; chosen 0.50 mid-range, dynamic 0.40 (about "
            "20 % below static, usual for polymer on elastomer)",
        ),
        ("pe_film", DEFLECTOR): _row(
            0.30,
            0.25,
            _NO_DATA + "dry PE film on stainless steel sheet, usually 0.2-0.4 static; chosen "
            "0.30 mid-range, dynamic 0.25",
        ),
        ("kraft_paper", BELT): _row(
            0.55,
            0.45,
            _NO_DATA + "dry paper on a smooth PU belt cover, usually 0.45-0.7 static; chosen "
            "0.55, dynamic 0.45",
        ),
        ("kraft_paper", DEFLECTOR): _row(
            0.25,
            0.20,
            _NO_DATA + "dry paper on smooth steel, usually 0.2-0.35 static; chosen 0.25 "
            "(the lower half: the deflector is a smooth rolled sheet), dynamic 0.20",
        ),
        ("bubble_wrap", BELT): _row(
            0.50,
            0.40,
            _NO_DATA + "same LDPE surface as pe_film; the bubbles reduce the nominal contact "
            "area, which to first order does not change the friction coefficient; as pe_film",
        ),
        ("bubble_wrap", DEFLECTOR): _row(
            0.30,
            0.25,
            _NO_DATA + "same LDPE surface as pe_film on steel (0.2-0.4 static); as pe_film",
        ),
        ("cardboard", BELT): _row(
            0.60,
            0.50,
            _NO_DATA + "corrugated board on a smooth PU belt cover, usually 0.5-0.7 static "
            "(the range conveyor layouts assume for cartons on elastomer belts); chosen 0.60, "
            "dynamic 0.50",
        ),
        ("cardboard", DEFLECTOR): _row(
            0.30,
            0.25,
            _NO_DATA + "corrugated board on steel, usually 0.25-0.4 static; chosen 0.30, "
            "dynamic 0.25",
        ),
    }
)
"""Default coefficients per ``(surface material, counterpart)``; see the module docstring."""


def _check_name(kind: str, name: object, allowed: tuple[str, ...]) -> str:
    if name in allowed:
        return str(name)
    hint = ""
    if isinstance(name, str) and name in PACKAGING_SURFACES:
        hint = (
            f" ({name!r} is a packaging material: its outer surface is "
            f"surface_material({name!r}) = {PACKAGING_SURFACES[name]!r})"
        )
    raise FrictionTableError(f"unknown {kind} {name!r}; allowed: {', '.join(allowed)}{hint}")


def surface_material(packaging_material: str) -> str:
    """Outer surface material of a packaging material of
    :data:`flexparcel.selection.export.PACKAGING_MATERIALS` (e.g. ``"polybag"`` ->
    ``"pe_film"``)."""
    if packaging_material not in PACKAGING_SURFACES:
        raise FrictionTableError(
            f"unknown packaging material {packaging_material!r}; allowed: "
            f"{', '.join(PACKAGING_SURFACES)}"
        )
    return PACKAGING_SURFACES[packaging_material]


def friction_pair(
    material: str,
    counterpart: str,
    table: Mapping[tuple[str, str], FrictionPair] | None = None,
) -> tuple[float, float]:
    """``(mu_static, mu_dynamic)`` [-] of surface ``material`` (one of
    :data:`SURFACE_MATERIALS`) on ``counterpart`` (:data:`BELT` or :data:`DEFLECTOR`), from
    ``table`` (default :data:`DEFAULT_FRICTION_TABLE`)."""
    m = _check_name("surface material", material, SURFACE_MATERIALS)
    c = _check_name("counterpart", counterpart, COUNTERPARTS)
    row = (table if table is not None else DEFAULT_FRICTION_TABLE)[(m, c)]
    return row.mu_static, row.mu_dynamic


def with_friction(
    law: ContactLaw,
    material: str,
    counterpart: str,
    table: Mapping[tuple[str, str], FrictionPair] | None = None,
) -> ContactLaw:
    """A copy of ``law`` (normal force, threshold speeds unchanged) with the friction
    coefficients of ``material`` on ``counterpart``."""
    mu_s, mu_d = friction_pair(material, counterpart, table)
    return dataclasses.replace(law, mu_static=mu_s, mu_dynamic=mu_d)


def load_friction_table(
    path: str | Path,
    base: Mapping[tuple[str, str], FrictionPair] | None = None,
) -> Mapping[tuple[str, str], FrictionPair]:
    """Read a TOML override file (format in the module docstring) over ``base`` (default
    :data:`DEFAULT_FRICTION_TABLE`); returns a new read-only table.

    Raises :class:`FrictionTableError` naming the file and the offending key for invalid TOML,
    an unknown material, counterpart or field, a missing coefficient, a non-number, a value
    outside [0, 2] or mu_dynamic > mu_static; ``FileNotFoundError`` for a missing file.
    """
    path = Path(path)
    doc = read_toml(path, FrictionTableError, "friction table file")
    table = dict(base if base is not None else DEFAULT_FRICTION_TABLE)
    for material, rows in doc.items():
        try:
            _check_name("surface material", material, SURFACE_MATERIALS)
        except FrictionTableError as exc:
            raise FrictionTableError(f"{path}: [{material}]: {exc}") from None
        if not isinstance(rows, dict):
            raise FrictionTableError(
                f"{path}: {material} must be a table of counterparts "
                f"([{material}.{BELT}], [{material}.{DEFLECTOR}]), got {rows!r}"
            )
        for counterpart, row in rows.items():
            key = f"{material}.{counterpart}"
            try:
                _check_name("counterpart", counterpart, COUNTERPARTS)
            except FrictionTableError as exc:
                raise FrictionTableError(f"{path}: [{key}]: {exc}") from None
            if not isinstance(row, dict):
                raise FrictionTableError(
                    f"{path}: {key} must be a table with mu_static, mu_dynamic, got {row!r}"
                )
            unknown = sorted(set(row) - set(_FIELDS))
            if unknown:
                raise FrictionTableError(
                    f"{path}: [{key}]: unknown key(s) {', '.join(unknown)}; allowed: "
                    f"{', '.join(_FIELDS)}"
                )
            missing = [f for f in _FIELDS[:2] if f not in row]
            if missing:
                raise FrictionTableError(f"{path}: [{key}]: missing {', '.join(missing)}")
            source = row.get("source", f"override from {path.name}")
            try:
                table[(material, counterpart)] = FrictionPair(
                    row["mu_static"], row["mu_dynamic"], source
                )
            except FrictionTableError as exc:
                raise FrictionTableError(f"{path}: [{key}]: {exc}") from None
    return MappingProxyType(table)
