"""A closed two-layer envelope mesh: a bottom and a top rectangle of square quads sharing their
boundary nodes (the packaging of a flat consignment, before any opening or settling).

The top layer's interior nodes are raised by ``gap`` so the envelope already has room for its
content; the first ring of top quads slopes from the shared border up to that height. Normals
point outwards (bottom -z, top +z), so the mesh is one consistently oriented closed surface.
"""

from __future__ import annotations

import numpy as np

from flexparcel.model import mesh

__all__ = ["two_layer_envelope"]


def two_layer_envelope(
    length: float,
    width: float,
    gap: float,
    element_size: float,
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points (n, 3) [m] and quads (m, 4) of the envelope, plus the node ids of the bottom layer
    (including the shared border) and of the top layer's interior.

    The bottom layer lies in z = origin z, centred on (origin x, origin y).
    """
    if not gap > 0:
        raise ValueError(f"two_layer_envelope: gap must be > 0 m, got {gap!r}")
    nx = max(2, round(length / element_size))
    ny = max(2, round(width / element_size))
    ox, oy, oz = origin
    bottom, q_bottom = mesh.rectangle(
        length, width, nx, ny, origin=(ox - length / 2, oy - width / 2, oz)
    )
    # node (i, j) -> i + j (nx + 1); interior nodes get a twin on the top layer
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="xy")
    interior = ((i > 0) & (i < nx) & (j > 0) & (j < ny)).ravel()
    top_of = np.arange(len(bottom))
    top_ids = len(bottom) + np.arange(interior.sum())
    top_of[interior] = top_ids
    top_pts = bottom[interior] + (0.0, 0.0, gap)
    points = np.vstack([bottom, top_pts])
    quads_bottom = q_bottom[:, ::-1]  # outward normal -z
    quads_top = top_of[q_bottom]  # +z
    quads = np.vstack([quads_bottom, quads_top]).astype(np.int64)
    return points, quads, np.arange(len(bottom)), top_ids
