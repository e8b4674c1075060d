"""Envelope meshes of flat consignments, before any opening or settling.

:func:`two_layer_envelope`: a bottom and a top rectangle of square quads sharing their
boundary nodes. The top layer's interior nodes are raised by ``gap`` so the envelope already
has room for its content; the first ring of top quads slopes from the shared border up to
that height. Normals point outwards (bottom -z, top +z), so the mesh is one consistently
oriented closed surface.

:func:`gusseted_envelope`: a flat-folded bag with a W-gusset along each long side and sealed
ends, in six layers (KP's construction, :mod:`flexparcel.consignments.build`).
"""

from __future__ import annotations

import numpy as np

from flexparcel.model import mesh

__all__ = ["two_layer_envelope", "gusseted_envelope"]


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


def _split_grid(bounds: list[float], element_size: float) -> np.ndarray:
    """Points of a 1-D grid through every value of ``bounds`` (increasing), each interval
    split into pieces of about ``element_size`` (at least one)."""
    out = [bounds[0]]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        n = max(1, round((b - a) / element_size))
        out += list(np.linspace(a, b, n + 1)[1:])
    return np.asarray(out)


def gusseted_envelope(
    length: float,
    width: float,
    gusset_depth: float,
    spacing: float,
    element_size: float,
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """A flat-folded bag with a W-gusset along each long side and sealed ends: points (n, 3)
    [m], quads (m, 4) and its node ids by role.

    Cross-section (y, z) of the folded state, from the bottom: the bottom panel (z = 0,
    y in [-w/2, w/2]); at each side edge it folds back inward as the gusset's lower ply
    (z = ``spacing``) to the inner fold ``gusset_depth`` from the edge, which turns out again
    as the upper ply (z = 2 ``spacing``) to the edge, where it folds into the top panel
    (z = 3 ``spacing``). Unfolded, each gusset is a side wall 2 ``gusset_depth`` high. At
    x = +-``length``/2 every layer ends in one seam line (z = 1.5 ``spacing``), so the ends of
    the filled bag are wedges. Each fold is a node line shared by its two plies, half a
    spacing from both; the layers stay ``spacing`` apart elsewhere.

    The y grid passes through the inner folds (each strip split into pieces of about
    ``element_size``), so the plies end on seam nodes. Normals point to the bag's outside:
    bottom panel -z, lower plies +z (the gusset's pocket, open to the outside, lies between
    the plies), upper plies -z, top panel +z. Centred on the origin, x along the length.

    Roles: ``bottom`` and ``top`` (the panels' nodes off the seams and folds), ``bottom_layer``
    (every node of the bottom panel), ``seam`` (both ends), ``edge`` (the +x seam, ordered
    by y), ``top_quads`` (rows of the top panel's quads in ``quads``).
    """
    for name, v in (("length", length), ("width", width), ("gusset_depth", gusset_depth),
                    ("spacing", spacing), ("element_size", element_size)):  # fmt: skip
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"gusseted_envelope: {name} must be > 0 m, got {v!r}")
    if not gusset_depth < width / 2:
        raise ValueError(
            f"gusseted_envelope: gusset_depth must be < width / 2 = {width / 2:g} m, "
            f"got {gusset_depth!r}"
        )
    nx = max(2, round(length / element_size))
    xs = np.linspace(-length / 2, length / 2, nx + 1)
    ys = _split_grid([-width / 2, -width / 2 + gusset_depth, width / 2 - gusset_depth,
                      width / 2], element_size)  # fmt: skip
    ny = len(ys) - 1
    j_left = int(np.argmin(np.abs(ys - (-width / 2 + gusset_depth))))
    j_right = int(np.argmin(np.abs(ys - (width / 2 - gusset_depth))))
    points: list[np.ndarray] = []

    def new_nodes(mask: np.ndarray, z: float) -> np.ndarray:
        """Node ids (nx + 1, ny + 1) of fresh nodes where ``mask``, at height z; -1 elsewhere."""
        ids = np.full(mask.shape, -1, np.int64)
        start = sum(len(p) for p in points)
        ids[mask] = start + np.arange(mask.sum())
        i, j = np.nonzero(mask)
        points.append(np.column_stack([xs[i], ys[j], np.full(len(i), z)]))
        return ids

    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    end = (i == 0) | (i == nx)
    side = (j == 0) | (j == ny)
    seam = new_nodes(end, 1.5 * spacing)
    bottom = np.where(end, seam, new_nodes(~end & ~side, 0.0))
    bottom = np.where(~end & side, new_nodes(~end & side, 0.5 * spacing), bottom)
    top = np.where(end, seam, new_nodes(~end & ~side, 3 * spacing))
    top = np.where(~end & side, new_nodes(~end & side, 2.5 * spacing), top)
    inner = ~end & ((j == j_left) | (j == j_right))
    fold_in = new_nodes(inner, 1.5 * spacing)
    lower = np.where(end, seam, np.where(side, bottom, fold_in))
    upper = np.where(end, seam, np.where(side, top, fold_in))
    mid_l = ~end & (j > 0) & (j < j_left)
    mid_r = ~end & (j > j_right) & (j < ny)
    lower = np.where(mid_l | mid_r, new_nodes(mid_l | mid_r, spacing), lower)
    upper = np.where(mid_l | mid_r, new_nodes(mid_l | mid_r, 2 * spacing), upper)

    def quads_of(ids: np.ndarray, j_cells: np.ndarray, up: bool) -> np.ndarray:
        """Quads of the cells (i, j) for j in ``j_cells``: counter-clockwise about +z if ``up``."""
        ci, cj = np.meshgrid(np.arange(nx), j_cells, indexing="ij")
        ci, cj = ci.ravel(), cj.ravel()
        a, b = ids[ci, cj], ids[ci + 1, cj]
        c, d = ids[ci + 1, cj + 1], ids[ci, cj + 1]
        return np.column_stack([a, b, c, d] if up else [a, d, c, b])

    gusset_cells = np.r_[np.arange(0, j_left), np.arange(j_right, ny)]
    blocks = [
        quads_of(bottom, np.arange(ny), up=False),
        quads_of(lower, gusset_cells, up=True),
        quads_of(upper, gusset_cells, up=False),
        quads_of(top, np.arange(ny), up=True),
    ]
    quads = np.vstack(blocks).astype(np.int64)
    n_before_top = sum(len(q) for q in blocks[:3])
    roles = {
        "bottom": bottom[~end & ~side],
        "top": top[~end & ~side],
        "bottom_layer": np.unique(bottom),
        "seam": seam[end],
        "edge": seam[nx, :],
        "top_quads": np.arange(n_before_top, len(quads)),
    }
    return np.vstack(points), quads, roles
