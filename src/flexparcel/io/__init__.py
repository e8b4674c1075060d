"""Results files (npz) and ParaView export. Heavy dependencies are imported lazily.

Every reader of a flexparcel file raises :class:`FileFormatError` (a ``ValueError``) naming
the file when it cannot be read; its subclasses are ``CheckpointError``
(:mod:`flexparcel.io.checkpoint`) and ``SnapshotError``
(:mod:`flexparcel.consignments.snapshot`).
"""

from flexparcel.io.results import FileFormatError, load_result, save_result

__all__ = ["FileFormatError", "save_result", "load_result", "write_paraview"]


def write_paraview(*args, **kwargs):
    """See :func:`flexparcel.io.paraview.write_paraview` (needs meshio)."""
    from flexparcel.io.paraview import write_paraview as _w

    return _w(*args, **kwargs)
