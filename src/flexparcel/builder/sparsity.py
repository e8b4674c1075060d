"""The sparse pattern of a model's matrices and the CSR data slots of every block.

Matrices live over the unknowns and the FDR slave DOFs (the "ext" numbering of
``Model.free_index``). Each element group, every node's own 6x6 block (contact with fixed
surfaces, rigid-body inertia and follower loads couple a node's DOFs among themselves) and the
diagonal make up the pattern. A block entry on a held DOF gets the trash slot ``nnz``, the last
entry of every data array, which :func:`flexparcel.integrate.assembly.csr_from_data` drops.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SparsePattern"]


class SparsePattern:
    """CSR pattern over ``free_index`` numbers plus the slot maps of its blocks.

    Args:
        free_index: number of each DOF (node_count * 6,), -1 where held.
        group_dofs: per element group, the global DOF numbers (m, w) of its element rows.
    """

    def __init__(self, free_index: np.ndarray, group_dofs: list[np.ndarray]) -> None:
        self.free_index = free_index
        self.size = int(free_index.max()) + 1
        node_count = free_index.size // 6
        n = self.size
        keys = [np.arange(n) * (n + 1)]
        blocks = [free_index[d] for d in group_dofs]  # (m, w) numbers per group
        blocks.append(free_index.reshape(node_count, 6))  # every node's own block
        for fd in blocks:
            rows, cols = _pairs(fd)
            ok = (rows >= 0) & (cols >= 0)
            keys.append(rows[ok] * n + cols[ok])
        self._keys = np.unique(np.concatenate(keys))
        nnz = self._keys.size
        self.nnz = nnz
        r = self._keys // n
        self.indices = (self._keys % n).astype(np.int64)
        self.indptr = np.zeros(n + 1, dtype=np.int64)
        np.add.at(self.indptr, r + 1, 1)
        self.indptr = np.cumsum(self.indptr)
        self.diag = np.searchsorted(self._keys, np.arange(n) * (n + 1))
        self.group_slots = [self.slots(*_pairs(fd)) for fd in blocks[:-1]]
        """CSR data slots of each group's element matrices, (m, w, w) per group."""

    def slots(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Data slot of each (row, column) number pair (any equal shapes); ``nnz`` where
        either is held (-1) or the entry is not in the pattern."""
        n = self.size
        key = rows * n + cols
        pos = np.minimum(np.searchsorted(self._keys, key), self.nnz - 1)
        found = (rows >= 0) & (cols >= 0) & (self._keys[pos] == key)
        return np.where(found, pos, self.nnz).astype(np.int64)

    def _node_dofs(self, nodes: np.ndarray, first: int, count: int) -> np.ndarray:
        """Numbers (k, count) of DOFs first..first+count-1 of each node."""
        nodes = np.asarray(nodes, dtype=np.int64)
        return self.free_index[6 * nodes[:, None] + first + np.arange(count)]

    def node_slots(self, node_count: int) -> np.ndarray:
        """Slots of every node's own 6x6 block, shape (node_count, 6, 6)."""
        return self.slots(*_pairs(self._node_dofs(np.arange(node_count), 0, 6)))

    def rotation_slots(self, nodes: np.ndarray) -> np.ndarray:
        """Slots of the rotation-rotation 3x3 block of each node, shape (k, 3, 3)."""
        return self.slots(*_pairs(self._node_dofs(nodes, 3, 3)))

    def load_slots(self, nodes: np.ndarray) -> np.ndarray:
        """Slots of the (translation | rotation rows, spin columns) 3x3 blocks of each node,
        shape (k, 2, 3, 3) (the follower-load stiffness)."""
        spins = self._node_dofs(nodes, 3, 3)
        out = np.empty((len(spins), 2, 3, 3), dtype=np.int64)
        for blk in range(2):
            rows = self._node_dofs(nodes, 3 * blk, 3)
            out[:, blk] = self.slots(rows[:, :, None] + 0 * spins[:, None, :],
                                     spins[:, None, :] + 0 * rows[:, :, None])  # fmt: skip
        return out


def _pairs(numbers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column numbers (m, w, w) of the dense blocks over ``numbers`` (m, w)."""
    w = numbers.shape[1]
    return (np.repeat(numbers, w, axis=1).reshape(-1, w, w),
            np.tile(numbers, (1, w)).reshape(-1, w, w))  # fmt: skip
