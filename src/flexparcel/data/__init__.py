"""Reference data shipped with the package (installed as package data).

``verification/`` holds the published tables of the structural verification cases (Sze, Liu &
Lo 2004) that :mod:`flexparcel.verification` and ``flexparcel verify`` compare against; its
``README.md`` names the sources, the load cases and the units. Importing this module loads nothing
but :mod:`pathlib`.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DATA_DIR", "VERIFICATION_DIR"]

DATA_DIR: Path = Path(__file__).resolve().parent
"""Folder of the package data."""

VERIFICATION_DIR: Path = DATA_DIR / "verification"
"""Folder with ``sze2004_cantilever_end_shear.csv`` and ``sze2004_cantilever_end_moment.csv``."""
