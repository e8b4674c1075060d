"""ParaView export: one VTU file per output time plus a ``.pvd`` collection (via meshio)."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

__all__ = ["write_paraview"]


def write_paraview(
    directory: str | Path, result, model, name: str = "shell", every: int = 1
) -> Path:
    """Write ``DIR/name_XXXX.vtu`` and ``DIR/name.pvd``; open the ``.pvd`` in ParaView.

    Point data: ``displacement`` [m], ``rotation_vector`` [rad], ``velocity`` [m/s].
    """
    import meshio

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    cells = [(ctype, conn) for ctype, conn in model.cells]
    entries = []
    for k in range(0, len(result.time), max(1, int(every))):
        fname = f"{name}_{k:04d}.vtu"
        mesh = meshio.Mesh(
            result.positions[k],
            cells,
            point_data={
                "displacement": result.positions[k] - model.positions0,
                "rotation_vector": result.rotation_vectors[k],
                "velocity": result.velocities[k][:, :3],
            },
        )
        meshio.write(directory / fname, mesh, binary=True)
        entries.append((float(result.time[k]), fname))
    pvd = directory / f"{name}.pvd"
    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
        "  <Collection>",
    ]
    lines += [
        f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>' for t, f in entries
    ]
    lines += ["  </Collection>", "</VTKFile>", ""]
    pvd.write_text("\n".join(lines))
    return pvd
