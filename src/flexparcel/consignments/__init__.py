"""Consignments: the paper's four presets and user-defined ones, their assembly and snapshots."""

from flexparcel.consignments.build import (
    PRESETS,
    Consignment,
    ConsignmentBuild,
    add_consignment,
    preset,
)
from flexparcel.consignments.materials import PACKAGING_PRESETS, PackagingMaterial

__all__ = [
    "PRESETS",
    "PACKAGING_PRESETS",
    "PackagingMaterial",
    "Consignment",
    "ConsignmentBuild",
    "add_consignment",
    "preset",
]
