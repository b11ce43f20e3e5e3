"""Orthonormal bases with reorthogonalisation and rank-revealing deflation."""

from __future__ import annotations

import numpy as np


class OrthonormalBasis:
    """An orthonormal basis (Euclidean inner product) grown block by block.

    Each new block is orthogonalised twice against the basis (classical Gram-Schmidt with
    reorthogonalisation, "twice is enough"), then split by an SVD into directions that are new
    and directions that lie in the span already within the tolerance (deflation). Directions of
    a block enter in order of decreasing singular value, so a basis cut at a given size keeps the
    dominant part of the last block.

    Parameters
    ----------
    n : int
        Length of the vectors.
    tol : float
        A direction is deflated when its norm after orthogonalisation is below ``tol`` times the
        norm of the largest column of the block before orthogonalisation.
    dtype : numpy dtype
        ``float`` or ``complex``.
    """

    def __init__(self, n: int, tol: float = 1e-10, dtype: type = float) -> None:
        self.n = n
        self.tol = tol
        self._columns = np.zeros((n, 0), dtype=dtype)

    @property
    def size(self) -> int:
        return int(self._columns.shape[1])

    @property
    def matrix(self) -> np.ndarray:
        """The basis, shape (n, size), with orthonormal columns."""
        return self._columns

    def orthogonalize(self, block: np.ndarray) -> np.ndarray:
        """The block minus its projection on the basis (twice)."""
        q = self._columns
        for _ in range(2):
            block = block - q @ (q.conj().T @ block)
        return block

    def add(
        self, block: np.ndarray, limit: int | None = None, reference: float = 0.0
    ) -> np.ndarray:
        """Add the new directions of ``block`` (n, k); return them, shape (n, k_new).

        At most ``limit`` directions are added (the dominant ones). The deflation tolerance is
        relative to the largest column norm of the block, or to ``reference`` if that is larger
        (a block that is itself round-off, e.g. the part of unit vectors that should be zero, must
        not pass as new directions).
        """
        block = np.asarray(block)
        if block.ndim == 1:
            block = block[:, None]
        if block.shape[1] == 0:
            return block
        scale = max(float(np.max(np.linalg.norm(block, axis=0))), reference)
        if scale == 0.0 or not np.isfinite(scale):
            return block[:, :0]
        rest = self.orthogonalize(block)
        u, s, _ = np.linalg.svd(rest, full_matrices=False)
        keep = int(np.count_nonzero(s > self.tol * scale))
        if limit is not None:
            keep = min(keep, max(limit, 0))
        new = u[:, :keep]
        new = self.orthogonalize(new)  # guard against loss of orthogonality in the SVD step
        new, _ = np.linalg.qr(new)
        self._columns = np.hstack([self._columns, new])
        return new
