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
        A direction is deflated when, after scaling the block's columns to unit norm and
        orthogonalising, its singular value is below ``tol``.
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
            # (q^H b) without copying the conjugate of the whole basis
            coefficients = (block.conj().T @ q).conj().T if np.iscomplexobj(q) else q.T @ block
            block = block - q @ coefficients
        return block

    def add(
        self, block: np.ndarray, limit: int | None = None, reference: float = 0.0
    ) -> np.ndarray:
        """Add the new directions of ``block`` (n, k); return them, shape (n, k_new).

        Every column is scaled to unit norm first, so a direction is judged new or not by its
        own size, not by the largest column of the block (a weak input must not be deflated
        because another input is strong). Columns whose norm is below ``tol * reference`` are
        dropped as round-off (e.g. the part of unit vectors that should be zero). At most
        ``limit`` directions are added (the dominant ones).
        """
        block = np.asarray(block)
        if block.ndim == 1:
            block = block[:, None]
        norms = np.linalg.norm(block, axis=0)
        keep = np.isfinite(norms) & (norms > self.tol * reference) & (norms > 0)
        if not np.any(keep) or (limit is not None and limit <= 0):
            return block[:, :0]
        block = block[:, keep] / norms[keep]
        rest = self.orthogonalize(block)
        u, s, _ = np.linalg.svd(rest, full_matrices=False)
        count = int(np.count_nonzero(s > self.tol))
        if limit is not None:
            count = min(count, limit)
        new = self.orthogonalize(u[:, :count])  # guard against loss of orthogonality
        new, _ = np.linalg.qr(new)
        self._columns = np.hstack([self._columns, new])
        return new
