"""Assembly on the mesh's pattern (elements/assembly.py) against a dense element-by-element sum."""

from __future__ import annotations

import numpy as np

from pymorembs.elements.assembly import NodePattern
from pymorembs.elements.hex20 import HEX20_NODES, assemble_hex20, hex20_matrices


def two_by_one_hex20() -> tuple[np.ndarray, np.ndarray]:
    """Two 20-node bricks side by side along x (32 nodes, shared face merged), distorted."""
    corners = np.vstack([HEX20_NODES, HEX20_NODES + np.array([2.0, 0.0, 0.0])])
    points, connectivity = np.unique(corners, axis=0, return_inverse=True)
    points = points + 0.05 * np.sin(3.0 * points[:, [1, 2, 0]])
    return points, connectivity.reshape(2, 20)


def test_hex20_assembly_equals_the_dense_sum() -> None:
    points, elements = two_by_one_hex20()
    stiffness, mass = assemble_hex20(points, elements, 2.1e11, 0.3, 7850.0, chunk=1)
    k_e, m_e = hex20_matrices(points[elements], 2.1e11, 0.3, 7850.0)
    n = 3 * points.shape[0]
    k_dense, m_dense = np.zeros((n, n)), np.zeros((n, n))
    for e, nodes in enumerate(elements):
        dofs = (3 * nodes[:, None] + np.arange(3)).ravel()
        k_dense[np.ix_(dofs, dofs)] += k_e[e]
        for i in range(3):
            m_dense[np.ix_(3 * nodes + i, 3 * nodes + i)] += m_e[e]
    scale = np.abs(k_dense).max()
    assert np.abs(stiffness.toarray() - k_dense).max() <= 1e-15 * scale
    assert np.abs(mass.toarray() - m_dense).max() <= 1e-15 * np.abs(m_dense).max()
    for matrix in (stiffness, mass):  # canonical CSR: sorted, no duplicates
        assert matrix.has_canonical_format
        check = matrix.copy()
        check.has_canonical_format = False
        check.sum_duplicates()
        assert np.array_equal(check.indices, matrix.indices)
    # the mass couples equal directions only: 3 entries per adjacent node pair
    pattern = NodePattern(elements, points.shape[0])
    assert mass.nnz == 3 * pattern.indices.size and stiffness.nnz == 9 * pattern.indices.size
