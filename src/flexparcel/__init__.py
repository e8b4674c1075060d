"""flexparcel: multi flexible body dynamics of limp consignments in parcel sorting.

The structural core (shells, solvers) is imported here; the calibration and selection toolkits
live in :mod:`flexparcel.calibration` and :mod:`flexparcel.selection` and are imported on demand.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
