"""OrthonormalBasis against dense references: orthonormality, span, deflation, growth."""

from __future__ import annotations

import numpy as np
import pytest

from pymorembs.linalg.orthogonalization import OrthonormalBasis


def _projector_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest principal-angle sine between the column spans of ``a`` and ``b`` (orthonormal)."""
    return float(np.linalg.norm(a - b @ (b.conj().T @ a), 2))


@pytest.mark.parametrize("dtype", [float, complex])
def test_many_blocks_stay_orthonormal_and_span_what_was_added(dtype):
    rng = np.random.default_rng(3)
    n, blocks = 400, 23  # 69 columns: the storage grows several times
    basis = OrthonormalBasis(n, tol=1e-10, dtype=dtype)
    added = []
    for _ in range(blocks):
        block = rng.standard_normal((n, 3))
        if dtype is complex:
            block = block + 1j * rng.standard_normal((n, 3))
        new = basis.add(block)
        assert new.shape == (n, 3)  # random blocks: nothing to deflate
        added.append(block)
        # the returned directions are the last columns of the basis
        assert np.array_equal(basis.matrix[:, -3:], new)
    v = basis.matrix
    assert v.shape == (n, 3 * blocks) and basis.size == 3 * blocks
    assert np.abs(v.conj().T @ v - np.eye(v.shape[1])).max() < 1e-13
    # the span is that of all blocks (dense QR of the stacked blocks as the reference)
    reference, _ = np.linalg.qr(np.hstack(added))
    assert _projector_distance(reference, v) < 1e-12
    assert _projector_distance(v, reference) < 1e-12


def test_directions_inside_the_span_are_deflated_and_weak_new_ones_kept():
    rng = np.random.default_rng(5)
    n = 300
    basis = OrthonormalBasis(n, tol=1e-10)
    first = rng.standard_normal((n, 4))
    basis.add(first)
    q, _ = np.linalg.qr(first)
    outside = rng.standard_normal(n)
    outside -= q @ (q.T @ outside)
    outside /= np.linalg.norm(outside)
    inside = first @ rng.standard_normal((4, 2))  # exactly in the span (up to rounding)
    # unit columns: a new direction 1e-8 out of the span is above the tolerance (kept), the
    # combinations of the first block are deflated
    weak = inside[:, 0] / np.linalg.norm(inside[:, 0]) + 1e-8 * outside
    new = basis.add(np.column_stack([inside, weak]))
    assert new.shape[1] == 1
    assert abs(abs(float(new[:, 0] @ outside)) - 1.0) < 1e-6  # the weak direction itself
    v = basis.matrix
    # amplifying a 1e-8 direction to unit length must not cost orthogonality
    assert np.abs(v.T @ v - np.eye(5)).max() < 1e-13


def test_limit_keeps_the_dominant_directions():
    rng = np.random.default_rng(7)
    n = 200
    basis = OrthonormalBasis(n)
    q, _ = np.linalg.qr(rng.standard_normal((n, 3)))
    # columns of different weight after scaling to unit norm: the first two share a direction
    block = np.column_stack([q[:, 0], q[:, 0] + 1e-3 * q[:, 1], q[:, 2]])
    new = basis.add(block, limit=2)
    assert new.shape[1] == 2 and basis.size == 2
    # dense reference: the two leading left singular vectors of the normalised block
    scaled = block / np.linalg.norm(block, axis=0)
    u, _, _ = np.linalg.svd(scaled, full_matrices=False)
    assert _projector_distance(u[:, :2], new) < 1e-12
