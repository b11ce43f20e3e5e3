"""Assembly of element matrices into global CSR matrices on a pattern computed once.

Summing the sparse matrices of chunks of elements (``K = K + K_chunk``) holds the old sum, the
chunk and the new sum at once and copies the whole matrix per chunk: a peak of about 2.6 times
the final matrices. Here the pattern comes first, from the node adjacency of the mesh (every pair
of nodes that share an element, ``E^T E`` of the element-node incidence ``E``), and the element
matrices of each chunk are added into the final data array in place: the peak is the final
matrices plus one chunk of element matrices.

Solid elements with three translational dofs per node (equation ``3 r + i`` is direction ``i``
of the node in row ``r``): the stiffness couples every direction of two adjacent nodes (3 x 3
blocks), the consistent mass only equal directions (``m_ab I``, 3 entries per node pair).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["NodePattern"]

#: Node pairs handled per block when the index arrays are filled.
_PAIRS_PER_BLOCK = 1 << 20


class NodePattern:
    """The node adjacency of a mesh (sorted CSR) and where each dof entry goes.

    Parameters
    ----------
    elements : ndarray of int, shape (n_el, n_per_element)
        Rows of the nodes of each element (0-based).
    n_nodes : int

    Attributes
    ----------
    indptr, indices : ndarray of int64 and int32
        CSR pattern of the node adjacency, shape (n_nodes, n_nodes), sorted columns.
    """

    def __init__(self, elements: np.ndarray, n_nodes: int) -> None:
        elements = np.asarray(elements)
        n_el, per = elements.shape
        incidence = sp.csr_matrix(
            (np.ones(n_el * per, dtype=np.int32), elements.ravel().astype(np.int32),
             np.arange(0, n_el * per + 1, per, dtype=np.int64)),
            shape=(n_el, n_nodes),
        )  # fmt: skip
        adjacency = sp.csr_matrix(incidence.T @ incidence)
        adjacency.sort_indices()
        self.n_nodes = n_nodes
        self.indptr = adjacency.indptr.astype(np.int64)
        self.indices = adjacency.indices.astype(np.int32)
        self.lengths = np.diff(self.indptr)
        self._flat: np.ndarray | None = None  # sorted keys row * n_nodes + col, on first use

    def position(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Index ``p`` in :attr:`indices` of each node pair (rows, cols), any equal shapes: a
        binary search of the key ``row * n_nodes + col`` in the sorted keys of the pattern."""
        if self._flat is None:
            rows_of = np.repeat(np.arange(self.n_nodes, dtype=np.int64), self.lengths)
            self._flat = rows_of * self.n_nodes + self.indices
        return np.searchsorted(self._flat, rows.astype(np.int64) * self.n_nodes + cols)

    def empty(self, blocks: bool) -> sp.csr_matrix:
        """A zero CSR matrix of shape (3 n_nodes, 3 n_nodes) on the dof pattern: every entry
        of the 3 x 3 blocks (``blocks``) or their diagonals only, sorted columns."""
        n = self.n_nodes
        width = 3 if blocks else 1
        row_length = np.repeat(width * self.lengths, 3)  # dof rows 3a, 3a+1, 3a+2
        indptr = np.zeros(3 * n + 1, dtype=np.int64)
        np.cumsum(row_length, out=indptr[1:])
        indices = np.empty(indptr[-1], dtype=np.int32)
        for start in range(0, self.indices.size, _PAIRS_PER_BLOCK):
            p = np.arange(start, min(start + _PAIRS_PER_BLOCK, self.indices.size))
            rows = np.searchsorted(self.indptr, p, side="right") - 1
            for i in range(3):
                for j in range(3) if blocks else (i,):
                    indices[self._dof_position(rows, p, i, j, blocks)] = 3 * self.indices[p] + j
        index_type = np.int32 if indptr[-1] < 2**31 else np.int64
        matrix = sp.csr_matrix(
            (np.zeros(indptr[-1]), indices.astype(index_type, copy=False),
             indptr.astype(index_type)),
            shape=(3 * n, 3 * n),
            copy=False,
        )  # fmt: skip
        matrix.has_canonical_format = True
        return matrix

    def _dof_position(
        self, rows: np.ndarray, p: np.ndarray, i: int | np.ndarray, j: int | np.ndarray,
        blocks: bool,
    ) -> np.ndarray:  # fmt: skip
        """Index in the dof pattern's data of entry (direction i of node ``rows``, direction j of
        node pair ``p``)."""
        start, length = self.indptr[rows], self.lengths[rows]
        if blocks:
            return 9 * start + 3 * i * length + 3 * (p - start) + j
        return 3 * start + i * length + (p - start)

    def add_blocks(self, matrix: sp.csr_matrix, values: np.ndarray, conn: np.ndarray) -> None:
        """Add element matrices with 3 x 3 node blocks into ``matrix`` (from :meth:`empty`
        with ``blocks=True``), in place.

        ``values`` shape (n_el, 3 m, 3 m) with dof order (node, direction); ``conn`` shape
        (n_el, m).
        """
        m = conn.shape[1]
        rows = np.broadcast_to(conn[:, :, None], (conn.shape[0], m, m))
        cols = np.broadcast_to(conn[:, None, :], (conn.shape[0], m, m))
        p = self.position(rows, cols)[:, :, None, :, None]  # (n_el, m, 1, m, 1)
        i = np.arange(3)[None, None, :, None, None]
        j = np.arange(3)[None, None, None, None, :]
        where = self._dof_position(rows[:, :, None, :, None], p, i, j, True)
        np.add.at(matrix.data, where.ravel(), values.reshape(-1))

    def add_diagonal_blocks(
        self, matrix: sp.csr_matrix, values: np.ndarray, conn: np.ndarray
    ) -> None:
        """Add ``values[e, a, b] * I_3`` at the node pairs of ``conn`` into ``matrix`` (from
        :meth:`empty` with ``blocks=False``), in place; ``values`` shape (n_el, m, m)."""
        m = conn.shape[1]
        rows = np.broadcast_to(conn[:, :, None], (conn.shape[0], m, m))
        cols = np.broadcast_to(conn[:, None, :], (conn.shape[0], m, m))
        p = self.position(rows, cols)
        for i in range(3):
            np.add.at(matrix.data, self._dof_position(rows, p, i, i, False).ravel(),
                      values.ravel())  # fmt: skip
