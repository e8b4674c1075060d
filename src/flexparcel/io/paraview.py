"""ParaView export: one VTU file per output time plus a ``.pvd`` collection (via meshio)."""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import quoteattr

__all__ = ["write_paraview", "write_paraview_boxes"]


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
    return _write_pvd(directory / f"{name}.pvd", entries)


def write_paraview_boxes(
    directory: str | Path,
    time,
    centres,
    rotations,
    sizes,
    name: str = "content",
) -> Path:
    """Rigid boxes as one hexahedron each: ``DIR/name_XXXX.vtu`` and ``DIR/name.pvd``.

    ``time`` [s] (k,); ``centres`` [m] (k, b, 3); ``rotations`` body -> world (k, b, 3, 3);
    ``sizes`` edge lengths [m] along the body axes (b, 3). Rigid contents are a single node of
    the model, invisible in :func:`write_paraview`; this series shows them next to the
    packaging (open both ``.pvd`` files).
    """
    import meshio
    import numpy as np

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    time = np.asarray(time, float)
    centres = np.asarray(centres, float)
    rotations = np.asarray(rotations, float)
    sizes = np.asarray(sizes, float).reshape(-1, 3)
    nb = sizes.shape[0]
    if centres.shape != (len(time), nb, 3) or rotations.shape != (len(time), nb, 3, 3):
        raise ValueError(
            f"write_paraview_boxes: centres {centres.shape} and rotations {rotations.shape} "
            f"must be ({len(time)}, {nb}, 3) and ({len(time)}, {nb}, 3, 3)"
        )
    # VTK hexahedron order: bottom face counter-clockwise, then the top face above it
    unit = 0.5 * np.array(
        [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
         [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], float
    )  # fmt: skip
    local = unit[None, :, :] * sizes[:, None, :]  # (b, 8, 3)
    conn = np.arange(8 * nb).reshape(nb, 8)
    entries = []
    for k, t in enumerate(time):
        pts = centres[k][:, None, :] + np.einsum("bij,bcj->bci", rotations[k], local)
        fname = f"{name}_{k:04d}.vtu"
        meshio.write(directory / fname, meshio.Mesh(pts.reshape(-1, 3), [("hexahedron", conn)]),
                     binary=True)  # fmt: skip
        entries.append((float(t), fname))
    return _write_pvd(directory / f"{name}.pvd", entries)


def _write_pvd(pvd: Path, entries: list[tuple[float, str]]) -> Path:
    """A ParaView collection file listing ``(time, file)`` entries."""
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
