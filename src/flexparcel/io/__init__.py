"""Results files (npz) and ParaView export. Heavy dependencies are imported lazily."""

from flexparcel.io.results import load_result, save_result

__all__ = ["save_result", "load_result", "write_paraview"]


def write_paraview(*args, **kwargs):
    """See :func:`flexparcel.io.paraview.write_paraview` (needs meshio)."""
    from flexparcel.io.paraview import write_paraview as _w

    return _w(*args, **kwargs)
