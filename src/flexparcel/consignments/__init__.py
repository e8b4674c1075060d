"""Consignments: the paper's four presets and user-defined ones, their assembly and snapshots.

The names below are loaded lazily, on first access (PEP 562): the builders need the
finite-element code, while :mod:`flexparcel.consignments.spec` (the consignment specification and
its TOML file, lengths in mm and masses in g) is importable without it.
"""

from __future__ import annotations

from flexparcel._lazy import lazy_exports

# Public name -> module that defines it.
_LAZY: dict[str, str] = {
    "PRESETS": "flexparcel.consignments.build",
    "PACKAGING_PRESETS": "flexparcel.consignments.materials",
    "PackagingMaterial": "flexparcel.consignments.materials",
    "Consignment": "flexparcel.consignments.build",
    "ConsignmentBuild": "flexparcel.consignments.build",
    "ConsignmentSpec": "flexparcel.consignments.spec",
    "add_consignment": "flexparcel.consignments.build",
    "preset": "flexparcel.consignments.build",
}

__all__ = list(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, globals())
